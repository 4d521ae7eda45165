//! Acceleration structures, all interchangeable behind [`Accel`].
//!
//! Each structure is built over one primitive set ([`Triangles`] or [`Spheres`], both
//! implementing [`Primitives`]) and owns the copy of the primitive data it traverses, in
//! the order its leaves want. [`SceneAccel`] holds one structure per primitive kind the
//! scene actually has, so a scene without spheres never runs a sphere kernel.

mod bruteforce;
mod bvh2;
mod bvhn;
mod extras;
pub mod filter;
mod grid;
mod instance;
mod kdtree;
mod moving;
mod octree;
mod primitives;
mod sah_build;
pub mod spatial;
mod tiny;

pub use bruteforce::BruteForce;
pub use bvh2::{Bvh2, Bvh2BuildOptions, Bvh2Node};
pub use bvhn::{
    Bvh, Bvh4, Bvh4Node, Bvh4QNode, Bvh4c, Bvh8, Bvh8Node, Bvh8QNode, Bvh8c, BvhNode, NodeWidth,
    PACKET_MIN_ACTIVE, Prefetch, QNode, STREAM_MIN_BATCH, STREAM_MIN_RAYS, STREAM_WINS, WideNode,
    Width, incoherent_batch, prefers_stream,
};
pub use filter::{Candidate, HitFilter, QueryOptions, all_hits};
pub use grid::{Grid, GridOptions};
pub use instance::InstanceAccel;
pub use kdtree::{KdNode, KdTree, KdTreeOptions};
pub use moving::{MovingAccel, MovingSpheres, MovingTriangles};
pub use octree::{Octree, OctreeNode, OctreeOptions};
pub use primitives::{Primitives, Spheres, Triangles};
pub use spatial::TraversalCounts;
pub use tiny::{TINY_MAX_PRIMITIVES, TinyScene, TinyScratch};

use crate::error::{Error, Result};
use crate::geometry::{Hit, Ray, RayPacket};
use crate::scene::Scene;
use std::str::FromStr;

/// Closest-hit and any-hit queries over one primitive set.
///
/// Interval semantics for every implementation: a hit counts only if `tmin < t < tmax`
/// (both strict), and an invalid ray (NaN/inf components, zero direction, empty interval)
/// hits nothing. `Hit::prim` is the primitive's index in the set the structure was built
/// from, whatever order the structure keeps internally.
pub trait Accel: Send + Sync {
    fn closest_hit(&self, ray: &Ray) -> Option<Hit>;
    fn any_hit(&self, ray: &Ray) -> bool;

    /// Filtered query (Embree's intersection filter): `filter` is offered each
    /// candidate hit nearer than the nearest it accepted, each exactly once, and
    /// returns whether to accept it; the result is the nearest accepted candidate, or
    /// with `opts.any` the first. Back faces are dropped first with
    /// `opts.cull_back_faces`. Single rays on every structure, separate from the
    /// plain queries so that they pay nothing. Full semantics: [`filter`].
    fn filtered_hit(
        &self,
        ray: &Ray,
        opts: QueryOptions,
        filter: &mut HitFilter<'_>,
    ) -> Option<Hit>;

    /// Closest hits for a batch of rays. Structures with packet kernels override this.
    fn closest_hit_batch(&self, rays: &[Ray], out: &mut [Option<Hit>]) {
        for (r, o) in rays.iter().zip(out.iter_mut()) {
            *o = self.closest_hit(r);
        }
    }

    /// Occlusion for a batch of rays. Structures with packet kernels override this.
    fn any_hit_batch(&self, rays: &[Ray], out: &mut [bool]) {
        for (r, o) in rays.iter().zip(out.iter_mut()) {
            *o = self.any_hit(r);
        }
    }

    /// Closest hits for a large batch of rays (hundreds to thousands, incoherent ones
    /// above all) traced as one stream. Structures with a stream kernel (BVH4/BVH8:
    /// `bvhn/stream.rs`) override this; the others trace the batch as a batch.
    fn closest_hit_stream(&self, rays: &[Ray], out: &mut [Option<Hit>]) {
        self.closest_hit_batch(rays, out);
    }

    /// Occlusion for a large batch of rays traced as one stream.
    fn any_hit_stream(&self, rays: &[Ray], out: &mut [bool]) {
        self.any_hit_batch(rays, out);
    }

    /// Closest hits for one packet of rays in structure-of-arrays form (lanes
    /// `0..packet.len` into `out[..packet.len]`). Structures with packet kernels
    /// override this; the batch entry points of those go through it.
    fn closest_hit_packet(&self, packet: &RayPacket, out: &mut [Option<Hit>]) {
        for (i, o) in out[..packet.len].iter_mut().enumerate() {
            *o = self.closest_hit(&packet.ray(i));
        }
    }

    /// Occlusion for one packet of rays in structure-of-arrays form.
    fn any_hit_packet(&self, packet: &RayPacket, out: &mut [bool]) {
        for (i, o) in out[..packet.len].iter_mut().enumerate() {
            *o = self.any_hit(&packet.ray(i));
        }
    }

    /// What was built and what it cost.
    fn info(&self) -> AccelInfo;

    /// The closest-hit traversal's work for one ray (node visits, primitive tests), from
    /// a counting twin of the traversal so the normal path pays nothing; `None` where a
    /// structure has no counting twin.
    fn traversal_counts(&self, _ray: &Ray) -> Option<TraversalCounts> {
        None
    }
}

/// Build statistics of one structure.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct AccelInfo {
    pub name: &'static str,
    pub primitives: usize,
    pub build_ms: f64,
    pub nodes: usize,
    pub leaves: usize,
    pub max_depth: usize,
    pub memory_bytes: usize,
    /// SAH cost of the tree (traversal cost 1, intersection cost 1 per primitive,
    /// normalised by the root area); 0 where it does not apply.
    pub sah_cost: f64,
}

/// Which structure to build.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum AccelKind {
    BruteForce,
    Bvh2,
    Bvh4,
    Bvh8,
    /// The BVH4 with compressed (quantised) nodes.
    Bvh4c,
    /// The BVH8 with compressed (quantised) nodes.
    Bvh8c,
    Grid,
    Octree,
    KdTree,
}

impl AccelKind {
    pub const ALL: &'static [AccelKind] = &[
        AccelKind::BruteForce,
        AccelKind::Bvh2,
        AccelKind::Bvh4,
        AccelKind::Bvh8,
        AccelKind::Bvh4c,
        AccelKind::Bvh8c,
        AccelKind::Grid,
        AccelKind::Octree,
        AccelKind::KdTree,
    ];

    pub fn name(self) -> &'static str {
        match self {
            AccelKind::BruteForce => "bruteforce",
            AccelKind::Bvh2 => "bvh2",
            AccelKind::Bvh4 => "bvh4",
            AccelKind::Bvh8 => "bvh8",
            AccelKind::Bvh4c => "bvh4c",
            AccelKind::Bvh8c => "bvh8c",
            AccelKind::Grid => "grid",
            AccelKind::Octree => "octree",
            AccelKind::KdTree => "kdtree",
        }
    }

    /// Builds this structure over a primitive set.
    pub fn build<P: Primitives + 'static>(self, prims: P) -> Box<dyn Accel> {
        match self {
            AccelKind::BruteForce => Box::new(BruteForce::new(prims)),
            AccelKind::Bvh2 => Box::new(Bvh2::build(prims)),
            AccelKind::Bvh4 => Box::new(Bvh4::build(prims)),
            AccelKind::Bvh8 => Box::new(Bvh8::build(prims)),
            AccelKind::Bvh4c => Box::new(Bvh4c::build(prims)),
            AccelKind::Bvh8c => Box::new(Bvh8c::build(prims)),
            AccelKind::Grid => Box::new(Grid::build(prims)),
            AccelKind::Octree => Box::new(Octree::build(prims)),
            AccelKind::KdTree => Box::new(KdTree::build(prims)),
        }
    }
}

impl FromStr for AccelKind {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        AccelKind::ALL
            .iter()
            .copied()
            .find(|k| k.name() == s)
            .ok_or_else(|| {
                let names: Vec<_> = AccelKind::ALL.iter().map(|k| k.name()).collect();
                Error::parameter(
                    "accel",
                    format!(
                        "unknown structure '{s}', expected one of {}",
                        names.join(", ")
                    ),
                )
            })
    }
}

impl std::fmt::Display for AccelKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Which primitive set a scene-level hit belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PrimRef {
    Triangle(u32),
    Sphere(u32),
    /// Index into `Scene::motion.mesh`.
    MovingTriangle(u32),
    /// Index into `Scene::motion.spheres`.
    MovingSphere(u32),
    /// Triangle `prim` of the object placed by `Scene::instances.instances[instance]`.
    Instance {
        instance: u32,
        prim: u32,
    },
    /// Index into `Scene::planes` (infinite planes).
    Plane(u32),
}

/// A closest hit in the whole scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SceneHit {
    pub t: f32,
    pub prim: PrimRef,
    pub u: f32,
    pub v: f32,
}

/// Which primitive sets of a scene block a ray first, in the order the scene-level
/// queries test them ([`SceneAccel::occluder`], [`SceneAccel::occluders_batch`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Occluder {
    Triangles,
    Spheres,
    /// Moving triangles or moving spheres (one occlusion query covers both).
    Moving,
    /// Instances or infinite planes.
    Other,
}

impl Occluder {
    pub const ALL: [Occluder; 4] = [
        Occluder::Triangles,
        Occluder::Spheres,
        Occluder::Moving,
        Occluder::Other,
    ];

    /// The first of the filtered query's four flat sets (triangles, spheres, moving
    /// triangles, moving spheres) that this group covers; 4 is past them all.
    fn first_set(self) -> usize {
        match self {
            Occluder::Triangles => 0,
            Occluder::Spheres => 1,
            Occluder::Moving => 2,
            Occluder::Other => 4,
        }
    }
}

/// One primitive set of a scene and how its hits are named.
type PrimSet<'a> = (Option<&'a dyn Accel>, fn(u32) -> PrimRef);

/// A candidate hit of a scene-level filtered query ([`SceneAccel::filtered_hit`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SceneCandidate {
    pub hit: SceneHit,
    /// Whether the ray meets the front face ([`QueryOptions::cull_back_faces`]).
    pub front_face: bool,
}

/// One structure per primitive kind present in the scene.
pub struct SceneAccel {
    pub kind: AccelKind,
    pub triangles: Option<Box<dyn Accel>>,
    pub spheres: Option<Box<dyn Accel>>,
    /// Moving geometry (motion blur); `None` for a scene without it.
    pub moving: Option<MovingAccel>,
    /// Instanced geometry (two levels); `None` for a scene without instances.
    pub instances: Option<InstanceAccel>,
    /// Infinite planes, tested against every ray (`extras.rs`).
    pub planes: Vec<crate::scene::Plane>,
    /// The static triangles and spheres again, for the batch queries of a scene of at
    /// most [`TINY_MAX_PRIMITIVES`] of them (`tiny.rs`); `None` above that. Setting it
    /// to `None` sends the batch queries through the structures (same answers up to
    /// which primitive wins an exact tie in `t`).
    pub tiny: Option<TinyScene>,
}

impl SceneAccel {
    pub fn build(scene: &Scene, kind: AccelKind) -> SceneAccel {
        let triangles =
            (!scene.mesh.is_empty()).then(|| kind.build(Triangles::from_mesh(&scene.mesh)));
        let spheres =
            (!scene.spheres.is_empty()).then(|| kind.build(Spheres::from_set(&scene.spheres)));
        let moving = MovingAccel::build(&scene.motion, scene.camera_effects.shutter, kind);
        let (instances, planes) = extras::build_extras(scene, kind);
        SceneAccel {
            kind,
            triangles,
            spheres,
            moving,
            instances,
            planes,
            tiny: TinyScene::build(scene),
        }
    }

    pub fn closest_hit(&self, ray: &Ray) -> Option<SceneHit> {
        let mut best: Option<SceneHit> = self
            .triangles
            .as_ref()
            .and_then(|a| a.closest_hit(ray))
            .map(|h| SceneHit {
                t: h.t,
                prim: PrimRef::Triangle(h.prim),
                u: h.u,
                v: h.v,
            });
        if let Some(a) = &self.spheres {
            let mut r = *ray;
            if let Some(b) = &best {
                r.tmax = b.t;
            }
            if let Some(h) = a.closest_hit(&r) {
                best = Some(SceneHit {
                    t: h.t,
                    prim: PrimRef::Sphere(h.prim),
                    u: h.u,
                    v: h.v,
                });
            }
        }
        if let Some(m) = &self.moving {
            best = closer(
                best,
                ray,
                |r| m.closest_triangle(r),
                PrimRef::MovingTriangle,
            );
            best = closer(best, ray, |r| m.closest_sphere(r), PrimRef::MovingSphere);
        }
        self.closest_extra(ray, best)
    }

    /// The filtered query over the whole scene ([`Accel::filtered_hit`], same
    /// semantics): each structure in turn (triangles, spheres, moving triangles, moving
    /// spheres, instances, infinite planes), each searching only in front of the nearest candidate accepted so
    /// far; with `opts.any` the first accepted candidate ends the query.
    pub fn filtered_hit(
        &self,
        ray: &Ray,
        opts: QueryOptions,
        filter: &mut dyn FnMut(&SceneCandidate) -> bool,
    ) -> Option<SceneHit> {
        self.filtered_hit_from(ray, opts, filter, Occluder::Triangles)
    }

    /// Whether the scene has a primitive set from `from` on (the filtered query's
    /// order: triangles, spheres, moving geometry, instances and planes), so that a
    /// query from there could meet anything.
    pub fn has_sets_from(&self, from: Occluder) -> bool {
        let present = [
            self.triangles.is_some(),
            self.spheres.is_some(),
            self.moving.is_some(),
            self.instances.is_some() || !self.planes.is_empty(),
        ];
        present[from as usize..].contains(&true)
    }

    /// [`filtered_hit`](Self::filtered_hit) over the primitive sets from `from` on, in
    /// the same order, skipping the sets before it: for a ray that the occlusion query
    /// ([`occluders_batch`](Self::occluders_batch), [`occluder`](Self::occluder)) found
    /// blocked first by `from`, the sets before it have no candidate in the interval,
    /// so the result is the full query's.
    pub fn filtered_hit_from(
        &self,
        ray: &Ray,
        opts: QueryOptions,
        filter: &mut dyn FnMut(&SceneCandidate) -> bool,
        from: Occluder,
    ) -> Option<SceneHit> {
        let moving = self.moving.as_ref();
        let sets: [PrimSet; 4] = [
            (self.triangles.as_deref(), PrimRef::Triangle),
            (self.spheres.as_deref(), PrimRef::Sphere),
            (
                moving.and_then(|m| m.triangles.as_deref()),
                PrimRef::MovingTriangle,
            ),
            (
                moving.and_then(|m| m.spheres.as_deref()),
                PrimRef::MovingSphere,
            ),
        ];
        let mut best: Option<SceneHit> = None;
        for (accel, prim) in sets.into_iter().skip(from.first_set()) {
            let Some(accel) = accel else { continue };
            let mut r = *ray;
            if let Some(b) = &best {
                r.tmax = b.t;
            }
            let scene_hit = |h: &Hit| SceneHit {
                t: h.t,
                prim: prim(h.prim),
                u: h.u,
                v: h.v,
            };
            let found = accel.filtered_hit(&r, opts, &mut |c| {
                filter(&SceneCandidate {
                    hit: scene_hit(&c.hit),
                    front_face: c.front_face,
                })
            });
            if let Some(h) = found {
                best = Some(scene_hit(&h));
                if opts.any {
                    return best;
                }
            }
        }
        self.filtered_extra(ray, opts, filter, best).0
    }

    /// Every hit along the ray in the whole scene (back faces dropped with
    /// `cull_back_faces`), sorted by `t`, then primitive kind (triangles, spheres,
    /// moving triangles, moving spheres) and index, entries before exits.
    pub fn all_hits(&self, ray: &Ray, cull_back_faces: bool) -> Vec<SceneCandidate> {
        let mut hits = Vec::new();
        let opts = QueryOptions {
            cull_back_faces,
            any: false,
        };
        self.filtered_hit(ray, opts, &mut |c| {
            hits.push(*c);
            false
        });
        let key = |p: PrimRef| match p {
            PrimRef::Triangle(i) => (0, i, 0),
            PrimRef::Sphere(i) => (1, i, 0),
            PrimRef::MovingTriangle(i) => (2, i, 0),
            PrimRef::MovingSphere(i) => (3, i, 0),
            PrimRef::Instance { instance, prim } => (4, instance, prim),
            PrimRef::Plane(i) => (5, i, 0),
        };
        hits.sort_by(|a, b| {
            a.hit
                .t
                .total_cmp(&b.hit.t)
                .then(key(a.hit.prim).cmp(&key(b.hit.prim)))
                .then(b.front_face.cmp(&a.front_face))
        });
        hits
    }

    pub fn any_hit(&self, ray: &Ray) -> bool {
        self.triangles.as_ref().is_some_and(|a| a.any_hit(ray))
            || self.spheres.as_ref().is_some_and(|a| a.any_hit(ray))
            || self.moving.as_ref().is_some_and(|m| m.any_hit(ray))
            || self.any_extra(ray)
    }

    /// [`any_hit`](Self::any_hit) that says which primitive set blocks the ray: the
    /// first in the order the query tests them, `None` when nothing does.
    pub fn occluder(&self, ray: &Ray) -> Option<Occluder> {
        if self.triangles.as_ref().is_some_and(|a| a.any_hit(ray)) {
            Some(Occluder::Triangles)
        } else if self.spheres.as_ref().is_some_and(|a| a.any_hit(ray)) {
            Some(Occluder::Spheres)
        } else if self.moving.as_ref().is_some_and(|m| m.any_hit(ray)) {
            Some(Occluder::Moving)
        } else if self.any_extra(ray) {
            Some(Occluder::Other)
        } else {
            None
        }
    }

    /// Closest hits for a batch of rays, through each kind's batch entry point (BVH4:
    /// 16 consecutive rays as one packet; a batch that [`prefers_stream`], of at least
    /// [`STREAM_MIN_BATCH`] mostly incoherent rays in a build where the stream kernel
    /// measures faster ([`STREAM_WINS`]: AVX2 or AVX-512), as one stream), merged by distance exactly as
    /// [`closest_hit`](Self::closest_hit) merges them: each later kind searches only in
    /// front of the hit found so far, so the results are identical. `scratch` is reused
    /// between calls.
    pub fn closest_hit_batch(
        &self,
        rays: &[Ray],
        out: &mut [Option<SceneHit>],
        scratch: &mut BatchScratch,
    ) {
        debug_assert_eq!(rays.len(), out.len());
        out.fill(None);
        if let Some(tiny) = &self.tiny {
            tiny.closest_batch(rays, out, &mut scratch.tiny);
        } else {
            self.closest_sets_batch(rays, out, scratch);
        }
        if let Some(m) = &self.moving {
            for (r, o) in rays.iter().zip(out.iter_mut()) {
                let best = closer(*o, r, |r| m.closest_triangle(r), PrimRef::MovingTriangle);
                *o = closer(best, r, |r| m.closest_sphere(r), PrimRef::MovingSphere);
            }
        }
        if self.instances.is_some() || !self.planes.is_empty() {
            for (r, o) in rays.iter().zip(out.iter_mut()) {
                *o = self.closest_extra(r, *o);
            }
        }
    }

    /// The closest-hit batch over the triangle and sphere structures (`out` starts
    /// all `None`).
    fn closest_sets_batch(
        &self,
        rays: &[Ray],
        out: &mut [Option<SceneHit>],
        scratch: &mut BatchScratch,
    ) {
        let hits = &mut scratch.hits;
        hits.clear();
        hits.resize(rays.len(), None);
        let scene_hit = |h: Hit, prim: fn(u32) -> PrimRef| SceneHit {
            t: h.t,
            prim: prim(h.prim),
            u: h.u,
            v: h.v,
        };
        // Incoherent batches (diffuse-like queues) go through the stream kernel.
        let stream = prefers_stream(rays);
        if let Some(a) = &self.triangles {
            if stream {
                a.closest_hit_stream(rays, hits);
            } else {
                a.closest_hit_batch(rays, hits);
            }
            for (o, h) in out.iter_mut().zip(hits.iter()) {
                *o = h.map(|h| scene_hit(h, PrimRef::Triangle));
            }
        }
        if let Some(a) = &self.spheres {
            let clipped = &mut scratch.rays;
            clipped.clear();
            clipped.extend(rays.iter().zip(out.iter()).map(|(r, o)| {
                let mut r = *r;
                if let Some(b) = o {
                    r.tmax = b.t;
                }
                r
            }));
            if stream {
                a.closest_hit_stream(clipped, hits);
            } else {
                a.closest_hit_batch(clipped, hits);
            }
            for (o, h) in out.iter_mut().zip(hits.iter()) {
                if let Some(h) = h {
                    *o = Some(scene_hit(*h, PrimRef::Sphere));
                }
            }
        }
    }

    /// Occlusion for a batch of rays: each kind's batch entry point over the rays no
    /// earlier kind found blocked. Incoherent batches go through the stream kernel, as in
    /// [`closest_hit_batch`](Self::closest_hit_batch). Same answers as [`any_hit`](Self::any_hit).
    pub fn any_hit_batch(&self, rays: &[Ray], out: &mut [bool], scratch: &mut BatchScratch) {
        self.any_hit_batch_marking(rays, out, scratch, |_, _| {});
    }

    /// [`any_hit_batch`](Self::any_hit_batch) that says which primitive set blocks each
    /// ray (the same work and answers): `out[i]` is [`occluder`](Self::occluder) of ray
    /// `i`. `blocked` is scratch (the plain answers).
    pub fn occluders_batch(
        &self,
        rays: &[Ray],
        out: &mut [Option<Occluder>],
        blocked: &mut Vec<bool>,
        scratch: &mut BatchScratch,
    ) {
        debug_assert_eq!(rays.len(), out.len());
        out.fill(None);
        blocked.clear();
        blocked.resize(rays.len(), false);
        self.any_hit_batch_marking(rays, blocked, scratch, |i, set| out[i] = Some(set));
    }

    /// The occlusion batch, calling `mark(i, set)` once for each ray `i` when the set
    /// `set` is the first found blocking it.
    #[inline(always)]
    fn any_hit_batch_marking(
        &self,
        rays: &[Ray],
        out: &mut [bool],
        scratch: &mut BatchScratch,
        mut mark: impl FnMut(usize, Occluder),
    ) {
        debug_assert_eq!(rays.len(), out.len());
        out.fill(false);
        if let Some(tiny) = &self.tiny {
            tiny.occluders_batch(rays, &mut scratch.tiny, |i, set| {
                out[i] = true;
                mark(i, set);
            });
        } else {
            self.occluders_sets_batch(rays, out, scratch, &mut mark);
        }
        if let Some(m) = &self.moving {
            for (i, (r, o)) in rays.iter().zip(out.iter_mut()).enumerate() {
                if !*o && m.any_hit(r) {
                    *o = true;
                    mark(i, Occluder::Moving);
                }
            }
        }
        if self.instances.is_some() || !self.planes.is_empty() {
            for (i, (r, o)) in rays.iter().zip(out.iter_mut()).enumerate() {
                if !*o && self.any_extra(r) {
                    *o = true;
                    mark(i, Occluder::Other);
                }
            }
        }
    }

    /// The occlusion batch over the triangle and sphere structures (`out` starts all
    /// false).
    #[inline(always)]
    fn occluders_sets_batch(
        &self,
        rays: &[Ray],
        out: &mut [bool],
        scratch: &mut BatchScratch,
        mark: &mut impl FnMut(usize, Occluder),
    ) {
        let kinds = [
            (self.triangles.as_deref(), Occluder::Triangles),
            (self.spheres.as_deref(), Occluder::Spheres),
        ];
        let stream = prefers_stream(rays);
        let mut first = true;
        for (a, set) in kinds {
            let Some(a) = a else { continue };
            if first {
                if stream {
                    a.any_hit_stream(rays, out);
                } else {
                    a.any_hit_batch(rays, out);
                }
                first = false;
                for (i, &b) in out.iter().enumerate() {
                    if b {
                        mark(i, set);
                    }
                }
                continue;
            }
            // Only the rays still unblocked, packed so packets stay full.
            scratch.index.clear();
            scratch.rays.clear();
            for (i, (r, o)) in rays.iter().zip(out.iter()).enumerate() {
                if !*o {
                    scratch.index.push(i as u32);
                    scratch.rays.push(*r);
                }
            }
            scratch.blocked.clear();
            scratch.blocked.resize(scratch.rays.len(), false);
            if stream {
                a.any_hit_stream(&scratch.rays, &mut scratch.blocked);
            } else {
                a.any_hit_batch(&scratch.rays, &mut scratch.blocked);
            }
            for (&i, &b) in scratch.index.iter().zip(scratch.blocked.iter()) {
                out[i as usize] = b;
                if b {
                    mark(i as usize, set);
                }
            }
        }
    }

    /// Build statistics of each structure present.
    pub fn info(&self) -> Vec<AccelInfo> {
        self.triangles
            .iter()
            .chain(self.spheres.iter())
            .map(|a| a.info())
            .chain(self.moving.iter().flat_map(|m| m.info()))
            .chain(self.instances.iter().map(|i| i.info()))
            .collect()
    }
}

/// Reusable buffers of the batch queries.
#[derive(Default)]
pub struct BatchScratch {
    hits: Vec<Option<Hit>>,
    rays: Vec<Ray>,
    index: Vec<u32>,
    blocked: Vec<bool>,
    tiny: TinyScratch,
}

impl BatchScratch {
    /// The buffers of the tiny-scene lane groups, for a caller that runs them itself
    /// (`integrator::tiny_shadow`).
    pub fn tiny(&mut self) -> &mut TinyScratch {
        &mut self.tiny
    }
}

/// `best`, or the hit `query` finds before it.
fn closer(
    best: Option<SceneHit>,
    ray: &Ray,
    query: impl Fn(&Ray) -> Option<Hit>,
    prim: fn(u32) -> PrimRef,
) -> Option<SceneHit> {
    let mut r = *ray;
    if let Some(b) = &best {
        r.tmax = b.t;
    }
    match query(&r) {
        Some(h) => Some(SceneHit {
            t: h.t,
            prim: prim(h.prim),
            u: h.u,
            v: h.v,
        }),
        None => best,
    }
}
