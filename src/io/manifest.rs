//! Run manifests: what produced a result, written beside it as JSON: the
//! run's settings plus its provenance (the revision the binary was built
//! from, whether its tree was clean, the command as run, the UTC date, wall
//! time, worker threads, the machine's speed), and the process's peak memory.

use crate::error::{Error, Result};
use serde_json::{Map, Value};
use std::path::Path;
use std::time::{SystemTime, UNIX_EPOCH};

/// The git revision (12 hex digits) this binary was built from, embedded by
/// `build.rs`; "unknown" where it was built without git.
pub const REVISION: &str = env!("DUALPHOTON_REVISION");

/// Whether the tracked files outside `results/` matched [`REVISION`] when
/// this binary was built (see `build.rs` for when that is re-checked);
/// `None` where unknown. Results are what runs write, not the code that
/// produced them, so they do not count.
pub fn tree_clean() -> Option<bool> {
    match env!("DUALPHOTON_TREE_CLEAN") {
        "true" => Some(true),
        "false" => Some(false),
        _ => None,
    }
}

/// Stands for the revision where a record predates it being kept (a
/// resumed run's older rows, an older rig).
pub const UNRECORDED: &str = "unrecorded";

/// [`UNRECORDED`], as serde's default for a record's revision field.
pub fn unrecorded() -> String {
    UNRECORDED.into()
}

/// The revision this binary was built from, with `-dirty` if its tree was
/// not clean: one word for small caches' manifests (reference renders).
pub fn git_revision() -> String {
    revision_word(REVISION, tree_clean())
}

/// `revision` as one word: with `-dirty` where its tree was not `clean`.
pub fn revision_word(revision: &str, clean: Option<bool>) -> String {
    match clean {
        Some(false) => format!("{revision}-dirty"),
        _ => revision.to_string(),
    }
}

/// The revisions in `revisions`, each once, in the order they first appear
/// (where a resumed run's records came from).
pub fn each_once<'a>(revisions: impl IntoIterator<Item = &'a str>) -> Vec<&'a str> {
    let mut seen: Vec<&str> = Vec::new();
    for r in revisions {
        if !seen.contains(&r) {
            seen.push(r);
        }
    }
    seen
}

/// The command line as run: the program's file name and its arguments,
/// each argument quoted if it holds a space or is empty.
pub fn command_line() -> String {
    let mut args = std::env::args_os().map(|a| a.to_string_lossy().into_owned());
    let program = args.next().unwrap_or_default();
    let name = Path::new(&program).file_name().map_or(program.clone(), |n| n.to_string_lossy().into_owned());
    let quote = |a: String| if a.is_empty() || a.contains(char::is_whitespace) { format!("'{a}'") } else { a };
    std::iter::once(name).chain(args.map(quote)).collect::<Vec<_>>().join(" ")
}

/// The command line as run, as a user repeats it from the repository:
/// `cargo run --release --bin NAME -- ARGS` (a summary's "Regenerate" line).
pub fn cargo_run_line() -> String {
    cargo_run(&command_line())
}

/// `command` (the program's name, then its arguments) as a `cargo run` line.
fn cargo_run(command: &str) -> String {
    match command.split_once(' ') {
        Some((name, args)) => format!("cargo run --release --bin {name} -- {args}"),
        None => format!("cargo run --release --bin {command}"),
    }
}

/// `t` as an ISO 8601 UTC date and time to the second
/// (`2024-02-29T13:05:09Z`); times before 1970 read as 1970.
pub fn utc_date(t: SystemTime) -> String {
    let secs = t.duration_since(UNIX_EPOCH).map_or(0, |d| d.as_secs());
    let (days, rem) = (secs / 86_400, secs % 86_400);
    let (y, m, d) = civil_from_days(days);
    format!("{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}Z", rem / 3600, rem / 60 % 60, rem % 60)
}

/// (year, month 1-12, day 1-31) of the day `days` after 1970-01-01 in the
/// proleptic Gregorian calendar (H. Hinnant's `civil_from_days`, for days >= 0).
fn civil_from_days(days: u64) -> (u64, u64, u64) {
    let z = days + 719_468; // days since 0000-03-01
    let era = z / 146_097;
    let doe = z - era * 146_097; // day of the 400-year era, [0, 146096]
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365; // [0, 399]
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100); // day of the year from March 1st, [0, 365]
    let mp = (5 * doy + 2) / 153; // month from March, [0, 11]
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    (yoe + era * 400 + u64::from(m <= 2), m, d)
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

/// The provenance fields every manifest carries: `revision` (built from),
/// `tree_clean` (null where unknown), `command` (as run), `date` (UTC, when
/// the manifest is written: the run's end), `wall_s`, worker `threads`.
pub fn provenance(wall_s: f64) -> Map<String, Value> {
    let mut map = Map::new();
    map.insert("revision".into(), REVISION.into());
    map.insert("tree_clean".into(), tree_clean().into());
    map.insert("command".into(), command_line().into());
    map.insert("date".into(), utc_date(SystemTime::now()).into());
    map.insert("wall_s".into(), wall_s.into());
    map.insert("threads".into(), rayon::current_num_threads().into());
    map
}

/// Writes a run's manifest: the fields of `settings` (any serde-serialisable
/// settings struct, so no key is listed by hand), then the [`provenance`]
/// fields and the machine's `speed_probe` (timed now, after the run, in
/// about a second: it tells a slow machine from a slow revision).
pub fn write_manifest<T: serde::Serialize>(path: &Path, settings: &T, wall_s: f64) -> Result<()> {
    let mut value = serde_json::to_value(settings).map_err(|e| Error(e.to_string()))?;
    let Value::Object(map) = &mut value else {
        return Err(Error::new("manifest: settings must serialise to a JSON object"));
    };
    map.extend(provenance(wall_s));
    let probe = serde_json::to_value(super::speed_probe::speed_probe()).map_err(|e| Error(e.to_string()))?;
    map.insert("speed_probe".into(), probe);
    write_json(path, &value)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    /// A summary's "Regenerate" line repeats the flags the run was given.
    #[test]
    fn a_command_becomes_the_cargo_line_that_repeats_it() {
        assert_eq!(cargo_run("stability"), "cargo run --release --bin stability");
        assert_eq!(
            cargo_run("photon_diagnostics --path-spp 65536"),
            "cargo run --release --bin photon_diagnostics -- --path-spp 65536"
        );
    }

    #[test]
    fn dates_are_iso_8601_utc() {
        let at = |s: u64| utc_date(UNIX_EPOCH + Duration::from_secs(s));
        assert_eq!(at(0), "1970-01-01T00:00:00Z");
        assert_eq!(at(951_782_400), "2000-02-29T00:00:00Z");
        assert_eq!(at(1_709_164_800), "2024-02-29T00:00:00Z");
        assert_eq!(at(1_764_120_000), "2025-11-26T01:20:00Z");
        assert_eq!(at(4_102_444_799), "2099-12-31T23:59:59Z");
    }

    #[test]
    fn the_revision_is_embedded() {
        assert!(REVISION == "unknown" || (REVISION.len() >= 12 && REVISION.bytes().all(|b| b.is_ascii_hexdigit())));
        assert!(git_revision().starts_with(REVISION));
    }
}
