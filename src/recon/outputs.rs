//! The files of a reconstruction, in one directory: `log.csv` row by row as
//! training goes, then the density arrays (`density_initial.npy`,
//! `density_estimated.npy`, `hull.npy`, `density_gt.npy` if the truth is
//! known) and the figures: loss curves (Fig. 5), the density scatter
//! (Fig. 7), one camera during training (Fig. 6) and the held-out camera
//! (Fig. 8), the last two as PNG and as labelled SVG.

use super::problem::Problem;
use super::reconstruct::Reconstruction;
use super::train::LogRow;
use crate::error::{Error, Result};
use crate::image::{auto_white, Image};
use crate::io::{figures, npy, panels};
use serde::Serialize;
use std::fs::File;
use std::path::{Path, PathBuf};

/// The columns of `log.csv`, the fields of [`CsvRow`] (written before any
/// row, so that a log without rows still names its columns).
const LOG_COLUMNS: [&str; 8] = [
    "iteration",
    "train_loss",
    "held_out_loss",
    "held_out_rel_rmse",
    "density_rel_l1",
    "mean_density",
    "max_density",
    "wall_s",
];

/// A row of `log.csv`: the [`LogRow`] with its numbers as text, so that the
/// file keeps its fixed formats (losses `{:.9e}`, errors `{:.6}`, densities
/// `{:.6e}`, seconds `{:.3}`) rather than serde's shortest round trip.
#[derive(Serialize)]
struct CsvRow {
    iteration: usize,
    train_loss: String,
    held_out_loss: String,
    held_out_rel_rmse: String,
    density_rel_l1: String,
    mean_density: String,
    max_density: String,
    wall_s: String,
}

impl From<&LogRow> for CsvRow {
    fn from(r: &LogRow) -> CsvRow {
        CsvRow {
            iteration: r.iteration,
            train_loss: format!("{:.9e}", r.train_loss),
            held_out_loss: format!("{:.9e}", r.held_out_loss),
            held_out_rel_rmse: format!("{:.6}", r.held_out_rel_rmse),
            // Empty without a known truth (the error is undefined), never NaN.
            density_rel_l1: if r.density_rel_l1.is_finite() {
                format!("{:.6}", r.density_rel_l1)
            } else {
                String::new()
            },
            mean_density: format!("{:.6e}", r.mean_density),
            max_density: format!("{:.6e}", r.max_density),
            wall_s: format!("{:.3}", r.wall_s),
        }
    }
}

/// The directory a reconstruction is written to.
pub struct Outputs {
    dir: PathBuf,
    log: csv::Writer<File>,
    /// The first error met while logging, reported by [`Outputs::finish`].
    log_error: Option<Error>,
}

impl Outputs {
    /// Creates `dir` (if missing) and its `log.csv` (the column names only so far).
    pub fn create(dir: &Path) -> Result<Outputs> {
        std::fs::create_dir_all(dir).map_err(|e| Error(format!("cannot create {}: {e}", dir.display())))?;
        let path = dir.join("log.csv");
        let cannot = |e: csv::Error| Error(format!("cannot write {}: {e}", path.display()));
        let mut log = csv::WriterBuilder::new().has_headers(false).from_path(&path).map_err(cannot)?;
        log.write_record(LOG_COLUMNS).map_err(cannot)?;
        Ok(Outputs { dir: dir.to_path_buf(), log, log_error: None })
    }

    /// Appends `row` to `log.csv` and flushes it, so that the file can be
    /// read while training runs. An error is kept for [`Outputs::finish`].
    pub fn log(&mut self, row: &LogRow) {
        let written = self.log.serialize(CsvRow::from(row)).map_err(|e| e.to_string());
        let flushed = written.and_then(|()| self.log.flush().map_err(|e| e.to_string()));
        if let (Err(e), None) = (flushed, &self.log_error) {
            self.log_error = Some(Error(format!("cannot write {}: {e}", self.dir.join("log.csv").display())));
        }
    }

    /// Writes the arrays and figures of `r`, made from `problem`, beside the
    /// log, or reports the first error of logging.
    pub fn finish(mut self, r: &Reconstruction, problem: &Problem) -> Result<()> {
        self.log.flush().map_err(|e| Error(format!("cannot write log.csv: {e}")))?;
        if let Some(e) = self.log_error.take() {
            return Err(e);
        }
        write_arrays(r, problem, &self.dir)?;
        write_figures(r, problem, &self.dir)
    }
}

/// The density arrays: before and after training, the hull, the truth if known.
pub fn write_arrays(r: &Reconstruction, problem: &Problem, out: &Path) -> Result<()> {
    let shape = &problem.scene.density.shape;
    npy::write_f32(&out.join("density_initial.npy"), shape, &r.initial.data)?;
    npy::write_f32(&out.join("density_estimated.npy"), shape, &r.estimated.data)?;
    npy::write_u8(&out.join("hull.npy"), shape, &r.model.mask.iter().map(|&m| m as u8).collect::<Vec<_>>())?;
    if let Some(t) = problem.truth {
        npy::write_f32(&out.join("density_gt.npy"), shape, &t.data)?;
    }
    Ok(())
}

/// Figs. 5-8 from `r` and the `log.csv` already in `out`: Fig. 7 only if
/// the truth is known, Fig. 6 if the snapshot camera exists, Fig. 8 if a
/// camera is held out.
pub fn write_figures(r: &Reconstruction, problem: &Problem, out: &Path) -> Result<()> {
    let (targets, held_out) = (problem.targets, problem.held_out);
    if let Some(t) = problem.truth {
        let scatter = out.join("fig7_scatter.svg");
        figures::density_scatter(&t.data, &r.initial.data, &r.estimated.data, &r.model.mask, &scatter)?;
    }
    figures::loss_curves(&out.join("log.csv"), &out.join("fig5_loss.svg"))?;
    let camera = r.snapshot_camera;
    if let (Some(truth), false) = (targets.iter().chain(held_out).nth(camera), r.snapshots.is_empty()) {
        let white = auto_white(&truth.data);
        let mut strip: Vec<(&Image, String)> =
            r.snapshots.iter().map(|(i, im)| (im, format!("iteration {i}"))).collect();
        strip.push((truth, "ground truth".into()));
        let images: Vec<&Image> = strip.iter().map(|(im, _)| *im).collect();
        panels::image_strip(&images, white, &out.join(format!("fig6_camera{camera}.png")))?;
        let title = format!("Fig. 6: camera {camera} during training (rendered before each update), and its target");
        panels::labelled_strip(&strip, white, &title, &out.join(format!("fig6_camera{camera}.svg")))?;
    }
    if let (Some(h), Some(estimate)) = (held_out.first(), r.final_images.get(targets.len())) {
        panels::held_out_panel(h, estimate, &out.join("fig8_held_out.png"))?;
        let title = format!("Fig. 8: held-out camera {} (not trained on)", targets.len());
        panels::held_out_figure(h, estimate, &title, &out.join("fig8_held_out.svg"))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_rows_keep_their_formats_and_columns() {
        let row = LogRow {
            iteration: 3,
            train_loss: 6.0610756814e-4,
            held_out_loss: 0.0,
            held_out_rel_rmse: 0.8533914,
            density_rel_l1: f64::NAN,
            mean_density: 4.7414523e-3,
            max_density: 1.0,
            wall_s: 0.0074,
        };
        let mut w = csv::Writer::from_writer(vec![]);
        w.serialize(CsvRow::from(&row)).unwrap();
        let text = String::from_utf8(w.into_inner().unwrap()).unwrap();
        let mut lines = text.lines();
        assert_eq!(lines.next().unwrap(), LOG_COLUMNS.join(","));
        assert_eq!(lines.next().unwrap(), "3,6.061075681e-4,0.000000000e0,0.853391,,4.741452e-3,1.000000e0,0.007");
    }
}
