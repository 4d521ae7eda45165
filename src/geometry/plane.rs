//! Infinite planes: a robust ray/plane test and the hit point with an error bound.
//!
//! A plane is the set `{x : n·(x - p0) = 0}` for the stored f32 point `p0` and unit
//! normal `n` (exactly those f32 values define it). The test evaluates the numerator
//! `n·(p0 - o)` and the denominator `n·d` with running error bounds (Higham, *Accuracy
//! and Stability of Numerical Algorithms*, §3.1: a dot product of length 3 whose terms
//! are themselves differences is within `γ5 Σ|n_i||p0_i - o_i|`) and reports a hit only
//! when both signs are certified: an origin inside the plane's rounding band, or a
//! direction parallel to the plane within rounding, is a miss. This is the plane's
//! counterpart of the triangle test's `t > δt` (pbrt-v4 §6.8.7): a ray leaving a point
//! on the plane (offset or not) can never re-hit it, whatever its direction.

use super::{Ray, gamma};
use glam::Vec3;

/// Distance `t` in the ray's open interval `(tmin, tmax)` at which `ray` crosses the
/// plane through `p0` with unit normal `n`, or `None` (see the module notes: an origin
/// within the rounding band of the plane, or a direction whose angle with the plane is
/// below rounding, is a miss). Invalid rays miss.
#[inline]
pub fn intersect_plane(p0: Vec3, n: Vec3, ray: &Ray) -> Option<f32> {
    if !ray.is_valid() {
        return None;
    }
    let (o, d) = (ray.origin, ray.dir);
    let diff = p0 - o;
    let num = n.x * diff.x + n.y * diff.y + n.z * diff.z;
    let num_err = gamma(5) * (n.abs().dot(diff.abs()));
    let den = n.x * d.x + n.y * d.y + n.z * d.z;
    let den_err = gamma(4) * (n.abs().dot(d.abs()));
    if num.abs() <= num_err || den.abs() <= den_err {
        return None;
    }
    let t = num / den;
    (t > ray.tmin && t < ray.tmax && t.is_finite()).then_some(t)
}

/// The hit point at distance `t` along `ray` on the plane `(p0, n)` and a per-component
/// bound on its distance from the plane (the box `p ± err` contains a plane point).
///
/// `o + t d` is projected back onto the plane, `p' = p - s n` with `s = n·(p - p0)`,
/// which removes the error of `t` (proportional to the ray's length) and leaves the
/// error of the projection: `|s - s*| <= γ5 Σ|n_i||p_i - p0_i|`, `|1 - |n|²| <= γ4` for
/// a normalised f32 vector, and the two roundings of each `p_i - s n_i`
/// (`γ2 (|p_i| + |s n_i|)`, seen along `n`). Their sum `δ` bounds the distance of `p'`
/// from the plane along `n`, so `p' ± δ` on every axis contains a plane point (each
/// coordinate moves by `δ |n_i| <= δ`).
pub fn plane_point(p0: Vec3, n: Vec3, ray: &Ray, t: f32) -> (Vec3, Vec3) {
    let p = ray.at(t);
    let diff = p - p0;
    let s = n.x * diff.x + n.y * diff.y + n.z * diff.z;
    let q = p - s * n;
    let na = n.abs();
    let delta = gamma(5) * na.dot(diff.abs())
        + gamma(4) * s.abs()
        + gamma(2) * na.dot(p.abs() + (s * n).abs());
    // One more γ for evaluating the bound itself.
    (q, Vec3::splat(delta * (1.0 + gamma(2))))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::offset_ray_origin;

    #[test]
    fn axis_plane_hit_at_the_analytic_distance() {
        // y = 2 from (0, 5, 0) straight down: t = 3 exactly.
        let r = Ray::new(Vec3::new(0.0, 5.0, 0.0), Vec3::new(0.0, -1.0, 0.0));
        assert_eq!(
            intersect_plane(Vec3::new(7.0, 2.0, -3.0), Vec3::Y, &r),
            Some(3.0)
        );
        // Pointing away, or ending before the plane: no hit.
        let up = Ray::new(r.origin, Vec3::Y);
        assert_eq!(
            intersect_plane(Vec3::new(0.0, 2.0, 0.0), Vec3::Y, &up),
            None
        );
        let short = Ray::segment(r.origin, r.dir, 0.0, 3.0);
        assert_eq!(
            intersect_plane(Vec3::new(0.0, 2.0, 0.0), Vec3::Y, &short),
            None
        );
        // Parallel: no hit.
        let flat = Ray::new(r.origin, Vec3::X);
        assert_eq!(
            intersect_plane(Vec3::new(0.0, 2.0, 0.0), Vec3::Y, &flat),
            None
        );
    }

    #[test]
    fn rays_leaving_a_tilted_far_plane_never_rehit_it() {
        // A tilted plane far from the origin; rays from random points on it, offset by
        // the point's bound, in random directions on both sides: zero re-hits.
        let n = Vec3::new(0.3, 0.8, -0.52).normalize();
        let p0 = Vec3::new(1.0e4, -2.5e3, 3.3e3);
        let mut next = crate::test_rng::xorshift64(0x2545_f491_4f6c_dd1du64);
        let mut rnd = || (next() >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0;
        let mut hits = 0;
        let mut on_plane = 0;
        let mut raw = 0;
        for _ in 0..20_000 {
            let o = p0 + Vec3::new(rnd(), rnd(), rnd()) * 1.0e3;
            let d = Vec3::new(rnd(), rnd(), rnd()) - Vec3::splat(0.001);
            let Some(t) = intersect_plane(p0, n, &Ray::new(o, d)) else {
                continue;
            };
            on_plane += 1;
            let (p, e) = plane_point(p0, n, &Ray::new(o, d), t);
            let w = Vec3::new(rnd(), rnd(), rnd());
            let origin = offset_ray_origin(p, e, n, w);
            hits += intersect_plane(p0, n, &Ray::new(origin, w)).is_some() as u32;
            // Without the offset the projected point may truly lie off the plane (by
            // up to its bound) and a ray towards the plane then rightly hits it: only
            // count the offset rays.
            raw += intersect_plane(p0, n, &Ray::new(p, w)).is_some() as u32;
        }
        eprintln!("rays from the unoffset points that re-hit: {raw} of {on_plane}");
        assert!(on_plane > 5_000, "only {on_plane} rays reached the plane");
        assert_eq!(hits, 0);
    }

    #[test]
    fn hit_point_bound_contains_the_plane_in_f64() {
        let n = Vec3::new(-0.2, 0.9, 0.38).normalize();
        let p0 = Vec3::new(3.0, -700.0, 25.0);
        let mut worst = 0.0f64;
        for k in 0..2000 {
            let f = |s: u32| ((k * 7919 + s * 104_729) % 2001) as f32 / 1000.0 - 1.0;
            let o = p0 + Vec3::new(f(1) * 500.0, 300.0 + f(2) * 100.0, f(3) * 500.0);
            let d = Vec3::new(f(4), -1.0, f(5));
            let r = Ray::new(o, d);
            let Some(t) = intersect_plane(p0, n, &r) else {
                continue;
            };
            let (p, e) = plane_point(p0, n, &r, t);
            let dist: f64 = (0..3)
                .map(|i| n[i] as f64 * (p[i] as f64 - p0[i] as f64))
                .sum::<f64>()
                .abs();
            // The box p ± e reaches the plane iff Σ|n_i| e_i >= dist.
            let reach: f64 = (0..3).map(|i| (n[i].abs() * e[i]) as f64).sum();
            assert!(dist <= reach, "distance {dist} beyond the bound {reach}");
            worst = worst.max(dist / reach);
        }
        assert!(
            worst > 0.0,
            "every projected point was exact: nothing was tested"
        );
    }
}
