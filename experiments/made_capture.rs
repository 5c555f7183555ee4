//! A made capture: the built-in plume, rendered with multiple scattering
//! through a real capture's cameras and written as that capture is
//! distributed (`info.json` and one folder of 8-bit PNG frames per camera),
//! so that `experiment_real` fits it as it fits the real one.
//!
//! Why: on ScalarFlow's clip multiple scattering and emission-absorption
//! tie, and the fits give the lights 1 % of the light. A made capture says
//! whether that is the clip's lighting or the method: here the truth's
//! light is known (lights only, or a share from an ambient term), the
//! cameras are exactly the calibration's, and nothing is fitted.
//!
//! The truth, fixed before any fit: each frame is the built-in plume of
//! seed `--seed + frame` stretched over the capture's smoke box, at an
//! optical depth across it of the fit's start (`FitSettings::start_depth`,
//! 1, by the fit's own `start_density`); the albedo and g the fit assumes
//! (1 and 0.6), [`ORDERS`] orders; three lights ([`Lights`]: by default at
//! places the fit's candidates do not hold); the images scaled once, on frame 0, so
//! that the brightest of the smoke's pixels reach [`BRIGHTEST`]; the
//! photographs' noise ([`NOISE_CODES`]), 8-bit codes, and codes up to 8 set
//! to 0, as ScalarFlow's processing left them.

use clap::Parser;
use dualphoton::capture::calibration;
use dualphoton::capture::density::plume_in_box;
use dualphoton::capture::lighting::{candidate_lights, direction};
use dualphoton::capture::settings::FitSettings;
use dualphoton::error::{Error, Result};
use dualphoton::experiment::{self, Run};
use dualphoton::image::Image;
use dualphoton::io::png::write_codes;
use dualphoton::math::Vec3;
use dualphoton::render::render_photon;
use dualphoton::rng::{Purpose, Rng};
use dualphoton::scene::{Light, Medium, RenderSettings, Scene};
use serde::Serialize;
use serde_json::Value;
use std::path::PathBuf;

/// Scattering orders of the truth (the fit uses 3).
const ORDERS: u32 = 8;
/// Photons of the truth's renders of the lights: their noise below the photographs'.
const PHOTONS: u64 = 500_000;
/// The brightest 0.1 % of the training views' smoke pixels on frame 0 (code value / 255).
const BRIGHTEST: f64 = 0.6;
/// The photographs' noise, in code values (ScalarFlow's, from three consecutive frames: 1.33).
const NOISE_CODES: f64 = 1.33;
/// ScalarFlow's processing set codes up to this to 0.
const BLACK_CODES: f64 = 8.0;
/// The truth is rendered at 1/`RENDER_FACTOR` of the capture's resolution and
/// each pixel repeated: the fit sees 1/8 and the protocol scores 1/2, both
/// area averages that give back the render; the noise is the full resolution's.
const RENDER_FACTOR: usize = 2;

#[derive(Parser, Serialize)]
#[command(about = "A made capture: the built-in plume through a real capture's cameras, written as a capture")]
struct Args {
    /// The real capture whose cameras and smoke box are used (its info.json, or the folder holding it); its
    /// frames are not read.
    #[arg(long)]
    like: PathBuf,
    /// Shares of the training images' light from the ambient term (the rest from three lights), each in
    /// [0, 1]: one capture each, `OUT/ambient_P` for P percent, from the same renders.
    #[arg(long, value_delimiter = ',', default_value = "0,0.5")]
    ambient_shares: Vec<f64>,
    /// Frames (plumes) written.
    #[arg(long, default_value_t = 6)]
    frames: usize,
    /// Grid edge of the plume.
    #[arg(long, default_value_t = 64)]
    res: usize,
    /// Where the three lights are.
    #[arg(long, value_enum, default_value_t = Lights::Between)]
    lights: Lights,
    /// Seed of the plumes, the renders and the noise.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Output directory: per share, info.json and a folder of PNG frames per camera.
    #[arg(long)]
    out: PathBuf,
}

/// The truth's three lights.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, clap::ValueEnum)]
enum Lights {
    /// 35 degrees above the box's centre at azimuths 30, 150 and 270
    /// degrees, 1.5 box diagonals away: between the fit's candidates
    /// (`capture::lighting::candidate_lights`: every 60 degrees from 0, 20
    /// degrees up, 2 diagonals away), so the fit cannot hold them exactly.
    /// ScalarFlow's central camera looks almost into the one at 270 (18
    /// degrees of scattering, 31 for the nearest other camera).
    Between,
    /// The fit's candidates at azimuths 0, 120 and 240 degrees: the fit
    /// can hold them exactly, and on ScalarFlow's cameras the central one's
    /// strongest forward scattering (31 degrees) lies between two other
    /// cameras' (5 and 21).
    Candidates,
}

impl Lights {
    /// The three lights about the box `lo`..`hi`, each of intensity 1.
    fn place(self, lo: &Vec3, hi: &Vec3) -> Vec<Light> {
        match self {
            Lights::Between => {
                let centre = (lo + hi) / 2.0;
                let distance = 1.5 * (hi - lo).norm();
                [30.0, 150.0, 270.0]
                    .iter()
                    .map(|&az| Light { position: centre + direction(az, 35.0) * distance, intensity: 1.0 })
                    .collect()
            }
            // Every other one of the six candidates around the box: azimuths 0, 120, 240.
            Lights::Candidates => candidate_lights(lo, hi, 0.0)
                .into_iter()
                .step_by(2)
                .take(3)
                .map(|light| Light { intensity: 1.0, ..light })
                .collect(),
        }
    }
}

fn main() -> std::process::ExitCode {
    experiment::main(run)
}

fn run(args: Args) -> Result<()> {
    if let Some(bad) = args.ambient_shares.iter().find(|s| !(0.0..=1.0).contains(*s)) {
        return Err(Error(format!("--ambient-shares: {bad} is not in [0, 1]")));
    }
    if args.frames == 0 {
        return Err(Error("--frames: give at least 1".into()));
    }
    experiment::check_res(args.res)?;
    let info = calibration::locate(&args.like);
    let capture = calibration::load(&info)?;
    let (lo, hi) = capture.grid_box()?;
    if let Some(small) = capture.views.iter().find(|v| v.camera.width.min(v.camera.height) < RENDER_FACTOR) {
        return Err(Error(format!("camera {}: images of at least {RENDER_FACTOR} pixels a side", small.name)));
    }
    let run = Run::start(&args.out)?;
    let training: Vec<bool> = capture.views.iter().map(|v| !v.held_out).collect();
    let folders: Vec<PathBuf> =
        args.ambient_shares.iter().map(|s| run.path(&format!("ambient_{}", (s * 100.0).round()))).collect();
    let mut scales: Vec<Option<(f64, f64)>> = vec![None; folders.len()];
    for frame in 0..args.frames {
        let cameras = capture.views.iter().map(|v| v.camera.downsample(RENDER_FACTOR)).collect();
        let scene = truth(&args, frame, lo, hi, cameras);
        let (lit, ambient) = (render(&scene, false), render(&scene, true));
        for ((folder, &share), scale) in folders.iter().zip(&args.ambient_shares).zip(&mut scales) {
            // Each part's weight: fixed on frame 0, so the exposure never changes.
            let (w_lit, w_ambient) = *scale.get_or_insert_with(|| weights(&lit, &ambient, &training, share));
            for (c, view) in capture.views.iter().enumerate() {
                let image: Vec<f64> =
                    lit[c].data.iter().zip(&ambient[c].data).map(|(l, a)| w_lit * l + w_ambient * a).collect();
                let (width, height) = (view.camera.width, view.camera.height);
                let full = repeated(&image, (lit[c].width, lit[c].height), width, height);
                let codes = photograph(&full, args.seed, frame, c);
                let dir = folder.join(&view.name);
                std::fs::create_dir_all(&dir)?;
                write_codes(&dir.join(format!("{frame:03}.png")), width, height, &codes)?;
            }
        }
        eprintln!("frame {frame} of {} written ({:.0} s)", args.frames, run.seconds());
    }
    for folder in &folders {
        write_info(&info, folder, capture.views.iter().map(|v| v.name.as_str()).collect(), args.frames)?;
    }
    run.write_manifest(&args)
}

/// Frame `frame`'s scene: the plume on the smoke box, the three lights, every camera.
fn truth(args: &Args, frame: usize, lo: Vec3, hi: Vec3, cameras: Vec<dualphoton::scene::Camera>) -> Scene {
    let fit = FitSettings::default();
    let density = plume_in_box(lo, hi, args.res, args.seed.wrapping_add(frame as u64), fit.start_depth);
    Scene {
        density,
        medium: Medium { sigma_t_scale: 1.0, albedo: fit.albedo, g: fit.g, max_order: ORDERS, emission: 0.0 },
        lights: args.lights.place(&lo, &hi),
        cameras,
        render: RenderSettings {
            photons: PHOTONS,
            spp: 1,
            seed: args.seed.wrapping_mul(1000).wrapping_add(frame as u64),
            ..RenderSettings::default()
        },
    }
}

/// The images of the lights alone, or of the ambient term alone (emission 1, the lights off).
fn render(scene: &Scene, ambient: bool) -> Vec<Image> {
    let mut one = scene.clone();
    if ambient {
        // The emission is scattered once: no photons.
        one.medium.emission = 1.0;
        one.lights.iter_mut().for_each(|l| l.intensity = 0.0);
        one.render.photons = 0;
        one.medium.max_order = 1;
    }
    render_photon(&one).images
}

/// The weights of the lights' and the ambient term's images that give the
/// ambient term `share` of the training views' light and put their
/// brightest 0.1 % of smoke pixels at [`BRIGHTEST`].
fn weights(lit: &[Image], ambient: &[Image], training: &[bool], share: f64) -> (f64, f64) {
    let total = |images: &[Image]| -> f64 {
        images.iter().zip(training).filter(|(_, &t)| t).map(|(im, _)| im.data.iter().sum::<f64>()).sum()
    };
    let (w_lit, w_ambient) =
        ((1.0 - share) / total(lit).max(f64::MIN_POSITIVE), share / total(ambient).max(f64::MIN_POSITIVE));
    let mut smoke: Vec<f64> = lit
        .iter()
        .zip(ambient)
        .zip(training)
        .filter(|(_, &t)| t)
        .flat_map(|((l, a), _)| l.data.iter().zip(&a.data).map(|(l, a)| w_lit * l + w_ambient * a).collect::<Vec<_>>())
        .filter(|&v| v > 0.0)
        .collect();
    smoke.sort_by(f64::total_cmp);
    let brightest = smoke.get(smoke.len() * 999 / 1000).copied().unwrap_or(1.0).max(f64::MIN_POSITIVE);
    (w_lit * BRIGHTEST / brightest, w_ambient * BRIGHTEST / brightest)
}

/// `image` (`small_width` x `small_height`) at `width` x `height`, each
/// pixel repeated (an odd last row or column repeats the one before).
fn repeated(image: &[f64], small: (usize, usize), width: usize, height: usize) -> Vec<f64> {
    let (small_width, small_height) = small;
    (0..width * height)
        .map(|i| {
            let x = ((i % width) / RENDER_FACTOR).min(small_width - 1);
            let y = ((i / width) / RENDER_FACTOR).min(small_height - 1);
            image[y * small_width + x]
        })
        .collect()
}

/// `image` as a photograph: the noise added (seeded by frame and camera),
/// rounded to 8-bit codes, codes up to [`BLACK_CODES`] set to 0; code value / 255.
fn photograph(image: &[f64], seed: u64, frame: usize, camera: usize) -> Vec<f64> {
    let mut rng = Rng::new(seed, Purpose::Scene, (1 << 40) + (frame as u64) * 64 + camera as u64);
    image
        .iter()
        .map(|&v| {
            let code = (v * 255.0 + NOISE_CODES * rng.normal()).round().clamp(0.0, 255.0);
            if code <= BLACK_CODES {
                0.0
            } else {
                code / 255.0
            }
        })
        .collect()
}

/// The capture's `info.json` with every camera's `file_name` its folder of frames and `frame_num` `frames`.
fn write_info(info: &std::path::Path, folder: &std::path::Path, names: Vec<&str>, frames: usize) -> Result<()> {
    let mut json: Value =
        serde_json::from_str(&std::fs::read_to_string(info)?).map_err(|e| Error(format!("{}: {e}", info.display())))?;
    let mut named = names.into_iter();
    for key in ["train_videos", "test_videos"] {
        if let Some(Value::Array(videos)) = json.get_mut(key) {
            for video in videos {
                let name = named.next().ok_or_else(|| Error("the calibration changed while read".into()))?;
                video["file_name"] = Value::from(name);
                video["frame_num"] = Value::from(frames);
            }
        }
    }
    std::fs::write(folder.join("info.json"), serde_json::to_string_pretty(&json).map_err(|e| Error(e.to_string()))?)?;
    Ok(())
}
