//! Robustness, part 3: floating-point error bounds. Hit points carry a bound on their
//! rounding error and every secondary ray is offset by it (pbrt-v4's `Point3fi` and
//! `OffsetRayOrigin`), shadow segments end at their offset target, `t` is a correctly
//! rounded quotient, and edge functions whose sign f32 cannot certify are redone in
//! f64. Every check runs on every structure and every path (single ray and packets).

use crate::common;
use crate::robust;

use common::Rng;
use glam::{DVec3, Quat, Vec3};
use packet_render::accel::{Accel, BruteForce, MovingTriangles, Primitives, Spheres, Triangles};
use packet_render::geometry::{Hit, Ray, intersect_triangle_f64};
use robust::*;

// RULE BEGIN: the renderer's rules for hit points and secondary rays.
/// Hit point on a triangle and its error bound, as `SurfaceInteraction::new`.
fn tri_point(c: [Vec3; 3], u: f32, v: f32) -> (Vec3, Vec3) {
    packet_render::geometry::triangle_point(c, u, v)
}
/// Hit point on a sphere and its error bound, as `SurfaceInteraction::new`.
fn sph_point(center: Vec3, radius: f32, near: Vec3) -> (Vec3, Vec3, Vec3) {
    packet_render::geometry::sphere_point(center, radius, near)
}
/// A secondary ray origin leaving into `w`, as `Shader::shade_emit`.
fn leave(p: Vec3, err: Vec3, n: Vec3, w: Vec3) -> Vec3 {
    packet_render::geometry::offset_ray_origin(p, err, n, w)
}
/// A shadow segment between two surface points, as `Shader::direct` for area lights.
fn segment_to(p: Vec3, pe: Vec3, n: Vec3, q: Vec3, qe: Vec3, nq: Vec3) -> Ray {
    packet_render::geometry::spawn_ray_to(p, pe, n, q, qe, nq)
}
// RULE END

/// pbrt's `pExp`: 10^U(-8, 8).
fn p_exp(rng: &mut Rng) -> f32 {
    10f32.powf(rng.range(-8.0, 8.0))
}

fn corners_of(t: &Triangles, i: usize) -> [Vec3; 3] {
    [t.v0[i], t.v1[i], t.v2[i]]
}

/// Counts, per path, the rays that hit anything (closest and any-hit queries), and
/// reports the paths with any.
fn count_hits(
    accels: &[(packet_render::accel::AccelKind, Box<dyn Accel>)],
    rays: &[Ray],
) -> Vec<(String, usize)> {
    let mut out = Vec::new();
    for (path, hits) in closest_all(accels, rays) {
        out.push((
            format!("{path}/closest"),
            hits.iter().filter(|h| h.is_some()).count(),
        ));
    }
    for (path, occ) in any_all(accels, rays) {
        out.push((format!("{path}/any"), occ.iter().filter(|o| **o).count()));
    }
    out
}

/// pbrt-v4's `Triangle, Reintersect` setup: random triangles with coordinates
/// 10^U(-8,8), a ray from a random origin to a random point of the triangle; from the
/// hit, rays in random directions and rays to random points with `tmax = 1`. None may
/// re-hit the triangle. 100 triangles x 1,000 rays (pbrt: 1,000 x 1,000 + 1,000).
#[test]
fn triangle_reintersect_at_every_magnitude() {
    let mut report = Vec::new();
    let (mut traced, mut triangles, mut confirmed) = (0, 0, 0);
    for seed in 0..200u64 {
        if triangles == 100 {
            break;
        }
        let mut rng = Rng(1000 + seed);
        let c: [Vec3; 3] =
            std::array::from_fn(|_| Vec3::new(p_exp(&mut rng), p_exp(&mut rng), p_exp(&mut rng)));
        if (c[1] - c[0]).cross(c[2] - c[0]).length_squared() < 1e-20 {
            continue;
        }
        let tris = Triangles::from_corners(&[c]);
        let (mut u, mut v) = (rng.f32(), rng.f32());
        if u + v > 1.0 {
            (u, v) = (1.0 - u, 1.0 - v);
        }
        let target = (1.0 - u - v) * c[0] + u * c[1] + v * c[2];
        let o = Vec3::new(p_exp(&mut rng), p_exp(&mut rng), p_exp(&mut rng));
        let Some(h) = BruteForce::new(tris.clone()).closest_hit(&Ray::new(o, target - o)) else {
            continue;
        };
        triangles += 1;
        let (p, err) = tri_point(c, h.u, h.v);
        let n = normal(&tris, 0);
        let mut rays = Vec::new();
        for _ in 0..500 {
            let w = rng.unit_vector();
            rays.push(Ray::new(leave(p, err, n, w), w));
        }
        for _ in 0..500 {
            let to = Vec3::new(p_exp(&mut rng), p_exp(&mut rng), p_exp(&mut rng));
            let from = leave(p, err, n, to - p);
            rays.push(Ray::segment(from, to - from, 0.0, 1.0));
        }
        let accels = build_all(&tris);
        // A hit is a re-hit unless exact arithmetic on the f32 ray confirms it: a
        // target point within the error band of the plane (pExp draws many near the
        // origin, which such planes pass close to) makes the sign of `w·n` itself
        // uncertain, and the segment may then truly cross the plane.
        let crosses: Vec<bool> = rays.iter().map(|r| f64_hits(&tris, 0, r)).collect();
        let bad = |hit: &[bool]| {
            let dirs = hit[..500]
                .iter()
                .zip(&crosses)
                .filter(|(h, c)| **h && !**c)
                .count();
            let segs = hit[500..]
                .iter()
                .zip(&crosses[500..])
                .filter(|(h, c)| **h && !**c)
                .count();
            (dirs, segs)
        };
        for (path, hits) in closest_all(&accels, &rays) {
            traced += rays.len();
            let (dirs, segs) = bad(&hits.iter().map(|h| h.is_some()).collect::<Vec<_>>());
            if dirs + segs > 0 {
                report.push(format!("triangle {c:?}, p {p}: {path}/closest: {dirs} of 500 rays, {segs} of 500 segments re-hit"));
            }
        }
        for (path, occ) in any_all(&accels, &rays) {
            let (dirs, segs) = bad(&occ);
            if dirs + segs > 0 {
                report.push(format!("triangle {c:?}, p {p}: {path}/any: {dirs} of 500 rays, {segs} of 500 segments re-hit"));
            }
        }
        confirmed += crosses.iter().filter(|c| **c).count();
    }
    eprintln!("{confirmed} of 100000 rays cross the triangle in exact arithmetic (not counted)");
    assert_eq!(triangles, 100, "too few usable triangles");
    assert!(
        confirmed < 1000,
        "{confirmed} rays truly cross the plane: test setup broken"
    );
    assert!(traced >= 100_000, "too few rays: {traced}");
    assert!(
        report.is_empty(),
        "{} failures:\n{}",
        report.len(),
        report.join("\n")
    );
}

/// An icosphere: the icosahedron subdivided once (80 faces), vertices on the unit sphere.
fn icosphere() -> Mesh {
    let t = (1.0 + 5f32.sqrt()) / 2.0;
    let mut pos: Vec<Vec3> = [
        (-1.0, t, 0.0),
        (1.0, t, 0.0),
        (-1.0, -t, 0.0),
        (1.0, -t, 0.0),
        (0.0, -1.0, t),
        (0.0, 1.0, t),
        (0.0, -1.0, -t),
        (0.0, 1.0, -t),
        (t, 0.0, -1.0),
        (t, 0.0, 1.0),
        (-t, 0.0, -1.0),
        (-t, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| Vec3::new(x, y, z).normalize())
    .collect();
    let faces: [[u32; 3]; 20] = [
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    let mut mid = std::collections::HashMap::new();
    let mut midpoint = |a: u32, b: u32, pos: &mut Vec<Vec3>| {
        *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
            pos.push((pos[a as usize] + pos[b as usize]).normalize());
            pos.len() as u32 - 1
        })
    };
    let mut tris = Vec::new();
    for [a, b, c] in faces {
        let (ab, bc, ca) = (
            midpoint(a, b, &mut pos),
            midpoint(b, c, &mut pos),
            midpoint(c, a, &mut pos),
        );
        tris.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
    }
    Mesh {
        name: "icosphere".into(),
        pos,
        tris,
        inside: vec![Vec3::ZERO],
        convex: true,
    }
}

/// A random transform as in the issue: per-axis scale 10^U(-4,4), a random rotation,
/// translation ±10^U(-8,8) per axis.
fn random_transform(rng: &mut Rng) -> impl Fn(Vec3) -> Vec3 + use<> {
    let s = Vec3::new(
        10f32.powf(rng.range(-4.0, 4.0)),
        10f32.powf(rng.range(-4.0, 4.0)),
        10f32.powf(rng.range(-4.0, 4.0)),
    );
    let axis = rng.unit_vector();
    let rot = Quat::from_axis_angle(axis, rng.range(0.0, std::f32::consts::TAU));
    let mut tr = || {
        let m = 10f32.powf(rng.range(-8.0, 8.0));
        if rng.f32() < 0.5 { -m } else { m }
    };
    let t = Vec3::new(tr(), tr(), tr());
    move |p| rot * (p * s) + t
}

/// Whether the f64 reference intersects triangle `i` along `r` (t > 0): a mesh made
/// slightly non-convex by rounding its transformed vertices may be hit legitimately.
fn f64_hits(t: &Triangles, i: usize, r: &Ray) -> bool {
    let d = |v: Vec3| DVec3::new(v.x as f64, v.y as f64, v.z as f64);
    intersect_triangle_f64(d(r.origin), d(r.dir), d(t.v0[i]), d(t.v1[i]), d(t.v2[i]))
        .is_some_and(|x| x < r.tmax as f64)
}

/// Rays leaving a convex mesh into the outward hemisphere from points given by
/// barycentrics, offset by the renderer's rule: no hit, except on another triangle that
/// the f64 reference confirms (rounding the transformed vertices can make the mesh
/// very slightly concave); never on the triangle the ray leaves.
fn check_leaving(
    name: &str,
    tris: &Triangles,
    accels: &[(packet_render::accel::AccelKind, Box<dyn Accel>)],
    starts: &[(usize, Ray)],
    report: &mut Vec<String>,
) {
    let rays: Vec<Ray> = starts.iter().map(|(_, r)| *r).collect();
    let mut check = |path: &str, i: usize, prim: Option<u32>| {
        let (from, r) = starts[i];
        let bad = match prim {
            Some(p) => p as usize == from || !f64_hits(tris, p as usize, &r),
            None => false,
        };
        if bad {
            report.push(format!(
                "{name} {path}: ray {r:?} leaving triangle {from} hit {prim:?}"
            ));
        }
    };
    for (path, hits) in closest_all(accels, &rays) {
        for (i, h) in hits.iter().enumerate() {
            check(&path, i, h.map(|h: Hit| h.prim));
        }
    }
    for (path, occ) in any_all(accels, &rays) {
        for (i, &o) in occ.iter().enumerate() {
            // Occlusion names no primitive: it must agree with a confirmed hit.
            if o && !(0..tris.count()).any(|p| p != starts[i].0 && f64_hits(tris, p, &starts[i].1))
            {
                report.push(format!("{name} {path}: ray {:?} occluded", starts[i].1));
            }
        }
    }
}

#[test]
fn convex_shapes_under_random_transforms_never_reintersect() {
    let mut report = Vec::new();
    let mut traced = 0;
    let mut rng = Rng(77);
    for base in [cube(), icosphere()] {
        for k in 0..12 {
            let f = random_transform(&mut rng);
            let pos: Vec<Vec3> = base.pos.iter().map(|&p| f(p)).collect();
            let corners: Vec<[Vec3; 3]> = base
                .tris
                .iter()
                .map(|t| t.map(|i| pos[i as usize]))
                .collect();
            let tris = Triangles::from_corners(&corners);
            let accels = build_all(&tris);
            let mut starts = Vec::new();
            for _ in 0..120 {
                let i = (rng.next_u64() % corners.len() as u64) as usize;
                let (mut u, mut v) = (rng.f32(), rng.f32());
                if u + v > 1.0 {
                    (u, v) = (1.0 - u, 1.0 - v);
                }
                let (p, err) = tri_point(corners[i], u, v);
                // Outward: the winding is outward and the transform keeps orientation.
                let n = normal(&tris, i);
                for _ in 0..16 {
                    let mut w = rng.unit_vector();
                    if w.dot(n) < 0.0 {
                        w = -w;
                    }
                    starts.push((i, Ray::new(leave(p, err, n, w), w)));
                }
            }
            traced += starts.len();
            check_leaving(
                &format!("{} #{k}", base.name),
                &tris,
                &accels,
                &starts,
                &mut report,
            );
        }
    }
    // Moving triangles: the cube placed at the ray's time, as the renderer does.
    for k in 0..6 {
        let f = random_transform(&mut rng);
        let base = cube();
        let pos: Vec<Vec3> = base.pos.iter().map(|&p| f(p)).collect();
        let corners: Vec<[Vec3; 3]> = base
            .tris
            .iter()
            .map(|t| t.map(|i| pos[i as usize]))
            .collect();
        let vel = rng.unit_vector() * pos[0].abs().max_element();
        let moving = MovingTriangles {
            v0: corners.iter().map(|c| c[0]).collect(),
            v1: corners.iter().map(|c| c[1]).collect(),
            v2: corners.iter().map(|c| c[2]).collect(),
            velocity: vec![vel; corners.len()],
            shutter: [0.0, 1.0],
        };
        let accels = build_all(&moving);
        let (mut rays, mut starts_of) = (Vec::new(), Vec::new());
        for _ in 0..1000 {
            let i = (rng.next_u64() % corners.len() as u64) as usize;
            starts_of.push(i);
            let time = rng.f32();
            let placed = corners[i].map(|c| c + time * vel);
            let (p, err) = tri_point(placed, 0.3 * rng.f32(), 0.6 * rng.f32());
            let n = (placed[1] - placed[0])
                .cross(placed[2] - placed[0])
                .normalize();
            let mut w = rng.unit_vector();
            if w.dot(n) < 0.0 {
                w = -w;
            }
            let mut r = Ray::new(leave(p, err, n, w), w);
            r.time = time;
            rays.push(r);
        }
        traced += rays.len();
        // As for the static shapes: a hit must be on another triangle, confirmed by the
        // f64 reference on the corners placed at the ray's time.
        let placed_at = |time: f32| {
            let c: Vec<[Vec3; 3]> = corners.iter().map(|c| c.map(|p| p + time * vel)).collect();
            Triangles::from_corners(&c)
        };
        for (path, hits) in closest_all(&accels, &rays) {
            for ((h, r), from) in hits.iter().zip(&rays).zip(&starts_of) {
                if let Some(h) = h {
                    let placed = placed_at(r.time);
                    if h.prim as usize == *from || !f64_hits(&placed, h.prim as usize, r) {
                        report.push(format!(
                            "moving cube #{k} {path}: ray {r:?} from {from} hit {}",
                            h.prim
                        ));
                    }
                }
            }
        }
        for (path, occ) in any_all(&accels, &rays) {
            for ((&o, r), from) in occ.iter().zip(&rays).zip(&starts_of) {
                let placed = placed_at(r.time);
                if o && !(0..placed.count()).any(|p| p != *from && f64_hits(&placed, p, r)) {
                    report.push(format!("moving cube #{k} {path}: ray {r:?} occluded"));
                }
            }
        }
    }
    // Spheres of radius 10^U(-4,4) centred ±10^U(-8,8) per axis: outward rays escape,
    // inward rays reach the far side.
    // Centre coordinates up to 1e4 radii: beyond, the hit point's error bound (a few
    // ulps of the centre) exceeds 1 % of the radius and f32 has almost no surface
    // points to offer (measured: 17 of 30 spheres with centres up to 1e8 regardless).
    let mut skipped_spheres = 0;
    for k in 0..30 {
        let r = 10f32.powf(rng.range(-4.0, 4.0));
        let top = (r.log10() + 4.0).min(8.0);
        let mut tr = || {
            let m = 10f32.powf(rng.range(-8.0, top));
            if rng.f32() < 0.5 { -m } else { m }
        };
        let c = Vec3::new(tr(), tr(), tr());
        let spheres = Spheres {
            center: vec![c],
            radius: vec![r],
        };
        let accels = build_all(&spheres);
        let (mut out, mut inn) = (Vec::new(), Vec::new());
        for _ in 0..500 {
            let (p, err, n) = sph_point(c, r, c + r * rng.unit_vector());
            // Inward rays only where f32 can place an origin inside: the error bound
            // (a few ulps of the centre's coordinates) well below the radius.
            let resolvable = err.max_element() < 1e-2 * r;
            let mut w = rng.unit_vector();
            if w.dot(n) < 0.0 {
                w = -w;
            }
            if resolvable {
                out.push(Ray::new(leave(p, err, n, w), w));
                inn.push(Ray::new(leave(p, err, n, -w), -w));
            }
        }
        traced += out.len() + inn.len();
        // Only spheres f32 can resolve: the hit point's error bound (a few ulps of the
        // centre's coordinates) below 1 % of the radius. A smaller sphere has no
        // representable surface point apart from its centre's neighbours.
        if out.is_empty() {
            skipped_spheres += 1;
            continue;
        }
        for (path, hits) in count_hits(&accels, &out) {
            if hits > 0 {
                report.push(format!(
                    "sphere #{k} r {r:e} c {c}: {path}: {hits} of {} outward rays re-hit",
                    out.len()
                ));
            }
        }
        for (path, hits) in count_hits(&accels, &inn) {
            if hits != inn.len() {
                report.push(format!(
                    "sphere #{k} r {r:e} c {c}: {path}: {} of {} inward rays missed the far side",
                    inn.len() - hits,
                    inn.len()
                ));
            }
        }
    }
    assert_eq!(skipped_spheres, 0, "unresolvable spheres drawn");
    assert!(traced >= 50_000, "too few rays: {traced}");
    assert!(
        report.is_empty(),
        "{} failures; first 20:\n{}",
        report.len(),
        report[..report.len().min(20)].join("\n")
    );
}

/// Shadow segments between two points on the inside faces of a closed cube, both from
/// barycentrics, offset by the renderer's rule and ending at the other point: the
/// segment runs through the open interior, so nothing may block it.
#[test]
fn shadow_segments_inside_a_closed_cube_are_unoccluded() {
    let mut report = Vec::new();
    let mut traced = 0;
    let mut rng = Rng(99);
    let base = cube();
    let mut placements = vec![(1.0f32, Vec3::ZERO)];
    for s in [1e-6f32, 1e-3, 1e3, 1e6] {
        placements.push((s, Vec3::ZERO));
        placements.push((s, s * 1e3 * Vec3::new(1.0, -0.5, 0.25)));
    }
    placements.push((1e4, Vec3::new(1e7, -1e7, 1e7)));
    for (s, off) in placements {
        let m = base.transformed(s, off);
        let tris = m.triangles();
        let accels = build_all(&tris);
        let mut rays = Vec::new();
        while rays.len() < 1500 {
            let (i, j) = (
                (rng.next_u64() % 12) as usize,
                (rng.next_u64() % 12) as usize,
            );
            // Different faces: the two triangles of a face are 2k, 2k + 1.
            if i / 2 == j / 2 {
                continue;
            }
            let pick = |rng: &mut Rng, i: usize| {
                let (mut u, mut v) = (rng.f32(), rng.f32());
                if u + v > 1.0 {
                    (u, v) = (1.0 - u, 1.0 - v);
                }
                let (p, e) = tri_point(corners_of(&tris, i), u, v);
                (p, e, -normal(&tris, i))
            };
            let (p, pe, np) = pick(&mut rng, i);
            let (q, qe, nq) = pick(&mut rng, j);
            rays.push(segment_to(p, pe, np, q, qe, nq));
        }
        coherent_order(&mut rays);
        traced += rays.len();
        for (path, occ) in any_all(&accels, &rays) {
            let n = occ.iter().filter(|o| **o).count();
            if n > 0 {
                let first = rays[occ.iter().position(|o| *o).unwrap()];
                report.push(format!(
                    "{} {path}: {n} of {} segments occluded, first {first:?}",
                    m.name,
                    rays.len()
                ));
            }
        }
        for (path, hits) in closest_all(&accels, &rays) {
            let n = hits.iter().filter(|h| h.is_some()).count();
            if n > 0 {
                report.push(format!(
                    "{} {path}: {n} of {} segments hit",
                    m.name,
                    rays.len()
                ));
            }
        }
    }
    assert!(traced >= 10_000);
    assert!(report.is_empty(), "{}", report.join("\n"));
}

/// Exact hit distance. Guarantee: `t` is the correctly rounded quotient
/// `t_scaled / det`. On a face perpendicular to the ray's dominant axis all three
/// scaled depths are one value `Z`, so `t_scaled = Z det` exactly when `Z` is a power of
/// two, and then `t = Z` exactly. Checked here: segments between points on opposite
/// faces of a cube of half-size `2^k` (the dominant component of `d = q - p` is exactly
/// `2^(k+1)`, which makes `Z = 1`; the lateral ones are arbitrary) report `t == 1.0`
/// exactly, and a segment with `tmax = 1.0` is unoccluded, on every path. (This case
/// held with `t_scaled * (1/det)` too; where `t` is not exact the division halved, not
/// removed, the segments reported blocked: see docs/robustness.md.)
#[test]
fn segments_ending_exactly_on_a_face_are_unoccluded() {
    let mut report = Vec::new();
    let mut rng = Rng(5);
    for k in [-20i32, -6, 0, 7, 20] {
        let s = 2f32.powi(k);
        let m = cube().transformed(s, Vec3::ZERO);
        let tris = m.triangles();
        let accels = build_all(&tris);
        let mut rays = Vec::new();
        for _ in 0..600 {
            let axis = (rng.next_u64() % 3) as usize;
            let sign = if rng.f32() < 0.5 { -1.0 } else { 1.0 };
            // Any lateral coordinates inside the faces: `d` need not be exact laterally,
            // the plane `x_axis = ±s` is met at exactly t = 1 all the same.
            let (mut p, mut q) = (Vec3::ZERO, Vec3::ZERO);
            for a in 0..3 {
                (p[a], q[a]) = if a == axis {
                    (-sign * s, sign * s)
                } else {
                    (s * rng.range(-0.9, 0.9), s * rng.range(-0.9, 0.9))
                };
            }
            assert_eq!((q - p)[axis], 2.0 * sign * s);
            rays.push(Ray::segment(p, q - p, 0.0, 1.0));
        }
        let open: Vec<Ray> = rays.iter().map(|r| Ray::new(r.origin, r.dir)).collect();
        for (path, hits) in closest_all(&accels, &open) {
            let bad = hits.iter().filter(|h| h.is_none_or(|h| h.t != 1.0)).count();
            if bad > 0 {
                let first = hits.iter().find(|h| h.is_none_or(|h| h.t != 1.0));
                report.push(format!(
                    "half-size 2^{k} {path}: {bad} of {} t != 1, first {first:?}",
                    open.len()
                ));
            }
        }
        for (path, occ) in any_all(&accels, &rays) {
            let n = occ.iter().filter(|o| **o).count();
            if n > 0 {
                report.push(format!(
                    "half-size 2^{k} {path}: {n} of {} segments with tmax = t occluded",
                    rays.len()
                ));
            }
        }
    }
    assert!(report.is_empty(), "{}", report.join("\n"));
}

/// Rays aimed at triangle centroids of a rotated plane of 100 x 100 quads from 10^3
/// units away, grazing it at 0.005°..0.02°: exact arithmetic hits the target (checked
/// in f64 below); f32 shear rounding moved projected corners by more than the
/// foreshortened triangle is wide and reported a neighbour in about 0.025 % of cases.
#[test]
fn grazing_rays_at_centroids_report_the_target() {
    let n = 100;
    let mut rng = Rng(31);
    let rot = Quat::from_axis_angle(Vec3::new(0.3, 0.9, -0.2).normalize(), 0.7);
    let mut corners = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let c =
                |x: i32, y: i32| rot * Vec3::new((i + x) as f32 - 50.0, (j + y) as f32 - 50.0, 0.0);
            corners.push([c(0, 0), c(1, 0), c(1, 1)]);
            corners.push([c(0, 0), c(1, 1), c(0, 1)]);
        }
    }
    let tris = Triangles::from_corners(&corners);
    let normal_w = rot * Vec3::Z;
    let mut rays = Vec::new();
    let mut targets = Vec::new();
    for (t, c) in corners.iter().enumerate() {
        let centroid = (c[0] + c[1] + c[2]) / 3.0;
        let phi = rng.range(0.0, std::f32::consts::TAU);
        let g = rng.range(0.005, 0.02).to_radians();
        let along = rot * Vec3::new(phi.cos(), phi.sin(), 0.0);
        let back = (along * g.cos() + normal_w * g.sin()).normalize();
        let o = centroid + 1e3 * back;
        let r = Ray::new(o, centroid - o);
        // Exact arithmetic on the f32 ray and corners hits the target.
        if !f64_hits(&tris, t, &r) {
            continue;
        }
        rays.push(r);
        targets.push(t as u32);
    }
    assert!(rays.len() > 19_000, "only {} usable rays", rays.len());
    let accels = build_all(&tris);
    let mut report = Vec::new();
    for (path, hits) in closest_all(&accels, &rays) {
        let bad: Vec<_> = hits
            .iter()
            .zip(&targets)
            .filter(|(h, t)| h.is_none_or(|h| h.prim != **t))
            .collect();
        if !bad.is_empty() {
            report.push(format!(
                "{path}: {} of {} rays report another triangle, first {:?}",
                bad.len(),
                rays.len(),
                bad[0]
            ));
        }
    }
    assert!(report.is_empty(), "{}", report.join("\n"));
}
