//! A linear filter from a fitted density to the true one, learned on a made
//! capture's frames (`capture::learned_filter`), then applied to the fits
//! of another capture's frames through the same cameras, and the held-out
//! camera scored.
//!
//! Arms, per scored frame (one image model):
//! - `fit`: the frame's own fit, scored as `experiment_real` scores it;
//! - `fit, held`: its density held and the lighting fitted to it again
//!   (`capture::fit::fit_lighting`), the control of the next arms;
//! - `filtered, held`: the fit's density filtered, held likewise;
//! - `refit from filtered`: the frame's images fitted again on the finest
//!   level, starting from the filtered density (`capture::fit::fit_from`).
//!
//! Where the scored capture is a made one too, each arm's density is also
//! compared with the truth's. The frames learned from must be other plumes
//! than those scored (other frames of a made capture): the filter never
//! sees what it is judged on.

use clap::Parser;
use dualphoton::capture::density::{made_truth, plume_in_box};
use dualphoton::capture::fit::{fit, fit_from, fit_lighting, training_rmse, Fit};
use dualphoton::capture::frame::{check, held_out_view, read, CameraChoice, Roles};
use dualphoton::capture::learned_filter::Normal;
use dualphoton::capture::reuse;
use dualphoton::capture::rig::Rig;
use dualphoton::capture::settings::{FitSettings, ImageModel};
use dualphoton::capture::{calibration, Capture};
use dualphoton::error::{Error, Result};
use dualphoton::experiment::{self, Run};
use dualphoton::io::manifest::write_json;
use dualphoton::io::rows::{fmt, markdown_table, write_rows};
use dualphoton::volume::Grid;
use serde::Serialize;
use std::path::{Path, PathBuf};

#[derive(Parser, Serialize)]
#[command(
    about = "A linear filter from fitted to true densities, learned on a made capture, applied to another capture"
)]
struct Args {
    /// The made capture learned from (`made_capture`'s `OUT/ambient_P`).
    #[arg(long)]
    learn_data: PathBuf,
    /// Its frames learned from.
    #[arg(long, value_delimiter = ',', default_value = "0,2,4")]
    learn_frames: Vec<usize>,
    /// The capture scored (the real one, or a made one), through the same cameras.
    #[arg(long)]
    data: PathBuf,
    /// Its frames scored.
    #[arg(long, value_delimiter = ',', required = true)]
    frames: Vec<usize>,
    /// The image model of every fit.
    #[arg(long, value_enum, default_value = "multiple")]
    model: ImageModel,
    /// Neighbourhood of the filter: voxels each way.
    #[arg(long, default_value_t = 2)]
    radius: usize,
    /// Ridge weight, relative to the sums' mean diagonal.
    #[arg(long, default_value_t = 1e-3)]
    ridge: f64,
    /// The held-out and the dropped cameras, the same in both captures.
    #[command(flatten)]
    #[serde(flatten)]
    cameras: CameraChoice,
    /// Fit settings (JSON; fields not given keep their defaults).
    #[arg(long)]
    fit_settings: Option<PathBuf>,
    /// Output directory: learned_filter.csv, filter.json, the rigs (rig_learned.json, and rig_scored.json
    /// for another capture), summary.md, manifest.json.
    #[arg(long)]
    out: PathBuf,
}

/// One line of learned_filter.csv.
#[derive(Serialize)]
struct Row {
    frame: usize,
    arm: String,
    /// The training cameras' RMSE at the working resolution, in code values.
    #[serde(serialize_with = "fmt::f4")]
    train_rmse_codes: f64,
    #[serde(serialize_with = "fmt::opt_f4")]
    psnr_db: Option<f64>,
    #[serde(serialize_with = "fmt::opt_f4")]
    rel_rmse: Option<f64>,
    /// Against a made capture's truth: the density's RMSE over the fit's
    /// hull, relative to the truth's RMS there.
    #[serde(serialize_with = "fmt::opt_f4")]
    density_rel_rmse: Option<f64>,
    /// The arm's own seconds: its lighting or its refit, and the held-out
    /// render (for `fit`, the render alone).
    #[serde(serialize_with = "fmt::f1")]
    seconds: f64,
}

/// A capture with its roles and its rig's corrections.
struct Prepared {
    capture: Capture,
    roles: Roles,
    rig: Option<Rig>,
}

fn main() -> std::process::ExitCode {
    experiment::main(run)
}

fn run(args: Args) -> Result<()> {
    if args.frames.is_empty() || args.learn_frames.is_empty() {
        return Err(Error("--frames and --learn-frames: give at least one each".into()));
    }
    if !(args.ridge.is_finite() && args.ridge > 0.0) {
        return Err(Error(format!("--ridge {}: must be finite and > 0", args.ridge)));
    }
    let settings =
        FitSettings { model: args.model, ..FitSettings::read_option(args.fit_settings.as_deref(), "--fit-settings")? };
    let same =
        |a: &Path, b: &Path| calibration::locate(a).canonicalize().ok() == calibration::locate(b).canonicalize().ok();
    let same_capture = same(&args.learn_data, &args.data);
    if same_capture && args.frames.iter().any(|f| args.learn_frames.contains(f)) {
        return Err(Error(
            "--frames and --learn-frames share a frame of the same capture: learn from other plumes".into(),
        ));
    }
    let (learn_res, learn_seed) = made_truth(&args.learn_data)?;
    let scored_truth = made_truth(&args.data).ok();
    let open = |data: &Path, frames: &[usize]| -> Result<(Capture, Roles)> {
        let capture = calibration::open(data, None, None)?;
        let roles = args.cameras.roles(&capture)?;
        check(&capture, &roles, frames, &settings)?;
        Ok((capture, roles))
    };
    let (learn_capture, learn_roles) = open(&args.learn_data, &args.learn_frames)?;
    let (capture, roles) = open(&args.data, &args.frames)?;
    let names = |c: &Capture, r: &Roles| r.training.iter().map(|&v| c.views[v].name.clone()).collect::<Vec<_>>();
    if names(&learn_capture, &learn_roles) != names(&capture, &roles) {
        return Err(Error("--learn-data and --data: the training cameras differ (names)".into()));
    }
    let run = Run::start(&args.out)?;
    let prepare = |capture: Capture, roles: Roles, name: &str| -> Result<Prepared> {
        let rig = Rig::if_shared(&capture, &roles.training, &settings, &mut |frame, fit| {
            eprintln!("{name} rig: frame {frame} fitted under {} in {:.0} s", fit.settings.model.name(), fit.seconds)
        })?;
        if let Some(rig) = &rig {
            reuse::write_rig(&run.path(&format!("rig_{name}.json")), rig)?;
        }
        Ok(Prepared { capture, roles, rig })
    };
    // Learn.
    let learn = prepare(learn_capture, learn_roles, "learned")?;
    let fixed = learn.rig.as_ref().map(Rig::corrections);
    let smoke_box = learn.capture.grid_box()?;
    let mut normal = Normal::new(args.radius);
    for images in read(&learn.capture, &learn.roles, &args.learn_frames, &settings)? {
        let training = &images.training.images[0];
        let ceilings = Some(images.training.ceilings[0].as_slice());
        let fitted =
            fit(&images.training.cameras, training, ceilings, smoke_box, &settings, fixed.as_ref(), &mut |_| {})?;
        let truth = truth_on(&fitted.scene.density, learn_res, learn_seed, images.frame, &settings);
        normal.add(&fitted.scene.density, &truth)?;
        eprintln!("learned from frame {} ({} voxels so far, fit {:.0} s)", images.frame, normal.voxels, fitted.seconds);
    }
    let filter = normal.solve(args.ridge)?;
    write_json(
        &run.path("filter.json"),
        &serde_json::json!({"radius": filter.radius, "voxels": normal.voxels, "weights": filter.weights}),
    )?;
    // Score.
    // One capture learned from and scored: its rig, fitted once, serves both.
    let scored = if same_capture {
        Prepared { capture, roles, rig: learn.rig.clone() }
    } else {
        prepare(capture, roles, "scored")?
    };
    let fixed = scored.rig.as_ref().map(Rig::corrections);
    let smoke_box = scored.capture.grid_box()?;
    let held_out = scored.roles.held_out[0];
    let mut rows = Vec::new();
    for images in read(&scored.capture, &scored.roles, &args.frames, &settings)? {
        let (cameras, training) = (&images.training.cameras, &images.training.images[0]);
        let ceilings = Some(images.training.ceilings[0].as_slice());
        let fitted = fit(cameras, training, ceilings, smoke_box, &settings, fixed.as_ref(), &mut |_| {})?;
        eprintln!("frame {}: fitted in {:.0} s", images.frame, fitted.seconds);
        let truth = scored_truth.map(|(res, seed)| truth_on(&fitted.scene.density, res, seed, images.frame, &settings));
        let mut score = |arm: &str, arm_fit: &Fit, start: std::time::Instant| -> Result<()> {
            let held = held_out_view(&scored.capture, held_out, arm_fit, &images.held_out[0])?;
            let row = Row {
                frame: images.frame,
                arm: arm.into(),
                train_rmse_codes: training_rmse(arm_fit, training) * 255.0,
                psnr_db: held.score.psnr,
                rel_rmse: held.score.rel_rmse,
                density_rel_rmse: truth.as_ref().map(|t| density_error(&arm_fit.scene.density, t)),
                seconds: start.elapsed().as_secs_f64(),
            };
            eprintln!("frame {}: {arm}: held-out PSNR {:.2} dB", row.frame, row.psnr_db.unwrap_or(f64::NAN));
            rows.push(row);
            // Every row so far, so a run cut short keeps what it finished.
            write_rows(&run.path("learned_filter.csv"), &rows)
        };
        score("fit", &fitted, std::time::Instant::now())?;
        let held = |density: Grid<f64>| fit_lighting(cameras, training, smoke_box, density, &settings, fixed.as_ref());
        let start = std::time::Instant::now();
        score("fit, held", &held(fitted.scene.density.clone())?, start)?;
        let filtered = filter.apply(&fitted.scene.density);
        let start = std::time::Instant::now();
        score("filtered, held", &held(filtered.clone())?, start)?;
        let start = std::time::Instant::now();
        let refit = fit_from(cameras, training, smoke_box, filtered, &settings, fixed.as_ref(), &mut |_| {})?;
        score("refit from filtered", &refit, start)?;
    }
    std::fs::write(run.path("summary.md"), summary(&rows, normal.voxels))?;
    run.write_manifest(&args)
}

/// A made capture's true density of `frame`, sampled at the voxel centres
/// of `like` (the fit's grid).
fn truth_on(like: &Grid<f64>, res: usize, seed: u64, frame: usize, settings: &FitSettings) -> Grid<f64> {
    let truth = plume_in_box(like.lo, like.hi, res, seed.wrapping_add(frame as u64), settings.start_depth);
    let [nz, ny, nx] = like.shape;
    let mut data = Vec::with_capacity(like.len());
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                data.push(truth.at(&like.voxel_center(k, j, i)));
            }
        }
    }
    Grid::new(like.lo, like.hi, like.shape, data)
}

/// The RMSE of `density` against `truth` over the voxels where `density`
/// is above 0 or `truth` is, relative to the truth's RMS there.
fn density_error(density: &Grid<f64>, truth: &Grid<f64>) -> f64 {
    let (mut err, mut norm) = (0.0, 0.0);
    for (&d, &t) in density.data.iter().zip(&truth.data) {
        if d > 0.0 || t > 0.0 {
            err += (d - t) * (d - t);
            norm += t * t;
        }
    }
    (err / norm.max(f64::MIN_POSITIVE)).sqrt()
}

/// summary.md: per arm, the means over the frames, and the PSNR frame by frame.
fn summary(rows: &[Row], voxels: usize) -> String {
    let mut arms: Vec<&str> = Vec::new();
    for r in rows {
        if !arms.contains(&r.arm.as_str()) {
            arms.push(&r.arm);
        }
    }
    let mean = |v: Vec<f64>| v.iter().sum::<f64>() / v.len().max(1) as f64;
    let table = markdown_table(
        &[
            "arm",
            "held-out PSNR (dB)",
            "relative RMSE (%)",
            "training RMSE (codes)",
            "density error (%)",
            "PSNR per frame",
        ],
        arms.iter().map(|&arm| {
            let mine: Vec<&Row> = rows.iter().filter(|r| r.arm == arm).collect();
            let density: Vec<f64> = mine.iter().filter_map(|r| r.density_rel_rmse).collect();
            vec![
                arm.to_string(),
                format!("{:.2}", mean(mine.iter().filter_map(|r| r.psnr_db).collect())),
                format!("{:.1}", 100.0 * mean(mine.iter().filter_map(|r| r.rel_rmse).collect())),
                format!("{:.2}", mean(mine.iter().map(|r| r.train_rmse_codes).collect())),
                if density.is_empty() { String::new() } else { format!("{:.1}", 100.0 * mean(density)) },
                mine.iter()
                    .map(|r| format!("{}: {:.2}", r.frame, r.psnr_db.unwrap_or(f64::NAN)))
                    .collect::<Vec<_>>()
                    .join(", "),
            ]
        }),
    );
    format!(
        "# A learned filter\n\nLearned on {voxels} voxels of the made capture's fits. Means over frames:\n\n{table}"
    )
}
