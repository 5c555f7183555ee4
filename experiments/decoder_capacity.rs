//! How well can the latent + decoder represent the built-in plume at all?
//! Fits (z, w) by Adam straight to the true density inside the visual hull
//! (no rendering, mean squared density error, the decoder's exact
//! vector-Jacobian product): an upper bound on what training through the
//! renderer can reach with this model.
//!
//! The fitted density is then rendered and judged like a reconstruction
//! (`fit_quality.csv`): the image misfit that the model alone leaves.
//!
//! Writes `results/studies/decoder_capacity/{capacity.csv, fit_quality.csv,
//! density_fitted.npy, summary.md, manifest.json}`.

use clap::Parser;
use dualphoton::error::Result;
use dualphoton::eval::fit_quality::{fit_quality, fit_quality_markdown, FitQualitySettings, FitTarget};
use dualphoton::eval::metrics::{hull_stats, pearson, rel_l1};
use dualphoton::experiment::{self, Run};
use dualphoton::io::npy;
use dualphoton::io::rows::write_rows;
use dualphoton::optim::Adam;
use dualphoton::recon::problem::paper_problem;
use dualphoton::recon::reconstruct::initial_model;
use dualphoton::scene::rig;
use serde::Serialize;
use std::fmt::Write as _;
use std::path::PathBuf;

#[derive(Parser, Serialize)]
#[command(about = "Fit the latent and decoder straight to the true density: the model's capacity")]
struct Args {
    /// Grid resolution (res^3).
    #[arg(long, default_value_t = 64)]
    res: usize,
    /// Seed of the plume and the model's initial values.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Adam steps.
    #[arg(long, default_value_t = 500)]
    iterations: usize,
    /// Adam step of the latent.
    #[arg(long, default_value_t = 0.05)]
    lr_latent: f64,
    /// Adam step of the decoder weights.
    #[arg(long, default_value_t = 0.01)]
    lr_weights: f64,
    /// Log every this many steps.
    #[arg(long, default_value_t = 50)]
    every: usize,
    /// Output directory.
    #[arg(long, default_value = "results/studies/decoder_capacity")]
    out: PathBuf,
    /// A tiny run, to check that everything works.
    #[arg(long)]
    smoke: bool,
}

/// The fit's Table 1 measures at one step.
#[derive(Serialize)]
struct Row {
    iteration: usize,
    rel_l1_epsilon: f64,
    pearson_r: f64,
    mean: f64,
    max: f64,
}

fn main() -> std::process::ExitCode {
    experiment::main(run)
}

fn run(mut args: Args) -> Result<()> {
    if args.smoke {
        args.res = 16;
        args.iterations = 20;
        args.every = 10;
    }
    experiment::check_decoder_res(args.res)?;
    let run = Run::start(&args.out)?;
    // The hull comes from the same images the main job carves it from.
    let problem = paper_problem(args.res, args.seed, if args.smoke { 20_000 } else { 1_000_000 }, 0);
    let mut model = initial_model(&problem.scene, &problem.images[..rig::HELD_OUT_CAMERA], args.seed)?;
    let truth = &problem.truth.data;
    let mask = model.mask.clone();
    let hull = mask.iter().filter(|&&m| m).count() as f64;
    let (mut adam_z, mut adam_w) =
        (Adam::new(model.z.len(), args.lr_latent), Adam::new(model.w.len(), args.lr_weights));
    let measure = |iteration: usize, d: &[f64]| {
        let s = hull_stats(d, &mask);
        Row {
            iteration,
            rel_l1_epsilon: rel_l1(d, truth, &mask).expect("a plume is never all zero"),
            pearson_r: pearson(truth, d, &mask),
            mean: s.mean,
            max: s.max,
        }
    };
    let mut rows = vec![];
    for it in 0..=args.iterations {
        let d = model.decoder.forward(&model.z, &model.w, &mask);
        if it % args.every.max(1) == 0 || it == args.iterations {
            let row = measure(it, &d);
            eprint!("\rstep {it}/{}  eps {:.3}  r {:.3}   ", args.iterations, row.rel_l1_epsilon, row.pearson_r);
            rows.push(row);
        }
        if it == args.iterations {
            break;
        }
        let g: Vec<f64> =
            d.iter().zip(truth).zip(&mask).map(|((a, b), &m)| if m { 2.0 * (a - b) / hull } else { 0.0 }).collect();
        let (gz, gw) = model.decoder.backward(&model.z, &model.w, &mask, &g);
        adam_z.step(&mut model.z, &gz);
        adam_w.step(&mut model.w, &gw);
    }
    eprintln!();
    write_rows(&run.path("capacity.csv"), &rows)?;
    // The fitted density seen by the cameras: how well the best the model can
    // hold explains the images, the ceiling of a fit through the renderer.
    let fitted = model.density(&problem.scene.density);
    npy::write_f32(&run.path("density_fitted.npy"), &fitted.shape, &fitted.data)?;
    let judge = if args.smoke {
        FitQualitySettings { photons: 20_000, spp: 2, ..Default::default() }
    } else {
        FitQualitySettings::default()
    };
    eprintln!("judging the fitted density's images ({} photons, {} spp) ...", judge.photons, judge.spp);
    let fit = fit_quality(&problem.scene, &fitted, FitTarget::Truth(&problem.truth), rig::HELD_OUT_CAMERA, &judge)?;
    write_rows(&run.path("fit_quality.csv"), &fit)?;
    let t = hull_stats(truth, &mask);
    let last = rows.last().expect("at least one row");
    let mut md = format!(
        "# Decoder capacity ({}^3, {} hull voxels, {} decoder parameters, latent {})\n\n\
         Latent and decoder fitted by Adam straight to the true density (no rendering), {} steps.\n\n\
         | measure | fit | truth |\n|---|---|---|\n",
        args.res,
        hull,
        model.decoder.param_count(),
        model.z.len(),
        args.iterations
    );
    let _ = writeln!(md, "| voxel relative L1 error epsilon | {:.3} | 0 |", last.rel_l1_epsilon);
    let _ = writeln!(md, "| Pearson r | {:.3} | 1 |", last.pearson_r);
    let _ = writeln!(md, "| mean density | {:.4} | {:.4} |", last.mean, t.mean);
    let _ = writeln!(md, "| max density | {:.3} | {:.3} |", last.max, t.max);
    let _ = write!(
        md,
        "\nThe fitted density's images against the truth's (both at {} photons, {} spp, same seed; in brackets \
         the truth's two-seed noise floor), `fit_quality.csv`:\n\n{}",
        judge.photons,
        judge.spp,
        fit_quality_markdown(&fit)
    );
    let _ = writeln!(md, "\nRegenerate: `cargo run --release --bin decoder_capacity` ({:.0} s).", run.seconds());
    std::fs::write(run.path("summary.md"), &md)?;
    run.write_manifest(&args)?;
    print!("{md}");
    Ok(())
}
