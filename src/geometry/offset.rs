use super::Ray;
use super::triangle::gamma;
use glam::Vec3;

/// Moves a surface point off its surface so that a ray leaving it in direction `w`
/// cannot re-hit that surface (pbrt-v4 `OffsetRayOrigin`, Pharr, Jakob, Humphreys
/// §6.8.6).
///
/// `p_error` bounds, per component, how far the computed `p` may lie from the true
/// surface (the box `p ± p_error` contains a point of the surface); `n` is the unit
/// geometric normal. The point moves along `±n` (towards the side `w` leaves into) by
/// `d = |n|·p_error`, the extent of that box along `n`, so the new origin lies outside
/// the box on the right side of the surface. Each moved coordinate is then rounded one
/// float further away from `p`, so the rounding of `p + offset` cannot eat the offset.
/// `d` is enlarged by `γ(8)` for the rounding of the dot product and of `n` itself.
///
/// An exact point (`p_error = 0`, e.g. on an axis-aligned plane through the origin)
/// is not moved: the triangle test's conservative `t > δt` rejects the surface the ray
/// starts on (see `intersect_triangle`).
#[inline]
pub fn offset_ray_origin(p: Vec3, p_error: Vec3, n: Vec3, w: Vec3) -> Vec3 {
    let d = n.abs().dot(p_error) * (1.0 + gamma(8));
    let mut offset = d * n;
    if w.dot(n) < 0.0 {
        offset = -offset;
    }
    let po = p + offset;
    Vec3::new(
        step_towards_sign(po.x, offset.x),
        step_towards_sign(po.y, offset.y),
        step_towards_sign(po.z, offset.z),
    )
}

/// `x.next_up()` where `s > 0`, `x.next_down()` where `s < 0`, `x` where `s` is zero
/// or NaN: the same float as those (NaN stays NaN), computed as selects on the bits
/// instead of the per-component branches of `next_up`/`next_down`, whose direction
/// follows the sign of the normal and so mispredicts about half the time. Profiled on
/// the POV-Ray whitted frame (1 thread) the branchy loop was 15.6 % of the render:
/// the function runs once per child ray and twice per shadow ray (`spawn_ray_to`).
/// The branchy form stays in the tests as the oracle (bit equality).
#[inline(always)]
fn step_towards_sign(x: f32, s: f32) -> f32 {
    const SIGN: u32 = 0x8000_0000;
    const INF: u32 = 0x7f80_0000;
    let xb = x.to_bits();
    let mag = xb & !SIGN;
    let s_sign = s.to_bits() & SIGN;
    // Same sign: one more unit in the last place moves away from zero, one less towards.
    let away = xb & SIGN == s_sign;
    let next = if mag == 0 {
        s_sign | 1
    } else if away {
        xb.wrapping_add(1)
    } else {
        xb.wrapping_sub(1)
    };
    // `next_up(inf)`, `next_down(-inf)` and NaN are left as they are.
    let keep = s == 0.0 || s.is_nan() || mag > INF || (away && mag == INF);
    if keep { x } else { f32::from_bits(next) }
}

/// Relative error bound used to end a segment short of its target: the end point
/// `o + d` misses the offset target by the rounding of `d = target - o` (`u |d|`), and
/// the triangle test's `t` carries the error of translating and shearing the target's
/// corners, a few dozen roundings of the translated coordinates (`δt` of
/// `intersect_triangle`, first order). `γ(64)` covers both with a factor two to spare.
pub const SPAWN_TO_ERROR: f32 = gamma(64);

/// A segment from the surface point `p` (error `p_error`, unit geometric normal `n`)
/// to the surface point `q` (error `q_error`, unit normal `n_q`), offset at both ends
/// by [`offset_ray_origin`] (pbrt-v4 `SpawnRayTo` for two interactions), for shadow
/// rays: neither the surface it starts on nor the one it ends on can block it.
///
/// The direction is `q' - o` unnormalised and the segment ends at parametric
/// `tmax = 1 - ε`, `ε = SPAWN_TO_ERROR ‖d‖₁ / |n_q·d|`: the end stops
/// `SPAWN_TO_ERROR ‖d‖₁` short of the target, measured along `n_q`, which covers the
/// rounding of `d` and the error of `t` (both first order in the translated
/// coordinates, `‖d‖` plus the target's extent, which its `q_error` carries). No tuned
/// constant: a grazing segment ends proportionally earlier. A target without a surface (a point
/// light) passes `q_error = 0` and `n_q` along the segment. A segment shorter than its
/// own error bound is returned empty (`tmax = 0`): nothing can be resolved between its
/// ends.
pub fn spawn_ray_to(p: Vec3, p_error: Vec3, n: Vec3, q: Vec3, q_error: Vec3, n_q: Vec3) -> Ray {
    let o = offset_ray_origin(p, p_error, n, q - p);
    let target = offset_ray_origin(q, q_error, n_q, p - q);
    let d = target - o;
    let cos = n_q.dot(d).abs();
    let eps = SPAWN_TO_ERROR * (d.x.abs() + d.y.abs() + d.z.abs()) / cos;
    let tmax = if eps < 1.0 { 1.0 - eps } else { 0.0 };
    Ray::segment(o, d, 0.0, tmax)
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
    fn offset_leaves_the_error_box_on_the_side_of_w() {
        let n = Vec3::new(0.3, -0.8, 0.5).normalize();
        for s in [1e-30f32, 1e-6, 1.0, 1e6, 1e30] {
            let p = Vec3::new(s, -2.0 * s, 0.5 * s);
            let err = gamma(7) * p.abs();
            let box_extent = n.abs().dot(err);
            for (w, sign) in [(n, 1.0), (-n, -1.0)] {
                let o = offset_ray_origin(p, err, n, w);
                // Along n (in f64, exactly) the origin lies beyond the box's extent.
                let along = (o.as_dvec3() - p.as_dvec3()).dot(n.as_dvec3()) * sign;
                assert!(
                    along > box_extent as f64,
                    "scale {s}: {along} <= {box_extent}"
                );
                // ... and not absurdly far: within 2 ulps plus twice the box.
                assert!((o - p).length() <= 2.0 * box_extent + 4.0 * f32::EPSILON * p.length());
            }
        }
        // Zero error: the point is not moved.
        assert_eq!(
            offset_ray_origin(Vec3::X, Vec3::ZERO, Vec3::Y, Vec3::Y),
            Vec3::X
        );
    }

    #[test]
    fn spawn_to_ends_short_of_the_offset_target() {
        let (p, q) = (Vec3::new(0.0, 0.0, 0.0), Vec3::new(0.0, 1.0, 3.0));
        let r = spawn_ray_to(
            p,
            Vec3::splat(1e-7),
            Vec3::Y,
            q,
            Vec3::splat(1e-7),
            -Vec3::Y,
        );
        assert!(r.origin.y > 0.0 && r.tmax < 1.0 && r.tmax > 0.99);
        let end = r.at(r.tmax);
        assert!(
            end.y < q.y - 1e-7,
            "end {end} not short of the target plane"
        );
        // Grazing: the margin grows as 1 / cos.
        let q2 = Vec3::new(0.0, 1e-3, 3.0);
        let r2 = spawn_ray_to(p, Vec3::ZERO, Vec3::Y, q2, Vec3::ZERO, -Vec3::Y);
        assert!(1.0 - r2.tmax > 100.0 * (1.0 - r.tmax));
    }

    /// The per-component branches `offset_ray_origin` had before
    /// [`step_towards_sign`]: the oracle it must match bit for bit.
    fn offset_ray_origin_branchy(p: Vec3, p_error: Vec3, n: Vec3, w: Vec3) -> Vec3 {
        let d = n.abs().dot(p_error) * (1.0 + gamma(8));
        let mut offset = d * n;
        if w.dot(n) < 0.0 {
            offset = -offset;
        }
        let mut po = p + offset;
        for i in 0..3 {
            if offset[i] > 0.0 {
                po[i] = po[i].next_up();
            } else if offset[i] < 0.0 {
                po[i] = po[i].next_down();
            }
        }
        po
    }

    fn same_bits(a: f32, b: f32) -> bool {
        a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan())
    }

    #[test]
    fn step_matches_next_up_and_next_down_bit_for_bit() {
        let mut xs = vec![
            0.0f32,
            -0.0,
            f32::MIN_POSITIVE,
            -f32::MIN_POSITIVE,
            f32::from_bits(1),
            -f32::from_bits(1),
            f32::MAX,
            f32::MIN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            1.0,
            -1.0,
        ];
        // A sweep over the exponent range, both signs, plus the neighbours of each.
        let mut state = 0x9e37_79b9u32;
        for _ in 0..20_000 {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            let x = f32::from_bits(state);
            xs.extend([x, x.next_up(), x.next_down()]);
        }
        let ss = [
            1.0f32,
            -1.0,
            0.0,
            -0.0,
            f32::NAN,
            1e-40,
            -1e-40,
            f32::INFINITY,
        ];
        for &x in &xs {
            for &s in &ss {
                let want = if s > 0.0 {
                    x.next_up()
                } else if s < 0.0 {
                    x.next_down()
                } else {
                    x
                };
                let got = step_towards_sign(x, s);
                assert!(
                    same_bits(got, want),
                    "x {x:e} ({:#x}) s {s}: {got:e} != {want:e}",
                    x.to_bits()
                );
            }
        }
    }

    #[test]
    fn offset_matches_the_branchy_oracle_bit_for_bit() {
        let mut state = 0x1234_5678u32;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            state as f32 / u32::MAX as f32 * 2.0 - 1.0
        };
        for k in 0..50_000 {
            let scale = [1e-30f32, 1e-3, 1.0, 1e3, 1e30][k % 5];
            let p = Vec3::new(next(), next(), next()) * scale;
            // Some points on a coordinate plane (exact zero components).
            let p = if k % 7 == 0 {
                p * Vec3::new(1.0, 0.0, 1.0)
            } else {
                p
            };
            let err = if k % 11 == 0 {
                Vec3::ZERO
            } else {
                gamma(7) * p.abs()
            };
            let n = Vec3::new(next(), next(), next()).normalize_or(Vec3::Y);
            let w = Vec3::new(next(), next(), next());
            let (a, b) = (
                offset_ray_origin(p, err, n, w),
                offset_ray_origin_branchy(p, err, n, w),
            );
            for i in 0..3 {
                assert!(
                    same_bits(a[i], b[i]),
                    "p {p} err {err} n {n} w {w}: {a} != {b}"
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
