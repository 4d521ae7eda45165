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
//! 1. the *pilot*, passes `0 .. pilot - 1`: one more eye sample in every pixel per pass
//!    (pass 0, one sample, is the first image, soon). The pilot's samples are the
//!    first samples of each pixel's own sequence and stay in the image; from them each
//!    pixel gets the sample variance `s²_q` of its displayed value (clamped to [0, 1],
//!    sRGB-encoded, mean over channels) and its rays per sample `c_q`;
//! 2. passes `k >= pilot`: a deterministic schedule of total sample budgets
//!    `N_1 = first * pixels`, `N_{k+1} = max(N_k * growth, N_k + pixels)`, shared out
//!    as `n_p ∝ sqrt(v_p / c_p)` (the counts that minimise the estimated squared display
//!    error `Σ v_p / n_p` for a fixed time `Σ c_p n_p`, Lagrange), never fewer than a
//!    pixel already has, with `v_p` and `c_p` estimated **from the pixel's neighbours
//!    only** (the checkerboard plan below).
//!
//! # The checkerboard plan, and why the kept pilot leaves the image unbiased
//!
//! Colour the pixels as a checkerboard, `colour(x, y) = (x + y) mod 2`; a pixel's four
//! neighbours have the other colour. For a pixel `p` of colour `a`:
//! - `v̂_p` is the mean of `s²_q` over its neighbours `q` (at most 4, inside the
//!   region), `ĉ_p` the mean of their `c_q`; its weight is
//!   `w_p = sqrt((v̂_p + 0.05 m_b) / ĉ_p)`, with `m_b` the mean `s²_q` over all pixels
//!   of the other colour `b` (a floor, so that a pixel whose neighbours saw no
//!   variation is still sampled);
//! - colour `a` gets the share `N_k · |a| / |pixels|` of pass `k`'s budget, and `p` the
//!   part `w_p / Σ_{q ∈ a} w_q` of it;
//! - colour `a` stops (`--target-error`) when its estimated error
//!   `sqrt(mean_{p ∈ a} v̂_p / n_p)` is at most the target, and the schedule of budgets
//!   and the sample-budget stop (`max_mean_spp`, [`AdaptiveOptions`]) depend on nothing
//!   measured.
//!
//! So every quantity that decides `n_p` for a pixel of colour `a` is a function of the
//! pilot samples of colour-`b` pixels (and of constants), never of a colour-`a` pixel's
//! samples. The samples of different pixels are independent (each pixel's sequence is
//! scrambled by hashes of the seed and the pixel index, [`super::sobol`]), so `n_p` is
//! independent of pixel `p`'s own sample sequence `X_p = (X_p,0, X_p,1, ...)`. The pixel's
//! value is `F_n(X_p)`, the value a uniform render of its samples `0..n` gives, at
//! `n = n_p`; then `E[F_{n_p}(X_p)] = Σ_n P(n_p = n) E[F_n(X_p)]`, because conditioning
//! on `n_p = n` does not change the distribution of `X_p`. With every sample uniform
//! (the scrambled Sobol points), `F_n` is an unbiased estimate of the pixel integral for
//! every fixed `n` (its filter weighted mean is the uniform render's, as biased or
//! not as that), and so is the adaptive value. The pilot samples can therefore be the
//! first `pilot` samples of the pixel's own sequence and be kept: nothing is spent
//! twice. What would be biased is the usual scheme, deciding `n_p` from the pixel's own
//! samples: `n_p` is then a stopping time of the samples it averages (a pixel whose
//! first samples happened to agree stops early, with a value pulled towards them).
//! The normalisation `Σ_{q ∈ a} w_q` over one colour (not over all pixels) and the
//! per-colour stop matter: a sum over both colours would contain the weights of
//! `p`'s neighbours, which are computed from `p`'s own pilot samples.
//!
//! `--time-limit` is the one exception: whether a pass runs depends on the seconds the
//! passes took, which the samples influence only through the time they take to
//! trace. That dependence is not designed in and is the same for any render stopped by
//! a clock; with the sample-budget or target-error stops the argument above is exact.
//!
//! Deterministic: the image of pass `k` depends on the seed only (not on the thread
//! count: every pixel is rendered on its own). The time limit decides only how many
//! passes run: before each pass its time is predicted from the last pass's seconds per
//! sample, and it runs only if 1.5 times that ends before the limit.
//!
//! History (`dof_area.toml`, 128 x 128, equal seconds against jittered, docs/convergence.md):
//! the first version drew a pilot of 4 samples per pixel from an independent seed and
//! discarded it (overhead: pass 0 and the pilot, 5 samples per pixel); its display RMSE
//! was 1.35, 1.17, 1.00, 0.78 times jittered's at 0.02, 0.09, 0.25, 0.52 s. The kept
//! pilot removes that overhead.

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
    /// A sample budget: the last pass's total is this many eye samples per pixel on
    /// average (pixels already above their share keep their samples, so the mean can
    /// end a little above it).
    pub max_mean_spp: Option<f64>,
    /// Pilot eye samples per pixel (uniform, kept in the image; they estimate the
    /// variances).
    pub pilot: u32,
    /// Mean eye samples per pixel of the first adaptive pass's budget.
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
            first: 6,
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
    /// Eye samples in the image.
    pub samples: u64,
    pub mean_spp: f64,
    /// Estimated display RMSE, the larger of the two checkerboard colours' (`None`
    /// during the pilot).
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
/// rate predicts. A chosen margin: with 1.1 the 2.5 s CLI test (`tests/suite/adaptive.rs`)
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

/// The displayed value of a radiance, per channel: clamped to [0, 1], sRGB-encoded.
fn displayed(v: Vec3) -> [f64; 3] {
    [v.x, v.y, v.z].map(|c| linear_to_srgb(c.clamp(0.0, 1.0)) as f64)
}

/// Running pilot statistics of one pixel: sums of the displayed value and its square
/// per channel, and the rays traced.
#[derive(Clone, Copy, Debug, Default)]
struct PilotStats {
    sum: [f64; 3],
    sq: [f64; 3],
    rays: u64,
    samples: u32,
}

impl PilotStats {
    fn add(&mut self, v: Vec3, rays: u64) {
        for (c, d) in displayed(v).into_iter().enumerate() {
            self.sum[c] += d;
            self.sq[c] += d * d;
        }
        self.rays += rays;
        self.samples += 1;
    }

    /// The unbiased sample variance of one sample's displayed value, mean over channels.
    fn variance(&self) -> f64 {
        let n = self.samples as f64;
        if self.samples < 2 {
            return 0.0;
        }
        (0..3)
            .map(|c| ((self.sq[c] - self.sum[c] * self.sum[c] / n) / (n - 1.0)).max(0.0))
            .sum::<f64>()
            / 3.0
    }

    /// Rays per sample, at least 1.
    fn cost(&self) -> f64 {
        (self.rays as f64 / self.samples.max(1) as f64).max(1.0)
    }
}

/// The checkerboard allocation (module documentation): for each pixel of a `width` x
/// `height` region, row-major, its colour and the weight and variance estimate taken
/// from its neighbours' pilot statistics.
#[derive(Clone, Debug)]
pub(crate) struct Plan {
    colour: Vec<u8>,
    /// `v̂_p`: the mean pilot variance of the pixel's neighbours.
    vhat: Vec<f64>,
    /// `w_p = sqrt((v̂_p + floor) / ĉ_p)`.
    weight: Vec<f64>,
    /// Pixels of each colour.
    pixels: [u64; 2],
    /// `Σ w_q` over the pixels of each colour.
    total: [f64; 2],
}

impl Plan {
    /// `variance[p]` and `cost[p]` are pixel `p`'s own pilot variance and rays per
    /// sample; `parity` is the colour of the region's first pixel (`(x0 + y0) mod 2`,
    /// so that the colours are those of the whole image).
    pub(crate) fn new(width: u32, height: u32, parity: u8, variance: &[f64], cost: &[f64]) -> Plan {
        let (w, h) = (width as usize, height as usize);
        let n = w * h;
        assert_eq!(variance.len(), n);
        assert_eq!(cost.len(), n);
        let colour: Vec<u8> = (0..n)
            .map(|p| ((p % w + p / w) as u8 + parity) & 1)
            .collect();
        let mut pixels = [0u64; 2];
        let mut sum_v = [0.0f64; 2];
        for p in 0..n {
            pixels[colour[p] as usize] += 1;
            sum_v[colour[p] as usize] += variance[p];
        }
        let mean_v = |c: usize| sum_v[c] / pixels[c].max(1) as f64;
        let mut vhat = vec![0.0; n];
        let mut weight = vec![0.0; n];
        let mut total = [0.0f64; 2];
        for p in 0..n {
            let (x, y) = (p % w, p / w);
            let mut neighbours = Vec::with_capacity(4);
            if x > 0 {
                neighbours.push(p - 1);
            }
            if x + 1 < w {
                neighbours.push(p + 1);
            }
            if y > 0 {
                neighbours.push(p - w);
            }
            if y + 1 < h {
                neighbours.push(p + w);
            }
            let k = neighbours.len().max(1) as f64;
            let v = neighbours.iter().map(|&q| variance[q]).sum::<f64>() / k;
            let c = if neighbours.is_empty() {
                1.0
            } else {
                neighbours.iter().map(|&q| cost[q]).sum::<f64>() / k
            };
            let other = 1 - colour[p] as usize;
            vhat[p] = v;
            weight[p] = ((v + 0.05 * mean_v(other)) / c.max(1.0)).sqrt();
            total[colour[p] as usize] += weight[p];
        }
        Plan {
            colour,
            vhat,
            weight,
            pixels,
            total,
        }
    }

    /// Sample counts after a pass of total budget `budget` (samples) for the pixels
    /// of colour `c`: each one's share, never fewer than `counts`, at most `MAX_SPP`.
    /// Other pixels keep `counts`.
    pub(crate) fn targets(&self, budget: f64, c: usize, counts: &[u32], out: &mut [u32]) {
        let n = self.colour.len() as f64;
        let mine = budget * self.pixels[c] as f64 / n;
        for p in 0..self.colour.len() {
            out[p] = counts[p];
            if self.colour[p] as usize != c {
                continue;
            }
            let share = if self.total[c] > 0.0 {
                mine * self.weight[p] / self.total[c]
            } else {
                mine / self.pixels[c] as f64
            };
            out[p] = (share.round().min(MAX_SPP as f64) as u32).max(counts[p]);
        }
    }

    /// Estimated display RMSE of colour `c`'s pixels at `counts`:
    /// `sqrt(mean v̂_p / n_p)` (the i.i.d. bound; stratification does better).
    pub(crate) fn estimate(&self, c: usize, counts: &[u32]) -> f64 {
        let mse: f64 = (0..self.colour.len())
            .filter(|&p| self.colour[p] as usize == c)
            .map(|p| self.vhat[p] / counts[p].max(1) as f64)
            .sum();
        (mse / self.pixels[c].max(1) as f64).sqrt()
    }

    fn is(&self, p: usize, c: usize) -> bool {
        self.colour[p] as usize == c
    }
}

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
    // film (only the pixels a pass touched are resolved again), and the pilot
    // statistics if given (then every range is one sample); the seconds per sample.
    let refine = |target: &[u32],
                  sums: &mut [Acc],
                  counts: &mut [u32],
                  film: &mut Film,
                  rays: &mut RayCounts,
                  pilot: Option<&mut [PilotStats]>|
     -> f64 {
        let t = Instant::now();
        let work: Vec<(usize, PixelRange)> = (0..coords.len())
            .filter(|&p| target[p] > counts[p])
            .map(|p| (p, (coords[p].0, coords[p].1, counts[p]..target[p])))
            .collect();
        let list: Vec<_> = work.iter().map(|w| w.1.clone()).collect();
        let (new, cost, r) =
            recursive::render_pixels(scene, accel, &o, &list, |s| (Acc::of(s), s.value()));
        *rays += r;
        let mut added = 0u64;
        for ((p, range), (s, _)) in work.iter().zip(&new) {
            sums[*p].merge(s);
            counts[*p] = range.2.end;
            added += (range.2.end - range.2.start) as u64;
            film.set(range.0 - region.x0, range.1 - region.y0, sums[*p].value());
        }
        if let Some(stats) = pilot {
            for (((p, range), (_, v)), c) in work.iter().zip(&new).zip(&cost) {
                debug_assert_eq!(range.2.len(), 1);
                stats[*p].add(*v, *c);
            }
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

    // The pilot: uniform passes of one sample, kept; pass 0 always runs.
    let mut stats = vec![PilotStats::default(); coords.len()];
    let mut per_sample = 0.0;
    for i in 0..a.pilot {
        if i > 0
            && (a.max_mean_spp.is_some_and(|m| i as f64 >= m)
                || !fits(per_sample * npix as f64 * SAFETY))
        {
            return Ok(finish(film, counts, passes, rays));
        }
        let target = vec![i + 1; coords.len()];
        per_sample = refine(
            &target,
            &mut sums,
            &mut counts,
            &mut film,
            &mut rays,
            Some(&mut stats),
        );
        emit(i, &film, &counts, None)?;
    }

    let variance: Vec<f64> = stats.iter().map(PilotStats::variance).collect();
    let cost: Vec<f64> = stats.iter().map(PilotStats::cost).collect();
    let parity = ((region.x0 + region.y0) & 1) as u8;
    let plan = Plan::new(region.width(), region.height(), parity, &variance, &cost);
    let estimate = |counts: &[u32]| {
        (0..2)
            .filter(|&c| plan.pixels[c] > 0)
            .map(|c| plan.estimate(c, counts))
            .fold(0.0, f64::max)
    };

    let mut budget = a.first as f64 * npix as f64;
    let mut pass = a.pilot;
    let mut done = [plan.pixels[0] == 0, plan.pixels[1] == 0];
    let mut target = counts.clone();
    let mut next = counts.clone();
    loop {
        // Each colour's stop depends on its own estimate, which is computed from the
        // other colour's pilot samples (module documentation).
        for (c, d) in done.iter_mut().enumerate() {
            let full = (0..coords.len()).all(|p| !plan.is(p, c) || counts[p] >= MAX_SPP);
            if a.target_error
                .is_some_and(|e| plan.estimate(c, &counts) <= e)
                || full
            {
                *d = true;
            }
        }
        if done == [true, true] {
            break;
        }
        let capped = a.max_mean_spp.is_some_and(|m| budget >= m * npix as f64);
        if let Some(m) = a.max_mean_spp {
            budget = budget.min(m * npix as f64);
        }
        target.copy_from_slice(&counts);
        for c in (0..2).filter(|&c| !done[c]) {
            plan.targets(budget, c, &target, &mut next);
            target.copy_from_slice(&next);
        }
        let new: u64 = target
            .iter()
            .zip(&counts)
            .map(|(&t, &c)| (t - c) as u64)
            .sum();
        if new > 0 {
            if !fits(per_sample * new as f64 * SAFETY) {
                break;
            }
            per_sample = refine(&target, &mut sums, &mut counts, &mut film, &mut rays, None);
            emit(pass, &film, &counts, Some(estimate(&counts)))?;
            pass += 1;
        }
        if capped {
            // The sample budget's last pass is rendered.
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic pseudo-random number in [0, 1) from `i`.
    fn noise(i: u64) -> f64 {
        let mut z = i.wrapping_mul(0x9e37_79b9_7f4a_7c15);
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }

    /// The property the unbiasedness rests on: the counts and the error estimate of
    /// one colour's pixels do not change, at any budget, when every pilot statistic
    /// of that colour's own pixels changes; and they do change with the other
    /// colour's (so the test can fail).
    #[test]
    fn a_colours_counts_depend_only_on_the_other_colours_pilot() {
        for (w, h, parity) in [(7u32, 5u32, 0u8), (6, 4, 1), (1, 9, 0), (9, 1, 1)] {
            let n = (w * h) as usize;
            let colour = |p: usize| ((p % w as usize + p / w as usize) as u8 + parity) & 1;
            let var: Vec<f64> = (0..n).map(|p| noise(p as u64) * 0.1).collect();
            let cost: Vec<f64> = (0..n).map(|p| 1.0 + 8.0 * noise(1000 + p as u64)).collect();
            let counts = vec![4u32; n];
            let base = Plan::new(w, h, parity, &var, &cost);
            for c in 0..2usize {
                // Change colour c's own statistics, then the other colour's.
                for (own, salt) in [(true, 7u64), (false, 9)] {
                    let pick = |p: usize| (colour(p) as usize == c) == own;
                    let var2: Vec<f64> = (0..n)
                        .map(|p| {
                            if pick(p) {
                                noise(salt * 31 + p as u64)
                            } else {
                                var[p]
                            }
                        })
                        .collect();
                    let cost2: Vec<f64> = (0..n)
                        .map(|p| {
                            if pick(p) {
                                1.0 + 30.0 * noise(salt * 77 + p as u64)
                            } else {
                                cost[p]
                            }
                        })
                        .collect();
                    let other = Plan::new(w, h, parity, &var2, &cost2);
                    let mut same = other.estimate(c, &counts) == base.estimate(c, &counts);
                    for budget in [4.0, 6.0, 9.5, 40.0, 333.0] {
                        let b = budget * n as f64;
                        let (mut t1, mut t2) = (vec![0; n], vec![0; n]);
                        base.targets(b, c, &counts, &mut t1);
                        other.targets(b, c, &counts, &mut t2);
                        same &= t1 == t2;
                    }
                    assert_eq!(same, own, "{w}x{h} colour {c}, changed own pixels: {own}");
                }
            }
        }
    }

    /// Samples go where the neighbours vary, in proportion to `sqrt(v / c)`; a colour's
    /// counts add up to its share of the budget (up to rounding); nothing falls below
    /// what a pixel has.
    #[test]
    fn targets_follow_the_neighbours_variance() {
        // 8 x 8: the right half varies (variance 0.04), the left half is flat.
        let n = 64;
        let var: Vec<f64> = (0..n)
            .map(|p| if p % 8 >= 4 { 0.04 } else { 0.0 })
            .collect();
        let plan = Plan::new(8, 8, 0, &var, &vec![1.0; n]);
        let counts = vec![4u32; n];
        let mut t = vec![0; n];
        plan.targets(32.0 * n as f64, 0, &counts, &mut t);
        let of = |x: usize, y: usize| t[y * 8 + x] as f64;
        // Colour 0: (x + y) even. Deep in the varying half against deep in the flat
        // half: weights sqrt(0.04 + 0.05 * 0.02) and sqrt(0.05 * 0.02), ratio 6.40
        // (shares about 54 and 8.4, rounded).
        let ratio = of(6, 0) / of(1, 1);
        assert!((5.5..7.5).contains(&ratio), "{ratio}: {t:?}");
        for (p, &tp) in t.iter().enumerate() {
            if (p % 8 + p / 8) % 2 == 1 {
                assert_eq!(tp, 4, "the other colour is untouched");
            }
            assert!(tp >= 4);
        }
        let total: u32 = (0..n)
            .filter(|p| (p % 8 + p / 8) % 2 == 0)
            .map(|p| t[p])
            .sum();
        // The colour's share is 32 * 32 = 1024 samples, each of 32 pixels rounded.
        assert!((1024 - 16..=1024 + 16).contains(&total), "{total}");
        assert!(plan.estimate(0, &t) < plan.estimate(0, &counts));
    }
}
