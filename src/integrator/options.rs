//! What a render needs besides the scene and the structure, checked before work starts.

use super::{FilterKind, PixelBounds, SamplerKind, region};
use crate::error::Result;
use crate::scene::limits::{validate_dimensions, validate_sample_counts};
use crate::scene::{SampleCounts, Scene};
use std::ops::Range;
use std::sync::Arc;

/// Progress callback: `(tiles done, tiles total)`, called from worker threads as tiles
/// finish (so in no particular order of tiles, but `done` only grows).
pub type ProgressFn = Arc<dyn Fn(u64, u64) + Send + Sync>;

/// Everything a render needs besides the scene and the structure.
#[derive(Clone)]
pub struct RenderOptions {
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub max_depth: u32,
    pub min_contribution: f32,
    pub seed: u64,
    /// Per-effect sample counts (the eye count is `spp`).
    pub samples: SampleCounts,
    /// Pattern of every sample set (pixel, lens, time, light, glossy).
    pub sampler: SamplerKind,
    /// Pixel reconstruction filter.
    pub filter: FilterKind,
    /// Shadow rays through glass attenuated by its transmission instead of blocked
    /// ([`shadow`](super::shadow)).
    pub transmitted_shadows: bool,
    /// Called as tiles finish; `None` for silence.
    pub progress: Option<ProgressFn>,
    /// Render only these pixels (`--crop`, `--tile`); `None` for the whole image.
    pub crop: Option<PixelBounds>,
    /// Render only these eye samples of each pixel's `spp` (`--sample-range`).
    pub sample_range: Option<Range<u32>>,
    /// Also return every pixel's filter sums, encoded ([`RenderOutput::sums`](super::RenderOutput::sums)).
    pub keep_sums: bool,
}

// By hand because a closure is neither `Debug` nor `PartialEq`: the reporter is shown
// by presence and compared by identity.
impl std::fmt::Debug for RenderOptions {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RenderOptions")
            .field("width", &self.width)
            .field("height", &self.height)
            .field("spp", &self.spp)
            .field("max_depth", &self.max_depth)
            .field("min_contribution", &self.min_contribution)
            .field("seed", &self.seed)
            .field("samples", &self.samples)
            .field("sampler", &self.sampler)
            .field("filter", &self.filter)
            .field("transmitted_shadows", &self.transmitted_shadows)
            .field(
                "progress",
                &self.progress.as_ref().map(|_| "Fn(done, total)"),
            )
            .field("crop", &self.crop)
            .field("sample_range", &self.sample_range)
            .field("keep_sums", &self.keep_sums)
            .finish()
    }
}

impl PartialEq for RenderOptions {
    fn eq(&self, o: &Self) -> bool {
        let same_progress = match (&self.progress, &o.progress) {
            (None, None) => true,
            (Some(a), Some(b)) => Arc::ptr_eq(a, b),
            _ => false,
        };
        self.width == o.width
            && self.height == o.height
            && self.spp == o.spp
            && self.max_depth == o.max_depth
            && self.min_contribution == o.min_contribution
            && self.seed == o.seed
            && self.samples == o.samples
            && self.sampler == o.sampler
            && self.filter == o.filter
            && self.crop == o.crop
            && self.sample_range == o.sample_range
            && self.keep_sums == o.keep_sums
            && self.transmitted_shadows == o.transmitted_shadows
            && same_progress
    }
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
            samples: s.samples,
            sampler: SamplerKind::default(),
            filter: FilterKind::default(),
            transmitted_shadows: s.transmitted_shadows,
            progress: None,
            crop: None,
            sample_range: None,
            keep_sums: false,
        }
    }

    pub fn validate(&self) -> Result<()> {
        validate_dimensions(self.width, self.height, self.spp, self.max_depth)?;
        validate_sample_counts(&self.samples)?;
        if let Some(c) = &self.crop {
            c.check_inside(self.width, self.height)?;
        }
        if let Some(r) = &self.sample_range {
            region::check_sample_range(r, self.spp)?;
        }
        Ok(())
    }

    /// The pixels rendered: `crop`, or the whole image.
    pub fn region(&self) -> PixelBounds {
        self.crop
            .unwrap_or(PixelBounds::full(self.width, self.height))
    }
}
