//! The evaluation's report: its table (per plume, then per group and
//! method) and figures (block scatter, horizontal slices).

use super::plumes::{Row, Which, ROWS};
use dualphoton::error::Result;
use dualphoton::eval::metrics::{block_mask, block_means};
use dualphoton::image::Image;
use dualphoton::io::figures::estimate_scatter;
use dualphoton::io::npy;
use dualphoton::io::panels::labelled_strip;
use std::fmt::Write as _;
use std::path::Path;

/// Per-plume rows, then per group and method the mean and the worst.
pub fn table_markdown(rows: &[Row]) -> String {
    let mut md = String::from(
        "# The learned prior against the paper's per-scene decoder\n\n\
         Block measures are over 2x2x2 blocks at least half inside the visual hull; voxel measures over the hull \
         voxels (both over the default hull, whatever hull the fit ran in); the ceiling is r of the truth against \
         itself blurred by one voxel; fit hull: the voxels the fit ran in and the fraction of the truth's mass \
         outside them; empty: the fraction of the truth's mass where the estimate is 0; haze: the fraction of the \
         estimate's mass where the truth is 0.\n\n\
         | plume | group | method | fit hull (carved mass) | block r | block eps | block max err | r (ceiling) | eps | max err | mass err | empty | haze | held-out RMSE | wall s |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        let carved = r.carved_mass.map_or("—".into(), |c| format!("{:.1} %", 100.0 * c));
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} ({}) | {:.3} | {:.3} | {:+.0} % | {:.3} ({:.3}) | {:.3} | {:+.0} % | {:+.1} % | {} | {} | {:.1} % | {:.0} |",
            r.plume,
            r.group,
            r.method,
            r.fit_hull_voxels.unwrap_or(r.hull_voxels),
            carved,
            r.block_pearson_r,
            r.block_rel_l1_epsilon,
            100.0 * r.block_max_error,
            r.pearson_r,
            r.blur_ceiling_r,
            r.rel_l1_epsilon,
            100.0 * r.max_error,
            100.0 * r.mass_error,
            r.empty_truth_mass.map_or("—".into(), |e| format!("{:.1} %", 100.0 * e)),
            r.haze_mass.map_or("—".into(), |e| format!("{:.1} %", 100.0 * e)),
            100.0 * r.held_out_rel_rmse,
            r.wall_s
        );
    }
    md += "\n## Mean (worst) per group and method\n\n\
           | group | method | plumes | block r | block eps | abs block max err | r | eps | abs mass err | held-out RMSE | wall s |\n\
           |---|---|---|---|---|---|---|---|---|---|---|\n";
    let mut groups: Vec<&str> = rows.iter().map(|r| r.group.as_str()).collect();
    groups.dedup();
    groups.sort();
    groups.dedup();
    for g in groups {
        for method in ROWS {
            let sel: Vec<&Row> = rows.iter().filter(|r| r.group == g && r.method == method).collect();
            if sel.is_empty() {
                continue;
            }
            let n = sel.len() as f64;
            let mean = |f: &dyn Fn(&Row) -> f64| sel.iter().map(|r| f(r)).sum::<f64>() / n;
            let lo = |f: &dyn Fn(&Row) -> f64| sel.iter().map(|r| f(r)).fold(f64::INFINITY, f64::min);
            let hi = |f: &dyn Fn(&Row) -> f64| sel.iter().map(|r| f(r)).fold(f64::NEG_INFINITY, f64::max);
            let both_lo = |f: &dyn Fn(&Row) -> f64| format!("{:.3} ({:.3})", mean(f), lo(f));
            let both_hi = |f: &dyn Fn(&Row) -> f64, pct: bool| {
                if pct {
                    format!("{:.1} % ({:.1} %)", 100.0 * mean(f), 100.0 * hi(f))
                } else {
                    format!("{:.3} ({:.3})", mean(f), hi(f))
                }
            };
            let _ = writeln!(
                md,
                "| {g} | {method} | {} | {} | {} | {} | {} | {} | {} | {} | {:.0} ({:.0}) |",
                sel.len(),
                both_lo(&|r| r.block_pearson_r),
                both_hi(&|r| r.block_rel_l1_epsilon, false),
                both_hi(&|r| r.block_max_error.abs(), true),
                both_lo(&|r| r.pearson_r),
                both_hi(&|r| r.rel_l1_epsilon, false),
                both_hi(&|r| r.mass_error.abs(), true),
                both_hi(&|r| r.held_out_rel_rmse, true),
                mean(&|r| r.wall_s),
                hi(&|r| r.wall_s)
            );
        }
    }
    md
}

/// The scatter of block densities (truth against each method) for the
/// first plume, and horizontal slices of truth and estimates for up to
/// three plumes, from the cached estimates (plumes without them are skipped).
pub fn figures(res: usize, out: &Path, plumes: &[Which], cache: &Path) -> Result<()> {
    let load = |which: Which, method: &str| -> Option<Vec<f64>> {
        npy::read(&cache.join(format!("{}_{method}.npy", which.name())), "estimate").ok().map(|a| a.data)
    };
    let methods =
        [("paper", "paper's method"), ("prior", "prior, latent only"), ("prior_refine", "prior + refinement")];
    if let Some(&first) = plumes.first() {
        let truth = first.truth(res)?;
        let tb = block_means(&truth.data, res);
        let estimates: Vec<(&str, Vec<f64>)> =
            methods.iter().filter_map(|(m, label)| load(first, m).map(|d| (*label, block_means(&d, res)))).collect();
        if !estimates.is_empty() {
            let occupied: Vec<bool> = tb.iter().map(|&v| v > 0.0).collect();
            let mask: Vec<bool> =
                block_mask(&vec![true; res * res * res], res).iter().zip(&occupied).map(|(a, b)| *a && *b).collect();
            let named: Vec<(&str, &[f64])> = estimates.iter().map(|(n, d)| (*n, d.as_slice())).collect();
            let title = format!("{}: 2x2x2 block density, truth vs estimates", first.name());
            estimate_scatter(&title, &tb, &named, &mask, &out.join("scatter.svg"))?;
        }
    }
    for &which in plumes.iter().take(3) {
        let truth = which.truth(res)?;
        let mut panels: Vec<(Image, String)> = vec![];
        for frac in [0.3, 0.5, 0.7] {
            let y = ((frac * res as f64) as usize).min(res - 1);
            panels.push((slice(&truth.data, res, y), format!("truth, y = {frac}")));
            for (m, label) in methods {
                if let Some(d) = load(which, m) {
                    panels.push((slice(&d, res, y), label.to_string()));
                }
            }
        }
        if panels.len() > 3 {
            let refs: Vec<(&Image, String)> = panels.iter().map(|(im, s)| (im, s.clone())).collect();
            let title = format!("{}: horizontal slices at 30, 50 and 70 % of the height (white = 0.3)", which.name());
            labelled_strip(&refs, 0.3, &title, &out.join(format!("slices_{}.svg", which.name())))?;
        }
    }
    Ok(())
}

/// The horizontal slice `y` of a `res`^3 grid as an image (x across, z down).
fn slice(d: &[f64], res: usize, y: usize) -> Image {
    let data = (0..res * res).map(|p| d[((p / res) * res + y) * res + p % res]).collect();
    Image { width: res, height: res, data }
}
