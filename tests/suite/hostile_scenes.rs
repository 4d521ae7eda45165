//! Spatial subdivisions (grid, octree, kd-tree) on hostile scenes: primitives at
//! +-1e38, a small dense mesh inside a huge sparse enclosure ("teapot in a stadium").
//! Work is asserted through traversal counts, never through time.

use crate::common;

use common::*;
use glam::Vec3;
use packet_render::accel::{Accel, AccelKind, BruteForce, Primitives, Triangles};
use packet_render::geometry::{Aabb, Ray};

fn bounds_of<P: Primitives>(p: &P) -> Aabb {
    (0..p.count()).fold(Aabb::EMPTY, |b, i| b.union(&p.bounds(i)))
}

/// The 12 triangles of the box `[-half, half]^3`.
fn enclosure(half: f32) -> Vec<[Vec3; 3]> {
    let c = |x: bool, y: bool, z: bool| {
        Vec3::new(
            if x { half } else { -half },
            if y { half } else { -half },
            if z { half } else { -half },
        )
    };
    let mut corners = Vec::new();
    for axis in 0..3 {
        for side in [false, true] {
            let p = |u: bool, v: bool| match axis {
                0 => c(side, u, v),
                1 => c(u, side, v),
                _ => c(u, v, side),
            };
            corners.push([p(false, false), p(true, false), p(true, true)]);
            corners.push([p(false, false), p(true, true), p(false, true)]);
        }
    }
    corners
}

fn corners_of(t: &Triangles) -> Vec<[Vec3; 3]> {
    (0..t.count())
        .map(|i| [t.v0[i], t.v1[i], t.v2[i]])
        .collect()
}

/// Mean primitive tests per ray.
fn mean_tests(a: &dyn Accel, rays: &[Ray]) -> f64 {
    let total: u64 = rays
        .iter()
        .map(|r| a.traversal_counts(r).expect("counting twin").prim_tests)
        .sum();
    total as f64 / rays.len() as f64
}

/// Teapot in a stadium: a 20k-triangle mesh of radius 1 inside a 12-triangle box of
/// half size 5e4. Before issue 13 every primitive's margin was a fraction of the scene
/// size (about 1 here, the whole mesh): octree 20034 and kd-tree 33978 tests per ray
/// against 7.2 and 4.7 for the mesh alone. With margins relative to the primitive:
/// 24.2 and 22.5 (the rest is the depth the enclosure costs).
///
/// The uniform grid is not asserted: with `3 cbrt(n)` cells along the enclosure, the
/// mesh falls into one cell whatever the margin (20023 tests per ray against 3.2), the
/// classic failure of uniform grids on this scene, not a margin problem.
#[test]
fn small_mesh_in_huge_enclosure_costs_few_tests() {
    let blob = procedural_mesh(20_000);
    let rays = random_rays(&bounds_of(&blob), 2000, 11);
    let mut corners = corners_of(&blob);
    corners.extend(enclosure(5e4));
    let stadium = Triangles::from_corners(&corners);
    for kind in [AccelKind::Octree, AccelKind::KdTree] {
        let alone = mean_tests(kind.build(blob.clone()).as_ref(), &rays);
        let inside = mean_tests(kind.build(stadium.clone()).as_ref(), &rays);
        eprintln!("{kind}: mesh alone {alone:.1}, in the enclosure {inside:.1} tests per ray");
        // 8x: measured 3.4x (octree) and 4.7x (kd-tree); before the fix 2780x and 7100x.
        assert!(
            inside < 8.0 * alone,
            "{kind}: {inside:.1} tests per ray in the enclosure, {alone:.1} alone"
        );
    }
}

/// No hit is lost to the primitive-relative margins for rays from the far walls:
/// origins anywhere in the enclosure (up to 4.5e4 from the mesh), aimed at the mesh.
#[test]
fn rays_from_far_walls_agree_with_brute_force() {
    use rayon::prelude::*;
    let blob = procedural_mesh(20_000);
    let bb = bounds_of(&blob);
    let half = 5e4f32;
    let mut corners = corners_of(&blob);
    corners.extend(enclosure(half));
    let stadium = Triangles::from_corners(&corners);
    let bf = BruteForce::new(stadium.clone());
    let mut rng = Rng(21);
    let inner = Aabb::new(Vec3::splat(-0.9 * half), Vec3::splat(0.9 * half));
    let rays: Vec<Ray> = (0..8000)
        .map(|_| {
            let o = rng.point_in(&inner);
            let t = rng.point_in(&bb);
            Ray::new(o, (t - o).normalize())
        })
        .collect();
    let want: Vec<_> = rays
        .par_iter()
        .map(|r| bf.closest_hit(r).map(|h| h.t))
        .collect();
    assert!(want.iter().filter(|w| w.is_some_and(|t| t < half)).count() > 1000);
    for kind in [AccelKind::Grid, AccelKind::Octree, AccelKind::KdTree] {
        let a = kind.build(stadium.clone());
        let bad: Vec<usize> = (0..rays.len())
            .into_par_iter()
            .filter(|&i| {
                a.closest_hit(&rays[i]).map(|h| h.t) != want[i]
                    || a.any_hit(&rays[i]) != want[i].is_some()
            })
            .collect();
        assert!(
            bad.is_empty(),
            "{kind}: {} of {} rays differ from brute force, first {:?}",
            bad.len(),
            rays.len(),
            bad.first().map(|&i| rays[i])
        );
    }
}

/// Adversarial case for primitive-relative margins: walls of small triangles 1e-4 from
/// the middle planes x = 0 and y = 0 of every octree level (and of grid cells and kd
/// splits nearby), hit by rays from 1e4..4e4 away that cross both planes within a few
/// 1e-3 of the walls, where the traversal's plane distances are rounded by about as
/// much. A skipped region would show as a ray passing through a wall.
#[test]
fn rays_crossing_region_corners_near_walls_agree_with_brute_force() {
    let half = 5e4f32;
    let mut corners = enclosure(half);
    // at x = +-1e-4: a wall below y = 0 and one above, each 1e-6 from the plane
    for sx in [1.0f32, -1.0] {
        for sy in [1.0f32, -1.0] {
            for k in 0..50 {
                let z0 = -1e-2 + k as f32 * 4e-4;
                let x = sx * 1e-4;
                corners.push([
                    Vec3::new(x, sy * -1e-6, z0),
                    Vec3::new(x, sy * -1e-2, z0),
                    Vec3::new(x, sy * -1e-6, z0 + 4e-4),
                ]);
                corners.push([
                    Vec3::new(x, sy * -1e-2, z0),
                    Vec3::new(x, sy * -1e-2, z0 + 4e-4),
                    Vec3::new(x, sy * -1e-6, z0 + 4e-4),
                ]);
            }
        }
    }
    let prims = Triangles::from_corners(&corners);
    let bf = BruteForce::new(prims.clone());
    let mut rng = Rng(5);
    let rays: Vec<Ray> = (0..50_000)
        .map(|_| {
            let target = Vec3::new(0.0, -rng.range(0.0, 4e-3), rng.range(-9e-3, 9e-3));
            let dir = Vec3::new(1.0, rng.range(0.3, 3.0), rng.range(-1e-3, 1e-3)).normalize();
            Ray::new(target - dir * rng.range(1e4, 4e4), dir)
        })
        .collect();
    let want: Vec<_> = rays
        .iter()
        .map(|r| bf.closest_hit(r).map(|h| h.t))
        .collect();
    // nearly every ray stops at a wall near the origin, not at the far enclosure
    assert!(want.iter().filter(|w| w.is_some_and(|t| t < 4.1e4)).count() > 49_000);
    for kind in [AccelKind::Grid, AccelKind::Octree, AccelKind::KdTree] {
        let a = kind.build(prims.clone());
        let bad: Vec<usize> = (0..rays.len())
            .filter(|&i| a.closest_hit(&rays[i]).map(|h| h.t) != want[i])
            .collect();
        assert!(
            bad.is_empty(),
            "{kind}: {} of {} rays differ from brute force, first {:?}",
            bad.len(),
            rays.len(),
            bad.first().map(|&i| rays[i])
        );
    }
}

/// Rays from very far away (1e5 to 1e8 scene sizes) aimed at points on the triangles of a
/// unit-scale soup: the traversal's plane distances are rounded by a few `u` of the
/// distance, far more than any margin relative to the primitives or the regions.
#[test]
fn rays_from_far_away_agree_with_brute_force() {
    use rayon::prelude::*;
    let prims = triangle_soup(2000, 77);
    let corners = corners_of(&prims);
    let bf = BruteForce::new(prims.clone());
    let mut rng = Rng(99);
    let rays: Vec<Ray> = (0..40_000)
        .map(|i| {
            let [a, b, c] = corners[rng.next_u64() as usize % corners.len()];
            let (u, v) = (rng.f32(), rng.f32());
            let (u, v) = if u + v > 1.0 {
                (1.0 - u, 1.0 - v)
            } else {
                (u, v)
            };
            let target = a + u * (b - a) + v * (c - a);
            let dist = 10f32.powi(5 + i % 4);
            let dir = rng.unit_vector();
            Ray::new(target - dir * dist, dir)
        })
        .collect();
    let want: Vec<_> = rays
        .par_iter()
        .map(|r| bf.closest_hit(r).map(|h| (h.t, h.prim)))
        .collect();
    assert!(want.iter().filter(|w| w.is_some()).count() > 30_000);
    let mut failures = Vec::new();
    for kind in AccelKind::ALL {
        let a = kind.build(prims.clone());
        let bad: Vec<usize> = (0..rays.len())
            .into_par_iter()
            .filter(|&i| {
                let got = a.closest_hit(&rays[i]).map(|h| (h.t, h.prim));
                // an exact tie in t may resolve to either primitive
                got.map(|g| g.0) != want[i].map(|w| w.0)
            })
            .collect();
        eprintln!("{kind}: {} of {} differ", bad.len(), rays.len());
        if let Some(&i) = bad.first() {
            failures.push(format!(
                "{kind}: {} of {} rays differ from brute force, first {:?}",
                bad.len(),
                rays.len(),
                rays[i]
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
