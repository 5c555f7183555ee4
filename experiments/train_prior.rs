//! Trains the plume prior (an auto-decoder over many simulated plumes) and
//! writes it where reconstructions find it (`models/plume64/`):
//! `prior.json`, `weights.npy`, `latents.npy`, `manifest.json`, `loss.csv`,
//! `loss.svg` and `validation.csv` (latents fitted, weights fixed, to
//! held-out validation plumes: how well the prior represents plumes it
//! has not seen).
//!
//! Resumable: the state is checkpointed after every epoch under
//! `cache/` (git-ignored), and a run with the same settings continues
//! from there to the same bits. Deterministic from `--seed`.

use clap::Parser;
use dualphoton::data::plume::variation::VALIDATION_SEEDS;
use dualphoton::data::plume::{plume_with, Variation};
use dualphoton::error::Result;
use dualphoton::eval::metrics::{block_means, pearson, rel_l1};
use dualphoton::experiment::{self, Run};
use dualphoton::io::plot::{line_chart, Axes, Series};
use dualphoton::io::rows::write_rows;
use dualphoton::prior::train::{fit_latent, initial_state, load_checkpoint, targets, train, PriorSettings};
use dualphoton::prior::training_set::{cache_dir, training_set};
use dualphoton::prior::Prior;
use serde::Serialize;
use std::path::PathBuf;

#[derive(Parser, Serialize)]
#[command(about = "Train the plume prior (a decoder over many simulated plumes) into models/plume64")]
struct Args {
    /// Grid edge of the plumes and the decoder.
    #[arg(long, default_value_t = 64)]
    res: usize,
    /// Training plumes.
    #[arg(long, default_value_t = 400)]
    plumes: usize,
    /// Passes over the training plumes.
    #[arg(long, default_value_t = 100)]
    epochs: usize,
    /// Plumes per update of the weights.
    #[arg(long, default_value_t = 8)]
    batch: usize,
    /// Adam step of the weights.
    #[arg(long, default_value_t = 2e-3)]
    lr_weights: f64,
    /// Adam step of the latents.
    #[arg(long, default_value_t = 3e-2)]
    lr_latent: f64,
    /// Both steps fall exponentially to this fraction over the epochs.
    #[arg(long, default_value_t = 0.05)]
    lr_final: f64,
    /// Weight of |z|^2 per plume.
    #[arg(long, default_value_t = 1e-4)]
    latent_penalty: f64,
    /// The plumes are learned blurred by a Gaussian of this many voxels (0: as they are).
    #[arg(long, default_value_t = 1.0)]
    blur: f64,
    /// Seed of the initial weights, latents and shuffles.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Validation plumes (held-out seeds) whose latents are fitted at the end.
    #[arg(long, default_value_t = 8)]
    validation: usize,
    /// Stop after this many epochs of this run (a later run resumes).
    #[arg(long)]
    stop_after: Option<usize>,
    /// Output directory.
    #[arg(long, default_value = "models/plume64")]
    out: PathBuf,
    /// Where the plumes and the checkpoint are cached (git-ignored).
    #[arg(long, default_value = "cache")]
    cache: PathBuf,
    /// A tiny run (16^3, few plumes and epochs) into target/prior_smoke, to check that everything works.
    #[arg(long)]
    smoke: bool,
}

/// One validation plume's fit.
#[derive(Serialize)]
struct ValidationRow {
    seed: u64,
    sources: usize,
    /// Normalised loss against the blurred plume (1 = predicting nothing).
    loss: f64,
    /// Against the plume itself (not blurred), voxel by voxel, over the occupied voxels of truth or fit.
    pearson_r: f64,
    rel_l1_epsilon: f64,
    /// The same over 2x2x2 blocks.
    block_pearson_r: f64,
    block_rel_l1_epsilon: f64,
}

fn main() -> std::process::ExitCode {
    experiment::main(run)
}

fn run(mut args: Args) -> Result<()> {
    if args.smoke {
        (args.res, args.plumes, args.epochs, args.batch, args.validation) = (16, 6, 3, 2, 2);
        args.out = PathBuf::from("target/prior_smoke");
        args.cache = PathBuf::from("target/prior_smoke_cache");
    }
    let settings = PriorSettings {
        res: args.res,
        plumes: args.plumes,
        epochs: args.epochs,
        batch: args.batch,
        lr_weights: args.lr_weights,
        lr_latent: args.lr_latent,
        lr_final: args.lr_final,
        latent_penalty: args.latent_penalty,
        seed: args.seed,
        blur: args.blur,
        ..PriorSettings::default()
    };
    dualphoton::prior::train::validate(&settings)?;
    let run = Run::timer(&args.out);
    let plumes = targets(&settings, training_set(args.res, args.plumes, Some(&cache_dir(&args.cache, args.res)))?);
    let data_s = run.seconds();
    let name = args.out.file_name().map_or("prior".into(), |n| n.to_string_lossy().into_owned());
    let checkpoint = args.cache.join(format!("checkpoint_{name}"));
    let state = match load_checkpoint(&settings, &checkpoint)? {
        Some(s) => {
            eprintln!("resuming from {} after epoch {}", checkpoint.display(), s.epochs_done());
            s
        }
        None => initial_state(&settings)?,
    };
    let d = state.decoder.clone();
    eprintln!("decoder:\n{}", d.describe());
    let state = train(&settings, &plumes, state, Some(&checkpoint), args.stop_after, &mut |row, eta| {
        eprintln!(
            "epoch {}/{}  loss {:.4}  latent rms {:.3}  {:.0} s  ETA {:.0} s",
            row.epoch, settings.epochs, row.loss, row.latent_rms, row.wall_s, eta
        );
    })?;
    if state.epochs_done() < settings.epochs {
        eprintln!("stopped after epoch {}; run again to resume", state.epochs_done());
        return Ok(());
    }
    let train_s = state.rows.last().map_or(0.0, |r| r.wall_s);
    std::fs::create_dir_all(&args.out)?;
    let latents = state.latents();
    Prior::save(&d, &state.w, &latents, &args.out)?;
    write_rows(&args.out.join("loss.csv"), &state.rows)?;
    let points = state.rows.iter().map(|r| (r.epoch as f64, r.loss)).collect();
    line_chart(
        &args.out.join("loss.svg"),
        &Axes { title: "Prior training loss", x: "epoch", y: "normalised density loss", log_x: false, log_y: true },
        &[Series { name: "training plumes".into(), points, markers: false }],
    )?;

    // The saved prior as a reconstruction reads it (float32 weights), on unseen plumes.
    let prior = Prior::load(&args.out)?;
    let start = vec![0.0; d.latent()]; // the whitened latents' mean
    let mut rows = vec![];
    for seed in VALIDATION_SEEDS.start..VALIDATION_SEEDS.start + args.validation as u64 {
        let v = Variation::sample(seed);
        let truth = plume_with(args.res, seed, &v)?.data;
        let target = targets(&settings, vec![truth.clone()]).remove(0);
        let (z, loss) = fit_latent(&prior.decoder, &prior.w, &target, &start, 200, 0.05, settings.latent_penalty);
        let fit = prior.decoder.forward(&z, &prior.w, &vec![true; truth.len()]);
        let occupied: Vec<bool> = truth.iter().zip(&fit).map(|(a, b)| *a > 0.0 || *b > 0.0).collect();
        let (tb, fb) = (block_means(&truth, args.res), block_means(&fit, args.res));
        let occ_b: Vec<bool> = tb.iter().zip(&fb).map(|(a, b)| *a > 0.0 || *b > 0.0).collect();
        let row = ValidationRow {
            seed,
            sources: v.sources.len(),
            loss,
            pearson_r: pearson(&truth, &fit, &occupied),
            rel_l1_epsilon: rel_l1(&fit, &truth, &occupied).expect("a plume is never all zero"),
            block_pearson_r: pearson(&tb, &fb, &occ_b),
            block_rel_l1_epsilon: rel_l1(&fb, &tb, &occ_b).expect("a plume is never all zero"),
        };
        eprintln!(
            "validation seed {seed}: loss {:.3}  r {:.3} (blocks {:.3})  eps {:.3} (blocks {:.3})",
            row.loss, row.pearson_r, row.block_pearson_r, row.rel_l1_epsilon, row.block_rel_l1_epsilon
        );
        rows.push(row);
    }
    write_rows(&args.out.join("validation.csv"), &rows)?;

    #[derive(Serialize)]
    struct Manifest<'a> {
        #[serde(flatten)]
        args: &'a Args,
        training_seeds: String,
        validation_seeds: String,
        parameters: usize,
        architecture: String,
        plumes_s: f64,
        train_s: f64,
        final_loss: f64,
    }
    let manifest = Manifest {
        args: &args,
        training_seeds: format!(
            "{}..{}",
            dualphoton::prior::training_set::training_seed(0),
            dualphoton::prior::training_set::training_seed(args.plumes)
        ),
        validation_seeds: format!("{}..{}", VALIDATION_SEEDS.start, VALIDATION_SEEDS.start + args.validation as u64),
        parameters: d.param_count(),
        architecture: d.describe(),
        plumes_s: data_s,
        train_s,
        final_loss: state.rows.last().map_or(f64::NAN, |r| r.loss),
    };
    run.write_manifest(&manifest)?;
    eprintln!("wrote {}", args.out.display());
    Ok(())
}
