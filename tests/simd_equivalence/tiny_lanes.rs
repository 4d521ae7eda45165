//! (A module of `tests/simd_equivalence.rs`, so the portable build checks it too.)
//!
//! The lane paths for tiny scenes against their scalar oracles, ray for ray:
//!
//! - the batch queries of a scene of at most `TINY_MAX_PRIMITIVES` static primitives
//!   (`accel::TinyScene`, every ray against every primitive in lanes) return exactly
//!   the scalar brute-force answer (t, prim, u, v bit for bit, ties included), the same
//!   occlusion and the same first blocking set, and the structures' answers up to which
//!   primitive wins an exact tie;
//! - the glass crossings counted in lanes (`simd::glass_shadow`) are exactly the
//!   candidates the scalar filtered query offers.

use crate::common::Rng;
use glam::Vec3;
use packet_render::accel::{
    AccelKind, BatchScratch, BruteForce, SceneAccel, SceneHit, Spheres, TINY_MAX_PRIMITIVES,
    all_hits,
};
use packet_render::geometry::Ray;
use packet_render::scene::{Camera, Light, Material, Scene, SceneBuilder};
use packet_render::simd::glass_shadow::crossing_counts;

/// A floor quad (two triangles sharing a diagonal), then, with `crowded`, a coincident
/// copy of it (exact ties in `t` between different triangles) and more spheres, one
/// inside another and one touching the floor, up to exactly `TINY_MAX_PRIMITIVES`.
fn scene(crowded: bool) -> Scene {
    let mut b = SceneBuilder::new();
    let m = b.add_material(Material::diffuse("grey", Vec3::splat(0.5)));
    let quad = |b: &mut SceneBuilder| {
        b.add_quad(
            Vec3::new(-4.0, 0.0, -4.0),
            Vec3::new(0.0, 0.0, 8.0),
            Vec3::new(8.0, 0.0, 0.0),
            m,
        )
    };
    quad(&mut b);
    b.add_sphere(Vec3::new(1.1, 1.3, -1.4), 1.3, m);
    b.add_sphere(Vec3::new(-0.9, 1.0, 1.0), 1.0, m);
    if crowded {
        quad(&mut b);
        b.add_sphere(Vec3::new(1.1, 1.3, -1.4), 0.5, m);
        b.add_sphere(Vec3::new(2.5, 0.25, 2.0), 0.25, m);
    }
    b.add_light(Light::Point {
        position: Vec3::new(-5.0, 9.0, 7.0),
        intensity: Vec3::splat(100.0),
    });
    b.camera = Some(Camera {
        eye: Vec3::new(0.0, 1.8, 7.0),
        target: Vec3::new(0.0, 1.0, 0.0),
        up: Vec3::Y,
        vfov_deg: 40.0,
    });
    b.finish().unwrap()
}

/// Camera rays; rays from random points in random directions (every dominant axis and
/// sign) with whole and cut intervals; rays aimed exactly at the floor's corners and
/// diagonal (edge functions of zero, the scalar fallback); invalid rays.
fn rays(scene: &Scene) -> Vec<Ray> {
    let mut rays = Vec::new();
    let frame = scene.camera.frame(40, 30);
    for i in 0..40 * 30 {
        rays.push(frame.ray((i % 40) as f32 + 0.5, (i / 40) as f32 + 0.5));
    }
    let mut rng = Rng(7);
    for i in 0..3000 {
        let o = Vec3::new(
            rng.range(-5.0, 5.0),
            rng.range(-1.0, 4.0),
            rng.range(-5.0, 5.0),
        );
        let mut r = Ray::new(o, rng.unit_vector() * rng.range(0.5, 2.0));
        if i % 3 == 1 {
            r.tmax = rng.range(0.0, 4.0);
        } else if i % 3 == 2 {
            r.tmin = rng.range(0.0, 1.0);
        }
        rays.push(r);
    }
    for target in [
        Vec3::new(-4.0, 0.0, -4.0),
        Vec3::new(4.0, 0.0, 4.0),
        Vec3::new(-4.0, 0.0, 4.0),
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(1.0, 0.0, 1.0),
        Vec3::new(-2.5, 0.0, -2.5),
    ] {
        for o in [
            Vec3::new(0.3, 3.0, 0.7),
            Vec3::new(-3.0, 2.0, 5.0),
            Vec3::new(6.0, 1.0, -2.0),
        ] {
            rays.push(Ray::new(o, target - o));
        }
    }
    rays.push(Ray::new(Vec3::new(f32::NAN, 1.0, 0.0), Vec3::NEG_Y));
    rays.push(Ray::new(Vec3::new(0.0, 1.0, 0.0), Vec3::ZERO));
    rays.push(Ray::new(
        Vec3::new(0.0, 1.0, 0.0),
        Vec3::new(0.0, f32::INFINITY, 0.0),
    ));
    rays.push(Ray::segment(
        Vec3::new(0.0, 1.0, 0.0),
        Vec3::NEG_Y,
        2.0,
        1.0,
    ));
    rays
}

fn bits(h: Option<SceneHit>) -> Option<(u32, String, u32, u32)> {
    h.map(|h| {
        (
            h.t.to_bits(),
            format!("{:?}", h.prim),
            h.u.to_bits(),
            h.v.to_bits(),
        )
    })
}

#[test]
fn tiny_batches_equal_the_scalar_brute_force_ray_for_ray() {
    for crowded in [false, true] {
        let scene = scene(crowded);
        let rays = rays(&scene);
        let oracle = SceneAccel::build(&scene, AccelKind::BruteForce);
        for kind in [AccelKind::BruteForce, AccelKind::Bvh4, AccelKind::Bvh8] {
            let accel = SceneAccel::build(&scene, kind);
            let tiny = accel.tiny.as_ref().expect("a tiny scene");
            assert_eq!(tiny.len(), scene.mesh.len() + scene.spheres.len());
            let mut scratch = BatchScratch::default();
            // Several batch lengths, so groups of every fill and key mix occur.
            let all = rays.len();
            for len in [1, 15, 17, 333, all] {
                let rays = &rays[..len];
                let mut hits = vec![None; len];
                accel.closest_hit_batch(rays, &mut hits, &mut scratch);
                let mut blocked = vec![false; len];
                accel.any_hit_batch(rays, &mut blocked, &mut scratch);
                let (mut first, mut marks) = (vec![None; len], Vec::new());
                accel.occluders_batch(rays, &mut first, &mut marks, &mut scratch);
                let (mut on_tri, mut on_sphere, mut ties) = (0, 0, 0);
                for (i, r) in rays.iter().enumerate() {
                    let want = oracle.closest_hit(r);
                    assert_eq!(
                        bits(hits[i]),
                        bits(want),
                        "crowded {crowded} {kind} ray {i} {r:?}"
                    );
                    let tree = accel.closest_hit(r);
                    if bits(tree) != bits(want) {
                        // The structure may resolve an exact tie to the other primitive.
                        let (a, b) = (tree.unwrap(), want.unwrap());
                        assert!(
                            a.t == b.t && a.prim != b.prim,
                            "{kind} ray {i}: {a:?} {b:?}"
                        );
                        ties += 1;
                    }
                    assert_eq!(blocked[i], want.is_some(), "{kind} ray {i} {r:?}");
                    assert_eq!(first[i], oracle.occluder(r), "{kind} ray {i} {r:?}");
                    match want.map(|h| h.prim) {
                        Some(packet_render::accel::PrimRef::Triangle(_)) => on_tri += 1,
                        Some(_) => on_sphere += 1,
                        None => {}
                    }
                }
                if len == all {
                    eprintln!(
                        "crowded {crowded} {kind}: {len} rays, {on_tri} on triangles, \
                         {on_sphere} on spheres, {ties} ties resolved otherwise by the tree"
                    );
                    assert!(on_tri > 100 && on_sphere > 100);
                }
            }
        }
    }
}

#[test]
fn only_scenes_up_to_the_threshold_take_the_tiny_path() {
    let at = scene(true);
    assert_eq!(at.mesh.len() + at.spheres.len(), TINY_MAX_PRIMITIVES);
    assert!(SceneAccel::build(&at, AccelKind::Bvh4).tiny.is_some());
    let mut b = SceneBuilder::new();
    let m = b.add_material(Material::diffuse("grey", Vec3::splat(0.5)));
    for i in 0..=TINY_MAX_PRIMITIVES {
        b.add_sphere(Vec3::new(i as f32 * 3.0, 0.0, 0.0), 1.0, m);
    }
    b.camera = Some(Camera {
        eye: Vec3::new(0.0, 0.0, 10.0),
        target: Vec3::ZERO,
        up: Vec3::Y,
        vfov_deg: 40.0,
    });
    let above = b.finish().unwrap();
    let accel = SceneAccel::build(&above, AccelKind::Bvh4);
    assert!(accel.tiny.is_none());
    // Its batches still answer as the scalar queries do.
    let rays: Vec<Ray> = (0..64)
        .map(|i| Ray::new(Vec3::new(i as f32 * 0.5, 0.1, 10.0), Vec3::NEG_Z))
        .collect();
    let mut hits = vec![None; rays.len()];
    accel.closest_hit_batch(&rays, &mut hits, &mut BatchScratch::default());
    for (r, h) in rays.iter().zip(&hits) {
        assert_eq!(bits(*h), bits(accel.closest_hit(r)));
    }
    assert!(hits.iter().any(|h| h.is_some()));
}

#[test]
fn glass_crossings_in_lanes_are_the_filtered_query_candidates() {
    let set = [
        (Vec3::new(-0.9, 1.0, 1.0), 1.0),
        (Vec3::new(0.5, 1.2, 0.8), 0.7),
        (Vec3::new(3.0, 0.0, 0.0), 0.5),
    ];
    let spheres = Spheres {
        center: set.iter().map(|s| s.0).collect(),
        radius: set.iter().map(|s| s.1).collect(),
    };
    let brute = BruteForce::new(spheres);
    let mut rng = Rng(11);
    let mut rays = Vec::new();
    for i in 0..4000 {
        // Origins inside and outside the spheres; segments ending outside, inside and
        // before them; whole rays.
        let o = Vec3::new(
            rng.range(-2.5, 4.0),
            rng.range(-1.0, 3.0),
            rng.range(-1.5, 2.5),
        );
        let target = set[i % 3].0 + rng.unit_vector() * rng.range(0.0, 1.5);
        let mut r = Ray::segment(o, target - o, 0.0, rng.range(0.2, 1.5));
        if i % 5 == 0 {
            r.tmax = f32::INFINITY;
        }
        if i % 7 == 0 {
            // A later start, never past the end (a ray with tmin > tmax is invalid).
            r.tmin = rng.range(0.0, 0.5).min(r.tmax);
        }
        rays.push(r);
    }
    // Tangent rays (a double root: one candidate) and rays through a centre.
    rays.push(Ray::new(Vec3::new(-5.0, 2.0, 1.0), Vec3::X));
    rays.push(Ray::new(Vec3::new(3.0, 0.5, -4.0), Vec3::Z));
    rays.push(Ray::new(Vec3::new(-0.9, -3.0, 1.0), Vec3::Y));
    let mut seen = [0usize; 7];
    for (c, chunk) in rays.chunks(16).enumerate() {
        let counts = crossing_counts(chunk, &set);
        for (i, r) in chunk.iter().enumerate() {
            let want = all_hits(&brute, r, false).len() as u32;
            assert_eq!(counts[i], want, "chunk {c} ray {i}: {r:?}");
            seen[want.min(6) as usize] += 1;
        }
        assert!(counts[chunk.len()..].iter().all(|&n| n == 0));
    }
    eprintln!("rays by number of crossings: {seen:?}");
    assert!(seen[0] > 0 && seen[1] > 100 && seen[2] > 100 && seen[3] + seen[4] > 0);
}
