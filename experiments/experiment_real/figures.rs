//! Figures of a few frames: the held-out view (photograph, each model's
//! render, each model's signed error) and slices of each model's fitted
//! density. Each fit leaves its two small images in `views/` as it
//! finishes, so a resumed run still has every panel; the figures are put
//! together from them at the end.

use dualphoton::capture::protocol::Protocol;
use dualphoton::capture::{frames, View};
use dualphoton::error::{Error, Result};
use dualphoton::image::{auto_white, Image};
use dualphoton::io::panels::{grey, labelled_grid, signed_error};
use dualphoton::io::png::write_codes;
use dualphoton::io::svg::Rgb;
use dualphoton::volume::Grid;
use std::path::{Path, PathBuf};

/// The frames shown where they are among those scored: three frames spread
/// over ScalarFlow's clip, those of the baseline its protocol names.
const FIGURE_FRAMES: [usize; 3] = [30, 60, 90];

/// The frames of `scored` shown: [`FIGURE_FRAMES`] among them, or where
/// none is, the first, middle and last scored (a capture of other frames).
pub fn figure_frames(scored: &[usize]) -> Vec<usize> {
    let chosen: Vec<usize> = FIGURE_FRAMES.iter().copied().filter(|f| scored.contains(f)).collect();
    if !chosen.is_empty() || scored.is_empty() {
        return chosen;
    }
    let mut ends = vec![scored[0], scored[scored.len() / 2], scored[scored.len() - 1]];
    ends.dedup();
    ends
}

/// The held-out view's panels are the protocol's crop shrunk this many
/// times more by area averaging.
const SHRINK: usize = 3;

/// Voxels of a density slice become this many pixels across.
const SLICE_ZOOM: usize = 3;

fn view_path(dir: &Path, frame: usize, model: &str) -> PathBuf {
    dir.join(format!("frame{frame:03}_{model}.png"))
}

fn slice_path(dir: &Path, frame: usize, model: &str) -> PathBuf {
    dir.join(format!("frame{frame:03}_{model}_density.png"))
}

/// Keeps the panels of one fit: the held-out `prediction` (full resolution)
/// as the protocol sees it, shrunk (8-bit codes), and the slice of
/// `density` through the middle of its depth (z), seen as the cameras see
/// it (y up), each voxel's value over the slice's largest (8-bit).
pub fn keep(dir: &Path, frame: usize, model: &str, prediction: &Image, density: &Grid<f64>) -> Result<()> {
    std::fs::create_dir_all(dir)?;
    let protocol = Protocol::for_size(prediction.width, prediction.height);
    let view = protocol.view(prediction).downsample(SHRINK);
    write_codes(&view_path(dir, frame, model), view.width, view.height, &view.data)?;
    let [nz, ny, nx] = density.shape;
    let k = nz / 2;
    let slice: Vec<f64> =
        (0..ny).rev().flat_map(|j| (0..nx).map(move |i| density.data[density.index(k, j, i)])).collect();
    let max = slice.iter().copied().fold(0.0, f64::max);
    let scaled: Vec<f64> = slice.iter().map(|v| if max > 0.0 { v / max } else { 0.0 }).collect();
    write_codes(&slice_path(dir, frame, model), nx, ny, &scaled)
}

/// An 8-bit grey PNG as code value / 255.
fn read_codes(path: &Path) -> Result<Image> {
    let grey = image::open(path).map_err(|e| Error(format!("cannot read {}: {e}", path.display())))?.to_luma8();
    let data = grey.pixels().map(|p| p.0[0] as f64 / 255.0).collect();
    Ok(Image { width: grey.width() as usize, height: grey.height() as usize, data })
}

/// `held_out_views.svg` and `density_slices.svg` in `out` from the panels in
/// `dir`, for every figure frame of `scored` that has all `models`' panels,
/// beside the held-out camera `test`'s photograph. Writes nothing when no
/// frame has them all.
pub fn compose(out: &Path, dir: &Path, models: &[&str], test: &View, scored: &[usize]) -> Result<()> {
    let mut views = Vec::new();
    let mut slices = Vec::new();
    let has_panels =
        |&f: &usize| models.iter().all(|m| view_path(dir, f, m).exists() && slice_path(dir, f, m).exists());
    let shown: Vec<usize> = figure_frames(scored).into_iter().filter(has_panels).collect();
    for (&frame, photo) in shown.iter().zip(frames::read(test, &shown)?) {
        let protocol = Protocol::for_size(photo.width, photo.height);
        let truth = protocol.view(&photo).downsample(SHRINK);
        let white = auto_white(&truth.data);
        let renders = models.iter().map(|m| read_codes(&view_path(dir, frame, m))).collect::<Result<Vec<_>>>()?;
        let mut row = vec![grey(&truth, white)];
        row.extend(renders.iter().map(|r| grey(r, white)));
        row.extend(renders.iter().map(|r| signed_error(&truth, r, white)));
        views.push((format!("frame {frame}"), row));
        let slice_row = models
            .iter()
            .map(|m| Ok(grey(&read_codes(&slice_path(dir, frame, m))?, 1.0).upscale(SLICE_ZOOM)))
            .collect::<Result<Vec<Rgb>>>()?;
        slices.push((format!("frame {frame}"), slice_row));
    }
    if views.is_empty() {
        return Ok(());
    }
    let mut columns = vec!["photograph".to_string()];
    columns.extend(models.iter().map(|m| m.to_string()));
    columns.extend(models.iter().map(|m| format!("{m} - photograph")));
    labelled_grid(
        &views,
        &columns,
        "The held-out camera: photograph, each model's render, each model's error",
        "Grey: the photograph's 99.5th percentile is white (gamma 2.2). Error: red where the render is brighter, \
         blue where darker, full colour at a quarter of that white.",
        &out.join("held_out_views.svg"),
    )?;
    labelled_grid(
        &slices,
        &models.iter().map(|m| m.to_string()).collect::<Vec<_>>(),
        "Fitted density, the slice through the middle of the smoke box's depth",
        "Each panel scaled to its own largest value (white; gamma 2.2): the models' densities have different units.",
        &out.join("density_slices.svg"),
    )
}
