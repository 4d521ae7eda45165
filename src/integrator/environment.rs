//! Direct light from the environment at a lit shading point: `environment` directions
//! drawn from the environment's own distribution ([`Environment::sample`]: the map's
//! piecewise-constant 2D distribution, or cosine-weighted about the shading normal for
//! a constant sky), each with a shadow ray to infinity, weighted `L f / (pdf n)`.
//!
//! **No MIS.** Only the environment's distribution is sampled: the diffuse and
//! Blinn-Phong terms that the shading point's direct light covers are never also
//! reached by a BSDF-sampled ray that misses, since the renderer's mirror, glass and
//! glossy lobes are separate terms whose child rays see the environment as their miss
//! radiance (`Scene::miss_radiance`) and are not lit by shadow rays. Each term is
//! estimated by exactly one strategy, so nothing is counted twice. The price is
//! variance on sharp Blinn-Phong highlights under a large dim sky, which pbrt-v4
//! would cut with MIS against BSDF sampling.

use crate::geometry::{Ray, offset_ray_origin};
use crate::scene::Environment;
use glam::Vec3;

/// Where the environment's shadow rays leave from and along which normals.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ShadowOrigin {
    /// Base point of shadow rays (the hit point, or the terminator-lifted point).
    pub base: Vec3,
    pub p_error: Vec3,
    /// Facing geometric normal (offset direction).
    pub n_geometric: Vec3,
    /// Facing shading normal (what a constant sky is sampled about).
    pub n_shading: Vec3,
}

/// For each of `points` (in `[0, 1)²`), draws a direction towards `env`, evaluates the
/// surface's `reflectance` (BRDF times cosine; `None` below the surface) and emits a
/// shadow ray to infinity with the contribution it adds when unblocked, the mean over
/// the points of `L f / pdf`.
pub(crate) fn environment_shadow_rays(
    env: &Environment,
    points: &[(f32, f32)],
    at: ShadowOrigin,
    reflectance: impl Fn(Vec3) -> Option<Vec3>,
    mut emit: impl FnMut(Ray, Vec3),
) {
    let n = points.len() as f32;
    for &(u, v) in points {
        let Some(s) = env.sample(at.n_shading, u, v) else {
            continue;
        };
        let Some(f) = reflectance(s.wi) else {
            continue;
        };
        let contribution = s.radiance * f / (s.pdf * n);
        if contribution == Vec3::ZERO {
            continue;
        }
        let o = offset_ray_origin(at.base, at.p_error, at.n_geometric, s.wi);
        emit(Ray::new(o, s.wi), contribution);
    }
}
