//! SVG plots (plotters): line charts with optional log axes and panels of
//! grouped bars. SVG needs no font files, so plots render the same on every
//! machine.

use crate::error::{Error, Result};
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
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
pub fn tick(v: f64) -> String {
    if v != 0.0 && !(0.01..1e4).contains(&v.abs()) {
        format!("{v:.1e}")
    } else {
        let s = format!("{v:.3}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    }
}

/// `v` with 3 significant digits in plain decimals, trailing zeros dropped
/// (0.0045, 0.0417, 1.62): values of one scale read alike.
pub fn significant(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let decimals = (2 - v.abs().log10().floor() as i32).clamp(0, 12) as usize;
    let s = format!("{v:.decimals$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
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

/// One group of bars: its label and one value per series.
pub struct BarGroup {
    /// Text under the group.
    pub label: String,
    /// One value per series, in the order of the series names.
    pub values: Vec<f64>,
}

/// One panel of grouped bars with its own y axis (from 0).
pub struct BarPanel {
    /// Panel title.
    pub title: String,
    /// y-axis label.
    pub y: String,
    /// The groups, left to right.
    pub groups: Vec<BarGroup>,
}

/// Draws `panels` side by side into one SVG file, each group a bar per
/// series (named in the first panel's legend), its value written above it.
/// Separate panels let quantities of different scales sit side by side.
pub fn grouped_bars(path: &Path, title: &str, series: &[&str], panels: &[BarPanel]) -> Result<()> {
    let err = |e: &dyn std::fmt::Display| Error(format!("plot {}: {e}", path.display()));
    let base = SVGBackend::new(path, (440 * panels.len().max(1) as u32, 520)).into_drawing_area();
    base.fill(&WHITE).map_err(|e| err(&e))?;
    let root = base.titled(title, ("sans-serif", 20)).map_err(|e| err(&e))?;
    let label_style = TextStyle::from(("sans-serif", 13).into_font()).pos(Pos::new(HPos::Center, VPos::Top));
    let value_style = TextStyle::from(("sans-serif", 12).into_font()).pos(Pos::new(HPos::Center, VPos::Bottom));
    for (p, (area, panel)) in root.split_evenly((1, panels.len().max(1))).iter().zip(panels).enumerate() {
        let n = panel.groups.len().max(1) as f64;
        let hi =
            panel.groups.iter().flat_map(|g| g.values.iter().copied()).filter(|v| v.is_finite()).fold(0.0, f64::max);
        let hi = if hi > 0.0 { hi * 1.2 } else { 1.0 };
        let mut chart = ChartBuilder::on(area)
            .caption(panel.title.as_str(), ("sans-serif", 16))
            .margin(16)
            .x_label_area_size(40)
            .y_label_area_size(72)
            .build_cartesian_2d(0.0..n, 0.0..hi)
            .map_err(|e| err(&e))?;
        chart
            .configure_mesh()
            .disable_x_mesh()
            .x_labels(0)
            .max_light_lines(0)
            .y_desc(panel.y.as_str())
            .y_label_formatter(&|v| significant(*v))
            .draw()
            .map_err(|e| err(&e))?;
        let width = 0.8 / series.len().max(1) as f64;
        for (s, name) in series.iter().enumerate() {
            let colour = COLOURS[s % COLOURS.len()];
            let bars: Vec<(f64, f64)> = panel
                .groups
                .iter()
                .enumerate()
                .filter_map(|(g, grp)| grp.values.get(s).map(|&v| (g as f64 + 0.1 + s as f64 * width, v)))
                .filter(|(_, v)| v.is_finite())
                .collect();
            let drawn = chart
                .draw_series(bars.iter().map(|&(x, v)| Rectangle::new([(x, 0.0), (x + width, v)], colour.filled())))
                .map_err(|e| err(&e))?;
            if p == 0 {
                drawn.label(*name).legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 14, y + 5)], colour.filled()));
            }
            chart
                .draw_series(
                    bars.iter().map(|&(x, v)| Text::new(significant(v), (x + width / 2.0, v), value_style.clone())),
                )
                .map_err(|e| err(&e))?;
        }
        for (g, grp) in panel.groups.iter().enumerate() {
            let (x, y) = chart.backend_coord(&(g as f64 + 0.5, 0.0));
            base.draw(&Text::new(grp.label.clone(), (x, y + 8), label_style.clone())).map_err(|e| err(&e))?;
        }
        if p == 0 {
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::UpperLeft)
                .background_style(WHITE.mix(0.8))
                .border_style(BLACK)
                .draw()
                .map_err(|e| err(&e))?;
        }
    }
    base.present().map_err(|e| err(&e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn significant_keeps_three_digits() {
        assert_eq!(significant(0.0045), "0.0045");
        assert_eq!(significant(0.04174), "0.0417");
        assert_eq!(significant(1.6234), "1.62");
        assert_eq!(significant(1360.4), "1360");
        assert_eq!(significant(-0.1083), "-0.108");
        assert_eq!(significant(0.0), "0");
    }
}
