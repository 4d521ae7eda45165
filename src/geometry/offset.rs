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
///
#[inline]
pub fn offset_ray_origin(p: Vec3, p_error: Vec3, n: Vec3, w: Vec3) -> Vec3 {
    let offset = offset_along(p_error, n);
    nudge(p, if w.dot(n) < 0.0 { -offset } else { offset })
}

/// The offset of [`offset_ray_origin`] on the side of `n`: `d n`.
#[inline]
fn offset_along(p_error: Vec3, n: Vec3) -> Vec3 {
    let d = n.abs().dot(p_error) * (1.0 + gamma(8));
    d * n
}

/// `p + offset`, each moved coordinate rounded one float further along the offset.
#[inline]
fn nudge(p: Vec3, offset: Vec3) -> Vec3 {
    let mut po = p + offset;
    // Dead end (2026-11-23, tried twice independently): a branch-free form of this
    // loop (selects on the bits, bit-identical to next_up/next_down) did not help on
    // the POV-Ray whitted frame, 1 thread: shade stage min/median/max 229/233/276 ms
    // against 220/222/230 ms for this loop (5 interleaved reps), and 12.4 % of `perf`
    // samples against 12.1 %. The cost is the number of calls (one per child ray, two
    // per shadow ray), not mispredicted branches ([`OffsetOrigins`] halves them for
    // the shadow rays of one point).
    for i in 0..3 {
        if offset[i] > 0.0 {
            po[i] = po[i].next_up();
        } else if offset[i] < 0.0 {
            po[i] = po[i].next_down();
        }
    }
    po
}

/// Both offset origins of one surface point, for the many rays that leave it (an area
/// light's shadow rays): [`offset_ray_origin`]`(p, p_error, n, w)` is one of two points
/// whatever `w` is, chosen by the side of `n` it leaves into, so they are computed once
/// and `w` only picks. The same bits as [`offset_ray_origin`] for every `w` (its sign
/// test is repeated as it is, NaN included).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OffsetOrigins {
    p: Vec3,
    n: Vec3,
    front: Vec3,
    back: Vec3,
}

impl OffsetOrigins {
    pub fn new(p: Vec3, p_error: Vec3, n: Vec3) -> Self {
        let offset = offset_along(p_error, n);
        Self {
            p,
            n,
            front: nudge(p, offset),
            back: nudge(p, -offset),
        }
    }

    /// [`offset_ray_origin`] of the point towards `w`.
    #[inline]
    pub fn towards(&self, w: Vec3) -> Vec3 {
        if w.dot(self.n) < 0.0 {
            self.back
        } else {
            self.front
        }
    }

    /// [`spawn_ray_to`] from the point to `q`.
    #[inline]
    pub fn spawn_ray_to(&self, q: Vec3, q_error: Vec3, n_q: Vec3) -> Ray {
        segment(self.towards(q - self.p), self.p, q, q_error, n_q)
    }
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
    segment(offset_ray_origin(p, p_error, n, q - p), p, q, q_error, n_q)
}

/// The segment of [`spawn_ray_to`] from the offset origin `o` of `p`.
#[inline]
fn segment(o: Vec3, p: Vec3, q: Vec3, q_error: Vec3, n_q: Vec3) -> Ray {
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

    /// The per-point origins against the per-ray functions, bit for bit: points from
    /// 1e-30 to 1e30 with and without error, unit and degenerate normals, directions
    /// on both sides, along the surface, zero and NaN.
    #[test]
    fn offset_origins_are_the_per_ray_offsets_bit_for_bit() {
        let mut next = crate::test_rng::xorshift64(0x9e37_79b9_7f4a_7c15);
        let mut unit = move || (next() >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0;
        let bits = |v: Vec3| v.to_array().map(f32::to_bits);
        let mut checked = 0;
        for s in [1e-30f32, 1e-6, 1.0, 1e6, 1e30] {
            for _ in 0..200 {
                let p = s * Vec3::new(unit(), unit(), unit());
                let err = gamma(7) * p.abs() * (unit() + 1.0);
                let n = Vec3::new(unit(), unit(), unit()).normalize_or_zero();
                let q = s * Vec3::new(unit(), unit(), unit());
                let nq = Vec3::new(unit(), unit(), unit()).normalize_or_zero();
                let origins = OffsetOrigins::new(p, err, n);
                let along = n.cross(Vec3::new(unit(), unit(), unit()));
                for w in [q - p, n, -n, along, Vec3::ZERO, Vec3::NAN] {
                    assert_eq!(
                        bits(origins.towards(w)),
                        bits(offset_ray_origin(p, err, n, w))
                    );
                }
                let a = origins.spawn_ray_to(q, err, nq);
                assert_eq!(a.bits(), spawn_ray_to(p, err, n, q, err, nq).bits());
                checked += 1;
            }
        }
        assert_eq!(checked, 1000);
        // The two origins lie on opposite sides of the point along n.
        let o = OffsetOrigins::new(Vec3::ONE, Vec3::splat(1e-6), Vec3::Y);
        assert!(o.towards(Vec3::Y).y > 1.0 && o.towards(-Vec3::Y).y < 1.0);
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
