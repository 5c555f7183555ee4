//! Part 1 of error_vs_time: every estimator's reconstruction under the same wall-clock budgets.

use super::Args;
use dualphoton::error::Result;
use dualphoton::eval::metrics::{pearson, rel_l1, rel_rmse};
use dualphoton::grad::Estimator;
use dualphoton::io::plot::{line_chart, Axes, Series};
use dualphoton::recon::methods::Method;
use dualphoton::recon::problem::{paper_problem, PaperProblem, Problem};
use dualphoton::recon::reconstruct::{reconstruct, ReconstructSettings, Reconstruction};
use dualphoton::scene::rig;
use std::fmt::Write as _;

/// Caps the updates of a run that its time budgets stop.
const UPDATE_CAP: usize = 1_000_000;

/// Part 1: every estimator fits with the main job's settings under the same
/// wall-clock budgets (training, then the refinement, which is reverse mode for all).
pub fn reconstruction(args: &Args, estimators: &[Estimator], summary: &mut String) -> Result<()> {
    let target_photons = if args.smoke { 20_000 } else { 1_000_000 };
    eprintln!("rendering the targets ...");
    let PaperProblem { truth, scene, images } = paper_problem(args.res, args.seed, target_photons, 0);
    let (targets, held_out) = images.split_at(rig::HELD_OUT_CAMERA);
    let problem = Problem { scene: &scene, targets, held_out, truth: Some(&truth) };

    let mut log = String::from("estimator,iteration,phase,wall_s,train_loss,held_out_rel_rmse,density_rel_l1\n");
    let mut finals =
        String::from("estimator,updates,refine_updates,seconds,density_rel_l1,pearson_r,held_out_rel_rmse\n");
    let (mut eps_series, mut held_series) = (vec![], vec![]);
    let _ = writeln!(
        summary,
        "## Reconstruction under a {:.0} s + {:.0} s budget per estimator\n\n\
         The main job's problem, seed, initial model and fitting (`experiment_table1 --prior none`), each estimator \
         training for {:.0} s (the first 80 % of it at half resolution), then the same per-voxel refinement (reverse \
         mode, whatever the estimator) for {:.0} s. The per-update held-out error comes from that update's own quick \
         render (50,000 photons, 2 spp, half resolution in the coarse phase), so it carries render noise; the final \
         columns re-render the estimate with {target_photons} photons at 8 spp.\n\n\
         | estimator | training updates | refinement updates | final epsilon | final Pearson r | final held-out rel. RMSE |\n\
         |---|---|---|---|---|---|",
        args.budget, args.refine_budget, args.budget, args.refine_budget
    );
    for &estimator in estimators {
        let result = within_budgets(&problem, args, estimator, target_photons)?;
        let rows = &result.log;
        let (trained, refined) = (result.trained, rows.len() - result.trained);
        for (i, r) in rows.iter().enumerate() {
            let phase = if i < trained { "train" } else { "refine" };
            let _ = writeln!(
                log,
                "{},{},{phase},{:.3},{:.6e},{:.6},{:.6}",
                estimator.name(),
                r.iteration,
                r.wall_s,
                r.train_loss,
                r.held_out_rel_rmse,
                r.density_rel_l1
            );
        }
        let estimated = &result.estimated;
        let eps = rel_l1(&estimated.data, &truth.data, &result.model.mask)
            .expect("a plume and its images are never all zero");
        let r = pearson(&truth.data, &estimated.data, &result.model.mask);
        let held = rel_rmse(&result.final_images[rig::HELD_OUT_CAMERA].data, &held_out[0].data)
            .expect("a plume and its images are never all zero");
        let seconds = rows.last().map_or(0.0, |r| r.wall_s);
        let _ = writeln!(finals, "{},{trained},{refined},{seconds:.2},{eps:.6},{r:.6},{held:.6}", estimator.name());
        let _ = writeln!(
            summary,
            "| `{}` | {trained} | {refined} | {eps:.3} | {r:.3} | {:.1} % |",
            estimator.name(),
            100.0 * held
        );
        eps_series.push(Series {
            name: estimator.name().into(),
            points: rows.iter().map(|r| (r.wall_s, r.density_rel_l1)).collect(),
            markers: false,
        });
        held_series.push(Series {
            name: estimator.name().into(),
            points: rows.iter().map(|r| (r.wall_s, 100.0 * r.held_out_rel_rmse)).collect(),
            markers: false,
        });
    }
    std::fs::write(args.out.join("reconstruction.csv"), log)?;
    std::fs::write(args.out.join("reconstruction_final.csv"), finals)?;
    plots(args, &eps_series, &held_series)?;
    Ok(())
}

/// `estimator` trains with the main job's method for `args.budget` seconds,
/// then the refinement runs for `args.refine_budget`: the budgets stop both
/// parts, the update counts are only caps.
fn within_budgets(problem: &Problem, args: &Args, estimator: Estimator, target_photons: u64) -> Result<Reconstruction> {
    let mut method = Method::paper().seeded(args.seed);
    method.train.gradient.estimator = estimator;
    (method.train.iterations, method.train.time_budget) = (UPDATE_CAP, Some(args.budget));
    method.refine.updates = if args.refine_budget > 0.0 { UPDATE_CAP } else { 0 };
    method.refine.time_budget = (args.refine_budget > 0.0).then_some(args.refine_budget);
    let settings = ReconstructSettings::new(method, target_photons, 8);
    let result = reconstruct(problem, &settings, &mut |p| {
        eprint!(
            "\r{}: update {}  {:.0}/{:.0} s  eps {:.3}   ",
            estimator.name(),
            p.row.iteration + 1,
            p.row.wall_s,
            args.budget + args.refine_budget,
            p.row.density_rel_l1
        );
    })?;
    eprintln!();
    Ok(result)
}

/// The density error and the held-out error against time, one line per estimator.
fn plots(args: &Args, eps_series: &[Series], held_series: &[Series]) -> Result<()> {
    let axes = |title, y| Axes { title, x: "wall-clock time (s, 2 cores)", y, log_x: false, log_y: true };
    line_chart(
        &args.out.join("reconstruction_epsilon.svg"),
        &axes("Density error against fitting time", "voxel relative L1 error epsilon"),
        eps_series,
    )?;
    line_chart(
        &args.out.join("reconstruction_held_out.svg"),
        &axes("Held-out camera error against fitting time", "held-out relative RMSE (%, per-update render)"),
        held_series,
    )?;
    Ok(())
}
