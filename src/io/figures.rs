//! The paper's plots from saved data: loss curves (Fig. 5), the density
//! scatter (Fig. 7) and Table 1 as bars. All SVG (plotters); the figures
//! made of images (Figs. 6 and 8) are in [`super::panels`].

use super::plot::{grouped_bars, line_chart, Axes, BarGroup, BarPanel, Series};
use crate::error::{Error, Result};
use plotters::prelude::*;
use std::path::Path;

/// Fig. 5: training and held-out loss per iteration, from a training log CSV
/// with columns `iteration`, `train_loss`, `held_out_loss`.
pub fn loss_curves(log_csv: &Path, out: &Path) -> Result<()> {
    let mut reader = csv::Reader::from_path(log_csv).map_err(|e| Error(format!("{}: {e}", log_csv.display())))?;
    let headers = reader.headers().map_err(|e| Error(e.to_string()))?.clone();
    let col = |name: &str| {
        headers.iter().position(|h| h == name).ok_or_else(|| Error(format!("{}: no column {name}", log_csv.display())))
    };
    let (ci, ct, ch) = (col("iteration")?, col("train_loss")?, col("held_out_loss")?);
    let (mut train, mut held) = (vec![], vec![]);
    for record in reader.records() {
        let r = record.map_err(|e| Error(e.to_string()))?;
        let num = |c: usize| r.get(c).and_then(|v| v.parse::<f64>().ok()).unwrap_or(f64::NAN);
        train.push((num(ci), num(ct)));
        held.push((num(ci), num(ch)));
    }
    line_chart(
        out,
        &Axes { title: "Fig. 5: loss per iteration", x: "iteration", y: "MSE", log_x: false, log_y: true },
        &[
            Series { name: "training cameras 0-3".into(), points: train, markers: false },
            Series { name: "held-out camera 4".into(), points: held, markers: false },
        ],
    )
}

/// Fig. 7: ground-truth against estimated density over the hull voxels,
/// before and after training (at most 20,000 points each, evenly thinned).
pub fn density_scatter(truth: &[f64], before: &[f64], after: &[f64], mask: &[bool], out: &Path) -> Result<()> {
    let title = "Fig. 7: voxel density, ground truth vs estimate (hull voxels)";
    estimate_scatter(title, truth, &[("before training", before), ("after training", after)], mask, out)
}

/// Ground truth against one or more estimates (named) over the `mask`
/// entries, at most 20,000 points per estimate, evenly thinned; the first
/// estimate in grey, the others in colour.
pub fn estimate_scatter(
    title: &str,
    truth: &[f64],
    estimates: &[(&str, &[f64])],
    mask: &[bool],
    out: &Path,
) -> Result<()> {
    let idx: Vec<usize> = (0..truth.len()).filter(|&i| mask[i]).collect();
    let max_points = 20_000;
    let step = idx.len().div_ceil(max_points).max(1);
    let pts = |v: &[f64]| idx.iter().step_by(step).map(|&i| (truth[i], v[i])).collect::<Vec<_>>();
    let sets: Vec<Vec<(f64, f64)>> = estimates.iter().map(|(_, v)| pts(v)).collect();
    let hi = sets.iter().flatten().fold(0.0f64, |m, p| m.max(p.0).max(p.1)) * 1.05 + 1e-9;
    let err = |e: &dyn std::fmt::Display| Error(format!("plot {}: {e}", out.display()));
    let root = SVGBackend::new(out, (640, 640)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 18))
        .margin(16)
        .x_label_area_size(48)
        .y_label_area_size(64)
        .build_cartesian_2d(0.0..hi, 0.0..hi)
        .map_err(|e| err(&e))?;
    chart.configure_mesh().x_desc("ground truth").y_desc("estimate").draw().map_err(|e| err(&e))?;
    chart.draw_series(LineSeries::new(vec![(0.0, 0.0), (hi, hi)], BLACK.mix(0.5))).map_err(|e| err(&e))?;
    let colours = [RGBColor(127, 127, 127), RGBColor(214, 39, 40), RGBColor(31, 119, 180), RGBColor(44, 160, 44)];
    for (k, ((name, _), points)) in estimates.iter().zip(&sets).enumerate() {
        let style = colours[k % colours.len()].mix(0.4).filled();
        chart
            .draw_series(points.iter().map(|&p| Circle::new(p, 2, style)))
            .map_err(|e| err(&e))?
            .label(*name)
            .legend(move |(x, y)| Circle::new((x + 10, y), 4, style));
    }
    chart.configure_series_labels().background_style(WHITE.mix(0.8)).border_style(BLACK).draw().map_err(|e| err(&e))?;
    root.present().map_err(|e| err(&e))
}

/// One row of Table 1 as the bar chart shows it: mean and max density over
/// the hull voxels, ours and the paper's.
pub struct Table1Bars {
    /// Which density (before training, after training, ground truth).
    pub name: String,
    /// Our mean density.
    pub mean: f64,
    /// Our max density.
    pub max: f64,
    /// The paper's mean density.
    pub paper_mean: f64,
    /// The paper's max density.
    pub paper_max: f64,
}

/// Table 1 as grouped bars, ours beside the paper's: mean density in one
/// panel, max density in another (they differ by two orders of magnitude).
pub fn table1_chart(rows: &[Table1Bars], title: &str, out: &Path) -> Result<()> {
    let panel = |name: &str, pick: &dyn Fn(&Table1Bars) -> [f64; 2]| BarPanel {
        title: format!("{name} density over the hull voxels"),
        y: format!("{name} density"),
        groups: rows.iter().map(|r| BarGroup { label: r.name.clone(), values: pick(r).to_vec() }).collect(),
    };
    let panels = [panel("mean", &|r| [r.mean, r.paper_mean]), panel("max", &|r| [r.max, r.paper_max])];
    grouped_bars(out, title, &["ours", "paper"], &panels)
}
