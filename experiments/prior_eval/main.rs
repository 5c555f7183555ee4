//! Evaluates the learned prior against the paper's per-scene decoder on
//! plumes no part of training saw: test plumes from the training
//! distribution (unseen seeds), the Table 1 plume, and plumes deliberately
//! outside it (three sources, still air, strong turbulence, cut off by the
//! top of the box, thick and smooth), and the Table 1 plume in images of
//! another renderer (the path tracer). Every plume is seen by the paper's rig
//! (4 training cameras, camera 4 held out) and reconstructed by
//! - `paper`: the per-scene decoder (the main job's default settings),
//! - `prior`: the prior's latent only (fwd-full over its 64 coordinates),
//! - `prior_refine`: that, then the per-voxel refinement;
//! - `oracle` (a study, on request): starts no reconstruction could have,
//!   each measured as it is and after the prior's refinement: the truth
//!   blurred as the prior learned it (`oracle_truth`, a perfect prior), and
//!   the prior's latent fitted to that blurred truth directly, without
//!   rendering (`oracle_latent`, the best the latent can represent); and
//!   the truth itself, measured only (`oracle_exact`: its held-out error is
//!   the render noise's floor).
//!
//! Resumable: each (plume, method) row is written as it finishes under
//! `<out>/rows/`, and a later run skips the rows it finds (`--fresh`
//! recomputes). The estimates are cached under `cache/<name of --out>/` for the
//! slice figures. Writes `<out>/{table.csv, table.md, scatter.svg,
//! slices_<plume>.svg, manifest.json}`.

mod fits;
mod plumes;
mod report;

use clap::Parser;
use dualphoton::data::plume::Unusual;
use dualphoton::error::{Error, Result};
use dualphoton::experiment::Run;
use dualphoton::io::rows::write_rows;
use dualphoton::prior::Prior;
use dualphoton::recon::hull::HullSettings;
use dualphoton::recon::methods::{Method, MethodOptions};
use dualphoton::recon::paper;
use dualphoton::recon::problem::{paper_problem_of, target_render, PaperProblem, Problem};
use dualphoton::recon::study::{apply_study, read_study};
use dualphoton::render::path::{render_path, PathOptions};
use dualphoton::scene::rig;
use fits::Plume;
use plumes::{read_rows, Which};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

#[derive(Parser, Serialize)]
#[command(
    about = "Evaluate the learned prior against the paper's per-scene decoder on unseen plumes",
    after_help = "Options set both methods."
)]
struct Args {
    /// Grid resolution (res^3) and image size.
    #[arg(long, default_value_t = 64)]
    res: usize,
    /// Plumes, comma-separated: table1, test0..test99, val0..val99 (validation: for choosing settings,
    /// never reported as test), three_sources, no_drafts, strong_turbulence, cut_off, smooth,
    /// table1_path (the Table 1 plume, its images path-traced); default: table1, test0-test7, the
    /// five unusual plumes and table1_path.
    #[arg(long)]
    plumes: Option<String>,
    /// Methods, comma-separated: paper, prior (also writes prior_refine when the prior's refinement has
    /// updates), oracle (a study: the prior's refinement from the blurred truth, oracle_truth[_refine], and
    /// from the latent fitted to it without rendering, oracle_latent[_refine]; also oracle_exact, the truth
    /// measured as an estimate).
    #[arg(long, default_value = "paper,prior")]
    methods: String,
    /// The prior's directory.
    #[arg(long, default_value = "models/plume64")]
    #[serde(rename = "prior_dir")]
    prior: PathBuf,
    #[command(flatten)]
    #[serde(flatten)]
    method: MethodOptions,
    /// A study file: JSON setting anything of the run by name: {"paper": {"train": {...}, "refine": {...}},
    /// "prior": {...}, "hull": {"threshold": x, "dilate": n}, "path_spp": n} (experiments/studies/).
    #[arg(long)]
    study: Option<PathBuf>,
    /// Recompute rows that exist.
    #[arg(long)]
    fresh: bool,
    /// Output directory.
    #[arg(long, default_value = "results/studies/prior_eval")]
    out: PathBuf,
}

/// Everything a study file may set (it opens the manifest).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
struct Setup {
    /// The paper's method.
    paper: Method,
    /// The learned prior's fit.
    prior: Method,
    /// How the visual hull is carved.
    hull: HullSettings,
    /// Samples per pixel of the path-traced images of `table1_path`.
    path_spp: u32,
}

impl Default for Setup {
    fn default() -> Self {
        Setup { paper: Method::paper(), prior: Method::prior(), hull: HullSettings::default(), path_spp: 4096 }
    }
}

/// The methods `--methods` names.
const METHODS: [&str; 3] = ["paper", "prior", "oracle"];

/// The rows a method writes: a method runs again while any of them is missing (a
/// latent fit whose refinement was cut off is fitted again; the fit is deterministic).
fn rows_of(method: &str, refine_updates: usize) -> Vec<String> {
    match method {
        "oracle" => plumes::ROWS.iter().filter(|r| r.starts_with("oracle")).map(|r| r.to_string()).collect(),
        "prior" if refine_updates > 0 => vec!["prior".into(), "prior_refine".into()],
        m => vec![m.to_string()],
    }
}

/// The run's settings: the library's defaults, the study file, the options; checked before any work.
fn settings(args: &Args) -> Result<(Vec<Which>, Vec<String>, Setup)> {
    dualphoton::experiment::check_decoder_res(args.res)?;
    args.method.check()?;
    let plumes: Vec<Which> = match &args.plumes {
        Some(list) => list.split(',').map(|s| Which::parse(s.trim())).collect::<Result<_>>()?,
        None => std::iter::once(Which::Table1)
            .chain((0..8).map(Which::Test))
            .chain(Unusual::ALL.iter().map(|&u| Which::Unusual(u)))
            .chain(std::iter::once(Which::PathTraced))
            .collect(),
    };
    let methods: Vec<String> = args.methods.split(',').map(|m| m.trim().to_string()).collect();
    if let Some(m) = methods.iter().find(|m| !METHODS.contains(&m.as_str())) {
        return Err(Error(format!("--methods: unknown method '{m}' ({})", METHODS.join(", "))));
    }
    let mut setup = Setup::default();
    if let Some(path) = &args.study {
        apply_study(&mut setup, &read_study(path)?)?;
    }
    for m in [&mut setup.paper, &mut setup.prior] {
        args.method.apply(m);
        m.check()?;
    }
    if setup.path_spp < 2 {
        return Err(Error(format!("path_spp: {} must be at least 2", setup.path_spp)));
    }
    Ok((plumes, methods, setup))
}

fn main() -> std::process::ExitCode {
    dualphoton::experiment::main(run)
}

/// What the manifest records: the options, then the settings they led to.
#[derive(Serialize)]
struct Manifest<'a> {
    #[serde(flatten)]
    args: &'a Args,
    #[serde(flatten)]
    setup: &'a Setup,
}

fn run(args: Args) -> Result<()> {
    let out = Run::timer(&args.out);
    let (plumes, methods, setup) = settings(&args)?;
    let prior = match methods.iter().any(|m| m != "paper") {
        true => Some(Prior::load(&args.prior)?),
        false => None,
    };
    let rows_dir = args.out.join("rows");
    let name = args.out.file_name().map_or("prior_eval".into(), |n| n.to_string_lossy().into_owned());
    let cache = PathBuf::from("cache").join(name);
    std::fs::create_dir_all(&rows_dir)?;
    std::fs::create_dir_all(&cache)?;
    for (p, &which) in plumes.iter().enumerate() {
        let missing = |m: &&String| {
            let row_exists = |row: &String| rows_dir.join(format!("{}_{row}.json", which.name())).exists();
            args.fresh || !rows_of(m, setup.prior.refine.updates).iter().all(row_exists)
        };
        let wanted: Vec<&String> = methods.iter().filter(missing).collect();
        if wanted.is_empty() {
            continue;
        }
        eprintln!("[{}/{}] {} ({}): rendering the truth ...", p + 1, plumes.len(), which.name(), which.group());
        let truth = which.truth(args.res)?;
        let PaperProblem { truth, mut scene, mut images } =
            paper_problem_of(truth, which.seed(), paper::TARGET_PHOTONS, 0);
        target_render(&mut scene, which.seed(), paper::TARGET_PHOTONS);
        if which == Which::PathTraced {
            let opts =
                PathOptions { spp: setup.path_spp, seed: paper::target_seed(which.seed()), ..PathOptions::default() };
            images = render_path(&scene, &opts).radiance;
        }
        let (targets, held_out) = images.split_at(rig::HELD_OUT_CAMERA);
        let problem = Problem { scene: &scene, targets, held_out, truth: Some(&truth) };
        let plume = Plume { which, problem: &problem, setup: &setup, rows_dir: &rows_dir, cache: &cache };
        for method in wanted {
            match (method.as_str(), &prior) {
                ("paper", _) => plume.paper()?,
                ("prior", Some(prior)) => plume.prior(prior)?,
                (_, Some(prior)) => plume.oracle(prior)?,
                _ => unreachable!("the prior is loaded for every method but paper"),
            }
        }
    }
    let rows = read_rows(&rows_dir, &plumes)?;
    write_rows(&args.out.join("table.csv"), &rows)?;
    std::fs::write(args.out.join("table.md"), report::table_markdown(&rows))?;
    report::figures(args.res, &args.out, &plumes, &cache)?;
    let manifest = Manifest { args: &args, setup: &setup };
    out.write_manifest(&manifest)?;
    print!("{}", report::table_markdown(&rows));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_method_runs_again_while_any_of_its_rows_is_missing() {
        assert_eq!(rows_of("prior", 200), ["prior", "prior_refine"]);
        assert_eq!(rows_of("prior", 0), ["prior"]);
        assert_eq!(rows_of("paper", 200), ["paper"]);
        assert_eq!(rows_of("oracle", 0).len(), 5);
    }
}
