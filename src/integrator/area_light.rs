//! The quad lights of one shading point in lanes ([`shade_quads`]): the light samples
//! are generated sixteen at a time (`simd::direct_light::quad_light`), and then either
//! queued as shadow rays (the area-shadow stage of `wavefront::trace_shadows` tests
//! them later, one ray and one contribution per sample), or, where the scene is a
//! tiny one ([`LaneOccluders`]), tested in the same lanes right away and summed there:
//! one radiance value per shading point and light reaches the camera sample, instead
//! of `shadow` rays.
//!
//! Why: the samples of one shading point towards one quad light share their origin, a
//! coherent packet by construction. Queued, each became a 52-byte `Ray` + slot +
//! contribution written and read back (3.4 GB per frame of whitted_area64), dealt into
//! shear-key bins, gathered again into lanes, tested, and added to the pixel one by
//! one (perf, area64, 1 thread: `any_triangle` 23 %, `shade_group_lanes` 23 %,
//! `trace_shadows` 9 %, `occluder_groups` and its closure 11 %, `extend_trusted` 6 %).
//!
//! Exactness: the fused path blocks exactly the rays the queue path blocks and
//! multiplies in the same glass factors (see [`LaneOccluders`]); the ray counts and
//! samples drawn are the same. The sum differs in order only: the queue path adds the
//! unblocked contributions to the camera sample one at a time (after every other
//! contribution the wave already added to it), the fused path adds them lane-wise
//! (one lane accumulator per 16 samples) and then across lanes, and adds the total
//! once. All terms are non-negative (radiance, reflectance and weights are), so each
//! computed sum lies within `γ_N = N u / (1 - N u)` (u = 2^-24) of the exact sum of
//! its `N` terms, and the two within `2 γ_N` of each other, relative. With the 64
//! samples of whitted_area64 plus the rest of a camera sample's terms, that is about
//! 1e-5 relative, an order below the 1e-4 of the wavefront-against-recursive image
//! test (`tests/suite/wavefront.rs`).
//!
//! Measured (1 thread, AVX2, `--stats-json`, 5 runs interleaved with the queue-path
//! binary on a machine loaded 8-11 on 2 cores, so only the ratio means anything, min /
//! median / max ms): whitted_area64 render 17969/19625/21653 -> 14435/16357/18368
//! (~1.2x); the ray counts are unchanged and the PNG differs in 8 of 2.36 M bytes by
//! one. The fused path alone, before the plane and sphere culls, gave ~1.25x in a
//! 3-run check (10906 -> 8760 median, load ~7); the culls did not separate from the
//! noise in user-time checks at 512x384 (perf: `any_triangle` 29 % of the frame
//! before them, gone after; what remains is `quad_light`'s arithmetic, the sphere
//! lanes and the light points' draws, `fill_2d_split` ~10 %). Not done: a BVH scene
//! (area_lights.toml) keeps the queue, unchanged (images identical).
//!
//! Then (branch `area4`; images byte-identical on whitted_area64, whitted_base,
//! whitted_blur16, bunny, area_lights, dof_area): counters showed every lane group
//! running the full triangle test on both of the light's own triangles (the segments
//! end just short of them), now skipped by an exact depth test where the light is seen
//! along its axis (`TinyGroup::beyond`); a quad's two triangles share one plane test
//! (`TrianglePlane::same_plane`), which is not tried for the light's own plane
//! (`may_cull`); each sphere's clearance is computed once per point (not once per
//! list); the shadow-ray origins come from two computed once per shading point
//! (`simd::quad_samples`); `next_f32` skips `mix64`'s last step (same top bits).
//! whitted_area64 at 256x192, callgrind, whole process: 1296 M -> 1074 M instructions
//! (-17 %; the depth test alone -10 %). 1 thread, 5 runs interleaved with the previous
//! binary on a machine loaded 8-11 on 2 cores (only the ratio means anything, min /
//! median / max ms): render 5807/6436/7188 -> 4786/5595/6241, shade 5558/6129/6794 ->
//! 4515/5132/5817. Left: `quad_light`'s divisions and square root (bit-exact with the
//! queue path, so no reciprocal estimates), the light points' draws (`fill_2d_split`,
//! ~12 %: scalar SplitMix at ~9 instructions per draw, near its floor), the sphere
//! lanes of points near a sphere and the per-group key and shared-origin masks.
//!
//! Then (branch `area7`; images byte-identical on whitted_area64, area_lights and
//! dof_area against the previous binary): the light points in lanes
//! (`sampling::fill_2d_split`), the highlight's `pow` left out where it is zero for
//! every lit lane (`simd::quad_samples::dark_below`; since session 14 the higher cut
//! `faint_below`, which keeps the products out of the subnormals), a power-of-two sample count
//! multiplied in instead of divided, and the spheres tested once per sixteen samples
//! with their roots reused by the glass settlement (`LaneOccluders::settle`).
//! whitted_area64 512x384, 1 thread, AVX-512 (no hardware counters or valgrind
//! AVX-512 support on that machine, so process CPU time, `perf stat -e task-clock`,
//! 5 runs interleaved, load 9-18 on 2 cores): 298 -> 246 ms (-17 %), per step
//! 294 -> 270 (light points), -> 258 (highlight cut, sample count), -> 246 (spheres).
//!
//! Then (branch `area16`; images byte-identical against the previous binary on 71
//! PNGs: the 13 shipped scenes at 320x240, whitted_area64 at 512x384 and blur16 at
//! 256x192, dof_area with `--spp 1` and 1, 2, 3, 4, 5, 8, 9 and 16 light samples, with
//! the Sobol and the jittered sampler, at 1 and 2 threads, whitted_area64 and
//! area_lights at 1 to 9 samples): with few samples per point (dof_area: 4)
//! `shade_quads` ran its lane groups with 4 of 16 lanes live and paid its per-point
//! work (splats, origins, cull, reduction) per 4 samples. [`shade_quads_packed`]
//! puts the samples of up to `16 / stride` consecutive points of a material group in
//! one lane group (`stride`: the sample count rounded up to a power of two, for 1 to 8
//! samples): per-lane surfaces (`simd::quad_samples::spread`), each point's stream
//! drawn light by light as before, the settlement per point
//! (`LaneOccluders::settle_segments`: the plane sides of each point's origin, the
//! triangle test from a shared origin where a key group is one point's, the spheres
//! of the union of the points' cull bits, exact as the cull is), and the sums per
//! block in `reduce_add`'s tree (`block_sums`): every point's sum is `shade_quads`'
//! bit for bit (test `packed_points_match_one_point_at_a_time_bit_for_bit`).
//! dof_area 320x240, 1 thread, AVX-512, 5 rounds interleaved with the previous binary,
//! flock'd, load 4.6-5.4 on 2 cores (min / median / max ms): render 325/384/457 ->
//! 227/265/363, shade 265/321/352 -> 173/204/234, task-clock 322/358/397 ->
//! 226/246/322; Mitsuba 3.9 (llvm_ad_rgb, 1 thread) in the same run, warm render
//! 179/194/203. whitted_area64 (64 samples, not packed) unchanged within the noise.
//! A second such run of the final build (load 2.8-3.7): dof_area render 314/355/478 ->
//! 203/237/291, shade 264/301/404 -> 152/179/229, task-clock 332/373/500 ->
//! 220/255/313; whitted_area64 render 269/298/414 -> 255/266/378; Mitsuba warm
//! 182/185/226: still above Mitsuba's (median 237 against 185).
//! Per step (3 rounds each, noisier): the pack with its lanes built lane by lane
//! from the batch (`from_fn` per lane) was no faster (those gathers ~20 % of the
//! samples, perf); with `spread`, shade median ~262 -> ~191. Then, each 5-10 % of
//! `shade_quads_packed`'s samples in perf and not timed apart: plane sides as
//! bitmasks (`SegmentSides`), `may_cull` only for planes without a twin and not yet
//! set, `block_sums` by permutes, the light points appended at their blocks
//! (`path_keys::hit_points_append`). Left (perf of this build, dof_area):
//! `shade_quads_packed` 38 % (the light samples' divisions, the per-point `may_cull`
//! and setup), the light points' draws ~12 % (`append_2d_split`, `fill_2d`,
//! `decorrelate_pairs`: sampling.rs), `TrianglePlane::side` 5 % (one exact f64 side
//! test per point's origin; a box of a group's origins tested at its two extreme
//! corners would serve 16 points, not tried), the camera's `block_rays` 7.5 %.
//!
//! Then (branch `area17`; images byte-identical against the previous binary on 30
//! PNGs: the 13 scenes, dof_area at 1 and 2 threads with 1, 3, 4 and 9 light samples,
//! whitted_area64, blur16, bunny, whitted_base, area_lights on a BVH2, dof_area
//! recursive): perf of dof_area 640x480 (1 thread, AVX-512) before: `shade_quads_packed`
//! 35.3 %, `append_2d_split` 10.7 % (9 of them the light points), `TrianglePlane::side`
//! 5.3 %, `fill_2d` 2.2 %, `hit_points_append` 1.4 %. A pack's square jittered light
//! points are drawn in one lane group, each point's from its stream
//! (`simd::jittered_pack::PackLayout`: 32 draws of the pack's streams in lanes, where
//! each point's `append_2d_split` drew 32 for its 8, and a `jittered_block` whose row
//! wrap looped eight times for `k = 2`); a plane of constant coordinate answers `side`
//! by an f32 comparison (`TrianglePlane::axis_side`, proved to give the f64 test's
//! answer; the floor's level origins too); `fill_2d`'s square jittered sets (the
//! camera's pixel positions) in lanes. After: `shade_quads_packed` 43.5 % of fewer
//! samples (the draws inlined there), `side` and `append_2d_split`'s light part gone,
//! `fill_2d` 1.3 %; samples in the stages touched 13.1 k -> 9.7 k of 25.7 k. A first
//! try made the `PackLayout` per pack: 3.6 % of the frame (now once per sample count).
//! Timed (render phase, `--stats-json`, interleaved with the previous binary, flock'd,
//! host loaded 5-8 by other builds on 2 cores, min / median / max ms): dof_area 9 rounds
//! 301/348/682 -> 258/292/414 (median -16 %), another 9 rounds 300/398/747 ->
//! 266/358/452 (-10 %); 640x480 5 rounds 1421/1836/2357 -> 1159/1444/1893 (-21 %).
//!
//! Then (branch `dof18`; images byte-identical against the previous binary on the 30
//! PNGs of `imgcheck`): perf of dof_area 960x720 (1 thread, AVX-512) put ~12 % of
//! `shade_quads_packed`'s samples on `may_cull` and `spheres_near_points` (every point
//! below the light asks for the light's own plane, which it never culls), ~8 % on the
//! sixteen `Soa3::get` of the base points (four used) and ~5 % each on `V3::lane` of
//! the points' origins (`GroupCull::bits`) and of `settle_segments`' shared origins
//! (three 64-byte stores per point). Now `TrianglePlane::may_cull_lanes` answers for
//! the pack's points at once, the base points are the batch's lanes, and the origins
//! are unpacked once per pack (`quad_samples::Unpacked3`). After: `shade_quads_packed`
//! 49 % -> 40 % of the frame's samples, `spheres_near_points` 2.6 % on its own.
//! Timed with the camera change of the same branch (render phase, `--stats-json`,
//! interleaved with the previous binary, flock'd, host loaded 5-6 by other helpers on
//! 2 cores, min / median / max ms): 1 thread 9 rounds 350/430/594 -> 309/363/484 and
//! 334/350/398 -> 308/323/395 (shade 241/264/311 -> 216/248/330); 2 threads 7 rounds
//! 380/397/438 -> 342/361/478.
//!
//! Then (branch `dof22`; images byte-identical against the previous binary on the 30
//! PNGs of `imgcheck`): perf of dof_area 960x720 (1 thread, AVX-512, 8 kHz) put
//! `GroupCull::bits` and its per-point loop at ~14 % of `shade_quads_packed`'s samples
//! and `QuadCull::new`/`clear` at ~4 % of the frame: in AVX-512 builds a pack no
//! longer culls its spheres (`tiny_shadow::PACK_SPHERE_CULL`, as the point lights'
//! `SPHERE_CULL`), and a scene without glass tests its spheres by `sphere_lanes`
//! (no square root or divisions where no lane has a real discriminant). Then stores
//! that 64-byte loads waited on: the pack's `PackLayout` copied per pack (~2.7 %),
//! the albedo and path weight stored point by point and loaded as lanes (~2 %, now
//! `quad_samples::per_block` in registers), the streams' states likewise
//! (`PackLayout::draw_states`). Samples of `shade_quads_packed` 10964 -> 9182 (the
//! cull) -> 8258 (the stores), of the whole process 24174 -> 22552 -> 20960 (PNG
//! deflate ~1390 in each). Timed (render phase, `--stats-json`, 9 rounds interleaved
//! with the previous binary, flock'd, min / median / max ms): 1 thread, load ~3.4
//! 161/210/266 -> 149/173/216, load ~1.8 159/224/234 -> 132/195/212; 2 threads, load
//! ~1.6 76/97/129 -> 67/82/92; whitted_area64 (not packed) 1 thread 5 rounds
//! 1061/1145/1455 -> 917/1149/1415. `benches/mitsuba/run.sh` at 1 thread, load ~1.5:
//! dof_area 1.29x and 1.41x (Mitsuba 0.184 / 0.143 s, 0.183 / 0.130 s); at load ~3.5
//! 0.87x (0.196 / 0.227 s; the previous binary 0.86x in the run before). Left: the
//! light samples' square root and divisions
//! (`QuadSamples::lanes`, ~1 in 8 of the function's samples), the SplitMix draws'
//! 64-bit multiplies (`PackLayout::points`), the shear per key group
//! (`TinyGroup::from_lanes`, one division) and the floor plane's side per point
//! (`TrianglePlane::side`, f64 for origins level with the floor).

use super::hit_batch::HitBatch;
use super::path_keys::{HitSet, hit_points_append, hit_points_split, path_rng};
use super::sampling::{PixelRng, SamplerKind};
use super::shade_stage::{LanePaths, Sinks, push_shadow};
use super::shader::Shader;
use super::sobol::SobolDim;
use super::tiny_shadow::{GroupCull, LaneOccluders, SegmentSides, SphereBits};
use crate::simd::direct_light::{Highlight, QuadLight, SurfaceLanes, quad_light};
use crate::simd::jittered_pack::PackLayout;
use crate::simd::lanes3::V3;
use crate::simd::quad_samples::{OriginBox, QuadSamples, block_sums, per_block, spread};
use crate::simd::{Lanes, Packet};
use glam::Vec3;

/// The quad lights of a scene in lane form, and the tiny scene's occluders where the
/// fused path applies.
#[derive(Default)]
pub(crate) struct QuadLights {
    pub lights: Vec<(u32, QuadLight)>,
    pub occluders: Option<LaneOccluders>,
}

impl QuadLights {
    pub fn is_empty(&self) -> bool {
        self.lights.is_empty()
    }
}

/// Scratch of the light points of one shading point.
#[derive(Default)]
pub(crate) struct LightPoints {
    /// The pairs of a pattern drawn as pairs.
    pub pairs: Vec<(f32, f32)>,
    /// First and second coordinates, padded to whole lane groups.
    pub u: Vec<f32>,
    pub v: Vec<f32>,
    /// The sphere culls of the current lane group of shading points.
    pub cull: GroupCull,
    /// Of a pack ([`shade_quads_packed`]): per light the union of its points' sphere
    /// bits, and per point and light (point-major) its sum where a sample passed.
    near: Vec<SphereBits>,
    pub totals: Vec<Option<Vec3>>,
    /// The lane layout of a pack's light points for (samples, stride), made once.
    layout: Option<((u32, usize), Option<PackLayout>)>,
}

impl LightPoints {
    /// Lane group `c..c + 16` of the drawn points (`c` a multiple of 16 below
    /// `samples`): `u`, `v`, and the mask of the lanes that hold one of the `samples`
    /// points.
    pub(crate) fn group(&self, c: usize, samples: u32) -> (Packet, Packet, u32) {
        let lane = |a: &[f32]| Packet::new(a[c..c + 16].try_into().expect("16 lanes"));
        let left = samples as usize - c;
        let active = if left >= 16 {
            0xffff
        } else {
            (1u32 << left) - 1
        };
        (lane(&self.u), lane(&self.v), active)
    }
}

/// The lanes per shading point of a pack ([`shade_quads_packed`]) for `samples` light
/// samples per point and light: `samples` rounded up to a power of two, where that
/// leaves room for two points or more in a lane group (1 to 8 samples); `None` where
/// one point fills the lanes (or has none), and [`shade_quads`] serves.
pub(crate) fn pack_stride(samples: u32) -> Option<usize> {
    (1..=8)
        .contains(&samples)
        .then(|| samples.next_power_of_two() as usize)
}

/// One shading point of a lane-shaded material group.
#[derive(Clone, Copy)]
pub(crate) struct ShadingPoint<'a> {
    pub batch: &'a HitBatch,
    /// Its index in the batch.
    pub k: usize,
    pub albedo: Vec3,
    pub hl: Highlight,
    /// The camera sample, weight and time of its ray, and what keys its random numbers.
    pub slot: u32,
    pub weight: Vec3,
    pub time: f32,
    pub pixel: u64,
    pub path: u64,
    pub depth: u32,
}

impl ShadingPoint<'_> {
    /// The key of the point's light points towards light `index`.
    /// The point splatted over sixteen lanes: one shading point, its light samples in
    /// the lanes.
    pub(crate) fn lanes(&self) -> SurfaceLanes {
        let (batch, k) = (self.batch, self.k);
        let splat = |a: &super::hit_batch::Soa3| V3::splat(a.get(k));
        SurfaceLanes {
            p: splat(&batch.p),
            p_error: splat(&batch.p_error),
            ng: splat(&batch.ng),
            ns: splat(&batch.ns),
            base: splat(&batch.base),
            smooth: Packet::splat(batch.smooth[k]),
            wo: splat(&batch.dir).negated(),
            albedo: V3::splat(self.albedo),
        }
    }

    /// Draws the point's `samples` light points towards light `index` from its stream
    /// into `points.u` and `points.v` (padded to whole lane groups), as the scalar
    /// shader draws them, and counts them.
    pub(crate) fn draw_light_points(
        &self,
        shader: &Shader,
        index: u32,
        stream: &mut Option<PixelRng>,
        points: &mut LightPoints,
        sinks: &mut Sinks,
    ) {
        let samples = shader.plan.shadow;
        hit_points_split(
            shader.plan.sampler,
            self.light_set(shader.seed, index),
            samples,
            stream,
            (&mut points.u, &mut points.v),
            &mut points.pairs,
        );
        sinks.drawn.light += samples as u64;
    }

    fn light_set(&self, seed: u64, index: u32) -> HitSet {
        HitSet {
            seed,
            pixel: self.pixel,
            path: self.path,
            depth: self.depth,
            dim: SobolDim::Light(index),
        }
    }
}

/// The direct light of every quad light at the shading point `h`: `shadow` samples
/// per light (the sample plan's), drawn into lanes from the point's stream (`stream`,
/// created on first use, shared with the point's later draws); queued as shadow rays
/// into `sinks.shadow`, or settled and summed into `sinks.acc` where
/// `quads.occluders` is set (see the module).
pub(crate) fn shade_quads(
    shader: &Shader,
    quads: &QuadLights,
    h: &ShadingPoint,
    stream: &mut Option<PixelRng>,
    sinks: &mut Sinks,
    points: &mut LightPoints,
) {
    let (batch, k) = (h.batch, h.k);
    let s = h.lanes();
    let plan = &shader.plan;
    let samples = plan.shadow;
    let paths = LanePaths::splat(h.slot, h.weight, h.time);
    let lane_weight = V3::splat(h.weight);
    let base = batch.base.get(k);
    // The fused path's light samples with the shadow-ray origins computed once per
    // shading point (`QuadSamples`, `quad_light` bit for bit); the queue path keeps
    // `quad_light`.
    let hoisted = quads
        .occluders
        .as_ref()
        .and_then(|_| QuadSamples::new(&s, &h.hl));
    // The spheres near each light's segments, from the cull of the point's lane group:
    // the sixteen hits of the batch from this one on (`GroupCull`).
    let culled = match (&quads.occluders, &hoisted) {
        (Some(occluders), Some(fast)) => {
            points
                .cull
                .bits(occluders, fast.origins(), &quads.lights, || {
                    // (`shade_queue` holds the batch's material runs meanwhile: the
                    // last group of a run may take hits of the next, a looser box.)
                    let end = batch.ray.len().max(k + 1);
                    let live = (1u32 << (end - k).min(16)) - 1;
                    let lanes = |a: &super::hit_batch::Soa3| a.lanes(k);
                    let (b, e, n) = (lanes(&batch.base), lanes(&batch.p_error), lanes(&batch.ng));
                    OriginBox::of_group(b, e, n, live)
                })
        }
        _ => false,
    };
    for (i, (index, quad)) in quads.lights.iter().enumerate() {
        let mut near = quads.occluders.as_ref().map(|o| {
            let spheres = if culled {
                points.cull.near(i)
            } else {
                o.sphere_bits(None)
            };
            o.spheres_near(base, spheres, quad)
        });
        // The light points straight into lanes (`u`, `v` padded to 16).
        h.draw_light_points(shader, *index, stream, points, sinks);
        let mut sum = V3::splat(Vec3::ZERO);
        let mut any = false;
        for c in (0..samples as usize).step_by(16) {
            let (u, v, active) = points.group(c, samples);
            let sl = match &hoisted {
                Some(fast) => fast.lanes(&s, &h.hl, quad, u, v, samples as f32, active),
                None => quad_light(&s, &h.hl, quad, u, v, samples as f32, active),
            };
            let Some(occluders) = &quads.occluders else {
                push_shadow(
                    &mut sinks.shadow[*index as usize],
                    &sl,
                    &paths,
                    lane_weight,
                    &mut sinks.rays,
                );
                continue;
            };
            let live = sl.mask & 0xffff;
            if live == 0 {
                continue;
            }
            sinks.rays.shadow += live.count_ones() as u64;
            let near = near.as_mut().expect("with the occluders");
            let settled = occluders.settle(sl.origin, sl.dir, sl.tmax, live, near);
            sinks.rays.transmitted_shadow += settled.settled.count_ones() as u64;
            if settled.pass == 0 {
                continue;
            }
            any = true;
            // The queue path's `contribution * weight`, then `* transmittance`.
            let c = sl.contribution.times(lane_weight).times(settled.factor);
            let pass = <Packet as Lanes>::mask_from_bits(settled.pass);
            sum = sum.plus(V3::select(pass, c, V3::splat(Vec3::ZERO)));
        }
        if any {
            let total = Vec3::new(sum.x.reduce_add(), sum.y.reduce_add(), sum.z.reduce_add());
            sinks.acc[h.slot as usize] += total;
        }
    }
}

/// [`shade_quads`] for the shading points `pts` (consecutive hits of one material
/// group, at most `16 / stride`, `stride` from [`pack_stride`]) in one lane group per
/// light: point `j`'s samples in lanes `j stride ..`, drawn from its stream
/// `streams[j]` (light by light, as `shade_quads` draws them), settled by
/// `LaneOccluders::settle_segments` and summed per block ([`block_sums`]): every lane
/// computes what `shade_quads` computes in its point's lane group, and each point's
/// sum is `shade_quads`' bit for bit. The sums go to `points.totals` (index
/// `j * lights + i`, `None` where `shade_quads` adds nothing) for the caller to add in
/// point order; the counts go to `sinks`. Returns the bits of the points left to
/// `shade_quads` (whose geometric normal `QuadSamples::new` refuses).
///
/// Why: with 4 samples per point (dof_area) `shade_quads` ran its lane groups with 4 of
/// 16 lanes live, and paid the per-point work (splats, origins, the reduction of the
/// sum) per 4 samples.
#[allow(clippy::too_many_arguments)]
pub(crate) fn shade_quads_packed(
    shader: &Shader,
    quads: &QuadLights,
    occluders: &LaneOccluders,
    pts: &[ShadingPoint],
    stride: usize,
    streams: &mut [Option<PixelRng>],
    sinks: &mut Sinks,
    points: &mut LightPoints,
) -> u32 {
    let n = pts.len();
    debug_assert!(n >= 1 && n * stride <= 16 && streams.len() >= n);
    debug_assert!((1..=stride).contains(&(shader.plan.shadow as usize)));
    let samples = shader.plan.shadow as usize;
    let lights = quads.lights.len();
    points.totals.clear();
    points.totals.resize(n * lights, None);
    let (batch, k0) = (pts[0].batch, pts[0].k);
    debug_assert!(pts.iter().enumerate().all(|(j, h)| h.k == k0 + j));
    // Lane `l` holds point `l / stride` (the last point's values past the pack): the
    // points' values (point `j` in lane `j`, as loaded from the batch) spread over
    // their blocks.
    let shift = stride.trailing_zeros();
    let from: [u32; 16] = std::array::from_fn(|l| (l as u32 >> shift).min(n as u32 - 1));
    let spread3 = |v: V3| V3 {
        x: spread(v.x, &from),
        y: spread(v.y, &from),
        z: spread(v.z, &from),
    };
    let gather = |a: &super::hit_batch::Soa3| spread3(a.lanes(k0));
    // The points' own values (not the batch's) splatted over their blocks
    // (`per_block`: in registers, no stores to load back).
    let per_point = |f: fn(&ShadingPoint) -> Vec3| per_block(n, shift, |j| f(&pts[j]));
    let smooth = Packet::new(batch.smooth[k0..k0 + 16].try_into().expect("16 lanes"));
    let s = SurfaceLanes {
        p: gather(&batch.p),
        p_error: gather(&batch.p_error),
        ng: gather(&batch.ng),
        ns: gather(&batch.ns),
        base: gather(&batch.base),
        smooth: spread(smooth, &from),
        wo: gather(&batch.dir).negated(),
        albedo: per_point(|h| h.albedo),
    };
    let lane_weight = per_point(|h| h.weight);
    let hl = pts[0].hl;
    let (fast, accepted) = QuadSamples::per_lane(&s, &hl);
    let one = (1u32 << samples) - 1;
    let mut left = 0u32;
    let mut active = 0u32;
    let mut segments = [(0u32, SegmentSides::default()); 16];
    for (j, segment) in segments.iter_mut().enumerate().take(n) {
        let lanes = one << (j * stride);
        if accepted >> (j * stride) & 1 == 1 {
            active |= lanes;
            segment.0 = lanes;
        } else {
            left |= 1 << j;
        }
    }
    // The spheres near each light's segments: every sphere (`PACK_SPHERE_CULL`), or
    // per point from the cull of its lane group of hits (`GroupCull`, as
    // `shade_quads`), united per light.
    points.near.clear();
    points.near.resize(lights, occluders.every_sphere());
    if occluders.pack_sphere_cull() {
        cull_pack_spheres(occluders, quads, pts, left, stride, &fast, points);
    }
    let plan = &shader.plan;
    // `hit_points_append` draws a square jittered set (the default sampler's light
    // points) by `append_2d_split`, whatever the depth.
    //
    // Measured: made per pack, `PackLayout::new` was 3.6 % of the frame (perf).
    //
    // Borrowed, not copied: a copy of the layout (~0.5 kB) per pack was ~2.7 % of
    // `shade_quads_packed`'s samples (perf, dof_area 960x720, 1 thread).
    let key = (samples as u32, stride);
    if !matches!(points.layout, Some((k, _)) if k == key) {
        points.layout = Some((key, PackLayout::new(samples as u32, stride)));
    }
    let layout = points
        .layout
        .as_ref()
        .and_then(|(_, layout)| layout.as_ref())
        .filter(|_| plan.sampler == SamplerKind::Jittered);
    // The points' base points, point `j` in lane `j` (as loaded from the batch).
    let bases = batch.base.lanes(k0);
    let accepted_points = !left & ((1u32 << n) - 1);
    for (i, (index, quad)) in quads.lights.iter().enumerate() {
        let near = occluders.spheres_near_points(bases, accepted_points, points.near[i], quad);
        let (u, v) = match layout {
            // A square jittered set per point: the pack's draws in lanes, each point's
            // from its stream (`PackLayout`, the loop below bit for bit).
            Some(layout) => {
                let mut states = [0u64; 16];
                for (j, h) in pts.iter().enumerate() {
                    if left >> j & 1 == 1 {
                        continue;
                    }
                    let set = h.light_set(shader.seed, *index);
                    let rng =
                        streams[j].get_or_insert_with(|| path_rng(set.seed, set.pixel, set.path));
                    states[j & 15] = rng.skip_pairs(samples as u32);
                    sinks.drawn.light += samples as u64;
                }
                layout.points(&states, accepted_points)
            }
            None => {
                // Each point's light points appended at its block of lanes (zeros
                // between and after, as `hit_points_split` pads).
                let (u, v) = (&mut points.u, &mut points.v);
                u.clear();
                v.clear();
                for (j, h) in pts.iter().enumerate() {
                    if left >> j & 1 == 1 {
                        continue;
                    }
                    u.resize(j * stride, 0.0);
                    v.resize(j * stride, 0.0);
                    hit_points_append(
                        plan.sampler,
                        h.light_set(shader.seed, *index),
                        samples as u32,
                        &mut streams[j],
                        (u, v),
                        &mut points.pairs,
                    );
                    sinks.drawn.light += samples as u64;
                }
                u.resize(16, 0.0);
                v.resize(16, 0.0);
                let lane = |a: &[f32]| Packet::new(a[..16].try_into().expect("16 lanes"));
                (lane(u), lane(v))
            }
        };
        let sl = fast.lanes(&s, &hl, quad, u, v, samples as f32, active);
        let live = sl.mask & 0xffff;
        if live == 0 {
            continue;
        }
        sinks.rays.shadow += live.count_ones() as u64;
        let settled =
            occluders.settle_segments(sl.origin, sl.dir, sl.tmax, live, &near, &mut segments[..n]);
        sinks.rays.transmitted_shadow += settled.settled.count_ones() as u64;
        if settled.pass == 0 {
            continue;
        }
        // `shade_quads`' lane sum (one lane group: zero plus the passing terms), then
        // its `reduce_add` per point.
        let c = sl.contribution.times(lane_weight).times(settled.factor);
        let pass = <Packet as Lanes>::mask_from_bits(settled.pass);
        let sum = V3::splat(Vec3::ZERO).plus(V3::select(pass, c, V3::splat(Vec3::ZERO)));
        let (x, y, z) = (
            block_sums(sum.x, stride),
            block_sums(sum.y, stride),
            block_sums(sum.z, stride),
        );
        for j in 0..n {
            if settled.pass >> (j * stride) & one != 0 {
                points.totals[j * lights + i] = Some(Vec3::new(x[j], y[j], z[j]));
            }
        }
    }
    left
}

/// The pack's sphere cull ([`PACK_SPHERE_CULL`](super::tiny_shadow::PACK_SPHERE_CULL)):
/// per light, the union over the points not in `left` of the spheres near their
/// segments, from the cull of each point's lane group of hits (`GroupCull`, as
/// [`shade_quads`]), into `points.near`.
fn cull_pack_spheres(
    occluders: &LaneOccluders,
    quads: &QuadLights,
    pts: &[ShadingPoint],
    left: u32,
    stride: usize,
    fast: &QuadSamples,
    points: &mut LightPoints,
) {
    let batch = pts[0].batch;
    let mut first = true;
    let origins = fast.lane_origins();
    for (j, h) in pts.iter().enumerate() {
        if left >> j & 1 == 1 {
            continue;
        }
        let k = h.k;
        let culled = points
            .cull
            .bits(occluders, origins.at(j * stride), &quads.lights, || {
                let end = batch.ray.len().max(k + 1);
                let live = (1u32 << (end - k).min(16)) - 1;
                let lanes = |a: &super::hit_batch::Soa3| a.lanes(k);
                let (b, e, n) = (lanes(&batch.base), lanes(&batch.p_error), lanes(&batch.ng));
                OriginBox::of_group(b, e, n, live)
            });
        for (i, near) in points.near.iter_mut().enumerate() {
            let bits = if culled {
                points.cull.near(i)
            } else {
                occluders.every_sphere()
            };
            *near = if first { bits } else { near.union(bits) };
        }
        first = false;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::{AccelKind, BatchScratch, SceneAccel, TinyScratch};
    use crate::geometry::gamma;
    use crate::integrator::RenderOptions;
    use crate::integrator::camera_rays::SamplePlan;
    use crate::integrator::queues::{PerChildKind, RayQueue, ShadowQueue};
    use crate::integrator::shade_stage::{LaneShading, ShadeScratch, shade_queue};
    use crate::integrator::shader::{ChildKind, Emitted};
    use crate::integrator::shadow::ShadowFilter;
    use crate::scene::{Camera, Light, Material, Scene, SceneBuilder};
    use crate::stats::{EffectSamplesDrawn, RayCounts};

    /// A tiny scene (a floor quad, a mirror and a glass sphere: four primitives, the
    /// Whitted rows' kind) under a wide quad light whose samples, seen from the far
    /// ends of the floor, straddle the diagonals between dominant axes (mixed shear
    /// keys within one lane group), and a point light.
    fn scene() -> Scene {
        let mut b = SceneBuilder::new();
        let floor = b.add_material(Material {
            specular: Vec3::splat(0.3),
            shininess: 40.0,
            ..Material::diffuse("floor", Vec3::new(0.8, 0.6, 0.4))
        });
        let chrome = b.add_material(Material {
            diffuse: Vec3::splat(0.1),
            specular: Vec3::splat(0.6),
            shininess: 200.0,
            ..Material::mirror("chrome", Vec3::splat(0.8))
        });
        let glass = b.add_material(Material {
            transmission: Vec3::new(0.9, 0.7, 0.5),
            ..Material::glass("glass", 1.5)
        });
        b.add_quad(
            Vec3::new(-12.0, 0.0, -12.0),
            Vec3::new(0.0, 0.0, 24.0),
            Vec3::new(24.0, 0.0, 0.0),
            floor,
        );
        b.add_sphere(Vec3::new(1.1, 1.3, -1.4), 1.3, chrome);
        b.add_sphere(Vec3::new(-0.9, 1.0, 1.0), 1.0, glass);
        b.add_light(Light::Quad {
            corner: Vec3::new(-3.0, 4.0, -2.0),
            edge1: Vec3::new(6.0, 0.0, 0.0),
            edge2: Vec3::new(0.0, 0.0, 4.0),
            radiance: Vec3::splat(6.0),
        });
        b.add_light(Light::Point {
            position: Vec3::new(-5.0, 9.0, 7.0),
            intensity: Vec3::splat(60.0),
        });
        b.camera = Some(Camera {
            eye: Vec3::new(0.0, 3.0, 9.0),
            target: Vec3::new(0.0, 0.5, 0.0),
            up: Vec3::Y,
            vfov_deg: 75.0,
        });
        b.finish().expect("the test scene")
    }

    fn sinks(scene: &Scene, slots: usize) -> Sinks {
        Sinks {
            acc: vec![Vec3::ZERO; slots],
            slot_pixel: (0..slots as u64).collect::<Vec<_>>().into(),
            next: PerChildKind::default(),
            shadow: (0..scene.lights.len())
                .map(|_| ShadowQueue::default())
                .collect(),
            area: scene.lights.iter().map(Light::is_area).collect(),
            emitted: Emitted::default(),
            rays: RayCounts::default(),
            drawn: EffectSamplesDrawn::default(),
        }
    }

    /// The queue path's shadow stage (`wavefront::trace_shadows` for a tiny scene):
    /// every queued ray settled by the tiny pass or the plain occlusion batch, and its
    /// contribution times its transmittance added to its camera sample, in queue order.
    /// Counts the terms each camera sample receives into `terms`; returns the number
    /// of rays of the quad light (light 0) blocked outright.
    fn trace_queues(
        accel: &SceneAccel,
        filter: Option<&ShadowFilter>,
        sinks: &mut Sinks,
        terms: &mut [u32],
    ) -> usize {
        let mut dark = 0;
        let (mut tiny, mut batch) = (TinyScratch::default(), BatchScratch::default());
        for (light, q) in sinks.shadow.iter_mut().enumerate() {
            let mut t = Vec::new();
            if let Some(pass) = filter.and_then(|f| f.tiny_pass(accel)) {
                pass.transmittance_batch(&q.rays, &mut t, &mut tiny, &mut sinks.rays);
            } else {
                let mut blocked = vec![false; q.rays.len()];
                accel.any_hit_batch(&q.rays, &mut blocked, &mut batch);
                t = blocked
                    .iter()
                    .map(|&b| if b { Vec3::ZERO } else { Vec3::ONE })
                    .collect();
            }
            for ((&t, &slot), &c) in t.iter().zip(&q.slot).zip(&q.contribution) {
                terms[slot as usize] += 1;
                if t != Vec3::ZERO {
                    sinks.acc[slot as usize] += c * t;
                }
            }
            if light == 0 {
                dark += t.iter().filter(|&&t| t == Vec3::ZERO).count();
            }
            q.clear();
        }
        dark
    }

    fn bits(v: &Vec3) -> [u32; 3] {
        v.to_array().map(f32::to_bits)
    }

    /// Every field of a child queue, bit for bit.
    type QueueBits = (
        Vec<[u32; 9]>,
        Vec<u32>,
        Vec<[u32; 3]>,
        Vec<[u32; 3]>,
        Vec<u64>,
    );

    fn queue_bits(q: &Option<RayQueue>) -> Option<QueueBits> {
        q.as_ref().map(|q| {
            let ray = |r: &crate::geometry::Ray| {
                let [a, b, c] = bits(&r.origin);
                let [d, e, f] = bits(&r.dir);
                let rest = [r.tmin, r.tmax, r.time].map(f32::to_bits);
                [a, b, c, d, e, f, rest[0], rest[1], rest[2]]
            };
            let (slot, weight, throughput, path) = q.per_ray();
            (
                q.rays.iter().map(ray).collect(),
                slot,
                weight.iter().map(bits).collect(),
                throughput.iter().map(bits).collect(),
                path,
            )
        })
    }

    /// Packed shading points ([`shade_quads_packed`], the sums added in point order)
    /// against one point at a time ([`shade_quads`]) on the same hits, bit for bit:
    /// every camera sample's sum, the ray counts, the samples drawn and each point's
    /// stream after its draws; 1, 2, 3, 4 and 8 samples at their pack widths, 9 and
    /// 16 in packs of one point (lane-group width) and 64 left to `shade_quads`, at
    /// the first hits and two waves of children (mirror and glass), the Sobol sampler
    /// (the pixel's sequence at first hits) and the jittered one (the point's own
    /// stream), transmitted shadows through the glass sphere on and off, the pack's
    /// sphere cull (`PACK_SPHERE_CULL`) on and off. Each lane's
    /// albedo and weight differ from its neighbours'.
    #[test]
    fn packed_points_match_one_point_at_a_time_bit_for_bit() {
        use crate::integrator::SamplerKind;
        let scene = scene();
        let accel = SceneAccel::build(&scene, AccelKind::Bvh4);
        let (mut packs, mut lit_samples, mut points_compared) = (0usize, 0u64, 0usize);
        let mut culled_packs = [0usize; 2];
        for samples in [1u32, 2, 3, 4, 8, 9, 16, 64] {
            for sampler in [SamplerKind::Sobol, SamplerKind::Jittered] {
                for (through_glass, cull) in
                    [(true, false), (false, false), (true, true), (false, true)]
                {
                    let name = format!(
                        "{samples} samples, {sampler}, glass {through_glass}, pack cull {cull}"
                    );
                    let mut opts = RenderOptions::from_scene(&scene);
                    opts.samples.shadow = samples;
                    opts.transmitted_shadows = through_glass;
                    let mut plan = SamplePlan::new(&scene, &opts);
                    plan.sampler = sampler;
                    let shader = Shader::new(&scene, &opts, plan);
                    let filter = ShadowFilter::new(&scene, through_glass, accel.kind);
                    let occluders = LaneOccluders::new(&accel, filter.as_ref())
                        .map(|o| o.with_pack_sphere_cull(cull));
                    let lanes = LaneShading::new(&scene, plan.environment)
                        .expect("lane path")
                        .with_area_occluders(occluders);
                    let quads = lanes.quads();
                    let occluders = quads.occluders.as_ref().expect("a tiny scene");
                    let stride = pack_stride(samples).unwrap_or(16);
                    let (w, h) = (24, 18);
                    let frame = scene.camera.frame(w, h);
                    let queue = RayQueue::pixel_centres(&frame, w, h, plan.first_path());
                    let slots = (w * h) as usize;
                    let mut scratch = ShadeScratch::default();
                    let mut queues = vec![(queue, 0)];
                    while let Some((queue, depth)) = queues.pop() {
                        let hits: Vec<_> =
                            queue.rays.iter().map(|r| accel.closest_hit(r)).collect();
                        let (mut a, mut b) = (sinks(&scene, slots), sinks(&scene, slots));
                        let mut batch = crate::integrator::hit_batch::HitBatch::default();
                        batch.build(&scene, &queue.rays, &hits);
                        let (mut pa, mut pb) = (LightPoints::default(), LightPoints::default());
                        for (material, range) in batch.groups.clone() {
                            let m = &scene.materials[material as usize];
                            let hl = Highlight {
                                specular: m.specular,
                                shininess: m.shininess,
                            };
                            let point = |k: usize| {
                                let q = batch.ray[k] as usize;
                                let slot = queue.slot(q);
                                ShadingPoint {
                                    batch: &batch,
                                    k,
                                    albedo: m.diffuse * (1.0 + (k % 5) as f32 * 0.1),
                                    hl,
                                    slot,
                                    weight: queue.weight(q) * (1.0 + (k % 3) as f32 * 0.25),
                                    time: queue.rays[q].time,
                                    pixel: slot as u64,
                                    path: queue.path(q),
                                    depth,
                                }
                            };
                            let mut k = range.start;
                            while k < range.end {
                                let n = (range.end - k).min(16 / stride);
                                let pts: Vec<_> = (k..k + n).map(point).collect();
                                let mut one: Vec<Option<PixelRng>> = vec![None; n];
                                for (h, stream) in pts.iter().zip(&mut one) {
                                    shade_quads(&shader, quads, h, stream, &mut a, &mut pa);
                                }
                                let mut packed: Vec<Option<PixelRng>> = vec![None; 16];
                                if samples <= 16 {
                                    let left = shade_quads_packed(
                                        &shader,
                                        quads,
                                        occluders,
                                        &pts,
                                        stride,
                                        &mut packed,
                                        &mut b,
                                        &mut pb,
                                    );
                                    assert_eq!(left, 0, "{name}: every point accepted");
                                    let l = quads.lights.len();
                                    for (j, h) in pts.iter().enumerate() {
                                        for t in pb.totals[j * l..(j + 1) * l].iter().flatten() {
                                            b.acc[h.slot as usize] += *t;
                                        }
                                    }
                                    packs += 1;
                                    culled_packs[cull as usize] += 1;
                                } else {
                                    for (h, stream) in pts.iter().zip(&mut packed) {
                                        shade_quads(&shader, quads, h, stream, &mut b, &mut pb);
                                    }
                                }
                                for (j, (x, y)) in one.iter().zip(&packed).enumerate() {
                                    let after =
                                        |r: &Option<PixelRng>| r.clone().map(|mut r| r.next_u64());
                                    assert_eq!(
                                        after(x),
                                        after(y),
                                        "{name} depth {depth}: stream {j}"
                                    );
                                }
                                points_compared += n;
                                k += n;
                            }
                        }
                        assert_eq!(a.rays, b.rays, "{name} depth {depth}: ray counts");
                        assert_eq!(a.drawn, b.drawn, "{name} depth {depth}: samples drawn");
                        for (slot, (x, y)) in a.acc.iter().zip(&b.acc).enumerate() {
                            assert_eq!(bits(x), bits(y), "{name} depth {depth} sample {slot}");
                            lit_samples += (*x != Vec3::ZERO) as u64;
                        }
                        // The children of the mirror and the glass (no random numbers),
                        // for the next waves.
                        let mut c = sinks(&scene, slots);
                        shade_queue(
                            &shader,
                            Some(&lanes),
                            &queue,
                            &hits,
                            depth,
                            &mut c,
                            &mut scratch,
                        );
                        for kind in ChildKind::ALL {
                            if depth < 2
                                && let Some(q) = c.next[kind].take()
                                && !q.rays.is_empty()
                            {
                                queues.push((q, depth + 1));
                            }
                        }
                    }
                }
            }
        }
        eprintln!(
            "packed quad lights: {packs} packs ({culled_packs:?} without and with the pack's \
             sphere cull), {points_compared} points, {lit_samples} lit sums"
        );
        assert!(
            culled_packs.iter().all(|&p| p > 1000) && lit_samples > 5_000,
            "{culled_packs:?} packs, {lit_samples} lit"
        );
    }

    /// The fused path (samples settled and summed in lanes) against the queue path
    /// (queued, settled by the tiny scene's batch, added one by one) on the same hits:
    /// camera rays and two waves of their children, with transmitted shadows through
    /// the glass sphere on (the `TinyShadow` glass pass) and off (the plain occlusion
    /// batch), 64 samples (whole lane groups) and 20 (a partial one). The ray counts
    /// (shadow rays, rays settled through glass), the samples drawn, the child rays and
    /// the point light's queue are the same bit for bit; each camera sample's radiance
    /// is within `2 γ_N` relative of the queue path's, `N` the number of terms it
    /// summed (see the module: both sums of non-negative terms are within `γ_N` of the
    /// exact one).
    #[test]
    fn fused_quad_light_sums_match_the_queue_path_on_real_hits() {
        let scene = scene();
        let accel = SceneAccel::build(&scene, AccelKind::Bvh4);
        assert!(accel.tiny.is_some(), "the test scene is a tiny one");
        let (mut shadow_rays, mut settled, mut differ, mut slots_compared) = (0, 0, 0, 0);
        let mut blocked = 0;
        for (through_glass, samples) in [(true, 64), (true, 20), (false, 64)] {
            let name = format!("transmitted shadows {through_glass}, {samples} samples");
            let mut opts = RenderOptions::from_scene(&scene);
            opts.samples.shadow = samples;
            opts.transmitted_shadows = through_glass;
            let plan = SamplePlan::new(&scene, &opts);
            let shader = Shader::new(&scene, &opts, plan);
            let filter = ShadowFilter::new(&scene, through_glass, accel.kind);
            assert_eq!(filter.is_some(), through_glass, "{name}");
            let occluders = LaneOccluders::new(&accel, filter.as_ref());
            assert!(occluders.is_some(), "{name}: the fused path applies");
            let queued = LaneShading::new(&scene, plan.environment).expect("lane path");
            let fused = LaneShading::new(&scene, plan.environment)
                .expect("lane path")
                .with_area_occluders(occluders);
            let (w, h) = (64, 48);
            let frame = scene.camera.frame(w, h);
            let queue = RayQueue::pixel_centres(&frame, w, h, plan.first_path());
            let slots = (w * h) as usize;
            let mut scratch = ShadeScratch::default();
            let mut queues = vec![(queue, 0)];
            while let Some((queue, depth)) = queues.pop() {
                let hits: Vec<_> = queue.rays.iter().map(|r| accel.closest_hit(r)).collect();
                let (mut a, mut b) = (sinks(&scene, slots), sinks(&scene, slots));
                let f = Some(&fused);
                shade_queue(&shader, f, &queue, &hits, depth, &mut a, &mut scratch);
                assert!(a.shadow[0].rays.is_empty(), "{name}: nothing queued");
                let q = Some(&queued);
                shade_queue(&shader, q, &queue, &hits, depth, &mut b, &mut scratch);
                let mut terms = vec![1u32; slots];
                let mut ignored = vec![1u32; slots];
                trace_queues(&accel, filter.as_ref(), &mut a, &mut ignored);
                let quad_rays = b.shadow[0].rays.len();
                blocked += trace_queues(&accel, filter.as_ref(), &mut b, &mut terms);
                assert_eq!(a.rays, b.rays, "{name} depth {depth}: ray counts");
                assert_eq!(a.drawn, b.drawn, "{name} depth {depth}: samples drawn");
                shadow_rays += quad_rays;
                settled += a.rays.transmitted_shadow;
                for (slot, (x, y)) in a.acc.iter().zip(&b.acc).enumerate() {
                    let n = terms[slot];
                    let tol = 2.0 * gamma(n) * x.abs().max(y.abs());
                    for c in 0..3 {
                        assert!(
                            (x[c] - y[c]).abs() <= tol[c],
                            "{name} depth {depth} sample {slot}: fused {x} queued {y} ({n} terms)"
                        );
                    }
                    differ += (bits(x) != bits(y)) as usize;
                    slots_compared += 1;
                }
                for (light, (qa, qb)) in a.shadow.iter().zip(&b.shadow).enumerate() {
                    assert!(qa.rays.is_empty() && qb.rays.is_empty(), "light {light}");
                }
                for kind in ChildKind::ALL {
                    let qa = &mut a.next[kind];
                    assert!(
                        queue_bits(qa) == queue_bits(&b.next[kind]),
                        "{name} depth {depth}: {kind:?} children"
                    );
                    if depth < 2
                        && let Some(q) = qa.take()
                        && !q.rays.is_empty()
                    {
                        queues.push((q, depth + 1));
                    }
                }
            }
        }
        eprintln!(
            "fused quad lights: {shadow_rays} samples, {settled} settled through glass, \
             {blocked} blocked, {differ} of {slots_compared} camera-sample sums not bit-equal"
        );
        assert!(shadow_rays > 100_000, "{shadow_rays} samples compared");
        assert!(settled > 1_000, "{settled} samples through glass");
        assert!(blocked > 5_000, "{blocked} samples blocked");
    }
}
