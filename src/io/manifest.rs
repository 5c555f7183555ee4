//! Run manifests: what produced a result (settings, seed, git revision,
//! wall time, peak memory), written beside it as JSON.

use crate::error::{Error, Result};
use serde_json::Value;
use std::path::Path;

/// The current git revision, with `-dirty` if tracked files outside
/// `results/` have changes, or "unknown". Results are what a run writes
/// (and rewrites as it goes), not the code that produced them, so they do
/// not count.
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
            let dirty = run(&["status", "--porcelain", "--untracked-files=no", "--", ".", ":(exclude)results"])
                .is_some_and(|s| !s.is_empty());
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

/// Resets the process's resident-memory high-water mark (Linux, through
/// /proc/self/clear_refs); false if unsupported.
pub fn reset_peak_memory() -> bool {
    std::fs::write("/proc/self/clear_refs", "5").is_ok()
}

/// The process's resident-memory high-water mark (VmHWM) in MiB, 0 if unknown.
pub fn peak_memory_mib() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| s.lines().find(|l| l.starts_with("VmHWM:")).map(|l| l.to_string()))
        .and_then(|l| l.split_whitespace().nth(1).and_then(|kb| kb.parse::<f64>().ok()))
        .map_or(0.0, |kb| kb / 1024.0)
}

/// Writes a run's manifest: the fields of `settings` (any serde-serialisable
/// settings struct, so no key is listed by hand) plus where the result came
/// from: `git` revision, `wall_s` seconds, worker `threads` and the
/// machine's `speed_probe` (timed now, after the run).
pub fn write_manifest<T: serde::Serialize>(path: &Path, settings: &T, wall_s: f64) -> Result<()> {
    let mut value = serde_json::to_value(settings).map_err(|e| Error(e.to_string()))?;
    let Value::Object(map) = &mut value else {
        return Err(Error::new("manifest: settings must serialise to a JSON object"));
    };
    map.insert("git".into(), git_revision().into());
    map.insert("wall_s".into(), wall_s.into());
    map.insert("threads".into(), rayon::current_num_threads().into());
    let probe = serde_json::to_value(super::speed_probe::speed_probe()).map_err(|e| Error(e.to_string()))?;
    map.insert("speed_probe".into(), probe);
    write_json(path, &value)
}
