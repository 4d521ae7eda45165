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
use crate::simd::ray_gather::{gather_rays, load_rays};
use crate::simd::tiny::{TINY_WIDTH, TinyGroup, shear_key, uniform_shear_key};
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
    /// The scene-level reference of each lane primitive index (triangles, then
    /// spheres): one load per hit where the choice between the two kinds was a branch.
    refs: Vec<PrimRef>,
}

/// Reusable buffers of the tiny batch queries: one bin of ray indices per shear key.
#[derive(Default)]
pub struct TinyScratch {
    bins: [[u32; TINY_WIDTH]; KEYS],
}

/// Shear keys ([`shear_key`]): three dominant axes times two signs.
const KEYS: usize = 6;

/// The mask of a full lane group.
fn full_mask() -> u32 {
    ((1u64 << TINY_WIDTH) - 1) as u32
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
        let refs = (0..scene.mesh.len() as u32)
            .map(PrimRef::Triangle)
            .chain((0..scene.spheres.len() as u32).map(PrimRef::Sphere))
            .collect();
        Some(TinyScene {
            refs,
            triangles: (0..scene.mesh.len())
                .map(|i| scene.mesh.corners(i))
                .collect(),
            spheres: (0..scene.spheres.len())
                .map(|i| (scene.spheres.center(i), scene.spheres.radius[i]))
                .collect(),
        })
    }

    /// The triangles (corners), in scene order.
    pub fn triangles(&self) -> &[[Vec3; 3]] {
        &self.triangles
    }

    /// The spheres (centre, radius), in scene order.
    pub fn spheres(&self) -> &[(Vec3, f32)] {
        &self.spheres
    }

    /// Primitives held.
    pub fn len(&self) -> usize {
        self.triangles.len() + self.spheres.len()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Calls `f(indices, group)` for lane groups covering every valid ray of `rays`
    /// once, each group's rays of one shear key. The rays are dealt in order into one
    /// bin per key, and a bin is tested when it holds [`TINY_WIDTH`] rays (the rest at
    /// the end): groups as full as a sort by key makes them (at most one partial group
    /// per key), in one pass over the batch, with no index array the length of the
    /// batch. Rays of a run of one key (the shadow rays of one shading point towards
    /// one light, camera rays of a tile) fill their bin in a row.
    ///
    /// Measured against the counting sort of the whole batch by key that this
    /// replaced (keys and order arrays, three passes), in the same change as the
    /// fused shadow pass (`integrator::tiny_shadow`): see there.
    fn for_each_group(
        &self,
        rays: &[Ray],
        scratch: &mut TinyScratch,
        mut f: impl FnMut(&[u32], &TinyGroup),
    ) {
        let bins = &mut scratch.bins;
        let mut fill = [0usize; KEYS];
        let mut deal = |i: usize, f: &mut dyn FnMut(&[u32], &TinyGroup)| {
            let Some(k) = shear_key(&rays[i]) else {
                return;
            };
            bins[k][fill[k]] = i as u32;
            fill[k] += 1;
            if fill[k] == TINY_WIDTH {
                fill[k] = 0;
                let (lanes, tmax) = gather_rays(rays, &bins[k]);
                f(
                    &bins[k],
                    &TinyGroup::from_lanes(k, lanes, tmax, full_mask()),
                );
            }
        };
        let mut ids = [0u32; TINY_WIDTH];
        let mut windows = rays.chunks_exact(TINY_WIDTH);
        for (w, window) in windows.by_ref().enumerate() {
            // Sixteen rays in a row of one key, all valid (the common case): a group
            // as they stand, gathered once (transposed: `simd::ray_gather`), no key per
            // ray and no bin.
            let (lanes, tmax) = load_rays(window);
            let first = (w * TINY_WIDTH) as u32;
            if let Some(k) = uniform_shear_key(&lanes, tmax) {
                for (n, id) in ids.iter_mut().enumerate() {
                    *id = first + n as u32;
                }
                f(&ids, &TinyGroup::from_lanes(k, lanes, tmax, full_mask()));
            } else {
                for i in 0..TINY_WIDTH {
                    deal(first as usize + i, &mut f);
                }
            }
        }
        let rest = rays.len() - windows.remainder().len();
        for i in rest..rays.len() {
            deal(i, &mut f);
        }
        for k in 0..KEYS {
            let ids = &bins[k][..fill[k]];
            if !ids.is_empty() {
                f(ids, &TinyGroup::new(rays, ids, k));
            }
        }
    }

    /// Closest hits of `rays` over the triangles and spheres into `out` (`None` for a
    /// miss or an invalid ray): the scene-level answer of the triangle set merged with
    /// the sphere set, as `SceneAccel::closest_hit` merges them.
    ///
    /// Where it goes (callgrind, whitted_base, 1 thread, 1.68 M rays in 106,839 lane
    /// groups of 15.7 rays on average): the lane kernel (`TinyGroup::closest`, 2
    /// triangles and 2 spheres) 139 M instructions, ~1300 per group (with AVX2 a
    /// 16-lane value is two registers: 368 of the 1613 instructions of its code are
    /// spills and reloads; 145 M before the lane primitive index); grouping, loading
    /// and writing the hits back 81 M (90 M before the transposed loads).
    pub fn closest_batch(
        &self,
        rays: &[Ray],
        out: &mut [Option<SceneHit>],
        scratch: &mut TinyScratch,
    ) {
        debug_assert_eq!(rays.len(), out.len());
        out.fill(None);
        self.for_each_group(rays, scratch, |ids, g| {
            let h = g.closest(&self.triangles, &self.spheres);
            let mut bits = h.hit;
            while bits != 0 {
                let i = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                out[ids[i] as usize] = Some(SceneHit {
                    t: h.t[i],
                    prim: self.refs[h.prim[i] as usize],
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
        self.occluder_groups(rays, scratch, |ids, _, tri, sph| {
            for (i, &id) in ids.iter().enumerate() {
                if tri >> i & 1 == 1 {
                    mark(id as usize, Occluder::Triangles);
                } else if sph >> i & 1 == 1 {
                    mark(id as usize, Occluder::Spheres);
                }
            }
        });
    }

    /// The lane groups of [`occluders_batch`](Self::occluders_batch) with their
    /// answers: `f(indices, group, tri, sph)`, `tri` the bits of the lanes a triangle
    /// blocks, `sph` of those it leaves that a sphere blocks. For a caller that goes
    /// on in the same lanes (`integrator::tiny_shadow`).
    pub fn occluder_groups(
        &self,
        rays: &[Ray],
        scratch: &mut TinyScratch,
        mut f: impl FnMut(&[u32], &TinyGroup, u32, u32),
    ) {
        self.for_each_group(rays, scratch, |ids, g| {
            let tri = g.any_triangle(&self.triangles);
            let sph = g.any_sphere(&self.spheres, g.mask & !tri);
            f(ids, g, tri, sph);
        });
    }
}
