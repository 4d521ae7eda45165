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
/// Measured with `cargo run --release --example tiny_threshold` (AVX2, 1 thread, the
/// 2-core machine loaded ~5 by other work; a floor quad plus `n - 2` spheres, 512x384
/// camera rays and their shadow segments in batches of 4096, BVH4 packets against the
/// tiny lanes, ns per ray, the minimum over 4 runs of the minimum of 7):
///
/// | primitives | closest tree / tiny | occlusion tree / tiny |
/// |-----------:|--------------------:|----------------------:|
/// |  4 | 33.8 / 21.7 (1.56x) | 30.0 / 19.1 (1.57x) |
/// |  6 | 36.7 / 24.6 (1.49x) | 32.0 / 22.4 (1.43x) |
/// |  8 | 34.1 / 30.1 (1.13x) | 34.6 / 26.5 (1.31x) |
/// | 12 | 36.8 / 32.9 (1.12x) | 32.5 / 30.6 (1.06x) |
/// | 16 | 37.5 / 38.8 (0.97x) | 34.0 / 36.4 (0.93x) |
/// | 24 | 39.6 / 50.4 (0.79x) | 36.0 / 46.0 (0.78x) |
/// | 32 | 41.9 / 63.5 (0.66x) | 38.4 / 59.7 (0.64x) |
///
/// Break-even lies between 12 and 16; 8 keeps a clear margin on a noisy machine
/// (single runs scattered by up to 2x). On AVX-512, where a 16-lane group is one
/// register, the break-even should move up; not measured.
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
