//! The paper's figures from saved data: loss curves (Fig. 5), image strips
//! (Fig. 6, Fig. 8) and the density scatter (Fig. 7). Plots are SVG
//! (plotters), image strips PNG.

use super::plot::{line_chart, Axes, Series};
use crate::error::{Error, Result};
use crate::image::Image;
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

/// Images side by side (with a 2-pixel gap), all under one white point, as grey PNG.
pub fn image_strip(images: &[&Image], white: f64, out: &Path) -> Result<()> {
    let gap = 2;
    let h = images.iter().map(|i| i.height).max().unwrap_or(1);
    let w: usize = images.iter().map(|i| i.width).sum::<usize>() + gap * images.len().saturating_sub(1);
    let mut canvas = image::GrayImage::from_pixel(w as u32, h as u32, image::Luma([255]));
    let mut x0 = 0;
    for im in images {
        let grey = super::png::tone_map(&im.data, white);
        for y in 0..im.height {
            for x in 0..im.width {
                canvas.put_pixel((x0 + x) as u32, y as u32, image::Luma([grey[y * im.width + x]]));
            }
        }
        x0 += im.width + gap;
    }
    canvas.save(out).map_err(|e| Error(format!("cannot write {}: {e}", out.display())))
}

/// Fig. 8: ground truth | estimate (shared white point, grey) | signed error
/// (blue negative, red positive, full colour at `white / 4`), as one RGB PNG.
pub fn held_out_panel(truth: &Image, estimate: &Image, out: &Path) -> Result<()> {
    let white = crate::image::auto_white(&truth.data);
    let (w, h, gap) = (truth.width, truth.height, 2);
    let mut canvas = image::RgbImage::from_pixel((3 * w + 2 * gap) as u32, h as u32, image::Rgb([255, 255, 255]));
    let gt = super::png::tone_map(&truth.data, white);
    let est = super::png::tone_map(&estimate.data, white);
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            canvas.put_pixel(x as u32, y as u32, image::Rgb([gt[i]; 3]));
            canvas.put_pixel((w + gap + x) as u32, y as u32, image::Rgb([est[i]; 3]));
            let e = ((estimate.data[i] - truth.data[i]) / (0.25 * white)).clamp(-1.0, 1.0);
            let fade = (255.0 * (1.0 - e.abs())) as u8;
            let colour = if e >= 0.0 { [255, fade, fade] } else { [fade, fade, 255] };
            canvas.put_pixel((2 * (w + gap) + x) as u32, y as u32, image::Rgb(colour));
        }
    }
    canvas.save(out).map_err(|e| Error(format!("cannot write {}: {e}", out.display())))
}

/// Fig. 7: ground-truth against estimated density over the hull voxels,
/// before and after training (at most `max_points` points each, evenly thinned).
pub fn density_scatter(truth: &[f64], before: &[f64], after: &[f64], mask: &[bool], out: &Path) -> Result<()> {
    let idx: Vec<usize> = (0..truth.len()).filter(|&i| mask[i]).collect();
    let max_points = 20_000;
    let step = idx.len().div_ceil(max_points).max(1);
    let pts = |v: &[f64]| idx.iter().step_by(step).map(|&i| (truth[i], v[i])).collect::<Vec<_>>();
    let (pb, pa) = (pts(before), pts(after));
    let hi = pb.iter().chain(&pa).fold(0.0f64, |m, p| m.max(p.0).max(p.1)) * 1.05 + 1e-9;
    let err = |e: &dyn std::fmt::Display| Error(format!("plot {}: {e}", out.display()));
    let root = SVGBackend::new(out, (640, 640)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let mut chart = ChartBuilder::on(&root)
        .caption("Fig. 7: voxel density, ground truth vs estimate (hull voxels)", ("sans-serif", 18))
        .margin(16)
        .x_label_area_size(48)
        .y_label_area_size(64)
        .build_cartesian_2d(0.0..hi, 0.0..hi)
        .map_err(|e| err(&e))?;
    chart.configure_mesh().x_desc("ground truth").y_desc("estimate").draw().map_err(|e| err(&e))?;
    chart.draw_series(LineSeries::new(vec![(0.0, 0.0), (hi, hi)], BLACK.mix(0.5))).map_err(|e| err(&e))?;
    let before_style = RGBColor(127, 127, 127).mix(0.4).filled();
    let after_style = RGBColor(214, 39, 40).mix(0.4).filled();
    chart
        .draw_series(pb.iter().map(|&p| Circle::new(p, 2, before_style)))
        .map_err(|e| err(&e))?
        .label("before training")
        .legend(move |(x, y)| Circle::new((x + 10, y), 4, before_style));
    chart
        .draw_series(pa.iter().map(|&p| Circle::new(p, 2, after_style)))
        .map_err(|e| err(&e))?
        .label("after training")
        .legend(move |(x, y)| Circle::new((x + 10, y), 4, after_style));
    chart.configure_series_labels().background_style(WHITE.mix(0.8)).border_style(BLACK).draw().map_err(|e| err(&e))?;
    root.present().map_err(|e| err(&e))
}
