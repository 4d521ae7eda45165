use super::RayQuery;
use super::triangle::gamma;
use glam::Vec3;

/// Ray/sphere intersection, numerically stable (Haines, Günther, Akenine-Möller,
/// "Precision Improvements for Ray/Sphere Intersection", Ray Tracing Gems ch. 7).
///
/// The discriminant is computed from the distance of the centre to the ray line,
/// `r² - |f - (f·d/d·d) d|²`, which avoids the catastrophic cancellation of
/// `b² - 4ac` for small spheres far from the origin, and the two roots come from the
/// cancellation-free pair `c/q`, `q/a`. Returns the nearest root inside `(tmin, tmax)`.
#[inline]
pub fn intersect_sphere(q: &RayQuery, center: Vec3, radius: f32, tmax: f32) -> Option<f32> {
    let d = q.dir;
    let f = q.origin - center;
    let a = d.dot(d);
    let b = -f.dot(d);
    let l = f + (b / a) * d;
    let r2 = radius * radius;
    let disc = a * (r2 - l.dot(l));
    // NaN (degenerate input) fails the comparison and misses too.
    if disc.is_nan() || disc < 0.0 {
        return None;
    }
    let c = f.dot(f) - r2;
    let qq = b + disc.sqrt().copysign(b);
    if qq == 0.0 {
        // Ray origin at the centre with b = 0 and disc = 0 only for radius 0: no hit.
        return None;
    }
    let (mut t0, mut t1) = (c / qq, qq / a);
    if t0 > t1 {
        std::mem::swap(&mut t0, &mut t1);
    }
    if t0 > q.tmin && t0 < tmax {
        Some(t0)
    } else if t1 > q.tmin && t1 < tmax {
        Some(t1)
    } else {
        None
    }
}

/// A hit point on a sphere: `near` (e.g. `o + t d`, which carries the error of `t`
/// scaled by the ray length) reprojected onto the sphere as `center + radius n`,
/// `n = normalize(near - center)`, with a per-component bound on its distance from the
/// sphere: `γ(5) |radius n|` for the reprojection (pbrt-v4 §6.8.5) plus `γ(2) |p|` for
/// adding the centre. Returns `(p, p_error, n)`; `n` is zero if `near` is the centre.
#[inline]
pub fn sphere_point(center: Vec3, radius: f32, near: Vec3) -> (Vec3, Vec3, Vec3) {
    let n = (near - center).normalize_or_zero();
    let local = radius * n;
    let p = center + local;
    let err = gamma(5) * local.abs() + gamma(2) * p.abs();
    (p, err, n)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Ray;

    fn q(o: Vec3, d: Vec3) -> RayQuery {
        RayQuery::new(&Ray::new(o, d)).unwrap()
    }

    #[test]
    fn analytic_roots() {
        let t = intersect_sphere(
            &q(Vec3::new(0.0, 0.0, -5.0), Vec3::Z),
            Vec3::ZERO,
            1.0,
            f32::INFINITY,
        );
        assert_eq!(t, Some(4.0));
        // from inside: the far root
        let t = intersect_sphere(&q(Vec3::ZERO, Vec3::X), Vec3::ZERO, 2.0, f32::INFINITY);
        assert_eq!(t, Some(2.0));
        // unnormalised direction: t scales
        let t = intersect_sphere(
            &q(Vec3::new(0.0, 0.0, -5.0), 2.0 * Vec3::Z),
            Vec3::ZERO,
            1.0,
            f32::INFINITY,
        );
        assert_eq!(t, Some(2.0));
        // miss and behind
        assert!(
            intersect_sphere(
                &q(Vec3::new(0.0, 1.5, -5.0), Vec3::Z),
                Vec3::ZERO,
                1.0,
                f32::INFINITY
            )
            .is_none()
        );
        assert!(
            intersect_sphere(
                &q(Vec3::new(0.0, 0.0, 5.0), Vec3::Z),
                Vec3::ZERO,
                1.0,
                f32::INFINITY
            )
            .is_none()
        );
    }

    #[test]
    fn tiny_sphere_far_away_is_stable() {
        // The naive b² - 4ac loses all digits here.
        let c = Vec3::new(0.0, 0.0, 1.0e4);
        let t = intersect_sphere(&q(Vec3::ZERO, Vec3::Z), c, 1.0e-3, f32::INFINITY).unwrap();
        assert!((t - (1.0e4 - 1.0e-3)).abs() < 1.0e-3 * 0.05, "t = {t}");
    }
}
