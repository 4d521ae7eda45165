//! The local shading model, shared by both integrators (`Shader::shade_emit`):
//! emission, ambient, direct light (Lambert plus Blinn-Phong) with the shadow rays it
//! needs, and the mirror, glossy, glass and translucent child rays with their weights
//! and the contribution cutoff. The recursive integrator traces the emitted rays at
//! once, the wavefront queues them.

use super::RenderOptions;
use super::camera_rays::SamplePlan;
use super::environment::{ShadowOrigin, environment_shadow_rays};
use super::interaction::SurfaceInteraction;
use super::optics::{dielectric, reflect, scatter_dir};
use super::path_keys::{HitSet, child_path, hit_points};
use super::sampling::PixelRng;
use super::sobol::SobolDim;
use crate::geometry::warp::sample_phong_lobe;
use crate::geometry::{OffsetOrigins, Ray, offset_ray_origin, spawn_ray_to};
use crate::scene::{Light, Scene};
use crate::stats::{EffectSamplesDrawn, RayCounts};
use glam::Vec3;
use std::f32::consts::FRAC_1_PI;

/// Which queue a child ray belongs to (and which counter it is counted in).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum ChildKind {
    Reflection,
    Refraction,
    Glossy,
    Translucency,
}

impl ChildKind {
    /// Every kind, in the order the wavefront traces its queues.
    pub const ALL: [ChildKind; 4] = [
        ChildKind::Reflection,
        ChildKind::Refraction,
        ChildKind::Glossy,
        ChildKind::Translucency,
    ];
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
        if Self::is_lit(m) {
            // The winding normal, not the one facing the ray: a checker surface on a
            // cell boundary shows the same cell from both sides.
            let outward = if si.front_face {
                si.n_geometric
            } else {
                -si.n_geometric
            };
            // Image textures multiply the colours at the hit's uv (`texture`).
            let (albedo, specular) = m.colours_on_surface(si.p, si.p_error, outward, si.uv);
            out.local += scene.ambient * albedo;
            self.direct(
                -d,
                time,
                si,
                albedo,
                specular,
                depth,
                &mut stream,
                pixel,
                path,
                out,
                rays,
                drawn,
            );
        }
        self.emit_children(
            d,
            time,
            si,
            depth,
            throughput,
            pixel,
            path,
            &mut stream,
            out,
            rays,
            drawn,
        );
    }

    /// Whether a material asks for direct light (and ambient): it has a diffuse,
    /// checkerboard or specular lobe.
    pub fn is_lit(m: &crate::scene::Material) -> bool {
        m.diffuse != Vec3::ZERO || m.checker.is_some() || m.specular != Vec3::ZERO
    }

    /// The mirror, glossy, glass and translucent child rays of the hit `si`, appended
    /// to `out.children`: the second half of [`Self::shade_emit`], also called by the
    /// lane-parallel shading stage after it has done the direct light. `stream` is the
    /// shading point's random stream as the direct light left it.
    #[allow(clippy::too_many_arguments)]
    pub fn emit_children(
        &self,
        d: Vec3,
        time: f32,
        si: &SurfaceInteraction,
        depth: u32,
        throughput: Vec3,
        pixel: u64,
        path: u64,
        stream: &mut Option<PixelRng>,
        out: &mut Emitted,
        rays: &mut RayCounts,
        drawn: &mut EffectSamplesDrawn,
    ) {
        let m = &self.scene.materials[si.material as usize];
        if depth >= self.max_depth {
            return;
        }
        // Every reflected and glossy direction leaves on the facing side (checked
        // below), so one origin serves them all. A material that spawns no child (the
        // bulk of most frames: diffuse and Phong) does not pay for it.
        if m.mirror == Vec3::ZERO && !m.is_glossy() && !m.is_transmissive() {
            return;
        }
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
                let n = self.lobe_points(depth, SobolDim::Glossy, stream, pixel, path, out, drawn);
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
                            stream,
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
        specular: Vec3,
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
            if specular != Vec3::ZERO {
                let h = (wi + wo).normalize_or_zero();
                f += specular * h.dot(si.n_shading).max(0.0).powf(m.shininess);
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
                    // What the samples share (the light's frame or cone as seen from
                    // the point, the point's two offset origins) once per point: the
                    // same bits as `Light::sample` and `spawn_ray_to` per sample.
                    if let Some(view) = light.view(si.p) {
                        let origins = OffsetOrigins::new(base, si.p_error, si.n_geometric);
                        for &(u, v) in &points {
                            let Some(s) = view.sample(si.p, u, v) else {
                                continue;
                            };
                            let Some(f) = reflectance(s.wi) else {
                                continue;
                            };
                            let ray = origins.spawn_ray_to(s.point, s.p_error, s.normal);
                            shadow(out, ray, s.weight * f / n as f32, index);
                        }
                    }
                    out.points = points;
                }
            }
        }
        // The environment (`integrator::environment`): `environment` directions, each a
        // shadow ray to infinity, in the shadow queue after the lights'.
        if let Some(env) = &self.scene.environment
            && self.plan.environment > 0
        {
            let n = self.plan.environment;
            let mut points = std::mem::take(&mut out.points);
            let set = HitSet {
                seed: self.seed,
                pixel,
                path,
                depth,
                dim: SobolDim::Environment,
            };
            hit_points(self.plan.sampler, set, n, stream, &mut points);
            drawn.environment += n as u64;
            let at = ShadowOrigin {
                base,
                p_error: si.p_error,
                n_geometric: si.n_geometric,
                n_shading: si.n_shading,
            };
            let index = self.scene.lights.len() as u32;
            environment_shadow_rays(env, &points, at, reflectance, |ray, c| {
                shadow(out, ray, c, index)
            });
            out.points = points;
        }
    }
}
