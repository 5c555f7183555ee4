//! Study files: a JSON object that sets any setting of a program by its
//! name, for the studies that need a knob no command-line option offers.
//! `{"paper": {"refine": {"updates": 0}, "train": {"decorrelate": false}}}`
//! sets two settings of the paper's method ([`super::methods::Methods`])
//! and leaves every other at its default. An unknown name or a value of
//! the wrong type is a one-line error naming the setting.

use crate::error::{Error, Result};
use serde::de::DeserializeOwned;
use serde::Serialize;
use serde_json::Value;
use std::path::Path;

/// The largest study file read: settings, not data.
pub const MAX_STUDY_BYTES: u64 = 1 << 20;

/// Reads the study file `path` (a JSON object; `--study` names it in errors).
pub fn read_study(path: &Path) -> Result<Value> {
    let shown = crate::error::shorten(&path.display().to_string());
    let bytes =
        crate::io::npy::read_bounded(path, MAX_STUDY_BYTES).map_err(|e| Error(format!("--study: {shown}: {e}")))?;
    let value: Value =
        serde_json::from_slice(&bytes).map_err(|e| Error(format!("--study: {shown} is not JSON: {e}")))?;
    if !value.is_object() {
        return Err(Error(format!("--study: {shown} must hold a JSON object of settings")));
    }
    Ok(value)
}

/// Sets every setting `study` names in `settings` (nested objects name
/// nested settings). Errors, naming the setting as `a.b.c`, on a name
/// `settings` does not have or a value its type does not take; `settings`
/// is then unchanged.
pub fn apply_study<T: Serialize + DeserializeOwned>(settings: &mut T, study: &Value) -> Result<()> {
    let mut all = serde_json::to_value(&*settings).map_err(|e| Error(format!("--study: {e}")))?;
    let mut leaves = vec![];
    collect_leaves(study, &all, String::new(), &mut leaves)?;
    for (name, value) in leaves {
        let pointer = format!("/{}", name.replace('.', "/"));
        let slot = all.pointer_mut(&pointer).ok_or_else(|| Error(format!("--study: unknown setting '{name}'")))?;
        *slot = value.clone();
        serde_json::from_value::<T>(all.clone())
            .map_err(|e| Error(format!("--study: setting '{name}' cannot be {value}: {e}")))?;
    }
    *settings = serde_json::from_value(all).map_err(|e| Error(format!("--study: {e}")))?;
    Ok(())
}

/// The settings `study` sets, each as (dotted name, value), checked to
/// exist in `current` (the settings as JSON).
fn collect_leaves<'a>(
    study: &'a Value,
    current: &Value,
    prefix: String,
    out: &mut Vec<(String, &'a Value)>,
) -> Result<()> {
    let Value::Object(map) = study else {
        out.push((prefix, study));
        return Ok(());
    };
    for (key, value) in map {
        let name = if prefix.is_empty() { key.clone() } else { format!("{prefix}.{key}") };
        let Some(here) = current.as_object().and_then(|o| o.get(key)) else {
            return Err(Error(format!("--study: unknown setting '{name}'")));
        };
        if here.is_object() {
            if !value.is_object() {
                return Err(Error(format!("--study: setting '{name}' is a group of settings, not {value}")));
            }
            collect_leaves(value, here, name, out)?;
        } else {
            out.push((name, value));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::recon::estimator::WeightDirections;
    use crate::recon::methods::Methods;
    use serde_json::json;

    #[test]
    fn a_study_sets_any_setting_and_names_a_bad_one() {
        let mut m = Methods::default();
        let study = json!({"paper": {"refine": {"updates": 0, "blocks": []}, "train": {"gradient": {"weight_mode": "orthonormal"}}},
                           "prior": {"train": {"time_budget": 30.0}}});
        apply_study(&mut m, &study).unwrap();
        assert_eq!((m.paper.refine.updates, m.paper.refine.blocks.len()), (0, 0));
        assert_eq!(m.prior.train.time_budget, Some(30.0));
        // Everything the study does not name keeps its default.
        let mut expected = Methods::default().paper.train;
        expected.gradient.weight_mode = WeightDirections::Orthonormal;
        assert_eq!(m.paper.train, expected);
        let before = m.clone();
        for (bad, name) in [
            (json!({"paper": {"train": {"lr_latnet": 0.1}}}), "'paper.train.lr_latnet'"),
            (json!({"paper": {"train": {"spp": "two"}}}), "'paper.train.spp'"),
            (json!({"prior": 3}), "'prior'"),
            (json!({"paper": {"train": {"gradient": {"estimator": "fwd-magic"}}}}), "'paper.train.gradient.estimator'"),
        ] {
            let e = apply_study(&mut m, &bad).unwrap_err().to_string();
            assert!(e.contains(name) && !e.contains('\n'), "{e}");
            assert_eq!(m, before);
        }
    }

    #[test]
    fn the_shipped_study_files_set_what_they_say() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/studies");
        let read = |name: &str| {
            let mut m = Methods::default();
            apply_study(&mut m, &read_study(&dir.join(name)).unwrap()).unwrap();
            m
        };
        // The paper's method as published: no refinement, the loss of one render as it is.
        let published = read("paper_as_published.json");
        assert_eq!((published.paper.refine.updates, published.paper.train.decorrelate), (0, false));
        assert_eq!(published.prior, Methods::default().prior);
        let orthonormal = read("orthonormal_weights.json");
        assert_eq!(orthonormal.paper.train.gradient.weight_mode, WeightDirections::Orthonormal);
        assert_eq!(orthonormal.paper.refine.updates, 0);
        // eight_views.json sets experiment_table1's cameras too: tests/training.rs reads it.
        // (real_dev/ holds fit settings of real captures: capture::fit's tests read them.)
        let count = std::fs::read_dir(&dir).unwrap().filter(|e| e.as_ref().unwrap().path().is_file()).count();
        assert_eq!(count, 3, "every study file in {} is read by a test", dir.display());
    }

    #[test]
    fn a_study_file_that_is_not_a_file_is_an_error_before_reading() {
        let e = read_study(Path::new("/dev/zero")).unwrap_err().to_string();
        assert!(e.starts_with("--study:") && e.contains("not a regular file"), "{e}");
    }
}
