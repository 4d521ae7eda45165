//! Error of the f32 intersection kernels against a double-precision reference.
//!
//! Each case places primitives at a scale and an offset (or makes them tiny, or aims
//! grazing rays at them), converts the exact f32 inputs to f64 and intersects them
//! again with [`intersect_triangle_f64`] / [`intersect_sphere_f64`]. Since the inputs
//! are identical, the difference is the kernels' own rounding error. Reported per
//! kernel: the scalar reference (brute force), the BVH4 single-ray SIMD kernel and the
//! BVH4 16-ray packet kernel, for
//! - `t`: relative error and error in f32 ulps of the exact distance;
//! - the hit point `o + t d` (what a naive integrator would use) and the barycentric
//!   reconstruction `w a + u b + v c` the Whitted integrator uses, as absolute error
//!   relative to the primitive's size and in ulps of the largest coordinate of the
//!   point or the ray origin (the resolution f32 offers that computation).

use crate::accel::{Accel, AccelKind, Primitives, Spheres, Triangles};
use crate::geometry::{Hit, Ray, intersect_triangle_f64};
use glam::{DVec3, Vec3};
use serde::Serialize;

/// One line of the table: one case, one kernel.
#[derive(Clone, Debug, Serialize)]
pub struct PrecisionRow {
    pub case: String,
    pub kernel: &'static str,
    /// Rays the f64 reference hits.
    pub rays: usize,
    /// Rays where f32 and f64 disagree on hit or miss (edge and grazing cases).
    pub hit_mismatches: usize,
    pub t_rel_max: f64,
    pub t_rel_mean: f64,
    pub t_ulp_max: f64,
    pub t_ulp_mean: f64,
    /// |o + t d - p_exact| / size.
    pub p_ray_rel_max: f64,
    /// The same in ulps of the largest coordinate of the point or the ray origin.
    pub p_ray_ulp_max: f64,
    /// Barycentric reconstruction (triangles only; spheres: centre + r n): / size.
    pub p_bary_rel_max: f64,
    pub p_bary_ulp_max: f64,
}

/// A case: a primitive set, rays, and the size the point errors are relative to.
pub struct PrecisionCase {
    pub name: String,
    pub prims: CasePrims,
    pub rays: Vec<Ray>,
    pub size: f64,
}

pub enum CasePrims {
    Triangles(Triangles),
    Spheres(Spheres),
}

/// The ray/sphere test in f64 (the textbook quadratic, safe in double precision for
/// the f32 inputs used here): nearest root with `t > 0`.
pub fn intersect_sphere_f64(origin: DVec3, dir: DVec3, center: DVec3, radius: f64) -> Option<f64> {
    let f = origin - center;
    let a = dir.dot(dir);
    let b = -f.dot(dir);
    // Distance of the centre to the line, squared, as in the f32 kernel, but in f64.
    let l = f + (b / a) * dir;
    let disc = a * (radius * radius - l.dot(l));
    if disc < 0.0 {
        return None;
    }
    let c = f.dot(f) - radius * radius;
    let q = b + disc.sqrt().copysign(b);
    if q == 0.0 {
        return None;
    }
    let (t0, t1) = {
        let (x, y) = (c / q, q / a);
        (x.min(y), x.max(y))
    };
    if t0 > 0.0 {
        Some(t0)
    } else if t1 > 0.0 {
        Some(t1)
    } else {
        None
    }
}

/// splitmix64, so the cases are the same on every run.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> f32 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
    }
    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.next()
    }
    fn unit(&mut self) -> Vec3 {
        let z = self.range(-1.0, 1.0);
        let phi = self.range(0.0, std::f32::consts::TAU);
        let r = (1.0 - z * z).max(0.0).sqrt();
        Vec3::new(r * phi.cos(), r * phi.sin(), z)
    }
}

/// Random triangles of size `s` around `offset`, and `n` rays from distance `3 s`
/// aimed at random interior points; `grazing` tilts the rays to within about 1e-3
/// radians of each triangle's plane.
pub fn triangle_case(
    name: &str,
    s: f32,
    offset: Vec3,
    n: usize,
    grazing: bool,
    seed: u64,
) -> PrecisionCase {
    let mut rng = Rng(seed);
    let mut corners = Vec::new();
    let mut rays = Vec::new();
    for _ in 0..n {
        let c = offset + s * 0.5 * rng.unit();
        let tri = [
            c + s * 0.5 * rng.unit(),
            c + s * 0.5 * rng.unit(),
            c + s * 0.5 * rng.unit(),
        ];
        let (u, v) = (rng.range(0.1, 0.45), rng.range(0.1, 0.45));
        let target = tri[0] + u * (tri[1] - tri[0]) + v * (tri[2] - tri[0]);
        let from = if grazing {
            let nrm = (tri[1] - tri[0]).cross(tri[2] - tri[0]).normalize();
            let along = (tri[1] - tri[0]).normalize();
            target - 3.0 * s * (along + 1e-3 * nrm).normalize()
        } else {
            target + 3.0 * s * rng.unit()
        };
        rays.push(Ray::new(from, target - from));
        corners.push(tri);
    }
    PrecisionCase {
        name: name.to_string(),
        // One triangle per ray: ray i is measured against its own triangle.
        prims: CasePrims::Triangles(Triangles::from_corners(&corners)),
        rays,
        size: s as f64,
    }
}

/// Spheres of radius `r` around `offset`, rays from distance `dist` aimed inside, or
/// from `origin` where given.
pub fn sphere_case(
    name: &str,
    r: f32,
    dist: f32,
    offset: Vec3,
    origin: Option<Vec3>,
    n: usize,
    seed: u64,
) -> PrecisionCase {
    let mut rng = Rng(seed);
    let mut spheres = Spheres::default();
    let mut rays = Vec::new();
    for _ in 0..n {
        let c = offset + r * rng.unit();
        let target = c + 0.9 * r * rng.unit();
        let from = origin.unwrap_or(target + dist * rng.unit());
        spheres.center.push(c);
        spheres.radius.push(r);
        rays.push(Ray::new(from, target - from));
    }
    PrecisionCase {
        name: name.to_string(),
        prims: CasePrims::Spheres(spheres),
        rays,
        size: r as f64,
    }
}

/// The cases of the report: scales 1e-6..1e6, offsets up to 1e7, grazing rays, tiny
/// triangles far away, tiny spheres far away. `n` rays each.
pub fn standard_cases(n: usize) -> Vec<PrecisionCase> {
    let mut v = Vec::new();
    for s in [1e-6f32, 1e-3, 1.0, 1e3, 1e6] {
        v.push(triangle_case(
            &format!("tri s={s:e}"),
            s,
            Vec3::ZERO,
            n,
            false,
            1,
        ));
    }
    for (s, off) in [(1.0f32, 1e3f32), (1.0, 1e5), (1e3, 1e7), (1e6, 1e7)] {
        v.push(triangle_case(
            &format!("tri s={s:e} off={off:e}"),
            s,
            Vec3::new(off, -0.5 * off, 0.25 * off),
            n,
            false,
            2,
        ));
    }
    v.push(triangle_case(
        "tri grazing 1e-3 rad",
        1.0,
        Vec3::ZERO,
        n,
        true,
        3,
    ));
    v.push(triangle_case(
        "tri tiny 1e-4 at 1e2",
        1e-4,
        Vec3::splat(1e2),
        n,
        false,
        4,
    ));
    v.push(sphere_case("sphere r=1", 1.0, 3.0, Vec3::ZERO, None, n, 5));
    v.push(sphere_case(
        "sphere r=1e-6",
        1e-6,
        3e-6,
        Vec3::ZERO,
        None,
        n,
        6,
    ));
    v.push(sphere_case(
        "sphere r=1e6 off=1e7",
        1e6,
        3e6,
        Vec3::splat(1e7),
        None,
        n,
        7,
    ));
    // Tiny and far: the case of Haines et al.; the origin at 0, the sphere 1e5 and 1e7
    // radii away. At 1e7 (beyond 1/eps) the distance of the centre to the ray line can
    // no longer be resolved to a fraction of the radius in f32.
    for (d, seed) in [(1e2f32, 10), (1e4, 8)] {
        let far = d * Vec3::new(1.0, 0.2, -0.3);
        let name = format!("sphere r=1e-3 at {d:e}");
        v.push(sphere_case(
            &name,
            1e-3,
            0.0,
            far,
            Some(Vec3::ZERO),
            n,
            seed,
        ));
    }
    // The limit: an origin 1e4 away whose coordinates are not round. `o - c` in f32
    // already rounds by ulp(1e4) ~ 1e-3, the radius itself.
    v.push(sphere_case(
        "sphere r=1e-3 o 1e4 away",
        1e-3,
        1e4,
        Vec3::ZERO,
        None,
        n,
        9,
    ));
    v
}

/// Ray `i` against primitive `i` only: every kernel sees one primitive per ray (rays
/// are traced against the full set, but each targets its own primitive; hits on
/// another primitive are counted as mismatches).
fn reference(case: &PrecisionCase, i: usize) -> Option<(f64, DVec3)> {
    let r = &case.rays[i];
    let (o, d) = (r.origin.as_dvec3(), r.dir.as_dvec3());
    let t = match &case.prims {
        CasePrims::Triangles(t) => intersect_triangle_f64(
            o,
            d,
            t.v0[i].as_dvec3(),
            t.v1[i].as_dvec3(),
            t.v2[i].as_dvec3(),
        )?,
        CasePrims::Spheres(s) => {
            intersect_sphere_f64(o, d, s.center[i].as_dvec3(), s.radius[i] as f64)?
        }
    };
    Some((t, o + t * d))
}

fn ulp(x: f64) -> f64 {
    let x = (x.abs() as f32).max(f32::MIN_POSITIVE);
    (x.next_up() - x) as f64
}

/// Measures one case through every kernel.
pub fn measure(case: &PrecisionCase) -> Vec<PrecisionRow> {
    // Each ray is traced against its own primitive alone, so that neighbours never
    // hide the primitive being measured.
    let single = |i: usize| -> Box<dyn Accel> {
        match &case.prims {
            CasePrims::Triangles(t) => AccelKind::Bvh4.build(t.permute(&[i as u32])),
            CasePrims::Spheres(s) => AccelKind::Bvh4.build(s.permute(&[i as u32])),
        }
    };
    let scalar = |i: usize| -> Option<Hit> {
        let q = crate::geometry::RayQuery::new(&case.rays[i])?;
        let h = match &case.prims {
            CasePrims::Triangles(t) => t.intersect(i, &q, q.tmax)?,
            CasePrims::Spheres(s) => s.intersect(i, &q, q.tmax)?,
        };
        Some(Hit {
            t: h.t,
            prim: i as u32,
            u: h.u,
            v: h.v,
        })
    };
    let n = case.rays.len();
    let mut results: Vec<(&'static str, Vec<Option<Hit>>)> = vec![
        ("scalar", (0..n).map(scalar).collect()),
        ("bvh4-single", Vec::with_capacity(n)),
        ("bvh4-packet", Vec::with_capacity(n)),
    ];
    for i in 0..n {
        let accel = single(i);
        results[1]
            .1
            .push(accel.closest_hit(&case.rays[i]).map(|h| Hit {
                prim: i as u32,
                ..h
            }));
        // A packet of 16 copies of the ray: the packet kernel's answer for it.
        let packet = [case.rays[i]; crate::simd::PACKET_WIDTH];
        let mut out = [None; crate::simd::PACKET_WIDTH];
        accel.closest_hit_batch(&packet, &mut out);
        results[2].1.push(out[0].map(|h| Hit {
            prim: i as u32,
            ..h
        }));
    }
    let refs: Vec<_> = (0..n).map(|i| reference(case, i)).collect();
    results
        .into_iter()
        .map(|(kernel, hits)| {
            let mut row = PrecisionRow {
                case: case.name.clone(),
                kernel,
                rays: 0,
                hit_mismatches: 0,
                t_rel_max: 0.0,
                t_rel_mean: 0.0,
                t_ulp_max: 0.0,
                t_ulp_mean: 0.0,
                p_ray_rel_max: 0.0,
                p_ray_ulp_max: 0.0,
                p_bary_rel_max: 0.0,
                p_bary_ulp_max: 0.0,
            };
            for (i, (h, r)) in hits.iter().zip(&refs).enumerate() {
                let (h, (t64, p64)) = match (h, r) {
                    (Some(h), Some(r)) => (h, *r),
                    (None, None) => continue,
                    _ => {
                        row.hit_mismatches += 1;
                        continue;
                    }
                };
                row.rays += 1;
                let dt = (h.t as f64 - t64).abs();
                let rel = dt / t64;
                let ulps = dt / ulp(t64);
                row.t_rel_max = row.t_rel_max.max(rel);
                row.t_rel_mean += rel;
                row.t_ulp_max = row.t_ulp_max.max(ulps);
                row.t_ulp_mean += ulps;
                let ray = &case.rays[i];
                let p_ray = (ray.origin + h.t * ray.dir).as_dvec3();
                let p_bary = match &case.prims {
                    CasePrims::Triangles(t) => {
                        ((1.0 - h.u - h.v) * t.v0[i] + h.u * t.v1[i] + h.v * t.v2[i]).as_dvec3()
                    }
                    CasePrims::Spheres(s) => {
                        let nrm = (ray.origin + h.t * ray.dir - s.center[i]).normalize_or_zero();
                        (s.center[i] + s.radius[i] * nrm).as_dvec3()
                    }
                };
                // ulps of the largest coordinate the computation saw (point or origin).
                let pu = ulp(p64
                    .abs()
                    .max_element()
                    .max(ray.origin.abs().max_element() as f64));
                let e_ray = (p_ray - p64).length();
                let e_bary = (p_bary - p64).length();
                row.p_ray_rel_max = row.p_ray_rel_max.max(e_ray / case.size);
                row.p_ray_ulp_max = row.p_ray_ulp_max.max(e_ray / pu);
                row.p_bary_rel_max = row.p_bary_rel_max.max(e_bary / case.size);
                row.p_bary_ulp_max = row.p_bary_ulp_max.max(e_bary / pu);
            }
            if row.rays > 0 {
                row.t_rel_mean /= row.rays as f64;
                row.t_ulp_mean /= row.rays as f64;
            }
            row
        })
        .collect()
}

pub fn table_header() -> String {
    format!(
        "{:<26} {:<12} {:>6} {:>5} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9}",
        "case",
        "kernel",
        "rays",
        "miss",
        "t rel max",
        "t rel avg",
        "t ulp max",
        "t ulp avg",
        "p(t) /sz",
        "p(t) ulp",
        "p(uv) /sz",
        "p(uv) ulp"
    )
}

pub fn table_row(r: &PrecisionRow) -> String {
    format!(
        "{:<26} {:<12} {:>6} {:>5} {:>9.2e} {:>9.2e} {:>9.1} {:>9.2} {:>9.2e} {:>9.1} {:>9.2e} {:>9.1}",
        r.case,
        r.kernel,
        r.rays,
        r.hit_mismatches,
        r.t_rel_max,
        r.t_rel_mean,
        r.t_ulp_max,
        r.t_ulp_mean,
        r.p_ray_rel_max,
        r.p_ray_ulp_max,
        r.p_bary_rel_max,
        r.p_bary_ulp_max
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The bounds docs/robustness.md states, on a small run of the well-conditioned cases:
    /// f32 and f64 agree on every hit, mean error of t at most 4 ulps, max relative error
    /// of t at most 1e-4 (randomly oriented triangles include near-edge-on ones), and all
    /// three kernels give identical answers.
    #[test]
    fn f32_kernels_stay_within_the_stated_bounds() {
        let cases = [
            triangle_case("tri", 1.0, Vec3::ZERO, 300, false, 1),
            triangle_case("tri far", 1e3, Vec3::splat(1e6), 300, false, 2),
            sphere_case("sphere", 1.0, 3.0, Vec3::ZERO, None, 300, 3),
            sphere_case(
                "tiny far sphere",
                1e-3,
                0.0,
                Vec3::splat(1e2),
                Some(Vec3::ZERO),
                300,
                4,
            ),
        ];
        for case in &cases {
            let rows = measure(case);
            for r in &rows {
                assert!(r.rays > 250, "{}: {} rays measured", r.case, r.rays);
                assert_eq!(r.hit_mismatches, 0, "{}/{}", r.case, r.kernel);
                assert!(
                    r.t_ulp_mean <= 4.0,
                    "{}/{}: {}",
                    r.case,
                    r.kernel,
                    r.t_ulp_mean
                );
                assert!(
                    r.t_rel_max <= 1e-4,
                    "{}/{}: {}",
                    r.case,
                    r.kernel,
                    r.t_rel_max
                );
            }
            for r in &rows[1..] {
                assert_eq!(
                    r.t_rel_max, rows[0].t_rel_max,
                    "{}: {} differs from scalar",
                    r.case, r.kernel
                );
            }
        }
    }

    #[test]
    fn f64_sphere_reference() {
        let t = intersect_sphere_f64(DVec3::new(0.0, 0.0, -5.0), DVec3::Z, DVec3::ZERO, 1.0);
        assert_eq!(t, Some(4.0));
        assert_eq!(
            intersect_sphere_f64(DVec3::ZERO, DVec3::X, DVec3::ZERO, 2.0),
            Some(2.0)
        );
        assert!(
            intersect_sphere_f64(DVec3::new(0.0, 2.0, -5.0), DVec3::Z, DVec3::ZERO, 1.0).is_none()
        );
    }
}
