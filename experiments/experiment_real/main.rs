//! Real smoke: ScalarFlow's real capture (five cameras, 120 frames) under
//! the field's held-out-view protocol (train on four cameras, score the
//! held-out one: PSNR over a fixed crop at half resolution, relative RMSE
//! beside it).
//!
//! This first stage scores the predictions that need no reconstruction, the
//! floor any method must clear: an all-black image, and the training view
//! nearest the held-out camera's direction used as it is.
//!
//! Writes `results/scalarflow_real/{baselines.csv, summary.md, manifest.json}`.
//! The capture is read from `--data` (never copied into the repository).

use clap::Parser;
use dualphoton::capture::{calibration, frames, protocol::Protocol, Capture};
use dualphoton::error::{Error, Result};
use dualphoton::experiment::{self, Run};
use dualphoton::image::Image;
use dualphoton::io::rows::{fmt, markdown_table, write_rows};
use serde::Serialize;
use std::path::{Path, PathBuf};

#[derive(Parser, Serialize)]
#[command(about = "Held-out-view scores on a real capture (ScalarFlow's, as PINF and HyFluid distribute it)")]
struct Args {
    /// The capture: its info.json (or transforms.json), or the folder holding it.
    #[arg(long)]
    data: PathBuf,
    /// Frames scored.
    #[arg(long, value_delimiter = ',', default_value = "0,10,20,30,40,50,60,70,80,90,100,110,119")]
    frames: Vec<usize>,
    /// The held-out camera (default: the calibration's test camera).
    #[arg(long)]
    held_out: Option<String>,
    /// Output directory.
    #[arg(long, default_value = "results/scalarflow_real")]
    out: PathBuf,
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

fn run(args: Args) -> Result<()> {
    let capture = calibration::load(&calibration_path(&args.data))?;
    let held_out = held_out_camera(&capture, args.held_out.as_deref())?;
    let count = capture.frame_count();
    if let Some(n) = args.frames.iter().find(|&&n| n >= count) {
        return Err(Error(format!(
            "--frames: frame {n} is out of range (the capture has frames 0..{})",
            count.saturating_sub(1)
        )));
    }
    if !frames::have_ffmpeg()
        && capture.views.iter().any(|v| matches!(v.frames, dualphoton::capture::Frames::Video { .. }))
    {
        return Err(Error(frames::NO_FFMPEG.into()));
    }
    let nearest = nearest_training_view(&capture, held_out)?;
    let run = Run::start(&args.out)?;
    let test = &capture.views[held_out];
    let protocol = Protocol::for_size(test.camera.width, test.camera.height);
    let truth = frames::read(test, &args.frames)?;
    let neighbour = frames::read(&capture.views[nearest], &args.frames)?;
    let mut rows = Vec::new();
    for ((&frame, truth), neighbour) in args.frames.iter().zip(&truth).zip(&neighbour) {
        let black = Image::zeros(truth.width, truth.height);
        let nearest_name = format!("training view {} as is", capture.views[nearest].name);
        for (prediction, image) in [("all black".to_string(), &black), (nearest_name, neighbour)] {
            let score = protocol.score(image, truth);
            rows.push(Row { frame, prediction, psnr_db: score.psnr, rel_rmse: score.rel_rmse });
        }
        eprintln!("frame {frame}: scored");
    }
    write_rows(&run.path("baselines.csv"), &rows)?;
    std::fs::write(run.path("summary.md"), summary(&rows, &test.name))?;
    run.write_manifest(&args)
}

/// `data` itself if it is a file, else the `info.json` or `transforms.json` in it.
fn calibration_path(data: &Path) -> PathBuf {
    if data.is_dir() {
        let info = data.join("info.json");
        if info.exists() {
            info
        } else {
            data.join("transforms.json")
        }
    } else {
        data.to_path_buf()
    }
}

/// The camera named `name`, else the calibration's one test camera.
fn held_out_camera(capture: &Capture, name: Option<&str>) -> Result<usize> {
    if let Some(name) = name {
        return capture.view(name);
    }
    let tests: Vec<usize> = (0..capture.views.len()).filter(|&v| capture.views[v].held_out).collect();
    match tests[..] {
        [one] => Ok(one),
        _ => Err(Error(format!("--held-out: the calibration marks {} test cameras; name one", tests.len()))),
    }
}

/// The other camera whose viewing direction is closest to camera `held_out`'s.
fn nearest_training_view(capture: &Capture, held_out: usize) -> Result<usize> {
    let forward = |v: usize| capture.views[v].camera.basis().2;
    (0..capture.views.len())
        .filter(|&v| v != held_out && !capture.views[v].held_out)
        .max_by(|&a, &b| forward(a).dot(&forward(held_out)).total_cmp(&forward(b).dot(&forward(held_out))))
        .ok_or_else(|| Error("the capture has no training camera".into()))
}

fn summary(rows: &[Row], held_out: &str) -> String {
    let mut md = format!(
        "# Real capture: held-out camera {held_out}\n\n\
         Predictions that need no reconstruction, scored under the field's protocol \
         (half resolution by area averaging, crop rows 90..960 and columns 45..540, \
         PSNR = -10 log10 MSE of code value / 255). Mean over frames:\n\n"
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
