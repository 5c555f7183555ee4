//! What `dualphoton fit --capture` writes into its output folder:
//! `scene.json` with `density.npy` (the fitted density on the smoke box, the
//! lights and the emission, the training cameras at the working
//! resolution: a scene `dualphoton render` takes), `log.csv` (per update),
//! `fit_quality.csv` (per camera), `held_out.npy` and `held_out.png` (the
//! held-out camera at the capture's resolution, code value / 255 after the
//! fitted response; with several held-out cameras, `held_out_NAME.*`),
//! `rig.json` and `settings.json` (the training cameras' alignment, where
//! the settings align them once for every frame, and what it was made
//! with: a later frame's fit takes the folder as `--rig`) and
//! `manifest.json`.

use super::calibration;
use super::fit::{held_out_black, training_views, FitRow};
use super::frame::{check, fit_frame, read, FrameFit, Roles};
use super::reuse::{self, RunSettings};
use super::rig::Rig;
use super::settings::FitSettings;
use super::Capture;
use crate::error::{Error, Result};
use crate::eval::metrics::show_score;
use crate::experiment::Run;
use crate::io::rows::{fmt, write_rows};
use crate::io::{npy, png};
use crate::math::Vec3;
use crate::scene::file;
use serde::Serialize;
use std::path::Path;

/// One line of fit_quality.csv.
#[derive(Serialize)]
struct Quality {
    camera: String,
    role: &'static str,
    /// The resolution scored: the working one (training) or the protocol's (held out).
    width: usize,
    height: usize,
    #[serde(serialize_with = "fmt::opt_f4")]
    psnr_db: Option<f64>,
    #[serde(serialize_with = "fmt::opt_f4")]
    rel_rmse: Option<f64>,
    /// The camera's fitted gain (a held-out camera's by the fit's rule: 1)
    /// and black level in code values of 255 (a held-out camera's by the
    /// fit's rule: the training cameras' mean; 0 unless fitted).
    #[serde(serialize_with = "fmt::f4")]
    gain: f64,
    #[serde(serialize_with = "fmt::f2")]
    black_level_codes: f64,
    /// How far the fit moved the camera's principal point (full-resolution
    /// pixels, right and down) and the factor it scaled its focal lengths
    /// by, and the angle it was turned by about its optical axis (degrees);
    /// a held-out camera is never moved (0, 0, 1, 0).
    #[serde(serialize_with = "fmt::f1")]
    offset_x_px: f64,
    #[serde(serialize_with = "fmt::f1")]
    offset_y_px: f64,
    #[serde(serialize_with = "fmt::f4")]
    zoom: f64,
    #[serde(serialize_with = "fmt::f4")]
    roll_deg: f64,
    /// A held-out camera's PSNR with its view scaled by the least-squares
    /// gain onto its photograph, and moved by the best whole-pixel shift
    /// (`super::protocol::Oracle`): how much of its error its unknown
    /// response or a calibration error would explain. Empty for training cameras.
    #[serde(serialize_with = "fmt::opt_f4")]
    psnr_oracle_gain_db: Option<f64>,
    #[serde(serialize_with = "fmt::opt_f4")]
    psnr_oracle_shift_db: Option<f64>,
    /// A held-out camera's best magnification about its principal point and
    /// its PSNR and relative RMSE with it and the best shift after it
    /// (`super::protocol::Aligned`): the camera aligned as the training
    /// cameras are. Empty for training cameras.
    #[serde(serialize_with = "fmt::opt_f4")]
    oracle_magnification: Option<f64>,
    #[serde(serialize_with = "fmt::opt_f4")]
    psnr_oracle_aligned_db: Option<f64>,
    #[serde(serialize_with = "fmt::opt_f4")]
    rel_rmse_oracle_aligned: Option<f64>,
    /// What a reconstruction exact to the smoke would score through a
    /// held-out camera off by that error (`super::protocol::ExactSmoke`):
    /// its photograph moved back by the magnification and shift, PSNR and
    /// relative RMSE. Empty for training cameras.
    #[serde(serialize_with = "fmt::opt_f4")]
    psnr_exact_smoke_db: Option<f64>,
    #[serde(serialize_with = "fmt::opt_f4")]
    rel_rmse_exact_smoke: Option<f64>,
}

/// The manifest's settings.
#[derive(Serialize)]
struct Settings<'a> {
    capture: &'a Path,
    focal_lengths: Option<&'a Path>,
    frame: usize,
    fit: &'a FitSettings,
    /// The density grid's box (capture units) and shape (Z, Y, X).
    bbox_min: [f64; 3],
    bbox_max: [f64; 3],
    shape: [usize; 3],
    training: Vec<&'a str>,
    held_out: Vec<&'a str>,
}

/// Fits frame `frame` of the capture at `calibration_path` (a file or the
/// folder holding it), with the focal lengths of ScalarFlow's camera file
/// `focal_lengths` and the density on `smoke_box` if given (else the
/// calibration's), and writes everything into `out`. The training cameras'
/// alignment is the rig an earlier run wrote into `earlier` if given (made
/// with the same cameras and settings), else fitted here.
pub fn fit_and_write(
    calibration_path: &Path,
    focal_lengths: Option<&Path>,
    smoke_box: Option<(Vec3, Vec3)>,
    frame: usize,
    settings: &FitSettings,
    earlier: Option<&Path>,
    out: &Path,
) -> Result<()> {
    let capture = calibration::open(calibration_path, focal_lengths, smoke_box)?;
    let settings = &settings.for_capture(capture.frame_count());
    let roles = Roles::of(&capture);
    check(&capture, &roles, &[frame], settings).map_err(|e| Error(format!("--capture: {e}")))?;
    let record = RunSettings::of(&capture, &roles, settings)?;
    let earlier_rig = earlier
        .map(|dir| reuse::earlier_rig(dir, &record, &capture, &roles, settings))
        .transpose()
        .map_err(|e| Error(format!("--rig: {e}")))?;
    // The frame is read before the output folder is made: photographs the
    // fit refuses (another size, light outside the box) leave nothing behind.
    let first = &capture.views[roles.training[0]];
    let working = first.camera.downsample(settings.factor);
    eprintln!(
        "reading frame {frame} of {} cameras (fitted at 1/{} of their resolution: {}x{} for {}) ...",
        roles.training.len() + roles.held_out.len(),
        settings.factor,
        working.width,
        working.height,
        first.name
    );
    let images = read(&capture, &roles, &[frame], settings)?.remove(0);
    // So are the rig's calibration frames, where it is fitted here.
    let rig_photographs = match (&earlier_rig, settings.aligns_once()) {
        (None, true) => Some(Rig::photographs(&capture, &roles.training, settings)?),
        _ => None,
    };
    let run = Run::start(out).map_err(|e| Error(format!("--out: {e}")))?;
    let rig = match earlier_rig {
        Some(rig) => Some(rig),
        None => reuse::fit_rig(&capture, &roles, settings, rig_photographs)?,
    };
    if let Some(rig) = &rig {
        record.write(out)?;
        reuse::write_rig(&run.path("rig.json"), rig)?;
    }
    let mut log: Vec<FitRow> = Vec::new();
    let result = fit_frame(&capture, &roles, &images, settings, rig.as_ref(), &mut |row| {
        // A line every 10 updates: as readable in a log file as in a terminal.
        if row.update % 10 == 0 {
            eprintln!(
                "stage {} update {}: image RMSE {:.5} ({:.0} s)",
                row.level,
                row.update,
                row.image_mse.sqrt(),
                row.seconds
            );
        }
        log.push(row.clone());
    })?;
    write(&run, &capture, &roles, &images.training.images[0], &result, &log)?;
    let scene = &result.fit.scene;
    let d = &scene.density;
    run.write_manifest(&Settings {
        capture: &calibration::locate(calibration_path),
        focal_lengths,
        frame,
        fit: settings,
        bbox_min: [d.lo.x, d.lo.y, d.lo.z],
        bbox_max: [d.hi.x, d.hi.y, d.hi.z],
        shape: d.shape,
        training: roles.training.iter().map(|&v| capture.views[v].name.as_str()).collect(),
        held_out: roles.held_out.iter().map(|&v| capture.views[v].name.as_str()).collect(),
    })?;
    eprintln!("fit: frame {frame} in {:.0} s -> {}", result.fit.seconds, out.display());
    Ok(())
}

/// Writes the fit's files (all but the manifest).
fn write(
    run: &Run,
    capture: &Capture,
    roles: &Roles,
    targets: &[crate::image::Image],
    result: &FrameFit,
    log: &[FitRow],
) -> Result<()> {
    let scene = &result.fit.scene;
    file::save(scene, &run.out, "scene")?;
    write_rows(&run.path("log.csv"), log)?;
    let mut quality = Vec::new();
    let views = training_views(&result.fit);
    let fit = &result.fit;
    let offsets = fit.offsets_px();
    let moves = fit.gains.iter().zip(&fit.black_levels).zip(&offsets).zip(fit.zooms.iter().zip(&fit.rolls));
    for (((&v, image), target), (((&gain, &black), offset), (&zoom, &roll))) in
        roles.training.iter().zip(&views).zip(targets).zip(moves)
    {
        let score = super::protocol::Score::of(image, target);
        let name = capture.views[v].name.clone();
        quality.push(Quality {
            camera: name,
            role: "training",
            width: image.width,
            height: image.height,
            psnr_db: score.psnr,
            rel_rmse: score.rel_rmse,
            gain,
            black_level_codes: 255.0 * black,
            offset_x_px: offset[0],
            offset_y_px: offset[1],
            zoom,
            roll_deg: roll.to_degrees(),
            psnr_oracle_gain_db: None,
            psnr_oracle_shift_db: None,
            oracle_magnification: None,
            psnr_oracle_aligned_db: None,
            rel_rmse_oracle_aligned: None,
            psnr_exact_smoke_db: None,
            rel_rmse_exact_smoke: None,
        });
    }
    let single = result.held_out.len() == 1;
    for held in &result.held_out {
        let view = &capture.views[held.view];
        let stem = if single { "held_out".to_string() } else { format!("held_out_{}", view.name) };
        let p = &held.prediction;
        npy::write_f32(&run.path(&format!("{stem}.npy")), &[p.height, p.width], &p.data)?;
        png::write_codes(&run.path(&format!("{stem}.png")), p.width, p.height, &p.data)?;
        let protocol = super::protocol::Protocol::for_size(p.width, p.height);
        let [_, _, w, h] = protocol.crop;
        quality.push(Quality {
            camera: view.name.clone(),
            role: "held-out",
            width: w,
            height: h,
            psnr_db: held.score.psnr,
            rel_rmse: held.score.rel_rmse,
            gain: 1.0,
            black_level_codes: 255.0 * held_out_black(fit),
            offset_x_px: 0.0,
            offset_y_px: 0.0,
            zoom: 1.0,
            roll_deg: 0.0,
            psnr_oracle_gain_db: held.oracle.with_gain.psnr,
            psnr_oracle_shift_db: held.oracle.with_shift.psnr,
            oracle_magnification: Some(held.aligned.magnification),
            psnr_oracle_aligned_db: held.aligned.score.psnr,
            rel_rmse_oracle_aligned: held.aligned.score.rel_rmse,
            psnr_exact_smoke_db: held.exact.through_aligned.psnr,
            rel_rmse_exact_smoke: held.exact.through_aligned.rel_rmse,
        });
        eprintln!(
            "held-out camera {}: PSNR {}, relative RMSE {} ({})",
            view.name,
            show_score(held.score.psnr, 1.0, 2, " dB"),
            show_score(held.score.rel_rmse, 100.0, 1, " %"),
            protocol.name()
        );
        let [dx, dy] = held.oracle.shift;
        eprintln!(
            "  moved by its best whole-pixel shift ({dx} right, {dy} down, in the protocol's pixels) it would \
             score {}, magnified {:.4} times and shifted {}: what a calibration error of the held-out camera \
             costs (fit_quality.csv); the smoke itself, seen through a camera so far off, would score {}",
            show_score(held.oracle.with_shift.psnr, 1.0, 2, " dB"),
            held.aligned.magnification,
            show_score(held.aligned.score.psnr, 1.0, 2, " dB"),
            show_score(held.exact.through_aligned.psnr, 1.0, 2, " dB")
        );
    }
    write_rows(&run.path("fit_quality.csv"), &quality)
}
