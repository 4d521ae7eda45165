//! Recursive Whitted-style ray tracer (scalar reference).
//!
//! Whitted, "An Improved Illumination Model for Shaded Display" (CACM 1980): at each
//! hit, direct light from point and directional lights through one shadow ray each,
//! plus perfect mirror reflection and dielectric refraction traced recursively. This is
//! the reference the wavefront integrator is checked against, so it favours clarity
//! and exactness over speed, but it still never allocates per ray.
//!
//! Determinism: each pixel draws its sub-pixel positions from its own random stream,
//! seeded from `(seed, pixel index)`, and tiles are reassembled in a fixed order, so an
//! image is bit-identical whatever the number of threads and whatever order tiles run.

use super::{RenderOptions, RenderOutput};
use crate::accel::{PrimRef, SceneAccel, SceneHit};
use crate::film::Film;
use crate::geometry::{Ray, offset_ray_origin_scaled};
use crate::scene::{Light, Material, Scene};
use crate::stats::{RayCounts, ms_since};
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
    let frame = scene.camera.frame(width, height);
    let camera_ray = move |px: f32, py: f32| frame.ray(px, py);

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
            let result = render_tile(scene, accel, opts, &camera_ray, tile);
            if let Some(progress) = &opts.progress {
                progress(done.fetch_add(1, Ordering::Relaxed) + 1, total);
            }
            result
        })
        .collect();

    let mut film = Film::new(width, height);
    let mut rays = RayCounts::default();
    let mut nonfinite_samples = 0;
    for t in tiles {
        let mut values = t.pixels.into_iter();
        for y in t.tile.y0..t.tile.y1 {
            for x in t.tile.x0..t.tile.x1 {
                film.set(x, y, values.next().expect("tile holds all its pixels"));
            }
        }
        rays += t.rays;
        nonfinite_samples += t.nonfinite_samples;
    }
    RenderOutput {
        film,
        rays,
        render_ms: ms_since(start),
        nonfinite_samples,
    }
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
    nonfinite_samples: u64,
}

fn render_tile(
    scene: &Scene,
    accel: &SceneAccel,
    opts: &RenderOptions,
    camera_ray: &impl Fn(f32, f32) -> Ray,
    tile: Tile,
) -> TileResult {
    let spp = opts.spp.max(1);
    let mut tracer = Tracer {
        scene,
        accel,
        max_depth: opts.max_depth,
        min_contribution: opts.min_contribution,
        rays: RayCounts::default(),
    };
    let mut sampler = PixelSampler::new(spp);
    let mut pixels = Vec::with_capacity(((tile.x1 - tile.x0) * (tile.y1 - tile.y0)) as usize);
    let mut nonfinite_samples = 0;
    for y in tile.y0..tile.y1 {
        for x in tile.x0..tile.x1 {
            let index = y as u64 * opts.width as u64 + x as u64;
            let mut rng = PixelRng::new(opts.seed, index);
            let mut sum = Vec3::ZERO;
            for &(sx, sy) in sampler.positions(&mut rng) {
                let ray = camera_ray(x as f32 + sx, y as f32 + sy);
                tracer.rays.camera += 1;
                let radiance = tracer.radiance(&ray, 0, Vec3::ONE);
                if radiance.is_finite() {
                    sum += radiance;
                } else {
                    nonfinite_samples += 1;
                }
            }
            // Box filter: the mean of the samples inside the pixel.
            pixels.push(sum / spp as f32);
        }
    }
    TileResult {
        tile,
        pixels,
        rays: tracer.rays,
        nonfinite_samples,
    }
}

/// The recursive part, with the counters of the tile it works for.
struct Tracer<'a> {
    scene: &'a Scene,
    accel: &'a SceneAccel,
    max_depth: u32,
    min_contribution: f32,
    rays: RayCounts,
}

impl Tracer<'_> {
    /// Radiance arriving along `ray`. `throughput` is the product of the weights from
    /// the camera to this ray, for the contribution cutoff.
    fn radiance(&mut self, ray: &Ray, depth: u32, throughput: Vec3) -> Vec3 {
        match self.accel.closest_hit(ray) {
            None => self.scene.background,
            Some(hit) => {
                let si = SurfaceInteraction::new(self.scene, ray, &hit);
                self.shade(ray.dir.normalize(), &si, depth, throughput)
            }
        }
    }

    fn shade(&mut self, d: Vec3, si: &SurfaceInteraction, depth: u32, throughput: Vec3) -> Vec3 {
        let m = &self.scene.materials[si.material as usize];
        let mut l = m.emission;
        if m.diffuse != Vec3::ZERO || m.checker.is_some() || m.specular != Vec3::ZERO {
            let albedo = m.albedo_at(si.p);
            l += self.scene.ambient * albedo + self.direct(-d, si, m, albedo);
        }
        if depth >= self.max_depth {
            return l;
        }
        if m.mirror != Vec3::ZERO {
            let dir = scatter_dir(reflect(d, si.n_shading), si.n_geometric, || {
                reflect(d, si.n_geometric)
            });
            l += m.mirror * self.reflected(si, dir, depth, throughput * m.mirror);
        }
        if m.is_transmissive() {
            l += self.glass(d, si, m, depth, throughput);
        }
        l
    }

    /// Point and directional lights, one shadow ray each: Lambert diffuse
    /// (`albedo / π · E cosθ`, so that `ambient * albedo` and direct light share one
    /// scale) plus a Blinn-Phong highlight `ks (n·h)^shininess · E`.
    fn direct(&mut self, wo: Vec3, si: &SurfaceInteraction, m: &Material, albedo: Vec3) -> Vec3 {
        let origin = offset_ray_origin_scaled(si.p, si.n_geometric, si.scale);
        let mut l = Vec3::ZERO;
        for light in &self.scene.lights {
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
            };
            // A light below the surface (or below the shading normal) contributes
            // nothing: no shadow ray for it.
            let cos_s = wi.dot(si.n_shading);
            if !(wi.dot(si.n_geometric) > 0.0 && cos_s > 0.0) {
                continue;
            }
            self.rays.shadow += 1;
            if self.accel.any_hit(&Ray::segment(origin, wi, 0.0, tmax)) {
                continue;
            }
            let mut f = albedo * (FRAC_1_PI * cos_s);
            if m.specular != Vec3::ZERO {
                let h = (wi + wo).normalize_or_zero();
                f += m.specular * h.dot(si.n_shading).max(0.0).powf(m.shininess);
            }
            l += irradiance * f;
        }
        l
    }

    /// Fresnel-weighted reflection plus transmission.
    fn glass(
        &mut self,
        d: Vec3,
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
            l += f * self.reflected(si, dir, depth, throughput * f);
        }
        if let Some(t) = scatter.refracted {
            let weight = (1.0 - f) * m.transmission;
            let throughput = throughput * weight;
            if throughput.max_element() >= self.min_contribution && weight != Vec3::ZERO {
                self.rays.refraction += 1;
                // Refraction leaves into the far side: offset against the facing normal.
                let origin = offset_ray_origin_scaled(si.p, -si.n_geometric, si.scale);
                l += weight * self.radiance(&Ray::new(origin, t), depth + 1, throughput);
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
        depth: u32,
        throughput: Vec3,
    ) -> Vec3 {
        if throughput.max_element() < self.min_contribution {
            return Vec3::ZERO;
        }
        self.rays.reflection += 1;
        let origin = offset_ray_origin_scaled(si.p, si.n_geometric, si.scale);
        self.radiance(&Ray::new(origin, dir), depth + 1, throughput)
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

/// Sub-pixel sample positions in `[0, 1)²`.
///
/// One sample uses the pixel centre. A square count `k²` uses a jittered `k × k` grid
/// (stratified sampling, Cook 1986); any other count uses N-rooks / Latin hypercube
/// sampling (Shirley 1991): `n` jittered strata in x paired with a random permutation of
/// `n` jittered strata in y, which keeps both 1D projections stratified.
struct PixelSampler {
    spp: u32,
    grid: Option<u32>,
    positions: Vec<(f32, f32)>,
    permutation: Vec<u32>,
}

impl PixelSampler {
    fn new(spp: u32) -> Self {
        let k = spp.isqrt();
        PixelSampler {
            spp,
            grid: (k * k == spp).then_some(k),
            positions: Vec::with_capacity(spp as usize),
            permutation: Vec::new(),
        }
    }

    fn positions(&mut self, rng: &mut PixelRng) -> &[(f32, f32)] {
        self.positions.clear();
        if self.spp == 1 {
            self.positions.push((0.5, 0.5));
        } else if let Some(k) = self.grid {
            let inv = 1.0 / k as f32;
            for j in 0..k {
                for i in 0..k {
                    let (u, v) = (rng.next_f32(), rng.next_f32());
                    self.positions
                        .push(((i as f32 + u) * inv, (j as f32 + v) * inv));
                }
            }
        } else {
            let n = self.spp;
            self.permutation.clear();
            self.permutation.extend(0..n);
            // Fisher-Yates.
            for i in (1..n).rev() {
                let j = rng.below(i + 1);
                self.permutation.swap(i as usize, j as usize);
            }
            let inv = 1.0 / n as f32;
            for i in 0..n {
                let (u, v) = (rng.next_f32(), rng.next_f32());
                let j = self.permutation[i as usize];
                self.positions
                    .push(((i as f32 + u) * inv, (j as f32 + v) * inv));
            }
        }
        &self.positions
    }
}

/// A per-pixel random stream: SplitMix64 (Steele, Lea, Flood 2014) started from a hash
/// of `(seed, pixel index)`. Independent of which thread renders the pixel, which is
/// what makes images reproducible across thread counts.
struct PixelRng {
    state: u64,
}

const GOLDEN_GAMMA: u64 = 0x9e37_79b9_7f4a_7c15;

impl PixelRng {
    fn new(seed: u64, pixel: u64) -> Self {
        // Hash both so neighbouring pixels and neighbouring seeds start far apart.
        PixelRng {
            state: mix64(seed ^ mix64(pixel.wrapping_add(GOLDEN_GAMMA))),
        }
    }

    fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(GOLDEN_GAMMA);
        mix64(self.state)
    }

    /// Uniform in `[0, 1)`: the top 24 bits, so every value is exact in f32 and 1.0
    /// can never come out (it would step into the next stratum or pixel).
    fn next_f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 * (1.0 / (1u32 << 24) as f32)
    }

    /// Uniform in `[0, n)` by multiply-shift (Lemire 2019); the bias of at most
    /// `n / 2^32` is irrelevant for shuffling sample strata.
    fn below(&mut self, n: u32) -> u32 {
        (((self.next_u64() >> 32) * n as u64) >> 32) as u32
    }
}

/// SplitMix64's output function (Stafford's "Mix13" variant).
fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stratified_positions_cover_every_stratum() {
        let mut rng = PixelRng::new(7, 3);
        for spp in [1u32, 4, 9, 16, 2, 3, 5, 12] {
            let mut s = PixelSampler::new(spp);
            let pos = s.positions(&mut rng).to_vec();
            assert_eq!(pos.len(), spp as usize);
            assert!(
                pos.iter()
                    .all(|&(x, y)| (0.0..1.0).contains(&x) && (0.0..1.0).contains(&y))
            );
            if spp == 1 {
                assert_eq!(pos, vec![(0.5, 0.5)]);
                continue;
            }
            // Both 1D projections hit each of the spp (or k) strata exactly once.
            let strata = s.grid.map_or(spp, |k| k);
            for axis in 0..2 {
                let mut count = vec![0u32; strata as usize];
                for &(x, y) in &pos {
                    let c = if axis == 0 { x } else { y };
                    count[(c * strata as f32) as usize] += 1;
                }
                assert!(
                    count.iter().all(|&c| c == spp / strata),
                    "spp {spp}: {count:?}"
                );
            }
        }
    }

    #[test]
    fn pixel_streams_depend_on_seed_and_pixel_only() {
        let draw = |seed, pixel| {
            let mut r = PixelRng::new(seed, pixel);
            (0..4).map(|_| r.next_u64()).collect::<Vec<_>>()
        };
        assert_eq!(draw(1, 2), draw(1, 2));
        assert_ne!(draw(1, 2), draw(1, 3));
        assert_ne!(draw(1, 2), draw(2, 2));
        let mut r = PixelRng::new(0, 0);
        for _ in 0..10_000 {
            let x = r.next_f32();
            assert!((0.0..1.0).contains(&x));
            assert!(r.below(3) < 3);
        }
    }
}
