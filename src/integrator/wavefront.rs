//! Wavefront integrator: the recursive renderer's ray tree, traced breadth first from
//! ray queues in batches (Laine, Karras, Aila, "Megakernels Considered Harmful:
//! Wavefront Path Tracing on GPUs", HPG 2013; on the CPU, the batches feed the BVH4's
//! 16-ray packet kernels).
//!
//! Work proceeds per tile of `TILE`² pixels with all their samples, so the queues
//! are bounded by the tile, not the image. Per tile:
//!
//! 1. **camera**: the camera rays of every pixel, built 16 at a time by
//!    `CameraSampler::block_rays` (the same rays, bit for bit, as the recursive
//!    renderer's `CameraSampler::pixel_samples`), pixels in 4×4 blocks so that 16
//!    consecutive rays form a coherent packet;
//! 2. **trace**: their closest hits, in batches ([`SceneAccel::closest_hit_batch`]);
//! 3. **shade**: the hits grouped by material (`shade_queue`): in lanes where the
//!    lane path covers the material and lights, else through `Shader::shade_emit`,
//!    the local shading shared with the recursive renderer (the same rays either
//!    way): the local radiance goes into the accumulator of the
//!    camera sample, shadow rays into the point/directional or the area-light shadow
//!    queue with their unoccluded contribution, child rays into the reflection,
//!    refraction, glossy or translucency queue with their weight;
//! 4. **shadow**: each shadow queue is traced for occlusion in batches
//!    ([`SceneAccel::any_hit_batch`]); unblocked rays add their contribution;
//! 5. the child queues become the next wave (trace, shade, shadow) until they are
//!    empty (the depth limit and the contribution cutoff stop emission in `shade_emit`);
//! 6. the camera-sample accumulators are filtered into pixels by
//!    `resolve_pixels`, the recursive renderer's own filter step (a sample whose total
//!    is NaN or infinite is dropped and counted).
//!
//! Radiance is linear in the tree, so summing `weight · local` over the tree's nodes in
//! any order gives the recursive result up to float summation order. Random numbers
//! are keyed by path identity ([`path_rng`](super::path_keys::path_rng)), so the
//! distribution effects draw the same samples in both integrators too.
//!
//! The scene decides the pipeline ([`Pipeline`]): a queue, and its stage, exists only
//! if the scene's features can put a ray in it.
//!
//! This file holds the wave loop only; the queues are in [`super::queues`], and the
//! stages it shares with the recursive integrator (camera rays, surface interactions,
//! shading, pixel filter, tiles) in their own files.

use super::RenderOptions;
use super::RenderOutput;
use super::camera_packets::{CameraStaging, block_pixel_indices, push_block_pixels};
use super::camera_rays::{CameraSampler, SamplePlan};
use super::pixel_filter::{TileOut, reads_offsets, resolve_pixels};
use super::point_shadow::PointOccluders;
use super::queues::{PerChildKind, RayQueue, ShadowQueue};
use super::shade_stage::{LaneShading, ShadeScratch, Sinks, shade_queue};
use super::shader::{ChildKind, Emitted, Shader};
use super::shadow::{ShadowFilter, ShadowScratch};
use super::tiles::{Tile, TileResult, render_tiles};
use super::tiny_shadow::LaneOccluders;
use crate::accel::{BatchScratch, Occluder, SceneAccel, SceneHit};
use crate::film::Film;
use crate::geometry::Ray;
use crate::scene::{Light, Scene};
use crate::stats::{EffectSamplesDrawn, RayCounts, StageTimes};
use glam::Vec3;
use std::time::Instant;

/// Renders `scene` with the structure `accel`, breadth first. Same contract as
/// [`recursive::render`](super::recursive::render), and the same image up to float
/// summation order.
pub fn render(scene: &Scene, accel: &SceneAccel, opts: &RenderOptions) -> RenderOutput {
    render_with(scene, accel, opts, None)
}

/// [`render`] into `film` where one is given: made before the render with its memory
/// mapped ([`Film::committed`]), the size of the region (`opts.region()`). `None`
/// renders into a fresh film, as [`render`] does.
pub fn render_with(
    scene: &Scene,
    accel: &SceneAccel,
    opts: &RenderOptions,
    film: Option<Film>,
) -> RenderOutput {
    let pipeline = Pipeline::new(scene, opts);
    let filter = ShadowFilter::new(scene, opts.transmitted_shadows, accel.kind);
    // In a tiny scene the quad lights' samples are settled where they are generated
    // (`area_light`), not queued for the area-shadow stage.
    // Likewise the point and directional lights' shadow rays, in the shading lanes
    // (`point_shadow`): their queues stay empty, and the `shadow` stage with them.
    let lanes = LaneShading::new(scene, SamplePlan::new(scene, opts).environment).map(|l| {
        l.with_area_occluders(LaneOccluders::new(accel, filter.as_ref()))
            .with_point_occluders(PointOccluders::new(accel, filter.as_ref()))
    });
    render_tiles(
        scene,
        opts,
        film,
        || Workspace::new(&pipeline, scene),
        |ws, camera, tile, out| {
            let stage = (&pipeline, lanes.as_ref(), filter.as_ref());
            render_tile(scene, accel, opts, stage, camera, ws, (tile, out))
        },
    )
}

/// The queues (and stages) a scene needs, from its features and the render options.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Pipeline {
    /// Shadow rays towards point and directional lights: one per light and lit hit.
    pub shadow: bool,
    /// Shadow rays towards points sampled on area lights.
    pub area_shadow: bool,
    /// Mirror reflection and the reflected part of glass.
    pub reflection: bool,
    pub refraction: bool,
    pub glossy: bool,
    pub translucency: bool,
}

impl Pipeline {
    pub fn new(scene: &Scene, opts: &RenderOptions) -> Self {
        let f = &scene.features;
        // Only diffuse or specular materials ask for direct light.
        let lit = f.diffuse || f.specular;
        let secondary = opts.max_depth > 0;
        Pipeline {
            shadow: lit && (f.point_lights || f.directional_lights),
            // The environment's sampled shadow rays share the area-light stage.
            area_shadow: lit && (f.area_lights || f.environment),
            reflection: secondary && (f.mirror || f.glass),
            refraction: secondary && f.glass,
            glossy: secondary && f.glossy,
            translucency: secondary && f.translucency,
        }
    }

    /// Which child queues exist.
    fn child_queues(&self) -> PerChildKind<bool> {
        PerChildKind {
            reflection: self.reflection,
            refraction: self.refraction,
            glossy: self.glossy,
            translucency: self.translucency,
        }
    }
}

/// Most camera rays in flight per wave, per thread: a tile's camera rays are generated
/// in batches of at most this many, divided by the most rays one camera ray's first hit
/// can emit ([`Pipeline::first_hit_fanout`]), and each batch is traced, shaded and
/// finished (every child wave) before the next is generated. So the queues of a wave
/// hold about this many paths whatever the samples per pixel and per effect, and peak
/// memory depends on the thread count and the image, not on `spp x lens x time x
/// shadow`. 8192 paths keep 512 full 16-ray packets per batch.
pub const MAX_WAVE_PATHS: usize = 8192;

impl Pipeline {
    /// The most rays the first hit of one camera ray can put in the queues: one shadow
    /// ray per point, spot or directional light, `shadow` per area light, two
    /// reflections (mirror and glass), one refraction or `glossy` translucent rays, and
    /// `glossy` glossy rays.
    pub fn first_hit_fanout(scene: &Scene, plan: &SamplePlan) -> usize {
        let area = scene.lights.iter().filter(|l| l.is_area()).count();
        let other = scene.lights.len() - area;
        other + area * plan.shadow as usize + 3 + 2 * plan.glossy as usize
    }

    /// Camera rays per batch: [`MAX_WAVE_PATHS`] over the camera ray itself plus its
    /// first hit's fan-out, at least one.
    ///
    /// The fan-out still counts the shadow rays that a tiny scene settles in the
    /// shading lanes (`point_shadow`, `area_light`) and never queues, so those frames
    /// run smaller batches than the bound allows (whitted_blur16 1024 camera rays,
    /// whitted_area64 117). Tried (helper bl22, 2026-11-29, a temporary override of
    /// this value, one binary, images byte-identical; process CPU ms, 5 interleaved
    /// rounds, 1 thread, host load 6-8): whitted_blur16 1365 -> 2048 rays
    /// 1341/1452/1732 -> 1358/1485/1694 (min/median/max), whitted_area64 120 -> 2048
    /// 1122/1217/1381 -> 1258/1283/1382: no gain, so the count stays as it is.
    pub fn camera_batch(scene: &Scene, plan: &SamplePlan) -> usize {
        (MAX_WAVE_PATHS / (1 + Self::first_hit_fanout(scene, plan))).max(1)
    }
}

/// Per-worker queues and scratch, sized by the largest batch seen, reused across tiles.
struct Workspace {
    /// Staging of the lane-parallel camera rays, the pixels of the chunk being
    /// generated and their rays, before they enter the bounded queue. A chunk of whole
    /// 4x4 blocks only is `blocks` alone (`pixels` empty: no pixel list is made,
    /// `CameraSampler::whole_block_rays`); once a part of a block joins it, `pixels`
    /// lists every pixel of the chunk (`(x, y, index)`, the blocks' too).
    staging: CameraStaging,
    pixels: Vec<(u32, u32, u64)>,
    blocks: Vec<(u32, u32)>,
    generated: Vec<Ray>,
    /// The part of `generated` that fits the batch, when not all of it does.
    split: Vec<Ray>,
    /// Eye-sample offsets of each pixel not yet resolved, in generation order.
    offsets: Vec<(f32, f32)>,
    /// Row-major position in the tile of each pixel not yet resolved.
    unresolved: Vec<u32>,
    /// Radiance of the finished camera rays of the pixels not yet resolved.
    radiance: Vec<Vec3>,
    camera: RayQueue,
    current: PerChildKind<Option<RayQueue>>,
    sinks: Sinks,
    hits: Vec<Option<SceneHit>>,
    occluded: Vec<bool>,
    /// Which primitive set blocks each shadow ray (scenes with transmitted shadows).
    occluders: Vec<Option<Occluder>>,
    /// The transmittance of each shadow ray, and the buffers that settle it.
    transmitted: Vec<Vec3>,
    shadow_scratch: ShadowScratch,
    scratch: BatchScratch,
    shade: ShadeScratch,
}

impl Workspace {
    fn new(p: &Pipeline, scene: &Scene) -> Self {
        Workspace {
            staging: CameraStaging::default(),
            pixels: Vec::new(),
            blocks: Vec::new(),
            generated: Vec::new(),
            split: Vec::new(),
            offsets: Vec::new(),
            unresolved: Vec::new(),
            radiance: Vec::new(),
            camera: RayQueue::default(),
            current: p.child_queues().map(|on| on.then(RayQueue::default)),
            sinks: Sinks {
                acc: Vec::new(),
                slot_pixel: Default::default(),
                next: p.child_queues().map(|on| on.then(RayQueue::default)),
                // One queue per light, and one for the environment after them.
                shadow: (0..scene.lights.len() + scene.environment.is_some() as usize)
                    .map(|_| ShadowQueue::default())
                    .collect(),
                area: scene
                    .lights
                    .iter()
                    .map(Light::is_area)
                    .chain(scene.environment.as_ref().map(|_| true))
                    .collect(),
                emitted: Emitted::default(),
                rays: RayCounts::default(),
                drawn: EffectSamplesDrawn::default(),
            },
            hits: Vec::new(),
            occluded: Vec::new(),
            occluders: Vec::new(),
            transmitted: Vec::new(),
            shadow_scratch: ShadowScratch::default(),
            scratch: BatchScratch::default(),
            shade: ShadeScratch::default(),
        }
    }

    /// Paths held in the queues now: the queues being traced, the next wave's and
    /// the shadow queues.
    fn live_paths(&self, camera: bool) -> u64 {
        let queued = |q: &PerChildKind<Option<RayQueue>>| -> usize {
            q.iter()
                .filter_map(|(_, q)| q.as_ref())
                .map(|q| q.rays.len())
                .sum()
        };
        let shadow: usize = self.sinks.shadow.iter().map(|q| q.rays.len()).sum();
        let camera = if camera { self.camera.rays.len() } else { 0 };
        (camera + queued(&self.current) + queued(&self.sinks.next) + shadow) as u64
    }
}

/// Pixels are generated in 4×4 blocks: with one sample per pixel, 16 consecutive
/// camera rays cover one block, the footprint of a coherent packet.
const BLOCK: u32 = 4;

/// Pixels in the chunk being gathered: its whole blocks, or its listed pixels once it
/// lists them (see [`Workspace::pixels`]).
fn chunk_len(ws: &Workspace) -> usize {
    if ws.pixels.is_empty() {
        ws.blocks.len() * (BLOCK * BLOCK) as usize
    } else {
        ws.pixels.len()
    }
}

/// What every wave of a tile needs.
struct WaveContext<'a> {
    shader: Shader<'a>,
    /// The lane-parallel shading of the scene's common materials and lights
    /// (`shade_stage`); `None` when a light or the environment needs the scalar shader.
    lanes: Option<&'a LaneShading>,
    accel: &'a SceneAccel,
    /// Shadow rays through glass (`shadow` module) need the scene to look up materials.
    transmit: Option<(&'a Scene, &'a ShadowFilter)>,
    /// Cut-out holes (`texturing`): hits in them are replaced by the solid hit behind.
    cutouts: Option<&'a Scene>,
}

fn render_tile(
    scene: &Scene,
    accel: &SceneAccel,
    opts: &RenderOptions,
    (pipeline, lanes, filter): (&Pipeline, Option<&LaneShading>, Option<&ShadowFilter>),
    camera: &CameraSampler,
    ws: &mut Workspace,
    (tile, out): (Tile, &mut TileOut),
) -> TileResult {
    let plan = camera.plan;
    let cx = WaveContext {
        shader: Shader::new(scene, opts, plan),
        lanes,
        accel,
        transmit: filter.map(|f| (scene, f)),
        cutouts: super::texturing::has_cutouts(scene).then_some(scene),
    };
    let mut stages = StageTimes {
        shadow: pipeline.shadow.then_some(0.0),
        area_shadow: pipeline.area_shadow.then_some(0.0),
        reflection: pipeline.reflection.then_some(0.0),
        refraction: pipeline.refraction.then_some(0.0),
        glossy: pipeline.glossy.then_some(0.0),
        translucency: pipeline.translucency.then_some(0.0),
        ..StageTimes::default()
    };
    ws.sinks.rays = RayCounts::default();
    ws.sinks.drawn = EffectSamplesDrawn::default();
    ws.sinks.acc.clear();
    ws.sinks.slot_pixel.clear();
    ws.offsets.clear();
    ws.unresolved.clear();
    ws.radiance.clear();
    ws.camera.clear();

    let batch = Pipeline::camera_batch(scene, &plan);
    let rays_per_pixel = (plan.eye_rendered() * camera.rays_per_eye()) as usize;
    let eye = plan.eye_rendered() as usize;
    let mut nonfinite_samples = 0;
    let mut peak = 0;
    // The eye-sample offsets are kept only where the pixel filter reads them (not for
    // one box-filtered ray per pixel).
    let keep_offsets = reads_offsets(&plan, out.sums.is_some());
    // Traces a batch to the end, then filters every pixel whose rays are all done.
    let mut flush = |ws: &mut Workspace, stages: &mut StageTimes, clock: &mut Lap| {
        peak = run_waves(&cx, ws, stages, clock).max(peak);
        if ws.radiance.is_empty() {
            // Every pixel before was resolved (one ray per pixel, or whole pixels per
            // batch): the accumulators are the radiance, taken without a copy.
            std::mem::swap(&mut ws.radiance, &mut ws.sinks.acc);
            ws.sinks.acc.clear();
        } else {
            ws.radiance.append(&mut ws.sinks.acc);
        }
        ws.sinks.slot_pixel.clear();
        ws.camera.clear();
        let done = (ws.radiance.len() / rays_per_pixel).min(ws.unresolved.len());
        let offsets = if keep_offsets {
            &ws.offsets[..done * eye]
        } else {
            &[]
        };
        resolve_pixels(
            &plan,
            offsets,
            &ws.radiance[..done * rays_per_pixel],
            &ws.unresolved[..done],
            &mut nonfinite_samples,
            out,
        );
        ws.unresolved.drain(..done);
        if keep_offsets {
            ws.offsets.drain(..done * eye);
        }
        ws.radiance.drain(..done * rays_per_pixel);
        stages.resolve += clock.lap();
    };

    // Camera rays of a chunk of pixels, built lane-parallel (`camera_packets`, the same
    // rays as `pixel_samples`), enter the camera queue in batches of at most `batch`;
    // a pixel with more rays than a batch is split across batches.
    //
    // Tried and not kept (helper fr24, 2026-11-29): a chunk of at least one block cut
    // to whole blocks (whitted_blur16: 80 pixels instead of 85), so that every chunk of
    // a whole-block tile stays in block mode (no pixel list, `whole_block_rays`);
    // with 85 every chunk after a tile's first ends inside a block and lists its
    // pixels. Images identical; whitted_blur16 1024x768, 1 thread, AVX-512, 5
    // interleaved rounds (host load ~3.2), render min/median 832.8/835.0 ->
    // 839.5/843.9 ms, task-clock 856.7/859.2 -> 863.2/867.6 ms.
    let chunk_pixels = (batch / rays_per_pixel).max(1);
    const FULL: usize = (BLOCK * BLOCK) as usize;
    let width = opts.width;
    let mut emit = |ws: &mut Workspace, stages: &mut StageTimes, clock: &mut Lap, last: bool| {
        let mut generated = std::mem::take(&mut ws.generated);
        generated.clear();
        if ws.camera.rays.is_empty() {
            // Into the camera queue's own (empty) buffer, which `append_camera` takes
            // back whole: the one the last batch's rays were read from, rather than
            // the other of two buffers taking turns.
            std::mem::swap(&mut generated, &mut ws.camera.rays);
        }
        // Whole blocks only: no pixel list.
        let block_mode = ws.pixels.is_empty();
        if block_mode {
            camera.whole_block_rays(
                opts.seed,
                &ws.blocks,
                width,
                &mut ws.staging,
                keep_offsets.then_some(&mut ws.offsets),
                &mut generated,
                &mut ws.sinks.drawn,
            );
        } else {
            camera.block_rays(
                opts.seed,
                (&ws.pixels, &[]),
                &mut ws.staging,
                &mut ws.offsets,
                &mut generated,
                &mut ws.sinks.drawn,
            );
        }
        ws.sinks.rays.camera += generated.len() as u64;
        // The rays enter the queue a run at a time (up to the batch's free room), every
        // array filled in bulk: ray `i` of the block gets the next accumulator slot,
        // path `first_path + i mod rays_per_pixel` and its pixel's index. Pushing the
        // seven arrays ray by ray was a third of the camera stage (bunny 1024x1024).
        // A block that fits whole is handed over without a copy.
        let total = generated.len();
        let mut i = 0;
        while i < total {
            let room = batch.saturating_sub(ws.camera.rays.len()).max(1);
            let end = (i + room).min(total);
            let first_slot = ws.sinks.acc.len() as u32;
            let paths = (plan.first_path(), i, rays_per_pixel);
            if i == 0 && end == total {
                ws.camera.append_camera(&mut generated, first_slot, paths);
            } else {
                ws.split.clear();
                ws.split.extend_from_slice(&generated[i..end]);
                ws.camera.append_camera(&mut ws.split, first_slot, paths);
            }
            zero_slots(&mut ws.sinks.acc, end - i);
            let (pixels, blocks) = (&ws.pixels, &ws.blocks);
            // Image index of pixel `p` of the chunk.
            let index = |p: usize| {
                if block_mode {
                    block_pixel_indices(blocks[p / FULL], width)[p % FULL]
                } else {
                    pixels[p].2
                }
            };
            if rays_per_pixel == 1 && block_mode && i == 0 && end == total {
                // The whole chunk's blocks: their pixels are made where they are read
                // (`SlotPixels`).
                ws.sinks.slot_pixel.push_blocks(&ws.blocks, width);
            } else if rays_per_pixel == 1 && block_mode {
                // A block's 16 indices at a time, into the spare capacity with one
                // length update for the whole run: a whole block written in place
                // (`block_indices`; a slice of varying length is a call to memcpy
                // per block, the 16 indices built on the stack and copied stalled on
                // the loads). Before, each block was an `extend_array` of its own,
                // the length stored and reloaded with the capacity per block: its
                // scalar stores were a third of the emit closure's perf samples
                // (bunny 4096x4096, 1 thread).
                let slot_pixel = ws.sinks.slot_pixel.listed();
                slot_pixel.reserve(end - i);
                let spare = &mut slot_pixel.spare_capacity_mut()[..end - i];
                let w = width as u64;
                let lanes = lane_offsets(w);
                let mut k = i;
                while k < end {
                    let b = k / FULL;
                    let stop = ((b + 1) * FULL).min(end);
                    let dst = &mut spare[k - i..stop - i];
                    if let Ok(dst) = <&mut [_; FULL]>::try_from(&mut *dst) {
                        block_indices(dst, blocks[b], w, &lanes);
                    } else {
                        let indices = block_pixel_indices(blocks[b], width);
                        for (d, &v) in dst.iter_mut().zip(&indices[k - b * FULL..]) {
                            d.write(v);
                        }
                    }
                    k = stop;
                }
                // SAFETY: the runs above cover `spare`, the `end - i` elements after
                // the length, without a gap (`k` goes from `i` to `end`).
                unsafe { slot_pixel.set_len(slot_pixel.len() + (end - i)) };
            } else if rays_per_pixel == 1 {
                ws.sinks
                    .slot_pixel
                    .listed()
                    .extend(pixels[i..end].iter().map(|p| p.2));
            } else {
                // Pixel by pixel, a run of its rays at a time (a division per ray
                // here was a quarter of this closure on whitted_blur16), into the
                // spare capacity with one length update for the whole run (an
                // `extend` per pixel was an out-of-line call, the length reloaded
                // after each).
                let slot_pixel = ws.sinks.slot_pixel.listed();
                slot_pixel.reserve(end - i);
                let spare = &mut slot_pixel.spare_capacity_mut()[..end - i];
                let mut k = i;
                while k < end {
                    let p = k / rays_per_pixel;
                    let stop = ((p + 1) * rays_per_pixel).min(end);
                    spare[k - i..stop - i].fill(std::mem::MaybeUninit::new(index(p)));
                    k = stop;
                }
                // SAFETY: the runs above cover `spare`, the `end - i` elements after
                // the length, without a gap (`k` goes from `i` to `end`).
                unsafe { slot_pixel.set_len(slot_pixel.len() + (end - i)) };
            }
            debug_assert_eq!(ws.sinks.slot_pixel.len(), ws.sinks.acc.len());
            i = end;
            if ws.camera.rays.len() >= batch {
                stages.camera += clock.lap();
                flush(ws, stages, clock);
            }
        }
        ws.generated = generated;
        ws.pixels.clear();
        ws.blocks.clear();
        if last {
            stages.camera += clock.lap();
            if !ws.camera.rays.is_empty() {
                flush(ws, stages, clock);
            }
        }
    };
    let tile_w = tile.x1 - tile.x0;
    // A whole block's positions in the tile: its top-left one plus these (one vector
    // addition; per lane `(dy + l / 4) tile_w + dx + l % 4` was scalar work per block).
    let tile_lanes = lane_offsets(tile_w);
    let mut clock = Lap(Instant::now());
    ws.pixels.clear();
    ws.blocks.clear();
    // A tile of whole blocks whose pixels stay below the chunk's (the bunny's 32x32
    // tiles at one ray per pixel): the loop below would add every block and emit
    // once, at the end; its blocks and positions are written in one pass instead.
    if !whole_tile_blocks(
        tile,
        chunk_pixels,
        &tile_lanes,
        &mut ws.blocks,
        &mut ws.unresolved,
    ) {
        for by in (tile.y0..tile.y1).step_by(BLOCK as usize) {
            for bx in (tile.x0..tile.x1).step_by(BLOCK as usize) {
                // A block row at a time, up to the chunk's free room, each array extended
                // in bulk (pushing pixel by pixel kept both lengths in memory: the loop
                // was as long as the rest of the camera stage, bunny 1024x1024).
                let x1 = (bx + BLOCK).min(tile.x1);
                let y1 = (by + BLOCK).min(tile.y1);
                if x1 - bx == BLOCK && y1 - by == BLOCK && chunk_pixels - chunk_len(ws) >= FULL {
                    // A whole block that fits the chunk: the block itself (and its pixels
                    // if the chunk lists them), its positions in the tile from the stack.
                    if !ws.pixels.is_empty() {
                        push_block_pixels(&[(bx, by)], width, &mut ws.pixels);
                    }
                    ws.blocks.push((bx, by));
                    let (dx, dy) = (bx - tile.x0, by - tile.y0);
                    let base = dy * tile_w + dx;
                    extend_array::<u32, FULL>(&mut ws.unresolved, |l| base + tile_lanes[l]);
                    if chunk_len(ws) >= chunk_pixels {
                        emit(ws, &mut stages, &mut clock, false);
                    }
                    continue;
                }
                // Part of a block: the chunk lists its pixels from here on.
                if ws.pixels.is_empty() && !ws.blocks.is_empty() {
                    push_block_pixels(&ws.blocks, width, &mut ws.pixels);
                }
                for y in by..y1 {
                    let row = y as u64 * opts.width as u64;
                    let tile_row = (y - tile.y0) * tile_w;
                    let mut x0 = bx;
                    while x0 < x1 {
                        let room = chunk_pixels - chunk_len(ws);
                        let x_end = x1.min(x0.saturating_add(room as u32));
                        ws.pixels
                            .extend((x0..x_end).map(|x| (x, y, row + x as u64)));
                        ws.unresolved
                            .extend((x0..x_end).map(|x| tile_row + (x - tile.x0)));
                        x0 = x_end;
                        if chunk_len(ws) >= chunk_pixels {
                            emit(ws, &mut stages, &mut clock, false);
                        }
                    }
                }
            }
        }
    }
    emit(ws, &mut stages, &mut clock, true);
    debug_assert!(ws.unresolved.is_empty() && ws.radiance.is_empty());
    TileResult {
        tile,
        rays: ws.sinks.rays,
        samples_drawn: ws.sinks.drawn,
        nonfinite_samples,
        stages,
        peak_queue_paths: peak,
    }
}

/// Appends `n` zero accumulators to `acc`: one fill of zero bytes (`memset`) and one
/// length update. `resize(len + n, Vec3::ZERO)` wrote each 12-byte `Vec3` with two
/// scalar stores, a third of the emit closure's perf samples (bunny 2048x2048, 1
/// thread); a copy of 16 at a time from a constant updated the length after each.
fn zero_slots(acc: &mut Vec<Vec3>, n: usize) {
    acc.reserve(n);
    let spare = &mut acc.spare_capacity_mut()[..n];
    // SAFETY: `spare` is `n` elements of the vector's spare capacity (`reserve`); all
    // zero bytes are a valid `Vec3` (three `f32` zeros), so after the fill the `n`
    // elements after the length are initialised and the length may cover them.
    unsafe {
        std::ptr::write_bytes(spare.as_mut_ptr(), 0, n);
        acc.set_len(acc.len() + n);
    }
}

/// Appends `N` values to `v`, value `l` being `f(l)`, written in place into its spare
/// capacity with one length update. Pushing them in a few `extend_from_slice` calls
/// reloads the vector's length after each call's stores (they may alias it), a
/// chain of store-to-load forwards; an array built on the stack and copied stalls
/// the copy's vector loads on the array's scalar stores.
#[inline(always)]
fn extend_array<T: Copy, const N: usize>(v: &mut Vec<T>, f: impl Fn(usize) -> T) {
    v.reserve(N);
    let spare = &mut v.spare_capacity_mut()[..N];
    for (l, s) in spare.iter_mut().enumerate() {
        s.write(f(l));
    }
    // SAFETY: the loop above initialised the `N` elements after the length.
    unsafe { v.set_len(v.len() + N) }
}

/// The offsets of a 4x4 block's pixels from its top-left pixel in a row-major array
/// `width` wide (the image, or a tile): lane `l` at `(l / 4) width + l % 4`. Made
/// once per tile or chunk, so that a block's sixteen positions are its top-left
/// position plus these, one vector addition.
#[inline(always)]
fn lane_offsets<T>(width: T) -> [T; 16]
where
    T: Copy + From<u32> + std::ops::Add<Output = T> + std::ops::Mul<Output = T>,
{
    std::array::from_fn(|l| T::from((l / 4) as u32) * width + T::from((l % 4) as u32))
}

/// Writes the image indices of the 4x4 block with top-left pixel `(bx, by)` into
/// `dst`, lane `l` at pixel `(bx + l % 4, by + l / 4)`: [`block_pixel_indices`] in
/// place, from the image's [`lane_offsets`] `lanes`. (Computing `(by + l / 4) w + bx +
/// l % 4` per lane compiled to sixteen scalar multiply-adds and stores, with the width
/// reloaded through the closure's capture for every block: perf annotate, bunny
/// 4096x4096, 1 thread.)
#[inline(always)]
fn block_indices(
    dst: &mut [std::mem::MaybeUninit<u64>; 16],
    (bx, by): (u32, u32),
    width: u64,
    lanes: &[u64; 16],
) {
    let base = by as u64 * width + bx as u64;
    for (d, &l) in dst.iter_mut().zip(lanes) {
        d.write(base + l);
    }
}

/// The chunk of a tile made only of whole 4x4 blocks with fewer pixels than
/// `chunk_pixels`, all at once: appends its blocks to `blocks` row by row and each
/// block's sixteen row-major positions in the tile (its top-left one plus
/// `tile_lanes`, the tile's [`lane_offsets`]) to `unresolved`, as `render_tile`'s
/// block loop does block by block, and returns true; leaves both untouched and returns
/// false for any other tile. The positions go into the spare capacity with one length
/// update: the loop stored and reloaded each array's length per block, with two checks
/// of the chunk's room (perf annotate, bunny 4096x4096, 1 thread: the loop was about a
/// tenth of the camera stage after the block indices were vectorised).
fn whole_tile_blocks(
    tile: Tile,
    chunk_pixels: usize,
    tile_lanes: &[u32; 16],
    blocks: &mut Vec<(u32, u32)>,
    unresolved: &mut Vec<u32>,
) -> bool {
    let (w, h) = (tile.x1 - tile.x0, tile.y1 - tile.y0);
    let n = w as usize * h as usize;
    if !w.is_multiple_of(BLOCK) || !h.is_multiple_of(BLOCK) || n >= chunk_pixels {
        return false;
    }
    let first = blocks.len();
    for by in (tile.y0..tile.y1).step_by(BLOCK as usize) {
        blocks.extend(
            (tile.x0..tile.x1)
                .step_by(BLOCK as usize)
                .map(|bx| (bx, by)),
        );
    }
    unresolved.reserve(n);
    let spare = &mut unresolved.spare_capacity_mut()[..n];
    // A block's sixteen positions as one vector addition and one 64-byte store. Written
    // lane by lane, the compiler vectorised the loop across blocks instead, as sixteen
    // `vpscatterqd` per four blocks (a scatter per lane, each writing four blocks 64
    // bytes apart): 60 % of `render_tile`'s own samples (perf annotate, bunny
    // 1024x1024, 1 thread, AVX-512).
    let lanes = wide::u32x16::new(*tile_lanes);
    for (dst, &(bx, by)) in spare.chunks_exact_mut(16).zip(&blocks[first..]) {
        let base = (by - tile.y0) * w + (bx - tile.x0);
        let v = (wide::u32x16::splat(base) + lanes).to_array();
        // SAFETY: `dst` is sixteen `MaybeUninit<u32>` (a chunk of 16), written whole
        // by one unaligned store of sixteen `u32`s.
        unsafe { dst.as_mut_ptr().cast::<[u32; 16]>().write_unaligned(v) };
    }
    // SAFETY: the `n / 16` blocks listed above each wrote their chunk of 16 of the
    // `n` spare elements after the length, every chunk once.
    unsafe { unresolved.set_len(unresolved.len() + n) };
    true
}

/// The clock of a tile's stage timers: each stage's time is the lap since the end of
/// the stage before, so one clock reading ends a stage and starts the next (the few
/// steps between two stages count in the later one). Before: a reading at each
/// stage's start and end, ten per bunny tile (12,288 per 1024x1024 frame with the
/// tile scheduler's two): `clock_gettime` and `Instant::now` were 0.6 % of the render
/// phase's samples (perf record -e cpu-clock, 1 thread).
struct Lap(Instant);

impl Lap {
    /// Milliseconds since the last lap (or the start); starts the next.
    #[inline]
    fn lap(&mut self) -> f64 {
        let now = Instant::now();
        let ms = now.duration_since(self.0).as_secs_f64() * 1e3;
        self.0 = now;
        ms
    }
}

/// Traces the camera rays in `ws.camera` and every wave they cause, accumulating the
/// radiance of each camera sample in `ws.sinks.acc`. Returns the most paths the queues
/// held at once.
fn run_waves(
    cx: &WaveContext,
    ws: &mut Workspace,
    stages: &mut StageTimes,
    clock: &mut Lap,
) -> u64 {
    let (accel, transmit, cutouts) = (cx.accel, cx.transmit, cx.cutouts);
    // Wave 0: camera rays.
    trace_closest(accel, cutouts, &ws.camera, &mut ws.hits, &mut ws.scratch);
    stages.trace += clock.lap();
    shade_queue(
        &cx.shader,
        cx.lanes,
        &ws.camera,
        &ws.hits,
        0,
        &mut ws.sinks,
        &mut ws.shade,
    );
    stages.shade += clock.lap();
    let mut peak = ws.live_paths(true);
    trace_shadows(accel, transmit, ws, stages, clock);

    // Later waves: the child queues, one kind at a time.
    let mut depth = 1;
    loop {
        std::mem::swap(&mut ws.current, &mut ws.sinks.next);
        if ws
            .current
            .iter()
            .filter_map(|(_, q)| q.as_ref())
            .all(|q| q.rays.is_empty())
        {
            break;
        }
        for kind in ChildKind::ALL {
            let Some(queue) = &mut ws.current[kind] else {
                continue;
            };
            if queue.rays.is_empty() {
                continue;
            }
            trace_closest(accel, cutouts, queue, &mut ws.hits, &mut ws.scratch);
            *child_stage(stages, kind).get_or_insert(0.0) += clock.lap();
            shade_queue(
                &cx.shader,
                cx.lanes,
                queue,
                &ws.hits,
                depth,
                &mut ws.sinks,
                &mut ws.shade,
            );
            stages.shade += clock.lap();
            peak = peak.max(ws.live_paths(false));
            if let Some(queue) = &mut ws.current[kind] {
                queue.clear();
            }
        }
        trace_shadows(accel, transmit, ws, stages, clock);
        depth += 1;
    }
    peak
}

/// The stage time of the queue of child rays of `kind`.
fn child_stage(stages: &mut StageTimes, kind: ChildKind) -> &mut Option<f64> {
    match kind {
        ChildKind::Reflection => &mut stages.reflection,
        ChildKind::Refraction => &mut stages.refraction,
        ChildKind::Glossy => &mut stages.glossy,
        ChildKind::Translucency => &mut stages.translucency,
    }
}

fn trace_closest(
    accel: &SceneAccel,
    cutouts: Option<&Scene>,
    queue: &RayQueue,
    hits: &mut Vec<Option<SceneHit>>,
    scratch: &mut BatchScratch,
) {
    // Every entry is written by `closest_hit_batch` (`None` first): the resize only
    // sets the length (before: `clear` then `resize`, a `None` written over every
    // entry twice per wave).
    hits.resize(queue.rays.len(), None);
    accel.closest_hit_batch(&queue.rays, hits, scratch);
    if let Some(scene) = cutouts {
        for (hit, ray) in hits.iter_mut().zip(&queue.rays) {
            if let Some(h) = *hit {
                *hit = super::texturing::solid_hit(scene, accel, ray, h).0;
            }
        }
    }
}

/// Traces the shadow queues for occlusion and adds what reaches the lights. With
/// `transmit` (transmitted shadows in a scene with glass, or cut-outs) the occlusion
/// query also says which primitive set blocks each ray, and a blocked ray adds its
/// contribution times its transmittance ([`ShadowFilter::transmittance`]: zero behind
/// an opaque set, else the filtered query from that set on), as the recursive
/// integrator does.
fn trace_shadows(
    accel: &SceneAccel,
    transmit: Option<(&Scene, &ShadowFilter)>,
    ws: &mut Workspace,
    stages: &mut StageTimes,
    clock: &mut Lap,
) {
    let sinks = &mut ws.sinks;
    let acc = &mut sinks.acc;
    for (q, &area) in sinks.shadow.iter_mut().zip(&sinks.area) {
        let stage = if area {
            &mut stages.area_shadow
        } else {
            &mut stages.shadow
        };
        if q.rays.is_empty() {
            continue;
        }
        if let Some(pass) = transmit.and_then(|(_, filter)| filter.tiny_pass(accel)) {
            // Tiny scene: occlusion and glass in one pass of lanes (`tiny_shadow`).
            let transmitted = &mut ws.transmitted;
            pass.transmittance_batch(&q.rays, transmitted, ws.scratch.tiny(), &mut sinks.rays);
            for ((&t, &slot), &c) in transmitted.iter().zip(&q.slot).zip(&q.contribution) {
                if t != Vec3::ZERO {
                    acc[slot as usize] += c * t;
                }
            }
        } else if let Some((scene, filter)) = transmit {
            let occluders = &mut ws.occluders;
            occluders.clear();
            occluders.resize(q.rays.len(), None);
            accel.occluders_batch(&q.rays, occluders, &mut ws.occluded, &mut ws.scratch);
            filter.transmittance_batch(
                scene,
                accel,
                &q.rays,
                occluders,
                &mut ws.transmitted,
                &mut ws.shadow_scratch,
                &mut sinks.rays,
            );
            for ((&t, &slot), &c) in ws.transmitted.iter().zip(&q.slot).zip(&q.contribution) {
                // An unblocked ray's factor is exactly one, and `c * 1` is `c`.
                if t != Vec3::ZERO {
                    acc[slot as usize] += c * t;
                }
            }
        } else {
            let occluded = &mut ws.occluded;
            occluded.clear();
            occluded.resize(q.rays.len(), false);
            accel.any_hit_batch(&q.rays, occluded, &mut ws.scratch);
            for ((&blocked, &slot), &c) in occluded.iter().zip(&q.slot).zip(&q.contribution) {
                if !blocked {
                    acc[slot as usize] += c;
                }
            }
        }
        q.clear();
        *stage.get_or_insert(0.0) += clock.lap();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `block_indices` writes exactly `block_pixel_indices` (the image indices the
    /// pixel lists carry), for blocks at the image's corners and inside, in images of
    /// several widths, up to one past 2^32 pixels (indices beyond `u32`).
    #[test]
    fn block_indices_are_block_pixel_indices() {
        for width in [4, 36, 1024, 70_001] {
            for (bx, by) in [(0, 0), (width - 4, 0), (8, 12), (width - 4, 70_000)] {
                let mut got = [std::mem::MaybeUninit::new(u64::MAX); 16];
                block_indices(
                    &mut got,
                    (bx, by),
                    width as u64,
                    &lane_offsets(width as u64),
                );
                // SAFETY: every element was initialised (the sentinel, then the write).
                let got = got.map(|g| unsafe { g.assume_init() });
                assert_eq!(
                    got,
                    block_pixel_indices((bx, by), width),
                    "{width} ({bx}, {by})"
                );
            }
        }
    }

    /// A block's positions from `lane_offsets` (top-left position plus the offsets)
    /// are the per-lane formula's, `(y + l / 4) width + x + l % 4`, in a tile's `u32`
    /// positions and an image's `u64` indices, for the widths of tiles and images.
    #[test]
    fn lane_offsets_give_each_lanes_position() {
        for width in [1u32, 4, 13, 16, 1024, 70_001] {
            let (l32, l64) = (lane_offsets(width), lane_offsets(width as u64));
            for (x, y) in [(0u32, 0u32), (4, 8), (width.saturating_sub(4), 60_000)] {
                for l in 0..16 {
                    let (r, c) = ((l / 4) as u32, (l % 4) as u32);
                    if width < 20_000 && y < 20_000 {
                        assert_eq!(y * width + x + l32[l], (y + r) * width + x + c);
                    }
                    let (w, x, y) = (width as u64, x as u64, y as u64);
                    assert_eq!(y * w + x + l64[l], (y + r as u64) * w + x + c as u64);
                }
            }
        }
    }

    /// `whole_tile_blocks` lists a whole-block tile's blocks row by row and each
    /// block's positions by the per-lane formula `(by - y0 + l / 4) w + bx - x0 + l %
    /// 4`, after what the arrays held; it takes no tile with a part block or with as
    /// many pixels as the chunk, and leaves the arrays as they were then.
    #[test]
    fn whole_tile_blocks_are_the_loops_blocks() {
        let tile = |x0, y0, x1, y1| Tile { x0, y0, x1, y1 };
        for (t, chunk, whole) in [
            (tile(32, 16, 48, 32), 1638, true),
            (tile(0, 0, 8, 12), 97, true),
            (tile(1008, 496, 1024, 512), 256, false),
            (tile(1008, 496, 1024, 512), 257, true),
            (tile(0, 0, 16, 14), 1638, false),
            (tile(0, 0, 13, 16), 1638, false),
        ] {
            let w = t.x1 - t.x0;
            let (mut blocks, mut unresolved) = (vec![(7, 7)], vec![9]);
            let got = whole_tile_blocks(t, chunk, &lane_offsets(w), &mut blocks, &mut unresolved);
            assert_eq!(got, whole, "{t:?}");
            let (mut want_b, mut want_u) = (vec![(7, 7)], vec![9]);
            if whole {
                for by in (t.y0..t.y1).step_by(4) {
                    for bx in (t.x0..t.x1).step_by(4) {
                        want_b.push((bx, by));
                        want_u.extend((0..16).map(|l| (by - t.y0 + l / 4) * w + bx - t.x0 + l % 4));
                    }
                }
            }
            assert_eq!(blocks, want_b, "{t:?}");
            assert_eq!(unresolved, want_u, "{t:?}");
        }
    }

    /// `zero_slots` appends exactly `n` zero accumulators after the ones already there
    /// (whole runs of 16, a rest, both, none), leaving those untouched.
    #[test]
    fn zero_slots_appends_n_zeros() {
        let kept = Vec3::new(1.0, -2.0, 3.5);
        for n in [0, 1, 15, 16, 17, 32, 40] {
            let mut acc = vec![kept; 3];
            zero_slots(&mut acc, n);
            assert_eq!(acc.len(), 3 + n, "n {n}");
            assert!(acc[..3].iter().all(|&v| v == kept));
            assert!(acc[3..].iter().all(|&v| v == Vec3::ZERO), "n {n}");
        }
    }
}
