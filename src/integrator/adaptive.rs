//! Progressive, adaptive rendering (`--time-limit`, `--target-error`): the image is
//! rendered in passes, each adding eye samples where the estimated error is largest,
//! and every pass yields a complete image (the caller writes it, atomically).
//!
//! Samples: the [`Sobol`](super::SamplerKind::Sobol) sampler, whose every
//! power-of-two prefix of a pixel's samples is stratified in every dimension, so a
//! pixel that stops after `n` samples has an unbiased, well spread estimate. Sample `i`
//! of a pixel is the same whichever pass renders it.
//!
//! Passes:
//! 1. pass 0: one eye sample in every pixel (the first image, soon);
//! 2. a *pilot*: `pilot` eye samples per pixel from an independent seed, used only to
//!    estimate each pixel's variance `v_p` in the displayed space (the sample variance
//!    of its samples clamped to [0, 1] and sRGB-encoded, mean over channels), then
//!    discarded; where the pilot would not end before the time limit, uniform passes
//!    of one more sample per pixel use the time left instead;
//! 3. passes `k >= 1`: a deterministic schedule of total sample budgets
//!    `N_1 = first * pixels`, `N_{k+1} = max(N_k * growth, N_k + pixels)`, shared out
//!    as `n_p ∝ sqrt(v_p / c_p)`, `c_p` the pixel's rays per pilot sample (the counts
//!    that minimise the estimated squared display error `Σ v_p / n_p` for a fixed
//!    time `Σ c_p n_p`, Lagrange), never fewer than a pixel already has. The estimated display RMSE after a pass is `sqrt(mean v_p / n_p)`.
//!
//! Unbiased: each pixel's value is the mean of its own samples `0..n_p`, and `n_p`
//! depends only on the pilot, whose samples are independent of the kept ones and not
//! part of the image; so `n_p` is independent of the kept samples and the mean of any
//! fixed count of Sobol samples (each one uniform) is unbiased. (Deciding from the kept
//! samples themselves, the usual scheme, makes `n_p` a stopping time of the samples it
//! averages, which biases the mean; the pilot costs `pilot` samples per pixel.)
//!
//! Deterministic: the image of pass `k` depends on the seed only (not on the thread
//! count: every pixel is rendered on its own). The time limit decides only how many
//! passes run: before each pass its time is predicted from the last pass's seconds per
//! sample, and it runs only if 1.5 times that ends before the limit.

use super::{RenderOptions, SamplerKind, recursive};
use crate::accel::SceneAccel;
use crate::error::{Error, Result};
use crate::film::{Film, PixelSums, linear_to_srgb};
use crate::scene::Scene;
use crate::scene::limits::MAX_SPP;
use crate::stats::RayCounts;
use glam::Vec3;
use std::time::Instant;

/// When to stop and how to schedule passes.
#[derive(Clone, Debug, PartialEq)]
pub struct AdaptiveOptions {
    /// Stop before a pass that would end later than this many seconds after `start`.
    pub time_limit: Option<f64>,
    /// Stop once the estimated display RMSE is at most this.
    pub target_error: Option<f64>,
    /// Stop once the mean eye samples per pixel reach this (a sample budget).
    pub max_mean_spp: Option<f64>,
    /// Pilot eye samples per pixel (for the variance estimates, then discarded).
    pub pilot: u32,
    /// Mean eye samples per pixel after pass 1.
    pub first: u32,
    /// Growth of the total sample count from pass to pass.
    pub growth: f64,
}

impl Default for AdaptiveOptions {
    fn default() -> Self {
        AdaptiveOptions {
            time_limit: None,
            target_error: None,
            max_mean_spp: None,
            pilot: 4,
            first: 4,
            growth: 1.25,
        }
    }
}

impl AdaptiveOptions {
    /// Checks that the render stops: a limit, positive and finite, and a sane schedule.
    pub fn validate(&self) -> Result<()> {
        let positive = |name: &str, v: Option<f64>| match v {
            Some(x) if !(x.is_finite() && x > 0.0) => Err(Error::parameter(
                name,
                format!("{name} must be a positive number, got {x}"),
            )),
            _ => Ok(()),
        };
        positive("time-limit", self.time_limit)?;
        positive("target-error", self.target_error)?;
        positive("max-mean-spp", self.max_mean_spp)?;
        if self.time_limit.is_none() && self.target_error.is_none() && self.max_mean_spp.is_none() {
            return Err(Error::parameter(
                "time-limit",
                "progressive rendering needs --time-limit or --target-error",
            ));
        }
        if self.pilot < 2 || self.first == 0 || self.growth.is_nan() || self.growth <= 1.0 {
            return Err(Error::parameter(
                "adaptive",
                "need pilot >= 2, first >= 1, growth > 1",
            ));
        }
        Ok(())
    }
}

/// What one pass produced.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct PassInfo {
    pub pass: u32,
    /// Eye samples in the image (the pilot's not counted).
    pub samples: u64,
    pub mean_spp: f64,
    /// Estimated display RMSE (from the pilot variances; `None` before the pilot).
    pub estimated_error: Option<f64>,
    /// Seconds since `start` when the pass's image was ready.
    pub seconds: f64,
}

/// The final image and how it was made.
#[derive(Clone, Debug)]
pub struct AdaptiveOutput {
    pub film: Film,
    /// Eye samples of each pixel, row-major over the region.
    pub counts: Vec<u32>,
    pub passes: Vec<PassInfo>,
    pub rays: RayCounts,
}

/// A pass runs only if its predicted seconds times this end before the time limit:
/// on a machine shared with other work a pass can take longer than the last one's
/// rate predicts. A chosen margin: with 1.1 the 2.5 s CLI test (`tests/adaptive.rs`)
/// failed once in a few runs on the loaded 2-core machine; with 1.5 it passed 4 of 4.
const SAFETY: f64 = 1.5;

/// A pixel's filter sums in f64 (64 bytes, where [`PixelSums`]' exact sums take 600:
/// the progressive renderer keeps one per pixel of the image). Sums of the same
/// passes in the same order give the same bits, which is all its determinism needs.
#[derive(Clone, Copy, Debug, Default)]
struct Acc {
    weighted: [f64; 3],
    weight: f64,
    plain: [f64; 3],
    samples: u32,
}

impl Acc {
    fn of(s: &PixelSums) -> Acc {
        let f = s.sums_f64();
        Acc {
            weighted: [f[0], f[1], f[2]],
            weight: f[3],
            plain: [f[4], f[5], f[6]],
            samples: s.samples,
        }
    }

    fn merge(&mut self, o: &Acc) {
        for c in 0..3 {
            self.weighted[c] += o.weighted[c];
            self.plain[c] += o.plain[c];
        }
        self.weight += o.weight;
        self.samples += o.samples;
    }

    /// As [`PixelSums::value`]: the weighted mean, the plain mean if every weight is
    /// zero, black without samples.
    fn value(&self) -> Vec3 {
        let (num, den) = if self.weight > 0.0 {
            (&self.weighted, self.weight)
        } else if self.samples > 0 {
            (&self.plain, self.samples as f64)
        } else {
            return Vec3::ZERO;
        };
        Vec3::new(
            (num[0] / den) as f32,
            (num[1] / den) as f32,
            (num[2] / den) as f32,
        )
    }
}

/// A pixel and the eye samples to render in it.
type PixelRange = (u32, u32, std::ops::Range<u32>);

/// Separates the pilot's samples from the image's.
const PILOT_SEED: u64 = 0x9106_7a11_c0ff_ee15;

/// Renders `opts`' region progressively (recursive integrator, Sobol sampler; `spp`,
/// `sampler` and `sample_range` of `opts` are not used). `on_pass` receives every
/// pass's complete image; an error from it stops the render. `start` is when the
/// time limit started counting (the command's start, so loading counts too).
pub fn render(
    scene: &Scene,
    accel: &SceneAccel,
    opts: &RenderOptions,
    a: &AdaptiveOptions,
    start: Instant,
    mut on_pass: impl FnMut(&Film, &PassInfo) -> Result<()>,
) -> Result<AdaptiveOutput> {
    a.validate()?;
    let mut o = opts.clone();
    o.sampler = SamplerKind::Sobol;
    o.spp = MAX_SPP;
    o.sample_range = None;
    o.keep_sums = false;
    o.validate()?;
    let region = o.region();
    let coords: Vec<(u32, u32)> = (region.y0..region.y1)
        .flat_map(|y| (region.x0..region.x1).map(move |x| (x, y)))
        .collect();
    let npix = coords.len() as u64;
    let mut sums = vec![Acc::default(); coords.len()];
    let mut counts = vec![0u32; coords.len()];
    let mut rays = RayCounts::default();
    let mut passes = Vec::new();
    let elapsed = || start.elapsed().as_secs_f64();
    let fits = |seconds: f64| a.time_limit.is_none_or(|l| elapsed() + seconds <= l);

    // Renders up to `target[p]` samples in each pixel, updating those pixels of the
    // film (only the pixels a pass touched are resolved again); the seconds per sample.
    let refine = |target: &[u32],
                  sums: &mut [Acc],
                  counts: &mut [u32],
                  film: &mut Film,
                  rays: &mut RayCounts|
     -> f64 {
        let t = Instant::now();
        let work: Vec<(usize, PixelRange)> = (0..coords.len())
            .filter(|&p| target[p] > counts[p])
            .map(|p| (p, (coords[p].0, coords[p].1, counts[p]..target[p])))
            .collect();
        let list: Vec<_> = work.iter().map(|w| w.1.clone()).collect();
        let (new, _, r) = recursive::render_pixels(scene, accel, &o, &list, Acc::of);
        *rays += r;
        let mut added = 0u64;
        for ((p, range), s) in work.iter().zip(&new) {
            sums[*p].merge(s);
            counts[*p] = range.2.end;
            added += (range.2.end - range.2.start) as u64;
            film.set(range.0 - region.x0, range.1 - region.y0, sums[*p].value());
        }
        t.elapsed().as_secs_f64() / added.max(1) as f64
    };
    let mut film = Film::new(region.width(), region.height());
    let mut emit = |pass: u32, film: &Film, counts: &[u32], err: Option<f64>| {
        let samples: u64 = counts.iter().map(|&c| c as u64).sum();
        let info = PassInfo {
            pass,
            samples,
            mean_spp: samples as f64 / npix as f64,
            estimated_error: err,
            seconds: elapsed(),
        };
        on_pass(film, &info)?;
        passes.push(info);
        Ok::<_, Error>(())
    };

    // Pass 0: one sample everywhere.
    let mut per_sample = refine(
        &vec![1; coords.len()],
        &mut sums,
        &mut counts,
        &mut film,
        &mut rays,
    );
    emit(0, &film, &counts, None)?;

    // The pilot, from an independent stream. Where it would not fit in the time
    // left, uniform passes of one more sample per pixel use the time instead.
    if a.max_mean_spp.is_some_and(|m| m <= 1.0) {
        return Ok(finish(film, counts, passes, rays));
    }
    if !fits(per_sample * (a.pilot as f64) * npix as f64 * SAFETY) {
        let mut pass = 1;
        while fits(per_sample * npix as f64 * SAFETY)
            && a.max_mean_spp.is_none_or(|m| (counts[0] as f64) < m)
            && counts[0] < MAX_SPP
        {
            let target: Vec<u32> = counts.iter().map(|c| c + 1).collect();
            per_sample = refine(&target, &mut sums, &mut counts, &mut film, &mut rays);
            emit(pass, &film, &counts, None)?;
            pass += 1;
        }
        return Ok(finish(film, counts, passes, rays));
    }
    let (variance, cost) = pilot_variance(scene, accel, &o, &coords, a.pilot, &mut rays);
    let mean_v = variance.iter().sum::<f64>() / npix.max(1) as f64;
    // A floor, so that a pixel whose pilot saw no variation still gets samples.
    let weight: Vec<f64> = variance
        .iter()
        .zip(&cost)
        .map(|(v, c)| ((v + 0.05 * mean_v) / c).sqrt())
        .collect();
    let total_w: f64 = weight.iter().sum();
    let estimate = |counts: &[u32]| {
        let mse: f64 = variance
            .iter()
            .zip(counts)
            .map(|(v, &n)| v / n.max(1) as f64)
            .sum::<f64>()
            / npix as f64;
        mse.sqrt()
    };

    let mut budget = a.first as f64 * npix as f64;
    let mut pass = 1;
    loop {
        let err = estimate(&counts);
        let mean_spp = counts.iter().map(|&c| c as f64).sum::<f64>() / npix as f64;
        if a.target_error.is_some_and(|e| err <= e)
            || a.max_mean_spp.is_some_and(|m| mean_spp >= m)
            || counts.iter().all(|&c| c >= MAX_SPP)
        {
            break;
        }
        let capped = a.max_mean_spp.is_some_and(|m| budget >= m * npix as f64);
        if let Some(m) = a.max_mean_spp {
            budget = budget.min(m * npix as f64);
        }
        let target: Vec<u32> = (0..coords.len())
            .map(|p| {
                let share = (budget * weight[p] / total_w).round();
                (share.min(MAX_SPP as f64) as u32).max(counts[p])
            })
            .collect();
        let new: u64 = target
            .iter()
            .zip(&counts)
            .map(|(&t, &c)| (t - c) as u64)
            .sum();
        if new > 0 {
            if !fits(per_sample * new as f64 * SAFETY) {
                break;
            }
            per_sample = refine(&target, &mut sums, &mut counts, &mut film, &mut rays);
            emit(pass, &film, &counts, Some(estimate(&counts)))?;
            pass += 1;
        } else if capped {
            // The budget's shares, rounded, are all rendered.
            break;
        }
        budget = (budget * a.growth).max(budget + npix as f64);
    }
    Ok(finish(film, counts, passes, rays))
}

fn finish(film: Film, counts: Vec<u32>, passes: Vec<PassInfo>, rays: RayCounts) -> AdaptiveOutput {
    AdaptiveOutput {
        film,
        counts,
        passes,
        rays,
    }
}

/// Each pixel's variance of one sample's displayed value (clamped to [0, 1],
/// sRGB-encoded; the unbiased sample variance of `n` pilot samples, mean over the
/// channels), from samples of an independent seed; and its cost, the rays per sample
/// (at least 1).
fn pilot_variance(
    scene: &Scene,
    accel: &SceneAccel,
    o: &RenderOptions,
    coords: &[(u32, u32)],
    n: u32,
    rays: &mut RayCounts,
) -> (Vec<f64>, Vec<f64>) {
    let mut p = o.clone();
    p.seed = o.seed ^ PILOT_SEED;
    let mut sum = vec![[0.0f64; 3]; coords.len()];
    let mut sq = vec![[0.0f64; 3]; coords.len()];
    let mut cost = vec![0.0f64; coords.len()];
    for i in 0..n {
        let list: Vec<_> = coords.iter().map(|&(x, y)| (x, y, i..i + 1)).collect();
        let (one, c, r) = recursive::render_pixels(scene, accel, &p, &list, PixelSums::value);
        *rays += r;
        for (k, &c) in c.iter().enumerate() {
            cost[k] += c as f64 / n as f64;
        }
        for (k, &v) in one.iter().enumerate() {
            for c in 0..3 {
                let d = linear_to_srgb(v[c].clamp(0.0, 1.0)) as f64;
                sum[k][c] += d;
                sq[k][c] += d * d;
            }
        }
    }
    let n = n as f64;
    let variance = sum
        .iter()
        .zip(&sq)
        .map(|(s, q)| {
            (0..3)
                .map(|c| ((q[c] - s[c] * s[c] / n) / (n - 1.0)).max(0.0))
                .sum::<f64>()
                / 3.0
        })
        .collect();
    (variance, cost.into_iter().map(|c| c.max(1.0)).collect())
}
