//! Integrators: how radiance is estimated per pixel. `whitted` is the recursive scalar
//! reference renderer.

pub mod whitted;

use crate::error::{Error, Result};
use crate::film::Film;
use crate::scene::Scene;
use crate::stats::RayCounts;

/// Largest image side accepted (a 64k x 64k RGB f32 film is already 48 GiB).
pub const MAX_IMAGE_SIDE: u32 = 65_536;
/// Largest sample count per pixel accepted.
pub const MAX_SPP: u32 = 1 << 16;
/// Largest recursion depth accepted.
pub const MAX_DEPTH: u32 = 64;

/// Rejects absurd render parameters with a message saying what is allowed.
pub fn validate_dimensions(width: u32, height: u32, spp: u32, max_depth: u32) -> Result<()> {
    if width == 0 || height == 0 || width > MAX_IMAGE_SIDE || height > MAX_IMAGE_SIDE {
        return Err(Error::parameter(
            "image size",
            format!("{width}x{height}: width and height must be between 1 and {MAX_IMAGE_SIDE}"),
        ));
    }
    if (width as u64) * (height as u64) > 1 << 30 {
        return Err(Error::parameter(
            "image size",
            format!("{width}x{height} exceeds 2^30 pixels"),
        ));
    }
    if spp == 0 || spp > MAX_SPP {
        return Err(Error::parameter(
            "spp",
            format!("{spp}: samples per pixel must be between 1 and {MAX_SPP}"),
        ));
    }
    if max_depth > MAX_DEPTH {
        return Err(Error::parameter(
            "max depth",
            format!("{max_depth}: must be at most {MAX_DEPTH}"),
        ));
    }
    Ok(())
}

/// Everything a render needs besides the scene and the structure.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderOptions {
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub max_depth: u32,
    pub min_contribution: f32,
    pub seed: u64,
    /// Called with the fraction done (0..=1) as tiles finish; `None` for silence.
    pub progress: bool,
}

impl RenderOptions {
    pub fn from_scene(scene: &Scene) -> Self {
        let s = &scene.settings;
        RenderOptions {
            width: s.width,
            height: s.height,
            spp: s.spp,
            max_depth: s.max_depth,
            min_contribution: s.min_contribution,
            seed: 0,
            progress: false,
        }
    }

    pub fn validate(&self) -> Result<()> {
        validate_dimensions(self.width, self.height, self.spp, self.max_depth)
    }
}

/// A finished render.
pub struct RenderOutput {
    pub film: Film,
    pub rays: RayCounts,
    pub render_ms: f64,
}
