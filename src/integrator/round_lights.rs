//! The disk and sphere lights of one shading point in lanes ([`shade_round`]): the
//! wavefront's shading stage draws a point's light points into lanes, builds their
//! shadow rays sixteen at a time (`simd::round_light`) and queues them for the
//! area-shadow stage, as [`shade_quads`](super::area_light::shade_quads) does for
//! quads without tiny occluders.
//!
//! Why: before, a scene with a disk or a sphere light (area_lights.toml) left the lane
//! path altogether, and every hit went through the scalar `Shader::shade_emit`, one
//! light sample at a time: `LightView::sample` 24 % and `shade_emit` 23 % of the
//! wavefront's area_lights frame at 1 sample per pixel (perf, 320x200, 1 thread), the
//! same work as the recursive integrator's, so the wavefront was barely ahead of it
//! (render 60-65 ms against 52-77 ms at 128x96, loaded host).
//!
//! Exactness: the light points, the rays, their order and the counts are the scalar
//! shader's; the contributions differ by the lane power function only (the shading
//! stage's test compares them on area_lights.toml).

use super::area_light::{LightPoints, ShadingPoint};
use super::shade_stage::{LanePaths, Sinks, push_shadow};
use super::shader::Shader;
use crate::scene::{Light, LightView, SphereView};
use crate::simd::lanes3::V3;
use crate::simd::round_light::{DiskLight, disk_light, sphere_light};
use glam::Vec3;

/// A round light in lane form.
#[derive(Clone, Copy, Debug)]
pub(crate) enum RoundLight {
    /// A disk's frame does not depend on the shading point: computed once.
    Disk(DiskLight),
    /// A sphere's cone does: its `Light`, viewed per point.
    Sphere(Light),
}

impl RoundLight {
    /// The lane form of a disk or sphere light; `None` for any other kind.
    pub fn of(light: &Light) -> Option<RoundLight> {
        match light {
            Light::Disk { .. } => light
                .view(Vec3::ZERO)
                .as_ref()
                .and_then(DiskLight::of_view)
                .map(RoundLight::Disk),
            Light::Sphere { .. } => Some(RoundLight::Sphere(*light)),
            _ => None,
        }
    }
}

/// A round light as seen from one shading point.
enum Seen<'a> {
    Disk(&'a DiskLight),
    Sphere(SphereView),
}

/// The direct light of every round light at the shading point `h`: `shadow` samples
/// per light (the sample plan's), drawn into lanes from the point's stream (`stream`,
/// created on first use, shared with the point's later draws), queued as shadow rays
/// into `sinks.shadow` in sample order.
pub(crate) fn shade_round(
    shader: &Shader,
    lights: &[(u32, RoundLight)],
    h: &ShadingPoint,
    stream: &mut Option<crate::integrator::sampling::PixelRng>,
    sinks: &mut Sinks,
    points: &mut LightPoints,
) {
    let s = h.lanes();
    let p = h.batch.p.get(h.k);
    let plan = &shader.plan;
    let samples = plan.shadow;
    let paths = LanePaths::splat(h.slot, h.weight, h.time);
    let lane_weight = V3::splat(h.weight);
    for &(index, light) in lights {
        // The points are drawn whether or not the light is seen, as the scalar
        // shader draws them.
        h.draw_light_points(shader, index, stream, points, sinks);
        // A point inside a sphere light sees none of it.
        let seen = match &light {
            RoundLight::Disk(d) => Seen::Disk(d),
            RoundLight::Sphere(l) => match l.view(p) {
                Some(LightView::Sphere(cone)) => Seen::Sphere(cone),
                _ => continue,
            },
        };
        for c in (0..samples as usize).step_by(16) {
            let (u, v, active) = points.group(c, samples);
            let n = samples as f32;
            let sl = match &seen {
                Seen::Disk(d) => disk_light(&s, &h.hl, d, u, v, n, active),
                Seen::Sphere(cone) => sphere_light(&s, &h.hl, cone, u, v, n, active),
            };
            push_shadow(
                &mut sinks.shadow[index as usize],
                &sl,
                &paths,
                lane_weight,
                &mut sinks.rays,
            );
        }
    }
}
