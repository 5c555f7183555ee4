//! What a rerun may reuse of a run before it: the rows of `fits.csv` and
//! the rig, only where they were made with this run's cameras and
//! settings. The record of them is `settings.json`, written before the
//! first fit.

use dualphoton::capture::fit::FitSettings;
use dualphoton::capture::frame::Roles;
use dualphoton::capture::rig::{calibration_frames, Rig};
use dualphoton::capture::Capture;
use dualphoton::error::{Error, Result};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// What every row of a run's `fits.csv` depends on beyond its frame and
/// model, written to `settings.json` before the first fit: a rerun resumes
/// only a run that recorded the same, so rows fitted with other settings
/// are never mixed into one table.
#[derive(Serialize, Deserialize, PartialEq, Debug)]
pub struct RunSettings {
    /// The training cameras, in their order.
    training: Vec<String>,
    /// The held-out camera.
    held_out: String,
    /// ScalarFlow's camera file, when the focal lengths came from it.
    focal_lengths: Option<PathBuf>,
    /// The fit settings, `model` left out (each row names its own).
    fit: serde_json::Value,
}

impl RunSettings {
    pub fn of(
        capture: &Capture,
        roles: &Roles,
        base: &FitSettings,
        focal_lengths: Option<&Path>,
    ) -> Result<RunSettings> {
        let names = |views: &[usize]| views.iter().map(|&v| capture.views[v].name.clone()).collect::<Vec<_>>();
        let mut fit = serde_json::to_value(base).map_err(|e| Error(e.to_string()))?;
        if let Some(fields) = fit.as_object_mut() {
            fields.remove("model");
        }
        Ok(RunSettings {
            training: names(&roles.training),
            held_out: names(&roles.held_out).join(","),
            focal_lengths: focal_lengths.map(Path::to_path_buf),
            fit,
        })
    }

    /// Records `self` in `dir/settings.json`, or checks it against what a
    /// run before this one recorded there. A folder holding fits or a rig
    /// but no record is refused: what made them cannot be told.
    pub fn record(&self, dir: &Path) -> Result<()> {
        let path = dir.join("settings.json");
        let refuse = |why: String| {
            Err(Error(format!("{}: {why}; give another --out or delete the folder to start afresh", dir.display())))
        };
        if path.exists() {
            let text = std::fs::read_to_string(&path)?;
            let earlier: RunSettings =
                serde_json::from_str(&text).map_err(|e| Error(format!("{}: {e}", path.display())))?;
            return match self.differences(&earlier).as_slice() {
                [] => Ok(()),
                what => refuse(format!("holds a run made with other {} (settings.json)", what.join(", "))),
            };
        }
        if ["fits.csv", "rig.json"].iter().any(|f| dir.join(f).exists()) {
            return refuse("holds fits but not the settings they were made with (settings.json)".into());
        }
        std::fs::write(&path, serde_json::to_string_pretty(self).map_err(|e| Error(e.to_string()))?)?;
        Ok(())
    }

    /// What differs between `self` and `other`, by name (the fit settings'
    /// fields one by one).
    fn differences(&self, other: &RunSettings) -> Vec<String> {
        let mut what = Vec::new();
        if self.training != other.training {
            what.push("training cameras".to_string());
        }
        if self.held_out != other.held_out {
            what.push("held-out camera".into());
        }
        if self.focal_lengths != other.focal_lengths {
            what.push("focal lengths".into());
        }
        let empty = serde_json::Map::new();
        let fields = |v: &serde_json::Value| v.as_object().cloned().unwrap_or_else(|| empty.clone());
        let (mine, theirs) = (fields(&self.fit), fields(&other.fit));
        let mut keys: Vec<&String> = mine.keys().chain(theirs.keys()).collect();
        keys.sort();
        keys.dedup();
        what.extend(keys.into_iter().filter(|k| mine.get(*k) != theirs.get(*k)).map(|k| format!("fit setting {k}")));
        what
    }
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
            return Err(Error(format!(
                "{}: aligns other cameras or frames than this run's ({} on frames {frames:?}); delete it to fit it again",
                path.display(),
                names.join(", ")
            )));
        }
        return Ok(Some(rig));
    }
    let rig = Rig::if_shared(capture, &roles.training, base, &mut |frame, fit| {
        eprintln!("rig: frame {frame} fitted in {:.0} s", fit.seconds)
    })?;
    if let Some(rig) = &rig {
        std::fs::write(path, serde_json::to_string_pretty(rig).map_err(|e| Error(e.to_string()))?)?;
    }
    Ok(rig)
}
