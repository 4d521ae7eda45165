//! Every acceleration structure returns the brute-force answer: the same closest
//! primitive and distance, and any-hit agreeing with closest-hit.

mod common;

use common::*;
use packet_render::accel::{Accel, AccelKind, BruteForce, Primitives};
use packet_render::geometry::{Aabb, Ray, RayQuery};
use rayon::prelude::*;

fn bounds_of<P: Primitives>(p: &P) -> Aabb {
    (0..p.count()).fold(Aabb::EMPTY, |b, i| b.union(&p.bounds(i)))
}

/// Compares `accel` with brute force on `rays`. Two answers agree when they name the same
/// primitive at the same distance, or, on an exact tie (a ray through a shared edge or
/// duplicated triangles), different primitives at the same distance.
fn assert_matches_bruteforce<P: Primitives + Clone + 'static>(name: &str, prims: P, rays: &[Ray]) {
    let reference = BruteForce::new(prims.clone());
    for kind in AccelKind::ALL
        .iter()
        .filter(|k| **k != AccelKind::BruteForce)
    {
        let accel = kind.build(prims.clone());
        let mismatches: Vec<String> = rays
            .par_iter()
            .enumerate()
            .filter_map(|(i, r)| {
                let want = reference.closest_hit(r);
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
fn procedural_tessellated_mesh() {
    let prims = procedural_mesh(20_000);
    let rays = random_rays(&bounds_of(&prims), 30_000, 5);
    assert_matches_bruteforce("tessellated", prims, &rays);
}

#[test]
fn triangle_soup_with_slivers() {
    let prims = triangle_soup(3000, 7);
    let rays = random_rays(&bounds_of(&prims), 40_000, 2);
    assert_matches_bruteforce("soup", prims, &rays);
}

#[test]
fn sphereflake_spheres() {
    let prims = flake_spheres(3);
    assert_eq!(prims.count(), 820);
    let rays = random_rays(&bounds_of(&prims), 30_000, 3);
    assert_matches_bruteforce("sphereflake", prims, &rays);
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
