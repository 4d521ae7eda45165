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

/// `γ(n) = n u / (1 - n u)` with `u = f32::EPSILON / 2`, the unit roundoff: the bound
/// on the relative error of `n` successive f32 roundings (Higham, "Accuracy and
/// Stability of Numerical Algorithms", §3.1; pbrt-v4 §6.8.1).
pub const fn gamma(n: u32) -> f32 {
    let nu = n as f32 * (f32::EPSILON * 0.5);
    nu / (1.0 - nu)
}

/// Constants of the triangle test's error bounds (pbrt-v4 §6.8.7, "Conservative
/// Ray-Triangle t Tests", adapted to this kernel's order of operations).
pub(crate) mod err {
    use super::gamma;
    /// Shear: `x' = (v_x - o_x) - s_x (v_z - o_z)` with `s_x = d_x (1 / d_z)` carries
    /// two roundings in `s_x`, one in the translation, one in the product and one in
    /// the difference; `|s_x| <= 1`, so `|x' - x'*| <= γ(6)(|v_x - o_x| + |v_z - o_z|)
    /// <= γ(7)(max|x'| + 2 max|z|)` (one more γ for evaluating the bound itself).
    pub const SHEAR: f32 = gamma(7);
    /// The products and the difference of an edge function.
    pub const EDGE: f32 = gamma(2);
    /// The scaled depths `s_z z` and the sum `t_scaled`.
    pub const DEPTH: f32 = gamma(3);
}

/// Watertight ray/triangle intersection (Woop, Benthin, Wald, JCGT 2013), with the
/// conservative error bounds of pbrt-v4 (Pharr, Jakob, Humphreys, §6.8.7).
///
/// The vertices are translated to the ray origin, sheared so the ray becomes the +z
/// axis, and the 2D edge functions `U, V, W` decide inside/outside. Because each edge
/// function of a shared edge is computed from the same two projected vertices in the
/// same way, two triangles sharing an edge can never both reject a ray that crosses it:
/// no ray slips through a closed mesh. Both faces are hit (no culling). The hit must lie
/// in the open interval `(tmin, tmax)`.
///
/// Precision, three deviations from the paper's f32 test:
/// - **Uncertain edges in f64.** An edge function whose f32 value lies within its
///   error bound `δE` of zero (the paper's exactly-zero case included) may have the
///   wrong sign: far from the origin or at grazing angles the shear alone (rounding of
///   `d_x / d_z` and of `s_x z`) moves a projected corner by more than the projected
///   triangle is wide, and a ray aimed at a triangle's centroid reported its neighbour.
///   Then all three edges are recomputed in f64 from the exactly translated corners
///   with the f64 shear `d_x / d_z`, which resolves them unless the ray passes within
///   ~1e-15 relative of an edge. The recomputation of an edge reads only its two
///   corners and the ray, so a shared edge gives both triangles the same (negated)
///   value; a certified f32 sign equals the exact sign, so a neighbour that kept f32
///   for the shared edge agrees too (barring an exact value below the f64 noise).
/// - **Exact division.** `t = t_scaled / det` is one correctly rounded quotient;
///   `t_scaled * (1 / det)` rounded twice and came out one ulp short, so a segment
///   whose `tmax` was exactly the hit distance reported the surface.
/// - **Conservative `t > 0`.** A hit with `t <= δt`, the error bound of `t`, is
///   rejected (pbrt-v4): an origin lying on the surface (an offset of zero along an
///   exactly axis-aligned normal) cannot re-hit it with a rounding-positive `t`.
///
/// The SIMD twins in `simd::kernels` evaluate the same expressions in the same order
/// and hand every lane with an uncertain edge to this function.
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
    let (a_z, b_z, c_z) = (a[kz], b[kz], c[kz]);

    let ax = a[kx] - q.sx * a_z;
    let ay = a[ky] - q.sy * a_z;
    let bx = b[kx] - q.sx * b_z;
    let by = b[ky] - q.sy * b_z;
    let cx = c[kx] - q.sx * c_z;
    let cy = c[ky] - q.sy * c_z;

    let mut u = cx * by - cy * bx;
    let mut v = ax * cy - ay * cx;
    let mut w = bx * ay - by * ax;

    let mut delta_e = edge_error_bound(ax, ay, bx, by, cx, cy, a_z, b_z, c_z);
    if u.abs() <= delta_e || v.abs() <= delta_e || w.abs() <= delta_e {
        // All three, as Woop et al. do for their exactly-zero case: then `t` and its
        // bound rest on f64 edges only. Their error: the same bound in f64 units
        // (`2^-29` of it, `2^-27` with slack) plus the final rounding to f32.
        [u, v, w] = edges_f64(q, v0, v1, v2);
        let max_e = u.abs().max(v.abs()).max(w.abs());
        delta_e = gamma(1) * max_e + delta_e * F64_BOUND_RATIO;
    }

    if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
        return None;
    }
    let det = u + v + w;
    if det == 0.0 || !det.is_finite() {
        return None;
    }

    let az = q.sz * a_z;
    let bz = q.sz * b_z;
    let cz = q.sz * c_z;
    let t_scaled = u * az + v * bz + w * cz;
    let t = t_scaled / det;
    // Strict interval test; NaN compares false and so misses.
    if !(t > q.tmin && t < tmax) {
        return None;
    }
    let rcp = 1.0 / det;
    // As the SIMD twin's mask `t > δt`: a NaN bound rejects.
    let certain = t > t_error_bound(u, v, w, az, bz, cz, delta_e, rcp);
    if !certain {
        return None;
    }
    Some(PrimHit {
        t,
        u: v * rcp,
        v: w * rcp,
    })
}

/// Ratio of the f64 to the f32 unit roundoff (`2^-29`), times 4 for slack.
const F64_BOUND_RATIO: f32 = 1.0 / (1u64 << 27) as f32;

/// `δE`: bound on the error of an f32 edge function against the same function of the
/// exactly translated, exactly sheared corners (pbrt-v4 eq. 6.31, with the shear bound
/// of [`err::SHEAR`]): `2 (γ2 X Y + δy X + δx Y)`, `X, Y` the largest projected
/// coordinates, `δx = SHEAR (X + 2 Z)`, `Z` the largest translated depth.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn edge_error_bound(
    ax: f32,
    ay: f32,
    bx: f32,
    by: f32,
    cx: f32,
    cy: f32,
    a_z: f32,
    b_z: f32,
    c_z: f32,
) -> f32 {
    let max_x = ax.abs().max(bx.abs()).max(cx.abs());
    let max_y = ay.abs().max(by.abs()).max(cy.abs());
    let max_z = a_z.abs().max(b_z.abs()).max(c_z.abs());
    let two_z = max_z + max_z;
    let delta_x = err::SHEAR * (max_x + two_z);
    let delta_y = err::SHEAR * (max_y + two_z);
    2.0 * (err::EDGE * max_x * max_y + delta_y * max_x + delta_x * max_y)
}

/// `δt`: bound on the error of `t` (pbrt-v4 eq. 6.32): `3 (γ3 E Zt + δE Zt + δz E) /
/// |det|`, `E` the largest edge function, `Zt` the largest scaled depth.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn t_error_bound(u: f32, v: f32, w: f32, az: f32, bz: f32, cz: f32, delta_e: f32, rcp: f32) -> f32 {
    let max_zt = az.abs().max(bz.abs()).max(cz.abs());
    let max_e = u.abs().max(v.abs()).max(w.abs());
    let delta_z = err::DEPTH * max_zt;
    3.0 * (err::DEPTH * max_e * max_zt + delta_e * max_zt + delta_z * max_e) * rcp.abs()
}

/// The three edge functions in f64 from the exactly translated corners (a difference
/// of two f32 values is exact in f64) sheared with the f64 ratios `d_x / d_z`,
/// `d_y / d_z`, rounded to f32. Each value reads only its edge's two corners.
#[cold]
#[inline(never)]
fn edges_f64(q: &RayQuery, v0: Vec3, v1: Vec3, v2: Vec3) -> [f32; 3] {
    let (kx, ky, kz) = (q.kx, q.ky, q.kz);
    let (o, d) = (q.origin.as_dvec3(), q.dir.as_dvec3());
    let (sx, sy) = (d[kx] / d[kz], d[ky] / d[kz]);
    let proj = |p: Vec3| {
        let r = p.as_dvec3() - o;
        (r[kx] - sx * r[kz], r[ky] - sy * r[kz])
    };
    let (ax, ay) = proj(v0);
    let (bx, by) = proj(v1);
    let (cx, cy) = proj(v2);
    [
        (cx * by - cy * bx) as f32,
        (ax * cy - ay * cx) as f32,
        (bx * ay - by * ax) as f32,
    ]
}

/// The point at barycentrics `(u, v)` of the triangle `[p0, p1, p2]`, as
/// `(1 - u - v) p0 + u p1 + v p2`, and a per-component bound on its distance from the
/// triangle's plane: `γ(7) (|b0 p0| + |b1 p1| + |b2 p2|)` for the interpolation (pbrt-v4
/// eq. 6.30) plus `γ(3) (1 + |u| + |v|) |p0|` because `b0 = 1 - u - v` is rounded, so
/// the weights may not sum to exactly one.
#[inline]
pub fn triangle_point([p0, p1, p2]: [Vec3; 3], u: f32, v: f32) -> (Vec3, Vec3) {
    let b0 = 1.0 - u - v;
    let p = b0 * p0 + u * p1 + v * p2;
    let sum = (b0 * p0).abs() + (u * p1).abs() + (v * p2).abs();
    let err = gamma(7) * sum + (gamma(3) * (1.0 + u.abs() + v.abs())) * p0.abs();
    (p, err)
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
        // Two triangles sharing the diagonal (1,0)-(0,1). Each ray passes exactly
        // through a point of the diagonal: `e = (s, 1 - s, 0)` with dyadic `s`, the
        // direction dyadic too, so `o = e - d` is exact and the ray meets the plane
        // at `e` itself. At least one triangle must report it, at the same `t` if both do.
        let v3 = Vec3::new(1.0, 1.0, 0.0);
        let dirs = [
            Vec3::new(0.0, 0.0, -1.0),
            Vec3::new(0.015625, -0.0078125, -1.0),
            Vec3::new(-0.5, 0.25, -1.0),
            Vec3::new(3.0, -1.0, -0.125),
            Vec3::new(-0.75, -0.75, 0.5),
        ];
        let mut on_edge = 0;
        for i in 1..1024 {
            let s = i as f32 / 1024.0;
            let e = Vec3::new(s, 1.0 - s, 0.0);
            assert_eq!(e.x + e.y, 1.0, "edge point {e} not exact");
            for d in dirs {
                let o = e - d;
                assert_eq!(o + d, e, "origin {o} not exact");
                let qq = q(o, d);
                let h1 = intersect_triangle(&qq, V0, V1, V2, f32::INFINITY);
                let h2 = intersect_triangle(&qq, V1, v3, V2, f32::INFINITY);
                match (h1, h2) {
                    (None, None) => {
                        panic!("ray {o} + t {d} slipped through the shared edge at {e}")
                    }
                    (Some(a), Some(b)) => assert_eq!(a.t, b.t),
                    _ => {}
                }
                on_edge += 1;
            }
        }
        assert_eq!(on_edge, 1023 * dirs.len());
    }

    #[test]
    fn uncertain_edges_are_resolved_in_f64() {
        // A grazing ray from far away at a thin triangle: the f32 shear moves the
        // projected corners by more than the triangle's projected width, so some edge
        // functions fall within their error bound and are recomputed in f64; the
        // answer must equal the f64 reference's hit/miss.
        let (v0, v1, v2) = (
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
        );
        let mut agree = 0;
        for k in 0..2000 {
            let f = k as f32 / 2000.0;
            let target = Vec3::new(0.2 + 0.6 * f, 0.5 - 0.6 * f, 0.0);
            let o = target + 1e3 * Vec3::new(0.6, 0.8, 2e-4).normalize();
            let d = target - o;
            // Where the exact f32 ray meets the plane z = 0, in f64 (exact enough).
            let (od, dd) = (o.as_dvec3(), d.as_dvec3());
            let p = od + (-od.z / dd.z) * dd;
            let margin = p.x.min(p.y).min(1.0 - p.x - p.y);
            let h = intersect_triangle(&q(o, d), v0, v1, v2, f32::INFINITY);
            // Away from every edge by more than f64 noise, the sign is certain.
            if margin.abs() > 1e-9 {
                assert_eq!(h.is_some(), margin > 0.0, "ray {k} at {p}");
                agree += 1;
            }
        }
        assert!(agree > 1900);
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
