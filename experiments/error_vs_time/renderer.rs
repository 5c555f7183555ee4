//! Part 2 of error_vs_time: the renderers' error against render time.

use super::Args;
use dualphoton::error::Result;
use dualphoton::eval::metrics::reference_noise;
use dualphoton::eval::reference::reference;
use dualphoton::eval::sweep::{error, photon_sweep, ERROR_BLOCK};
use dualphoton::io::plot::{line_chart, Axes, Series};
use dualphoton::io::rows::write_rows;
use dualphoton::render::path::{render_path, PathOptions};
use dualphoton::scene::rig;
use serde::Serialize;
use std::fmt::Write as _;
use std::time::Instant;

/// One renderer configuration: photon mapping or the path tracer.
#[derive(Serialize)]
struct RendererRow {
    method: &'static str,
    photons: Option<u64>,
    radius_voxels: Option<f64>,
    spp: u32,
    seconds: f64,
    block_rel_rmse: f64,
}

/// Part 2: photon mapping over photon counts and radii, and the path tracer, against the reference.
pub fn renderer(args: &Args, summary: &mut String) -> Result<()> {
    let scene = rig::paper_training_scene(dualphoton::data::plume::plume(args.res, args.seed), args.res);
    eprintln!("renderer: reference at {} spp ({})", args.ref_spp, args.reference_dir.display());
    let reference = reference(&scene, args.seed, args.ref_spp, &args.reference_dir)?;
    let noise = reference_noise(&reference.radiance, &reference.std_err, ERROR_BLOCK);
    let _ = writeln!(
        summary,
        "\n## Renderer error against render time\n\n\
         Block (4x4) relative RMSE of the 4 training cameras against a {} spp path-traced reference (its own noise, \
         {:.2} %, removed). Photon mapping uses {} spp at the camera; time is the median of {} renders.\n\n\
         | method | photons | radius (voxels) | spp | time (s) | block rel. RMSE |\n|---|---|---|---|---|---|",
        args.ref_spp,
        100.0 * noise,
        scene.render.spp,
        args.repeats
    );
    let spp = scene.render.spp;
    let points = photon_sweep(&scene, &reference, &args.photons, &args.radii, |_| args.repeats);
    let mut rows: Vec<RendererRow> = points
        .iter()
        .map(|p| RendererRow {
            method: "photon",
            photons: Some(p.photons),
            radius_voxels: Some(p.radius_voxels),
            spp,
            seconds: p.seconds,
            block_rel_rmse: p.block_rel_rmse,
        })
        .collect();
    for &spp in &args.path_spp {
        let opts = PathOptions { spp, seed: 99, max_order: None, min_order: 1 };
        let t = Instant::now();
        let r = render_path(&scene, &opts);
        let seconds = t.elapsed().as_secs_f64();
        let block_rel_rmse = error(&r.radiance, &reference);
        eprintln!("  path tracing: {spp} spp: {seconds:.3} s, {:.2} %", 100.0 * block_rel_rmse);
        rows.push(RendererRow { method: "path", photons: None, radius_voxels: None, spp, seconds, block_rel_rmse });
    }
    for r in &rows {
        let (name, opt) = (if r.method == "path" { "path tracing" } else { "photon mapping" }, |v: Option<String>| {
            v.unwrap_or_default()
        });
        let _ = writeln!(
            summary,
            "| {name} | {} | {} | {} | {:.3} | {:.2} % |",
            opt(r.photons.map(|p| p.to_string())),
            opt(r.radius_voxels.map(|v| v.to_string())),
            r.spp,
            r.seconds,
            100.0 * r.block_rel_rmse
        );
    }
    let mut series: Vec<Series> = args
        .radii
        .iter()
        .map(|radius| Series {
            name: format!("photon mapping, r = {radius} vox"),
            points: rows
                .iter()
                .filter(|r| r.radius_voxels == Some(*radius))
                .map(|r| (r.seconds, 100.0 * r.block_rel_rmse))
                .collect(),
            markers: true,
        })
        .collect();
    series.push(Series {
        name: "path tracing (unbiased)".into(),
        points: rows.iter().filter(|r| r.method == "path").map(|r| (r.seconds, 100.0 * r.block_rel_rmse)).collect(),
        markers: true,
    });
    write_rows(&args.out.join("renderer.csv"), &rows)?;
    line_chart(
        &args.out.join("renderer_error_vs_time.svg"),
        &Axes {
            title: "Renderer error against render time",
            x: "render time (s, 2 cores)",
            y: "block relative RMSE vs reference (%)",
            log_x: true,
            log_y: true,
        },
        &series,
    )
}
