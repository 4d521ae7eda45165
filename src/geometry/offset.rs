use glam::Vec3;

/// Offsets a surface point along the geometric normal so that a secondary ray started
/// there cannot re-hit the surface it leaves (Wächter & Binder, "A Fast and Robust
/// Method for Avoiding Self-Intersection", Ray Tracing Gems ch. 6), for a primitive of
/// unit scale: [`offset_ray_origin_scaled`] with `scale = 1`.
pub fn offset_ray_origin(p: Vec3, n: Vec3) -> Vec3 {
    offset_ray_origin_scaled(p, n, 1.0)
}

/// Wächter-Binder offset for a hit point computed from coordinates of magnitude
/// `scale` (the largest |coordinate| of the triangle's corners, or of a sphere's centre
/// plus its radius).
///
/// Far from the origin the offset is a fixed number of units in the last place of each
/// coordinate (integer arithmetic on the float bits), so it scales with the magnitude of
/// the coordinates. Near the origin, where ulps of the point become tiny but the
/// rounding error of the point does not (it is a few ulps of the *inputs*), a small
/// absolute offset takes over. The paper fixes that offset and the near-origin region
/// for scenes of unit scale (1/65536 within 1/32 of the origin), which pushes the origin
/// of a refracted ray straight through anything smaller than about 1e-5 near the
/// origin; both are therefore proportional to `scale` here. `n` must point to the side
/// the new ray leaves into (flip it for refraction).
pub fn offset_ray_origin_scaled(p: Vec3, n: Vec3, scale: f32) -> Vec3 {
    const ORIGIN: f32 = 1.0 / 32.0;
    const FLOAT_SCALE: f32 = 1.0 / 65536.0;
    const INT_SCALE: f32 = 256.0;
    // A zero, subnormal or non-finite scale (degenerate primitive) falls back to the
    // smallest normal magnitude: the offset is then the integer one almost everywhere.
    let scale = if scale.is_finite() {
        scale.max(f32::MIN_POSITIVE)
    } else {
        1.0
    };
    let (origin, float_scale) = (ORIGIN * scale, FLOAT_SCALE * scale);
    let mut out = Vec3::ZERO;
    for i in 0..3 {
        let of_i = (INT_SCALE * n[i]) as i32;
        let bits = p[i].to_bits() as i32;
        let moved = if p[i] < 0.0 { bits - of_i } else { bits + of_i };
        let p_i = f32::from_bits(moved as u32);
        out[i] = if p[i].abs() < origin {
            p[i] + float_scale * n[i]
        } else {
            p_i
        };
    }
    out
}

/// Branch-free orthonormal basis around a unit vector (Duff et al., JCGT 2017).
/// Returns `(t, b)` with `t × b = n`.
pub fn orthonormal_basis(n: Vec3) -> (Vec3, Vec3) {
    let sign = 1.0f32.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (
        Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        Vec3::new(b, sign + n.y * n.y * a, -n.y),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offset_moves_to_the_normal_side_at_all_scales() {
        let n = Vec3::new(0.3, -0.8, 0.5).normalize();
        for s in [1e-6f32, 1e-3, 1.0, 1e3, 1e6, 1e7] {
            for p in [Vec3::splat(s), Vec3::new(-s, s, -s), Vec3::new(s, 0.0, -s)] {
                let o = offset_ray_origin(p, n);
                assert!((o - p).dot(n) > 0.0, "scale {s}: offset not along n");
                assert!(
                    (o - p).length() <= 1e-3 * p.length().max(1.0),
                    "scale {s}: offset too large"
                );
            }
        }
    }

    #[test]
    fn scaled_offset_stays_inside_tiny_geometry_near_the_origin() {
        // Regression: a 1e-6 cube at the origin. The unit-scale offset (1/65536) moves a
        // refraction origin 15 cube widths past the far face; scaled, it stays inside.
        let p = Vec3::new(3e-7, -1e-6, 2e-7);
        let inward = Vec3::new(0.0, 1.0, 0.0);
        let unit = offset_ray_origin(p, inward);
        assert!(
            unit.y > 1e-6,
            "unit-scale offset no longer leaves the cube: {unit}"
        );
        let o = offset_ray_origin_scaled(p, inward, 1e-6);
        assert!(o.y > p.y && o.y < -0.99e-6, "scaled offset {o}");
        // Scale 1 is the paper's offset, bit for bit.
        let n = Vec3::new(0.3, -0.8, 0.5).normalize();
        for q in [Vec3::splat(0.01), Vec3::new(-3.0, 0.001, 7.0)] {
            assert_eq!(offset_ray_origin(q, n), offset_ray_origin_scaled(q, n, 1.0));
        }
        // Degenerate scales never produce NaN.
        for s in [0.0, -1.0, f32::NAN, f32::INFINITY] {
            assert!(offset_ray_origin_scaled(p, n, s).is_finite());
        }
    }

    #[test]
    fn basis_is_orthonormal() {
        for n in [
            Vec3::Z,
            -Vec3::Z,
            Vec3::X,
            Vec3::new(1.0, 2.0, -3.0).normalize(),
        ] {
            let (t, b) = orthonormal_basis(n);
            assert!(t.dot(b).abs() < 1e-6 && t.dot(n).abs() < 1e-6 && b.dot(n).abs() < 1e-6);
            assert!((t.cross(b) - n).length() < 1e-5);
        }
    }
}
