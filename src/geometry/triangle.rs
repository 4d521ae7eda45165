use super::RayQuery;
use glam::{DVec3, Vec3};

/// Result of a ray/primitive test: distance and, for triangles, the barycentrics of
/// `v1` (`u`) and `v2` (`v`); zero for spheres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PrimHit {
    pub t: f32,
    pub u: f32,
    pub v: f32,
}

/// Watertight ray/triangle intersection (Woop, Benthin, Wald, JCGT 2013).
///
/// The vertices are translated to the ray origin, sheared so the ray becomes the +z
/// axis, and the 2D edge functions `U, V, W` decide inside/outside. Because each edge
/// function of a shared edge is computed from the same two projected vertices in the
/// same way, two triangles sharing an edge can never both reject a ray that crosses it:
/// no ray slips through a closed mesh. When an edge function is exactly zero the test
/// recomputes all three in f64, as the paper prescribes, so the sign on a shared edge is
/// consistent. Both faces are hit (no culling). The hit must lie in the open interval
/// `(tmin, tmax)`.
#[inline]
pub fn intersect_triangle(
    q: &RayQuery,
    v0: Vec3,
    v1: Vec3,
    v2: Vec3,
    tmax: f32,
) -> Option<PrimHit> {
    let (kx, ky, kz) = (q.kx, q.ky, q.kz);
    let a = v0 - q.origin;
    let b = v1 - q.origin;
    let c = v2 - q.origin;

    let ax = a[kx] - q.sx * a[kz];
    let ay = a[ky] - q.sy * a[kz];
    let bx = b[kx] - q.sx * b[kz];
    let by = b[ky] - q.sy * b[kz];
    let cx = c[kx] - q.sx * c[kz];
    let cy = c[ky] - q.sy * c[kz];

    let mut u = cx * by - cy * bx;
    let mut v = ax * cy - ay * cx;
    let mut w = bx * ay - by * ax;

    if u == 0.0 || v == 0.0 || w == 0.0 {
        let (ax, ay, bx, by, cx, cy) = (
            ax as f64, ay as f64, bx as f64, by as f64, cx as f64, cy as f64,
        );
        u = (cx * by - cy * bx) as f32;
        v = (ax * cy - ay * cx) as f32;
        w = (bx * ay - by * ax) as f32;
    }

    if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
        return None;
    }
    let det = u + v + w;
    if det == 0.0 || !det.is_finite() {
        return None;
    }

    let az = q.sz * a[kz];
    let bz = q.sz * b[kz];
    let cz = q.sz * c[kz];
    let t_scaled = u * az + v * bz + w * cz;

    let rcp = 1.0 / det;
    let t = t_scaled * rcp;
    // Strict interval test; NaN compares false and so misses.
    if t > q.tmin && t < tmax {
        Some(PrimHit {
            t,
            u: v * rcp,
            v: w * rcp,
        })
    } else {
        None
    }
}

/// The same test evaluated entirely in f64: the reference for error reports and tests.
pub fn intersect_triangle_f64(
    origin: DVec3,
    dir: DVec3,
    v0: DVec3,
    v1: DVec3,
    v2: DVec3,
) -> Option<f64> {
    let e1 = v1 - v0;
    let e2 = v2 - v0;
    let p = dir.cross(e2);
    let det = e1.dot(p);
    if det == 0.0 {
        return None;
    }
    let inv = 1.0 / det;
    let s = origin - v0;
    let u = s.dot(p) * inv;
    let qv = s.cross(e1);
    let v = dir.dot(qv) * inv;
    if u < 0.0 || v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = e2.dot(qv) * inv;
    (t > 0.0).then_some(t)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Ray;

    fn q(o: Vec3, d: Vec3) -> RayQuery {
        RayQuery::new(&Ray::new(o, d)).unwrap()
    }

    const V0: Vec3 = Vec3::new(0.0, 0.0, 0.0);
    const V1: Vec3 = Vec3::new(1.0, 0.0, 0.0);
    const V2: Vec3 = Vec3::new(0.0, 1.0, 0.0);

    #[test]
    fn analytic_hit_and_barycentrics() {
        let h = intersect_triangle(
            &q(Vec3::new(0.25, 0.5, 2.0), -Vec3::Z),
            V0,
            V1,
            V2,
            f32::INFINITY,
        )
        .unwrap();
        assert_eq!(h.t, 2.0);
        assert!((h.u - 0.25).abs() < 1e-6 && (h.v - 0.5).abs() < 1e-6);
        // from behind, both faces are hit
        let h = intersect_triangle(
            &q(Vec3::new(0.25, 0.25, -3.0), Vec3::Z),
            V0,
            V1,
            V2,
            f32::INFINITY,
        )
        .unwrap();
        assert_eq!(h.t, 3.0);
    }

    #[test]
    fn miss_outside_and_behind() {
        assert!(
            intersect_triangle(
                &q(Vec3::new(0.75, 0.75, 1.0), -Vec3::Z),
                V0,
                V1,
                V2,
                f32::INFINITY
            )
            .is_none()
        );
        assert!(
            intersect_triangle(
                &q(Vec3::new(0.25, 0.25, 1.0), Vec3::Z),
                V0,
                V1,
                V2,
                f32::INFINITY
            )
            .is_none()
        );
        // beyond tmax
        assert!(
            intersect_triangle(&q(Vec3::new(0.25, 0.25, 1.0), -Vec3::Z), V0, V1, V2, 0.5).is_none()
        );
    }

    #[test]
    fn shared_edge_is_watertight() {
        // Two triangles sharing the diagonal (1,0)-(0,1): rays on the diagonal hit at least one.
        let v3 = Vec3::new(1.0, 1.0, 0.0);
        for i in 0..=1000 {
            let s = i as f32 / 1000.0;
            let o = Vec3::new(s, 1.0 - s, 1.0);
            let d = Vec3::new(0.013, -0.007, -1.0);
            let qq = q(o - d * 0.0, d);
            let h1 = intersect_triangle(&qq, V0, V1, V2, f32::INFINITY);
            let h2 = intersect_triangle(&qq, V1, v3, V2, f32::INFINITY);
            let inside = o.x + 0.013 >= 0.0
                && o.y - 0.007 >= 0.0
                && o.x + 0.013 <= 1.0
                && o.y - 0.007 <= 1.0;
            if inside {
                assert!(
                    h1.is_some() || h2.is_some(),
                    "ray {i} slipped through the shared edge"
                );
            }
        }
    }

    #[test]
    fn axis_parallel_and_in_plane() {
        for d in [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y] {
            // a ray lying in the triangle's plane never reports a hit
            let h = intersect_triangle(
                &q(Vec3::new(0.2, 0.2, 0.0) - 3.0 * d, d),
                V0,
                V1,
                V2,
                f32::INFINITY,
            );
            assert!(h.is_none());
        }
        let h = intersect_triangle(
            &q(Vec3::new(0.1, 0.1, 5.0), Vec3::new(-0.0, 0.0, -1.0)),
            V0,
            V1,
            V2,
            f32::INFINITY,
        );
        assert!((h.unwrap().t - 5.0).abs() < 5.0 * 1e-6);
    }

    #[test]
    fn agrees_with_f64_reference() {
        let o = Vec3::new(0.3, 0.2, 7.0);
        let d = Vec3::new(-0.01, 0.02, -1.0).normalize();
        let h = intersect_triangle(&q(o, d), V0, V1, V2, f32::INFINITY).unwrap();
        let r = intersect_triangle_f64(
            o.as_dvec3(),
            d.as_dvec3(),
            V0.as_dvec3(),
            V1.as_dvec3(),
            V2.as_dvec3(),
        )
        .unwrap();
        assert!(((h.t as f64 - r) / r).abs() < 1e-6);
    }
}
