use crate::geometry::warp::concentric_disk;
use crate::geometry::{gamma, sphere_point};
use glam::Vec3;
use std::f32::consts::{PI, TAU};

/// Lights. A point or directional light is sampled with exactly one shadow ray (the
/// Whitted model); an area light (quad, disk, sphere) with `shadow` stratified samples
/// per shading point, which gives soft shadows (Cook, Porter, Carpenter 1984).
///
/// Area lights emit radiance `radiance` from one side (quad: along `edge1 × edge2`;
/// disk: along `normal`) or outwards (sphere). [`SceneBuilder::add_light`](crate::scene::SceneBuilder::add_light)
/// (super::SceneBuilder::add_light) also adds matching emissive geometry, so camera and
/// reflection rays see the light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Light {
    /// Radiant intensity `intensity` (per colour channel); irradiance falls off as 1/r².
    Point { position: Vec3, intensity: Vec3 },
    /// A point light restricted to a cone (pbrt-v4's `SpotLight`, Pharr, Jakob and
    /// Humphreys, PBRT 4th ed., sec. 12.2.1): intensity `intensity` along the unit
    /// `direction`, scaled by [`Light::spot_falloff`]: 1 inside `cos_falloff_start`,
    /// 0 outside `cos_total`, a smoothstep in cos θ between them.
    Spot {
        position: Vec3,
        direction: Vec3,
        intensity: Vec3,
        /// Cosine of the cone's half-angle (no light beyond it).
        cos_total: f32,
        /// Cosine of the half-angle where the falloff starts (full intensity within).
        cos_falloff_start: f32,
    },
    /// Light arriving along `direction` (pointing from the light into the scene) with
    /// irradiance `irradiance` on a surface facing it.
    Directional { direction: Vec3, irradiance: Vec3 },
    /// The parallelogram `corner + u edge1 + v edge2`, `u, v ∈ [0, 1]`.
    Quad {
        corner: Vec3,
        edge1: Vec3,
        edge2: Vec3,
        radiance: Vec3,
    },
    Disk {
        center: Vec3,
        normal: Vec3,
        radius: f32,
        radiance: Vec3,
    },
    Sphere {
        center: Vec3,
        radius: f32,
        radiance: Vec3,
    },
}

/// One sampled point on an area light as seen from a shading point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightSample {
    /// Unit direction from the shading point towards the light point.
    pub wi: Vec3,
    /// Distance to the light point.
    pub dist: f32,
    /// Radiance over the sampling density in solid angle: the estimate of the
    /// irradiance-like factor `∫ L dω` that multiplies `f · cosθ` (the same role as
    /// `intensity / r²` for a point light).
    pub weight: Vec3,
    /// The sampled point on the light.
    pub point: Vec3,
    /// Per-component bound on the distance of `point` from the light's emissive
    /// geometry, so that a shadow segment ending there can be ended short of it
    /// ([`spawn_ray_to`](crate::geometry::spawn_ray_to)).
    pub p_error: Vec3,
    /// Unit normal of the light at `point`, on its emitting side.
    pub normal: Vec3,
}

/// An area light as seen from one shading point ([`Light::view`]): what its samples
/// there share. [`LightView::sample`] with the view's point gives the bits of
/// [`Light::sample`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LightView {
    Quad {
        corner: Vec3,
        edge1: Vec3,
        edge2: Vec3,
        n: Vec3,
        area: f32,
        err: Vec3,
        radiance: Vec3,
    },
    Disk {
        center: Vec3,
        n: Vec3,
        t: Vec3,
        b: Vec3,
        radius: f32,
        err: Vec3,
        radiance: Vec3,
    },
    Sphere(SphereView),
}

impl LightView {
    /// The sample of the view's light at `(u, v)` seen from `p`, the point the view
    /// was made for (see [`Light::sample`]).
    pub fn sample(&self, p: Vec3, u: f32, v: f32) -> Option<LightSample> {
        let towards = |point: Vec3, n: Vec3, area: f32, radiance: Vec3, p_error: Vec3| {
            let to = point - p;
            let dist2 = to.length_squared();
            let dist = dist2.sqrt();
            let wi = to / dist;
            let cos_l = -wi.dot(n);
            (cos_l > 0.0 && dist > 0.0).then(|| LightSample {
                wi,
                dist,
                weight: radiance * (cos_l * area / dist2),
                point,
                p_error,
                normal: n,
            })
        };
        match *self {
            LightView::Quad {
                corner,
                edge1,
                edge2,
                n,
                area,
                err,
                radiance,
            } => towards(corner + u * edge1 + v * edge2, n, area, radiance, err),
            LightView::Disk {
                center,
                n,
                t,
                b,
                radius,
                err,
                radiance,
            } => {
                let d = concentric_disk(u, v) * radius;
                towards(
                    center + d.x * t + d.y * b,
                    n,
                    PI * radius * radius,
                    radiance,
                    err,
                )
            }
            LightView::Sphere(c) => c.sample(p, u, v),
        }
    }
}

/// A sphere light as seen from a point outside it: the cone it subtends.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SphereView {
    pub(crate) center: Vec3,
    pub(crate) radius: f32,
    /// From the point to the centre, its squared length, and its direction.
    pub(crate) to_c: Vec3,
    pub(crate) dc2: f32,
    pub(crate) axis: Vec3,
    /// `1 - cos θmax` of the cone, and a basis around its axis.
    pub(crate) one_minus: f32,
    pub(crate) t: Vec3,
    pub(crate) b: Vec3,
    /// Radiance over the cone's density in solid angle.
    pub(crate) weight: Vec3,
}

impl SphereView {
    fn sample(&self, p: Vec3, u: f32, v: f32) -> Option<LightSample> {
        let (to_c, radius) = (self.to_c, self.radius);
        let cos = 1.0 - u * self.one_minus;
        let sin = (1.0 - cos * cos).max(0.0).sqrt();
        let phi = TAU * v;
        let wi =
            (sin * phi.cos() * self.t + sin * phi.sin() * self.b + cos * self.axis).normalize();
        // Nearer root of |p + s wi - c| = r; at grazing directions the
        // discriminant may round below zero: use the closest approach.
        let proj = wi.dot(to_c);
        let disc = radius * radius - (self.dc2 - proj * proj);
        let dist = proj - disc.max(0.0).sqrt();
        let (point, p_error, normal) = sphere_point(self.center, radius, p + dist * wi);
        Some(LightSample {
            wi,
            dist,
            weight: self.weight,
            point,
            p_error,
            normal,
        })
    }
}

impl Light {
    pub fn is_area(&self) -> bool {
        matches!(
            self,
            Light::Quad { .. } | Light::Disk { .. } | Light::Sphere { .. }
        )
    }

    /// Samples a point of an area light seen from `p` with the uniform numbers `(u,
    /// v)`; `None` for a point the light does not emit towards (its back, or `p` inside
    /// a sphere light), which contributes zero and needs no shadow ray. Quads and disks
    /// are sampled uniformly by area (pdf `1/A`, converted to solid angle by
    /// `cosθ' / r²`); spheres uniformly inside the cone they subtend (pdf
    /// `1 / (2π (1 - cosθmax))`), so no sample is wasted on the far side.
    ///
    /// `p_error` of a quad or disk sample: `γ(32)` times the magnitudes that form the
    /// point and the corners of the emissive triangles (corner and edges; centre and
    /// radius times the basis). The point itself rounds within `γ(3)` of the light's
    /// plane and the corners within `γ(4)`; the rest covers the triangle test's error on
    /// corners up to the light's size away from the point, which `spawn_ray_to`'s
    /// margin (proportional to the segment length) does not see. A sphere sample is
    /// reprojected onto the sphere ([`sphere_point`](crate::geometry::sphere_point)).
    pub fn sample(&self, p: Vec3, u: f32, v: f32) -> Option<LightSample> {
        self.view(p)?.sample(p, u, v)
    }

    /// The part of [`Light::sample`] that depends on the light and the shading point
    /// only, computed once for all of a point's samples (a disk's frame, a sphere's
    /// cone). `None` for a light that is not an area light, and for a point inside a
    /// sphere light.
    pub fn view(&self, p: Vec3) -> Option<LightView> {
        match *self {
            Light::Point { .. } | Light::Directional { .. } | Light::Spot { .. } => None,
            Light::Quad {
                corner,
                edge1,
                edge2,
                radiance,
            } => {
                let c = edge1.cross(edge2);
                let area = c.length();
                Some(LightView::Quad {
                    corner,
                    edge1,
                    edge2,
                    n: c / area,
                    area,
                    err: gamma(32) * (corner.abs() + edge1.abs() + edge2.abs()),
                    radiance,
                })
            }
            Light::Disk {
                center,
                normal,
                radius,
                radiance,
            } => {
                let n = normal.normalize();
                let (t, b) = crate::geometry::orthonormal_basis(n);
                Some(LightView::Disk {
                    center,
                    n,
                    t,
                    b,
                    radius,
                    err: gamma(32) * (center.abs() + radius * (t.abs() + b.abs())),
                    radiance,
                })
            }
            Light::Sphere {
                center,
                radius,
                radiance,
            } => {
                let to_c = center - p;
                let dc2 = to_c.length_squared();
                if dc2 <= radius * radius {
                    return None;
                }
                let dc = dc2.sqrt();
                let axis = to_c / dc;
                let sin2_max = radius * radius / dc2;
                let cos_max = (1.0 - sin2_max).max(0.0).sqrt();
                // 1 - cosθmax without cancellation for small, distant spheres.
                let one_minus = sin2_max / (1.0 + cos_max);
                let (t, b) = crate::geometry::orthonormal_basis(axis);
                Some(LightView::Sphere(SphereView {
                    center,
                    radius,
                    to_c,
                    dc2,
                    axis,
                    one_minus,
                    t,
                    b,
                    weight: radiance * (TAU * one_minus),
                }))
            }
        }
    }

    /// The spot light's falloff for `cos_theta`, the cosine of the angle between the
    /// spot's axis and the direction from the light to the shaded point: pbrt-v4's
    /// `SmoothStep(cos_theta, cos_total, cos_falloff_start)`, `t² (3 - 2t)` of the
    /// clamped `t = (cos_theta - cos_total) / (cos_falloff_start - cos_total)`; a hard
    /// edge (0 or 1) when the two cosines are equal.
    pub fn spot_falloff(cos_theta: f32, cos_total: f32, cos_falloff_start: f32) -> f32 {
        if cos_theta < cos_total {
            return 0.0;
        }
        if cos_theta >= cos_falloff_start {
            return 1.0;
        }
        let t = ((cos_theta - cos_total) / (cos_falloff_start - cos_total)).clamp(0.0, 1.0);
        t * t * (3.0 - 2.0 * t)
    }

    pub fn validate(&self) -> Result<(), String> {
        let colour_ok = |c: Vec3| c.is_finite() && c.min_element() >= 0.0;
        match *self {
            Light::Spot {
                position,
                direction,
                intensity,
                cos_total,
                cos_falloff_start,
            } => {
                if !position.is_finite() || !colour_ok(intensity) {
                    return Err(
                        "spot light needs a finite position and a finite, non-negative intensity"
                            .into(),
                    );
                }
                if !direction.is_finite() || (direction.length() - 1.0).abs() > 1e-4 {
                    return Err("spot light needs a finite unit direction".into());
                }
                if !(cos_total.is_finite()
                    && cos_falloff_start.is_finite()
                    && (-1.0..=1.0).contains(&cos_total)
                    && cos_total <= cos_falloff_start
                    && cos_falloff_start <= 1.0)
                {
                    return Err(format!(
                        "spot light needs -1 <= cos_total <= cos_falloff_start <= 1, got {cos_total}, {cos_falloff_start}"
                    ));
                }
            }
            Light::Point {
                position,
                intensity,
            } => {
                if !position.is_finite() || !colour_ok(intensity) {
                    return Err(
                        "point light needs a finite position and a finite, non-negative intensity"
                            .into(),
                    );
                }
            }
            Light::Directional {
                direction,
                irradiance,
            } => {
                if !direction.is_finite() || direction.length_squared() == 0.0 {
                    return Err("directional light needs a finite, non-zero direction".into());
                }
                if !colour_ok(irradiance) {
                    return Err("directional light needs a finite, non-negative irradiance".into());
                }
            }
            Light::Quad {
                corner,
                edge1,
                edge2,
                radiance,
            } => {
                if !(corner.is_finite() && edge1.is_finite() && edge2.is_finite())
                    || edge1.cross(edge2).length_squared() <= 0.0
                    || !colour_ok(radiance)
                {
                    return Err("quad light needs a finite corner, two independent finite edges and a finite, non-negative radiance".into());
                }
            }
            Light::Disk {
                center,
                normal,
                radius,
                radiance,
            } => {
                if !(center.is_finite()
                    && normal.is_finite()
                    && normal.length_squared() > 0.0
                    && radius.is_finite()
                    && radius > 0.0
                    && colour_ok(radiance))
                {
                    return Err("disk light needs a finite centre, a non-zero normal, a radius > 0 and a finite, non-negative radiance".into());
                }
            }
            Light::Sphere {
                center,
                radius,
                radiance,
            } => {
                if !(center.is_finite()
                    && radius.is_finite()
                    && radius > 0.0
                    && colour_ok(radiance))
                {
                    return Err("sphere light needs a finite centre, a radius > 0 and a finite, non-negative radiance".into());
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Irradiance at the centre below a light, estimated by sampling, against the
    /// closed forms: a disk of radius R at height h gives `π L R² / (h² + R²)`; a sphere
    /// of radius R at distance d gives `π L (R/d)²` on a facing surface.
    #[test]
    fn spot_falloff_is_pbrt_v4_smoothstep() {
        let (total, start) = (30f32.to_radians().cos(), 20f32.to_radians().cos());
        assert_eq!(Light::spot_falloff(1.0, total, start), 1.0);
        assert_eq!(Light::spot_falloff(start, total, start), 1.0);
        assert_eq!(Light::spot_falloff(total - 1e-6, total, start), 0.0);
        // midpoint in cos θ: smoothstep(0.5) = 0.5 (2e-6: f32 rounding of t near 0.5)
        let mid = 0.5 * (total + start);
        assert!((Light::spot_falloff(mid, total, start) - 0.5).abs() < 2e-6);
        // monotone between the edges
        let mut last = 0.0;
        for i in 0..=100 {
            let c = total + (start - total) * i as f32 / 100.0;
            let f = Light::spot_falloff(c, total, start);
            assert!(f >= last, "{c}: {f} < {last}");
            last = f;
        }
        // hard edge
        assert_eq!(Light::spot_falloff(start, start, start), 1.0);
        assert_eq!(Light::spot_falloff(start - 1e-6, start, start), 0.0);
    }

    #[test]
    fn area_light_sampling_integrates_irradiance() {
        let p = Vec3::ZERO;
        let n = Vec3::Y;
        let estimate = |l: &Light| {
            let k = 256;
            let mut sum = 0.0f64;
            for j in 0..k {
                for i in 0..k {
                    let (u, v) = ((i as f32 + 0.5) / k as f32, (j as f32 + 0.5) / k as f32);
                    if let Some(s) = l.sample(p, u, v) {
                        sum += (s.weight.x * s.wi.dot(n).max(0.0)) as f64;
                    }
                }
            }
            sum / (k * k) as f64
        };
        let (h, r) = (2.0f32, 1.0f32);
        let disk = Light::Disk {
            center: Vec3::new(0.0, h, 0.0),
            normal: -Vec3::Y,
            radius: r,
            radiance: Vec3::ONE,
        };
        let expect = (PI * r * r / (h * h + r * r)) as f64;
        assert!((estimate(&disk) / expect - 1.0).abs() < 2e-3);
        // Seen from behind, a disk emits nothing.
        let back = Light::Disk {
            center: Vec3::new(0.0, h, 0.0),
            normal: Vec3::Y,
            radius: r,
            radiance: Vec3::ONE,
        };
        assert_eq!(estimate(&back), 0.0);
        let quad = Light::Quad {
            corner: Vec3::new(-1.0, h, -1.0),
            edge1: Vec3::new(2.0, 0.0, 0.0),
            edge2: Vec3::new(0.0, 0.0, 2.0),
            radiance: Vec3::ONE,
        };
        // Facing down needs edge1 x edge2 = -y: (2,0,0) x (0,0,2) = (0,-4,0). A square
        // of half-side a at height h: E = 4 L (a/√(a²+h²)) atan(a/√(a²+h²)).
        let (a, hh) = (1.0f64, h as f64);
        let s = a / (a * a + hh * hh).sqrt();
        let expect_quad = 4.0 * s * s.atan();
        assert!((estimate(&quad) / expect_quad - 1.0).abs() < 2e-3);
        let d = 5.0;
        let sphere = Light::Sphere {
            center: Vec3::new(0.0, d, 0.0),
            radius: r,
            radiance: Vec3::ONE,
        };
        let expect = (PI * (r / d).powi(2)) as f64;
        assert!((estimate(&sphere) / expect - 1.0).abs() < 2e-3);
    }
}
