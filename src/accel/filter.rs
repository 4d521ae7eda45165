//! Filtered ray queries: an intersection filter called for every candidate hit during
//! traversal, after Embree's `RTCFilterFunctionN` (Wald et al., "Embree: A Kernel
//! Framework for Efficient CPU Ray Tracing", SIGGRAPH 2014, and the Embree manual,
//! "Filter Functions").
//!
//! One mechanism serves three queries:
//!
//! - **all hits**: a filter that records each candidate and rejects it sees every hit
//!   of the ray in `(tmin, tmax)` exactly once ([`all_hits`]);
//! - **back-face culling**: [`QueryOptions::cull_back_faces`] drops hits on the back
//!   face before the filter sees them;
//! - **transmitted shadows**: the integrators multiply the transmission of every
//!   dielectric hit and reject it; an opaque hit is accepted and ends the query
//!   (`integrator::shadow`).
//!
//! # Semantics (every structure in `AccelKind::ALL`)
//!
//! A *candidate* is one intersection of the ray with one primitive inside the strict
//! interval `(tmin, tmax)` (a triangle has at most one, a sphere up to two: entry and
//! exit). The traversal offers a candidate to the filter if it is nearer than every
//! candidate accepted so far; the filter returns `true` to accept it. Then:
//!
//! - each candidate is offered **at most once**, also where a spatial subdivision
//!   holds a primitive in several cells (the structure remembers which primitives it
//!   tested: [`TestedSet`]) and for coincident or duplicated primitives (each one is
//!   its own candidate, with its own `prim`);
//! - a filter that rejects everything is offered **every** candidate, so the set of
//!   candidates is the same for every structure (the tests compare it with brute
//!   force);
//! - candidates come in traversal order, not sorted: [`all_hits`] sorts them by
//!   `(t, prim)`, which is also how to walk the hits along a ray in order;
//! - in closest mode the result is the nearest accepted candidate (for a filter that
//!   is a function of the candidate alone this is the same hit for every structure, up
//!   to exact ties in `t`, as for `closest_hit`); with [`QueryOptions::any`] the query
//!   ends at the first accepted candidate and returns it.
//!
//! Packet structures run filtered queries ray by ray: the filter is a per-candidate
//! callback, which does not vectorise, and the unfiltered `closest_hit` / `any_hit`
//! paths stay exactly as they were (filtered queries are separate entry points).
//!
//! Why not re-issue `closest_hit` from the last hit with `tmin = t`: the interval is
//! open, so a second primitive at exactly the same `t` (coincident or duplicated
//! triangles) is never found; an inclusive `tmin` would find the same primitive again.
//! The filter needs neither.

use super::Primitives;
use crate::geometry::{Hit, PrimHit, RayQuery};
use std::collections::HashSet;

/// Options of a filtered query.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct QueryOptions {
    /// Drop candidates on the back face of their primitive before the filter sees them.
    /// The front face of a triangle is the side its normal `(v1 - v0) x (v2 - v0)`
    /// points to (counter-clockwise winding seen from there, the OBJ convention); the
    /// front face of a sphere is its outside. A ray from inside a closed, consistently
    /// wound mesh therefore hits nothing.
    pub cull_back_faces: bool,
    /// Any-hit mode: end the query at the first accepted candidate.
    pub any: bool,
}

/// One candidate hit offered to a filter.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Candidate {
    pub hit: Hit,
    /// Whether the ray meets the front face (see [`QueryOptions::cull_back_faces`]).
    pub front_face: bool,
}

/// The filter callback: `true` accepts the candidate.
pub type HitFilter<'a> = dyn FnMut(&Candidate) -> bool + 'a;

/// Every hit of the ray in its interval on one structure, sorted by `(t, prim)`
/// (sphere exits after their entries at equal `t`, which only a tangent ray gives).
pub fn all_hits(
    accel: &dyn super::Accel,
    ray: &crate::geometry::Ray,
    cull_back_faces: bool,
) -> Vec<Candidate> {
    let mut hits = Vec::new();
    let opts = QueryOptions {
        cull_back_faces,
        any: false,
    };
    accel.filtered_hit(ray, opts, &mut |c| {
        hits.push(*c);
        false
    });
    sort_candidates(&mut hits);
    hits
}

/// Sorts candidates by `(t, prim)`, front faces first on ties.
pub fn sort_candidates(hits: &mut [Candidate]) {
    hits.sort_by(|a, b| {
        a.hit
            .t
            .total_cmp(&b.hit.t)
            .then(a.hit.prim.cmp(&b.hit.prim))
            .then(b.front_face.cmp(&a.front_face))
    });
}

/// Which primitives a filtered traversal has tested, for structures that reference a
/// primitive from several cells. Testing a primitive offers all its candidates at
/// once, so a second test could only offer them again.
#[derive(Default)]
pub struct TestedSet {
    ids: HashSet<u32>,
}

impl TestedSet {
    /// True the first time `id` is seen.
    #[inline]
    pub fn first_time(&mut self, id: u32) -> bool {
        self.ids.insert(id)
    }
}

/// The state of one filtered traversal: the current end of the interval (the nearest
/// accepted candidate), the result, the filter and the options.
pub(crate) struct FilterSink<'f, 'a> {
    pub tmax: f32,
    pub best: Option<Hit>,
    pub opts: QueryOptions,
    pub filter: &'f mut HitFilter<'a>,
    /// `Some` for structures whose cells share primitives.
    pub tested: Option<TestedSet>,
}

impl<'f, 'a> FilterSink<'f, 'a> {
    pub fn new(q: &RayQuery, opts: QueryOptions, filter: &'f mut HitFilter<'a>) -> Self {
        FilterSink {
            tmax: q.tmax,
            best: None,
            opts,
            filter,
            tested: None,
        }
    }

    /// With deduplication of primitives referenced more than once.
    pub fn deduplicating(mut self) -> Self {
        self.tested = Some(TestedSet::default());
        self
    }

    /// Tests primitive `k` of `prims`, reported as `id`, and offers its candidates.
    /// Returns true when the traversal is finished (any mode, a candidate accepted).
    #[inline]
    pub fn test<P: Primitives>(&mut self, prims: &P, k: usize, id: u32, q: &RayQuery) -> bool {
        self.test_with(id, |tmax, f| prims.intersect_each(k, q, tmax, f))
    }

    /// Offers the candidates `candidates(tmax, f)` passes to `f` as primitive `id`'s
    /// (for leaves that store primitives in their own layout).
    #[inline]
    pub fn test_with(
        &mut self,
        id: u32,
        candidates: impl FnOnce(f32, &mut dyn FnMut(PrimHit, bool)),
    ) -> bool {
        if let Some(t) = &mut self.tested
            && !t.first_time(id)
        {
            return false;
        }
        let mut done = false;
        let tmax = self.tmax;
        candidates(tmax, &mut |h, front| {
            if !done {
                done = self.offer(id, h, front);
            }
        });
        done
    }

    /// Offers one candidate (already inside `(tmin, tmax)` when tested, but an earlier
    /// candidate of the same primitive may have been accepted since). Returns true
    /// when the traversal is finished.
    #[inline]
    pub fn offer(&mut self, id: u32, h: PrimHit, front_face: bool) -> bool {
        // `h.t` is never NaN: the primitive tests return only distances inside the
        // interval.
        if h.t >= self.tmax || (self.opts.cull_back_faces && !front_face) {
            return false;
        }
        let hit = Hit {
            t: h.t,
            prim: id,
            u: h.u,
            v: h.v,
        };
        if (self.filter)(&Candidate { hit, front_face }) {
            self.best = Some(hit);
            self.tmax = h.t;
            return self.opts.any;
        }
        false
    }
}

/// The candidate of one triangle: the watertight test's hit (the same arithmetic as
/// `closest_hit`, so a filter accepting everything returns exactly its hit) and the
/// face, from the sign of the geometric normal along the ray (the rule
/// `SurfaceInteraction` uses for shading).
#[inline]
pub fn triangle_candidates(
    q: &RayQuery,
    [v0, v1, v2]: [glam::Vec3; 3],
    tmax: f32,
    f: &mut dyn FnMut(PrimHit, bool),
) {
    if let Some(h) = crate::geometry::intersect_triangle(q, v0, v1, v2, tmax) {
        let front = (v1 - v0).cross(v2 - v0).dot(q.dir) < 0.0;
        f(h, front);
    }
}

/// The candidates of one sphere, nearest first: the stable test's root in
/// `(tmin, tmax)`, then the next root beyond it (the same test with `tmin` moved to
/// the first root, so both roots are the numbers `closest_hit` would report). A root
/// is on the front face where the ray enters, `(o + t d - c) . d < 0`.
#[inline]
pub fn sphere_candidates(
    q: &RayQuery,
    center: glam::Vec3,
    radius: f32,
    tmax: f32,
    f: &mut dyn FnMut(PrimHit, bool),
) {
    let face = |t: f32| (q.origin + t * q.dir - center).dot(q.dir) < 0.0;
    let hit = |t| PrimHit { t, u: 0.0, v: 0.0 };
    let Some(t0) = crate::geometry::intersect_sphere(q, center, radius, tmax) else {
        return;
    };
    f(hit(t0), face(t0));
    let mut beyond = *q;
    beyond.tmin = t0;
    if let Some(t1) = crate::geometry::intersect_sphere(&beyond, center, radius, tmax) {
        f(hit(t1), face(t1));
    }
}
