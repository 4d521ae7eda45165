//! The parts of [`SceneAccel`]'s queries beyond the flat primitive sets: instances
//! (two-level structure, [`InstanceAccel`]) and infinite planes (no structure: each
//! ray tests every plane, [`intersect_plane`]). Every structure kind goes through
//! these same functions, so they agree on instances and planes by construction.
//!
//! Order within a query: the flat sets first (in [`SceneAccel`]), then instances, then
//! planes, each searching only in front of the nearest hit so far.

use super::{InstanceAccel, PrimRef, QueryOptions, SceneAccel, SceneCandidate, SceneHit};
use crate::geometry::{Ray, intersect_plane};
use crate::scene::Plane;

impl SceneAccel {
    /// `best`, or a nearer hit on an instance or a plane.
    pub(super) fn closest_extra(&self, ray: &Ray, mut best: Option<SceneHit>) -> Option<SceneHit> {
        let clip = |best: &Option<SceneHit>| clipped(ray, best);
        if let Some((i, h)) = self
            .instances
            .as_ref()
            .and_then(|inst| inst.closest_hit(&clip(&best)))
        {
            best = Some(SceneHit {
                t: h.t,
                prim: PrimRef::Instance {
                    instance: i,
                    prim: h.prim,
                },
                u: h.u,
                v: h.v,
            });
        }
        for (i, p) in self.planes.iter().enumerate() {
            if let Some(t) = intersect_plane(p.point, p.normal, &clip(&best)) {
                best = Some(SceneHit {
                    t,
                    prim: PrimRef::Plane(i as u32),
                    u: 0.0,
                    v: 0.0,
                });
            }
        }
        best
    }

    /// Whether an instance or a plane blocks the ray.
    pub(super) fn any_extra(&self, ray: &Ray) -> bool {
        self.instances.as_ref().is_some_and(|i| i.any_hit(ray))
            || self
                .planes
                .iter()
                .any(|p| intersect_plane(p.point, p.normal, ray).is_some())
    }

    /// The filtered query's instances and planes, in front of `best`; returns the new
    /// best and whether the query is over (`opts.any` and a candidate was accepted).
    pub(super) fn filtered_extra(
        &self,
        ray: &Ray,
        opts: QueryOptions,
        filter: &mut dyn FnMut(&SceneCandidate) -> bool,
        mut best: Option<SceneHit>,
    ) -> (Option<SceneHit>, bool) {
        let clip = |best: &Option<SceneHit>| clipped(ray, best);
        if let Some(inst) = &self.instances {
            let scene_hit = |i: u32, h: &crate::geometry::Hit| SceneHit {
                t: h.t,
                prim: PrimRef::Instance {
                    instance: i,
                    prim: h.prim,
                },
                u: h.u,
                v: h.v,
            };
            let found = inst.filtered_hit(&clip(&best), opts, &mut |i, c| {
                filter(&SceneCandidate {
                    hit: scene_hit(i, &c.hit),
                    front_face: c.front_face,
                })
            });
            if let Some((i, h)) = found {
                best = Some(scene_hit(i, &h));
                if opts.any {
                    return (best, true);
                }
            }
        }
        for (i, p) in self.planes.iter().enumerate() {
            let r = clip(&best);
            let Some(t) = intersect_plane(p.point, p.normal, &r) else {
                continue;
            };
            let front_face = r.dir.dot(p.normal) < 0.0;
            if opts.cull_back_faces && !front_face {
                continue;
            }
            let c = SceneCandidate {
                hit: SceneHit {
                    t,
                    prim: PrimRef::Plane(i as u32),
                    u: 0.0,
                    v: 0.0,
                },
                front_face,
            };
            if filter(&c) {
                best = Some(c.hit);
                if opts.any {
                    return (best, true);
                }
            }
        }
        (best, false)
    }
}

/// The instance structure and the planes of a scene, for [`SceneAccel::build`].
pub(super) fn build_extras(
    scene: &crate::scene::Scene,
    kind: super::AccelKind,
) -> (Option<InstanceAccel>, Vec<Plane>) {
    (
        InstanceAccel::build(&scene.instances, kind),
        scene.planes.clone(),
    )
}

/// `ray` ending at the current best hit, if any: the extras are searched in front of it.
#[inline]
fn clipped(ray: &Ray, best: &Option<SceneHit>) -> Ray {
    let mut r = *ray;
    if let Some(b) = best {
        r.tmax = b.t;
    }
    r
}
