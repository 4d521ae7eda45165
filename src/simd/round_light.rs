//! Disk and sphere lights over the lanes of a [`Packet`]: the light samples of one
//! shading point, sixteen at a time, as shadow rays with their unoccluded
//! contributions ([`disk_light`], [`sphere_light`]), the lane form of
//! `LightView::sample` and the scalar shader's area-light loop for the two round
//! lights (the quad's is [`super::direct_light::quad_light`]).
//!
//! Every lane repeats the scalar f32 operations in the scalar order, so the rays are
//! bit-identical and the contributions differ only by the lane power function
//! ([`super::direct_light::reflectance`]). The sines and cosines are libm's, called
//! lane by lane: the disk's concentric map and the sphere's azimuth are the scalar
//! functions' own calls, so the light points are the scalar ones bit for bit (a lane
//! polynomial, as the lens uses, would move them by up to `SIN_COS_MAX_ERROR` and
//! the wavefront's image off the recursive one's). They were 2.7 % of an area_lights
//! frame (perf, 1 thread), the arithmetic around them the rest of the 50 % that
//! `LightView::sample` and `Shader::shade_emit` took.

use super::Packet;
use super::direct_light::{
    FlatLight, Highlight, ShadowLanes, SurfaceLanes, reflectance, spawn_ray_to, towards_points,
};
use super::lanes3::V3;
use crate::geometry::gamma;
use crate::geometry::warp::concentric_disk;
use crate::scene::{LightView, SphereView};
use glam::Vec3;
use std::f32::consts::TAU;

/// A disk light's frame and constants, as `Light::view` computes them (they do not
/// depend on the shading point).
#[derive(Clone, Copy, Debug)]
pub struct DiskLight {
    pub center: Vec3,
    pub t: Vec3,
    pub b: Vec3,
    pub radius: f32,
    pub flat: FlatLight,
}

impl DiskLight {
    /// The disk of a view (`None` for another kind of light).
    pub fn of_view(view: &LightView) -> Option<DiskLight> {
        let LightView::Disk {
            center,
            n,
            t,
            b,
            radius,
            err,
            radiance,
        } = *view
        else {
            return None;
        };
        Some(DiskLight {
            center,
            t,
            b,
            radius,
            flat: FlatLight {
                normal: n,
                // `LightView::sample`'s `PI * radius * radius`.
                area: std::f32::consts::PI * radius * radius,
                radiance,
                p_error: err,
            },
        })
    }
}

/// libm's `(sin a[i], cos a[i])` per lane.
#[inline(always)]
fn sin_cos_per_lane(a: Packet) -> (Packet, Packet) {
    let (mut s, mut c) = ([0.0f32; 16], [0.0f32; 16]);
    for (i, x) in a.to_array().into_iter().enumerate() {
        (s[i], c[i]) = x.sin_cos();
    }
    (Packet::new(s), Packet::new(c))
}

/// Shadow rays from one shading point (splatted over the lanes of `s`) to the points
/// `(u, v)` of the disk light `disk`, lanes in `active`, each contribution divided by
/// `samples`: `LightView::sample`'s disk bit for bit (the concentric map per lane),
/// then [`towards_points`].
#[inline(always)]
pub fn disk_light(
    s: &SurfaceLanes,
    hl: &Highlight,
    disk: &DiskLight,
    u: Packet,
    v: Packet,
    samples: f32,
    active: u32,
) -> ShadowLanes {
    let (u, v) = (u.to_array(), v.to_array());
    let mut dx = [0.0f32; 16];
    let mut dy = [0.0f32; 16];
    for i in 0..16 {
        let d = concentric_disk(u[i], v[i]) * disk.radius;
        (dx[i], dy[i]) = (d.x, d.y);
    }
    // `center + d.x * t + d.y * b`.
    let point = V3::splat(disk.center)
        .plus(V3::splat(disk.t).scale(Packet::new(dx)))
        .plus(V3::splat(disk.b).scale(Packet::new(dy)));
    towards_points(s, hl, &disk.flat, point, samples, active)
}

/// Shadow rays from one shading point (splatted over the lanes of `s`, at `p`) to the
/// points `(u, v)` of the sphere light seen from there as `cone`, lanes in `active`,
/// each contribution divided by `samples`: `SphereView::sample` bit for bit (a
/// direction in the cone, its nearer root on the sphere, reprojected by
/// `sphere_point`), then the reflectance and the segment of the scalar loop.
#[inline(always)]
pub fn sphere_light(
    s: &SurfaceLanes,
    hl: &Highlight,
    cone: &SphereView,
    u: Packet,
    v: Packet,
    samples: f32,
    active: u32,
) -> ShadowLanes {
    let (zero, one) = (Packet::splat(0.0), Packet::splat(1.0));
    let cos = one - u * Packet::splat(cone.one_minus);
    // `f32::max(x, 0.0)`: zero for a NaN `x` too.
    let sin2 = one - cos * cos;
    let sin = sin2.simd_gt(zero).select(sin2, zero).sqrt();
    let phi = Packet::splat(TAU) * v;
    let (sin_phi, cos_phi) = sin_cos_per_lane(phi);
    // `sin * phi.cos() * t + sin * phi.sin() * b + cos * axis`, normalised as glam's
    // `normalize`: times `1 / length`.
    let w = V3::splat(cone.t)
        .scale(sin * cos_phi)
        .plus(V3::splat(cone.b).scale(sin * sin_phi))
        .plus(V3::splat(cone.axis).scale(cos));
    let wi = w.scale(one / w.dot(w).sqrt());
    // The nearer root of |p + s wi - c| = r (at grazing directions the closest
    // approach).
    let proj = wi.dot(V3::splat(cone.to_c));
    let r = Packet::splat(cone.radius);
    let disc = r * r - (Packet::splat(cone.dc2) - proj * proj);
    let dist = proj - disc.simd_gt(zero).select(disc, zero).sqrt();
    let near = s.p.plus(wi.scale(dist));
    // `sphere_point`: the point reprojected onto the sphere and its error bound.
    let center = V3::splat(cone.center);
    let normal = near.minus(center).normalize_or_zero();
    let local = normal.scale(r);
    let point = center.plus(local);
    let p_error = local
        .abs()
        .scale(Packet::splat(gamma(5)))
        .plus(point.abs().scale(Packet::splat(gamma(2))));
    let (lit, f) = reflectance(s, hl, wi);
    let contribution = V3::splat(cone.weight).times(f).over(Packet::splat(samples));
    let (origin, dir, tmax) = spawn_ray_to(s.base, s.p_error, s.ng, point, p_error, normal);
    ShadowLanes {
        origin,
        dir,
        tmax,
        contribution,
        mask: lit.to_bitmask() & active,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Ray, spawn_ray_to as scalar_spawn_ray_to};
    use crate::scene::Light;
    use crate::test_rng::xorshift64;
    use std::f32::consts::FRAC_1_PI;

    fn bits(v: Vec3) -> [u32; 3] {
        v.to_array().map(f32::to_bits)
    }

    /// Each lane of [`disk_light`] and [`sphere_light`] against `Light::sample` and
    /// `spawn_ray_to` per sample (the scalar shader's loop) for a Lambert surface
    /// (no power, so every value is compared bit for bit): shading points all around
    /// the lights, from far away to a hair off the sphere, with normals that face the
    /// light, graze it or turn away; 16 samples each from `(0, 1)`, their ends and 0.
    #[test]
    fn round_light_lanes_are_the_scalar_samples_bit_for_bit() {
        let lights = [
            Light::Disk {
                center: Vec3::new(-1.0, 3.2, 0.2),
                normal: Vec3::new(0.1, -1.0, 0.05),
                radius: 0.6,
                radiance: Vec3::new(5.0, 4.5, 4.0),
            },
            Light::Sphere {
                center: Vec3::new(2.5, 2.8, 1.0),
                radius: 0.3,
                radiance: Vec3::new(25.0, 25.0, 30.0),
            },
        ];
        let mut next = xorshift64(0x9e37_79b9_7f4a_7c15);
        // Uniform in [0, 1): the top 24 bits.
        let mut f = move || (next() >> 40) as f32 / (1u64 << 24) as f32;
        let (mut compared, mut lit) = (0, 0);
        for round in 0..400 {
            for light in &lights {
                // Points from the light's surface out to 1e4 away, in every direction.
                let dir = Vec3::new(f() - 0.5, f() - 0.5, f() - 0.5).normalize_or(Vec3::Y);
                let reach = [0.3001, 0.31, 1.0, 5.0, 1e4][round % 5];
                let centre = match light {
                    Light::Disk { center, .. } | Light::Sphere { center, .. } => *center,
                    _ => unreachable!(),
                };
                let p = centre + dir * reach;
                let ng = (Vec3::new(f(), f(), f()) - 0.5).normalize_or(Vec3::Z);
                let p_error = p.abs() * 1e-6;
                let albedo = Vec3::new(0.8, 0.5, 0.2);
                let s = SurfaceLanes::splat_point(p, p_error, ng, albedo);
                let hl = Highlight {
                    specular: Vec3::ZERO,
                    shininess: 1.0,
                };
                let mut u = [0.0f32; 16];
                let mut v = [0.0f32; 16];
                for i in 0..16 {
                    (u[i], v[i]) = (f(), f());
                }
                (u[0], v[0], u[1], v[1]) = (0.0, 0.0, 1.0 - f32::EPSILON / 2.0, 0.5);
                let samples = 16.0;
                let view = light.view(p).expect("every point is outside the sphere");
                let (pu, pv) = (Packet::new(u), Packet::new(v));
                let sl = match (DiskLight::of_view(&view), view) {
                    (Some(d), _) => disk_light(&s, &hl, &d, pu, pv, samples, 0xffff),
                    (None, LightView::Sphere(cone)) => {
                        sphere_light(&s, &hl, &cone, pu, pv, samples, 0xffff)
                    }
                    _ => unreachable!("a disk or a sphere"),
                };
                for i in 0..16 {
                    // The scalar shader's loop for one sample.
                    let scalar = light.sample(p, u[i], v[i]).and_then(|ls| {
                        let cos_s = ls.wi.dot(ng);
                        (cos_s > 0.0 && ls.wi.dot(ng) > 0.0).then(|| {
                            let f = albedo * (FRAC_1_PI * cos_s);
                            let ray = scalar_spawn_ray_to(
                                p, p_error, ng, ls.point, ls.p_error, ls.normal,
                            );
                            (ray, ls.weight * f / samples)
                        })
                    });
                    let set = sl.mask >> i & 1 == 1;
                    assert_eq!(
                        set,
                        scalar.is_some(),
                        "round {round} lane {i}: {light:?} from {p}"
                    );
                    compared += 1;
                    if let Some((ray, c)) = scalar {
                        lit += 1;
                        let lane = Ray::segment(
                            sl.origin.lane(i),
                            sl.dir.lane(i),
                            0.0,
                            sl.tmax.to_array()[i],
                        );
                        assert_eq!(
                            bits(lane.origin),
                            bits(ray.origin),
                            "round {round} lane {i}"
                        );
                        assert_eq!(bits(lane.dir), bits(ray.dir), "round {round} lane {i}");
                        assert_eq!(
                            lane.tmax.to_bits(),
                            ray.tmax.to_bits(),
                            "round {round} lane {i}"
                        );
                        assert_eq!(
                            bits(sl.contribution.lane(i)),
                            bits(c),
                            "round {round} lane {i}"
                        );
                    }
                }
            }
        }
        eprintln!("{compared} samples compared, {lit} lit");
        assert!(
            lit > 4_000 && compared - lit > 4_000,
            "{lit} lit of {compared}"
        );
    }
}
