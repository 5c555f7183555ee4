//! Run manifests: what produced a result (settings, seed, git revision,
//! wall time), written beside it as JSON (STYLE.md habit 6).

use crate::error::{Error, Result};
use serde_json::Value;
use std::path::Path;

/// The current git revision (with `-dirty` if the tree has changes), or "unknown".
pub fn git_revision() -> String {
    let run = |args: &[&str]| {
        std::process::Command::new("git")
            .args(args)
            .output()
            .ok()
            .filter(|o| o.status.success())
            .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
    };
    match run(&["rev-parse", "--short=12", "HEAD"]) {
        Some(rev) => {
            let dirty = run(&["status", "--porcelain", "--untracked-files=no"]).is_some_and(|s| !s.is_empty());
            if dirty {
                format!("{rev}-dirty")
            } else {
                rev
            }
        }
        None => "unknown".into(),
    }
}

/// Writes `value` as pretty JSON to `path`.
pub fn write_json(path: &Path, value: &Value) -> Result<()> {
    let text = serde_json::to_string_pretty(value).map_err(|e| Error(e.to_string()))?;
    std::fs::write(path, text + "\n").map_err(|e| Error(format!("cannot write {}: {e}", path.display())))
}
