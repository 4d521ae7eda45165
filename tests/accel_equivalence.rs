//! Every acceleration structure returns the brute-force answer: the same closest
//! primitive and distance, and any-hit agreeing with closest-hit.

mod common;

use common::*;
use glam::Vec3;
use packet_render::accel::{
    Accel, AccelKind, BruteForce, Grid, GridOptions, Primitives, Spheres, Triangles,
};
use packet_render::geometry::{Aabb, Ray, RayQuery};
use packet_render::scene::{Material, SceneBuilder, procedural};
use rayon::prelude::*;

fn bounds_of<P: Primitives>(p: &P) -> Aabb {
    (0..p.count()).fold(Aabb::EMPTY, |b, i| b.union(&p.bounds(i)))
}

/// Compares `accel` with brute force on `rays`. Two answers agree when they name the same
/// primitive at the same distance, or, on an exact tie (a ray through a shared edge or
/// duplicated triangles), different primitives at the same distance.
fn assert_matches_bruteforce<P: Primitives + Clone + 'static>(name: &str, prims: P, rays: &[Ray]) {
    let reference = BruteForce::new(prims.clone());
    // brute force once per ray, shared by every structure (it dominates the test time)
    let wants: Vec<_> = rays.par_iter().map(|r| reference.closest_hit(r)).collect();
    for kind in AccelKind::ALL
        .iter()
        .filter(|k| **k != AccelKind::BruteForce)
    {
        let accel = kind.build(prims.clone());
        let mismatches: Vec<String> = rays
            .par_iter()
            .enumerate()
            .filter_map(|(i, r)| {
                let want = wants[i];
                let got = accel.closest_hit(r);
                let same = match (want, got) {
                    (None, None) => true,
                    // the same primitive, or a true tie: the other primitive is hit at the same t
                    (Some(a), Some(b)) => {
                        a.t == b.t
                            && (a.prim == b.prim
                                || RayQuery::new(r)
                                    .and_then(|q| {
                                        prims.intersect(b.prim as usize, &q, f32::INFINITY)
                                    })
                                    .is_some_and(|h| h.t == a.t))
                    }
                    _ => false,
                };
                let occluded = accel.any_hit(r);
                (!same || occluded != want.is_some()).then(|| {
                    format!(
                        "ray {i} {r:?}: brute force {want:?}, {kind} {got:?}, any_hit {occluded}"
                    )
                })
            })
            .collect();
        assert!(
            mismatches.is_empty(),
            "{name}/{kind}: {} of {} rays differ, first: {}",
            mismatches.len(),
            rays.len(),
            mismatches[0]
        );
    }
}

#[test]
fn bumpy_sphere_mesh() {
    let (pos, tris) = bumpy_sphere(40, 64, 2.0);
    let prims = triangles_of(&pos, &tris);
    let rays = random_rays(&bounds_of(&prims), 40_000, 1);
    assert_matches_bruteforce("bumpy sphere", prims, &rays);
}

#[test]
fn triangle_soup_with_slivers() {
    let prims = triangle_soup(3000, 7);
    let rays = random_rays(&bounds_of(&prims), 40_000, 2);
    assert_matches_bruteforce("soup", prims, &rays);
}

#[test]
fn shortened_rays_and_intervals() {
    // any-hit with finite tmax: a ray stopped just before its hit is unoccluded, one
    // stopped just after is occluded, for every structure.
    let (pos, tris) = bumpy_sphere(20, 32, 1.0);
    let prims = triangles_of(&pos, &tris);
    let rays = random_rays(&bounds_of(&prims), 5000, 4);
    let reference = BruteForce::new(prims.clone());
    for kind in AccelKind::ALL {
        let accel = kind.build(prims.clone());
        for r in &rays {
            if let Some(h) = reference.closest_hit(r) {
                let mut short = *r;
                short.tmax = h.t * 0.99;
                assert_eq!(accel.any_hit(&short), reference.any_hit(&short), "{kind}");
                let mut long = *r;
                long.tmax = h.t * 1.01;
                assert!(accel.any_hit(&long), "{kind}: missed occluder");
            }
        }
    }
}

#[test]
fn procedural_tessellated_mesh() {
    let prims = procedural_mesh(5000);
    let rays = random_rays(&bounds_of(&prims), 15_000, 5);
    assert_matches_bruteforce("tessellated", prims, &rays);
}

#[test]
fn procedural_sphereflake() {
    let mut b = SceneBuilder::new();
    let m = b.add_material(Material::default());
    assert_eq!(
        procedural::sphereflake(&mut b, 3, Vec3::new(0.0, 0.5, 0.0), 0.5, m),
        820
    );
    let prims = Spheres::from_set(&b.spheres);
    let rays = random_rays(&bounds_of(&prims), 15_000, 6);
    assert_matches_bruteforce("procedural sphereflake", prims, &rays);
}

/// A dense 20k-triangle blob of radius 1 inside a 12-triangle box of size 1000: the case
/// where a uniform grid puts the whole blob into a few cells.
#[test]
fn teapot_in_a_stadium() {
    let blob = procedural_mesh(20_000);
    let (lo, hi) = (Vec3::splat(-500.0), Vec3::splat(500.0));
    let c = |x: bool, y: bool, z: bool| {
        Vec3::new(
            if x { hi.x } else { lo.x },
            if y { hi.y } else { lo.y },
            if z { hi.z } else { lo.z },
        )
    };
    let mut corners: Vec<[Vec3; 3]> = (0..blob.count())
        .map(|i| [blob.v0[i], blob.v1[i], blob.v2[i]])
        .collect();
    for axis in 0..3 {
        for side in [false, true] {
            // the two triangles of the face `axis = side`
            let p = |u: bool, v: bool| match axis {
                0 => c(side, u, v),
                1 => c(u, side, v),
                _ => c(u, v, side),
            };
            corners.push([p(false, false), p(true, false), p(true, true)]);
            corners.push([p(false, false), p(true, true), p(false, true)]);
        }
    }
    let prims = Triangles::from_corners(&corners);
    let mut rays = random_rays(&bounds_of(&blob), 5000, 7);
    rays.extend(random_rays(&Aabb::new(lo * 0.9, hi * 0.9), 1500, 8));
    assert_matches_bruteforce("teapot in a stadium", prims, &rays);
}

#[test]
fn counting_entry_points() {
    let prims = triangle_soup(500, 9);
    let rays = random_rays(&bounds_of(&prims), 300, 10);
    for kind in AccelKind::ALL {
        let accel = kind.build(prims.clone());
        let Some(_) = accel.traversal_counts(&rays[0]) else {
            assert!(
                matches!(
                    kind,
                    AccelKind::Bvh4 | AccelKind::Bvh8 | AccelKind::Bvh4c | AccelKind::Bvh8c
                ),
                "{kind} has no counting twin"
            );
            continue;
        };
        let (mut nodes, mut tests) = (0, 0);
        for r in &rays {
            let c = accel.traversal_counts(r).unwrap();
            nodes += c.nodes;
            tests += c.prim_tests;
        }
        assert!(nodes > 0 && tests > 0, "{kind}");
        if *kind != AccelKind::BruteForce {
            assert!(tests < 500 * rays.len() as u64 / 4, "{kind}: {tests} tests");
        }
        // invalid rays do no work
        let bad = Ray::new(Vec3::ZERO, Vec3::ZERO);
        assert_eq!(
            accel.traversal_counts(&bad).unwrap().prim_tests,
            0,
            "{kind}"
        );
    }
}

/// A triangle spanning many grid cells is tested once per ray with mailboxing, once per
/// cell without.
#[test]
fn grid_mailbox_tests_spanning_primitive_once() {
    let mut corners = vec![[
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(100.0, 0.0, 100.0),
        Vec3::new(0.0, 1.0, 100.0),
    ]];
    for i in 0..999 {
        let p = Vec3::new(
            (i % 10) as f32 * 10.0,
            50.0 + (i / 100) as f32,
            (i / 10 % 10) as f32 * 10.0,
        );
        corners.push([p, p + Vec3::X, p + Vec3::Z]);
    }
    let prims = Triangles::from_corners(&corners);
    let on = Grid::build(prims.clone());
    let off = Grid::build_with(
        prims,
        GridOptions {
            mailbox: false,
            ..Default::default()
        },
    );
    // along the big triangle's diagonal, just off its plane, through many cells
    let ray = Ray::new(Vec3::new(0.5, 0.5, 0.0), Vec3::new(1.0, 0.0, 1.0));
    let a = on.traversal_counts(&ray).unwrap();
    let b = off.traversal_counts(&ray).unwrap();
    assert_eq!(on.closest_hit(&ray), off.closest_hit(&ray));
    assert!(a.nodes >= 10, "{a:?}");
    assert_eq!(a.prim_tests, 1, "{a:?}");
    assert!(b.prim_tests >= 10, "{b:?}");
}

/// Unit squares on the integer planes of a 4x4x4 lattice, and axis-parallel rays that
/// run exactly along lattice planes and edges (cell, voxel and split planes of the
/// spatial structures coincide with or sit next to them), with both signed zeros.
#[test]
fn lattice_planes_and_edges() {
    let mut corners = Vec::new();
    for a in 0..3 {
        let (u, v) = ((a + 1) % 3, (a + 2) % 3);
        for k in 0..=4 {
            for i in 0..4 {
                for j in 0..4 {
                    let p = |di: f32, dj: f32| {
                        let mut q = Vec3::ZERO;
                        q[a] = k as f32;
                        q[u] = i as f32 + di;
                        q[v] = j as f32 + dj;
                        q
                    };
                    if (i + j + k) % 3 != 0 {
                        corners.push([p(0.0, 0.0), p(1.0, 0.0), p(1.0, 1.0)]);
                        corners.push([p(0.0, 0.0), p(1.0, 1.0), p(0.0, 1.0)]);
                    }
                }
            }
        }
    }
    let prims = Triangles::from_corners(&corners);
    let mut rays = Vec::new();
    let coords = [-0.5f32, 0.0, 0.5, 1.0, 2.0, 2.5, 4.0, 4.5];
    for a in 0..3 {
        for &x in &coords {
            for &y in &coords {
                for sign in [1.0f32, -1.0] {
                    for zero in [0.0f32, -0.0] {
                        let mut o = Vec3::splat(0.0);
                        o[(a + 1) % 3] = x;
                        o[(a + 2) % 3] = y;
                        o[a] = if sign > 0.0 { -1.0 } else { 5.0 };
                        let mut d = Vec3::splat(zero);
                        d[a] = sign;
                        rays.push(Ray::new(o, d));
                        // starting inside, on a lattice plane
                        o[a] = 2.0;
                        rays.push(Ray::new(o, d));
                    }
                }
            }
        }
    }
    rays.extend(random_rays(&bounds_of(&prims), 3000, 11));
    assert_matches_bruteforce("lattice", prims, &rays);
}

/// Degenerate sets for every structure: one primitive, 10^4 identical triangles, a
/// tilted plane of triangles (all coplanar, box not flat), and an axis-aligned plane
/// (zero-thickness scene box), plus the empty set.
#[test]
fn degenerate_sets() {
    let one = Triangles::from_corners(&[[Vec3::ZERO, Vec3::X, Vec3::Y]]);
    let identical = Triangles::from_corners(&vec![[Vec3::ZERO, Vec3::X, Vec3::Y]; 10_000]);
    let plane = |tilt: Vec3| {
        let corners: Vec<[Vec3; 3]> = (0..900)
            .map(|i| {
                let (x, y) = ((i % 30) as f32 * 0.1, (i / 30) as f32 * 0.1);
                let p = |u: f32, v: f32| Vec3::new(u, v, tilt.dot(Vec3::new(u, v, 0.0)));
                [p(x, y), p(x + 0.1, y), p(x, y + 0.1)]
            })
            .collect();
        Triangles::from_corners(&corners)
    };
    for (name, prims) in [
        ("one", one),
        ("identical", identical),
        ("tilted plane", plane(Vec3::new(0.3, -0.7, 0.0))),
        ("flat box", plane(Vec3::ZERO)),
    ] {
        let rays = random_rays(&bounds_of(&prims), 3000, 12);
        assert_matches_bruteforce(name, prims, &rays);
    }
    for kind in AccelKind::ALL {
        let empty = kind.build(Triangles::default());
        let r = Ray::new(Vec3::ZERO, Vec3::X);
        assert!(
            empty.closest_hit(&r).is_none() && !empty.any_hit(&r),
            "{kind}"
        );
    }
}

/// Rays aimed exactly at the shared vertices and edge midpoints of a closed mesh, from
/// inside and from outside: every structure finds the brute-force hit, at the same t.
/// (A box entry rounded above the current closest t once culled a neighbour triangle
/// hit one ulp nearer.)
#[test]
fn rays_through_shared_vertices_and_edges() {
    let mut b = SceneBuilder::new();
    let m = b.add_material(Material::default());
    procedural::tessellated_mesh(&mut b, 3000, Vec3::new(0.3, -0.2, 0.1), 1.0, m);
    let mesh = &b.mesh;
    let prims = Triangles::from_mesh(mesh);
    let mut targets: Vec<Vec3> = (0..mesh.vertex_count() as u32)
        .map(|i| mesh.vertex(i))
        .collect();
    for t in 0..mesh.len() {
        let [a, b, c] = mesh.corners(t);
        targets.extend([0.5 * (a + b), 0.5 * (b + c), 0.5 * (c + a)]);
    }
    let inside = Vec3::new(0.31, -0.18, 0.12);
    let outside = Vec3::new(4.0, 3.0, 5.0);
    let rays: Vec<Ray> = targets
        .iter()
        .flat_map(|&p| {
            [
                Ray::new(inside, (p - inside).normalize()),
                Ray::new(outside, (p - outside).normalize()),
            ]
        })
        .collect();
    assert_matches_bruteforce("shared vertices and edges", prims, &rays);
}

/// Moving geometry: every structure built over moving spheres and moving triangles
/// (bounds over the shutter interval, primitives placed at the ray's time) returns the
/// brute-force answer for rays at times spread over the whole shutter, the open and
/// close instants included. Bounds taken at one instant only would lose the primitives
/// that have moved out of them: the renderer's moving BVH2 is one of the structures
/// checked.
#[test]
fn moving_geometry_matches_bruteforce_at_every_time() {
    use packet_render::accel::{MovingSpheres, MovingTriangles};
    let shutter = [0.25f32, 1.5];
    let mut rng = Rng(21);
    let n = 400;
    let mut spheres = MovingSpheres {
        shutter,
        ..Default::default()
    };
    let mut tris = MovingTriangles {
        shutter,
        ..Default::default()
    };
    for _ in 0..n {
        let c = Vec3::new(
            rng.range(-4.0, 4.0),
            rng.range(-4.0, 4.0),
            rng.range(-4.0, 4.0),
        );
        // Velocities up to 3 units per time unit: over the shutter a primitive moves
        // up to 3.75, many times its own size.
        let v = rng.unit_vector() * rng.range(0.0, 3.0);
        spheres.center.push(c);
        spheres.velocity.push(v);
        spheres.radius.push(rng.range(0.05, 0.4));
        tris.v0.push(c);
        tris.v1.push(c + rng.unit_vector() * rng.range(0.1, 0.8));
        tris.v2.push(c + rng.unit_vector() * rng.range(0.1, 0.8));
        tris.velocity.push(Vec3::new(v.z, v.x, v.y));
    }
    let bounds = bounds_of(&spheres).union(&bounds_of(&tris));
    let mut rays = random_rays(&bounds, 20_000, 22);
    let count = rays.len();
    for (i, r) in rays.iter_mut().enumerate() {
        // Every 10th ray at the open instant, every 10th at close, the rest spread.
        r.time = match i % 10 {
            0 => shutter[0],
            1 => shutter[1],
            _ => shutter[0] + (shutter[1] - shutter[0]) * (i as f32 / count as f32),
        };
    }
    assert_matches_bruteforce("moving spheres", spheres, &rays);
    assert_matches_bruteforce("moving triangles", tris, &rays);
}
