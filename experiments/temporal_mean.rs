//! What neighbouring frames add to a frame's density: each frame fitted
//! alone (as `experiment_real` fits it), then its density replaced by the
//! mean of its own and its neighbours' densities, each shifted onto it by
//! the plume's motion (`capture::temporal`), and the held-out camera scored.
//!
//! Arms, per frame and image model:
//! - `fit`: the frame's own fit, scored as `experiment_real` scores it;
//! - `alone, held`: its density held and the lighting fitted to it again
//!   (`capture::fit::fit_lighting`), the control of the next arms;
//! - `mean of N, held`: the mean over N frames centred on it, held likewise;
//! - `refit from mean of N`: the frame's images fitted again on the finest
//!   level, starting from that mean (`capture::fit::fit_from`).
//!
//! Why: four views leave the density's fine detail to each frame's fit.
//! If what they misplace differs from frame to frame while the smoke only
//! moves, the mean keeps the smoke and loses the errors.

use clap::Parser;
use dualphoton::capture::fit::{fit, fit_from, fit_lighting, training_rmse, Fit};
use dualphoton::capture::frame::{check, held_out_view, read, CameraChoice, FrameImages, Roles};
use dualphoton::capture::reuse;
use dualphoton::capture::rig::Rig;
use dualphoton::capture::settings::{FitSettings, ImageModel};
use dualphoton::capture::temporal::{mean_onto, Shift};
use dualphoton::capture::{calibration, Capture};
use dualphoton::error::{Error, Result};
use dualphoton::experiment::{self, Run};
use dualphoton::io::rows::{fmt, markdown_table, write_rows};
use dualphoton::volume::Grid;
use serde::Serialize;
use std::path::PathBuf;

/// How far (voxels along the vertical) the smoke is searched for per frame between two frames.
const RISE_PER_FRAME: isize = 6;

#[derive(Parser, Serialize)]
#[command(about = "What neighbouring frames' densities, shifted by the smoke's motion, add to a frame's")]
struct Args {
    /// The capture: its info.json (or transforms.json), or the folder holding it.
    #[arg(long)]
    data: PathBuf,
    /// Frames scored; each is fitted with its neighbours.
    #[arg(long, value_delimiter = ',', required = true)]
    frames: Vec<usize>,
    /// Neighbours on each side: means over 3, 5, ... frames up to 2 x reach + 1.
    #[arg(long, default_value_t = 2)]
    reach: usize,
    /// Image models.
    #[arg(long, value_enum, value_delimiter = ',', default_value = "multiple")]
    models: Vec<ImageModel>,
    #[command(flatten)]
    #[serde(flatten)]
    cameras: CameraChoice,
    /// Fit settings (JSON; fields not given keep their defaults).
    #[arg(long)]
    fit_settings: Option<PathBuf>,
    /// Output directory: temporal.csv, summary.md, rig.json, manifest.json.
    #[arg(long)]
    out: PathBuf,
}

/// One line of temporal.csv.
#[derive(Serialize)]
struct Row {
    frame: usize,
    model: String,
    arm: String,
    /// The frames whose densities the arm's density comes from.
    frames: String,
    /// Per other frame, its shift onto this one (voxels along z/y/x; y up).
    shifts: String,
    /// The training cameras' RMSE at the working resolution, in code values.
    #[serde(serialize_with = "fmt::f4")]
    train_rmse_codes: f64,
    #[serde(serialize_with = "fmt::opt_f4")]
    psnr_db: Option<f64>,
    #[serde(serialize_with = "fmt::opt_f4")]
    rel_rmse: Option<f64>,
    /// The arm's own seconds: its lighting or its refit, and the held-out
    /// render (for `fit`, the render alone).
    #[serde(serialize_with = "fmt::f1")]
    seconds: f64,
}

fn main() -> std::process::ExitCode {
    experiment::main(run)
}

fn run(args: Args) -> Result<()> {
    if args.frames.is_empty() || args.models.is_empty() || args.reach == 0 {
        return Err(Error("--frames and --models: give at least one each; --reach: at least 1".into()));
    }
    let capture = calibration::open(&args.data, None, None)?;
    let roles = args.cameras.roles(&capture)?;
    let settings = FitSettings::read_option(args.fit_settings.as_deref(), "--fit-settings")?;
    let count = capture.frame_count();
    if let Some(f) = args.frames.iter().find(|&&f| f < args.reach || f + args.reach >= count) {
        return Err(Error(format!(
            "--frames {f}: needs {} frames on each side (the capture has frames 0..{})",
            args.reach,
            count.saturating_sub(1)
        )));
    }
    // The centres may not repeat; their windows may overlap (--frames 10,11).
    check(&capture, &roles, &args.frames, &settings)?;
    let mut needed: Vec<usize> = args.frames.iter().flat_map(|&f| f - args.reach..=f + args.reach).collect();
    needed.sort_unstable();
    needed.dedup();
    check(&capture, &roles, &needed, &settings)?;
    let run = Run::start(&args.out)?;
    let rig = reuse::fit_rig(&capture, &roles, &settings, None)?;
    if let Some(rig) = &rig {
        reuse::write_rig(&run.path("rig.json"), rig)?;
    }
    let fixed = rig.as_ref().map(Rig::corrections);
    let smoke_box = capture.grid_box()?;
    let mut rows = Vec::new();
    for &centre in &args.frames {
        let frames: Vec<usize> = (centre - args.reach..=centre + args.reach).collect();
        let images = read(&capture, &roles, &frames, &settings)?;
        let own = &images[args.reach];
        for &model in &args.models {
            let settings = FitSettings { model, ..settings.clone() };
            let mut fits = Vec::new();
            for frame in &images {
                let training = &frame.training.images[0];
                let ceilings = Some(frame.training.ceilings[0].as_slice());
                let (cameras, fixed) = (&frame.training.cameras, fixed.as_ref());
                let fitted = fit(cameras, training, ceilings, smoke_box, &settings, fixed, &mut |_| {})?;
                eprintln!("frame {centre} {}: frame {} fitted in {:.0} s", model.name(), frame.frame, fitted.seconds);
                fits.push(fitted);
            }
            let centre_fit = &fits[args.reach];
            let mut score = |arm: String, used: &[usize], shifts: &[Shift], fitted: &Fit, start: std::time::Instant| {
                let held = held_out_view(&capture, roles.held_out[0], fitted, &own.held_out[0])?;
                let row = Row {
                    frame: centre,
                    model: model.name().into(),
                    arm,
                    frames: joined(used.iter().map(|f| f.to_string())),
                    shifts: joined(shifts.iter().map(|s| format!("{:.0}/{:.2}/{:.0}", s.0[0], s.0[1], s.0[2]))),
                    train_rmse_codes: training_rmse(fitted, &own.training.images[0]) * 255.0,
                    psnr_db: held.score.psnr,
                    rel_rmse: held.score.rel_rmse,
                    seconds: start.elapsed().as_secs_f64(),
                };
                eprintln!(
                    "frame {centre} {}: {}: held-out PSNR {:.2} dB",
                    row.model,
                    row.arm,
                    row.psnr_db.unwrap_or(f64::NAN)
                );
                rows.push(row);
                // Every row so far, so a run cut short keeps what it finished.
                write_rows(&run.path("temporal.csv"), &rows)
            };
            score("fit".into(), &[centre], &[], centre_fit, std::time::Instant::now())?;
            let held = |density: Grid<f64>| {
                fit_lighting(
                    &own.training.cameras,
                    &own.training.images[0],
                    smoke_box,
                    density,
                    &settings,
                    fixed.as_ref(),
                )
            };
            let start = std::time::Instant::now();
            score("alone, held".into(), &[centre], &[], &held(centre_fit.scene.density.clone())?, start)?;
            let mut widest = None;
            for r in 1..=args.reach {
                let start = std::time::Instant::now();
                let (mean, used, shifts) = temporal_mean(&fits, &images, args.reach, r);
                score(format!("mean of {}, held", 2 * r + 1), &used, &shifts, &held(mean.clone())?, start)?;
                widest = Some((mean, used, shifts));
            }
            if let Some((mean, used, shifts)) = widest {
                let start = std::time::Instant::now();
                let training = &own.training.images[0];
                let refit =
                    fit_from(&own.training.cameras, training, smoke_box, mean, &settings, fixed.as_ref(), &mut |_| {})?;
                score(format!("refit from mean of {}", used.len()), &used, &shifts, &refit, start)?;
            }
        }
    }
    std::fs::write(run.path("summary.md"), summary(&rows, &capture, &roles))?;
    run.write_manifest(&args)
}

/// The mean of the centre fit's density (at index `reach` of `fits`) and
/// its neighbours up to `r` frames away, each shifted onto it; the frames
/// used and the neighbours' shifts.
fn temporal_mean(fits: &[Fit], images: &[FrameImages], reach: usize, r: usize) -> (Grid<f64>, Vec<usize>, Vec<Shift>) {
    let others: Vec<usize> = (reach - r..=reach + r).filter(|&i| i != reach).collect();
    let grids: Vec<Grid<f64>> = others.iter().map(|&i| fits[i].scene.density.clone()).collect();
    let (mean, shifts) = mean_onto(&fits[reach].scene.density, &grids, RISE_PER_FRAME * r as isize);
    let used = (reach - r..=reach + r).map(|i| images[i].frame).collect();
    (mean, used, shifts)
}

/// `items` separated by `;` (one CSV field).
fn joined(items: impl Iterator<Item = String>) -> String {
    items.collect::<Vec<_>>().join(";")
}

/// summary.md: per model and arm, the mean held-out PSNR and relative RMSE
/// and the training RMSE over the frames, and the PSNR frame by frame.
fn summary(rows: &[Row], capture: &Capture, roles: &Roles) -> String {
    let mut keys: Vec<(&str, &str)> = Vec::new();
    for r in rows {
        if !keys.contains(&(r.model.as_str(), r.arm.as_str())) {
            keys.push((&r.model, &r.arm));
        }
    }
    let mean = |v: Vec<f64>| v.iter().sum::<f64>() / v.len().max(1) as f64;
    let table = markdown_table(
        &["model", "arm", "held-out PSNR (dB)", "relative RMSE (%)", "training RMSE (codes)", "PSNR per frame"],
        keys.iter().map(|&(model, arm)| {
            let mine: Vec<&Row> = rows.iter().filter(|r| r.model == model && r.arm == arm).collect();
            vec![
                model.to_string(),
                arm.to_string(),
                format!("{:.2}", mean(mine.iter().filter_map(|r| r.psnr_db).collect())),
                format!("{:.1}", 100.0 * mean(mine.iter().filter_map(|r| r.rel_rmse).collect())),
                format!("{:.2}", mean(mine.iter().map(|r| r.train_rmse_codes).collect())),
                mine.iter()
                    .map(|r| format!("{}: {:.2}", r.frame, r.psnr_db.unwrap_or(f64::NAN)))
                    .collect::<Vec<_>>()
                    .join(", "),
            ]
        }),
    );
    let names = |vs: &[usize]| vs.iter().map(|&v| capture.views[v].name.as_str()).collect::<Vec<_>>().join(", ");
    format!(
        "# Neighbouring frames' densities\n\nTraining cameras {}; held-out camera {}. Means over frames:\n\n{table}",
        names(&roles.training),
        names(&roles.held_out)
    )
}
