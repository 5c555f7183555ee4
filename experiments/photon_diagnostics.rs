//! Two checks of the photon map on the paper rig, built-in plume:
//! - `orders.csv`: photon mapping against the path tracer order by order
//!   (block relative RMSE with the path tracer's noise removed, next to that
//!   noise, and the difference of the image sums);
//! - `tails.csv`: the share of camera 2's photon estimate carried by the
//!   heaviest 0.1 %, 1 % and 10 % of the photons of each order: the heavy
//!   tail that camera-guided scattering exists to cut.
//!
//! Writes `results/photon_diagnostics/{orders.csv, tails.csv, summary.md, manifest.json}`.

use clap::Parser;
use dualphoton::data::plume::plume;
use dualphoton::error::Result;
use dualphoton::eval::metrics::{reference_noise, rel_mean_diff};
use dualphoton::eval::sweep::ERROR_BLOCK;
use dualphoton::experiment::{self, Run};
use dualphoton::image::Image;
use dualphoton::io::manifest::cargo_run_line;
use dualphoton::io::rows::write_rows;
use dualphoton::render::frozen::Frozen;
use dualphoton::render::path::{render_path, PathOptions};
use dualphoton::render::render_photon;
use dualphoton::render::splat::phase_towards;
use dualphoton::scene::rig;
use serde::Serialize;
use std::fmt::Write as _;
use std::path::PathBuf;

#[derive(Parser, Serialize)]
#[command(about = "Photon mapping against the path tracer order by order, and the photon estimate's heavy tail")]
struct Args {
    /// Grid resolution (res^3) and image size (res x res).
    #[arg(long, default_value_t = 64)]
    res: usize,
    /// Seed of the plume and the renders.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Photons of the photon-mapping renders.
    #[arg(long, default_value_t = 300_000)]
    photons: u64,
    /// Samples per pixel of the path tracer, per order.
    #[arg(long, default_value_t = 4096)]
    path_spp: u32,
    /// Output directory.
    #[arg(long, default_value = "results/photon_diagnostics")]
    out: PathBuf,
    /// A tiny run, to check that everything works.
    #[arg(long)]
    smoke: bool,
}

/// One scattering order, photon mapping against the path tracer.
#[derive(Serialize)]
struct OrderRow {
    order: u32,
    path_traced_sum: f64,
    sum_rel_diff: f64,
    block_rel_rmse: f64,
    path_tracer_noise: f64,
}

/// The heavy tail of one order's photons, seen from camera 2.
#[derive(Serialize)]
struct TailRow {
    order: u8,
    photons: usize,
    top_0_1_percent: f64,
    top_1_percent: f64,
    top_10_percent: f64,
}

fn main() -> std::process::ExitCode {
    experiment::main(run)
}

fn run(mut args: Args) -> Result<()> {
    if args.smoke {
        args.res = 16;
        args.photons = 20_000;
        args.path_spp = 64;
    }
    experiment::check_res(args.res)?;
    let run = Run::start(&args.out)?;
    let mut scene = rig::paper_training_scene(plume(args.res, args.seed), args.res);
    scene.render.photons = args.photons;
    scene.render.seed = args.seed;

    let mut orders = vec![];
    let mut previous: Option<Vec<Image>> = None;
    for n in 1..=scene.medium.max_order {
        let mut s = scene.clone();
        s.medium.max_order = n;
        let up_to_n = render_photon(&s).images;
        let only_n = match &previous {
            None => up_to_n.clone(),
            Some(p) => difference(&up_to_n, p),
        };
        previous = Some(up_to_n);
        eprintln!("order {n}: path tracing at {} spp ...", args.path_spp);
        let pt = render_path(&s, &PathOptions { spp: args.path_spp, seed: 7, max_order: Some(n), min_order: n });
        orders.push(OrderRow {
            order: n,
            path_traced_sum: pt.radiance.iter().map(|i| i.data.iter().sum::<f64>()).sum(),
            sum_rel_diff: rel_mean_diff(&only_n, &pt.radiance),
            block_rel_rmse: dualphoton::eval::metrics::block_rel_rmse(
                &only_n,
                &pt.radiance,
                Some(&pt.std_err),
                ERROR_BLOCK,
            )
            .expect("a plume's path-traced order is never all black"),
            path_tracer_noise: reference_noise(&pt.radiance, &pt.std_err, ERROR_BLOCK),
        });
    }

    let frozen = Frozen::new(&scene, None);
    let camera = scene.cameras[2].position;
    let tails: Vec<TailRow> = (2..=scene.medium.max_order as u8)
        .map(|order| {
            let mut v: Vec<f64> = frozen
                .photons
                .iter()
                .filter(|p| p.order == order)
                .filter_map(|p| phase_towards(p, &camera, scene.medium.g).map(|phase| phase * p.power))
                .collect();
            v.sort_by(|a, b| b.total_cmp(a));
            let total: f64 = v.iter().sum();
            let share = |f: f64| v[..((v.len() as f64 * f) as usize).max(1).min(v.len())].iter().sum::<f64>() / total;
            TailRow {
                order,
                photons: v.len(),
                top_0_1_percent: share(0.001),
                top_1_percent: share(0.01),
                top_10_percent: share(0.1),
            }
        })
        .collect();

    write_rows(&run.path("orders.csv"), &orders)?;
    write_rows(&run.path("tails.csv"), &tails)?;
    let mut md = format!(
        "# Photon-map diagnostics ({}^3 paper rig, 4 training cameras, {} photons, default kernel)\n\n\
         | order | block rel. RMSE vs path tracer | path tracer's own noise | image-sum difference |\n|---|---|---|---|\n",
        args.res, args.photons
    );
    for o in &orders {
        let _ = writeln!(
            md,
            "| {} | {:.2} % | {:.2} % | {:+.2} % |",
            o.order,
            100.0 * o.block_rel_rmse,
            100.0 * o.path_tracer_noise,
            100.0 * o.sum_rel_diff
        );
    }
    let _ = writeln!(
        md,
        "\nShare of camera 2's photon estimate carried by the heaviest photons:\n\n| order | photons | top 0.1 % | top 1 % | top 10 % |\n|---|---|---|---|---|"
    );
    for t in &tails {
        let _ = writeln!(
            md,
            "| {} | {} | {:.1} % | {:.1} % | {:.1} % |",
            t.order,
            t.photons,
            100.0 * t.top_0_1_percent,
            100.0 * t.top_1_percent,
            100.0 * t.top_10_percent
        );
    }
    let _ = writeln!(md, "\nRegenerate: `{}` ({:.0} s).", cargo_run_line(), run.seconds());
    std::fs::write(run.path("summary.md"), &md)?;
    run.write_manifest(&args)?;
    print!("{md}");
    Ok(())
}

/// `a - b`, camera by camera: one order's images from two cumulative renders.
fn difference(a: &[Image], b: &[Image]) -> Vec<Image> {
    a.iter()
        .zip(b)
        .map(|(x, y)| Image { data: x.data.iter().zip(&y.data).map(|(p, q)| p - q).collect(), ..x.clone() })
        .collect()
}
