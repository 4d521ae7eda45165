//! Error against run time for distribution ray tracing (Cook, Porter, Carpenter 1984;
//! Cook 1986): render a high-sample reference, then each strategy at a series of
//! sample budgets, and record seconds and RMSE/PSNR against the reference.
//!
//! Strategies at equal budget `B` samples per pixel:
//! - one per sample pattern, all samples spent on the eye (`B` eye x 1 shadow);
//! - the eye/shadow splits of Cook's paper with the jittered pattern: `1 x B`
//!   (one eye sample, `B` shadow rays per area light) and `√B x √B` (square `B`),
//!   besides `B x 1` above.
//!
//! The slope of `log(error)` against `log(time)` is fitted per strategy by least
//! squares; Monte Carlo error falls as `N^-1/2` (slope -0.5), stratification does
//! better where the integrand is smooth inside strata.

use crate::accel::{AccelKind, SceneAccel};
use crate::error::{Error, Result};
use crate::film::Film;
use crate::integrator::{RenderOptions, SamplerKind, whitted};
use crate::plot::{Series, loglog_svg};
use crate::scene::Scene;
use std::io::Write;
use std::path::Path;

/// What to measure.
#[derive(Clone, Debug)]
pub struct ConvergeOptions {
    pub width: u32,
    pub height: u32,
    pub seed: u64,
    /// Reference: eye samples and shadow samples, jittered.
    pub reference_eye: u32,
    pub reference_shadow: u32,
    /// Total samples per pixel (eye x shadow) of each measured render.
    pub budgets: Vec<u32>,
    pub samplers: Vec<SamplerKind>,
    /// Also measure the eye/shadow splits (1 x B, √B x √B).
    pub splits: bool,
    pub accel: AccelKind,
}

impl Default for ConvergeOptions {
    fn default() -> Self {
        ConvergeOptions {
            width: 64,
            height: 64,
            seed: 1,
            reference_eye: 1024,
            reference_shadow: 16,
            budgets: vec![1, 4, 16, 64],
            samplers: SamplerKind::ALL.to_vec(),
            splits: true,
            accel: AccelKind::Bvh4,
        }
    }
}

/// One measured render.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ConvergeRow {
    pub strategy: String,
    pub sampler: SamplerKind,
    pub budget: u32,
    pub eye: u32,
    pub shadow: u32,
    pub seconds: f64,
    pub rmse: f64,
    pub psnr: f64,
    pub rays: u64,
}

/// Fitted slopes of one strategy.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Slope {
    pub strategy: String,
    /// d log(RMSE) / d log(seconds).
    pub vs_time: f64,
    /// d log(RMSE) / d log(budget).
    pub vs_budget: f64,
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct ConvergeReport {
    pub reference_seconds: f64,
    pub rows: Vec<ConvergeRow>,
    pub slopes: Vec<Slope>,
}

/// A strategy: a name and the (sampler, eye, shadow) it uses at budget `b`.
struct Strategy {
    name: String,
    sampler: SamplerKind,
    split: fn(u32) -> Option<(u32, u32)>,
}

fn strategies(o: &ConvergeOptions) -> Vec<Strategy> {
    let mut s: Vec<Strategy> = o
        .samplers
        .iter()
        .map(|&k| Strategy {
            name: format!("{k} Bx1"),
            sampler: k,
            split: |b| Some((b, 1)),
        })
        .collect();
    if o.splits {
        s.push(Strategy {
            name: "jittered 1xB".into(),
            sampler: SamplerKind::Jittered,
            split: |b| Some((1, b)),
        });
        s.push(Strategy {
            name: "jittered √Bx√B".into(),
            sampler: SamplerKind::Jittered,
            split: |b| {
                let k = b.isqrt();
                (k * k == b).then_some((k, k))
            },
        });
    }
    s
}

/// Renders once with the given counts; the film and the seconds it took.
pub fn render_counts(
    scene: &Scene,
    accel: &SceneAccel,
    base: &RenderOptions,
    sampler: SamplerKind,
    eye: u32,
    shadow: u32,
) -> Result<(Film, f64, u64)> {
    let mut o = base.clone();
    o.sampler = sampler;
    o.spp = eye;
    o.samples.shadow = shadow;
    o.validate()?;
    let out = whitted::render(scene, accel, &o);
    Ok((out.film, out.render_ms / 1e3, out.rays.total()))
}

/// Runs the whole measurement; `row` is called as each render finishes.
pub fn run(
    scene: &Scene,
    opts: &ConvergeOptions,
    mut row: impl FnMut(&ConvergeRow),
) -> Result<ConvergeReport> {
    if opts.budgets.is_empty() || opts.budgets.contains(&0) {
        return Err(Error::parameter(
            "budgets",
            "need at least one budget, each >= 1",
        ));
    }
    let accel = SceneAccel::build(scene, opts.accel);
    let mut base = RenderOptions::from_scene(scene);
    base.width = opts.width;
    base.height = opts.height;
    // A seed unrelated to the measured renders', so the reference's errors are
    // independent of theirs.
    base.seed = opts.seed ^ 0x5eed_5eed_5eed_5eed;
    let (reference, reference_seconds, _) = render_counts(
        scene,
        &accel,
        &base,
        SamplerKind::Jittered,
        opts.reference_eye,
        opts.reference_shadow,
    )?;
    base.seed = opts.seed;
    let mut rows = Vec::new();
    for s in strategies(opts) {
        for &b in &opts.budgets {
            let Some((eye, shadow)) = (s.split)(b) else {
                continue;
            };
            let (film, seconds, rays) =
                render_counts(scene, &accel, &base, s.sampler, eye, shadow)?;
            let r = ConvergeRow {
                strategy: s.name.clone(),
                sampler: s.sampler,
                budget: b,
                eye,
                shadow,
                seconds,
                rmse: film.rmse(&reference)?,
                psnr: film.psnr(&reference)?,
                rays,
            };
            row(&r);
            rows.push(r);
        }
    }
    let slopes = slopes(&rows);
    Ok(ConvergeReport {
        reference_seconds,
        rows,
        slopes,
    })
}

fn slopes(rows: &[ConvergeRow]) -> Vec<Slope> {
    let mut names: Vec<&str> = Vec::new();
    for r in rows {
        if !names.contains(&r.strategy.as_str()) {
            names.push(&r.strategy);
        }
    }
    names
        .into_iter()
        .map(|n| {
            let pts: Vec<&ConvergeRow> = rows.iter().filter(|r| r.strategy == n).collect();
            let time: Vec<(f64, f64)> = pts.iter().map(|r| (r.seconds, r.rmse)).collect();
            let budget: Vec<(f64, f64)> = pts.iter().map(|r| (r.budget as f64, r.rmse)).collect();
            Slope {
                strategy: n.to_string(),
                vs_time: loglog_slope(&time),
                vs_budget: loglog_slope(&budget),
            }
        })
        .collect()
}

/// Least-squares slope of `log y` against `log x`; NaN with fewer than two usable points.
pub fn loglog_slope(points: &[(f64, f64)]) -> f64 {
    let p: Vec<(f64, f64)> = points
        .iter()
        .filter(|(x, y)| *x > 0.0 && *y > 0.0 && x.is_finite() && y.is_finite())
        .map(|(x, y)| (x.ln(), y.ln()))
        .collect();
    if p.len() < 2 {
        return f64::NAN;
    }
    let n = p.len() as f64;
    let mx = p.iter().map(|q| q.0).sum::<f64>() / n;
    let my = p.iter().map(|q| q.1).sum::<f64>() / n;
    let sxy: f64 = p.iter().map(|q| (q.0 - mx) * (q.1 - my)).sum();
    let sxx: f64 = p.iter().map(|q| (q.0 - mx).powi(2)).sum();
    if sxx == 0.0 { f64::NAN } else { sxy / sxx }
}

impl ConvergeReport {
    /// The rows as a Markdown table.
    pub fn table(&self) -> String {
        let mut s = String::from(
            "| strategy | budget | eye | shadow | seconds | rays | RMSE | PSNR (dB) |\n|---|---:|---:|---:|---:|---:|---:|---:|\n",
        );
        for r in &self.rows {
            s += &format!(
                "| {} | {} | {} | {} | {:.4} | {} | {:.5} | {:.2} |\n",
                r.strategy, r.budget, r.eye, r.shadow, r.seconds, r.rays, r.rmse, r.psnr
            );
        }
        s
    }

    /// The fitted slopes as a Markdown table.
    pub fn slope_table(&self) -> String {
        let mut s =
            String::from("| strategy | slope vs time | slope vs budget |\n|---|---:|---:|\n");
        for l in &self.slopes {
            s += &format!(
                "| {} | {:.3} | {:.3} |\n",
                l.strategy, l.vs_time, l.vs_budget
            );
        }
        s
    }

    pub fn write_csv(&self, path: &Path) -> Result<()> {
        let mut text = String::from("strategy,sampler,budget,eye,shadow,seconds,rays,rmse,psnr\n");
        for r in &self.rows {
            text += &format!(
                "{},{},{},{},{},{:.6},{},{:.8},{:.4}\n",
                r.strategy, r.sampler, r.budget, r.eye, r.shadow, r.seconds, r.rays, r.rmse, r.psnr
            );
        }
        crate::film::write_atomic(path, |out| {
            out.write_all(text.as_bytes())
                .map_err(|e| Error::io(path, e))
        })
    }

    /// Log-log RMSE against seconds, one line per strategy.
    pub fn write_plot(&self, path: &Path, title: &str) -> Result<()> {
        let mut series: Vec<Series> = Vec::new();
        for r in &self.rows {
            match series.iter_mut().find(|s| s.name == r.strategy) {
                Some(s) => s.points.push((r.seconds, r.rmse)),
                None => series.push(Series {
                    name: r.strategy.clone(),
                    points: vec![(r.seconds, r.rmse)],
                }),
            }
        }
        loglog_svg(path, title, "render time (s)", "RMSE vs reference", &series)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slope_of_a_power_law() {
        let pts: Vec<(f64, f64)> = [1.0, 4.0, 16.0, 64.0]
            .iter()
            .map(|&n: &f64| (n, 3.0 * n.powf(-0.5)))
            .collect();
        assert!((loglog_slope(&pts) + 0.5).abs() < 1e-12);
        assert!(loglog_slope(&pts[..1]).is_nan());
    }
}
