//! Pieces shared by the spatial subdivisions (grid, octree, kd-tree): the conservative
//! cell-assignment margin, ray/box clipping that returns the whole interval, traversal
//! counters and the per-ray mailbox.
//!
//! Robustness rule of all three structures: the *hit* is always decided by the
//! watertight primitive test with the ray's own strict interval; the structure only
//! decides which primitives are tested. A primitive is therefore assigned to every
//! cell, voxel or leaf region it overlaps when grown by its margin
//! ([`primitive_margin`]), so that a primitive whose surface lies within rounding
//! distance of a region is in it, and the traversal may round cell boundaries either
//! way without ever skipping a primitive the ray hits.

use super::filter::{FilterSink, HitFilter, QueryOptions};
use super::{Accel, AccelInfo, Primitives};
use crate::geometry::{Aabb, Hit, Ray, RayQuery, gamma};
use glam::Vec3;

/// Traversal work of one ray: node (cell, voxel, BVH node) visits and primitive tests.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TraversalCounts {
    pub nodes: u64,
    pub prim_tests: u64,
}

impl TraversalCounts {
    #[inline(always)]
    pub(crate) fn node<const COUNT: bool>(&mut self) {
        if COUNT {
            self.nodes += 1;
        }
    }

    #[inline(always)]
    pub(crate) fn prim<const COUNT: bool>(&mut self) {
        if COUNT {
            self.prim_tests += 1;
        }
    }
}

/// Relative rounding unit of f32 (`2^-24`, half an ulp at 1).
const UNIT_ROUNDOFF: f32 = f32::EPSILON * 0.5;

/// Units of roundoff in the margin of a primitive relative to its own coordinates: the
/// overlap tests and cell/plane computations round each coordinate a few times (at
/// most about 8 units each); 64 leaves a factor 8 of slack.
const PRIMITIVE_MARGIN_UNITS: f32 = 64.0;

/// Margin by which primitive `b` (its bounds) is grown when it is assigned to cells,
/// voxels or leaves: a bound of the rounding of its own coordinates,
/// `64 u (extent + magnitude)` of `b` with `u = 2^-24` (never zero: at least `1e-30`).
///
/// Relative to the primitive, not to the scene (issue 13): the margin used to be
/// `1e-5 extent + 1e-6 magnitude` of the *scene*, which inside a huge sparse enclosure
/// swallowed a whole small mesh. A 20k-triangle mesh of radius 1 inside a box of half
/// size 5e4 took 20034 (octree) and 33978 (kd-tree) primitive tests per ray against
/// 7.2 and 4.7 for the mesh alone; now 24 and 23 (tests/suite/hostile_scenes.rs). What this
/// margin does not bound is the traversal's rounding of plane distances, a few units of
/// the distance from the ray origin: the traversals bound that themselves
/// ([`PLANE_DISTANCE_ERROR`], the grid's f64 walk); see docs/robustness.md, "Assignment
/// margins".
pub fn primitive_margin(b: &Aabb) -> f32 {
    let extent = b.extent().max_element();
    let magnitude = b.min.abs().max(b.max.abs()).max_element();
    (PRIMITIVE_MARGIN_UNITS * UNIT_ROUNDOFF * (extent + magnitude)).max(1e-30)
}

/// Units of roundoff, relative to a region's largest extent, added to the primitive's
/// margin for that region.
const REGION_MARGIN_UNITS: f32 = 32.0;

/// Extra margin of a cell, voxel or leaf region: `32 u (extent + magnitude)` of the
/// region. The overlap tests work relative to the region's centre and the grid maps
/// points to cells relative to its corner, so their rounding grows with the region's
/// size and position (a primitive inside a node of size 10^5 is seen to within
/// `~10^5 u`), which a margin relative to a small primitive alone would not cover.
pub fn region_margin(region: &Aabb) -> f32 {
    let extent = region.extent().max_element();
    let magnitude = region.min.abs().max(region.max.abs()).max_element();
    REGION_MARGIN_UNITS * UNIT_ROUNDOFF * (extent + magnitude)
}

/// Every primitive's bounds and margin ([`primitive_margin`]), and the largest margin.
pub fn bounds_and_margins<P: super::Primitives>(prims: &P) -> (Vec<Aabb>, Vec<f32>, f32) {
    let bounds: Vec<Aabb> = (0..prims.count()).map(|i| prims.bounds(i)).collect();
    let pads: Vec<f32> = bounds.iter().map(primitive_margin).collect();
    let max = pads.iter().copied().fold(0.0, f32::max);
    (bounds, pads, max)
}

/// `b` grown by `pad` on every side.
#[inline]
pub fn grown(b: &Aabb, pad: f32) -> Aabb {
    Aabb::new(b.min - Vec3::splat(pad), b.max + Vec3::splat(pad))
}

/// Whether two boxes overlap (closed intervals).
#[inline]
pub fn boxes_overlap(a: &Aabb, b: &Aabb) -> bool {
    a.min.cmple(b.max).all() && b.min.cmple(a.max).all()
}

/// Relative bound on the error of a plane distance `t = (x - o) * inv_dir` computed in
/// f32, as used by the conservative traversal decisions: `2 γ(3)`.
///
/// Derivation (Ize 2013, "Robust BVH Ray Traversal", JCGT 2(2); pbrt-v4 §6.8.2): the
/// difference `x - o`, the reciprocal `1 / d` and the product each round once, so the
/// computed `t̃ = t* (1 + δ)` with `|δ| <= γ(3)` relative to the exact distance `t*`;
/// then `|t̃ - t*| <= γ(3) |t*| <= γ(3) |t̃| / (1 - γ(3))`, which is below `2 γ(3) |t̃|`.
/// The factor 2 (Ize's far-plane scale `1 + 2 γ(3)`, [`crate::geometry::ROBUST_FAR_SCALE`]
/// in spirit) also covers the rounding of the bound itself, and leaves as much again for
/// the primitive test's own rounding of a hit's `t` (a few `u`, compared with these
/// bounds when a traversal decides to stop).
pub const PLANE_DISTANCE_ERROR: f32 = 2.0 * gamma(3);

/// Bound on the error of the f32 plane distance `t` ([`PLANE_DISTANCE_ERROR`] `|t|`),
/// at most `f32::MAX` so that `t ± plane_error(t)` stays `±inf` for an infinite `t`
/// (never NaN).
#[inline(always)]
pub fn plane_error(t: f32) -> f32 {
    (PLANE_DISTANCE_ERROR * t.abs()).min(f32::MAX)
}

/// The part `(enter, exit)` of the ray's interval inside `b`, or `None`, conservatively:
/// every slab distance is widened by its error bound ([`plane_error`]) before the
/// comparison, so the result contains the exact ray's interval inside `b` (within the
/// query's `[tmin, tmax]`), and `None` means the exact ray misses `b`. The returned
/// bounds are lower/upper bounds, not exact distances.
///
/// Same plane selection as [`Aabb::intersect`] (by the sign of `inv_dir`, so `-0.0`
/// picks the planes of a negative direction and an empty box is never entered), and the
/// same NaN rule: a ray lying in a slab plane gives `0 * inf = NaN`, which `max`/`min`
/// ignore, so the ray counts as inside that slab.
#[inline]
pub fn clip_conservative(b: &Aabb, q: &RayQuery) -> Option<(f32, f32)> {
    let mut enter = q.tmin;
    let mut exit = q.tmax;
    for a in 0..3 {
        let (near, far) = if q.inv_dir[a].is_sign_negative() {
            (b.max[a], b.min[a])
        } else {
            (b.min[a], b.max[a])
        };
        let tn = (near - q.origin[a]) * q.inv_dir[a];
        let tf = (far - q.origin[a]) * q.inv_dir[a];
        enter = enter.max(tn - plane_error(tn));
        exit = exit.min(tf + plane_error(tf));
    }
    (enter <= exit).then_some((enter, exit))
}

/// Whether the ray can be traversed along axis `a`: a zero (either sign) or subnormal
/// direction component has an infinite reciprocal, and the ray is treated as parallel
/// to that axis's planes (a subnormal component moves the ray by less than the
/// assignment margin over any finite distance of a normal-sized direction).
#[inline(always)]
pub fn moves_along(q: &RayQuery, a: usize) -> bool {
    q.inv_dir[a].is_finite() && q.dir[a] != 0.0
}

/// Per-ray mailbox (Amanatides & Woo 1987; Kirk & Arvo 1991): a small direct-mapped
/// cache of the ids of the primitives this ray has already tested, carried on the
/// traversal's stack. It needs no shared state, so any number of rays can run
/// concurrently, and it costs 128 bytes per ray. A primitive is retested only if
/// another id with the same low bits was tested in between (then the test is merely
/// repeated; the answer is the same, since the ray's interval only shrinks).
pub struct Mailbox {
    ids: [u32; MAILBOX_SLOTS],
}

/// Slots of the mailbox (a power of two).
pub const MAILBOX_SLOTS: usize = 32;

impl Mailbox {
    #[inline(always)]
    pub fn new() -> Self {
        Mailbox {
            ids: [u32::MAX; MAILBOX_SLOTS],
        }
    }

    /// True if `id` was tested already; otherwise records it and returns false.
    #[inline(always)]
    pub fn seen(&mut self, id: u32) -> bool {
        let slot = &mut self.ids[id as usize & (MAILBOX_SLOTS - 1)];
        if *slot == id {
            true
        } else {
            *slot = id;
            false
        }
    }
}

impl Default for Mailbox {
    fn default() -> Self {
        Self::new()
    }
}

/// Conservative triangle/box overlap: the separating-axis test of Akenine-Möller
/// ("Fast 3D Triangle-Box Overlap Testing", JGT 2001): the box's three face normals,
/// the triangle's normal and the nine edge cross products. Returns false only if one of
/// the 13 axes separates them; callers pass a box already grown by the assignment
/// margin, which is far above the rounding of these products.
pub fn triangle_overlaps_box(v0: Vec3, v1: Vec3, v2: Vec3, b: &Aabb) -> bool {
    let c = b.center();
    let h = 0.5 * (b.max - b.min);
    let (a, bb, cc) = (v0 - c, v1 - c, v2 - c);
    // box face normals
    let tmin = a.min(bb).min(cc);
    let tmax = a.max(bb).max(cc);
    if tmin.cmpgt(h).any() || tmax.cmplt(-h).any() {
        return false;
    }
    let e = [bb - a, cc - bb, a - cc];
    // nine edge cross products
    for edge in e {
        for axis in [Vec3::X, Vec3::Y, Vec3::Z] {
            let l = axis.cross(edge);
            let (p0, p1, p2) = (l.dot(a), l.dot(bb), l.dot(cc));
            let r = h.x * l.x.abs() + h.y * l.y.abs() + h.z * l.z.abs();
            if p0.min(p1).min(p2) > r || p0.max(p1).max(p2) < -r {
                return false;
            }
        }
    }
    // triangle normal
    let n = e[0].cross(e[1]);
    let d = n.dot(a);
    let r = h.x * n.x.abs() + h.y * n.y.abs() + h.z * n.z.abs();
    d.abs() <= r || !d.is_finite()
}

/// Conservative sphere/box overlap (Arvo, "A Simple Method for Box-Sphere Intersection
/// Testing", Graphics Gems 1990): squared distance from the centre to the box.
pub fn sphere_overlaps_box(center: Vec3, radius: f32, b: &Aabb) -> bool {
    let d = (b.min - center).max(Vec3::ZERO) + (center - b.max).max(Vec3::ZERO);
    d.length_squared() <= radius * radius * (1.0 + 1e-5)
}

/// What a spatial traversal does with the primitives of a cell, voxel or leaf: the
/// plain closest/any hit ([`NearestSink`]) or a filtered query ([`FilterSink`]). The
/// traversals are generic over it (monomorphised, the sink a by-value local holding
/// the `tmax` and hit the traversals kept before), so the plain queries do the same
/// work as before filters existed.
pub(crate) trait LeafSink {
    /// The current end of the ray's interval (the nearest hit kept so far).
    fn tmax(&self) -> f32;
    /// Tests primitive `id`; true ends the traversal.
    fn test<P: Primitives>(&mut self, prims: &P, id: u32, q: &RayQuery) -> bool;
}

/// The plain query: nearest hit, or (`ANY`) the first hit found.
pub(crate) struct NearestSink<const ANY: bool> {
    tmax: f32,
    best: Option<Hit>,
}

impl<const ANY: bool> NearestSink<ANY> {
    #[inline(always)]
    pub fn new(q: &RayQuery) -> Self {
        NearestSink {
            tmax: q.tmax,
            best: None,
        }
    }
}

impl<const ANY: bool> LeafSink for NearestSink<ANY> {
    #[inline(always)]
    fn tmax(&self) -> f32 {
        self.tmax
    }

    #[inline(always)]
    fn test<P: Primitives>(&mut self, prims: &P, id: u32, q: &RayQuery) -> bool {
        if let Some(h) = prims.intersect(id as usize, q, self.tmax) {
            self.best = Some(Hit {
                t: h.t,
                prim: id,
                u: h.u,
                v: h.v,
            });
            if ANY {
                return true;
            }
            self.tmax = h.t;
        }
        false
    }
}

impl LeafSink for FilterSink<'_, '_> {
    #[inline]
    fn tmax(&self) -> f32 {
        self.tmax
    }

    #[inline]
    fn test<P: Primitives>(&mut self, prims: &P, id: u32, q: &RayQuery) -> bool {
        FilterSink::test(self, prims, id as usize, id, q)
    }
}

/// What a spatial subdivision implements: one traversal, generic over what it does
/// with the primitives it reaches ([`LeafSink`]), with a compile-time switch for
/// counting (`COUNT`). The sink is passed by value and handed back, so that the plain
/// query's `tmax` and hit stay traversal locals as they were before sinks. The
/// `Accel` entry points and the counting twin are written once, below, for all three
/// structures.
pub(crate) trait CountedTraversal: Send + Sync {
    fn traverse_with<const COUNT: bool, S: LeafSink>(
        &self,
        q: &RayQuery,
        sink: S,
    ) -> (S, TraversalCounts);

    fn build_info(&self) -> &AccelInfo;

    /// Closest hit with traversal counts (the counting twin of `closest_hit`).
    fn closest_hit_counted(&self, ray: &Ray) -> (Option<Hit>, TraversalCounts) {
        match RayQuery::new(ray) {
            Some(q) => {
                let (sink, counts) =
                    self.traverse_with::<true, _>(&q, NearestSink::<false>::new(&q));
                (sink.best, counts)
            }
            None => (None, TraversalCounts::default()),
        }
    }
}

impl<T: CountedTraversal> Accel for T {
    fn closest_hit(&self, ray: &Ray) -> Option<Hit> {
        let q = RayQuery::new(ray)?;
        self.traverse_with::<false, _>(&q, NearestSink::<false>::new(&q))
            .0
            .best
    }

    fn any_hit(&self, ray: &Ray) -> bool {
        RayQuery::new(ray).is_some_and(|q| {
            let (sink, _) = self.traverse_with::<false, _>(&q, NearestSink::<true>::new(&q));
            sink.best.is_some()
        })
    }

    /// Primitives spanning several cells are tested once (the sink deduplicates).
    fn filtered_hit(
        &self,
        ray: &Ray,
        opts: QueryOptions,
        filter: &mut HitFilter<'_>,
    ) -> Option<Hit> {
        let q = RayQuery::new(ray)?;
        let sink = FilterSink::new(&q, opts, filter).deduplicating();
        self.traverse_with::<false, _>(&q, sink).0.best
    }

    fn traversal_counts(&self, ray: &Ray) -> Option<TraversalCounts> {
        Some(self.closest_hit_counted(ray).1)
    }

    fn info(&self) -> AccelInfo {
        self.build_info().clone()
    }
}

/// Scenes and checks the unit tests of the three spatial subdivisions share.
#[cfg(test)]
pub(crate) mod test_scenes {
    use crate::accel::{Accel, BruteForce, Triangles};
    use crate::geometry::Ray;
    use glam::Vec3;

    pub fn tri(a: [f32; 3], b: [f32; 3], c: [f32; 3]) -> [Vec3; 3] {
        [Vec3::from(a), Vec3::from(b), Vec3::from(c)]
    }

    /// 10,000 copies of one triangle.
    pub fn identical_triangles() -> Triangles {
        let t = tri([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
        Triangles::from_corners(&vec![t; 10_000])
    }

    /// The ray straight down onto [`identical_triangles`] hits at t = 1.
    pub fn hits_identical_triangles(a: &dyn Accel) {
        let h = a
            .closest_hit(&Ray::new(Vec3::new(0.2, 0.2, 1.0), -Vec3::Z))
            .unwrap();
        assert_eq!(h.t, 1.0);
    }

    /// 400 triangles in z = 0 (a zero-thickness scene box): the structure built by
    /// `build` has more than one node and agrees with brute force on rays from above and
    /// on rays lying in the plane.
    pub fn flat_scene_agrees_with_brute_force<A: Accel>(build: impl Fn(Triangles) -> A) {
        let corners: Vec<_> = (0..400)
            .map(|i| {
                let x = (i % 20) as f32;
                let y = (i / 20) as f32;
                tri([x, y, 0.0], [x + 1.0, y, 0.0], [x, y + 1.0, 0.0])
            })
            .collect();
        let prims = Triangles::from_corners(&corners);
        let a = build(prims.clone());
        assert!(a.info().nodes > 1);
        let bf = BruteForce::new(prims);
        for i in 0..400 {
            let org = Vec3::new(i as f32 * 0.05 - 0.5, (i % 13) as f32 * 1.5, 3.0);
            for d in [
                Vec3::new(0.1, 0.2, -1.0),
                -Vec3::Z,
                Vec3::new(0.3, 1.0, -1.0),
            ] {
                let r = Ray::new(org, d);
                assert_eq!(
                    a.closest_hit(&r).map(|h| h.t),
                    bf.closest_hit(&r).map(|h| h.t)
                );
                let r = Ray::new(Vec3::new(org.x, org.y, 0.0), Vec3::new(d.x, d.y, -0.0));
                assert_eq!(a.any_hit(&r), bf.any_hit(&r));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sat_accepts_touching_and_rejects_separated() {
        let b = Aabb::new(Vec3::ZERO, Vec3::ONE);
        // diagonal triangle whose bounds cover the box's corner region but which misses it
        let far = [
            Vec3::new(1.65, 0.0, 1.65),
            Vec3::new(1.65, 1.65, 0.0),
            Vec3::new(0.0, 1.65, 1.65),
        ];
        assert!(!triangle_overlaps_box(far[0], far[1], far[2], &b));
        let through = [
            Vec3::new(0.5, -1.0, 0.5),
            Vec3::new(2.0, 2.0, 0.5),
            Vec3::new(-1.0, 2.0, 0.5),
        ];
        assert!(triangle_overlaps_box(
            through[0], through[1], through[2], &b
        ));
        // touching a face from outside
        assert!(triangle_overlaps_box(
            Vec3::new(1.0, 0.2, 0.2),
            Vec3::new(2.0, 0.2, 0.2),
            Vec3::new(1.0, 0.8, 0.8),
            &b
        ));
        assert!(sphere_overlaps_box(Vec3::new(2.0, 0.5, 0.5), 1.0, &b));
        assert!(!sphere_overlaps_box(Vec3::new(2.0, 2.0, 2.0), 1.0, &b));
    }

    #[test]
    fn mailbox_remembers_recent_ids() {
        let mut m = Mailbox::new();
        assert!(!m.seen(7));
        assert!(m.seen(7));
        assert!(!m.seen(7 + MAILBOX_SLOTS as u32));
        assert!(!m.seen(7));
    }
}
