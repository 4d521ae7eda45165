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
            .build_cartesian_2d(xr.log_scale(), yr.log_scale())
            .map_err(|e| plot_err(&e))?;
        chart
            .configure_mesh()
            .x_desc(x_label)
            .y_desc(y_label)
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

#[cfg(test)]
mod tests {
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
