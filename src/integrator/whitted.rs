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
//! Determinism: each pixel draws all its samples from its own random stream, seeded
//! from `(seed, pixel index)`, in a fixed order, and tiles are reassembled in a fixed
//! order, so an image is bit-identical whatever the number of threads and whatever
//! order tiles run.

use super::sampling::{
    Dimension, PixelRng, decorrelate, fill_1d, fill_2d, sample_aperture, sample_phong_lobe,
};
use super::{FilterKind, RenderOptions, RenderOutput, SamplerKind};
use crate::accel::{PrimRef, SceneAccel, SceneHit};
use crate::film::Film;
use crate::geometry::{Ray, offset_ray_origin_scaled};
use crate::scene::{CameraFrame, LensFrame, Light, Material, Scene};
use crate::stats::{EffectSamplesDrawn, RayCounts, ms_since};
use glam::Vec3;
use rayon::prelude::*;
use std::f32::consts::FRAC_1_PI;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

/// Renders `scene` with the structure `accel`. `opts` must pass
/// [`RenderOptions::validate`]; parallelism is whatever rayon pool the caller runs in.
pub fn render(scene: &Scene, accel: &SceneAccel, opts: &RenderOptions) -> RenderOutput {
    let start = Instant::now();
    let (width, height) = (opts.width, opts.height);
    let camera = CameraSampler {
        frame: scene.camera.frame(width, height),
        lens: LensFrame::new(&scene.camera, &scene.camera_effects),
        plan: SamplePlan::new(scene, opts),
    };

    let tiles_x = width.div_ceil(TILE);
    let tiles_y = height.div_ceil(TILE);
    let total = tiles_x as u64 * tiles_y as u64;
    let done = AtomicU64::new(0);
    let tiles: Vec<TileResult> = (0..total)
        .into_par_iter()
        .map(|i| {
            let (tx, ty) = ((i % tiles_x as u64) as u32, (i / tiles_x as u64) as u32);
            let tile = Tile {
                x0: tx * TILE,
                y0: ty * TILE,
                x1: ((tx + 1) * TILE).min(width),
                y1: ((ty + 1) * TILE).min(height),
            };
            let result = render_tile(scene, accel, opts, &camera, tile);
            if let Some(progress) = &opts.progress {
                progress(done.fetch_add(1, Ordering::Relaxed) + 1, total);
            }
            result
        })
        .collect();

    let mut film = Film::new(width, height);
    let mut rays = RayCounts::default();
    let mut samples_drawn = EffectSamplesDrawn::default();
    let mut nonfinite_samples = 0;
    for t in tiles {
        let mut values = t.pixels.into_iter();
        for y in t.tile.y0..t.tile.y1 {
            for x in t.tile.x0..t.tile.x1 {
                film.set(x, y, values.next().expect("tile holds all its pixels"));
            }
        }
        rays += t.rays;
        samples_drawn += t.samples_drawn;
        nonfinite_samples += t.nonfinite_samples;
    }
    RenderOutput {
        film,
        rays,
        render_ms: ms_since(start),
        nonfinite_samples,
        samples_drawn,
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
        }
    }

    /// Camera rays per pixel: `eye * lens * time` (absent effects count 1).
    pub fn camera_rays_per_pixel(&self) -> u32 {
        self.eye * self.lens.max(1) * self.time.max(1)
    }
}

/// Everything that turns sample positions into camera rays.
struct CameraSampler {
    frame: CameraFrame,
    lens: LensFrame,
    plan: SamplePlan,
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
    pub n_geometric: Vec3,
    pub n_shading: Vec3,
    pub material: u32,
    pub front_face: bool,
    /// Largest |coordinate| of the primitive (corners, or centre plus radius): the
    /// scale of the rounding error of `p`, which sizes the offset of secondary origins.
    pub scale: f32,
}

impl SurfaceInteraction {
    /// The hit point is rebuilt from the primitive, not as `o + t d`: `t` carries the
    /// rounding error of the whole intersection test scaled by the ray length, whereas
    /// barycentric interpolation of the corners (or centre + radius * normal for a
    /// sphere) lands within a few ulps of the surface, which is what the
    /// Wächter-Binder offset of the next ray origin is sized for.
    pub fn new(scene: &Scene, ray: &Ray, hit: &SceneHit) -> Self {
        let (p, ng, ns, material, scale) = match hit.prim {
            PrimRef::Triangle(t) => {
                let t = t as usize;
                let mesh = &scene.mesh;
                let [a, b, c] = mesh.corners(t);
                let w = 1.0 - hit.u - hit.v;
                let p = w * a + hit.u * b + hit.v * c;
                let ng = mesh.geometric_normal(t);
                let ns = mesh.shading_normal(t, hit.u, hit.v);
                let scale = a.abs().max(b.abs()).max(c.abs()).max_element();
                (p, ng, ns, mesh.material[t], scale)
            }
            PrimRef::Sphere(s) => {
                let s = s as usize;
                let center = scene.spheres.center(s);
                let radius = scene.spheres.radius[s];
                let n = (ray.at(hit.t) - center).normalize_or_zero();
                let scale = center.abs().max_element() + radius;
                (center + radius * n, n, n, scene.spheres.material[s], scale)
            }
            // Moving primitives are placed at the ray's time; translation leaves
            // normals unchanged.
            PrimRef::MovingTriangle(t) => {
                let t = t as usize;
                let mesh = &scene.motion.mesh;
                let [a, b, c] = scene.motion.triangle_corners(t, ray.time);
                let w = 1.0 - hit.u - hit.v;
                let p = w * a + hit.u * b + hit.v * c;
                let ng = mesh.geometric_normal(t);
                let ns = mesh.shading_normal(t, hit.u, hit.v);
                let scale = a.abs().max(b.abs()).max(c.abs()).max_element();
                (p, ng, ns, mesh.material[t], scale)
            }
            PrimRef::MovingSphere(s) => {
                let s = s as usize;
                let center = scene.motion.sphere_center(s, ray.time);
                let radius = scene.motion.spheres.radius[s];
                let n = (ray.at(hit.t) - center).normalize_or_zero();
                let scale = center.abs().max_element() + radius;
                (
                    center + radius * n,
                    n,
                    n,
                    scene.motion.spheres.material[s],
                    scale,
                )
            }
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
        let ns = if ns.dot(ng) < 0.0 { -ns } else { ns };
        SurfaceInteraction {
            p,
            n_geometric: ng,
            n_shading: ns,
            material,
            front_face,
            scale,
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
const TILE: u32 = 16;

/// Shadow rays to a point light stop this fraction short of it, so that geometry the
/// light sits on (a lamp on a ceiling) does not shadow it through rounding of `t`.
/// Relative, like the error of `t` itself: no scene-scale epsilon.
const SHADOW_TMAX_SCALE: f32 = 1.0 - 16.0 * f32::EPSILON;

/// Shadow rays to a point on an area light stop this fraction short of it: the light's
/// own emissive geometry lies there (a disk light's 64-gon even slightly off the true
/// disk), and must not shadow its own samples.
const AREA_SHADOW_TMAX_SCALE: f32 = 1.0 - 1e-4;

#[derive(Clone, Copy, Debug)]
struct Tile {
    x0: u32,
    y0: u32,
    x1: u32,
    y1: u32,
}

struct TileResult {
    tile: Tile,
    /// Row-major within the tile.
    pixels: Vec<Vec3>,
    rays: RayCounts,
    samples_drawn: EffectSamplesDrawn,
    nonfinite_samples: u64,
}

fn render_tile(
    scene: &Scene,
    accel: &SceneAccel,
    opts: &RenderOptions,
    camera: &CameraSampler,
    tile: Tile,
) -> TileResult {
    let plan = camera.plan;
    let mut tracer = Tracer {
        scene,
        accel,
        max_depth: opts.max_depth,
        min_contribution: opts.min_contribution,
        plan,
        rng: PixelRng::new(opts.seed, 0),
        rays: RayCounts::default(),
        drawn: EffectSamplesDrawn::default(),
        light_points: Vec::new(),
        lobe_points: Vec::new(),
    };
    let (lens_n, time_n) = (plan.lens.max(1), plan.time.max(1));
    let mut pixel_pos = Vec::with_capacity(plan.eye as usize);
    let mut lens_pos = Vec::new();
    let mut times = Vec::new();
    let mut pixels = Vec::with_capacity(((tile.x1 - tile.x0) * (tile.y1 - tile.y0)) as usize);
    let mut nonfinite_samples = 0;
    // Box: samples inside the pixel; otherwise over the filter's footprint.
    let footprint = 2.0 * plan.filter.radius();
    for y in tile.y0..tile.y1 {
        for x in tile.x0..tile.x1 {
            let index = y as u64 * opts.width as u64 + x as u64;
            let rng = &mut tracer.rng;
            *rng = PixelRng::new(opts.seed, index);
            // Draw order is fixed: pixel positions, lens points, shutter times, then
            // whatever the paths draw. A scene with no lens and no motion draws the
            // pixel positions only, exactly as the plain Whitted renderer did.
            fill_2d(
                plan.sampler,
                plan.eye,
                Dimension::Pixel,
                true,
                rng,
                &mut pixel_pos,
            );
            if plan.lens > 0 {
                let n = plan.eye * lens_n;
                fill_2d(plan.sampler, n, Dimension::Lens, false, rng, &mut lens_pos);
                decorrelate(plan.sampler, &mut lens_pos, rng);
                tracer.drawn.lens += n as u64;
            }
            if plan.time > 0 {
                let n = plan.eye * lens_n * time_n;
                fill_1d(plan.sampler, n, Dimension::Time, rng, &mut times);
                decorrelate(plan.sampler, &mut times, rng);
                tracer.drawn.time += n as u64;
            }
            let mut sum = Vec3::ZERO;
            let mut weight_sum = 0.0f32;
            let mut plain_sum = Vec3::ZERO;
            for (e, &(sx, sy)) in pixel_pos.iter().enumerate() {
                let (ox, oy) = if plan.filter == FilterKind::Box {
                    (sx, sy)
                } else {
                    (0.5 + (sx - 0.5) * footprint, 0.5 + (sy - 0.5) * footprint)
                };
                let pinhole = camera.frame.ray(x as f32 + ox, y as f32 + oy);
                let mut radiance_sum = Vec3::ZERO;
                for l in 0..lens_n {
                    let lens_index = e * lens_n as usize + l as usize;
                    let lens_point = (plan.lens > 0).then(|| {
                        let (u, v) = lens_pos[lens_index];
                        sample_aperture(u, v, camera.lens.blades, camera.lens.rotation)
                    });
                    for t in 0..time_n {
                        let time = if plan.time > 0 {
                            camera
                                .lens
                                .time(times[lens_index * time_n as usize + t as usize])
                        } else {
                            camera.lens.shutter[0]
                        };
                        let ray = camera.lens.ray(&camera.frame, pinhole, lens_point, time);
                        tracer.rays.camera += 1;
                        let radiance = tracer.radiance(&ray, 0, Vec3::ONE);
                        if radiance.is_finite() {
                            radiance_sum += radiance;
                        } else {
                            nonfinite_samples += 1;
                        }
                    }
                }
                let radiance = if lens_n * time_n == 1 {
                    radiance_sum
                } else {
                    radiance_sum / (lens_n * time_n) as f32
                };
                let w = plan.filter.weight(ox - 0.5, oy - 0.5);
                sum += w * radiance;
                weight_sum += w;
                plain_sum += radiance;
            }
            // Box filter: the mean of the samples inside the pixel. Weighted filters
            // divide by the weights drawn (a ratio estimator, consistent); should every
            // sample land where the filter is zero, the plain mean stands in.
            pixels.push(if weight_sum > 0.0 {
                sum / weight_sum
            } else {
                plain_sum / plan.eye as f32
            });
        }
    }
    TileResult {
        tile,
        pixels,
        rays: tracer.rays,
        samples_drawn: tracer.drawn,
        nonfinite_samples,
    }
}

/// The recursive part, with the counters of the tile it works for and the random
/// stream of the pixel it works on.
struct Tracer<'a> {
    scene: &'a Scene,
    accel: &'a SceneAccel,
    max_depth: u32,
    min_contribution: f32,
    plan: SamplePlan,
    rng: PixelRng,
    rays: RayCounts,
    drawn: EffectSamplesDrawn,
    /// Scratch sets, reused so that sampling never allocates per ray.
    light_points: Vec<(f32, f32)>,
    lobe_points: Vec<(f32, f32)>,
}

impl Tracer<'_> {
    /// Radiance arriving along `ray`. `throughput` is the product of the weights from
    /// the camera to this ray, for the contribution cutoff.
    fn radiance(&mut self, ray: &Ray, depth: u32, throughput: Vec3) -> Vec3 {
        match self.accel.closest_hit(ray) {
            None => self.scene.background,
            Some(hit) => {
                let si = SurfaceInteraction::new(self.scene, ray, &hit);
                self.shade(ray.dir.normalize(), ray.time, &si, depth, throughput)
            }
        }
    }

    fn shade(
        &mut self,
        d: Vec3,
        time: f32,
        si: &SurfaceInteraction,
        depth: u32,
        throughput: Vec3,
    ) -> Vec3 {
        let scene = self.scene;
        let m = &scene.materials[si.material as usize];
        let mut l = m.emission;
        if m.diffuse != Vec3::ZERO || m.checker.is_some() || m.specular != Vec3::ZERO {
            let albedo = m.albedo_at(si.p);
            l += scene.ambient * albedo + self.direct(-d, time, si, m, albedo);
        }
        if depth >= self.max_depth {
            return l;
        }
        if m.mirror != Vec3::ZERO {
            let dir = scatter_dir(reflect(d, si.n_shading), si.n_geometric, || {
                reflect(d, si.n_geometric)
            });
            l += m.mirror * self.reflected(si, dir, time, depth, throughput * m.mirror);
        }
        if m.is_glossy() {
            l += m.glossy * self.glossy(d, time, si, m, depth, throughput * m.glossy);
        }
        if m.is_transmissive() {
            l += self.glass(d, time, si, m, depth, throughput);
        }
        l
    }

    /// Direct light: point and directional lights with one shadow ray each, area lights
    /// with `shadow` stratified points each. The reflectance is Lambert diffuse
    /// (`albedo / π · cosθ`, so that `ambient * albedo` and direct light share one
    /// scale) plus a Blinn-Phong highlight `ks (n·h)^shininess`.
    fn direct(
        &mut self,
        wo: Vec3,
        time: f32,
        si: &SurfaceInteraction,
        m: &Material,
        albedo: Vec3,
    ) -> Vec3 {
        let origin = offset_ray_origin_scaled(si.p, si.n_geometric, si.scale);
        // A light below the surface (or below the shading normal) contributes nothing:
        // no shadow ray for it.
        let reflectance = |wi: Vec3| {
            let cos_s = wi.dot(si.n_shading);
            if !(wi.dot(si.n_geometric) > 0.0 && cos_s > 0.0) {
                return None;
            }
            let mut f = albedo * (FRAC_1_PI * cos_s);
            if m.specular != Vec3::ZERO {
                let h = (wi + wo).normalize_or_zero();
                f += m.specular * h.dot(si.n_shading).max(0.0).powf(m.shininess);
            }
            Some(f)
        };
        let mut l = Vec3::ZERO;
        let scene = self.scene;
        for light in &scene.lights {
            let (wi, tmax, irradiance) = match *light {
                Light::Point {
                    position,
                    intensity,
                } => {
                    let to_light = position - origin;
                    let dist2 = to_light.length_squared();
                    let dist = dist2.sqrt();
                    (to_light / dist, dist * SHADOW_TMAX_SCALE, intensity / dist2)
                }
                Light::Directional {
                    direction,
                    irradiance,
                } => (-direction.normalize(), f32::INFINITY, irradiance),
                _ => {
                    l += self.area_light(light, origin, time, &reflectance);
                    continue;
                }
            };
            let Some(f) = reflectance(wi) else {
                continue;
            };
            self.rays.shadow += 1;
            if self.occluded(origin, wi, tmax, time) {
                continue;
            }
            l += irradiance * f;
        }
        l
    }

    /// The mean over `shadow` stratified points of the light of `f · L dω / pdf`.
    fn area_light(
        &mut self,
        light: &Light,
        origin: Vec3,
        time: f32,
        reflectance: &impl Fn(Vec3) -> Option<Vec3>,
    ) -> Vec3 {
        let n = self.plan.shadow;
        let mut points = std::mem::take(&mut self.light_points);
        fill_2d(
            self.plan.sampler,
            n,
            Dimension::Hit,
            false,
            &mut self.rng,
            &mut points,
        );
        self.drawn.light += n as u64;
        let mut sum = Vec3::ZERO;
        for &(u, v) in &points {
            let Some(s) = light.sample(origin, u, v) else {
                continue;
            };
            let Some(f) = reflectance(s.wi) else {
                continue;
            };
            self.rays.shadow += 1;
            if !self.occluded(origin, s.wi, s.dist * AREA_SHADOW_TMAX_SCALE, time) {
                sum += s.weight * f;
            }
        }
        self.light_points = points;
        sum / n as f32
    }

    fn occluded(&self, origin: Vec3, dir: Vec3, tmax: f32, time: f32) -> bool {
        let mut r = Ray::segment(origin, dir, 0.0, tmax);
        r.time = time;
        self.accel.any_hit(&r)
    }

    /// Glossy reflection: the mean radiance over directions drawn from the Phong lobe
    /// around the mirror direction. Directions below the surface carry nothing (the
    /// lobe is clipped by the surface, as a real glossy coat is).
    fn glossy(
        &mut self,
        d: Vec3,
        time: f32,
        si: &SurfaceInteraction,
        m: &Material,
        depth: u32,
        throughput: Vec3,
    ) -> Vec3 {
        if throughput.max_element() < self.min_contribution {
            return Vec3::ZERO;
        }
        let axis = scatter_dir(reflect(d, si.n_shading), si.n_geometric, || {
            reflect(d, si.n_geometric)
        });
        let dirs = self.lobe(depth, axis, m.gloss_exponent);
        let origin = offset_ray_origin_scaled(si.p, si.n_geometric, si.scale);
        let mut sum = Vec3::ZERO;
        for &dir in dirs.iter() {
            if dir.dot(si.n_geometric) <= 0.0 {
                continue;
            }
            self.rays.glossy += 1;
            let mut r = Ray::new(origin, dir);
            r.time = time;
            sum += self.radiance(&r, depth + 1, throughput);
        }
        sum / dirs.len() as f32
    }

    /// Directions of the lobe `cos^exponent` around `axis`: `glossy` stratified ones at
    /// the first hit of a camera ray, one deeper down (the ray tree stays linear).
    fn lobe(&mut self, depth: u32, axis: Vec3, exponent: f32) -> LobeDirections {
        let n = if depth == 0 { self.plan.glossy } else { 1 };
        let mut points = std::mem::take(&mut self.lobe_points);
        fill_2d(
            self.plan.sampler,
            n,
            Dimension::Hit,
            false,
            &mut self.rng,
            &mut points,
        );
        self.drawn.glossy += n as u64;
        let dirs = points
            .iter()
            .map(|&(u, v)| sample_phong_lobe(axis, exponent, u, v))
            .collect();
        self.lobe_points = points;
        dirs
    }

    /// Fresnel-weighted reflection plus transmission; a translucent material blurs the
    /// transmitted ray over the Phong lobe around the refracted direction.
    fn glass(
        &mut self,
        d: Vec3,
        time: f32,
        si: &SurfaceInteraction,
        m: &Material,
        depth: u32,
        throughput: Vec3,
    ) -> Vec3 {
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
        let mut l = Vec3::ZERO;
        if f > 0.0 {
            let dir = scatter_dir(reflect(d, si.n_shading), si.n_geometric, || {
                reflect(d, si.n_geometric)
            });
            l += f * self.reflected(si, dir, time, depth, throughput * f);
        }
        if let Some(t) = scatter.refracted {
            let weight = (1.0 - f) * m.transmission;
            let throughput = throughput * weight;
            if throughput.max_element() >= self.min_contribution && weight != Vec3::ZERO {
                // Refraction leaves into the far side: offset against the facing normal.
                let origin = offset_ray_origin_scaled(si.p, -si.n_geometric, si.scale);
                if m.is_translucent() {
                    let dirs = self.lobe(depth, t, m.translucency_exponent);
                    let mut sum = Vec3::ZERO;
                    for &dir in dirs.iter() {
                        if dir.dot(si.n_geometric) >= 0.0 {
                            continue;
                        }
                        self.rays.translucency += 1;
                        let mut r = Ray::new(origin, dir);
                        r.time = time;
                        sum += self.radiance(&r, depth + 1, throughput);
                    }
                    l += weight * sum / dirs.len() as f32;
                } else {
                    self.rays.refraction += 1;
                    let mut r = Ray::new(origin, t);
                    r.time = time;
                    l += weight * self.radiance(&r, depth + 1, throughput);
                }
            }
        }
        l
    }

    /// Traces a reflection ray leaving on the incident side, unless its weight has
    /// fallen below the contribution cutoff.
    fn reflected(
        &mut self,
        si: &SurfaceInteraction,
        dir: Vec3,
        time: f32,
        depth: u32,
        throughput: Vec3,
    ) -> Vec3 {
        if throughput.max_element() < self.min_contribution {
            return Vec3::ZERO;
        }
        self.rays.reflection += 1;
        let origin = offset_ray_origin_scaled(si.p, si.n_geometric, si.scale);
        let mut r = Ray::new(origin, dir);
        r.time = time;
        self.radiance(&r, depth + 1, throughput)
    }
}

/// Lobe directions of one shading point: up to 16 inline, so the common counts never
/// allocate; more (a large `glossy` count at a first hit) spill to the heap once per
/// such hit, not per ray.
enum LobeDirections {
    Inline([Vec3; 16], usize),
    Heap(Vec<Vec3>),
}

impl FromIterator<Vec3> for LobeDirections {
    fn from_iter<I: IntoIterator<Item = Vec3>>(iter: I) -> Self {
        let mut buf = [Vec3::ZERO; 16];
        let mut n = 0;
        let mut it = iter.into_iter();
        for d in it.by_ref() {
            if n == 16 {
                let mut v = buf.to_vec();
                v.push(d);
                v.extend(it);
                return LobeDirections::Heap(v);
            }
            buf[n] = d;
            n += 1;
        }
        LobeDirections::Inline(buf, n)
    }
}

impl std::ops::Deref for LobeDirections {
    type Target = [Vec3];
    fn deref(&self) -> &[Vec3] {
        match self {
            LobeDirections::Inline(b, n) => &b[..*n],
            LobeDirections::Heap(v) => v,
        }
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
