//! The main job's report: Table 1 (CSV, Markdown, chart), the comparison
//! of both methods against the targets, and the manifest.

use super::{Args, MethodRun, Setup};
use dualphoton::error::Result;
use dualphoton::eval::fit_quality::fit_quality_markdown;
use dualphoton::eval::metrics::hull_stats;
use dualphoton::io::figures::{table1_chart, Table1Bars};
use dualphoton::recon::paper::TABLE1;
use dualphoton::scene::Scene;
use dualphoton::volume::Grid;
use serde::Serialize;
use std::fmt::Write as _;

/// What the report is about beyond the methods' runs.
pub struct Run<'a> {
    pub args: &'a Args,
    pub setup: &'a Setup,
    pub truth: &'a Grid<f64>,
    pub n_train: usize,
    /// The output folder and the run's clock.
    pub out: &'a dualphoton::experiment::Run,
}

/// What produced a run: its options and settings, then what they led to.
#[derive(Serialize)]
struct Manifest<'a> {
    #[serde(flatten)]
    args: &'a Args,
    #[serde(flatten)]
    setup: &'a Setup,
    /// Photons of the target images and the final renders.
    target_photons: u64,
    /// Samples per pixel of the target images and the final renders.
    target_spp: u32,
    hull_voxels: usize,
    decoder: String,
    decoder_parameters: usize,
    prior_decoder_parameters: Option<usize>,
}

/// A row of the comparison table: its name, how to show it for one method, its target.
type Measure<'a> = (&'a str, &'a dyn Fn(&MethodRun) -> String, &'a str);

/// Writes `table1.{csv,md,svg}` and `manifest.json` into `--out` and prints the Markdown.
pub fn write(run: &Run, scene: &Scene, paper_run: &MethodRun, prior_run: Option<&MethodRun>) -> Result<()> {
    let (args, setup, truth, n_train) = (run.args, run.setup, run.truth, run.n_train);
    let r = &paper_run.r;
    let mask = &r.model.mask;
    let hull_voxels = mask.iter().filter(|&&m| m).count();
    let rows = [hull_stats(&r.initial.data, mask), hull_stats(&r.estimated.data, mask), hull_stats(&truth.data, mask)];
    let mut csv = String::from("row,mean,max,paper_mean,paper_max\n");
    let mut md = format!(
        "# Table 1: density over the {hull_voxels} hull voxels ({}^3 grid; the paper kept 68,771 of 128^3)\n\n| | mean | max | paper mean | paper max |\n|---|---|---|---|---|\n",
        args.res
    );
    for (s, p) in rows.iter().zip(TABLE1) {
        let (name, pm, px) = (p.name, p.mean, p.max);
        let _ = writeln!(csv, "{name},{:.6},{:.6},{pm},{px}", s.mean, s.max);
        let _ = writeln!(md, "| {name} | {:.4} | {:.4} | {pm} | {px} |", s.mean, s.max);
    }
    if let Some(p) = prior_run {
        let s = hull_stats(&p.r.estimated.data, &p.r.model.mask);
        let _ = writeln!(csv, "after fitting the learned prior,{:.6},{:.6},,", s.mean, s.max);
        let _ = writeln!(md, "| after fitting the learned prior | {:.4} | {:.4} | | |", s.mean, s.max);
    }
    let runs: Vec<(&str, &MethodRun)> =
        std::iter::once(("paper's method", paper_run)).chain(prior_run.map(|p| ("learned prior", p))).collect();
    let cell = |f: &dyn Fn(&MethodRun) -> String| runs.iter().map(|(_, m)| f(m)).collect::<Vec<_>>().join(" | ");
    let pct = |v: f64| format!("{:.1} %", 100.0 * v);
    let _ = write!(
        md,
        "\n| measure | {} | target |\n|---{}|---|\n",
        runs.iter().map(|(n, _)| *n).collect::<Vec<_>>().join(" | "),
        "|---".repeat(runs.len())
    );
    let measures: [Measure; 13] = [
        ("mean-density error", &|m| pct(m.d.mass_error.abs()), "<= 2 % (paper 3.5 %)"),
        ("max-density error", &|m| pct(m.d.max_error.abs()), "<= 10 % (paper 19.5 %)"),
        ("mass error delta", &|m| format!("{:+.1} %", 100.0 * m.d.mass_error), ""),
        ("voxel relative L1 error epsilon", &|m| format!("{:.3}", m.d.rel_l1_epsilon), "<= 0.3"),
        ("Pearson r", &|m| format!("{:.3}", m.d.pearson_r), ">= 0.9"),
        ("r ceiling (truth vs truth blurred by 1 voxel)", &|m| format!("{:.3}", m.d.blur_ceiling_r), ""),
        ("2x2x2 blocks: epsilon", &|m| format!("{:.3}", m.d.block_rel_l1_epsilon), "<= 0.35 (prior)"),
        ("2x2x2 blocks: Pearson r", &|m| format!("{:.3}", m.d.block_pearson_r), ">= 0.95 (prior)"),
        ("2x2x2 blocks: max-density error", &|m| format!("{:+.1} %", 100.0 * m.d.block_max_error), "<= 10 % (prior)"),
        ("truth mass where the estimate is 0", &|m| pct(m.d.empty_truth_mass), ""),
        ("estimate mass where the truth is 0 (haze)", &|m| pct(m.d.haze_mass), ""),
        ("held-out camera 4 relative RMSE", &|m| pct(m.held), "<= 5 %"),
        ("wall time", &|m| format!("{:.0} s", m.wall_s), ""),
    ];
    for (name, f, target) in measures {
        let _ = writeln!(md, "| {name} | {} | {target} |", cell(f));
    }
    let fit = &setup.paper;
    let trained = r.trained;
    let _ = writeln!(
        md,
        "\nPaper's method: estimator `{}`, {n_train} training cameras, {} updates{}, then {} per-voxel refinement updates{} (reverse mode), {} photons and {} spp per update, decoder: {} parameters, latent 64.",
        fit.train.gradient.estimator.name(),
        trained,
        fit.train.time_budget.map_or(String::new(), |b| format!(" (time budget {b:.0} s)")),
        r.log.len() - trained,
        fit.refine.time_budget.map_or(String::new(), |b| format!(" (time budget {b:.0} s)")),
        fit.train.photons,
        fit.train.spp,
        r.model.decoder.param_count(),
    );
    if let Some(p) = prior_run {
        let f = &setup.prior.train;
        let _ = writeln!(
            md,
            "Learned prior ({}): {} updates of its latent only (`{}`, {:.0} % at half resolution, penalty {}), then {} refinement updates; decoder {} parameters, fixed. Files: `prior/`, `density_estimated_prior.npy`.",
            args.prior,
            f.iterations,
            f.gradient.estimator.name(),
            100.0 * f.coarse_fraction,
            f.latent_penalty,
            p.r.log.len() - f.iterations.min(p.r.log.len()),
            p.r.model.decoder.param_count(),
        );
    }
    let _ = writeln!(md, "Wall time {:.0} s ({} threads).", run.out.seconds(), rayon::current_num_threads());
    for (name, m) in &runs {
        let _ = write!(
            md,
            "\n## How well the estimate explains the images: {name}\n\nRelative RMSE of the estimate's image against the truth's, \
             both rendered at {} photons and {} spp with the same seed, per pixel and over pixel blocks; in brackets the \
             noise floor (the truth against itself rendered with a second seed). `fit_quality{}.csv`.\n\n{}",
            setup.fit_photons,
            setup.fit_spp,
            if m.is_prior { "_prior" } else { "" },
            fit_quality_markdown(&m.fit)
        );
    }
    let d = &paper_run.d;
    let (delta, eps, pr, held) = (d.mass_error, d.rel_l1_epsilon, d.pearson_r, paper_run.held);
    let _ = writeln!(csv, "mass_error_delta,{delta:.6},,,\nrel_l1_epsilon,{eps:.6},,,\npearson_r,{pr:.6},,,\nheld_out_rel_rmse,{held:.6},,,");
    for (suffix, m) in runs.iter().map(|(_, m)| (if m.is_prior { "_prior" } else { "" }, m)) {
        let d = &m.d;
        if m.is_prior {
            let _ = writeln!(csv, "mass_error_delta{suffix},{:.6},,,\nrel_l1_epsilon{suffix},{:.6},,,\npearson_r{suffix},{:.6},,,\nheld_out_rel_rmse{suffix},{:.6},,,", d.mass_error, d.rel_l1_epsilon, d.pearson_r, m.held);
        }
        let _ = writeln!(csv, "block_rel_l1_epsilon{suffix},{:.6},,,\nblock_pearson_r{suffix},{:.6},,,\nblock_max_error{suffix},{:.6},,,\nblur_ceiling_r{suffix},{:.6},,,\nempty_truth_mass{suffix},{:.6},,,\nhaze_mass{suffix},{:.6},,,\nwall_s{suffix},{:.1},,,", d.block_rel_l1_epsilon, d.block_pearson_r, d.block_max_error, d.blur_ceiling_r, d.empty_truth_mass, d.haze_mass, m.wall_s);
    }
    std::fs::write(args.out.join("table1.csv"), csv)?;
    std::fs::write(args.out.join("table1.md"), &md)?;
    let bars: Vec<Table1Bars> = rows
        .iter()
        .zip(TABLE1)
        .map(|(s, p)| Table1Bars {
            name: p.name.into(),
            mean: s.mean,
            max: s.max,
            paper_mean: p.mean,
            paper_max: p.max,
        })
        .collect();
    let title = format!("Table 1: ours ({}^3, {hull_voxels} hull voxels) and the paper's (128^3)", args.res);
    table1_chart(&bars, &title, &args.out.join("table1.svg"))?;
    let manifest = Manifest {
        args,
        setup,
        target_photons: scene.render.photons,
        target_spp: scene.render.spp,
        hull_voxels,
        decoder: r.model.decoder.describe(),
        decoder_parameters: r.model.decoder.param_count(),
        prior_decoder_parameters: prior_run.map(|p| p.r.model.decoder.param_count()),
    };
    run.out.write_manifest(&manifest)?;
    print!("{md}");
    Ok(())
}
