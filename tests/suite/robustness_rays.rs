//! Robustness, part 2: special rays (signed zeros, in-plane, NaN/inf, zero and subnormal
//! directions), exact interval ends, degenerate and duplicated geometry, and the optics
//! helpers of the Whitted integrator at their limits. Every structure, every path.

use crate::common;
use crate::robust;

use glam::Vec3;
use packet_render::accel::{Accel, AccelKind, BruteForce, Spheres, Triangles};
use packet_render::geometry::{Hit, Ray};
use packet_render::integrator::optics::{dielectric, reflect};
use robust::*;

fn assert_all_agree(
    name: &str,
    accels: &[(AccelKind, Box<dyn Accel>)],
    rays: &[Ray],
) -> Vec<Option<Hit>> {
    let all = closest_all(accels, rays);
    let want = all[0].1.clone();
    for (path, hits) in &all {
        for (i, (g, w)) in hits.iter().zip(&want).enumerate() {
            let same = match (g, w) {
                (None, None) => true,
                (Some(g), Some(w)) => g.t == w.t,
                _ => false,
            };
            assert!(
                same,
                "{name} {path} ray {i} {:?}: {g:?}, brute force {w:?}",
                rays[i]
            );
        }
    }
    for (path, occ) in any_all(accels, rays) {
        for (i, o) in occ.iter().enumerate() {
            assert_eq!(
                *o,
                want[i].is_some(),
                "{name} {path} any-hit of ray {i} {:?}",
                rays[i]
            );
        }
    }
    want
}

#[test]
fn signed_zero_and_in_plane_directions() {
    let tris = cube().triangles();
    let accels = build_all(&tris);
    let mut rays = Vec::new();
    for sx in [0.0f32, -0.0] {
        for sy in [0.0f32, -0.0] {
            // Toward the z = -1 face from outside (t = 4) and from inside (t = 1).
            rays.push(Ray::new(Vec3::new(0.3, -0.2, -5.0), Vec3::new(sx, sy, 1.0)));
            rays.push(Ray::new(Vec3::new(0.3, -0.2, 0.0), Vec3::new(sx, sy, -1.0)));
            // Lying in the plane of the x = 1 face, and on the cube's edge line.
            rays.push(Ray::new(Vec3::new(1.0, 0.5, -5.0), Vec3::new(sx, sy, 1.0)));
            rays.push(Ray::new(Vec3::new(1.0, 1.0, -5.0), Vec3::new(sx, sy, 1.0)));
            // Lying in a slab plane outside the box: a miss.
            rays.push(Ray::new(Vec3::new(2.0, 0.5, -5.0), Vec3::new(sx, sy, 1.0)));
        }
    }
    let hits = assert_all_agree("signed zeros", &accels, &rays);
    for (i, h) in hits.iter().enumerate() {
        match i % 5 {
            0 => assert_eq!(h.map(|h| h.t), Some(4.0), "ray {i}"),
            1 => assert_eq!(h.map(|h| h.t), Some(1.0), "ray {i}"),
            4 => assert!(h.is_none(), "ray {i}"),
            // On the boundary: either the face's edge is hit at t = 4 or nothing.
            _ => assert!(h.is_none_or(|h| h.t == 4.0 || h.t == 6.0), "ray {i}: {h:?}"),
        }
    }
}

#[test]
fn invalid_rays_miss_and_leave_packet_neighbours_alone() {
    let m = jittered_sphere(12, 24, 0.05, 5);
    let tris = m.triangles();
    let accels = build_all(&tris);
    // 64 coherent rays toward the sphere from one side, in packets of 16.
    let rays: Vec<Ray> = (0..64)
        .map(|i| {
            let (x, y) = ((i % 8) as f32 / 8.0 - 0.45, (i / 8) as f32 / 8.0 - 0.45);
            Ray::new(Vec3::new(x, y, -4.0), Vec3::new(0.01 * x, 0.01 * y, 1.0))
        })
        .collect();
    let clean = assert_all_agree("clean", &accels, &rays);
    assert!(clean.iter().all(|h| h.is_some()));
    let good = rays[0];
    let bad = [
        Ray::new(Vec3::new(f32::NAN, 0.0, -4.0), Vec3::Z),
        Ray::new(Vec3::new(0.0, f32::INFINITY, -4.0), Vec3::Z),
        Ray::new(good.origin, Vec3::new(f32::NAN, 0.0, 1.0)),
        Ray::new(good.origin, Vec3::new(0.0, f32::NEG_INFINITY, 1.0)),
        Ray::new(good.origin, Vec3::ZERO),
        Ray::new(good.origin, Vec3::new(0.0, -0.0, 0.0)),
        Ray {
            tmin: f32::NAN,
            ..good
        },
        Ray {
            tmax: f32::NAN,
            ..good
        },
        Ray {
            tmin: 5.0,
            tmax: 1.0,
            ..good
        },
        Ray {
            tmin: f32::INFINITY,
            ..good
        },
        Ray {
            tmax: f32::NEG_INFINITY,
            ..good
        },
    ];
    let mut poisoned = rays.clone();
    let mut is_bad = vec![false; rays.len()];
    for (k, i) in (1..rays.len()).step_by(3).enumerate() {
        poisoned[i] = bad[k % bad.len()];
        is_bad[i] = true;
    }
    for (path, hits) in closest_all(&accels, &poisoned) {
        for i in 0..rays.len() {
            if is_bad[i] {
                assert!(
                    hits[i].is_none(),
                    "{path}: invalid ray {:?} hit {:?}",
                    poisoned[i],
                    hits[i]
                );
            } else {
                assert_eq!(
                    hits[i], clean[i],
                    "{path}: lane {i} changed by invalid neighbours"
                );
            }
        }
    }
    for (path, occ) in any_all(&accels, &poisoned) {
        for i in 0..rays.len() {
            assert_eq!(occ[i], !is_bad[i], "{path}: occlusion of lane {i}");
        }
    }
}

#[test]
fn subnormal_and_tiny_directions() {
    let tris = cube().triangles();
    let accels = build_all(&tris);
    let o = Vec3::new(0.2, 0.1, -5.0);
    let sub = f32::MIN_POSITIVE / 8.0;
    assert!(sub > 0.0 && !sub.is_normal());
    let rays = [
        // Subnormal side components: the same hit as with exact zeros.
        Ray::new(o, Vec3::new(sub, -sub, 1.0)),
        // A subnormal dominant component: t would be ~1e39, not representable; it must
        // miss cleanly (never NaN, never a hit at inf).
        Ray::new(Vec3::new(-5.0, 0.0, 0.0), Vec3::new(sub, 0.0, 0.0)),
        // Tiny but normal: t scales by 1/1e-30.
        Ray::new(o, Vec3::new(0.0, 0.0, 1e-30)),
    ];
    let hits = assert_all_agree("subnormal", &accels, &rays);
    assert_eq!(hits[0].map(|h| h.t), Some(4.0));
    assert!(hits[1].is_none());
    let t = hits[2].expect("tiny direction hits").t;
    assert!((t / 4e30 - 1.0).abs() < 1e-6, "t = {t}");
}

#[test]
fn interval_ends_are_strict_and_shadow_rays_ending_on_a_surface_are_unoccluded() {
    let m = jittered_sphere(16, 32, 0.05, 8);
    let tris = m.triangles();
    let accels = build_all(&tris);
    let mut rng = common::Rng(4);
    let base: Vec<Ray> = (0..512)
        .map(|_| {
            let o = 3.0 * rng.unit_vector();
            Ray::new(o, (0.5 * rng.unit_vector() - o).normalize())
        })
        .collect();
    let reference = BruteForce::new(tris.clone());
    let first: Vec<Hit> = base
        .iter()
        .map(|r| reference.closest_hit(r).expect("aimed inside the sphere"))
        .collect();
    // tmax exactly at the first hit: excluded, and nothing else is nearer (convex-ish
    // from outside: the first hit is the entry).
    let shadow: Vec<Ray> = base
        .iter()
        .zip(&first)
        .map(|(r, h)| Ray { tmax: h.t, ..*r })
        .collect();
    for (path, hits) in closest_all(&accels, &shadow) {
        for (i, h) in hits.iter().enumerate() {
            assert!(
                h.is_none_or(|h| h.t < first[i].t),
                "{path} ray {i}: {h:?} at tmax {}",
                first[i].t
            );
        }
    }
    for (path, occ) in any_all(&accels, &shadow) {
        let hit_own: Vec<_> = (0..occ.len())
            .filter(|&i| occ[i] && reference.closest_hit(&shadow[i]).is_none())
            .collect();
        assert!(
            hit_own.is_empty(),
            "{path}: shadow rays ending on the surface occluded: {hit_own:?}"
        );
    }
    // tmin exactly at the first hit: that hit is excluded, the exit is found instead.
    let from: Vec<Ray> = base
        .iter()
        .zip(&first)
        .map(|(r, h)| Ray { tmin: h.t, ..*r })
        .collect();
    for (path, hits) in closest_all(&accels, &from) {
        for (i, h) in hits.iter().enumerate() {
            let h = h.unwrap_or_else(|| panic!("{path} ray {i}: no exit hit"));
            assert!(h.t > first[i].t, "{path} ray {i}: {h:?} not beyond tmin");
        }
    }
    // Exactly representable case: an axis ray to the cube face at t = 2.
    let cube_accels = build_all(&cube().triangles());
    let r = Ray::new(Vec3::new(0.25, 0.5, -3.0), Vec3::Z);
    let at = |tmin, tmax| Ray { tmin, tmax, ..r };
    let rays = [
        at(0.0, 2.0),
        at(0.0, 2.0f32.next_up()),
        at(2.0, f32::INFINITY),
        at(2.0, 2.0),
    ];
    let hits = assert_all_agree("exact interval", &cube_accels, &rays);
    let ts: Vec<_> = hits.iter().map(|h| h.map(|h| h.t)).collect();
    assert_eq!(ts, vec![None, Some(2.0), Some(4.0), None]);
}

#[test]
fn degenerate_needle_sliver_and_duplicated_triangles() {
    let a = Vec3::new(0.1, 0.2, 0.0);
    let b = Vec3::new(1.3, -0.4, 0.1);
    let mut corners = vec![
        [a, a, a],                                             // a point
        [a, b, 0.5 * (a + b)],                                 // collinear
        [a, a + Vec3::X * 2.0, a + Vec3::new(2.0, 1e-6, 0.0)], // needle
        [a, b, a + Vec3::new(0.0, 0.0, 1e-7)],                 // sliver
    ];
    // Coplanar overlapping and exactly duplicated triangles in the z = 0.5 plane.
    let q = [
        Vec3::new(-1.0, -1.0, 0.5),
        Vec3::new(1.0, -1.0, 0.5),
        Vec3::new(0.0, 1.0, 0.5),
    ];
    corners.push(q);
    corners.push(q);
    corners.push([
        q[0] + Vec3::X * 0.3,
        q[1] + Vec3::X * 0.3,
        q[2] + Vec3::X * 0.3,
    ]);
    let tris = Triangles::from_corners(&corners);
    let accels = build_all(&tris);
    let rays = common::random_rays(
        &packet_render::geometry::Aabb::new(Vec3::splat(-1.5), Vec3::splat(1.5)),
        6000,
        3,
    );
    let hits = assert_all_agree("degenerate", &accels, &rays);
    // Zero-area triangles are never hit.
    assert!(
        hits.iter().flatten().all(|h| h.prim >= 2),
        "a zero-area triangle was hit"
    );
    // Straight down through the overlap: one of the three coplanar triangles at t = 1.
    let down = [Ray::new(Vec3::new(0.2, 0.0, 1.5), -Vec3::Z)];
    let h = assert_all_agree("overlap", &accels, &down)[0].unwrap();
    assert!(h.t == 1.0 && (4..7).contains(&h.prim), "{h:?}");
}

#[test]
fn hundred_thousand_identical_triangles_build_with_bounded_depth_and_memory() {
    let t = [
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(0.0, 1.0, 0.0),
    ];
    let n = 100_000;
    let tris = Triangles::from_corners(&vec![t; n]);
    for &kind in AccelKind::ALL {
        let accel = kind.build(tris.clone());
        let info = accel.info();
        assert_eq!(info.primitives, n, "{kind}");
        assert!(info.max_depth <= 80, "{kind}: depth {}", info.max_depth);
        assert!(
            info.memory_bytes <= 200 * n,
            "{kind}: {} bytes",
            info.memory_bytes
        );
        if kind == AccelKind::BruteForce {
            continue; // 10^5 tests per ray; the other structures cull nothing either
        }
        let rays = [
            Ray::new(Vec3::new(0.2, 0.2, 1.0), -Vec3::Z),
            Ray::new(Vec3::new(0.8, 0.8, 1.0), -Vec3::Z),
        ];
        let h = accel.closest_hit(&rays[0]).expect("hit");
        assert_eq!(h.t, 1.0);
        assert!(accel.closest_hit(&rays[1]).is_none() && accel.any_hit(&rays[0]));
        let mut batch = [None; 2];
        accel.closest_hit_batch(&rays, &mut batch);
        assert_eq!(batch[0].map(|h| h.t), Some(1.0), "{kind}");
        assert!(batch[1].is_none(), "{kind}");
    }
}

#[test]
fn empty_scene_and_single_triangle() {
    let rays = common::random_rays(
        &packet_render::geometry::Aabb::new(Vec3::splat(-1.0), Vec3::ONE),
        300,
        9,
    );
    for accels in [build_all(&Triangles::default())] {
        for (path, hits) in closest_all(&accels, &rays) {
            assert!(hits.iter().all(|h| h.is_none()), "{path}");
        }
        for (path, occ) in any_all(&accels, &rays) {
            assert!(occ.iter().all(|o| !o), "{path}");
        }
    }
    let spheres = build_all(&Spheres::default());
    for (path, hits) in closest_all(&spheres, &rays) {
        assert!(hits.iter().all(|h| h.is_none()), "{path}");
    }
    let one = Triangles::from_corners(&[[
        Vec3::new(-1.0, -1.0, 0.0),
        Vec3::new(1.0, -1.0, 0.0),
        Vec3::new(0.0, 1.0, 0.0),
    ]]);
    let accels = build_all(&one);
    let hits = assert_all_agree("one triangle", &accels, &rays);
    assert!(hits.iter().any(|h| h.is_some()) && hits.iter().any(|h| h.is_none()));
}

/// The integrator's Fresnel/Snell helper at its limits: reflectance in [0, 1] (so
/// R + T <= 1 with T = 1 - R), unit refracted directions on the far side, no NaN.
#[test]
fn dielectric_limits() {
    let n = Vec3::Z;
    let dir = |theta: f64| Vec3::new(theta.sin() as f32, 0.0, -(theta.cos() as f32));
    let check = |d: Vec3, eta_i: f32, eta_t: f32| {
        let s = dielectric(d, n, eta_i, eta_t);
        assert!(
            (0.0..=1.0).contains(&s.reflectance),
            "R = {} for {d} {eta_i}->{eta_t}",
            s.reflectance
        );
        if let Some(t) = s.refracted {
            assert!(t.is_finite() && (t.length() - 1.0).abs() < 1e-5, "{t}");
            assert!(t.dot(n) <= 0.0, "refracted to the incident side: {t}");
        } else {
            assert_eq!(s.reflectance, 1.0);
        }
        let r = reflect(d, n);
        assert!(r.is_finite() && (d.dot(n) > 0.0 || r.dot(n) >= 0.0), "{r}");
        s
    };
    // IOR 1: no bend, no reflection.
    for k in 0..=90 {
        let d = dir((k as f64)
            .to_radians()
            .min(std::f64::consts::FRAC_PI_2 - 1e-9));
        let s = check(d, 1.0, 1.0);
        assert_eq!((s.reflectance, s.refracted), (0.0, Some(d)));
    }
    // Total internal reflection around the critical angle, glass to air.
    let crit = (1.0f64 / 1.5).asin();
    let mut last = 0.0;
    for k in -200..=200 {
        let theta = crit + k as f64 * 1e-5;
        let s = check(dir(theta), 1.5, 1.0);
        assert!(s.reflectance >= last - 1e-6, "R not monotone at {theta}");
        last = s.reflectance;
        if k > 2 {
            assert!(
                s.refracted.is_none(),
                "no TIR {k}e-5 past the critical angle"
            );
        }
        if k < -2 {
            assert!(
                s.refracted.is_some(),
                "TIR {k}e-5 before the critical angle"
            );
        }
    }
    // Just before the critical angle Schlick (fed the rarer side's cosine) is near 1.
    assert!(check(dir(crit - 1e-4), 1.5, 1.0).reflectance > 0.9);
    // Extreme IOR and grazing incidence (cos 1e-8, 0, and slightly wrong side).
    for (ei, et) in [
        (1.0, 1e3),
        (1e3, 1.0),
        (1.0, 1e-3),
        (1e-3, 1.0),
        (1.0, 1.5),
        (1.5, 1.0),
    ] {
        for theta in [
            0.0,
            0.3,
            1.0,
            1.5,
            std::f64::consts::FRAC_PI_2 - 1e-8,
            std::f64::consts::FRAC_PI_2,
        ] {
            check(dir(theta), ei, et);
        }
        let grazing = check(Vec3::new(1.0, 0.0, -1e-8), ei, et);
        assert!(
            grazing.reflectance > 0.999,
            "{ei}->{et}: R {}",
            grazing.reflectance
        );
        check(Vec3::new(1.0, 0.0, 1e-8).normalize(), ei, et);
    }
}

/// Energy is never created. The bound is derived from the scene: no ambient term, no
/// background, one point light of intensity I = 10 at height h = 5 above the floor, and
/// the floor is the only surface with a diffuse (or any direct-light) response: glass
/// and chrome have zero diffuse and specular. The floor's radiance at a point at
/// distance r from the light is `0.8 / pi * I cos(theta) / r^2` with cos(theta) = h / r,
/// so at most `0.8 / pi * I / h^2` (the point straight below the light, r = h). Every
/// other pixel sees the floor through mirrors (weight 0.9) and glass (reflection F plus
/// transmission 1 - F, weights summing to 1), so no path can exceed that either:
/// bound = 0.8 / pi * 10 / 25 = 0.1019. (The old bound used the distance from the light
/// to the glass sphere, 3, which has no diffuse response: 0.283, 2.8x too loose.)
#[test]
fn renders_never_exceed_what_the_light_can_deliver() {
    let text = r#"
        [render]
        width = 40
        height = 30
        max_depth = 12
        min_contribution = 0.0
        [camera]
        eye = [0, 2, 7]
        target = [0.5, 0.8, 0]
        [materials.floor]
        diffuse = [0.8, 0.8, 0.8]
        [materials.glass]
        preset = "glass"
        diffuse = [0, 0, 0]
        [materials.chrome]
        preset = "mirror"
        diffuse = [0, 0, 0]
        mirror = [0.9, 0.9, 0.9]
        [[light]]
        type = "point"
        position = [0, 5, 0]
        intensity = [10, 10, 10]
        [[plane]]
        point = [0, 0, 0]
        normal = [0, 1, 0]
        size = 10
        material = "floor"
        [[sphere]]
        center = [0, 1, 0]
        radius = 1
        material = "glass"
        [[sphere]]
        center = [2.5, 1, 0]
        radius = 1
        material = "chrome"
    "#;
    let scene =
        packet_render::scene::load::parse_toml_scene(text, std::path::Path::new("energy.toml"))
            .unwrap();
    let bound = 0.8 / std::f32::consts::PI * 10.0 / 25.0;
    for &kind in AccelKind::ALL {
        let accel = packet_render::accel::SceneAccel::build(&scene, kind);
        let opts = packet_render::integrator::RenderOptions::from_scene(&scene);
        let out = packet_render::integrator::recursive::render(&scene, &accel, &opts);
        assert_eq!(out.nonfinite_samples, 0);
        let max = out
            .film
            .pixels
            .iter()
            .map(|p| p.max_element())
            .fold(0.0f32, f32::max);
        // 1e-4: f32 rounding of the shading arithmetic, far below any real excess.
        assert!(
            max <= bound * (1.0 + 1e-4),
            "{kind}: pixel {max} > bound {bound}"
        );
        // And the bound is tight: the floor just outside the glass sphere's shadow
        // (radius 5 tan(asin(1/4)) = 1.29 around the foot of the light, r = 5.16) gets
        // cos(theta) / r^2 = 0.91 / h^2, so some pixel comes within 10 % of the bound.
        assert!(
            max > 0.85 * bound,
            "{kind}: brightest pixel {max}, expected above 0.85 x {bound}"
        );
    }
}
