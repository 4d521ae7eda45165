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
//! Two errors per render: `rmse`, over linear radiance, and `display_rmse`, over what
//! the PNG shows (each channel clamped to [0, 1] and sRGB-encoded, as
//! [`Film::to_srgb8`] does, before its 8-bit rounding). Directly visible emitters
//! (radiance 5-30 in `scenes/area_lights.toml`) dominate the linear RMSE through their
//! edge pixels, which no number of shadow samples changes: it stayed at 0.2932-0.2934
//! from 1 to 64 shadow samples while the penumbrae visibly converged. The display
//! error weighs an emitter edge as the viewer sees it (white against the background)
//! and follows the shadows; it is the one plotted.
//!
//! The slope of `log(error)` against `log(time)` is fitted per strategy by least
//! squares; Monte Carlo error falls as `N^-1/2` (slope -0.5), stratification does
//! better where the integrand is smooth inside strata.

use crate::accel::{AccelKind, SceneAccel};
use crate::error::{Error, Result};
use crate::film::{Film, linear_to_srgb};
use crate::integrator::adaptive::{self, AdaptiveOptions};
use crate::integrator::{RenderOptions, SamplerKind, recursive};
use crate::plot::{Series, loglog_svg};
use crate::scene::Scene;
use std::io::Write;
use std::path::Path;
use std::time::Instant;

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
    /// Also measure progressive adaptive rendering ([`adaptive`]) at mean budget `B`
    /// (its seconds include every pass), and its error at equal time against jittered
    /// and sobol `Bx1`.
    pub adaptive: bool,
    /// Renders per measurement; the fastest one's seconds are reported (on a shared
    /// machine the minimum is the least disturbed).
    pub reps: u32,
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
            adaptive: true,
            reps: 1,
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
    /// RMSE over linear radiance.
    pub rmse: f64,
    /// PSNR of `rmse` against a peak of 1.
    pub psnr: f64,
    /// RMSE over the displayed values (clamped, sRGB-encoded, in [0, 1]).
    pub display_rmse: f64,
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
    /// The same two slopes of the display RMSE.
    pub display_vs_time: f64,
    pub display_vs_budget: f64,
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct ConvergeReport {
    pub reference_seconds: f64,
    pub rows: Vec<ConvergeRow>,
    pub slopes: Vec<Slope>,
    /// Adaptive against jittered and sobol `Bx1` at equal seconds, one per adaptive
    /// render.
    pub equal_time: Vec<EqualTime>,
}

/// The adaptive strategy's display RMSE against uniform sampling's at the same
/// seconds: a uniform strategy's display RMSE interpolated linearly in log-log between
/// its two measured renders that bracket the adaptive render's seconds (`None` where
/// none do, or the strategy was not measured).
#[derive(Clone, Debug, serde::Serialize)]
pub struct EqualTime {
    pub budget: u32,
    pub seconds: f64,
    pub adaptive_display_rmse: f64,
    /// `jittered Bx1` at equal seconds (the issue's comparison).
    pub jittered_display_rmse: Option<f64>,
    /// `adaptive / jittered`: below 1 is better.
    pub ratio: Option<f64>,
    /// `sobol Bx1` (the same samples, uniformly spent) at equal seconds.
    pub sobol_display_rmse: Option<f64>,
    pub sobol_ratio: Option<f64>,
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
    let out = recursive::render(scene, accel, &o);
    Ok((out.film, out.render_ms / 1e3, out.rays.total()))
}

/// Runs the whole measurement; `row` is called for each render at the end.
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
    // Every render once, then the repetitions round-robin over all of them, so that a
    // change of the machine's load during the run slows every strategy alike instead of
    // the ones measured while it lasts; each render's time is its fastest repetition.
    // (Measured strategy by strategy, with the 3 repetitions back to back, sobol took
    // 0.41 s at 16 samples against jittered's 0.20 s on the loaded machine, where a
    // quiet 1-thread run of both at 64 samples gives 1.83 s against 1.64 s.)
    struct Job {
        strategy: String,
        sampler: SamplerKind,
        budget: u32,
        eye: u32,
        shadow: u32,
        adaptive: bool,
    }
    let mut jobs = Vec::new();
    for s in strategies(opts) {
        for &b in &opts.budgets {
            if let Some((eye, shadow)) = (s.split)(b) {
                jobs.push(Job {
                    strategy: s.name.clone(),
                    sampler: s.sampler,
                    budget: b,
                    eye,
                    shadow,
                    adaptive: false,
                });
            }
        }
    }
    if opts.adaptive {
        for &b in &opts.budgets {
            jobs.push(Job {
                strategy: ADAPTIVE.into(),
                sampler: SamplerKind::Sobol,
                budget: b,
                eye: b,
                shadow: 1,
                adaptive: true,
            });
        }
    }
    let measure = |j: &Job| -> Result<(Film, f64, u64)> {
        if !j.adaptive {
            return render_counts(scene, &accel, &base, j.sampler, j.eye, j.shadow);
        }
        let mut o = base.clone();
        o.samples.shadow = 1;
        let a = AdaptiveOptions {
            max_mean_spp: Some(j.budget as f64),
            ..Default::default()
        };
        let out = adaptive::render(scene, &accel, &o, &a, Instant::now(), |_, _| Ok(()))?;
        let seconds = out.passes.last().map_or(0.0, |p| p.seconds);
        Ok((out.film, seconds, out.rays.total()))
    };
    let mut rows = Vec::new();
    for j in &jobs {
        let (film, seconds, rays) = measure(j)?;
        rows.push(ConvergeRow {
            strategy: j.strategy.clone(),
            sampler: j.sampler,
            budget: j.budget,
            eye: j.eye,
            shadow: j.shadow,
            seconds,
            rmse: film.rmse(&reference)?,
            psnr: film.psnr(&reference)?,
            display_rmse: display_rmse(&film, &reference)?,
            rays,
        });
    }
    for _ in 1..opts.reps {
        for (j, r) in jobs.iter().zip(rows.iter_mut()) {
            r.seconds = r.seconds.min(measure(j)?.1);
        }
    }
    rows.iter().for_each(&mut row);
    let slopes = slopes(&rows);
    let equal_time = equal_time(&rows);
    Ok(ConvergeReport {
        reference_seconds,
        rows,
        slopes,
        equal_time,
    })
}

/// Name of the adaptive strategy's rows.
pub const ADAPTIVE: &str = "adaptive sobol";

/// A strategy's display RMSE at `t` seconds, interpolated linearly in log-log between
/// its two renders that bracket `t`; `None` outside its range of seconds.
fn at_seconds(rows: &[ConvergeRow], strategy: &str, t: f64) -> Option<f64> {
    let mut pts: Vec<(f64, f64)> = rows
        .iter()
        .filter(|r| r.strategy == strategy)
        .map(|r| (r.seconds, r.display_rmse))
        .collect();
    pts.sort_by(|a, b| a.0.total_cmp(&b.0));
    let w = pts.windows(2).find(|w| w[0].0 <= t && t <= w[1].0)?;
    let (x0, x1) = (w[0].0.ln(), w[1].0.ln());
    let f = if x1 > x0 {
        (t.ln() - x0) / (x1 - x0)
    } else {
        0.0
    };
    Some((w[0].1.ln() + f * (w[1].1.ln() - w[0].1.ln())).exp())
}

fn equal_time(rows: &[ConvergeRow]) -> Vec<EqualTime> {
    rows.iter()
        .filter(|r| r.strategy == ADAPTIVE)
        .map(|r| {
            let t = r.seconds;
            let j = at_seconds(rows, "jittered Bx1", t);
            let s = at_seconds(rows, "sobol Bx1", t);
            EqualTime {
                budget: r.budget,
                seconds: t,
                adaptive_display_rmse: r.display_rmse,
                jittered_display_rmse: j,
                ratio: j.map(|j| r.display_rmse / j),
                sobol_display_rmse: s,
                sobol_ratio: s.map(|s| r.display_rmse / s),
            }
        })
        .collect()
}

/// One number of a row, for fitting slopes.
type Field = fn(&ConvergeRow) -> f64;

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
            let slope = |x: Field, y: Field| {
                loglog_slope(&pts.iter().map(|r| (x(r), y(r))).collect::<Vec<_>>())
            };
            let time: Field = |r| r.seconds;
            let budget: Field = |r| r.budget as f64;
            Slope {
                strategy: n.to_string(),
                vs_time: slope(time, |r| r.rmse),
                vs_budget: slope(budget, |r| r.rmse),
                display_vs_time: slope(time, |r| r.display_rmse),
                display_vs_budget: slope(budget, |r| r.display_rmse),
            }
        })
        .collect()
}

/// RMSE between two films as the PNG shows them: every channel clamped to [0, 1] (NaN
/// as 0) and encoded with the sRGB OETF, as [`Film::to_srgb8`] does before rounding to
/// 8 bits, so the error is in display units (1 = black against white). Films of
/// different sizes are an error.
pub fn display_rmse(a: &Film, b: &Film) -> Result<f64> {
    a.same_size(b)?;
    if a.pixels.is_empty() {
        return Ok(0.0);
    }
    let shown = |c: f32| {
        let c = if c.is_nan() { 0.0 } else { c.clamp(0.0, 1.0) };
        linear_to_srgb(c) as f64
    };
    let sum: f64 = a
        .pixels
        .iter()
        .zip(&b.pixels)
        .flat_map(|(p, q)| (0..3).map(move |c| (shown(p[c]) - shown(q[c])).powi(2)))
        .sum();
    Ok((sum / (3 * a.pixels.len()) as f64).sqrt())
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
            "| strategy | budget | eye | shadow | seconds | rays | RMSE | PSNR (dB) | display RMSE |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|\n",
        );
        for r in &self.rows {
            s += &format!(
                "| {} | {} | {} | {} | {:.4} | {} | {:.5} | {:.2} | {:.5} |\n",
                r.strategy,
                r.budget,
                r.eye,
                r.shadow,
                r.seconds,
                r.rays,
                r.rmse,
                r.psnr,
                r.display_rmse
            );
        }
        s
    }

    /// The equal-time comparison as a Markdown table (`-`: the adaptive render's
    /// seconds are outside the uniform strategy's measured range).
    pub fn equal_time_table(&self) -> String {
        let mut s = String::from(
            "| adaptive budget | seconds | adaptive display RMSE | jittered Bx1 at equal time | ratio | sobol Bx1 at equal time | ratio |\n|---:|---:|---:|---:|---:|---:|---:|\n",
        );
        let num = |v: Option<f64>, digits: usize| v.map_or("-".into(), |v| format!("{v:.digits$}"));
        for e in &self.equal_time {
            s += &format!(
                "| {} | {:.4} | {:.5} | {} | {} | {} | {} |\n",
                e.budget,
                e.seconds,
                e.adaptive_display_rmse,
                num(e.jittered_display_rmse, 5),
                num(e.ratio, 2),
                num(e.sobol_display_rmse, 5),
                num(e.sobol_ratio, 2)
            );
        }
        s
    }

    /// The fitted slopes as a Markdown table.
    pub fn slope_table(&self) -> String {
        let mut s = String::from(
            "| strategy | slope vs time | slope vs budget | display: vs time | display: vs budget |\n|---|---:|---:|---:|---:|\n",
        );
        for l in &self.slopes {
            s += &format!(
                "| {} | {:.3} | {:.3} | {:.3} | {:.3} |\n",
                l.strategy, l.vs_time, l.vs_budget, l.display_vs_time, l.display_vs_budget
            );
        }
        s
    }

    pub fn write_csv(&self, path: &Path) -> Result<()> {
        let mut text = String::from(
            "strategy,sampler,budget,eye,shadow,seconds,rays,rmse,psnr,display_rmse\n",
        );
        for r in &self.rows {
            text += &format!(
                "{},{},{},{},{},{:.6},{},{:.8},{:.4},{:.8}\n",
                r.strategy,
                r.sampler,
                r.budget,
                r.eye,
                r.shadow,
                r.seconds,
                r.rays,
                r.rmse,
                r.psnr,
                r.display_rmse
            );
        }
        crate::film::write_atomic(path, |out| {
            out.write_all(text.as_bytes())
                .map_err(|e| Error::io(path, e))
        })
    }

    /// Log-log display RMSE against seconds, one line per strategy.
    pub fn write_plot(&self, path: &Path, title: &str) -> Result<()> {
        let mut series: Vec<Series> = Vec::new();
        for r in &self.rows {
            match series.iter_mut().find(|s| s.name == r.strategy) {
                Some(s) => s.points.push((r.seconds, r.display_rmse)),
                None => series.push(Series {
                    name: r.strategy.clone(),
                    points: vec![(r.seconds, r.display_rmse)],
                }),
            }
        }
        loglog_svg(
            path,
            title,
            "render time (s)",
            "RMSE vs reference, displayed values (clamped, sRGB)",
            &series,
        )
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

    fn row(strategy: &str, seconds: f64, display_rmse: f64) -> ConvergeRow {
        ConvergeRow {
            strategy: strategy.into(),
            sampler: SamplerKind::Sobol,
            budget: 1,
            eye: 1,
            shadow: 1,
            seconds,
            rmse: display_rmse,
            psnr: 0.0,
            display_rmse,
            rays: 0,
        }
    }

    /// Equal time: a uniform strategy's error is interpolated in log-log between the
    /// two renders that bracket the adaptive render's seconds (on a power law
    /// `e = 0.1 t^-0.5` the interpolation is exact), and nothing is extrapolated.
    #[test]
    fn equal_time_interpolates_in_log_log_and_never_extrapolates() {
        let rows = vec![
            row("jittered Bx1", 1.0, 0.1),
            row("jittered Bx1", 4.0, 0.05),
            row("sobol Bx1", 1.0, 0.08),
            row("sobol Bx1", 2.0, 0.04),
            row(ADAPTIVE, 2.0, 0.0212),
            row(ADAPTIVE, 8.0, 0.01),
        ];
        let e = equal_time(&rows);
        assert_eq!(e.len(), 2);
        let j = e[0].jittered_display_rmse.unwrap();
        assert!((j - 0.1 / 2f64.sqrt()).abs() < 1e-12, "{j}");
        assert!((e[0].ratio.unwrap() - 0.0212 / j).abs() < 1e-12);
        // At a bracket's end: that render's error (up to exp(ln x) rounding).
        assert!((e[0].sobol_display_rmse.unwrap() - 0.04).abs() < 1e-15);
        assert_eq!(e[1].jittered_display_rmse, None);
        assert_eq!(e[1].sobol_ratio, None);
        let report = ConvergeReport {
            reference_seconds: 0.0,
            rows,
            slopes: Vec::new(),
            equal_time: e,
        };
        assert!(
            report
                .equal_time_table()
                .contains("| 8.0000 | 0.01000 | - | - | - | - |")
        );
    }

    /// Bright visible emitters over a wide penumbra (the lights of
    /// `scenes/area_lights.toml`, seen from above): with one eye sample per pixel,
    /// going from 1 to 16 shadow samples leaves the linear RMSE where it is (within
    /// 2 %: the sphere light's edge pixels, off by radiance ~25 against a 64-eye
    /// reference, dominate it), while the display RMSE, what the PNG shows, falls by a
    /// factor above 1.2 (measured 1.30). Not 4: only its shadow-noise part falls as
    /// 1/√16; the edge aliasing of one eye sample per pixel (floor, sphere and light
    /// silhouettes), which it also counts, is fixed.
    #[test]
    fn display_error_follows_shadow_samples_where_linear_error_is_flat() {
        let text = r#"
            background = [0.02, 0.02, 0.03]
            [camera]
            eye = [0, 4.5, 2.0]
            target = [0, 0, 0]
            fov = 50
            [materials.floor]
            diffuse = [0.75, 0.75, 0.75]
            [materials.orange]
            diffuse = [0.9, 0.5, 0.15]
            [[plane]]
            point = [0, 0, 0]
            normal = [0, 1, 0]
            size = 10
            material = "floor"
            [[sphere]]
            center = [-0.3, 0.9, 0]
            radius = 0.4
            material = "orange"
            [[light]]
            type = "disk"
            center = [0.2, 2.0, 0.1]
            normal = [0, -1, 0]
            radius = 0.8
            radiance = [3, 2.7, 2.4]
            [[light]]
            type = "sphere"
            center = [1.2, 1.2, 0.6]
            radius = 0.2
            radiance = [25, 25, 30]
        "#;
        let scene = crate::scene::load::parse_toml_scene(text, Path::new("converge.toml")).unwrap();
        let opts = ConvergeOptions {
            width: 48,
            height: 36,
            reference_eye: 64,
            reference_shadow: 16,
            budgets: vec![1, 16],
            samplers: Vec::new(),
            splits: true,
            ..Default::default()
        };
        let report = run(&scene, &opts, |_| {}).unwrap();
        let row = |shadow| {
            report
                .rows
                .iter()
                .find(|r| r.strategy == "jittered 1xB" && r.shadow == shadow)
                .unwrap()
        };
        let (one, sixteen) = (row(1), row(16));
        let linear = one.rmse / sixteen.rmse;
        let display = one.display_rmse / sixteen.display_rmse;
        eprintln!(
            "1 -> 16 shadow samples: linear RMSE {:.5} -> {:.5} (x{linear:.3}), display {:.5} -> {:.5} (x{display:.3})",
            one.rmse, sixteen.rmse, one.display_rmse, sixteen.display_rmse
        );
        assert!(display > 1.2, "display RMSE fell only x{display:.3}");
        assert!(
            linear < 1.02,
            "linear RMSE fell x{linear:.3}: not the flat case"
        );
        assert!(report.table().contains("display RMSE"));
    }
}
