//! Integrators: how radiance is estimated per pixel. [`recursive`] is the depth-first
//! scalar reference renderer; [`wavefront`] renders the same images breadth first,
//! tracing rays in batches from queues.
//!
//! Both are built from the same stages, one file each, in the order a sample meets
//! them: [`camera_rays`] (ray generation), [`interaction`] (surface interactions),
//! [`shader`] (materials, BRDFs, Fresnel via [`optics`], emitted shadow and child
//! rays), [`path_keys`] (random streams keyed by path identity), [`pixel_filter`]
//! (camera-ray radiance into filter sums) and [`tiles`] (tile scheduler and film
//! assembly); the wavefront adds its [`queues`].

pub mod adaptive;
pub mod aov;
pub(crate) mod area_light;
pub mod budget;
pub mod camera_packets;
pub mod camera_rays;
pub(crate) mod environment;
pub(crate) mod hit_batch;
pub mod interaction;
pub mod optics;
pub mod path_keys;
pub mod pixel_filter;
pub mod queues;
pub mod recursive;
pub mod region;
pub mod sampling;
pub(crate) mod shade_stage;
pub mod shader;
pub mod shadow;
pub mod sobol;
pub mod texturing;
pub mod tiles;
pub mod tiny_shadow;
pub mod wavefront;

use crate::error::{Error, Result};
use crate::film::Film;
use crate::scene::SampleCounts;
use crate::scene::Scene;
use crate::scene::limits::{validate_dimensions, validate_sample_counts};
use crate::stats::{EffectSamplesDrawn, RayCounts, StageTimes};
pub use region::PixelBounds;
pub use sampling::{FilterKind, SamplerKind};
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
    /// ([`shadow`]).
    pub transmitted_shadows: bool,
    /// Called as tiles finish; `None` for silence.
    pub progress: Option<ProgressFn>,
    /// Render only these pixels (`--crop`, `--tile`); `None` for the whole image.
    pub crop: Option<PixelBounds>,
    /// Render only these eye samples of each pixel's `spp` (`--sample-range`).
    pub sample_range: Option<Range<u32>>,
    /// Also return every pixel's filter sums, encoded ([`RenderOutput::sums`]).
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

/// A finished render.
#[derive(Clone, Debug)]
pub struct RenderOutput {
    /// The pixels of `region` (the whole image unless cropped).
    pub film: Film,
    /// Which pixels of the full image `film` holds.
    pub region: PixelBounds,
    /// With [`RenderOptions::keep_sums`]: the filter sums of every pixel of `region`,
    /// row-major, as pixel records of a partial image ([`crate::film::partial`]).
    pub sums: Option<Vec<u8>>,
    pub rays: RayCounts,
    pub render_ms: f64,
    /// Samples whose radiance came out NaN or infinite. Each was written as black, so a
    /// numeric bug shows here instead of poisoning the image (and every later average).
    pub nonfinite_samples: u64,
    /// Random samples drawn for the distributed effects; all zero for a scene that has
    /// none of them (pay for what you use).
    pub samples_drawn: EffectSamplesDrawn,
    /// Time by stage for the wavefront integrator; `None` for the recursive one.
    pub stages_ms: Option<StageTimes>,
    /// Most paths (camera, child and shadow rays) the wavefront's queues held at once in
    /// one worker, bounded by about [`wavefront::MAX_WAVE_PATHS`]; 0 for the recursive
    /// integrator.
    pub peak_queue_paths: u64,
}

/// Which integrator renders.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum IntegratorKind {
    /// Recursive, depth first, one ray at a time: the reference.
    #[default]
    Whitted,
    /// Breadth first over ray queues, traced in packets.
    Wavefront,
}

impl IntegratorKind {
    pub const ALL: &'static [IntegratorKind] =
        &[IntegratorKind::Whitted, IntegratorKind::Wavefront];

    pub fn name(self) -> &'static str {
        match self {
            IntegratorKind::Whitted => "whitted",
            IntegratorKind::Wavefront => "wavefront",
        }
    }

    /// Renders with this integrator.
    pub fn render(
        self,
        scene: &Scene,
        accel: &crate::accel::SceneAccel,
        opts: &RenderOptions,
    ) -> RenderOutput {
        match self {
            IntegratorKind::Whitted => recursive::render(scene, accel, opts),
            IntegratorKind::Wavefront => wavefront::render(scene, accel, opts),
        }
    }
}

impl std::str::FromStr for IntegratorKind {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        sampling::parse_named(IntegratorKind::ALL, IntegratorKind::name, "integrator", s)
    }
}

impl std::fmt::Display for IntegratorKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}
