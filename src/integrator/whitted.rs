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
//! its *path identity* ([`path_rng`]: the camera sample's index in its pixel, extended
//! by the branch index at each scattering event). A shading point's random numbers
//! therefore do not depend on the order in which the ray tree is visited, which is what
//! lets the breadth-first [`wavefront`](super::wavefront) integrator draw exactly the
//! samples this depth-first one draws. Tiles are reassembled in a fixed order, so an
//! image is bit-identical whatever the number of threads and whatever order tiles run.
//!
//! The local shading ([`Shader::shade_emit`]: emission, ambient, the direct-light
//! reflectance with the shadow rays it needs, and the mirror, glossy and glass child
//! rays with their weights and the contribution cutoff) is shared with the wavefront
//! integrator: this renderer traces the emitted rays at once, the wavefront queues them.

use super::sampling::{
    Dimension, PixelRng, decorrelate, fill_1d, fill_2d, sample_aperture, sample_phong_lobe,
};
use super::sobol::{SobolDim, SobolSet};
use super::{FilterKind, RenderOptions, RenderOutput, SamplerKind, shadow};
use crate::accel::{PrimRef, SceneAccel, SceneHit};
use crate::film::{Film, PixelSums, partial};
use crate::geometry::terminator::shadow_terminator_point;
use crate::geometry::{Ray, offset_ray_origin, spawn_ray_to, sphere_point, triangle_point};
use crate::scene::{CameraFrame, LensFrame, Light, Scene, TriangleMesh};
use crate::stats::{EffectSamplesDrawn, RayCounts, StageTimes, ms_since};
use glam::Vec3;
use rayon::prelude::*;
use std::f32::consts::FRAC_1_PI;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

/// Renders `scene` with the structure `accel`. `opts` must pass
/// [`RenderOptions::validate`]; parallelism is whatever rayon pool the caller runs in.
pub fn render(scene: &Scene, accel: &SceneAccel, opts: &RenderOptions) -> RenderOutput {
    let mut out = render_tiles(scene, opts, Workspace::default, |ws, camera, tile| {
        render_tile(scene, accel, opts, camera, ws, tile)
    });
    out.stages_ms = None;
    out
}

/// Splits the image region (the whole image, or `opts.crop`) into tiles, renders them
/// in parallel with `tile_fn` (each rayon worker reuses one scratch value made by
/// `init`) and reassembles them in a fixed order. Each pixel's filter sums are
/// resolved into its value as its tile finishes, and, with `opts.keep_sums`, also
/// encoded for a partial image ([`crate::film::partial`]). Shared by both integrators.
pub(crate) fn render_tiles<W>(
    scene: &Scene,
    opts: &RenderOptions,
    init: impl Fn() -> W + Sync + Send,
    tile_fn: impl Fn(&mut W, &CameraSampler, Tile) -> TileResult + Sync + Send,
) -> RenderOutput {
    let start = Instant::now();
    let (width, height) = (opts.width, opts.height);
    let camera = CameraSampler {
        frame: scene.camera_frame(width, height),
        lens: LensFrame::new(&scene.camera, &scene.camera_effects),
        plan: SamplePlan::new(scene, opts),
    };

    let region = opts.region();
    let tiles_x = region.width().div_ceil(TILE);
    let tiles_y = region.height().div_ceil(TILE);
    let total = tiles_x as u64 * tiles_y as u64;
    let done = AtomicU64::new(0);
    let tiles: Vec<(TileResult, Vec<Vec3>, Vec<u8>)> = (0..total)
        .into_par_iter()
        .map_init(&init, |ws, i| {
            let (tx, ty) = ((i % tiles_x as u64) as u32, (i / tiles_x as u64) as u32);
            let tile = Tile {
                x0: region.x0 + tx * TILE,
                y0: region.y0 + ty * TILE,
                x1: (region.x0 + (tx + 1) * TILE).min(region.x1),
                y1: (region.y0 + (ty + 1) * TILE).min(region.y1),
            };
            let mut result = tile_fn(ws, &camera, tile);
            let values = result.pixels.iter().map(PixelSums::value).collect();
            let mut encoded = Vec::new();
            if opts.keep_sums {
                for p in &result.pixels {
                    partial::encode_pixel(p, &mut encoded);
                }
            }
            result.pixels = Vec::new();
            if let Some(progress) = &opts.progress {
                progress(done.fetch_add(1, Ordering::Relaxed) + 1, total);
            }
            (result, values, encoded)
        })
        .collect();

    // Encoded sums, row-major over the region: row by row through each row of tiles.
    let sums = opts.keep_sums.then(|| {
        let mut bytes = Vec::new();
        for row in tiles.chunks(tiles_x as usize) {
            let mut rest: Vec<&[u8]> = row.iter().map(|t| &t.2[..]).collect();
            for _ in row[0].0.tile.y0..row[0].0.tile.y1 {
                for (t, r) in row.iter().zip(&mut rest) {
                    let n = (t.0.tile.x1 - t.0.tile.x0) as usize;
                    let len = partial::encoded_len(r, n);
                    bytes.extend_from_slice(&r[..len]);
                    *r = &r[len..];
                }
            }
        }
        bytes
    });

    let mut film = Film::new(region.width(), region.height());
    let mut rays = RayCounts::default();
    let mut samples_drawn = EffectSamplesDrawn::default();
    let mut stages = StageTimes::default();
    let mut nonfinite_samples = 0;
    for (t, values, _) in tiles {
        let mut values = values.into_iter();
        for y in t.tile.y0..t.tile.y1 {
            for x in t.tile.x0..t.tile.x1 {
                let v = values.next().expect("tile holds all its pixels");
                film.set(x - region.x0, y - region.y0, v);
            }
        }
        rays += t.rays;
        samples_drawn += t.samples_drawn;
        stages += t.stages;
        nonfinite_samples += t.nonfinite_samples;
    }
    RenderOutput {
        film,
        rays,
        render_ms: ms_since(start),
        nonfinite_samples,
        samples_drawn,
        stages_ms: Some(stages),
        region,
        sums,
    }
}

/// The sample counts a render actually uses: a count for an effect the scene lacks is
/// 1 and draws nothing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SamplePlan {
    pub eye: u32,
    /// Lens samples per eye sample; 0 when the scene has no depth of field.
    pub lens: u32,
    /// Shutter times per lens sample; 0 when nothing moves.
    pub time: u32,
    pub shadow: u32,
    pub glossy: u32,
    pub sampler: SamplerKind,
    pub filter: FilterKind,
    /// The eye samples rendered, `eye_begin..eye_end` of `0..eye` (all of them unless
    /// `--sample-range` picks a round). The pattern is always drawn for all `eye`.
    pub eye_begin: u32,
    pub eye_end: u32,
}

impl SamplePlan {
    pub fn new(scene: &Scene, opts: &RenderOptions) -> Self {
        let f = &scene.features;
        SamplePlan {
            eye: opts.spp.max(1),
            lens: if f.depth_of_field {
                opts.samples.lens
            } else {
                0
            },
            time: if f.motion { opts.samples.time } else { 0 },
            shadow: opts.samples.shadow,
            glossy: opts.samples.glossy,
            sampler: opts.sampler,
            filter: opts.filter,
            eye_begin: opts.sample_range.as_ref().map_or(0, |r| r.start),
            eye_end: opts
                .sample_range
                .as_ref()
                .map_or(opts.spp.max(1), |r| r.end),
        }
    }

    /// Eye samples rendered per pixel (`eye_end - eye_begin`).
    pub fn eye_rendered(&self) -> u32 {
        self.eye_end - self.eye_begin
    }

    /// Path identity of the first camera ray rendered: camera rays are numbered over
    /// all `eye` samples of the pixel, so a round's rays keep the numbers (and the
    /// random streams) they have in a render of all samples.
    pub fn first_path(&self) -> u64 {
        self.eye_begin as u64 * (self.lens.max(1) * self.time.max(1)) as u64
    }

    /// Camera rays per pixel: `eye * lens * time` (absent effects count 1).
    pub fn camera_rays_per_pixel(&self) -> u32 {
        self.eye * self.lens.max(1) * self.time.max(1)
    }
}

/// Everything that turns sample positions into camera rays.
#[derive(Clone, Copy)]
pub(crate) struct CameraSampler {
    pub frame: CameraFrame,
    pub lens: LensFrame,
    pub plan: SamplePlan,
}

/// The camera samples of one pixel: the pixel offsets of the eye samples rendered
/// (`eye_begin..eye_end`), and for each of them `rays_per_eye` rays (lens points times
/// shutter times), eye sample major.
#[derive(Default)]
pub(crate) struct PixelSamples {
    /// Offset of each eye sample inside the pixel (or the filter footprint).
    pub offsets: Vec<(f32, f32)>,
    pub rays: Vec<Ray>,
    pixel_pos: Vec<(f32, f32)>,
    lens_pos: Vec<(f32, f32)>,
    times: Vec<f32>,
}

impl CameraSampler {
    /// Camera rays per eye sample: `lens * time` (absent effects count 1).
    pub fn rays_per_eye(&self) -> u32 {
        self.plan.lens.max(1) * self.plan.time.max(1)
    }

    /// The camera rays of pixel `(x, y)` (`index` in the image), drawn from the pixel's
    /// own stream. Draw order is fixed: pixel positions, lens points, shutter times. A
    /// scene with no lens and no motion draws the pixel positions only, exactly as the
    /// plain Whitted renderer did.
    pub fn pixel_samples(
        &self,
        seed: u64,
        index: u64,
        x: u32,
        y: u32,
        out: &mut PixelSamples,
        drawn: &mut EffectSamplesDrawn,
    ) {
        let plan = self.plan;
        let (lens_n, time_n) = (plan.lens.max(1), plan.time.max(1));
        // The Sobol sampler computes each point from its index (only the rendered
        // ones); the others draw every set of the pixel, in a fixed order.
        let sobol = (plan.sampler == SamplerKind::Sobol).then(|| {
            [SobolDim::Pixel, SobolDim::Lens, SobolDim::Time].map(|d| SobolSet::new(seed, index, d))
        });
        if sobol.is_some() {
            let rendered = (plan.eye_end - plan.eye_begin) as u64;
            if plan.lens > 0 {
                drawn.lens += rendered * lens_n as u64;
            }
            if plan.time > 0 {
                drawn.time += rendered * (lens_n * time_n) as u64;
            }
        } else {
            self.draw_sets(seed, index, out, drawn);
        }
        // Box: samples inside the pixel; otherwise over the filter's footprint.
        let footprint = 2.0 * plan.filter.radius();
        out.offsets.clear();
        out.rays.clear();
        for e in plan.eye_begin as usize..plan.eye_end as usize {
            let (sx, sy) = match &sobol {
                Some(sets) => sets[0].point(e as u32),
                None => out.pixel_pos[e],
            };
            let (ox, oy) = if plan.filter == FilterKind::Box {
                (sx, sy)
            } else {
                (0.5 + (sx - 0.5) * footprint, 0.5 + (sy - 0.5) * footprint)
            };
            out.offsets.push((ox, oy));
            let pinhole = self.frame.ray(x as f32 + ox, y as f32 + oy);
            for l in 0..lens_n {
                let lens_index = e * lens_n as usize + l as usize;
                let lens_point = (plan.lens > 0).then(|| {
                    let (u, v) = match &sobol {
                        Some(sets) => sets[1].point(lens_index as u32),
                        None => out.lens_pos[lens_index],
                    };
                    sample_aperture(u, v, self.lens.blades, self.lens.rotation)
                });
                for t in 0..time_n {
                    let time = if plan.time > 0 {
                        let k = lens_index * time_n as usize + t as usize;
                        self.lens.time(match &sobol {
                            Some(sets) => sets[2].value(k as u32),
                            None => out.times[k],
                        })
                    } else {
                        self.lens.shutter[0]
                    };
                    out.rays
                        .push(self.lens.ray(&self.frame, pinhole, lens_point, time));
                }
            }
        }
    }

    /// Draws every camera set of the pixel (all `eye` samples) from the pixel's own
    /// stream, for the patterns that are drawn as whole sets. Draw order is fixed:
    /// pixel positions, lens points, shutter times.
    fn draw_sets(
        &self,
        seed: u64,
        index: u64,
        out: &mut PixelSamples,
        drawn: &mut EffectSamplesDrawn,
    ) {
        let plan = self.plan;
        let (lens_n, time_n) = (plan.lens.max(1), plan.time.max(1));
        let rng = &mut PixelRng::new(seed, index);
        fill_2d(
            plan.sampler,
            plan.eye,
            Dimension::Pixel,
            true,
            rng,
            &mut out.pixel_pos,
        );
        if plan.lens > 0 {
            let n = plan.eye * lens_n;
            fill_2d(
                plan.sampler,
                n,
                Dimension::Lens,
                false,
                rng,
                &mut out.lens_pos,
            );
            decorrelate(plan.sampler, &mut out.lens_pos, rng);
            drawn.lens += n as u64;
        }
        if plan.time > 0 {
            let n = plan.eye * lens_n * time_n;
            fill_1d(plan.sampler, n, Dimension::Time, rng, &mut out.times);
            decorrelate(plan.sampler, &mut out.times, rng);
            drawn.time += n as u64;
        }
    }
}

/// Filters the radiance of a pixel's camera rays (`radiance[i]` for `rays[i]` of
/// [`PixelSamples`]) into the pixel's filter sums ([`PixelSums::value`] is the pixel
/// value). A ray whose radiance is NaN or infinite is dropped and counted in
/// `nonfinite`; so is an eye sample whose mean overflows.
///
/// The sums are exact ([`ExactSum`](crate::film::exact_sum::ExactSum)), so they do not
/// depend on the order or grouping of the samples: rounds of samples rendered apart
/// and merged give the bits of one render of all of them.
pub(crate) fn resolve_pixel(
    plan: &SamplePlan,
    offsets: &[(f32, f32)],
    radiance: &[Vec3],
    nonfinite: &mut u64,
) -> PixelSums {
    let per_eye = (plan.lens.max(1) * plan.time.max(1)) as usize;
    let mut sums = PixelSums::default();
    for (e, &(ox, oy)) in offsets.iter().enumerate() {
        let mut radiance_sum = Vec3::ZERO;
        for &r in &radiance[e * per_eye..(e + 1) * per_eye] {
            if r.is_finite() {
                radiance_sum += r;
            } else {
                *nonfinite += 1;
            }
        }
        let radiance = if per_eye == 1 {
            radiance_sum
        } else {
            radiance_sum / per_eye as f32
        };
        let w = plan.filter.weight(ox - 0.5, oy - 0.5);
        if !(w * radiance).is_finite() {
            *nonfinite += 1;
            continue;
        }
        sums.add_sample(w, radiance);
    }
    sums
}

/// What the shader needs to know about a hit.
///
/// Both normals are unit length and face the side the incident ray came from, so
/// shading never has to ask which way a triangle was wound; `front_face` keeps the
/// lost information (the ray hit the outside: triangle winding or sphere exterior),
/// which is what tells a dielectric whether the ray enters or leaves.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceInteraction {
    pub p: Vec3,
    /// Per-component bound on the distance of `p` from the true surface (the box
    /// `p ± p_error` contains a surface point): what every secondary ray origin is
    /// offset by ([`offset_ray_origin`], [`spawn_ray_to`]).
    pub p_error: Vec3,
    pub n_geometric: Vec3,
    pub n_shading: Vec3,
    pub material: u32,
    pub front_face: bool,
    /// On a triangle with vertex normals, the base point of its shadow rays: `p`
    /// lifted onto the smooth surface the normals describe ([`shadow_terminator_point`],
    /// Hanika 2021), so that a coarse mesh shaded smooth neither shadows itself in
    /// facets near the terminator nor drops lights that are above the shading normal's
    /// horizon but below the flat facet. `None` elsewhere (shadow rays leave from `p`,
    /// and a light below the geometric surface contributes nothing).
    pub p_shadow: Option<Vec3>,
}

impl SurfaceInteraction {
    /// The hit point is rebuilt from the primitive, not as `o + t d`: `t` carries the
    /// rounding error of the whole intersection test scaled by the ray length, whereas
    /// barycentric interpolation of the corners ([`triangle_point`]) or reprojection
    /// onto a sphere ([`sphere_point`]) lands within a bound of the surface that is
    /// computed with the point and kept in `p_error` (pbrt-v4's `Point3fi`).
    ///
    /// Moving primitives are placed at the ray's time exactly as the intersection
    /// kernels place them (`v + time * velocity`, the same f32 operations), and a ray
    /// spawned here keeps that time, so the error is relative to the placed corners
    /// (or centre): placing them adds nothing the next ray does not see identically.
    pub fn new(scene: &Scene, ray: &Ray, hit: &SceneHit) -> Self {
        // Translation leaves normals unchanged, so both kinds of triangle (and of
        // sphere) share one rule. The last element: corners and vertex normals, for the
        // shadow-ray base point.
        let on_triangle = |mesh: &TriangleMesh, t: usize, corners: [Vec3; 3]| {
            let (p, p_error) = triangle_point(corners, hit.u, hit.v);
            let (ng, ns) = (
                mesh.geometric_normal(t),
                mesh.shading_normal(t, hit.u, hit.v),
            );
            let smooth = mesh.vertex_normals(t).map(|n| (corners, n));
            (p, p_error, ng, ns, mesh.material[t], smooth)
        };
        let on_sphere = |center: Vec3, radius: f32, material: u32| {
            let (p, p_error, n) = sphere_point(center, radius, ray.at(hit.t));
            (p, p_error, n, n, material, None)
        };
        let (motion, spheres) = (&scene.motion, &scene.spheres);
        let (p, p_error, ng, ns, material, smooth) = match hit.prim {
            PrimRef::Triangle(t) => {
                on_triangle(&scene.mesh, t as usize, scene.mesh.corners(t as usize))
            }
            PrimRef::Sphere(s) => {
                let s = s as usize;
                on_sphere(spheres.center(s), spheres.radius[s], spheres.material[s])
            }
            PrimRef::MovingTriangle(t) => {
                let t = t as usize;
                on_triangle(&motion.mesh, t, motion.triangle_corners(t, ray.time))
            }
            PrimRef::MovingSphere(s) => {
                let s = s as usize;
                let center = motion.sphere_center(s, ray.time);
                on_sphere(center, motion.spheres.radius[s], motion.spheres.material[s])
            }
            // Instances and infinite planes: world-space surface with its error bound.
            PrimRef::Instance { instance, prim } => scene
                .instances
                .surface(instance, prim, hit.u, hit.v)
                .parts(),
            PrimRef::Plane(i) => scene.planes[i as usize].surface(ray, hit.t).parts(),
        };
        // A degenerate triangle or a hit at a sphere's centre has no normal; facing the
        // ray keeps every later formula finite.
        let ng = if ng == Vec3::ZERO {
            -ray.dir.normalize()
        } else {
            ng
        };
        let front_face = ray.dir.dot(ng) < 0.0;
        let ng = if front_face { ng } else { -ng };
        // Interpolated normals may disagree with the true surface (coarse meshes,
        // inconsistent winding); keep them on the geometric side.
        let flip = ns.dot(ng) < 0.0;
        let ns = if flip { -ns } else { ns };
        let p_shadow = smooth.map(|(corners, normals)| {
            let normals = if flip { normals.map(|n| -n) } else { normals };
            let bary = [1.0 - hit.u - hit.v, hit.u, hit.v];
            shadow_terminator_point(p, corners, normals, bary, ng)
        });
        SurfaceInteraction {
            p,
            p_error,
            n_geometric: ng,
            n_shading: ns,
            material,
            front_face,
            p_shadow,
        }
    }
}

/// Reflectance and refracted direction at a dielectric interface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DielectricScatter {
    /// Fresnel reflectance in [0, 1]; 1 under total internal reflection.
    pub reflectance: f32,
    /// Unit refracted direction; `None` under total internal reflection.
    pub refracted: Option<Vec3>,
}

/// Mirror direction of `d` about the unit normal `n` (either side).
#[inline]
pub fn reflect(d: Vec3, n: Vec3) -> Vec3 {
    d - 2.0 * d.dot(n) * n
}

/// Snell refraction with Schlick's Fresnel approximation (Schlick 1994).
///
/// `d` is the unit incident direction, `n` the unit normal on the incident side
/// (`d·n <= 0`), `eta_i`/`eta_t` the refractive indices of the incident and the
/// transmitted medium.
///
/// Schlick's formula is symmetric only if it is fed the cosine in the rarer medium:
/// leaving a denser medium it uses the transmitted-side cosine, otherwise it would give
/// a reflectance well below 1 just short of the critical angle where the true Fresnel
/// curve goes to 1 (pbrt-v3 §8.2; Bram de Greve, "Reflections and Refractions in Ray
/// Tracing", 2006). Past the critical angle (`sin²θt > 1`) all energy is reflected.
pub fn dielectric(d: Vec3, n: Vec3, eta_i: f32, eta_t: f32) -> DielectricScatter {
    if eta_i == eta_t {
        // Index-matched media have no interface. Schlick would still return
        // (1 - cos)^5 here, reflecting light off nothing.
        return DielectricScatter {
            reflectance: 0.0,
            refracted: Some(d),
        };
    }
    let cos_i = (-d.dot(n)).clamp(0.0, 1.0);
    let eta = eta_i / eta_t;
    let sin2_t = eta * eta * (1.0 - cos_i * cos_i);
    if sin2_t > 1.0 {
        return DielectricScatter {
            reflectance: 1.0,
            refracted: None,
        };
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let refracted = (eta * d + (eta * cos_i - cos_t) * n).normalize();
    let r0 = ((eta_i - eta_t) / (eta_i + eta_t)).powi(2);
    let cos = if eta_i > eta_t { cos_t } else { cos_i };
    let reflectance = (r0 + (1.0 - r0) * (1.0 - cos).powi(5)).clamp(0.0, 1.0);
    DielectricScatter {
        reflectance,
        refracted: Some(refracted),
    }
}

/// Tile edge in pixels: 256 pixels amortise rayon's per-task cost while leaving many
/// tiles per thread for load balance on uneven scenes.
pub(crate) const TILE: u32 = 16;

#[derive(Clone, Copy, Debug)]
pub(crate) struct Tile {
    pub x0: u32,
    pub y0: u32,
    pub x1: u32,
    pub y1: u32,
}

pub(crate) struct TileResult {
    pub tile: Tile,
    /// Filter sums of each pixel, row-major within the tile.
    pub pixels: Vec<PixelSums>,
    pub rays: RayCounts,
    pub samples_drawn: EffectSamplesDrawn,
    pub nonfinite_samples: u64,
    pub stages: StageTimes,
}

/// Which per-hit set a shading point draws: its pixel, path and depth, and what the
/// points are for.
#[derive(Clone, Copy, Debug)]
pub(crate) struct HitSet {
    pub seed: u64,
    pub pixel: u64,
    pub path: u64,
    pub depth: u32,
    pub dim: SobolDim,
}

/// Fills `out` with the `n` points of a per-hit set (light points, lobe directions).
/// With the Sobol sampler, at the first hit of a camera ray (`depth == 0`, where the
/// path identity is the camera ray's index `c` in its pixel) the points are
/// `c n .. c n + n` of the pixel's sequence for `dim`: one set stratified across all of
/// the pixel's camera rays, so that one shadow point per eye sample still covers the
/// light evenly over the pixel. Everywhere else the set is drawn from the shading
/// point's own stream ([`path_rng`], created on first use).
pub(crate) fn hit_points(
    sampler: SamplerKind,
    set: HitSet,
    n: u32,
    stream: &mut Option<PixelRng>,
    out: &mut Vec<(f32, f32)>,
) {
    if sampler == SamplerKind::Sobol && set.depth == 0 {
        let seq = SobolSet::new(set.seed, set.pixel, set.dim);
        let first = (set.path as u32).wrapping_mul(n);
        out.clear();
        out.extend((0..n).map(|i| seq.point(first.wrapping_add(i))));
        return;
    }
    let rng = stream.get_or_insert_with(|| path_rng(set.seed, set.pixel, set.path));
    fill_2d(sampler, n, Dimension::Hit, false, rng, out);
}

/// The random stream of the shading point reached by path `path` of pixel `pixel`.
/// Keyed by identity, not by visiting order, so a depth-first and a breadth-first
/// traversal of the same ray tree draw the same numbers. Distinct from the pixel's own
/// stream (`PixelRng::new(seed, pixel)`), which draws the camera samples.
pub fn path_rng(seed: u64, pixel: u64, path: u64) -> PixelRng {
    PixelRng::new(
        seed ^ PATH_STREAM,
        pixel ^ path.wrapping_mul(0x9e37_79b9_7f4a_7c15).rotate_left(32),
    )
}

/// Identity of the `branch`-th child ray emitted at the shading point of `parent`.
#[inline]
pub fn child_path(parent: u64, branch: u32) -> u64 {
    // SplitMix64's finaliser spreads consecutive inputs over the whole range.
    let mut z = parent
        .wrapping_add(branch as u64 + 1)
        .wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 30)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 27)
}

/// Separates the shading-point streams from the pixel streams of the same seed.
const PATH_STREAM: u64 = 0x5bd1_e995_7f4a_7c15;

/// Which queue a child ray belongs to (and which counter it is counted in).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum ChildKind {
    Reflection = 0,
    Refraction = 1,
    Glossy = 2,
    Translucency = 3,
}

/// A shadow ray and what its light adds if nothing blocks it.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ShadowRay {
    pub ray: Ray,
    /// Reflected radiance from this light sample, unoccluded (already divided by the
    /// number of samples of its light).
    pub contribution: Vec3,
    /// Index of the light in `Scene::lights` (the wavefront keeps one queue per light,
    /// so a packet of shadow rays converges on one light).
    pub light: u32,
}

/// A reflected, refracted or lobe-sampled ray and the weight its radiance gets.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ChildRay {
    pub ray: Ray,
    pub kind: ChildKind,
    /// Factor applied to the child's radiance in this shading point's radiance.
    pub weight: Vec3,
    /// Throughput the child carries for the contribution cutoff (the product of the
    /// lobe albedos from the camera; unlike `weight`, not divided by the lobe count).
    pub throughput: Vec3,
    pub path: u64,
}

/// What shading one hit produces: its local radiance and the rays it needs traced.
#[derive(Default)]
pub(crate) struct Emitted {
    /// Emission plus ambient light.
    pub local: Vec3,
    pub shadow: Vec<ShadowRay>,
    pub children: Vec<ChildRay>,
    /// Scratch sets, reused so that sampling never allocates per ray.
    points: Vec<(f32, f32)>,
}

/// The local shading model, shared by both integrators: what a hit emits and which
/// rays it spawns with which weights. The radiance at the hit is
/// `local + Σ unoccluded shadow contributions + Σ weight · radiance(child)`.
#[derive(Clone, Copy)]
pub(crate) struct Shader<'a> {
    pub scene: &'a Scene,
    pub max_depth: u32,
    pub min_contribution: f32,
    pub plan: SamplePlan,
    pub seed: u64,
}

impl Shader<'_> {
    pub fn new<'a>(scene: &'a Scene, opts: &RenderOptions, plan: SamplePlan) -> Shader<'a> {
        Shader {
            scene,
            max_depth: opts.max_depth,
            min_contribution: opts.min_contribution,
            plan,
            seed: opts.seed,
        }
    }

    /// Shades the hit `si` of a ray with unit direction `d` at depth `depth`, reached
    /// with `throughput`, by path `path` of pixel `pixel`. Fills `out` (cleared first)
    /// and counts the rays it emits and the samples it draws.
    #[allow(clippy::too_many_arguments)]
    pub fn shade_emit(
        &self,
        d: Vec3,
        time: f32,
        si: &SurfaceInteraction,
        depth: u32,
        throughput: Vec3,
        pixel: u64,
        path: u64,
        out: &mut Emitted,
        rays: &mut RayCounts,
        drawn: &mut EffectSamplesDrawn,
    ) {
        out.shadow.clear();
        out.children.clear();
        let scene = self.scene;
        let m = &scene.materials[si.material as usize];
        // The shading point's random stream, created on first use: most draw nothing.
        let mut stream: Option<PixelRng> = None;
        out.local = m.emission;
        if m.diffuse != Vec3::ZERO || m.checker.is_some() || m.specular != Vec3::ZERO {
            // The winding normal, not the one facing the ray: a checker surface on a
            // cell boundary shows the same cell from both sides.
            let outward = if si.front_face {
                si.n_geometric
            } else {
                -si.n_geometric
            };
            let albedo = m.albedo_on_surface(si.p, si.p_error, outward);
            out.local += scene.ambient * albedo;
            self.direct(
                -d,
                time,
                si,
                albedo,
                depth,
                &mut stream,
                pixel,
                path,
                out,
                rays,
                drawn,
            );
        }
        if depth >= self.max_depth {
            return;
        }
        // Every reflected and glossy direction leaves on the facing side (checked
        // below), so one origin serves them all.
        let origin_out = offset_ray_origin(si.p, si.p_error, si.n_geometric, si.n_geometric);
        let push = |out: &mut Emitted, kind, dir, origin, weight, throughput| {
            let branch = out.children.len() as u32;
            let mut ray = Ray::new(origin, dir);
            ray.time = time;
            out.children.push(ChildRay {
                ray,
                kind,
                weight,
                throughput,
                path: child_path(path, branch),
            });
        };
        if m.mirror != Vec3::ZERO {
            let tp = throughput * m.mirror;
            if tp.max_element() >= self.min_contribution {
                let dir = scatter_dir(reflect(d, si.n_shading), si.n_geometric, || {
                    reflect(d, si.n_geometric)
                });
                rays.reflection += 1;
                push(out, ChildKind::Reflection, dir, origin_out, m.mirror, tp);
            }
        }
        // Glossy reflection: the mean radiance over directions drawn from the Phong
        // lobe around the mirror direction. Directions below the surface carry nothing
        // (the lobe is clipped by the surface, as a real glossy coat is).
        if m.is_glossy() {
            let tp = throughput * m.glossy;
            if tp.max_element() >= self.min_contribution {
                let axis = scatter_dir(reflect(d, si.n_shading), si.n_geometric, || {
                    reflect(d, si.n_geometric)
                });
                let n = self.lobe_points(
                    depth,
                    SobolDim::Glossy,
                    &mut stream,
                    pixel,
                    path,
                    out,
                    drawn,
                );
                let weight = m.glossy / n as f32;
                for i in 0..n as usize {
                    let (u, v) = out.points[i];
                    let dir = sample_phong_lobe(axis, m.gloss_exponent, u, v);
                    if dir.dot(si.n_geometric) <= 0.0 {
                        continue;
                    }
                    rays.glossy += 1;
                    push(out, ChildKind::Glossy, dir, origin_out, weight, tp);
                }
            }
        }
        // Glass: Fresnel-weighted reflection plus transmission; a translucent material
        // blurs the transmitted ray over the Phong lobe around the refracted direction.
        if m.is_transmissive() {
            let (eta_i, eta_t) = if si.front_face {
                (1.0, m.ior)
            } else {
                (m.ior, 1.0)
            };
            let mut scatter = dielectric(d, si.n_shading, eta_i, eta_t);
            // With shading normals the refracted ray can end up on the incident side of
            // the true surface; the geometric normal always gives a consistent answer.
            if scatter
                .refracted
                .is_some_and(|t| t.dot(si.n_geometric) >= 0.0)
            {
                scatter = dielectric(d, si.n_geometric, eta_i, eta_t);
            }
            let f = scatter.reflectance;
            if f > 0.0 {
                let tp = throughput * f;
                if tp.max_element() >= self.min_contribution {
                    let dir = scatter_dir(reflect(d, si.n_shading), si.n_geometric, || {
                        reflect(d, si.n_geometric)
                    });
                    rays.reflection += 1;
                    push(
                        out,
                        ChildKind::Reflection,
                        dir,
                        origin_out,
                        Vec3::splat(f),
                        tp,
                    );
                }
            }
            if let Some(t) = scatter.refracted {
                let weight = (1.0 - f) * m.transmission;
                let tp = throughput * weight;
                if tp.max_element() >= self.min_contribution && weight != Vec3::ZERO {
                    // Refraction leaves into the far side: offset against the facing
                    // normal.
                    let origin =
                        offset_ray_origin(si.p, si.p_error, si.n_geometric, -si.n_geometric);
                    if m.is_translucent() {
                        let n = self.lobe_points(
                            depth,
                            SobolDim::Translucency,
                            &mut stream,
                            pixel,
                            path,
                            out,
                            drawn,
                        );
                        let w = weight / n as f32;
                        for i in 0..n as usize {
                            let (u, v) = out.points[i];
                            let dir = sample_phong_lobe(t, m.translucency_exponent, u, v);
                            if dir.dot(si.n_geometric) >= 0.0 {
                                continue;
                            }
                            rays.translucency += 1;
                            push(out, ChildKind::Translucency, dir, origin, w, tp);
                        }
                    } else {
                        rays.refraction += 1;
                        push(out, ChildKind::Refraction, t, origin, weight, tp);
                    }
                }
            }
        }
    }

    /// Lobe sample points in `out.points`: `glossy` stratified ones at the first hit
    /// of a camera ray, one deeper down (the ray tree stays linear). Returns the count.
    #[allow(clippy::too_many_arguments)]
    fn lobe_points(
        &self,
        depth: u32,
        dim: SobolDim,
        stream: &mut Option<PixelRng>,
        pixel: u64,
        path: u64,
        out: &mut Emitted,
        drawn: &mut EffectSamplesDrawn,
    ) -> u32 {
        let n = if depth == 0 { self.plan.glossy } else { 1 };
        let set = HitSet {
            seed: self.seed,
            pixel,
            path,
            depth,
            dim,
        };
        hit_points(self.plan.sampler, set, n, stream, &mut out.points);
        drawn.glossy += n as u64;
        n
    }

    /// Direct light: point and directional lights with one shadow ray each, area lights
    /// with `shadow` stratified points each. The reflectance is Lambert diffuse
    /// (`albedo / π · cosθ`, so that `ambient * albedo` and direct light share one
    /// scale) plus a Blinn-Phong highlight `ks (n·h)^shininess`.
    #[allow(clippy::too_many_arguments)]
    fn direct(
        &self,
        wo: Vec3,
        time: f32,
        si: &SurfaceInteraction,
        albedo: Vec3,
        depth: u32,
        stream: &mut Option<PixelRng>,
        pixel: u64,
        path: u64,
        out: &mut Emitted,
        rays: &mut RayCounts,
        drawn: &mut EffectSamplesDrawn,
    ) {
        let m = &self.scene.materials[si.material as usize];
        // A light below the shading normal's horizon contributes nothing, and neither
        // does one below the true surface, unless the surface is a smooth-shaded mesh:
        // there the facet is only an approximation, and the shadow ray from the lifted
        // origin decides (Hanika 2021). No shadow ray for a light that contributes
        // nothing. Shadow rays leave from the lifted point where there is one, offset by
        // the hit point's error bound.
        let smooth = si.p_shadow.is_some();
        let base = si.p_shadow.unwrap_or(si.p);
        let reflectance = |wi: Vec3| {
            let cos_s = wi.dot(si.n_shading);
            if !(cos_s > 0.0 && (smooth || wi.dot(si.n_geometric) > 0.0)) {
                return None;
            }
            let mut f = albedo * (FRAC_1_PI * cos_s);
            if m.specular != Vec3::ZERO {
                let h = (wi + wo).normalize_or_zero();
                f += m.specular * h.dot(si.n_shading).max(0.0).powf(m.shininess);
            }
            Some(f)
        };
        // Shadow rays end at their target by the error-bound rule of `spawn_ray_to`
        // (both ends offset, the end short by a bound on the rounding of the segment),
        // never by a tuned fraction of the distance.
        let mut shadow = |out: &mut Emitted, mut ray: Ray, contribution, light| {
            ray.time = time;
            rays.shadow += 1;
            out.shadow.push(ShadowRay {
                ray,
                contribution,
                light,
            });
        };
        for (index, light) in self.scene.lights.iter().enumerate() {
            let index = index as u32;
            match *light {
                Light::Point {
                    position,
                    intensity,
                } => {
                    // A point light is exact and has no surface: the segment's end
                    // is only short by the rounding margin, along the segment.
                    let to_light = position - si.p;
                    let dist2 = to_light.length_squared();
                    let wi = to_light / dist2.sqrt();
                    if let Some(f) = reflectance(wi) {
                        let ray = spawn_ray_to(
                            base,
                            si.p_error,
                            si.n_geometric,
                            position,
                            Vec3::ZERO,
                            -wi,
                        );
                        shadow(out, ray, intensity / dist2 * f, index);
                    }
                }
                Light::Spot {
                    position,
                    direction,
                    intensity,
                    cos_total,
                    cos_falloff_start,
                } => {
                    // As the point light, scaled by the cone's falloff (pbrt-v4).
                    let to_light = position - si.p;
                    let dist2 = to_light.length_squared();
                    let wi = to_light / dist2.sqrt();
                    let falloff =
                        Light::spot_falloff(-wi.dot(direction), cos_total, cos_falloff_start);
                    if falloff > 0.0
                        && let Some(f) = reflectance(wi)
                    {
                        let ray = spawn_ray_to(
                            base,
                            si.p_error,
                            si.n_geometric,
                            position,
                            Vec3::ZERO,
                            -wi,
                        );
                        shadow(out, ray, intensity * falloff / dist2 * f, index);
                    }
                }
                Light::Directional {
                    direction,
                    irradiance,
                } => {
                    let wi = -direction.normalize();
                    if let Some(f) = reflectance(wi) {
                        let o = offset_ray_origin(base, si.p_error, si.n_geometric, wi);
                        shadow(out, Ray::new(o, wi), irradiance * f, index);
                    }
                }
                _ => {
                    // The mean over `shadow` stratified points of the light of
                    // `f · L dω / pdf`.
                    let n = self.plan.shadow;
                    let mut points = std::mem::take(&mut out.points);
                    hit_points(
                        self.plan.sampler,
                        HitSet {
                            seed: self.seed,
                            pixel,
                            path,
                            depth,
                            dim: SobolDim::Light(index),
                        },
                        n,
                        stream,
                        &mut points,
                    );
                    drawn.light += n as u64;
                    for &(u, v) in &points {
                        let Some(s) = light.sample(si.p, u, v) else {
                            continue;
                        };
                        let Some(f) = reflectance(s.wi) else {
                            continue;
                        };
                        let ray = spawn_ray_to(
                            base,
                            si.p_error,
                            si.n_geometric,
                            s.point,
                            s.p_error,
                            s.normal,
                        );
                        shadow(out, ray, s.weight * f / n as f32, index);
                    }
                    out.points = points;
                }
            }
        }
    }
}

/// The recursive integrator: traces the rays [`Shader::shade_emit`] emits at once,
/// depth first, with the counters of the tile it works for.
struct Tracer<'a> {
    shader: Shader<'a>,
    accel: &'a SceneAccel,
    /// Shadow rays blocked by glass are traced again for its transmission.
    transmits: bool,
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
    camera: &CameraSampler,
    ws: &mut Workspace,
    tile: Tile,
) -> TileResult {
    let plan = camera.plan;
    let mut tracer = Tracer::new(scene, accel, opts, plan, ws);
    let mut pixels = Vec::with_capacity(((tile.x1 - tile.x0) * (tile.y1 - tile.y0)) as usize);
    let mut nonfinite_samples = 0;
    for y in tile.y0..tile.y1 {
        for x in tile.x0..tile.x1 {
            let index = y as u64 * opts.width as u64 + x as u64;
            let samples = &mut ws.samples;
            camera.pixel_samples(opts.seed, index, x, y, samples, &mut tracer.drawn);
            tracer.rays.camera += samples.rays.len() as u64;
            ws.radiance.clear();
            for (s, ray) in samples.rays.iter().enumerate() {
                let path = plan.first_path() + s as u64;
                let l = tracer.radiance(ray, 0, Vec3::ONE, index, path);
                ws.radiance.push(l);
            }
            pixels.push(resolve_pixel(
                &plan,
                &samples.offsets,
                &ws.radiance,
                &mut nonfinite_samples,
            ));
        }
    }
    ws.emitted = tracer.emitted;
    TileResult {
        tile,
        pixels,
        rays: tracer.rays,
        samples_drawn: tracer.drawn,
        nonfinite_samples,
        stages: StageTimes::default(),
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
    let camera = CameraSampler {
        frame: scene.camera_frame(opts.width, opts.height),
        lens: LensFrame::new(&scene.camera, &scene.camera_effects),
        plan: SamplePlan::new(scene, opts),
    };
    type Chunk<T> = (Vec<T>, Vec<u64>, RayCounts);
    let chunks: Vec<Chunk<T>> = pixels
        .par_chunks(64)
        .map_init(Workspace::default, |ws, chunk| {
            let mut tracer = Tracer::new(scene, accel, opts, camera.plan, ws);
            let mut sums = Vec::with_capacity(chunk.len());
            let mut cost = Vec::with_capacity(chunk.len());
            let mut nonfinite = 0;
            for (x, y, range) in chunk {
                let before = tracer.rays.total();
                let mut cam = camera;
                cam.plan.eye_begin = range.start;
                cam.plan.eye_end = range.end;
                let index = *y as u64 * opts.width as u64 + *x as u64;
                let samples = &mut ws.samples;
                cam.pixel_samples(opts.seed, index, *x, *y, samples, &mut tracer.drawn);
                tracer.rays.camera += samples.rays.len() as u64;
                ws.radiance.clear();
                for (s, ray) in samples.rays.iter().enumerate() {
                    let path = cam.plan.first_path() + s as u64;
                    let l = tracer.radiance(ray, 0, Vec3::ONE, index, path);
                    ws.radiance.push(l);
                }
                sums.push(keep(&resolve_pixel(
                    &cam.plan,
                    &samples.offsets,
                    &ws.radiance,
                    &mut nonfinite,
                )));
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
        plan: SamplePlan,
        ws: &mut Workspace,
    ) -> Tracer<'a> {
        Tracer {
            shader: Shader::new(scene, opts, plan),
            accel,
            transmits: shadow::transmits(scene, opts.transmitted_shadows),
            rays: RayCounts::default(),
            drawn: EffectSamplesDrawn::default(),
            emitted: std::mem::take(&mut ws.emitted),
        }
    }

    /// Radiance arriving along `ray` by path `path` of pixel `pixel`. `throughput` is
    /// the product of the weights from the camera to this ray, for the contribution
    /// cutoff.
    fn radiance(&mut self, ray: &Ray, depth: u32, throughput: Vec3, pixel: u64, path: u64) -> Vec3 {
        let Some(hit) = self.accel.closest_hit(ray) else {
            return self.shader.scene.background;
        };
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
            if !self.accel.any_hit(&s.ray) {
                l += s.contribution;
            } else if self.transmits {
                // Blocked, but perhaps only by glass (`shadow` module).
                self.rays.transmitted_shadow += 1;
                let t = shadow::transmittance(self.shader.scene, self.accel, &s.ray);
                if t != Vec3::ZERO {
                    l += s.contribution * t;
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

/// `dir` if it leaves on the incident side of the true surface (`n_geometric`), else
/// the fallback computed from the geometric normal: a shading normal must never send a
/// reflection into the surface.
#[inline]
fn scatter_dir(dir: Vec3, n_geometric: Vec3, fallback: impl FnOnce() -> Vec3) -> Vec3 {
    if dir.dot(n_geometric) > 0.0 {
        dir
    } else {
        fallback()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The first-hit light points of a pixel's 16 camera rays, one each: with the
    /// Sobol sampler they form a (0,4,2)-net (one point in every elementary interval
    /// of area 1/16), so the light is covered evenly across the pixel. The jittered
    /// sampler (the behaviour before the Sobol sampler) draws each camera ray's single
    /// point on its own, which is checked to fail the same test in most pixels.
    #[test]
    fn sobol_light_points_are_stratified_across_the_pixels_camera_rays() {
        let points = |sampler, pixel| -> Vec<(f32, f32)> {
            let mut out = Vec::new();
            (0..16u64)
                .map(|path| {
                    let set = HitSet {
                        seed: 3,
                        pixel,
                        path,
                        depth: 0,
                        dim: SobolDim::Light(0),
                    };
                    hit_points(sampler, set, 1, &mut None, &mut out);
                    out[0]
                })
                .collect()
        };
        let pixels = 64;
        for p in 0..pixels {
            let pts = points(SamplerKind::Sobol, p);
            assert!(
                crate::integrator::sobol::is_0m2_net(&pts),
                "pixel {p}: {pts:?}"
            );
        }
        let jittered_nets = (0..pixels)
            .filter(|&p| crate::integrator::sobol::is_0m2_net(&points(SamplerKind::Jittered, p)))
            .count();
        assert!(jittered_nets < 4, "{jittered_nets} jittered nets");
        // Deeper hits keep a set of their own per shading point.
        let deep = |path| {
            let mut out = Vec::new();
            let set = HitSet {
                seed: 3,
                pixel: 0,
                path,
                depth: 1,
                dim: SobolDim::Light(0),
            };
            hit_points(SamplerKind::Sobol, set, 16, &mut None, &mut out);
            out
        };
        assert!(crate::integrator::sobol::is_0m2_net(&deep(12345)));
        assert_ne!(deep(12345), deep(12346));
    }

    /// A round of the first 4 of 16 eye samples (`--sample-range 0..4`, or the first
    /// progressive pass): with the Sobol sampler their pixel positions are a
    /// (0,2,2)-net, one in each quarter of the pixel in every elementary shape; the
    /// jittered pattern (the behaviour before) orders strata row by row, so its first
    /// 4 all lie in the top row of strata, in every pixel.
    #[test]
    fn a_prefix_of_sobol_pixel_positions_is_stratified_and_of_jittered_is_not() {
        use crate::integrator::sobol::is_0m2_net;
        let mut pos = Vec::new();
        for pixel in 0..64 {
            let set = SobolSet::new(1, pixel, SobolDim::Pixel);
            let sobol: Vec<_> = (0..4).map(|i| set.point(i)).collect();
            assert!(is_0m2_net(&sobol), "pixel {pixel}: {sobol:?}");
            let mut rng = PixelRng::new(1, pixel);
            fill_2d(
                SamplerKind::Jittered,
                16,
                Dimension::Pixel,
                true,
                &mut rng,
                &mut pos,
            );
            assert!(!is_0m2_net(&pos[..4]), "pixel {pixel}: {:?}", &pos[..4]);
            assert!(pos[..4].iter().all(|p| p.1 < 0.25));
        }
    }
}
