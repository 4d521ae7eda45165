//! One structure per primitive kind a scene has ([`SceneAccel`]), merged into
//! scene-level single-ray queries.

use super::scene_hit::PrimSet;
use super::{
    Accel, AccelInfo, AccelKind, InstanceAccel, MovingAccel, Occluder, PrimRef, QueryOptions,
    SceneCandidate, SceneHit, Spheres, TinyScene, Triangles, extras,
};
use crate::geometry::{Hit, Ray};
use crate::scene::Scene;

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
    /// most [`TINY_MAX_PRIMITIVES`](super::TINY_MAX_PRIMITIVES) of them (`tiny.rs`); `None` above that. Setting it
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

/// `best`, or the hit `query` finds before it.
pub(super) fn closer(
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
