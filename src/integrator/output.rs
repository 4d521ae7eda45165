//! What a finished render hands back: the film, counts, times and stats.

use super::PixelBounds;
use crate::film::Film;
use crate::stats::{EffectSamplesDrawn, RayCounts, StageTimes};

/// A finished render.
#[derive(Clone, Debug)]
pub struct RenderOutput {
    /// The pixels of `region` (the whole image unless cropped).
    pub film: Film,
    /// Which pixels of the full image `film` holds.
    pub region: PixelBounds,
    /// With [`RenderOptions::keep_sums`](super::RenderOptions::keep_sums): the filter sums of every pixel of `region`,
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
    /// one worker, bounded by about [`wavefront::MAX_WAVE_PATHS`](super::wavefront::MAX_WAVE_PATHS); 0 for the recursive
    /// integrator.
    pub peak_queue_paths: u64,
}
