//! Filtered ray queries (`accel::filter`) on every structure in `AccelKind::ALL`: all
//! hits along a ray (coincident and duplicated triangles each reported once, also by
//! the spatial subdivisions that reference a primitive from several cells), back-face
//! culling on a closed mesh from outside and inside, and filters that skip candidates
//! agree with brute force.

use crate::common;

use common::*;
use glam::Vec3;
use packet_render::accel::{
    Accel, AccelKind, BruteForce, Candidate, Grid, GridOptions, Primitives, QueryOptions, Spheres,
    Triangles, all_hits,
};
use packet_render::geometry::{Aabb, Ray};

fn bounds_of<P: Primitives>(p: &P) -> Aabb {
    (0..p.count()).fold(Aabb::EMPTY, |b, i| b.union(&p.bounds(i)))
}

/// Every structure, plus a grid without its mailbox (so that only the filtered query's
/// own deduplication keeps a primitive spanning many cells from being reported twice).
fn structures<P: Primitives + Clone + 'static>(prims: &P) -> Vec<(String, Box<dyn Accel>)> {
    let mut all: Vec<(String, Box<dyn Accel>)> = AccelKind::ALL
        .iter()
        .map(|k| (k.name().to_string(), k.build(prims.clone())))
        .collect();
    let no_mailbox = GridOptions {
        mailbox: false,
        ..GridOptions::default()
    };
    all.push((
        "grid-no-mailbox".into(),
        Box::new(Grid::build_with(prims.clone(), no_mailbox)),
    ));
    all
}

/// The big triangle repeated at 0..4 and at the end with the opposite winding.
const BIG: [Vec3; 3] = [
    Vec3::new(-6.0, -6.0, 0.5),
    Vec3::new(6.0, -6.0, 0.5),
    Vec3::new(0.0, 6.0, 0.5),
];

/// Four coincident copies of a triangle spanning the scene, a soup of 300 triangles
/// (overlapping, slivers), and the same big triangle once more, wound the other way.
fn coincident_scene() -> Triangles {
    let soup = triangle_soup(300, 7);
    let mut corners = vec![BIG; 4];
    for i in 0..soup.count() {
        corners.push([soup.v0[i], soup.v1[i], soup.v2[i]]);
    }
    corners.push([BIG[0], BIG[2], BIG[1]]);
    Triangles::from_corners(&corners)
}

/// Rays for the comparisons: random rays over the bounds and rays crossing the big
/// triangle's plane from both sides.
fn test_rays(bounds: &Aabb, n: usize) -> Vec<Ray> {
    let mut rays = random_rays(bounds, n, 11);
    let mut rng = Rng(5);
    for _ in 0..n / 4 {
        let target = Vec3::new(rng.range(-2.0, 2.0), rng.range(-2.0, 2.0), 0.5);
        let o = target + 8.0 * rng.unit_vector();
        rays.push(Ray::new(o, target - o));
    }
    rays
}

#[test]
fn all_hits_on_coincident_and_duplicated_triangles() {
    let prims = coincident_scene();
    let last = prims.count() as u32 - 1;
    let reference = BruteForce::new(prims.clone());
    // Straight down through the big triangle where no soup triangle is: five hits at
    // one distance, the four copies from the front and the reversed one from the back.
    let ray = (0..400)
        .map(|k| {
            let (x, y) = ((k % 20) as f32 * 0.2 - 2.0, (k / 20) as f32 * 0.2 - 2.0);
            Ray::new(Vec3::new(x, y, 20.0), -Vec3::Z)
        })
        .find(|r| {
            all_hits(&reference, r, false)
                .iter()
                .all(|c| c.hit.prim < 4 || c.hit.prim == last)
        })
        .expect("a ray through the big triangle that misses the soup");
    for (name, accel) in structures(&prims) {
        let hits = all_hits(accel.as_ref(), &ray, false);
        let got: Vec<(u32, bool)> = hits.iter().map(|c| (c.hit.prim, c.front_face)).collect();
        assert_eq!(
            got,
            vec![(0, true), (1, true), (2, true), (3, true), (last, false)],
            "{name}"
        );
        assert!(hits.iter().all(|c| c.hit.t == 19.5), "{name}: {hits:?}");
        // Culled: the reversed copy goes.
        let culled = all_hits(accel.as_ref(), &ray, true);
        assert_eq!(culled.len(), 4, "{name}");
        assert!(culled.iter().all(|c| c.front_face && c.hit.prim < 4));
    }
}

#[test]
fn all_hits_agree_with_brute_force_on_every_structure() {
    let prims = coincident_scene();
    let rays = test_rays(&bounds_of(&prims), 900);
    let reference = BruteForce::new(prims.clone());
    let want: Vec<_> = rays
        .iter()
        .map(|r| all_hits(&reference, r, false))
        .collect();
    let want_culled: Vec<_> = rays.iter().map(|r| all_hits(&reference, r, true)).collect();
    // The comparison means something only if many rays cross several surfaces.
    let several = want.iter().filter(|h| h.len() >= 3).count();
    eprintln!("{} rays, {several} with three hits or more", rays.len());
    assert!(several > 200, "only {several} rays with three hits or more");
    for (name, accel) in structures(&prims) {
        for (i, r) in rays.iter().enumerate() {
            // Exact: every structure runs the same scalar test on the same corners.
            assert_eq!(
                all_hits(accel.as_ref(), r, false),
                want[i],
                "{name} ray {i}"
            );
            assert_eq!(
                all_hits(accel.as_ref(), r, true),
                want_culled[i],
                "{name} ray {i} culled"
            );
        }
    }
}

#[test]
fn all_hits_on_spheres_report_entry_and_exit() {
    let mut rng = Rng(3);
    let b = Aabb::new(Vec3::splat(-4.0), Vec3::splat(4.0));
    let mut spheres = Spheres::default();
    for i in 0..120 {
        spheres.center.push(rng.point_in(&b));
        spheres.radius.push(if i % 10 == 0 { 2.0 } else { 0.4 });
    }
    // Two identical spheres.
    spheres.center.push(Vec3::ZERO);
    spheres.radius.push(1.0);
    spheres.center.push(Vec3::ZERO);
    spheres.radius.push(1.0);
    let n = spheres.count() as u32;
    let reference = BruteForce::new(spheres.clone());
    let through = Ray::new(Vec3::new(0.0, 0.0, -30.0), Vec3::Z);
    let rays = test_rays(&bounds_of(&spheres), 600);
    for (name, accel) in structures(&spheres) {
        let twins: Vec<(u32, f32, bool)> = all_hits(accel.as_ref(), &through, false)
            .iter()
            .filter(|c| c.hit.prim >= n - 2)
            .map(|c| (c.hit.prim, c.hit.t, c.front_face))
            .collect();
        assert_eq!(
            twins,
            vec![
                (n - 2, 29.0, true),
                (n - 1, 29.0, true),
                (n - 2, 31.0, false),
                (n - 1, 31.0, false)
            ],
            "{name}"
        );
        for (i, r) in rays.iter().enumerate() {
            assert_eq!(
                all_hits(accel.as_ref(), r, false),
                all_hits(&reference, r, false),
                "{name} ray {i}"
            );
        }
    }
}

/// Accepting everything is `closest_hit` (and with `any`, `any_hit`) on the same
/// structure, down to the primitive chosen on exact ties.
#[test]
fn accepting_everything_is_the_plain_query() {
    let prims = coincident_scene();
    let rays = test_rays(&bounds_of(&prims), 900);
    for (name, accel) in structures(&prims) {
        for (i, r) in rays.iter().enumerate() {
            let closest = accel.filtered_hit(r, QueryOptions::default(), &mut |_| true);
            assert_eq!(closest, accel.closest_hit(r), "{name} ray {i}");
            let any = QueryOptions {
                any: true,
                ..QueryOptions::default()
            };
            let first = accel.filtered_hit(r, any, &mut |_| true);
            assert_eq!(first.is_some(), accel.any_hit(r), "{name} ray {i}");
        }
    }
}

/// A filter that skips candidates: traversal goes on behind them, and the nearest
/// accepted candidate is the nearest of those the filter likes among all hits.
#[test]
fn rejected_candidates_let_traversal_continue() {
    let prims = coincident_scene();
    let rays = test_rays(&bounds_of(&prims), 900);
    let reference = BruteForce::new(prims.clone());
    let likes = |c: &Candidate| c.hit.prim % 3 == 1;
    let mut skipped = 0;
    for (name, accel) in structures(&prims) {
        for (i, r) in rays.iter().enumerate() {
            let everything = all_hits(&reference, r, false);
            let want = everything.iter().find(|c| likes(c)).map(|c| c.hit.t);
            skipped += (everything.first().map(|c| c.hit.t) != want) as usize;
            let got = accel.filtered_hit(r, QueryOptions::default(), &mut |c| likes(c));
            // Distances only: on an exact tie the structures may keep different ones.
            assert_eq!(got.map(|h| h.t), want, "{name} ray {i}");
            assert!(got.is_none_or(|h| h.prim % 3 == 1));
        }
    }
    assert!(skipped > 100, "the filter changed only {skipped} answers");
}

/// Every triangle of the mesh faces away from the origin (outward, counter-clockwise
/// seen from outside).
fn assert_outward(t: &Triangles) {
    for i in 0..t.count() {
        let n = (t.v1[i] - t.v0[i]).cross(t.v2[i] - t.v0[i]);
        let c = (t.v0[i] + t.v1[i] + t.v2[i]) / 3.0;
        assert!(n.dot(c) > 0.0, "triangle {i} faces inward");
    }
}

#[test]
fn back_face_culling_on_a_closed_mesh_from_outside_and_inside() {
    let (pos, tris) = bumpy_sphere(16, 24, 2.0);
    let mesh = triangles_of(&pos, &tris);
    assert_outward(&mesh);
    let mut rng = Rng(9);
    let cull = QueryOptions {
        cull_back_faces: true,
        any: false,
    };
    let cull_any = QueryOptions { any: true, ..cull };
    let outside: Vec<Ray> = (0..400)
        .map(|_| {
            let o = 6.0 * rng.unit_vector();
            let target = rng.range(-1.0, 1.0) * rng.unit_vector();
            Ray::new(o, target - o)
        })
        .collect();
    let inside: Vec<Ray> = (0..400)
        .map(|_| Ray::new(0.5 * rng.unit_vector(), rng.unit_vector()))
        .collect();
    for (name, accel) in structures(&mesh) {
        for r in &outside {
            // From outside the first surface met is a front face: culling changes nothing.
            let plain = accel.closest_hit(r);
            assert!(plain.is_some(), "{name}: aimed at the mesh");
            assert_eq!(accel.filtered_hit(r, cull, &mut |_| true), plain, "{name}");
            let hits = all_hits(accel.as_ref(), r, false);
            assert!(hits[0].front_face && !hits[hits.len() - 1].front_face);
        }
        for r in &inside {
            assert!(accel.closest_hit(r).is_some(), "{name}: closed mesh");
            assert_eq!(accel.filtered_hit(r, cull, &mut |_| true), None, "{name}");
            assert_eq!(accel.filtered_hit(r, cull_any, &mut |_| true), None);
            assert!(all_hits(accel.as_ref(), r, true).is_empty(), "{name}");
        }
    }
}

#[test]
fn back_face_culling_on_spheres() {
    let spheres = Spheres {
        center: vec![Vec3::ZERO, Vec3::new(5.0, 0.0, 0.0)],
        radius: vec![1.0, 1.0],
    };
    let cull = QueryOptions {
        cull_back_faces: true,
        any: false,
    };
    for (name, accel) in structures(&spheres) {
        let outside = Ray::new(Vec3::new(0.0, 0.0, -5.0), Vec3::Z);
        let h = accel.filtered_hit(&outside, cull, &mut |_| true);
        assert_eq!(h.map(|h| (h.prim, h.t)), Some((0, 4.0)), "{name}");
        // From the centre of the first sphere along +x: its exit (back face) is culled,
        // the second sphere's entry at 4 is the hit.
        let inside = Ray::new(Vec3::ZERO, Vec3::X);
        assert_eq!(accel.closest_hit(&inside).map(|h| h.t), Some(1.0));
        let h = accel.filtered_hit(&inside, cull, &mut |_| true);
        assert_eq!(h.map(|h| (h.prim, h.t)), Some((1, 4.0)), "{name}");
    }
}

/// Invalid rays hit nothing and never call the filter.
#[test]
fn invalid_rays_never_reach_the_filter() {
    let prims = coincident_scene();
    let bad = [
        Ray::new(Vec3::new(f32::NAN, 0.0, 5.0), -Vec3::Z),
        Ray::new(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO),
        Ray::segment(Vec3::new(0.0, 0.0, 5.0), -Vec3::Z, 3.0, 2.0),
    ];
    for (name, accel) in structures(&prims) {
        for r in &bad {
            let mut calls = 0;
            let h = accel.filtered_hit(r, QueryOptions::default(), &mut |_| {
                calls += 1;
                false
            });
            assert_eq!((h, calls), (None, 0), "{name}");
        }
    }
}

/// `SceneAccel::filtered_hit` walks every primitive kind (triangles, spheres, moving
/// spheres) with each structure: all candidates, the nearest accepted one across kinds,
/// and any mode stopping at the first accepted.
#[test]
fn scene_level_filtered_query_covers_every_primitive_kind() {
    use packet_render::accel::{PrimRef, SceneAccel, SceneCandidate};
    use packet_render::scene::{Material, SceneBuilder};
    let mut b = SceneBuilder::new();
    let m = b.add_material(Material::default());
    // Counter-clockwise seen from -z: the ray along +z meets its front face.
    b.add_triangle(
        Vec3::new(-3.0, -3.0, 0.0),
        Vec3::new(0.0, 3.0, 0.0),
        Vec3::new(3.0, -3.0, 0.0),
        m,
    );
    b.add_sphere(Vec3::new(0.1, 0.1, 2.0), 0.5, m);
    b.add_moving_sphere(Vec3::new(0.1, 0.1, 5.0), 0.5, Vec3::ZERO, m);
    let scene = b.finish().unwrap();
    let ray = Ray::new(Vec3::new(0.1, 0.1, -5.0), Vec3::Z);
    let want = [
        (PrimRef::Triangle(0), 5.0, true),
        (PrimRef::Sphere(0), 6.5, true),
        (PrimRef::Sphere(0), 7.5, false),
        (PrimRef::MovingSphere(0), 9.5, true),
        (PrimRef::MovingSphere(0), 10.5, false),
    ];
    for &kind in AccelKind::ALL {
        let accel = SceneAccel::build(&scene, kind);
        let seen = accel.all_hits(&ray, false);
        assert_eq!(seen.len(), want.len(), "{kind}: {seen:?}");
        for (c, &(prim, t, front)) in seen.iter().zip(&want) {
            // The spheres' roots are exact here (7.5, 48.75 / 7.5, ...); the triangle's t
            // carries the watertight test's few ulps of rounding.
            assert!(
                c.hit.prim == prim && c.front_face == front && (c.hit.t - t).abs() < 1e-5,
                "{kind}: {c:?} against {prim:?} {t} {front}"
            );
        }
        // Culled: the spheres' exits go.
        let culled: Vec<_> = accel
            .all_hits(&ray, true)
            .iter()
            .map(|c| c.hit.prim)
            .collect();
        assert_eq!(
            culled,
            [
                PrimRef::Triangle(0),
                PrimRef::Sphere(0),
                PrimRef::MovingSphere(0)
            ],
            "{kind}"
        );
        let not_triangles = |c: &SceneCandidate| !matches!(c.hit.prim, PrimRef::Triangle(_));
        let h = accel.filtered_hit(&ray, QueryOptions::default(), &mut |c| not_triangles(c));
        assert_eq!(h.map(|h| (h.prim, h.t)), Some((PrimRef::Sphere(0), 6.5)));
        let any = QueryOptions {
            any: true,
            ..QueryOptions::default()
        };
        let moving = |c: &SceneCandidate| matches!(c.hit.prim, PrimRef::MovingSphere(_));
        let h = accel.filtered_hit(&ray, any, &mut |c| moving(c));
        assert_eq!(h.map(|h| h.prim), Some(PrimRef::MovingSphere(0)), "{kind}");
    }
}
