//! Property-based tests (proptest) of the kernels and the builders: what must hold for
//! any input, not just the cases someone thought of. Case counts are modest (128-256)
//! so the suite stays fast.

use glam::Vec3;
use packet_render::accel::{Accel, AccelKind, BruteForce, Bvh2, Bvh4, Primitives, Triangles};
use packet_render::geometry::{Aabb, Ray, RayQuery, intersect_sphere, intersect_triangle};
use proptest::prelude::*;

fn vec3(r: f32) -> impl Strategy<Value = Vec3> {
    (-r..r, -r..r, -r..r).prop_map(|(x, y, z)| Vec3::new(x, y, z))
}

/// Directions including axis-parallel ones with signed zeros.
fn direction() -> impl Strategy<Value = Vec3> {
    prop_oneof![
        3 => vec3(1.0).prop_filter("non-zero", |d| d.length() > 1e-3),
        1 => (0usize..3, any::<bool>(), any::<bool>(), any::<bool>()).prop_map(|(a, s, z1, z2)| {
            let mut d = Vec3::new(if z1 { -0.0 } else { 0.0 }, if z2 { -0.0 } else { 0.0 }, 0.0);
            d = match a {
                0 => Vec3::new(1.0, d.x, d.y),
                1 => Vec3::new(d.x, 1.0, d.y),
                _ => Vec3::new(d.x, d.y, 1.0),
            };
            if s { -d } else { d }
        }),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    /// A triangle hit lies on the triangle's plane, has barycentrics in [0, 1] and a
    /// distance inside the open interval.
    #[test]
    fn triangle_hit_is_on_the_triangle(
        v0 in vec3(10.0), v1 in vec3(10.0), v2 in vec3(10.0),
        o in vec3(20.0), (u, v) in (0.0f32..1.0, 0.0f32..1.0),
        tmin in prop_oneof![Just(0.0f32), 0.0f32..1.0], tmax_scale in 0.5f32..4.0,
    ) {
        let (u, v) = if u + v > 1.0 { (1.0 - u, 1.0 - v) } else { (u, v) };
        let target = v0 + u * (v1 - v0) + v * (v2 - v0);
        let d = target - o;
        prop_assume!(d.length() > 1e-3);
        let tmax = tmin + tmax_scale;
        let q = RayQuery::new(&Ray::segment(o, d, tmin, tmax)).unwrap();
        if let Some(h) = intersect_triangle(&q, v0, v1, v2, tmax) {
            prop_assert!(h.t > tmin && h.t < tmax, "t {} outside ({tmin}, {tmax})", h.t);
            let eps = 1e-6;
            prop_assert!((-eps..=1.0 + eps).contains(&h.u), "u {}", h.u);
            prop_assert!((-eps..=1.0 + eps).contains(&h.v), "v {}", h.v);
            prop_assert!(h.u + h.v <= 1.0 + eps, "u + v {}", h.u + h.v);
            let n = (v1 - v0).cross(v2 - v0);
            prop_assume!(n.length() > 1e-3);
            let n = n.normalize();
            let p = o + h.t * d;
            let scale = o.abs().max_element() + (h.t * d).abs().max_element()
                + v0.abs().max(v1.abs()).max(v2.abs()).max_element();
            // Relative to the magnitudes involved, divided by how steeply the ray meets
            // the plane (a grazing ray's t error moves p along the plane, mostly).
            let bound = 1e-5 * scale;
            prop_assert!(n.dot(p - v0).abs() <= bound, "off plane by {} > {bound}", n.dot(p - v0).abs());
        } else if tmin == 0.0 && tmax_scale > 1.001 {
            // Aimed at an interior point inside the interval: only a degenerate
            // (near zero-area or edge-on) triangle may be missed.
            let n = (v1 - v0).cross(v2 - v0);
            let cos = n.normalize_or_zero().dot(d.normalize()).abs();
            prop_assert!(n.length() < 1e-2 || cos < 1e-3 || u.min(v).min(1.0 - u - v) < 1e-4,
                "missed an interior point: cos {cos}, |n| {}", n.length());
        }
    }

    /// A sphere hit lies on the sphere: | |o + t d - c| - r | is small relative to the
    /// magnitudes involved.
    #[test]
    fn sphere_hit_is_on_the_sphere(c in vec3(100.0), r in 1e-3f32..50.0, o in vec3(200.0), d in direction()) {
        let q = RayQuery::new(&Ray::new(o, d)).unwrap();
        if let Some(t) = intersect_sphere(&q, c, r, f32::INFINITY) {
            prop_assert!(t > 0.0 && t.is_finite());
            let p = o + t * d;
            let err = ((p - c).length() - r).abs();
            let bound = 1e-5 * (o.abs().max_element() + c.abs().max_element() + r + (t * d).length());
            prop_assert!(err <= bound, "off the sphere by {err} > {bound}");
        }
    }

    /// The slab test is conservative: a box containing a point of the ray, within the
    /// interval, is never missed (whatever the signs and zeros of the direction).
    #[test]
    fn slab_test_never_misses_a_box_the_ray_passes_through(
        lo in vec3(50.0), ext in (0.0f32..20.0, 0.0f32..20.0, 0.0f32..20.0),
        (fx, fy, fz) in (0.0f32..=1.0, 0.0f32..=1.0, 0.0f32..=1.0),
        d in direction(), t in 0.0f32..100.0,
    ) {
        let b = Aabb::new(lo, lo + Vec3::new(ext.0, ext.1, ext.2));
        let p = b.min + Vec3::new(fx, fy, fz) * (b.max - b.min);
        let o = p - t * d;
        // Rounding of o can move it off the plane of a flat box by an ulp; the slab test
        // must still see p, which lies at distance ~t.
        prop_assume!(b.min.cmple(p).all() && p.cmple(b.max).all());
        let q = RayQuery::new(&Ray::new(o, d)).unwrap();
        let hit = b.intersect(q.origin, q.inv_dir, 0.0, f32::INFINITY);
        // Only assert for points the f32 ray really passes through (o + t d == p up to
        // the rounding of o itself).
        let back = o + t * d;
        if b.min.cmple(back).all() && back.cmple(b.max).all() {
            prop_assert!(hit.is_some(), "box {b:?} missed by ray {o} {d}, point {p} at t {t}");
        }
    }
}

/// The leaf flag of a BVH4 child reference, as documented on `Bvh4Node::children`.
const LEAF: u32 = 1 << 31;

fn soup() -> impl Strategy<Value = Triangles> {
    prop::collection::vec((vec3(5.0), vec3(1.5), vec3(1.5)), 1..160).prop_map(|v| {
        let corners: Vec<[Vec3; 3]> = v.iter().map(|&(c, a, b)| [c, c + a, c + b]).collect();
        Triangles::from_corners(&corners)
    })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    /// Any soup: every structure and path gives the brute-force answer on random rays.
    #[test]
    fn structures_match_brute_force_on_any_soup(
        tris in soup(),
        rays in prop::collection::vec((vec3(12.0), direction()), 16..64),
    ) {
        let rays: Vec<Ray> = rays.iter().map(|&(o, d)| Ray::new(o, d)).collect();
        let reference = BruteForce::new(tris.clone());
        let want: Vec<_> = rays.iter().map(|r| reference.closest_hit(r)).collect();
        for &kind in AccelKind::ALL {
            let a = kind.build(tris.clone());
            let mut batch = vec![None; rays.len()];
            for (r, o) in rays.chunks(16).zip(batch.chunks_mut(16)) {
                a.closest_hit_batch(r, o);
            }
            for (i, r) in rays.iter().enumerate() {
                for (path, got) in [("single", a.closest_hit(r)), ("packet", batch[i])] {
                    let same = match (want[i], got) {
                        (None, None) => true,
                        (Some(w), Some(g)) => w.t == g.t && (w.prim == g.prim || {
                            // an exact tie: the other triangle is hit at the same t
                            let q = RayQuery::new(r).unwrap();
                            tris.intersect(g.prim as usize, &q, f32::INFINITY).is_some_and(|h| h.t == w.t)
                        }),
                        _ => false,
                    };
                    prop_assert!(same, "{kind}/{path} ray {i} {r:?}: {got:?}, brute force {:?}", want[i]);
                }
                prop_assert_eq!(a.any_hit(r), want[i].is_some(), "{}/any ray {}", kind, i);
            }
        }
    }

    /// Every primitive appears in exactly one leaf: the BVH2's leaves partition its
    /// primitive order, which is a permutation of the input; the BVH4's leaf references
    /// partition its triangle groups, which hold every triangle once.
    #[test]
    fn every_primitive_is_in_exactly_one_leaf(tris in soup()) {
        let n = tris.count();
        let bvh2 = Bvh2::build(tris.clone());
        let mut ids = bvh2.prim_ids.clone();
        ids.sort_unstable();
        prop_assert_eq!(ids, (0..n as u32).collect::<Vec<_>>());
        let mut ranges: Vec<(u32, u32)> = bvh2
            .nodes
            .iter()
            .filter(|nd| nd.is_leaf())
            .map(|nd| (nd.first, nd.count))
            .collect();
        ranges.sort_unstable();
        let mut next = 0;
        for (first, count) in ranges {
            prop_assert_eq!(first, next, "BVH2 leaves overlap or leave a gap");
            next = first + count;
        }
        prop_assert_eq!(next as usize, n);

        let bvh4 = Bvh4::build(tris.clone());
        // Child references: LEAF | count << 27 | first (see Bvh4Node).
        let mut groups: Vec<(u32, u32)> = bvh4
            .nodes
            .iter()
            .flat_map(|nd| nd.children)
            .filter(|&c| c & LEAF != 0 && c != LEAF)
            .map(|c| (c & ((1 << 27) - 1), (c & !LEAF) >> 27))
            .collect();
        if bvh4.nodes.is_empty() {
            // A root that is a single leaf is not stored in a node; nothing to decode.
            prop_assert!(n <= 4);
        } else {
            groups.sort_unstable();
            let mut next = 0;
            for (first, count) in groups {
                prop_assert_eq!(first, next, "BVH4 leaves overlap or leave a gap");
                next = first + count;
            }
            // Four triangles per group at most: at least ceil(n / 4) groups.
            prop_assert!(next as usize >= n.div_ceil(4));
        }
        prop_assert_eq!(bvh4.info().primitives, n);
    }
}
