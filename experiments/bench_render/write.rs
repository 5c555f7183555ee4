//! What bench_render writes: the summary's tables, the CSV files and the plot.

use super::rows::{BlurredRow, ShadowRow, Tables};
use dualphoton::error::Result;
use dualphoton::experiment::Run;
use dualphoton::io::plot::{line_chart, Axes, Series};
use dualphoton::io::rows::write_rows;
use std::fmt::Write as _;

/// The blurred plumes' table (nothing without blurred plumes).
pub fn blurred_table(summary: &mut String, blurred: &[BlurredRow]) {
    if blurred.is_empty() {
        return;
    }
    let _ = writeln!(
        summary,
        "## Blurred plumes: the built-in one blurred, seen by all 5 cameras (defaults, medians)\n\n\
         Blur 0 is the built-in plume itself seen by the 4 training cameras, the render of `timing.csv`.\n\n\
         | res | blur (voxels at 64^3) | occupied | cameras | tracing / gathering / light-depth grids / camera (s) | total (s) |\n\
         |---|---|---|---|---|---|"
    );
    for b in blurred {
        let _ = writeln!(
            summary,
            "| {} | {} | {:.0} % | {} | {:.3} / {:.3} / {:.3} / {:.3} | {:.3} |",
            b.res,
            b.blur_voxels,
            100.0 * b.occupied,
            b.cameras,
            b.trace_s,
            b.gather_s,
            b.shadows_s,
            b.camera_s,
            b.total_s
        );
    }
    summary.push('\n');
}

/// The light-depth grids against marched shadow rays.
pub fn shadows_table(summary: &mut String, shadows: &[ShadowRow]) {
    let _ = writeln!(
        summary,
        "## The lights' transmittance: light-depth grids against marched shadow rays\n\n\
         Same photons in every row of a scene; the reference has the same orders. \
         Against marched: the block relative RMSE between the row's render and the marched shadow rays' (the \
         transmittance's own error).\n\n\
         | scene | res | cameras | orders | shadows | voxels per node | time (s) | grids + camera rays (s) | block rel. RMSE | image-sum diff | against marched |\n\
         |---|---|---|---|---|---|---|---|---|---|---|"
    );
    for r in shadows {
        let _ = writeln!(
            summary,
            "| {} | {} | {} | {} | {} | {} | {:.3} | {:.3} | {:.2} % | {:+.2} % | {:.2} % |",
            r.scene,
            r.res,
            r.cameras,
            r.orders,
            r.shadows,
            if r.voxels_per_node == 0 { "-".to_string() } else { r.voxels_per_node.to_string() },
            r.total_s,
            r.grids_and_camera_s,
            100.0 * r.block_rel_rmse,
            100.0 * r.mean_rel_diff,
            100.0 * r.vs_marched
        );
    }
    summary.push('\n');
}

/// The CSV files (those with rows) and the error-against-time plot of `series`.
pub fn files(run: &Run, t: &Tables, series: &[Series]) -> Result<()> {
    write_rows(&run.path("shadows.csv"), &t.shadows)?;
    if !t.blurred.is_empty() {
        write_rows(&run.path("blurred.csv"), &t.blurred)?;
    }
    if t.timing.is_empty() {
        return Ok(());
    }
    write_rows(&run.path("timing.csv"), &t.timing)?;
    write_rows(&run.path("sweep.csv"), &t.sweep)?;
    line_chart(
        &run.path("error_vs_time.svg"),
        &Axes {
            title: "Photon mapping: error against render time (photon count swept)",
            x: "render time (s, 2 cores)",
            y: "block relative RMSE vs path tracer (%)",
            log_x: true,
            log_y: true,
        },
        series,
    )
}

/// This run's options as typed (` -- OPTIONS`, or nothing), for the summary's command.
pub fn command_options() -> String {
    let options: Vec<String> = std::env::args().skip(1).collect();
    if options.is_empty() {
        String::new()
    } else {
        format!(" -- {}", options.join(" "))
    }
}
