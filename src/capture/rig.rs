//! The training cameras' alignment shared by every frame of a capture.
//!
//! The cameras of a capture never move, yet a fit that aligns them frame by
//! frame ([`super::align`]) finds different corrections on every frame: on
//! a thin column of smoke near the image's edge a camera's magnification
//! and its vertical offset explain the same pixels. A rig fits them once,
//! on calibration frames spread over the clip (frames nobody reports,
//! [`calibration_frames`]), each fitted under one image model, and keeps
//! per camera the median over those frames. The alignment is the cameras',
//! so every model then sees the same cameras. The model is
//! emission-absorption, the cheapest, unless the lights shape the images:
//! then a model without them moves the cameras to make up for their light,
//! so where a multiple-scattering fit of the first calibration frame gives
//! the lights a large share of the light
//! ([`FitSettings::rig_lit_share`]), every calibration frame is fitted
//! under multiple scattering. The rig keeps each camera's gain the same
//! way, for fits that hold it ([`FitSettings::rig_gains`]). The held-out
//! camera is not part of the rig.

use super::align::{geometric_mean, take_out_shared, Corrections};
use super::fit::{fit, fit_aligning_from, Fit};
use super::observe::{observe, Observed};
use super::settings::{FitSettings, ImageModel};
use super::Capture;
use crate::error::Result;
use crate::io::manifest::{git_revision, unrecorded};
use serde::{Deserialize, Serialize};

/// One training camera's share of a rig.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RigCamera {
    /// The camera's name in the calibration.
    pub name: String,
    /// How far its principal point moves, in pixels of the capture's full
    /// resolution (right, down).
    pub offset_px: [f64; 2],
    /// The factor its focal lengths are multiplied by.
    pub zoom: f64,
    /// The angle it is turned by about its optical axis, in degrees
    /// ([`crate::scene::Camera::roll`]; 0, and not written, unless fitted).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub roll_deg: f64,
    /// Its gain: its photograph is its render times this (1 in a rig
    /// written before gains were kept).
    #[serde(default = "one")]
    pub gain: f64,
}

fn one() -> f64 {
    1.0
}

/// The training cameras' corrections, fitted once for every frame: the
/// offsets' mean is 0 and the magnifications' and gains' geometric means
/// 1, as in a frame's own fit.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Rig {
    /// The frames it was fitted on.
    pub frames: Vec<usize>,
    /// Per training camera, in the training cameras' order.
    pub cameras: Vec<RigCamera>,
    /// Seconds its fits took, all frames together: paid once per capture.
    #[serde(default)]
    pub seconds: f64,
    /// The image model its frames were fitted under (none in a rig written
    /// before it was recorded: the settings' `rig_model`).
    #[serde(default)]
    pub model: Option<ImageModel>,
    /// The lights' share of the first calibration frame's training images
    /// in its fit under multiple scattering, where the settings' rule
    /// ([`FitSettings::rig_lit_share`]) asked for that fit.
    #[serde(default)]
    pub lit_share: Option<f64>,
    /// The revision of the binary that fitted it (`git_revision`: `-dirty`
    /// where its tree was not clean; `unrecorded` in a rig written before it
    /// was recorded), so that a run reusing it can say where it came from.
    #[serde(default = "unrecorded")]
    pub revision: String,
}

fn is_zero(x: &f64) -> bool {
    *x == 0.0
}

/// `n` frames of a clip of `count` frames, at the middles of `n` equal
/// parts of it (rounded down): away from both ends, where the smoke may be a
/// thin column or leave the box. For 3 of 120 frames, 19, 59 and 99.
pub fn calibration_frames(count: usize, n: usize) -> Vec<usize> {
    let last = count.saturating_sub(1);
    let mut frames: Vec<usize> = (0..n).map(|i| (2 * i + 1) * last / (2 * n)).collect();
    frames.dedup();
    frames
}

impl Rig {
    /// The rig `settings` ask for: `None` unless they align the training
    /// cameras once for every frame ([`FitSettings::shared_alignment`]).
    pub fn if_shared(
        capture: &Capture,
        training: &[usize],
        settings: &FitSettings,
        progress: &mut dyn FnMut(usize, &Fit),
    ) -> Result<Option<Rig>> {
        if settings.aligns_once() {
            Rig::fit(capture, training, settings, None, progress).map(Some)
        } else {
            Ok(None)
        }
    }

    /// The photographs a rig of `training` cameras of `capture` is fitted
    /// on: its [`calibration_frames`] at the rig's working resolution.
    pub fn photographs(capture: &Capture, training: &[usize], settings: &FitSettings) -> Result<Observed> {
        let frames = calibration_frames(capture.frame_count(), settings.rig_frames);
        let rig = rig_settings(settings);
        observe(capture, training, &frames, &rig)
    }

    /// Fits the rig of `training` cameras of `capture` on its
    /// [`calibration_frames`] (`photographs` if read already, else read
    /// here), each with `settings` (their per-frame alignment on) under
    /// their `rig_model`, or under multiple scattering where their
    /// `rig_lit_share` rule says so. `progress` hears each fit.
    pub fn fit(
        capture: &Capture,
        training: &[usize],
        settings: &FitSettings,
        photographs: Option<Observed>,
        progress: &mut dyn FnMut(usize, &Fit),
    ) -> Result<Rig> {
        let start = std::time::Instant::now();
        let smoke_box = capture.grid_box()?;
        let frames = calibration_frames(capture.frame_count(), settings.rig_frames);
        let observed = match photographs {
            Some(read) => read,
            None => Rig::photographs(capture, training, settings)?,
        };
        let settings = rig_settings(settings);
        let mut fit_under = |model: ImageModel, i: usize, from: Option<&Corrections>| {
            let settings = FitSettings { model, ..settings.clone() };
            let (cameras, images) = (&observed.cameras, &observed.images[i]);
            let ceilings = Some(observed.ceilings[i].as_slice());
            let fitted = match from {
                None => fit(cameras, images, ceilings, smoke_box, &settings, None, &mut |_| {})?,
                Some(from) => fit_aligning_from(cameras, images, ceilings, smoke_box, &settings, from, &mut |_| {})?,
            };
            progress(frames[i], &fitted);
            Ok::<Fit, crate::error::Error>(fitted)
        };
        let mut fits = Vec::new();
        let (mut model, mut lit_share) = (settings.rig_model, None);
        if let (Some(bound), true) = (settings.rig_lit_share, model != ImageModel::Multiple) {
            let probe = fit_under(ImageModel::Multiple, 0, None)?;
            let share = probe.light_share.unwrap_or(0.0);
            lit_share = Some(share);
            if share > bound {
                model = ImageModel::Multiple;
                fits.push(probe);
            }
        }
        for i in fits.len()..frames.len() {
            fits.push(fit_under(model, i, None)?);
        }
        let mut cameras = medians(capture, training, &fits);
        for _ in 1..settings.rig_rounds {
            let from = corrections_of(&cameras);
            let fits = (0..frames.len()).map(|i| fit_under(model, i, Some(&from))).collect::<Result<Vec<Fit>>>()?;
            cameras = medians(capture, training, &fits);
        }
        Ok(Rig {
            frames,
            cameras,
            seconds: start.elapsed().as_secs_f64(),
            model: Some(model),
            lit_share,
            revision: git_revision(),
        })
    }

    /// The corrections a fit starts from, in the training cameras' order.
    pub fn corrections(&self) -> Corrections {
        corrections_of(&self.cameras)
    }
}

/// The settings a rig's calibration frames are read and fitted with:
/// `settings` with each frame's cameras aligned, at the rig's working
/// resolution.
fn rig_settings(settings: &FitSettings) -> FitSettings {
    FitSettings {
        align: true,
        shared_alignment: false,
        // The rig measures the gains that its frames' fits may hold.
        rig_gains: false,
        factor: settings.rig_factor.unwrap_or(settings.factor),
        // The cameras' alignment, coarse to fine per voxel, whatever the
        // frames' own fits start from: every setting of them sees the same cameras.
        ..settings.per_voxel()
    }
}

/// The corrections of a rig's `cameras`, in their order.
fn corrections_of(cameras: &[RigCamera]) -> Corrections {
    Corrections {
        offsets_px: cameras.iter().map(|c| c.offset_px).collect(),
        zooms: cameras.iter().map(|c| c.zoom).collect(),
        rolls: cameras.iter().map(|c| c.roll_deg.to_radians()).collect(),
        gains: Some(cameras.iter().map(|c| c.gain).collect()),
    }
}

/// Per training camera, the median of `fits`' corrections, [`centred`]:
/// of an even number of frames, the mean of the middle two, so that each
/// correction lies between the frames' and none leans to the larger.
fn medians(capture: &Capture, training: &[usize], fits: &[Fit]) -> Vec<RigCamera> {
    let offsets: Vec<Vec<[f64; 2]>> = fits.iter().map(Fit::offsets_px).collect();
    let cameras: Vec<RigCamera> = training
        .iter()
        .enumerate()
        .map(|(c, &v)| RigCamera {
            name: capture.views[v].name.clone(),
            offset_px: [0, 1].map(|a| median(offsets.iter().map(|o| o[c][a]).collect())),
            zoom: median(fits.iter().map(|f| f.zooms[c]).collect()),
            roll_deg: median(fits.iter().map(|f| f.rolls[c].to_degrees()).collect()),
            gain: median(fits.iter().map(|f| f.gains[c]).collect()),
        })
        .collect();
    centred(cameras)
}

/// The median of `values`: of an even number, the mean of the middle two.
fn median(mut values: Vec<f64>) -> f64 {
    values.sort_by(f64::total_cmp);
    let half = values.len() / 2;
    if values.len() % 2 == 1 {
        values[half]
    } else {
        0.5 * (values[half - 1] + values[half])
    }
}

/// `cameras` with their offsets' and turns' means taken out and their
/// magnifications divided by their geometric mean ([`take_out_shared`]),
/// their gains by theirs.
fn centred(mut cameras: Vec<RigCamera>) -> Vec<RigCamera> {
    let mut offsets: Vec<[f64; 2]> = cameras.iter().map(|c| c.offset_px).collect();
    let mut zooms: Vec<f64> = cameras.iter().map(|c| c.zoom).collect();
    let mut rolls: Vec<f64> = cameras.iter().map(|c| c.roll_deg).collect();
    take_out_shared(&mut offsets, &mut zooms, &mut rolls);
    let shared_gain = geometric_mean(&cameras.iter().map(|c| c.gain).collect::<Vec<_>>());
    for (((c, o), k), r) in cameras.iter_mut().zip(offsets).zip(zooms).zip(rolls) {
        (c.offset_px, c.zoom, c.roll_deg, c.gain) = (o, k, r, c.gain / shared_gain);
    }
    cameras
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera(name: &str, offset_px: [f64; 2], zoom: f64) -> RigCamera {
        RigCamera { name: name.into(), offset_px, zoom, roll_deg: 0.0, gain: zoom }
    }

    #[test]
    fn a_rig_keeps_the_mean_offset_and_magnification_of_the_calibration() {
        let rig = centred(vec![camera("a", [10.0, -4.0], 1.1), camera("b", [2.0, 8.0], 1.1 * 1.21)]);
        assert!((rig[0].offset_px[0] - 4.0).abs() < 1e-12 && (rig[1].offset_px[1] - 6.0).abs() < 1e-12, "{rig:?}");
        assert!((rig[0].zoom * rig[1].zoom - 1.0).abs() < 1e-12 && (rig[1].zoom / rig[0].zoom - 1.21).abs() < 1e-12);
        assert!((rig[0].gain * rig[1].gain - 1.0).abs() < 1e-12 && (rig[1].gain / rig[0].gain - 1.21).abs() < 1e-12);
    }

    #[test]
    fn a_rig_hands_a_fit_its_cameras_corrections_in_order() {
        let rig = Rig {
            frames: vec![0],
            cameras: vec![camera("a", [16.0, -8.0], 1.05), camera("b", [1.0, 2.0], 0.95)],
            seconds: 0.0,
            model: None,
            lit_share: None,
            revision: crate::io::manifest::UNRECORDED.into(),
        };
        let fixed = rig.corrections();
        assert_eq!((fixed.offsets_px, fixed.zooms), (vec![[16.0, -8.0], [1.0, 2.0]], vec![1.05, 0.95]));
        assert_eq!(fixed.gains, Some(vec![1.05, 0.95]));
    }

    #[test]
    fn a_rig_written_before_gains_were_kept_reads_them_as_1() {
        let json = r#"{"frames": [19], "cameras": [{"name": "a", "offset_px": [1.0, 2.0], "zoom": 1.01}]}"#;
        let rig: Rig = serde_json::from_str(json).unwrap();
        assert_eq!(rig.cameras[0].gain, 1.0);
        assert_eq!(rig.revision, crate::io::manifest::UNRECORDED);
    }

    #[test]
    fn a_median_of_an_even_count_is_the_mean_of_the_middle_two() {
        assert_eq!(median(vec![3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(vec![10.0, 1.0, 3.0, 2.0]), 2.5);
        assert_eq!(median(vec![-1.0]), -1.0);
    }

    #[test]
    fn calibration_frames_are_inside_the_clip_and_spread_over_it() {
        assert_eq!(calibration_frames(120, 3), vec![19, 59, 99]);
        assert_eq!(calibration_frames(120, 5), vec![11, 35, 59, 83, 107]);
        assert_eq!(calibration_frames(1, 3), vec![0]);
        assert_eq!(calibration_frames(0, 3), vec![0]);
        for (count, n) in (1..50).flat_map(|count| (1..=8).map(move |n| (count, n))) {
            let f = calibration_frames(count, n);
            assert!(f.len() <= n && !f.is_empty(), "{count}, {n}: {f:?}");
            assert!(f.iter().all(|&x| x < count) && f.windows(2).all(|w| w[0] < w[1]), "{count}, {n}: {f:?}");
        }
    }
}
