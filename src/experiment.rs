//! The preamble every experiment binary shares (`experiments/*`).
//!
//! Why it exists: each experiment used to repeat the same opening and
//! closing (memory settings, argument parsing, an error turned into a
//! one-line message and exit code, the output folder, the clock, the
//! manifest), and the copies drifted apart. Here they are written once, so
//! an experiment is only its settings, its computation and what it writes:
//!
//! ```no_run
//! use dualphoton::experiment::{self, Run};
//!
//! #[derive(clap::Parser, serde::Serialize)]
//! struct Args {
//!     #[arg(long, default_value = "results/example")]
//!     out: std::path::PathBuf,
//! }
//!
//! fn main() -> std::process::ExitCode {
//!     experiment::main(|args: Args| {
//!         let run = Run::start(&args.out)?;
//!         std::fs::write(run.path("summary.md"), "# Example\n")?;
//!         run.write_manifest(&args)
//!     })
//! }
//! ```

use crate::error::{exit_code, Error, Result};
use crate::io::manifest::write_manifest;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

/// An experiment's `main`: keeps freed memory in the process (see
/// [`crate::process::keep_freed_memory`]), parses the command line into `A`
/// (clap prints help or a usage error and exits), runs `run`, and turns its
/// error into `error: <message>` on stderr and a failing exit code.
/// Worker threads are rayon's default (all cores); results do not depend on them.
pub fn main<A: clap::Parser>(run: impl FnOnce(A) -> Result<()>) -> ExitCode {
    crate::process::keep_freed_memory();
    exit_code(run(A::parse()))
}

/// The largest grid edge an experiment accepts (the decoder's largest).
pub const MAX_RES: usize = 1024;

/// Checks an experiment's `--res` (grid edge, and image size where the
/// rig's cameras use it) before any work: from 2 to [`MAX_RES`].
pub fn check_res(res: usize) -> Result<()> {
    if !(2..=MAX_RES).contains(&res) {
        return Err(Error(format!("--res: {res} is not a grid edge from 2 to {MAX_RES}")));
    }
    Ok(())
}

/// Checks the `--res` of an experiment that fits the paper's decoder before
/// any work: an edge the decoder supports (see
/// [`crate::model::Decoder::paper_small`]), the error naming the option.
pub fn check_decoder_res(res: usize) -> Result<()> {
    crate::model::Decoder::paper_small(res).map(|_| ()).map_err(|e| Error(format!("--res: {e}")))
}

/// One run of an experiment: its output folder and its clock.
#[derive(Debug)]
pub struct Run {
    /// The output folder.
    pub out: PathBuf,
    started: Instant,
}

impl Run {
    /// Creates the output folder `out` (and its parents) and starts the clock.
    pub fn start(out: &Path) -> Result<Run> {
        std::fs::create_dir_all(out)?;
        Ok(Run::timer(out))
    }

    /// Starts the clock of a run whose folder is created later (or not at
    /// all, as in a training run stopped to be resumed).
    pub fn timer(out: &Path) -> Run {
        Run { out: out.to_path_buf(), started: Instant::now() }
    }

    /// Seconds since the run started.
    pub fn seconds(&self) -> f64 {
        self.started.elapsed().as_secs_f64()
    }

    /// `name` inside the output folder.
    pub fn path(&self, name: &str) -> PathBuf {
        self.out.join(name)
    }

    /// Writes `manifest.json` into the output folder: `settings` (any
    /// serde-serialisable struct of the run's settings) plus provenance and
    /// the wall time since the start (see [`write_manifest`]).
    pub fn write_manifest<T: serde::Serialize>(&self, settings: &T) -> Result<()> {
        write_manifest(&self.path("manifest.json"), settings, self.seconds())
    }

    /// As [`Run::write_manifest`], with the wall time given (a run that
    /// measures its own, e.g. before its last writes).
    pub fn write_manifest_timed<T: serde::Serialize>(&self, settings: &T, wall_s: f64) -> Result<()> {
        write_manifest(&self.path("manifest.json"), settings, wall_s)
    }
}
