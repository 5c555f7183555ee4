//! The lights a made capture's true density gives: the lighting a fit
//! would fit (the candidates' intensities, the ambient term and the
//! training cameras' gains) with the density held at the truth, through
//! the calibration's cameras, under multiple scattering with the fit's
//! orders and with the truth's, and under emission-absorption (its
//! emission and gains). Then the held-out camera, rendered and scored as
//! `experiment_real` scores it.
//!
//! With `--blur`, the density is also held blurred (a Gaussian of so many
//! voxels): how much of the held-out score lives in the density's fine
//! detail, which four views resolve least. With `--fitted`, the density
//! held is the one a fit reaches (each arm's settings, the cameras as
//! calibrated) instead of the truth's: whether its fine detail helps the
//! held-out view or harms it.
//!
//! Why: on a made capture the fit misplaces one of the truth's lights. With
//! the truth's density, whether the lights come back says whether the
//! training views can tell them apart, or whether the density the fit
//! reaches is what sends them elsewhere; the training RMSE and the held-out
//! score say what each image model gives at best, its density right.

use clap::Parser;
use dualphoton::capture::calibration;
use dualphoton::capture::density::{made_truth, plume_in_box};
use dualphoton::capture::fit::{fit, fit_lighting, training_rmse};
use dualphoton::capture::frame::{held_out_view, read, Roles};
use dualphoton::capture::settings::{FitSettings, ImageModel};
use dualphoton::error::{Error, Result};
use dualphoton::experiment::{self, Run};
use dualphoton::io::rows::{fmt, markdown_table, write_rows};
use dualphoton::volume::blur::gaussian_blur;
use serde::Serialize;
use std::path::PathBuf;

#[derive(Parser, Serialize)]
#[command(about = "The lighting a made capture's true density gives, and its held-out score")]
struct Args {
    /// A made capture (`made_capture`'s `OUT/ambient_P`): its info.json and frames; the folder above it holds
    /// the manifest that gives the truth's plume.
    #[arg(long)]
    data: PathBuf,
    /// Frames fitted and scored.
    #[arg(long, value_delimiter = ',', default_value = "1,3,5")]
    frames: Vec<usize>,
    /// Image models.
    #[arg(long, value_enum, value_delimiter = ',', default_value = "multiple,emission-absorption")]
    models: Vec<ImageModel>,
    /// Scattering orders of multiple scattering's renders: the fit's (3) and the truth's (8) by default.
    #[arg(long, value_delimiter = ',', default_value = "3,8")]
    orders: Vec<u32>,
    /// Widths (voxels, standard deviation) of a Gaussian blur of the density, each an arm; 0: as it is.
    #[arg(long, value_delimiter = ',', default_value = "0")]
    blur: Vec<f64>,
    /// Hold the density each arm's fit reaches (the cameras as calibrated) instead of the truth's.
    #[arg(long)]
    fitted: bool,
    /// Fit settings (JSON; fields not given keep their defaults), for studies: the image model and the
    /// orders come from `--models` and `--orders`, and the cameras are never aligned.
    #[arg(long)]
    fit_settings: Option<PathBuf>,
    /// Output directory: lights.csv, summary.md, manifest.json.
    #[arg(long)]
    out: PathBuf,
}

/// One line of lights.csv.
#[derive(Serialize)]
struct Row {
    frame: usize,
    model: String,
    /// Most scattering events on a light path (0: emission-absorption, no lights).
    orders: u32,
    /// The width of the Gaussian blur of the density (voxels; 0: none).
    #[serde(serialize_with = "fmt::f1")]
    blur_voxels: f64,
    /// The candidates' intensities (`;`-separated, in `candidate_lights`' order).
    lights: String,
    #[serde(serialize_with = "fmt::e6")]
    emission: f64,
    #[serde(serialize_with = "fmt::opt_f4")]
    light_share: Option<f64>,
    /// Per training camera (`;`-separated).
    gains: String,
    /// The training cameras' RMSE at the working resolution, in code values.
    #[serde(serialize_with = "fmt::f4")]
    train_rmse_codes: f64,
    #[serde(serialize_with = "fmt::opt_f4")]
    psnr_db: Option<f64>,
    #[serde(serialize_with = "fmt::opt_f4")]
    rel_rmse: Option<f64>,
    /// Seconds for the row's lighting and score, plus its arm's fit with `--fitted`.
    #[serde(serialize_with = "fmt::f1")]
    seconds: f64,
}

fn main() -> std::process::ExitCode {
    experiment::main(run)
}

fn run(args: Args) -> Result<()> {
    if args.frames.is_empty() || args.orders.is_empty() || args.models.is_empty() || args.blur.is_empty() {
        return Err(Error("--frames, --models, --orders and --blur: give at least one each".into()));
    }
    if let Some(b) = args.blur.iter().find(|b| !(b.is_finite() && **b >= 0.0)) {
        return Err(Error(format!("--blur {b}: a width must be finite and >= 0")));
    }
    let defaults = FitSettings::read_option(args.fit_settings.as_deref(), "--fit-settings")?;
    // Each arm's settings and its orders (0: emission-absorption), all checked before any work.
    let mut arms = Vec::new();
    for &model in &args.models {
        let orders = if model == ImageModel::Multiple { args.orders.clone() } else { vec![defaults.orders] };
        for orders in orders {
            let settings = FitSettings { model, orders, align: false, ..defaults.clone() };
            settings.validate().map_err(|e| Error(format!("--orders {orders}: {}", e.0)))?;
            let shown = match model {
                ImageModel::Multiple => orders,
                ImageModel::Single => 1,
                ImageModel::EmissionAbsorption => 0,
            };
            arms.push((settings, shown));
        }
    }
    let (res, seed) = made_truth(&args.data)?;
    let capture = calibration::load(&calibration::locate(&args.data))?;
    let roles = Roles::of(&capture);
    let &held_out = roles.held_out.first().ok_or_else(|| Error("the capture has no held-out camera".into()))?;
    dualphoton::capture::frame::check(&capture, &roles, &args.frames, &defaults)?;
    let smoke_box = capture.grid_box()?;
    let run = Run::start(&args.out)?;
    let frames = read(&capture, &roles, &args.frames, &defaults)?;
    let mut rows = Vec::new();
    for images in &frames {
        let truth =
            plume_in_box(smoke_box.0, smoke_box.1, res, seed.wrapping_add(images.frame as u64), defaults.start_depth);
        let training = &images.training.images[0];
        for (settings, orders) in &arms {
            let start = std::time::Instant::now();
            let held = if args.fitted {
                fit(
                    &images.training.cameras,
                    training,
                    Some(&images.training.ceilings[0]),
                    smoke_box,
                    settings,
                    None,
                    &mut |_| {},
                )?
                .scene
                .density
            } else {
                truth.clone()
            };
            let fit_s = start.elapsed().as_secs_f64();
            let (model, orders) = (settings.model, *orders);
            for &blur in &args.blur {
                let density = gaussian_blur(&held, blur);
                let start = std::time::Instant::now();
                let fit = fit_lighting(&images.training.cameras, training, smoke_box, density, settings, None)?;
                let score = held_out_view(&capture, held_out, &fit, &images.held_out[0])?.score;
                let join = |v: &[f64]| v.iter().map(|x| format!("{x:.4}")).collect::<Vec<_>>().join(";");
                let lights: Vec<f64> = fit.scene.lights.iter().map(|l| l.intensity).collect();
                rows.push(Row {
                    frame: images.frame,
                    model: model.name().into(),
                    orders,
                    blur_voxels: blur,
                    lights: join(&lights),
                    emission: fit.scene.medium.emission,
                    light_share: fit.light_share,
                    gains: join(&fit.gains),
                    train_rmse_codes: training_rmse(&fit, training) * 255.0,
                    psnr_db: score.psnr,
                    rel_rmse: score.rel_rmse,
                    seconds: fit_s + start.elapsed().as_secs_f64(),
                });
                // Every row so far, so a run cut short keeps what it finished.
                write_rows(&run.path("lights.csv"), &rows)?;
                eprintln!(
                    "frame {} {} orders {orders} blur {blur}: done ({:.0} s)",
                    images.frame,
                    model.name(),
                    run.seconds()
                );
            }
        }
    }
    let table = markdown_table(
        &[
            "frame",
            "model",
            "orders",
            "blur (voxels)",
            "lights (candidates' order)",
            "emission",
            "lights' share",
            "gains",
            "training RMSE (codes)",
            "held-out PSNR (dB)",
            "relative RMSE",
        ],
        rows.iter().map(|r| {
            let opt = |v: Option<f64>, d: usize| v.map_or("-".into(), |v| format!("{v:.d$}"));
            vec![
                r.frame.to_string(),
                r.model.clone(),
                r.orders.to_string(),
                format!("{}", r.blur_voxels),
                r.lights.clone(),
                format!("{:.4}", r.emission),
                opt(r.light_share, 3),
                r.gains.clone(),
                format!("{:.3}", r.train_rmse_codes),
                opt(r.psnr_db, 2),
                opt(r.rel_rmse, 3),
            ]
        }),
    );
    std::fs::write(
        run.path("summary.md"),
        format!(
            "# The lighting of the {} density\n\nHeld-out camera: {}.\n\n{table}",
            if args.fitted { "fitted" } else { "true" },
            capture.views[held_out].name
        ),
    )?;
    run.write_manifest(&args)
}
