//! What a run may reuse of a run before it: the rows of a table of fits
//! and the rig (the training cameras' alignment), only where they were made
//! with this run's cameras and settings. The record of them is
//! `settings.json`, written beside them before the first fit.

use super::frame::Roles;
use super::observe::Observed;
use super::rig::{calibration_frames, Rig};
use super::settings::FitSettings;
use super::Capture;
use crate::error::{Error, Result};
use crate::io::manifest::write_json;
use crate::math::Vec3;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// What every row of a run's `fits.csv` depends on beyond its frame and
/// model, written to `settings.json` before the first fit: a rerun resumes
/// only a run that recorded the same, so rows fitted with other cameras or
/// settings are never mixed into one table.
#[derive(Serialize, Deserialize, Debug)]
pub struct RunSettings {
    /// The training cameras, in their order, at the capture's resolution
    /// (with `--focal-lengths`, its focal lengths).
    training: Vec<CameraRecord>,
    /// The held-out camera, if the capture has one.
    held_out: Option<CameraRecord>,
    /// The calibration's smoke box, lower and upper corner, if it has one.
    smoke_box: Option<[[f64; 3]; 2]>,
    /// The fit settings, `model` left out (each row names its own).
    fit: serde_json::Value,
}

/// A camera as the calibration gives it.
#[derive(Serialize, Deserialize, Debug)]
struct CameraRecord {
    name: String,
    position: [f64; 3],
    look_at: [f64; 3],
    up: [f64; 3],
    /// fx, fy, cx, cy in pixels.
    intrinsics: [f64; 4],
    width: usize,
    height: usize,
}

impl RunSettings {
    /// The record of a run fitting `roles` of `capture` with `base`.
    pub fn of(capture: &Capture, roles: &Roles, base: &FitSettings) -> Result<RunSettings> {
        let record = |v: usize| {
            let (view, cam) = (&capture.views[v], &capture.views[v].camera);
            let xyz = |p: Vec3| [p.x, p.y, p.z];
            CameraRecord {
                name: view.name.clone(),
                position: xyz(cam.position),
                look_at: xyz(cam.look_at),
                up: xyz(cam.up),
                intrinsics: cam.intrinsics(),
                width: cam.width,
                height: cam.height,
            }
        };
        let mut fit = serde_json::to_value(base).map_err(|e| Error(e.to_string()))?;
        if let Some(fields) = fit.as_object_mut() {
            fields.remove("model");
        }
        Ok(RunSettings {
            training: roles.training.iter().map(|&v| record(v)).collect(),
            held_out: roles.held_out.first().map(|&v| record(v)),
            smoke_box: capture.smoke_box.map(|(lo, hi)| [[lo.x, lo.y, lo.z], [hi.x, hi.y, hi.z]]),
            fit,
        })
    }

    /// Checks `self` against what a run before this one recorded in
    /// `dir/settings.json`: its cameras always, its fit settings when this
    /// run `fits`. A run that fits and finds no record writes one; a folder
    /// holding fits or a rig but no record is refused, since what made them
    /// cannot be told.
    pub fn record(&self, dir: &Path, fits: bool) -> Result<()> {
        let path = dir.join("settings.json");
        let refuse = |why: String| Err(start_afresh(dir, &why));
        let mine = self.value()?;
        if path.exists() {
            let theirs = read_json(&path)?;
            return match differences(&mine, &theirs, fits).as_slice() {
                [] => Ok(()),
                what => refuse(format!("holds a run made with other {}", what.join(", "))),
            };
        }
        if !fits {
            return Ok(());
        }
        if ["fits.csv", "rig.json"].iter().any(|f| dir.join(f).exists()) {
            return refuse("holds fits but not the settings they were made with (settings.json)".into());
        }
        write_json(&path, &mine)
    }

    /// Writes the record into `dir/settings.json`, replacing any there: a
    /// folder one frame's fit rewrites whole.
    pub fn write(&self, dir: &Path) -> Result<()> {
        write_json(&dir.join("settings.json"), &self.value()?)
    }

    /// The record as `settings.json` holds it (written and read back), so
    /// that it compares equal to the file it wrote.
    fn value(&self) -> Result<serde_json::Value> {
        let text = serde_json::to_string(self).map_err(|e| Error(e.to_string()))?;
        serde_json::from_str(&text).map_err(|e| Error(e.to_string()))
    }
}

fn read_json(path: &Path) -> Result<serde_json::Value> {
    let text = std::fs::read_to_string(path).map_err(|e| Error(format!("{}: {e}", path.display())))?;
    serde_json::from_str(&text).map_err(|e| Error(format!("{}: {e}", path.display())))
}

/// The one-line refusal of a folder (or a file in it) that holds another
/// run: why, and how to start afresh.
fn start_afresh(what: &Path, why: &str) -> Error {
    Error(format!("{}: {why}; give another --out or delete the folder to start afresh", what.display()))
}

/// What differs between two records, by name: the fit settings' fields one
/// by one (when `fits`), each with both values; a field one record lacks
/// (a setting newer than it) counts as its default.
fn differences(mine: &serde_json::Value, theirs: &serde_json::Value, fits: bool) -> Vec<String> {
    if theirs.get("smoke_box").is_none() {
        return vec!["record (its settings.json is of an earlier form, without the cameras' geometry)".into()];
    }
    let mut what: Vec<String> =
        [("training", "training cameras"), ("held_out", "held-out camera"), ("smoke_box", "smoke box")]
            .into_iter()
            .filter(|(key, _)| mine.get(key) != theirs.get(key))
            .map(|(_, name)| name.to_string())
            .collect();
    if !fits {
        return what;
    }
    let fields = |record: &serde_json::Value| {
        let settings: Option<FitSettings> = record.get("fit").and_then(|f| serde_json::from_value(f.clone()).ok());
        settings.and_then(|s| serde_json::to_value(s).ok()).and_then(|v| v.as_object().cloned()).unwrap_or_default()
    };
    let (now, before) = (fields(mine), fields(theirs));
    if before.is_empty() {
        what.push("fit settings (its settings.json has none this version reads)".into());
    }
    for (key, value) in &now {
        match before.get(key) {
            Some(old) if old != value => {
                what.push(format!("fit setting {key} ({old} in its settings.json, {value} here)"))
            }
            _ => {}
        }
    }
    what
}

/// The rig `base` asks for: read from `path` if a run before this one
/// fitted it (for the same cameras and calibration frames), else fitted on
/// the training cameras and written there.
pub fn rig(capture: &Capture, roles: &Roles, base: &FitSettings, path: &Path) -> Result<Option<Rig>> {
    if path.exists() && base.aligns_once() {
        let rig = read_rig(path, capture, roles, base).map_err(|why| start_afresh(path, &why))?;
        eprintln!(
            "rig: the training cameras' alignment taken from {} (fitted by revision {})",
            path.display(),
            rig.revision
        );
        return Ok(Some(rig));
    }
    let rig = fit_rig(capture, roles, base, None)?;
    if let Some(rig) = &rig {
        write_rig(path, rig)?;
    }
    Ok(rig)
}

/// The rig `settings` ask for, as [`Rig::if_shared`] gives it, on its
/// `photographs` where they were read already ([`Rig::photographs`]),
/// saying on stderr what it does while it runs (a minute or more, with
/// nothing else to show).
pub fn fit_rig(
    capture: &Capture,
    roles: &Roles,
    settings: &FitSettings,
    photographs: Option<Observed>,
) -> Result<Option<Rig>> {
    if !settings.aligns_once() {
        return Ok(None);
    }
    let frames = calibration_frames(capture.frame_count(), settings.rig_frames);
    eprintln!("rig: aligning the training cameras once for the capture, on frames {frames:?} ...");
    Rig::fit(capture, &roles.training, settings, photographs, &mut |frame, fit| {
        eprintln!("rig: frame {frame} fitted under {} in {:.0} s", fit.settings.model.name(), fit.seconds)
    })
    .map(Some)
}

/// Writes `rig` as JSON into `path`.
pub fn write_rig(path: &Path, rig: &Rig) -> Result<()> {
    write_json(path, &serde_json::to_value(rig).map_err(|e| Error(e.to_string()))?)
}

/// The rig an earlier run wrote into `dir` (its `rig.json`, beside the
/// `settings.json` that records what it was made with), for a run that
/// `record` describes: refused unless that run had the same cameras and fit
/// settings (its image model aside: one rig serves every model).
pub fn earlier_rig(
    dir: &Path,
    record: &RunSettings,
    capture: &Capture,
    roles: &Roles,
    base: &FitSettings,
) -> Result<Rig> {
    if !base.aligns_once() {
        return Err(Error(
            "these fit settings (or a capture of one frame) align the cameras on each frame: there is no rig to reuse"
                .into(),
        ));
    }
    let (settings, rig) = (dir.join("settings.json"), dir.join("rig.json"));
    if let Some(missing) = [&settings, &rig].into_iter().find(|f| !f.exists()) {
        let why = "not found: give the folder of an earlier `fit --capture` or experiment_real";
        return Err(Error(format!("{}: {why}", missing.display())));
    }
    match differences(&record.value()?, &read_json(&settings)?, true).as_slice() {
        [] => read_rig(&rig, capture, roles, base).map_err(|why| Error(format!("{}: {why}", rig.display()))),
        what => Err(Error(format!("{}: made with other {}", dir.display(), what.join(", ")))),
    }
}

/// The rig in `path`, if it aligns the training cameras of `roles` on the
/// calibration frames `base` asks for; else why not.
fn read_rig(path: &Path, capture: &Capture, roles: &Roles, base: &FitSettings) -> std::result::Result<Rig, String> {
    let text = std::fs::read_to_string(path).map_err(|e| e.to_string())?;
    let rig: Rig = serde_json::from_str(&text).map_err(|e| e.to_string())?;
    let names: Vec<&str> = roles.training.iter().map(|&v| capture.views[v].name.as_str()).collect();
    let frames = calibration_frames(capture.frame_count(), base.rig_frames);
    if rig.cameras.iter().map(|c| c.name.as_str()).ne(names.iter().copied()) || rig.frames != frames {
        return Err(format!(
            "aligns other cameras or frames than this run's ({} on frames {frames:?})",
            names.join(", ")
        ));
    }
    Ok(rig)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::capture::{Frames, View};
    use crate::scene::{Camera, Lens};

    /// The record names the held-out camera or says there is none, so a
    /// folder scored on no camera never resumes as one scored on a camera.
    #[test]
    fn the_record_names_the_held_out_camera_or_says_there_is_none() {
        let lens = Lens::Pinhole { fx: 90.0, fy: 90.0, cx: 20.0, cy: 30.0 };
        let view = |name: &str, x: f64| View {
            name: name.into(),
            camera: Camera {
                position: Vec3::new(x, 0.0, 2.0),
                look_at: Vec3::zeros(),
                up: Vec3::y(),
                lens,
                width: 40,
                height: 60,
            },
            frames: Frames::Images(vec![]),
            held_out: false,
        };
        let capture = Capture { views: vec![view("a", -1.0), view("b", 0.0), view("c", 1.0)], smoke_box: None };
        let base = FitSettings::default();
        let roles = |held_out: Vec<usize>| Roles { training: vec![0, 2], held_out };
        let none = RunSettings::of(&capture, &roles(vec![]), &base).unwrap().value().unwrap();
        let b = RunSettings::of(&capture, &roles(vec![1]), &base).unwrap();
        assert_eq!(none["held_out"], serde_json::Value::Null, "{none}");
        assert_eq!(b.value().unwrap()["held_out"]["name"], "b");
        assert_eq!(none["training"], b.value().unwrap()["training"]);

        let dir = std::env::temp_dir().join(format!("dualphoton-reuse-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        write_json(&dir.join("settings.json"), &none).unwrap();
        let e = b.record(&dir, true).unwrap_err().0;
        assert!(e.contains("holds a run made with other held-out camera"), "{e}");
        RunSettings::of(&capture, &roles(vec![]), &base).unwrap().record(&dir, true).unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
