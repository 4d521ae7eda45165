//! Recursive Whitted-style ray tracer (scalar reference), extended to distribution ray
//! tracing.
//!
//! Whitted, "An Improved Illumination Model for Shaded Display" (CACM 1980): at each
//! hit, direct light from point and directional lights through one shadow ray each,
//! plus perfect mirror reflection and dielectric refraction traced recursively. This is
//! the reference the wavefront integrator is checked against, so it favours clarity
//! and exactness over speed, but it still never allocates per ray.
//!
//! Cook, Porter, Carpenter, "Distributed Ray Tracing" (SIGGRAPH 1984): the same tree
//! with rays distributed over the quantities it integrates: pixel area (any
//! [`SamplerKind`](super::SamplerKind) and [`FilterKind`](super::FilterKind)), lens
//! area (depth of field), shutter time (motion blur), area-light surface (soft
//! shadows) and the glossy and translucent lobes. Each effect takes its own sample
//! count ([`SampleCounts`](crate::scene::SampleCounts)); a scene without an effect draws
//! no sample for it, so it traces exactly the rays of the plain Whitted renderer.
//!
//! Determinism: the camera samples of a pixel (positions, lens points, shutter times)
//! come from the pixel's own random stream, seeded from `(seed, pixel index)`; every
//! shading point then draws its light points and lobe directions from a stream keyed by
//! its *path identity* ([`path_rng`](super::path_keys::path_rng): the camera sample's index in its pixel, extended
//! by the branch index at each scattering event). A shading point's random numbers
//! therefore do not depend on the order in which the ray tree is visited, which is what
//! lets the breadth-first [`wavefront`](super::wavefront) integrator draw exactly the
//! samples this depth-first one draws. Tiles are reassembled in a fixed order, so an
//! image is bit-identical whatever the number of threads and whatever order tiles run.
//!
//! This file holds the recursion only. The stages it shares with the wavefront
//! integrator live in their own files: camera rays ([`super::camera_rays`]), surface
//! interactions ([`super::interaction`]), the local shading (`Shader::shade_emit` in
//! [`super::shader`]: emission, ambient, the direct-light reflectance with the shadow
//! rays it needs, and the mirror, glossy and glass child rays with their weights and
//! the contribution cutoff), the pixel filter ([`super::pixel_filter`]) and the tile
//! scheduler ([`super::tiles`]). This renderer traces the rays the shader emits at
//! once; the wavefront queues them.

use super::camera_rays::{CameraSampler, PixelSamples, SamplePlan};
use super::interaction::SurfaceInteraction;
use super::pixel_filter::{TileOut, resolve_pixel};
use super::shader::{Emitted, Shader};
use super::shadow::ShadowFilter;
use super::tiles::{Tile, TileResult, render_tiles};
use super::{RenderOptions, RenderOutput, texturing};
use crate::accel::SceneAccel;
use crate::film::{Film, PixelSums};
use crate::geometry::Ray;
use crate::scene::Scene;
use crate::stats::{EffectSamplesDrawn, RayCounts, StageTimes};
use glam::Vec3;
use rayon::prelude::*;

/// Renders `scene` with the structure `accel`. `opts` must pass
/// [`RenderOptions::validate`]; parallelism is whatever rayon pool the caller runs in.
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
    let filter = ShadowFilter::new(scene, opts.transmitted_shadows, accel.kind);
    let mut out = render_tiles(
        scene,
        opts,
        film,
        Workspace::default,
        |ws, camera, tile, out| {
            render_tile(scene, accel, opts, filter.as_ref(), camera, ws, (tile, out))
        },
    );
    out.stages_ms = None;
    out
}

/// The recursive integrator: traces the rays [`Shader::shade_emit`] emits at once,
/// depth first, with the counters of the tile it works for.
struct Tracer<'a> {
    shader: Shader<'a>,
    accel: &'a SceneAccel,
    /// Shadow rays blocked by glass (or a cut-out) are traced again for its
    /// transmission (`shadow` module); `None` when the render has neither.
    filter: Option<&'a ShadowFilter>,
    /// The scene has cut-out materials: camera and child rays skip their holes
    /// (`texturing`).
    cutouts: bool,
    rays: RayCounts,
    drawn: EffectSamplesDrawn,
    /// What each depth of the current path emitted, reused so that shading never
    /// allocates per ray.
    emitted: Vec<Emitted>,
}

/// Per-worker scratch of the recursive integrator.
#[derive(Default)]
pub(crate) struct Workspace {
    samples: PixelSamples,
    radiance: Vec<Vec3>,
    emitted: Vec<Emitted>,
}

fn render_tile(
    scene: &Scene,
    accel: &SceneAccel,
    opts: &RenderOptions,
    filter: Option<&ShadowFilter>,
    camera: &CameraSampler,
    ws: &mut Workspace,
    (tile, out): (Tile, &mut TileOut),
) -> TileResult {
    let mut tracer = Tracer::new(scene, accel, opts, filter, camera.plan, ws);
    let mut nonfinite_samples = 0;
    let mut i = 0;
    for y in tile.y0..tile.y1 {
        for x in tile.x0..tile.x1 {
            let index = y as u64 * opts.width as u64 + x as u64;
            let sums = tracer.pixel(camera, opts.seed, index, (x, y), ws, &mut nonfinite_samples);
            out.values[i] = sums.value();
            if let Some(kept) = &mut out.sums {
                kept[i] = sums;
            }
            i += 1;
        }
    }
    ws.emitted = tracer.emitted;
    TileResult {
        tile,
        rays: tracer.rays,
        samples_drawn: tracer.drawn,
        nonfinite_samples,
        stages: StageTimes::default(),
        peak_queue_paths: 0,
    }
}

/// Renders eye samples `range` of each listed pixel (`(x, y, range)`, image
/// coordinates) with the recursive integrator, in parallel over chunks of the list,
/// each pixel exactly as a render of that `--sample-range` would: the sums of a pixel
/// do not depend on the chunking or the thread count. `opts.spp` bounds the ranges
/// (the sample patterns are planned for `opts.spp` eye samples). For the progressive
/// renderer ([`super::adaptive`]), whose pixels each get their own count. Each
/// pixel's sums are handed to `keep` (so that a caller can store less than the exact
/// sums, which are 600 bytes a pixel). Also returns the rays each pixel traced (its
/// cost).
pub(crate) fn render_pixels<T: Send>(
    scene: &Scene,
    accel: &SceneAccel,
    opts: &RenderOptions,
    pixels: &[(u32, u32, std::ops::Range<u32>)],
    keep: impl Fn(&PixelSums) -> T + Sync,
) -> (Vec<T>, Vec<u64>, RayCounts) {
    let camera = CameraSampler::new(scene, opts);
    let filter = ShadowFilter::new(scene, opts.transmitted_shadows, accel.kind);
    type Chunk<T> = (Vec<T>, Vec<u64>, RayCounts);
    let chunks: Vec<Chunk<T>> = pixels
        .par_chunks(64)
        .map_init(Workspace::default, |ws, chunk| {
            let mut tracer = Tracer::new(scene, accel, opts, filter.as_ref(), camera.plan, ws);
            let mut sums = Vec::with_capacity(chunk.len());
            let mut cost = Vec::with_capacity(chunk.len());
            let mut nonfinite = 0;
            for (x, y, range) in chunk {
                let before = tracer.rays.total();
                let mut cam = camera;
                cam.plan.eye_begin = range.start;
                cam.plan.eye_end = range.end;
                let index = *y as u64 * opts.width as u64 + *x as u64;
                let pixel = tracer.pixel(&cam, opts.seed, index, (*x, *y), ws, &mut nonfinite);
                sums.push(keep(&pixel));
                cost.push(tracer.rays.total() - before);
            }
            ws.emitted = std::mem::take(&mut tracer.emitted);
            (sums, cost, tracer.rays)
        })
        .collect();
    let mut rays = RayCounts::default();
    let mut sums = Vec::with_capacity(pixels.len());
    let mut costs = Vec::with_capacity(pixels.len());
    for (s, c, r) in chunks {
        sums.extend(s);
        costs.extend(c);
        rays += r;
    }
    (sums, costs, rays)
}

impl Tracer<'_> {
    /// A tracer for one worker, borrowing the worker's reusable emission buffers.
    fn new<'a>(
        scene: &'a Scene,
        accel: &'a SceneAccel,
        opts: &RenderOptions,
        filter: Option<&'a ShadowFilter>,
        plan: SamplePlan,
        ws: &mut Workspace,
    ) -> Tracer<'a> {
        Tracer {
            shader: Shader::new(scene, opts, plan),
            accel,
            filter,
            cutouts: texturing::has_cutouts(scene),
            rays: RayCounts::default(),
            drawn: EffectSamplesDrawn::default(),
            emitted: std::mem::take(&mut ws.emitted),
        }
    }

    /// The filter sums of pixel `(x, y)` (`index` in the image): its camera rays from
    /// `camera`, each traced depth first, filtered by [`resolve_pixel`].
    fn pixel(
        &mut self,
        camera: &CameraSampler,
        seed: u64,
        index: u64,
        (x, y): (u32, u32),
        ws: &mut Workspace,
        nonfinite: &mut u64,
    ) -> PixelSums {
        let samples = &mut ws.samples;
        camera.pixel_samples(seed, index, x, y, samples, &mut self.drawn);
        self.rays.camera += samples.rays.len() as u64;
        ws.radiance.clear();
        for (s, ray) in samples.rays.iter().enumerate() {
            let path = camera.plan.first_path() + s as u64;
            let l = self.radiance(ray, 0, Vec3::ONE, index, path);
            ws.radiance.push(l);
        }
        resolve_pixel(&camera.plan, &samples.offsets, &ws.radiance, nonfinite)
    }

    /// Radiance arriving along `ray` by path `path` of pixel `pixel`. `throughput` is
    /// the product of the weights from the camera to this ray, for the contribution
    /// cutoff.
    fn radiance(&mut self, ray: &Ray, depth: u32, throughput: Vec3, pixel: u64, path: u64) -> Vec3 {
        let Some(mut hit) = self.accel.closest_hit(ray) else {
            return self.shader.scene.miss_radiance(ray.dir);
        };
        if self.cutouts {
            // A hit in a cut-out's hole: the nearest solid one behind it.
            match texturing::solid_hit(self.shader.scene, self.accel, ray, hit).0 {
                Some(h) => hit = h,
                None => return self.shader.scene.miss_radiance(ray.dir),
            }
        }
        let si = SurfaceInteraction::new(self.shader.scene, ray, &hit);
        let d = depth as usize;
        if self.emitted.len() <= d {
            self.emitted.resize_with(d + 1, Emitted::default);
        }
        let mut out = std::mem::take(&mut self.emitted[d]);
        self.shader.shade_emit(
            ray.dir.normalize(),
            ray.time,
            &si,
            depth,
            throughput,
            pixel,
            path,
            &mut out,
            &mut self.rays,
            &mut self.drawn,
        );
        let mut l = out.local;
        for s in &out.shadow {
            let Some(filter) = self.filter else {
                if !self.accel.any_hit(&s.ray) {
                    l += s.contribution;
                }
                continue;
            };
            // Blocked, but perhaps only by glass (`shadow` module).
            match self.accel.occluder(&s.ray) {
                None => l += s.contribution,
                Some(first) => {
                    let scene = self.shader.scene;
                    let t = filter.transmittance(scene, self.accel, &s.ray, first, &mut self.rays);
                    if t != Vec3::ZERO {
                        l += s.contribution * t;
                    }
                }
            }
        }
        for c in &out.children {
            l += c.weight * self.radiance(&c.ray, depth + 1, c.throughput, pixel, c.path);
        }
        self.emitted[d] = out;
        l
    }
}
