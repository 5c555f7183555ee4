//! Fig. 5 (loss per iteration) from a saved training log:
//! `results/table1/log.csv` -> `results/table1/fig5_loss.svg` (`--dir` to change).

use clap::Parser;
use dualphoton::error::Error;
use std::path::PathBuf;

#[derive(Parser)]
#[command(about = "Regenerate Fig. 5 from the saved run log")]
struct Args {
    /// Directory of a reconstruction (holds log.csv).
    #[arg(long, default_value = "results/table1")]
    dir: PathBuf,
}

fn main() -> std::process::ExitCode {
    dualphoton::experiment::main(|args: Args| {
        let out = args.dir.join("fig5_loss.svg");
        dualphoton::io::figures::loss_curves(&args.dir.join("log.csv"), &out)
            .map_err(|e| Error(format!("{e} (run `cargo run --release --bin experiment_table1` first)")))?;
        eprintln!("wrote {}", out.display());
        Ok(())
    })
}
