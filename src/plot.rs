//! Log-log line plots as SVG, for convergence (error against time) and scaling
//! (time against primitive count) reports. Drawn with `plotters` (SVG backend only).

use crate::error::{Error, Result};
use plotters::prelude::*;
use std::path::Path;

/// One named line of `(x, y)` points; points with a non-positive coordinate cannot be
/// shown on log axes and are dropped.
#[derive(Clone, Debug)]
pub struct Series {
    pub name: String,
    pub points: Vec<(f64, f64)>,
}

/// Writes a log-log plot of `series` to `path` (SVG), atomically.
pub fn loglog_svg(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
) -> Result<()> {
    let svg = loglog_svg_string(title, x_label, y_label, series)?;
    crate::film::write_atomic(path, |out| {
        use std::io::Write;
        out.write_all(svg.as_bytes())
            .map_err(|e| Error::io(path, e))
    })
}

/// The same plot as an SVG document in a string.
pub fn loglog_svg_string(
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
) -> Result<String> {
    let shown: Vec<Vec<(f64, f64)>> = series
        .iter()
        .map(|s| {
            s.points
                .iter()
                .copied()
                .filter(|(x, y)| *x > 0.0 && *y > 0.0 && x.is_finite() && y.is_finite())
                .collect()
        })
        .collect();
    let all: Vec<(f64, f64)> = shown.iter().flatten().copied().collect();
    if all.is_empty() {
        return Err(Error::parameter(
            "plot",
            format!("'{title}': no positive, finite points to plot"),
        ));
    }
    let range = |f: fn(&(f64, f64)) -> f64| {
        let lo = all.iter().map(f).fold(f64::INFINITY, f64::min);
        let hi = all.iter().map(f).fold(f64::NEG_INFINITY, f64::max);
        // pad by a factor so lines do not sit on the frame; a single value gets a decade
        if hi > lo {
            (lo / 1.2)..(hi * 1.2)
        } else {
            (lo / 3.0)..(hi * 3.0)
        }
    };
    let (xr, yr) = (range(|p| p.0), range(|p| p.1));
    // Plot area of about 700 x 470 px: at most one tick label per 70 px across (a label
    // is up to 6 characters of ~6 px) and per 40 px up.
    let (xt, yt) = (
        log_ticks(xr.start, xr.end, 10),
        log_ticks(yr.start, yr.end, 11),
    );
    let mut svg = String::new();
    {
        let plot_err = |e: &dyn std::fmt::Display| Error::parameter("plot", e.to_string());
        let root = SVGBackend::with_string(&mut svg, (800, 560)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| plot_err(&e))?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 22))
            .margin(16)
            .x_label_area_size(44)
            .y_label_area_size(64)
            .build_cartesian_2d(
                xr.log_scale().with_key_points(xt),
                yr.log_scale().with_key_points(yt),
            )
            .map_err(|e| plot_err(&e))?;
        chart
            .configure_mesh()
            .x_desc(x_label)
            .y_desc(y_label)
            .x_label_formatter(&|v| tick_label(*v))
            .y_label_formatter(&|v| tick_label(*v))
            .draw()
            .map_err(|e| plot_err(&e))?;
        for (i, (s, pts)) in series.iter().zip(&shown).enumerate() {
            let color = Palette99::pick(i).to_rgba();
            chart
                .draw_series(LineSeries::new(pts.iter().copied(), color.stroke_width(2)))
                .map_err(|e| plot_err(&e))?
                .label(s.name.clone())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2))
                });
            chart
                .draw_series(pts.iter().map(|&p| Circle::new(p, 3, color.filled())))
                .map_err(|e| plot_err(&e))?;
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()
            .map_err(|e| plot_err(&e))?;
        root.present().map_err(|e| plot_err(&e))?;
    }
    Ok(svg)
}

/// Tick values for a log axis over `[lo, hi]` (`0 < lo < hi`): the densest of the
/// per-decade mantissa sets {1, 2, 5}, {1, 3}, {1} that gives at most `max` ticks, else
/// powers of ten thinned to every k-th decade. Ticks are mantissa x power of ten
/// computed from integers, so they print exactly (`0.3`, not `0.30000000000000004`),
/// and the sets never repeat a value, so no two labels land on one spot.
/// A range of less than a decade gets every mantissa 1..9 inside it (thinned to fit).
pub fn log_ticks(lo: f64, hi: f64, max: usize) -> Vec<f64> {
    if !(lo > 0.0 && hi > lo && hi.is_finite()) || max == 0 {
        return Vec::new();
    }
    let (d0, d1) = (lo.log10().floor() as i32, hi.log10().ceil() as i32);
    let decade = |k: i32, m: u32| {
        // m * 10^k, rounded through its decimal form so it is the nearest double.
        format!("{m}e{k}").parse::<f64>().unwrap_or(f64::NAN)
    };
    let ticks = |mantissas: &[u32], step: i32| -> Vec<f64> {
        let mut t = Vec::new();
        let mut k = d0;
        while k <= d1 {
            if (k - d0) % step == 0 {
                for &m in mantissas {
                    let v = decade(k, m);
                    if v >= lo && v <= hi {
                        t.push(v);
                    }
                }
            }
            k += 1;
        }
        t
    };
    for m in [&[1u32, 2, 5][..], &[1, 3], &[1]] {
        let t = ticks(m, 1);
        if t.len() <= max && t.len() >= 2 {
            return t;
        }
    }
    if ticks(&[1], 1).len() < 2 {
        // Less than a decade: every mantissa, thinned to fit.
        let t = ticks(&[1, 2, 3, 4, 5, 6, 7, 8, 9], 1);
        let keep = t.len().div_ceil(max).max(1);
        return t.into_iter().step_by(keep).collect();
    }
    let mut step = 1;
    loop {
        let t = ticks(&[1], step);
        if t.len() <= max {
            return t;
        }
        step += 1;
    }
}

/// A tick label with at most three significant digits and no trailing zeros: `0.3`,
/// `0.05`, `20`, `1e-5` (scientific below 0.001 and from 1e6).
pub fn tick_label(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let e = v.abs().log10().floor() as i32;
    if !(-3..6).contains(&e) {
        let s = format!("{v:.2e}");
        let (m, x) = s.split_once('e').unwrap_or((&s, "0"));
        let m = m.trim_end_matches('0').trim_end_matches('.');
        return format!("{m}e{x}");
    }
    let decimals = (2 - e).max(0) as usize;
    let s = format!("{v:.decimals$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn tick_labels_are_short_and_exact() {
        assert_eq!(tick_label(0.30000000000000004), "0.3");
        assert_eq!(tick_label(0.05), "0.05");
        assert_eq!(tick_label(0.0123456), "0.0123");
        assert_eq!(tick_label(20.0), "20");
        assert_eq!(tick_label(1500.0), "1500");
        assert_eq!(tick_label(1e-5), "1e-5");
        assert_eq!(tick_label(2.5e7), "2.5e7");
    }

    /// The ranges of docs/images/convergence.svg (seconds 0.004..0.33, RMSE
    /// 0.0025..0.035) and a wide one: few enough ticks, increasing, no repeats, all in
    /// range, every label distinct.
    #[test]
    fn log_ticks_are_few_distinct_and_in_range() {
        for (lo, hi, max) in [
            (0.0037, 0.33, 10),
            (0.0025, 0.035, 11),
            (1e-6, 1e3, 6),
            (0.5, 0.9, 10),
        ] {
            let t = log_ticks(lo, hi, max);
            assert!(!t.is_empty() && t.len() <= max, "{lo}..{hi}: {t:?}");
            assert!(t.windows(2).all(|w| w[0] < w[1]), "{t:?}");
            assert!(t.iter().all(|&v| v >= lo && v <= hi), "{t:?}");
            let labels: Vec<String> = t.iter().map(|&v| tick_label(v)).collect();
            let mut unique = labels.clone();
            unique.dedup();
            assert_eq!(unique, labels);
            assert!(labels.iter().all(|l| l.len() <= 6), "{labels:?}");
        }
        // Two decades of time: 1-2-5 ticks, 0.3 decade (about 100 px) apart at least.
        assert_eq!(
            log_ticks(0.0037, 0.33, 10),
            vec![0.005, 0.01, 0.02, 0.05, 0.1, 0.2]
        );
    }

    use super::*;

    #[test]
    fn draws_every_series_and_rejects_empty_plots() {
        let s = vec![
            Series {
                name: "random".into(),
                points: vec![(1.0, 1.0), (10.0, 0.3), (100.0, 0.1)],
            },
            Series {
                name: "jittered".into(),
                points: vec![(1.0, 0.8), (10.0, 0.1), (0.0, 5.0)],
            },
        ];
        let svg = loglog_svg_string("error vs time", "seconds", "RMSE", &s).unwrap();
        assert!(svg.starts_with("<svg") && svg.contains("random") && svg.contains("jittered"));
        let empty = vec![Series {
            name: "none".into(),
            points: vec![(0.0, 1.0)],
        }];
        assert!(loglog_svg_string("t", "x", "y", &empty).is_err());
    }
}
