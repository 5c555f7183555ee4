//! Real smoke: ScalarFlow's real capture (five cameras, 120 frames) under
//! the field's held-out-view protocol (train on four cameras, score the
//! held-out one: PSNR over a fixed crop at half resolution, relative RMSE
//! beside it).
//!
//! First the floor any method must clear, predictions that need no
//! reconstruction (an all-black image, and the training view nearest the
//! held-out camera's direction used as it is); then every frame fitted under
//! each image model and its held-out view scored.
//!
//! Writes `results/scalarflow_real/`: `baselines.csv`, `settings.json` (the
//! cameras and fit settings of every fit), `rig.json`, `fits.csv` (appended
//! frame by frame: a stopped run with the same settings resumes), `summary.md`, `psnr_per_frame.svg`,
//! `held_out_views.svg`, `density_slices.svg`, `manifest.json` (with the
//! revisions that fitted the rows it reports and the rig, where a resumed
//! run kept an earlier one's).
//! The capture is read from `--data` (never copied into the repository).

mod figures;
mod models;

use clap::Parser;
use dualphoton::capture::frame::{self, CameraChoice};
use dualphoton::capture::reuse;
use dualphoton::capture::scalarflow_cameras::held_out_zoom;
use dualphoton::capture::settings::{FitSettings, ImageModel};
use dualphoton::capture::{calibration, frames, protocol::Protocol, BoxChoice, Capture};
use dualphoton::error::{Error, Result};
use dualphoton::experiment::{self, Run};
use dualphoton::image::Image;
use dualphoton::io::rows::{fmt, markdown_table, write_rows};
use serde::Serialize;
use std::path::PathBuf;

#[derive(Parser, Serialize)]
#[command(about = "Held-out-view scores on a real capture (ScalarFlow's, as PINF and HyFluid distribute it)")]
struct Args {
    /// The capture: its info.json (or transforms.json), or the folder holding it.
    #[arg(long)]
    data: PathBuf,
    /// ScalarFlow's own camera file (GlobTrans's scalaFlow_cameras.json): each camera's focal length from
    /// its vertical field of view instead of the calibration's horizontal one; the poses stay.
    #[arg(long, conflicts_with = "held_out_focal_lengths")]
    focal_lengths: Option<PathBuf>,
    /// ScalarFlow's own camera file, for the held-out camera alone: its focal lengths are multiplied by its
    /// focal length there over the calibration's, divided by the training cameras' geometric mean of the same.
    #[arg(long)]
    held_out_focal_lengths: Option<PathBuf>,
    #[command(flatten)]
    #[serde(flatten)]
    smoke_box: BoxChoice,
    /// Frames scored [default: 0, 10, 20, ... and the capture's last; for ScalarFlow's 120, 0 to 110 and 119].
    #[arg(long, value_delimiter = ',')]
    frames: Option<Vec<usize>>,
    /// Image models fitted, comma-separated (multiple, single, emission-absorption), or `none` (the baselines only).
    #[arg(long, default_value = "multiple,single,emission-absorption")]
    models: Models,
    /// Fit settings (JSON; fields not given keep their defaults), as `dualphoton fit --capture --study` takes them.
    #[arg(long, visible_alias = "study")]
    fit_settings: Option<PathBuf>,
    #[command(flatten)]
    #[serde(flatten)]
    cameras: CameraChoice,
    /// Output directory.
    #[arg(long, default_value = "results/scalarflow_real")]
    out: PathBuf,
}

/// `--models`: image models, or none.
#[derive(Clone, Debug, Serialize)]
#[serde(transparent)]
struct Models(Vec<ImageModel>);

impl std::str::FromStr for Models {
    type Err = String;

    fn from_str(s: &str) -> std::result::Result<Self, String> {
        if s == "none" {
            return Ok(Models(Vec::new()));
        }
        let model = |m: &str| {
            <ImageModel as clap::ValueEnum>::from_str(m, false).map_err(|_| {
                let names: Vec<&str> =
                    <ImageModel as clap::ValueEnum>::value_variants().iter().map(|v| v.name()).collect();
                format!("'{m}' is not an image model: give {} (comma-separated), or none", names.join(", "))
            })
        };
        s.split(',').map(model).collect::<std::result::Result<_, _>>().map(Models)
    }
}

/// One line of baselines.csv.
#[derive(Serialize)]
struct Row {
    frame: usize,
    prediction: String,
    #[serde(serialize_with = "fmt::opt_f4")]
    psnr_db: Option<f64>,
    #[serde(serialize_with = "fmt::opt_f4")]
    rel_rmse: Option<f64>,
}

fn main() -> std::process::ExitCode {
    experiment::main(run)
}

fn run(mut args: Args) -> Result<()> {
    let image_models = &args.models.0;
    let smoke_box = args.smoke_box.corners()?;
    let mut capture = calibration::open(&args.data, args.focal_lengths.as_deref(), smoke_box)?;
    let roles = args.cameras.roles(&capture)?;
    // The manifest records the frames scored, given or not.
    let scored = args.frames.get_or_insert_with(|| every_tenth_and_last(capture.frame_count())).clone();
    let held_out = roles.held_out[0];
    let fit_settings =
        FitSettings::read_option(args.fit_settings.as_deref(), "--fit-settings")?.for_capture(capture.frame_count());
    if let Some(path) = &args.held_out_focal_lengths {
        let k = held_out_zoom(&capture, path, &roles.training, held_out)
            .map_err(|e| Error(format!("--held-out-focal-lengths: {e}")))?;
        eprintln!("held-out camera {}: focal lengths x {k:.4} (the camera file)", capture.views[held_out].name);
        capture.views[held_out].camera = capture.views[held_out].camera.zoom(k);
    }
    frame::check(&capture, &roles, &scored, &fit_settings)?;
    let nearest = nearest_training_view(&capture, &roles.training, held_out);
    let run = Run::start(&args.out)?;
    reuse::RunSettings::of(&capture, &roles, &fit_settings)?.record(&args.out, !image_models.is_empty())?;
    let test = &capture.views[held_out];
    let protocol = Protocol::for_size(test.camera.width, test.camera.height);
    let mut rows = Vec::new();
    // A few frames at a time: a clip's photographs at full resolution take gigabytes.
    for frames_now in scored.chunks(models::FRAMES_AT_ONCE) {
        let truth_now = frames::read(test, frames_now)?;
        let neighbours: Vec<Option<Image>> = match nearest {
            Some(v) => frames::read(&capture.views[v], frames_now)?.into_iter().map(Some).collect(),
            None => vec![None; frames_now.len()],
        };
        for ((&frame, truth), neighbour) in frames_now.iter().zip(&truth_now).zip(neighbours) {
            let mut predictions = vec![("all black".to_string(), Image::zeros(truth.width, truth.height))];
            if let (Some(v), Some(image)) = (nearest, neighbour) {
                predictions.push((format!("training view {} as is", capture.views[v].name), image));
            }
            for (prediction, image) in predictions {
                let score = protocol.score(&image, truth);
                rows.push(Row { frame, prediction, psnr_db: score.psnr, rel_rmse: score.rel_rmse });
            }
            eprintln!("frame {frame}: scored");
        }
    }
    write_rows(&run.path("baselines.csv"), &rows)?;
    let mut md = summary(&rows, &test.name, &protocol);
    let mut made_by = MadeBy::default();
    if !image_models.is_empty() {
        let views = run.path("views");
        let (fits, rig) =
            models::run(&capture, &roles, &scored, image_models, &fit_settings, &run.path("fits.csv"), &views)?;
        let fits: Vec<models::FitResult> = fits.into_iter().filter(|r| scored.contains(&r.frame)).collect();
        made_by = MadeBy { fits: models::revisions(&fits), rig: rig.as_ref().map(|r| r.revision.clone()) };
        md += &format!(
            "\n## Reconstructions\n\nEach frame fitted on the training cameras ({}) under each image model, \
             the held-out camera rendered at full resolution and scored as above. Mean over frames:\n\n",
            roles.training.iter().map(|&v| capture.views[v].name.as_str()).collect::<Vec<_>>().join(", ")
        );
        md += &models::table(&fits, image_models);
        if let Some(rig) = &rig {
            md += &models::rig_note(rig, &fit_settings);
        }
        let nearest_rows: Vec<(usize, f64)> =
            rows.iter().filter(|r| r.prediction != "all black").filter_map(|r| Some((r.frame, r.psnr_db?))).collect();
        models::plot(&run.path("psnr_per_frame.svg"), &fits, image_models, &nearest_rows, &protocol)?;
        let names: Vec<&str> = image_models.iter().map(|m| m.name()).collect();
        figures::compose(&args.out, &views, &names, test, &scored)?;
    }
    std::fs::write(run.path("summary.md"), md)?;
    run.write_manifest(&Manifest { args: &args, made_by })
}

/// `manifest.json`: the arguments, and what made the fits it reports.
#[derive(Serialize)]
struct Manifest<'a> {
    #[serde(flatten)]
    args: &'a Args,
    #[serde(flatten)]
    made_by: MadeBy,
}

/// The revisions that made the reported rows of `fits.csv` and the rig: a
/// resumed run keeps what an earlier one fitted, so they need not be the
/// manifest's own `revision`.
#[derive(Serialize, Default)]
struct MadeBy {
    #[serde(rename = "fit_revisions", skip_serializing_if = "Vec::is_empty")]
    fits: Vec<String>,
    #[serde(rename = "rig_revision", skip_serializing_if = "Option::is_none")]
    rig: Option<String>,
}

/// Frames 0, 10, 20, ... below `count`, and the last.
fn every_tenth_and_last(count: usize) -> Vec<usize> {
    let mut frames: Vec<usize> = (0..count).step_by(10).collect();
    if count > 0 && frames.last() != Some(&(count - 1)) {
        frames.push(count - 1);
    }
    frames
}

/// The training camera whose viewing direction is closest to camera
/// `held_out`'s, among those of its size (none: no baseline from a view).
fn nearest_training_view(capture: &Capture, training: &[usize], held_out: usize) -> Option<usize> {
    let camera = |v: usize| &capture.views[v].camera;
    let forward = |v: usize| camera(v).basis().2;
    let same_size = |v: usize| (camera(v).width, camera(v).height) == (camera(held_out).width, camera(held_out).height);
    training
        .iter()
        .copied()
        .filter(|&v| same_size(v))
        .max_by(|&a, &b| forward(a).dot(&forward(held_out)).total_cmp(&forward(b).dot(&forward(held_out))))
}

fn summary(rows: &[Row], held_out: &str, protocol: &Protocol) -> String {
    let mut md = format!(
        "# Real capture: held-out camera {held_out}\n\n\
         Predictions that need no reconstruction, scored under {} \
         ({}, PSNR = -10 log10 MSE of code value / 255). Mean over frames:\n\n",
        protocol.name(),
        protocol.describe()
    );
    let mut names: Vec<&str> = Vec::new();
    for r in rows {
        if !names.contains(&r.prediction.as_str()) {
            names.push(&r.prediction);
        }
    }
    let table = names.iter().map(|name| {
        let mine: Vec<&Row> = rows.iter().filter(|r| r.prediction == *name).collect();
        let mean = |f: &dyn Fn(&Row) -> Option<f64>| {
            let v: Vec<f64> = mine.iter().filter_map(|r| f(r)).collect();
            if v.is_empty() {
                String::new()
            } else {
                format!("{:.2}", v.iter().sum::<f64>() / v.len() as f64)
            }
        };
        vec![name.to_string(), mean(&|r| r.psnr_db), mean(&|r| r.rel_rmse.map(|x| 100.0 * x)), mine.len().to_string()]
    });
    md += &markdown_table(&["prediction", "PSNR (dB)", "relative RMSE (%)", "frames"], table);
    md
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_frames_are_every_tenth_and_the_last() {
        let scalarflow: Vec<usize> = (0..12).map(|k| 10 * k).chain([119]).collect();
        assert_eq!(every_tenth_and_last(120), scalarflow);
        assert_eq!(every_tenth_and_last(21), [0, 10, 20]);
        assert_eq!(every_tenth_and_last(2), [0, 1]);
        assert_eq!(every_tenth_and_last(1), [0]);
    }
}
