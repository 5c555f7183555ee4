//! Fig. 5 (loss per iteration) from a saved training log:
//! `results/table1/log.csv` -> `results/table1/fig5_loss.svg` (`--dir` to change).

use clap::Parser;
use std::path::PathBuf;

#[derive(Parser)]
#[command(about = "Regenerate Fig. 5 from the saved run log")]
struct Args {
    /// Directory of a reconstruction (holds log.csv).
    #[arg(long, default_value = "results/table1")]
    dir: PathBuf,
}

fn main() -> std::process::ExitCode {
    dualphoton::process::keep_freed_memory();
    let args = Args::parse();
    match dualphoton::io::figures::loss_curves(&args.dir.join("log.csv"), &args.dir.join("fig5_loss.svg")) {
        Ok(()) => {
            eprintln!("wrote {}", args.dir.join("fig5_loss.svg").display());
            std::process::ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {e} (run `cargo run --release --bin experiment_table1` first)");
            std::process::ExitCode::FAILURE
        }
    }
}
