//! The environment: radiance arriving from infinitely far away in every direction, a
//! constant sky or an equirectangular (latitude-longitude) map, seen by rays that
//! miss the scene and lighting it through shadow rays to infinity.
//!
//! **Map convention.** In the map's own frame (+Y up), a unit direction
//! `(sin θ cos φ, cos θ, sin θ sin φ)` with polar angle `θ` in `[0, π]` from +Y and
//! azimuth `φ = atan2(z, x)` in `[0, 2π)` has map coordinates `u = φ / 2π`,
//! `v = θ / π`: column `⌊u · width⌋`, row `⌊v · height⌋` (row 0, the top of the image, is
//! the zenith; `u = 0` is +X and `u` grows towards +Z). The map's frame is turned into
//! the world by `up` (the world direction of the map's zenith) and `rotate_y` (degrees
//! about the map's up axis, right-handed). Lookups are nearest-texel, so the radiance
//! is piecewise constant over texels: exactly what the piecewise-constant sampling
//! distribution below assumes, so the estimator's weights are exact.
//!
//! **Importance sampling** (pbrt-v3 §14.2.4 `InfiniteAreaLight`; pbrt-v4's
//! `ImageInfiniteLight` builds the same `PiecewiseConstant2D`, over an equal-area
//! parametrisation instead): a 2D distribution over `(u, v)` proportional to each
//! texel's mean channel times `sin θ` at its row centre (the lat-long map squeezes rows
//! towards the poles), sampled through the marginal CDF over rows and each row's
//! conditional CDF over columns. The solid-angle density of a direction is
//! `p(u, v) / (2π² sin θ)` (the Jacobian of `(u, v) → ω`). A texel with any non-zero
//! channel has non-zero weight, so no light is left unsampled. A constant sky is
//! sampled cosine-weighted about the shading normal instead (density `cos θ / π`),
//! which makes a Lambertian surface's estimate exact wherever the sky is unblocked.

use crate::error::{Error, Result};
use crate::geometry::piecewise::PiecewiseConstant2D;
use crate::geometry::warp::sample_phong_lobe;
use glam::{Mat3, Quat, Vec3};
use std::f32::consts::{PI, TAU};

/// Largest map side accepted (a 16k x 8k map is 1.5 GiB of f32 texels already).
pub const MAX_MAP_SIDE: usize = 16_384;

/// The radiance of the environment in every direction, and how to sample it.
#[derive(Clone, Debug, PartialEq)]
pub struct Environment {
    source: Source,
    /// Multiplies every radiance value (`scale` in TOML).
    scale: f32,
    /// Map frame to world and back; `None` when the map frame is the world's (the
    /// default), so that the default lookups involve no rotation at all.
    frame: Option<(Mat3, Mat3)>,
}

#[derive(Clone, Debug, PartialEq)]
enum Source {
    Constant(Vec3),
    Map(LatLongMap),
}

/// An equirectangular map and its sampling distribution.
#[derive(Clone, Debug, PartialEq)]
struct LatLongMap {
    width: usize,
    height: usize,
    /// Row-major, row 0 at the zenith.
    texels: Vec<Vec3>,
    /// `None` when every texel is black (nothing to sample).
    distribution: Option<PiecewiseConstant2D>,
}

/// A direction drawn towards the environment.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EnvironmentSample {
    /// Unit world direction towards the sky.
    pub wi: Vec3,
    /// Radiance arriving from `wi` (scale included).
    pub radiance: Vec3,
    /// Solid-angle density of `wi` under the sampling strategy, > 0.
    pub pdf: f32,
}

impl Environment {
    /// The same radiance `color` from every direction.
    pub fn constant(color: Vec3) -> Result<Self> {
        if !(color.is_finite() && color.min_element() >= 0.0) {
            return Err(Error::parameter(
                "environment",
                format!("`color` must be finite and non-negative, got {color}"),
            ));
        }
        Ok(Environment {
            source: Source::Constant(color),
            scale: 1.0,
            frame: None,
        })
    }

    /// An equirectangular map of `width x height` texels, row-major from the zenith
    /// row. Every texel must be finite and non-negative; `what` names the map (its file)
    /// in errors.
    pub fn map(width: usize, height: usize, texels: Vec<Vec3>, what: &str) -> Result<Self> {
        let bad = |m: String| Err(Error::parameter("environment map", format!("{what}: {m}")));
        if width == 0 || height == 0 || width > MAX_MAP_SIDE || height > MAX_MAP_SIDE {
            return bad(format!(
                "{width}x{height} texels: each side must be between 1 and {MAX_MAP_SIDE}"
            ));
        }
        if texels.len() != width * height {
            return bad(format!(
                "{} texels for a {width}x{height} map",
                texels.len()
            ));
        }
        if let Some(i) = texels
            .iter()
            .position(|t| !(t.is_finite() && t.min_element() >= 0.0))
        {
            return bad(format!(
                "texel at column {}, row {} is {}: radiance must be finite and non-negative",
                i % width,
                i / width,
                texels[i]
            ));
        }
        // pbrt-v3 §14.2.4: weight each texel by sin θ at its row centre.
        let mut func = Vec::with_capacity(texels.len());
        for row in 0..height {
            let sin_theta = (PI * (row as f32 + 0.5) / height as f32).sin() as f64;
            for t in &texels[row * width..(row + 1) * width] {
                func.push((t.x as f64 + t.y as f64 + t.z as f64) / 3.0 * sin_theta);
            }
        }
        let distribution = PiecewiseConstant2D::new(&func, width, height);
        let distribution = (distribution.integral() > 0.0).then_some(distribution);
        Ok(Environment {
            source: Source::Map(LatLongMap {
                width,
                height,
                texels,
                distribution,
            }),
            scale: 1.0,
            frame: None,
        })
    }

    /// Multiplies all radiance by `scale` (finite, >= 0).
    pub fn with_scale(mut self, scale: f32) -> Result<Self> {
        if !(scale.is_finite() && scale >= 0.0) {
            return Err(Error::parameter(
                "environment",
                format!("`scale` must be finite and >= 0, got {scale}"),
            ));
        }
        self.scale = scale;
        Ok(self)
    }

    /// Orients the map: its zenith along the world direction `up` (non-zero), turned by
    /// `rotate_y_deg` degrees about that axis. `up = +Y, rotate_y = 0` is the identity.
    pub fn with_frame(mut self, up: Vec3, rotate_y_deg: f32) -> Result<Self> {
        if !(up.is_finite() && up.length_squared() > 1e-20 && rotate_y_deg.is_finite()) {
            return Err(Error::parameter(
                "environment",
                format!(
                    "`up` must be a finite non-zero vector and `rotate_y` finite, got {up} and {rotate_y_deg}"
                ),
            ));
        }
        let up = up.normalize();
        if up == Vec3::Y && rotate_y_deg == 0.0 {
            self.frame = None;
            return Ok(self);
        }
        let to_world = Mat3::from_quat(Quat::from_rotation_arc(Vec3::Y, up))
            * Mat3::from_rotation_y(rotate_y_deg.to_radians());
        self.frame = Some((to_world, to_world.transpose()));
        Ok(self)
    }

    /// The size of the map in texels; `None` for a constant sky.
    pub fn map_size(&self) -> Option<(usize, usize)> {
        match &self.source {
            Source::Constant(_) => None,
            Source::Map(m) => Some((m.width, m.height)),
        }
    }

    /// True when no direction carries light (nothing to sample or show).
    pub fn is_black(&self) -> bool {
        self.scale == 0.0
            || match &self.source {
                Source::Constant(c) => *c == Vec3::ZERO,
                Source::Map(m) => m.distribution.is_none(),
            }
    }

    fn to_map(&self, d: Vec3) -> Vec3 {
        match &self.frame {
            Some((_, to_map)) => *to_map * d,
            None => d,
        }
    }

    fn to_world(&self, d: Vec3) -> Vec3 {
        match &self.frame {
            Some((to_world, _)) => *to_world * d,
            None => d,
        }
    }

    /// The texel `(column, row)` a world direction `d` (any length > 0) looks up in a
    /// map `width x height` texels (see the module's convention); `None` for a constant
    /// sky.
    pub fn texel(&self, d: Vec3) -> Option<(usize, usize)> {
        let Source::Map(m) = &self.source else {
            return None;
        };
        let (u, v) = direction_to_uv(self.to_map(d).normalize());
        Some((
            ((u * m.width as f32) as usize).min(m.width - 1),
            ((v * m.height as f32) as usize).min(m.height - 1),
        ))
    }

    /// Radiance arriving from world direction `d` (travelling along `-d`).
    pub fn radiance(&self, d: Vec3) -> Vec3 {
        match &self.source {
            Source::Constant(c) => *c * self.scale,
            Source::Map(m) => {
                let (c, r) = self.texel(d).expect("a map has texels");
                m.texels[r * m.width + c] * self.scale
            }
        }
    }

    /// Draws a direction for a shading point with unit shading normal `n` from
    /// `(u, v)` in `[0, 1)²`: from the map's distribution (independent of `n`), or
    /// cosine-weighted about `n` for a constant sky. `None` when the environment is
    /// black or the sample has zero density (a measure-zero rounding case).
    pub fn sample(&self, n: Vec3, u: f32, v: f32) -> Option<EnvironmentSample> {
        if self.is_black() {
            return None;
        }
        let wi = match &self.source {
            Source::Constant(_) => sample_phong_lobe(n, 1.0, u, v),
            Source::Map(m) => {
                let dist = m.distribution.as_ref()?;
                let ((mu, mv), _) = dist.sample(u as f64, v as f64);
                self.to_world(uv_to_direction(mu as f32, mv as f32))
            }
        };
        let pdf = self.pdf(n, wi);
        (pdf > 0.0 && pdf.is_finite()).then(|| EnvironmentSample {
            wi,
            radiance: self.radiance(wi),
            pdf,
        })
    }

    /// Solid-angle density with which [`sample`](Self::sample) draws the unit world
    /// direction `wi` for shading normal `n`.
    pub fn pdf(&self, n: Vec3, wi: Vec3) -> f32 {
        match &self.source {
            Source::Constant(_) => (wi.dot(n)).max(0.0) / PI,
            Source::Map(m) => {
                let Some(dist) = &m.distribution else {
                    return 0.0;
                };
                let local = self.to_map(wi).normalize();
                let sin_theta = (1.0 - local.y * local.y).max(0.0).sqrt();
                if sin_theta == 0.0 {
                    return 0.0;
                }
                let (c, r) = self.texel(wi).expect("a map has texels");
                (dist.pdf(c, r) / (2.0 * PI as f64 * PI as f64 * sin_theta as f64)) as f32
            }
        }
    }
}

/// Map coordinates `(u, v)` in `[0, 1]²` of a unit direction in the map's frame.
pub fn direction_to_uv(d: Vec3) -> (f32, f32) {
    let theta = d.y.clamp(-1.0, 1.0).acos();
    let mut phi = d.z.atan2(d.x);
    if phi < 0.0 {
        phi += TAU;
    }
    ((phi / TAU).min(1.0), (theta / PI).min(1.0))
}

/// The unit direction in the map's frame at map coordinates `(u, v)`.
pub fn uv_to_direction(u: f32, v: f32) -> Vec3 {
    let (phi, theta) = (TAU * u, PI * v);
    let (sin_t, cos_t) = theta.sin_cos();
    Vec3::new(sin_t * phi.cos(), cos_t, sin_t * phi.sin())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every texel centre's direction looks up that texel, for every texel of an odd
    /// sized map, with and without a frame rotation.
    #[test]
    fn texel_centres_round_trip() {
        let (w, h) = (37, 19);
        let texels = (0..w * h).map(|i| Vec3::splat(i as f32)).collect();
        let env = Environment::map(w, h, texels, "test").unwrap();
        let turned = env
            .clone()
            .with_frame(Vec3::new(0.3, 1.0, -0.2), 40.0)
            .unwrap();
        for r in 0..h {
            for c in 0..w {
                let local =
                    uv_to_direction((c as f32 + 0.5) / w as f32, (r as f32 + 0.5) / h as f32);
                assert_eq!(env.texel(local), Some((c, r)));
                assert_eq!(env.radiance(local), Vec3::splat((r * w + c) as f32));
                assert_eq!(turned.texel(turned.to_world(local)), Some((c, r)));
            }
        }
    }

    /// Bad maps are refused with the texel named.
    #[test]
    fn negative_or_nan_texels_are_refused() {
        let mut texels = vec![Vec3::ONE; 8];
        texels[5] = Vec3::new(0.0, -1.0, 0.0);
        let e = Environment::map(4, 2, texels, "sky.exr")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("sky.exr") && e.contains("column 1, row 1"),
            "{e}"
        );
        assert!(Environment::map(4, 2, vec![Vec3::ONE; 7], "x").is_err());
        assert!(Environment::constant(Vec3::NAN).is_err());
        assert!(
            Environment::constant(Vec3::ONE)
                .unwrap()
                .with_scale(-1.0)
                .is_err()
        );
    }
}
