//! Writes `results/README.md`, the index of the results: one row per run
//! folder (folder, command, revision, clean tree, date, wall time, threads,
//! speed probe) from its `manifest.json`. `--results` names another folder.

use clap::Parser;
use dualphoton::io::results_index::{markdown, FILE};
use std::path::PathBuf;

#[derive(Parser)]
#[command(about = "Write results/README.md, the index of the results, from their manifests")]
struct Args {
    /// The results folder.
    #[arg(long, default_value = "results")]
    results: PathBuf,
}

fn main() -> std::process::ExitCode {
    dualphoton::experiment::main(|args: Args| {
        let path = args.results.join(FILE);
        std::fs::write(&path, markdown(&args.results)?)?;
        eprintln!("wrote {}", path.display());
        Ok(())
    })
}
