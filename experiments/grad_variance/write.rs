//! What grad_variance writes: the summary's tables and the plots.

use super::{panels, Args, Row, PARTS};
use dualphoton::error::Result;
use dualphoton::io::plot::{line_chart, Axes, Series};
use dualphoton::io::rows::markdown_table;
use rayon::current_num_threads as num_threads;
use std::path::Path;

/// The study's `summary.md`: what was measured, then one table per point and part.
pub fn summary(args: &Args, rows: &[Row], photons: u64, spp: u32, wall_s: f64) -> String {
    let Args { res, seeds, midway, reference_factor, reference_seeds, .. } = args;
    let (threads, weights) = (num_threads(), rows.iter().find(|r| r.part == PARTS[1]).map_or(0, |r| r.n));
    let mut md = format!(
        "# Gradient variance of every estimator ({res}^3 paper rig, {seeds} seeds)\n\n\
         Regenerate: `cargo run --release --bin grad_variance` ({wall_s:.0} s on {threads} threads).\n\n\
         Gradient of the training loss with respect to the 64-d latent (`latent`) and the {weights} decoder weights \
         (`weights`), at the initial parameters and after {midway} training updates (`midway`). Each seed redraws the \
         renderer's photons and pixel samples ({photons} photons, {spp} spp) and the estimator's own directions or \
         subsets. Reference: `rev-full` at {reference_factor}x photons and samples, mean of {reference_seeds} seeds.\n\n\
         - `rel. var.`: total variance over seeds / |g_ref|^2 (renderer noise + the estimator's own).\n\
         - `bias`: |mean - g_ref| / |g_ref|; `floor`: what noise alone would give (mean's and reference's standard error).\n\
         - `rel. MSE`: mean |g_hat - g_ref|^2 / |g_ref|^2 over seeds (variance + bias^2: the fair measure for biased estimators).\n\
         - `cos`: mean cosine of one estimate with g_ref; `cos(mean)`: of the mean of all seeds.\n\
         - `own noise`: E|g_hat - g|^2 / |g|^2 against `rev-full` on the same frozen paths (the estimator's \
         own noise, renderer noise excluded), next to the forward-gradient theory: (n+1)/K Gaussian, n/K - 1 orthonormal.\n\
         - `s`: median seconds per estimate (the primal render that freezes the estimator is extra); \
         `efficiency` = 1 / (rel. var. x (s + primal s)).\n",
    );
    for (point, part) in panels() {
        let sel: Vec<&Row> = rows.iter().filter(|r| r.point == point && r.part == part).collect();
        let Some(first) = sel.first() else { continue };
        md += &format!("\n## {point}, {part} (n = {}; primal render {:.2} s)\n\n", first.n, first.primal_seconds);
        let header = [
            "method",
            "rel. var.",
            "bias",
            "floor",
            "rel. MSE",
            "cos",
            "cos(mean)",
            "own noise",
            "theory",
            "s",
            "peak MiB",
            "efficiency",
        ];
        md += &markdown_table(
            &header,
            sel.iter().map(|r| {
                vec![
                    r.method.clone(),
                    format!("{:.3e}", r.rel_variance),
                    format!("{:.3}", r.bias),
                    format!("{:.3}", r.bias_floor),
                    format!("{:.3e}", r.rel_mse),
                    format!("{:.3}", r.cosine_mean),
                    format!("{:.3}", r.cosine_of_mean),
                    format!("{:.3e}", r.estimator_noise),
                    r.theory.map_or(String::new(), |t| format!("{t:.3e}")),
                    format!("{:.2}", r.seconds),
                    format!("{:.0}", r.peak_mib),
                    format!("{:.3e}", r.efficiency),
                ]
            }),
        );
    }
    md
}

/// Relative variance against cost per point and part (each estimator
/// family one line over its sizes), and the theory check.
pub fn plots(out: &Path, rows: &[Row]) -> Result<()> {
    // A method's family: the sizes of one estimator joined into one line.
    let family = |method: &str| match method.split_once(" K=") {
        _ if method.starts_with("rev-sub") => "rev-sub (subsets 1/4 to 16 x the paper's)".to_string(),
        Some((head, _)) => format!("{head} (over K)"),
        None => method.to_string(),
    };
    for (point, part) in panels() {
        let mut series: Vec<Series> = vec![];
        for r in rows.iter().filter(|r| r.point == point && r.part == part) {
            let (name, p) = (family(&r.method), (r.seconds + r.primal_seconds, r.rel_variance));
            match series.iter_mut().find(|s| s.name == name) {
                Some(s) => s.points.push(p),
                None => series.push(Series { name, points: vec![p], markers: true }),
            }
        }
        series.iter_mut().for_each(|s| s.points.sort_by(|a, b| a.0.total_cmp(&b.0)));
        let title = format!("Gradient w.r.t. the {} ({point}): variance against cost", part);
        let x = "seconds per estimate (incl. the primal render)";
        let axes = Axes { title: &title, x, y: "total variance / |g_ref|^2", log_x: true, log_y: true };
        line_chart(&out.join(format!("variance_vs_time_{}_{point}.svg", part)), &axes, &series)?;
    }
    // Theory check: measured own noise against (n+1)/K or n/K - 1.
    let random = |point: &str| -> Vec<(f64, f64)> {
        let rows = rows.iter().filter(|r| r.point == point && r.theory.is_some_and(|t| t > 0.0));
        rows.filter_map(|r| Some((r.theory?, r.estimator_noise))).collect()
    };
    let all = rows.iter().filter_map(|r| r.theory).filter(|&t| t > 0.0);
    let (lo, hi) = all.fold((f64::INFINITY, 0.0f64), |(a, b), t| (a.min(t), b.max(t)));
    let series = [
        Series { name: "fwd-rand, initial".into(), points: random("initial"), markers: true },
        Series { name: "fwd-rand, midway".into(), points: random("midway"), markers: true },
        Series { name: "theory (measured = predicted)".into(), points: vec![(lo, lo), (hi, hi)], markers: false },
    ];
    let x = "predicted E|g_hat - g|^2 / |g|^2  ((n+1)/K or n/K - 1)";
    let title = "Forward-gradient noise: measured against theory";
    let axes = Axes { title, x, y: "measured over seeds", log_x: true, log_y: true };
    line_chart(&out.join("theory_check.svg"), &axes, &series)
}
