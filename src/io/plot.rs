//! SVG plots (plotters): line charts with optional log axes. SVG needs no
//! font files, so plots render the same on every machine.

use crate::error::{Error, Result};
use plotters::prelude::*;
use std::path::Path;

/// One named line of points.
pub struct Series {
    /// Legend text.
    pub name: String,
    /// Points `(x, y)`; non-finite ones (and non-positive ones on a log axis) are dropped.
    pub points: Vec<(f64, f64)>,
    /// Also draw a marker at every point.
    pub markers: bool,
}

/// Axis labels and scales of a chart.
pub struct Axes<'a> {
    /// Chart title.
    pub title: &'a str,
    /// x-axis label.
    pub x: &'a str,
    /// y-axis label.
    pub y: &'a str,
    /// Logarithmic x axis.
    pub log_x: bool,
    /// Logarithmic y axis.
    pub log_y: bool,
}

const COLOURS: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
];

fn range(values: impl Iterator<Item = f64>, log: bool) -> (f64, f64) {
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
    if !lo.is_finite() {
        return if log { (0.1, 10.0) } else { (0.0, 1.0) };
    }
    if log {
        (lo / 1.3, hi * 1.3)
    } else {
        let pad = ((hi - lo) * 0.05).max(1e-12 + hi.abs() * 1e-6);
        (lo - pad, hi + pad)
    }
}

/// A short tick label: 3 significant digits, scientific outside [0.01, 1e4).
fn tick(v: f64) -> String {
    if v != 0.0 && !(0.01..1e4).contains(&v.abs()) {
        format!("{v:.1e}")
    } else {
        let s = format!("{v:.3}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    }
}

/// Draws `series` into an SVG file of 800 x 560 pixels.
pub fn line_chart(path: &Path, axes: &Axes, series: &[Series]) -> Result<()> {
    let keep = |x: f64, y: f64| x.is_finite() && y.is_finite() && (!axes.log_x || x > 0.0) && (!axes.log_y || y > 0.0);
    let clean: Vec<Vec<(f64, f64)>> =
        series.iter().map(|s| s.points.iter().copied().filter(|&(x, y)| keep(x, y)).collect()).collect();
    let (x0, x1) = range(clean.iter().flatten().map(|p| p.0), axes.log_x);
    let (y0, y1) = range(clean.iter().flatten().map(|p| p.1), axes.log_y);
    let err = |e: &dyn std::fmt::Display| Error(format!("plot {}: {e}", path.display()));
    let root = SVGBackend::new(path, (800, 560)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let mut builder = ChartBuilder::on(&root);
    builder.caption(axes.title, ("sans-serif", 22)).margin(16).x_label_area_size(48).y_label_area_size(72);
    macro_rules! draw {
        ($chart:expr) => {{
            let mut chart = $chart.map_err(|e| err(&e))?;
            chart
                .configure_mesh()
                .x_desc(axes.x)
                .y_desc(axes.y)
                .x_label_formatter(&|v| tick(*v))
                .y_label_formatter(&|v| tick(*v))
                .draw()
                .map_err(|e| err(&e))?;
            for (i, (s, pts)) in series.iter().zip(&clean).enumerate() {
                let colour = COLOURS[i % COLOURS.len()];
                chart
                    .draw_series(LineSeries::new(pts.iter().copied(), colour.stroke_width(2)))
                    .map_err(|e| err(&e))?
                    .label(s.name.as_str())
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2)));
                if s.markers {
                    chart.draw_series(pts.iter().map(|&p| Circle::new(p, 3, colour.filled()))).map_err(|e| err(&e))?;
                }
            }
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::LowerLeft)
                .background_style(WHITE.mix(0.8))
                .border_style(BLACK)
                .draw()
                .map_err(|e| err(&e))?;
        }};
    }
    match (axes.log_x, axes.log_y) {
        (false, false) => draw!(builder.build_cartesian_2d(x0..x1, y0..y1)),
        (true, false) => draw!(builder.build_cartesian_2d((x0..x1).log_scale(), y0..y1)),
        (false, true) => draw!(builder.build_cartesian_2d(x0..x1, (y0..y1).log_scale())),
        (true, true) => draw!(builder.build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())),
    }
    root.present().map_err(|e| err(&e))
}
