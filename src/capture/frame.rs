//! One frame of a capture, end to end: every check before any work, the
//! training cameras' images at the working resolution, the fit, and each
//! held-out camera rendered at the capture's full resolution and scored
//! under its protocol (`Protocol::for_size`). `dualphoton fit --capture` and
//! `experiment_real` both go through here.

use super::fit::{fit, render_view, Fit, FitRow};
use super::observe::{area_average, area_ceiling, check_light_outside_box, observe, Observed};
use super::protocol::{Aligned, ExactSmoke, Oracle, Protocol, Score};
use super::rig::Rig;
use super::settings::FitSettings;
use super::{first_repeat, frames, Capture, Frames};
use crate::error::{Error, Result};
use crate::image::Image;
use crate::math::{inside_box, Vec3};
use serde::Serialize;
use std::time::Instant;

/// Which cameras train and which are held out.
#[derive(Clone, Debug)]
pub struct Roles {
    /// Training cameras (indices into the capture's views).
    pub training: Vec<usize>,
    /// Held-out cameras: scored, never fitted.
    pub held_out: Vec<usize>,
}

/// Which camera a study holds out and which it leaves out, as its command
/// line names them ([`Roles::choose`]).
#[derive(Clone, Debug, Default, clap::Args, Serialize)]
pub struct CameraChoice {
    /// The held-out camera (default: the calibration's test camera).
    #[arg(long)]
    pub held_out: Option<String>,
    /// Cameras left out of everything (to study settings on training cameras alone).
    #[arg(long, value_delimiter = ',')]
    pub drop: Vec<String>,
}

impl CameraChoice {
    /// The roles this choice gives the cameras of `capture`.
    pub fn roles(&self, capture: &Capture) -> Result<Roles> {
        Roles::choose(capture, self.held_out.as_deref(), &self.drop)
    }
}

impl Roles {
    /// The calibration's own split: its test cameras held out, every other camera trains.
    pub fn of(capture: &Capture) -> Roles {
        let (held_out, training) = (0..capture.views.len()).partition(|&v| capture.views[v].held_out);
        Roles { training, held_out }
    }

    /// One held-out camera, the one named `held_out` (default: the
    /// calibration's one test camera), and every other camera but the
    /// `dropped` ones (and the calibration's other test cameras) training.
    pub fn choose(capture: &Capture, held_out: Option<&str>, dropped: &[String]) -> Result<Roles> {
        let held_out = match held_out {
            Some(name) => capture.view(name)?,
            None => {
                let tests: Vec<usize> = (0..capture.views.len()).filter(|&v| capture.views[v].held_out).collect();
                match tests[..] {
                    [one] => one,
                    _ => {
                        return Err(Error(format!(
                            "--held-out: the calibration marks {} test cameras; name one",
                            tests.len()
                        )))
                    }
                }
            }
        };
        let dropped = dropped.iter().map(|name| capture.view(name)).collect::<Result<Vec<usize>>>()?;
        if dropped.contains(&held_out) {
            return Err(Error(format!(
                "--drop: {} is the held-out camera: it is scored, and a dropped camera is left out of everything",
                capture.views[held_out].name
            )));
        }
        let training = (0..capture.views.len())
            .filter(|&v| v != held_out && !capture.views[v].held_out && !dropped.contains(&v))
            .collect();
        Ok(Roles { training, held_out: vec![held_out] })
    }
}

/// A frame's images: the training cameras' at the working resolution, the
/// held-out cameras' at the capture's.
#[derive(Clone, Debug)]
pub struct FrameImages {
    /// The frame's index in the capture.
    pub frame: usize,
    /// The training cameras and their images, downsampled.
    pub training: Observed,
    /// Per held-out camera, its photograph at full resolution.
    pub held_out: Vec<Image>,
}

/// A held-out camera's rendering and its score.
#[derive(Clone, Debug)]
pub struct HeldOutView {
    /// The camera's index among the capture's views.
    pub view: usize,
    /// The fitted scene seen by it, at the capture's resolution.
    pub prediction: Image,
    /// Against its photograph under its protocol.
    pub score: Score,
    /// What a gain or a shift known only from its photograph would change
    /// (a diagnostic, never used to choose anything).
    pub oracle: Oracle,
    /// What aligning it as the training cameras are would change (a
    /// magnification and a shift found on its photograph; a diagnostic).
    pub aligned: Aligned,
    /// What a reconstruction exact to the smoke would score through this
    /// camera, were its calibration off by the error `aligned` found (a
    /// diagnostic).
    pub exact: ExactSmoke,
    /// Seconds its render took.
    pub render_s: f64,
}

/// A fitted frame and its held-out views.
#[derive(Clone, Debug)]
pub struct FrameFit {
    /// The fit.
    pub fit: Fit,
    /// Per held-out camera.
    pub held_out: Vec<HeldOutView>,
}

/// Every check a fit of `frames` of `capture` needs, before any work: the
/// frames exist, videos can be decoded, the grid has a box that every
/// camera sees, there is a camera to train on, and the working resolution
/// leaves an image.
pub fn check(capture: &Capture, roles: &Roles, wanted: &[usize], settings: &FitSettings) -> Result<()> {
    settings.validate()?;
    let count = capture.frame_count();
    if let Some(n) = wanted.iter().find(|&&n| n >= count) {
        return Err(Error(format!(
            "frame {n} is out of range (the capture has frames 0..{})",
            count.saturating_sub(1)
        )));
    }
    if let Some((_, i)) = first_repeat(wanted) {
        return Err(Error(format!("frame {} is given twice", wanted[i])));
    }
    if roles.training.is_empty() {
        return Err(Error("the capture has no training camera".into()));
    }
    let used = roles.training.iter().chain(&roles.held_out);
    if !frames::have_ffmpeg() && used.clone().any(|&v| matches!(capture.views[v].frames, Frames::Video { .. })) {
        return Err(Error(frames::NO_FFMPEG.into()));
    }
    let (lo, hi) = capture.grid_box()?;
    // Every resolution a training camera's images are fitted at.
    let mut factors = vec![("factor", settings.factor)];
    if let (true, Some(rig_factor)) = (settings.aligns_once(), settings.rig_factor) {
        factors.push(("rig_factor", rig_factor));
    }
    for &v in used {
        let view = &capture.views[v];
        if let Some(why) = box_unseen(&view.camera, &lo, &hi) {
            return Err(Error(format!("camera {}: {why}", view.name)));
        }
        if !roles.training.contains(&v) {
            continue;
        }
        for &(name, factor) in &factors {
            if view.camera.width < factor || view.camera.height < factor {
                return Err(Error(format!(
                    "camera {}: its {}x{} image is smaller than the working resolution's {name} {factor}",
                    view.name, view.camera.width, view.camera.height
                )));
            }
        }
    }
    Ok(())
}

/// Why `camera` cannot see the smoke box `lo`..`hi`, or `None` if one of
/// the box's corners or its centre projects into its image: it stands in
/// the box (a box in other units than the calibration's), the box is
/// behind it (as OpenCV's poses put it when read as OpenGL's), or the box
/// is out of its image.
fn box_unseen(camera: &crate::scene::Camera, lo: &Vec3, hi: &Vec3) -> Option<&'static str> {
    if inside_box(&camera.position, lo, hi) {
        return Some("it stands inside the smoke box: give the box in the calibration's units, around the smoke alone");
    }
    let mut points: Vec<Vec3> =
        (0..8).map(|c| Vec3::new([lo.x, hi.x][c & 1], [lo.y, hi.y][(c >> 1) & 1], [lo.z, hi.z][c >> 2])).collect();
    points.push((lo + hi) / 2.0);
    if points.iter().all(|p| camera.project(p).is_none()) {
        return Some(
            "the smoke box is behind it; a transform_matrix is camera-to-world in OpenGL's convention (the camera \
             looks along minus its third column, its second is up): poses in OpenCV's or COLMAP's (looking along \
             plus the third, the second down) need their second and third columns negated",
        );
    }
    (!points.iter().any(|p| camera.pixel_of(p).is_some())).then_some("the smoke box is not in its image")
}

/// The images of `wanted` frames (read in one pass per camera), the
/// training cameras' at the working resolution of `settings` (area-averaged
/// under its response), the held-out cameras' at the capture's.
pub fn read(capture: &Capture, roles: &Roles, wanted: &[usize], settings: &FitSettings) -> Result<Vec<FrameImages>> {
    let factor = settings.factor;
    let mut held: Vec<Vec<Image>> = vec![Vec::new(); wanted.len()];
    for &v in &roles.held_out {
        for (per_frame, image) in held.iter_mut().zip(frames::read(&capture.views[v], wanted)?) {
            per_frame.push(image);
        }
    }
    let training = observe(capture, &roles.training, wanted, settings)?;
    // The held-out photographs are checked as the training ones are: a
    // background left in would otherwise show only as a low score.
    let held_seen = Observed {
        cameras: roles.held_out.iter().map(|&v| capture.views[v].camera.downsample(factor)).collect(),
        images: held.iter().map(|per| per.iter().map(|i| area_average(i, factor, settings.gamma)).collect()).collect(),
        ceilings: held
            .iter()
            .map(|per| per.iter().map(|i| area_ceiling(i, factor, settings.gamma, settings.threshold)).collect())
            .collect(),
        names: roles.held_out.iter().map(|&v| capture.views[v].name.clone()).collect(),
    };
    check_light_outside_box(capture, &held_seen, wanted)?;
    Ok(wanted
        .iter()
        .zip(training.images.into_iter().zip(training.ceilings))
        .zip(held)
        .map(|((&frame, (images, ceilings)), held_out)| FrameImages {
            frame,
            training: Observed {
                cameras: training.cameras.clone(),
                images: vec![images],
                ceilings: vec![ceilings],
                names: training.names.clone(),
            },
            held_out,
        })
        .collect())
}

/// Fits `images` (one frame), its training cameras aligned by `rig` if
/// given, and renders and scores every held-out camera.
pub fn fit_frame(
    capture: &Capture,
    roles: &Roles,
    images: &FrameImages,
    settings: &FitSettings,
    rig: Option<&Rig>,
    progress: &mut dyn FnMut(&FitRow),
) -> Result<FrameFit> {
    let fixed = rig.map(Rig::corrections);
    let fitted = fit(
        &images.training.cameras,
        &images.training.images[0],
        Some(&images.training.ceilings[0]),
        capture.grid_box()?,
        settings,
        fixed.as_ref(),
        progress,
    )?;
    let held_out = roles
        .held_out
        .iter()
        .zip(&images.held_out)
        .map(|(&v, truth)| held_out_view(capture, v, &fitted, truth))
        .collect::<Result<Vec<_>>>()?;
    Ok(FrameFit { fit: fitted, held_out })
}

/// Held-out camera `v` of `capture` rendered from `fitted` at the capture's
/// resolution and scored against its photograph `truth` under its protocol.
pub fn held_out_view(capture: &Capture, v: usize, fitted: &Fit, truth: &Image) -> Result<HeldOutView> {
    let camera = &capture.views[v].camera;
    let start = Instant::now();
    let prediction = render_view(fitted, camera);
    let render_s = start.elapsed().as_secs_f64();
    if prediction.data.iter().any(|x| !x.is_finite()) {
        return Err(Error(format!("camera {}: the rendered view is not finite", capture.views[v].name)));
    }
    let protocol = Protocol::for_size(camera.width, camera.height);
    let (seen, photographed) = (protocol.view(&prediction), protocol.view(truth));
    let score = Score::of(&seen, &photographed);
    let oracle = Oracle::of(&seen, &photographed);
    let [_, _, cx, cy] = camera.intrinsics();
    let aligned = Aligned::of(&prediction, [cx, cy], &protocol, &photographed);
    let exact = ExactSmoke::of(truth, &photographed, &aligned, [cx, cy], &protocol);
    Ok(HeldOutView { view: v, prediction, score, oracle, aligned, exact, render_s })
}
