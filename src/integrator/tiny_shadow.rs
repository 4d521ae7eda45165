//! Shadow rays of a tiny scene settled in one pass of lanes ([`TinyShadow`]): the
//! occlusion query and the transmittance through glass spheres in the same lane group,
//! instead of the occlusion batch (`SceneAccel::occluders_batch`, which names the
//! first blocking set of every ray) followed by `ShadowFilter::transmittance_batch`
//! (which copies the rays blocked by the sphere set out and gathers them into lanes a
//! second time).
//!
//! Applies where the scene's batch queries go through [`TinyScene`] and nothing else
//! (no moving geometry, instances or planes), its triangles are all opaque, and its
//! spheres are either all opaque or a split set whose passing part is glass of one
//! transmission (`ShadowFilter::tiny_pass`): the Whitted rows. The answers are the
//! two-step path's bit for bit (a test compares factors and counts on real shadow
//! rays): the same lane kernels run on the same lanes (`TinyGroup::any_triangle`,
//! `any_sphere`, then [`settle_gathered`], the body of `settle_lanes`), each lane's
//! answer depends on its ray alone, and a ray through glass only gets `transmission`
//! multiplied in once per crossing, as `ShadowFilter::glass_factor` does.
//!
//! Measured with the binned lane groups of `accel/tiny.rs` (same change), 1 thread,
//! AVX2, `--stats-json`, interleaved with the previous binary on a machine loaded 5-10
//! on 2 cores (only the ratios mean anything), ms, images byte-identical:
//! whitted_area64 area-shadow stage 15245-17411 -> 10822-11976 (5 runs, load ~9) and
//! 7570-8565 -> 5088-5437 (3 runs, load ~6); whitted_blur16 shadow stage 1023-1123 ->
//! 519-658, whitted_base 71-85 -> 36-46 (3 runs each, load ~3). perf (area64 512x384):
//! the sort by key plus the second gather (`occluders_batch` with `TinyGroup::new`,
//! `transmittance_batch`, `settle_lanes`) were ~21 % of the frame before, the binning
//! and the fused pass ~14 % after.

use crate::accel::{TinyScene, TinyScratch};
use crate::geometry::Ray;
use crate::simd::glass_shadow::settle_gathered;
use crate::stats::RayCounts;
use glam::Vec3;

/// What a shadow ray blocked by the sphere set (and by no triangle) transmits.
#[derive(Clone, Copy)]
pub(super) enum SphereShadow<'a> {
    /// Every sphere blocks light.
    Opaque,
    /// `opaque` spheres block light; `glass` spheres each multiply `transmission` in
    /// once per crossing of their surface.
    Glass {
        opaque: &'a [(Vec3, f32)],
        glass: &'a [(Vec3, f32)],
        transmission: Vec3,
    },
}

/// The one-pass shadow settlement of a tiny scene (see the module).
pub struct TinyShadow<'a> {
    pub(super) tiny: &'a TinyScene,
    pub(super) spheres: SphereShadow<'a>,
}

impl TinyShadow<'_> {
    /// The transmittance of every ray of `rays` into `out`: one where unblocked, zero
    /// where an opaque primitive blocks it, `transmission^n` through `n` glass
    /// crossings; the rays blocked first by a split sphere set are counted in
    /// `counts.transmitted_shadow`. What `occluders_batch` then
    /// `ShadowFilter::transmittance_batch` give, bit for bit.
    pub fn transmittance_batch(
        &self,
        rays: &[Ray],
        out: &mut Vec<Vec3>,
        scratch: &mut TinyScratch,
        counts: &mut RayCounts,
    ) {
        out.clear();
        out.resize(rays.len(), Vec3::ONE);
        let mut settled = 0u64;
        let spheres = self.spheres;
        self.tiny
            .occluder_groups(rays, scratch, |ids, g, tri, sph| {
                for_each_bit(tri, |i| out[ids[i] as usize] = Vec3::ZERO);
                if sph == 0 {
                    return;
                }
                match spheres {
                    SphereShadow::Opaque => {
                        for_each_bit(sph, |i| out[ids[i] as usize] = Vec3::ZERO)
                    }
                    SphereShadow::Glass {
                        opaque,
                        glass,
                        transmission,
                    } => {
                        settled += sph.count_ones() as u64;
                        let (blocked, n) = settle_gathered(&g.lanes, g.tmax, sph, opaque, glass);
                        for_each_bit(sph, |i| {
                            out[ids[i] as usize] = if blocked >> i & 1 == 1 {
                                Vec3::ZERO
                            } else {
                                // `ShadowFilter::glass_factor` with no later sets.
                                let mut t = Vec3::ONE;
                                for _ in 0..n[i] {
                                    t *= transmission;
                                }
                                t
                            };
                        });
                    }
                }
            });
        counts.transmitted_shadow += settled;
    }
}

/// Calls `f` with the index of every set bit.
#[inline(always)]
fn for_each_bit(mut bits: u32, mut f: impl FnMut(usize)) {
    while bits != 0 {
        f(bits.trailing_zeros() as usize);
        bits &= bits - 1;
    }
}
