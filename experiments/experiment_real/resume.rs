//! What a rerun may reuse of a run before it: the rows of `fits.csv` and
//! the rig, only where they were made with this run's cameras and
//! settings. The record of them is `settings.json`, written before the
//! first fit.

use dualphoton::capture::frame::Roles;
use dualphoton::capture::rig::{calibration_frames, Rig};
use dualphoton::capture::settings::FitSettings;
use dualphoton::capture::Capture;
use dualphoton::error::{Error, Result};
use dualphoton::io::manifest::write_json;
use dualphoton::math::Vec3;
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
    /// The held-out camera.
    held_out: CameraRecord,
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
            held_out: record(roles.held_out[0]),
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
        let json = |e: serde_json::Error| Error(format!("{}: {e}", path.display()));
        // Compared as written and read back, so that a value's last bit lost to the text never differs.
        let mine: serde_json::Value =
            serde_json::from_str(&serde_json::to_string(self).map_err(json)?).map_err(json)?;
        if path.exists() {
            let theirs: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&path)?).map_err(json)?;
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
        let text = std::fs::read_to_string(path)?;
        let rig: Rig = serde_json::from_str(&text).map_err(|e| Error(format!("{}: {e}", path.display())))?;
        let names: Vec<&str> = roles.training.iter().map(|&v| capture.views[v].name.as_str()).collect();
        let frames = calibration_frames(capture.frame_count(), base.rig_frames);
        if rig.cameras.iter().map(|c| c.name.as_str()).ne(names.iter().copied()) || rig.frames != frames {
            let why =
                format!("aligns other cameras or frames than this run's ({} on frames {frames:?})", names.join(", "));
            return Err(start_afresh(path, &why));
        }
        return Ok(Some(rig));
    }
    let rig = Rig::if_shared(capture, &roles.training, base, &mut |frame, fit| {
        eprintln!("rig: frame {frame} fitted under {} in {:.0} s", fit.settings.model.name(), fit.seconds)
    })?;
    if let Some(rig) = &rig {
        write_json(path, &serde_json::to_value(rig).map_err(|e| Error(e.to_string()))?)?;
    }
    Ok(rig)
}
