//! `packet-render render --time-limit S` / `--target-error E`: a [`RenderJob`] rendered
//! progressively ([`crate::integrator::adaptive`]), the output image rewritten
//! atomically after every pass so that a viewer can watch it improve.

use crate::accel::SceneAccel;
use crate::error::{Error, Result};
use crate::integrator::SamplerKind;
use crate::integrator::adaptive::{self, AdaptiveOptions, PassInfo};
use crate::job::RenderJob;
use crate::scene;
use serde::Serialize;
use std::time::Instant;

/// What a progressive render did, for the stats block and `--stats-json`.
#[derive(Clone, Debug, Serialize)]
pub struct ProgressiveReport {
    pub scene: String,
    pub output: String,
    pub width: u32,
    pub height: u32,
    pub seed: u64,
    pub passes: Vec<PassInfo>,
    /// Fewest and most eye samples of a pixel in the final image.
    pub min_spp: u32,
    pub max_spp: u32,
    pub rays: u64,
    /// Seconds from `start` to the last image written.
    pub seconds: f64,
}

impl ProgressiveReport {
    /// A few lines for the terminal.
    pub fn summary(&self) -> String {
        let last = self.passes.last();
        format!(
            "progressive: {} passes in {:.2} s, mean {:.1} spp (pixels {}..{}), estimated display RMSE {}\n",
            self.passes.len(),
            self.seconds,
            last.map_or(0.0, |p| p.mean_spp),
            self.min_spp,
            self.max_spp,
            last.and_then(|p| p.estimated_error)
                .map_or("-".into(), |e| format!("{e:.5}")),
        )
    }
}

/// Runs `job` progressively; `start` is when the time limit began (the command's
/// start). The job's sampler must be `sobol` or unset (progressive passes need
/// samples whose every prefix is stratified); a `.partial` output and
/// `--sample-range` are refused. Renders with the recursive integrator in the job's
/// thread pool. `on_pass` is told of each pass after its image is written.
pub fn run(
    job: &RenderJob,
    a: &AdaptiveOptions,
    start: Instant,
    mut on_pass: impl FnMut(&PassInfo) + Send,
) -> Result<ProgressiveReport> {
    if crate::film::partial::is_partial_path(&job.output) {
        return Err(Error::parameter(
            "time-limit",
            "progressive rendering writes an image (.png or .hdr), not a .partial",
        ));
    }
    crate::film::check_image_path(&job.output)?;
    if job.part.sample_range.is_some() {
        return Err(Error::parameter(
            "time-limit",
            "--sample-range cannot be combined with --time-limit or --target-error",
        ));
    }
    if let Some(s) = job.overrides.sampler.filter(|&s| s != SamplerKind::Sobol) {
        return Err(Error::parameter(
            "sampler",
            format!(
                "progressive rendering uses the sobol sampler (every prefix of a pixel's samples stratified), not {s}"
            ),
        ));
    }
    a.validate()?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(job.threads)
        .build()
        .map_err(|e| Error::parameter("threads", e.to_string()))?;
    pool.install(|| {
        let scene = scene::load::load_scene(&job.scene)?;
        let opts = job.options(&scene)?;
        let accel = SceneAccel::build(&scene, job.accel);
        let out = adaptive::render(&scene, &accel, &opts, a, start, |film, info| {
            film.save(&job.output)?;
            on_pass(info);
            Ok(())
        })?;
        Ok(ProgressiveReport {
            scene: job.scene.display().to_string(),
            output: job.output.display().to_string(),
            width: out.film.width,
            height: out.film.height,
            seed: job.seed,
            seconds: out.passes.last().map_or(0.0, |p| p.seconds),
            passes: out.passes,
            min_spp: out.counts.iter().copied().min().unwrap_or(0),
            max_spp: out.counts.iter().copied().max().unwrap_or(0),
            rays: out.rays.total(),
        })
    })
}
