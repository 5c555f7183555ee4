//! Fig. 7 (ground-truth vs estimated voxel density) from the saved arrays of
//! `results/table1/` (`--dir` to change).

use clap::Parser;
use dualphoton::error::{Error, Result};
use dualphoton::io::npy;
use std::path::PathBuf;

#[derive(Parser)]
#[command(about = "Regenerate Fig. 7 from the saved density arrays")]
struct Args {
    /// Directory of a reconstruction (holds density_gt.npy, density_initial.npy, density_estimated.npy, hull.npy).
    #[arg(long, default_value = "results/table1")]
    dir: PathBuf,
}

fn run(args: &Args) -> Result<()> {
    let read = |name: &str| npy::read(&args.dir.join(name), name);
    let (gt, before, after, hull) =
        (read("density_gt.npy")?, read("density_initial.npy")?, read("density_estimated.npy")?, read("hull.npy")?);
    if [&before, &after, &hull].iter().any(|a| a.shape != gt.shape) {
        return Err(Error::new("the saved arrays do not share one shape"));
    }
    let mask: Vec<bool> = hull.data.iter().map(|&v| v != 0.0).collect();
    let out = args.dir.join("fig7_scatter.svg");
    dualphoton::io::figures::density_scatter(&gt.data, &before.data, &after.data, &mask, &out)?;
    eprintln!("wrote {}", out.display());
    Ok(())
}

fn main() -> std::process::ExitCode {
    dualphoton::experiment::main(|args: Args| {
        run(&args).map_err(|e| Error(format!("{e} (run `cargo run --release --bin experiment_table1` first)")))
    })
}
