use glam::Vec3;

/// Offsets a surface point along the geometric normal so that a secondary ray started
/// there cannot re-hit the surface it leaves (Wächter & Binder, "A Fast and Robust
/// Method for Avoiding Self-Intersection", Ray Tracing Gems ch. 6).
///
/// Far from the origin the offset is a fixed number of units in the last place of each
/// coordinate (integer arithmetic on the float bits), so it scales with the magnitude of
/// the coordinates and works from 1e-6 to 1e7; near the origin, where ulps become tiny,
/// a small absolute offset takes over. No scene-dependent epsilon. `n` must point to the
/// side the new ray leaves into (flip it for refraction).
pub fn offset_ray_origin(p: Vec3, n: Vec3) -> Vec3 {
    const ORIGIN: f32 = 1.0 / 32.0;
    const FLOAT_SCALE: f32 = 1.0 / 65536.0;
    const INT_SCALE: f32 = 256.0;
    let mut out = Vec3::ZERO;
    for i in 0..3 {
        let of_i = (INT_SCALE * n[i]) as i32;
        let bits = p[i].to_bits() as i32;
        let moved = if p[i] < 0.0 { bits - of_i } else { bits + of_i };
        let p_i = f32::from_bits(moved as u32);
        out[i] = if p[i].abs() < ORIGIN {
            p[i] + FLOAT_SCALE * n[i]
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
