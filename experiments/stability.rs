//! Numerical stability on stiff and extreme cases.
//!
//! Runs the cases of [`dualphoton::eval::stability`]: small scenes each
//! pushed to one extreme (values finite, derivatives finite and equal three
//! ways, energy balanced) and invalid inputs (rejected with a message naming
//! the field, in memory and from a scene file).
//!
//! Writes `results/stability/{report.csv, summary.md, fd_error.svg,
//! manifest.json}` and exits non-zero, naming the failed cases, if any fails.

use clap::Parser;
use dualphoton::error::{Error, Result};
use dualphoton::eval::stability::{run_all, Kind, Outcome, Settings, FD_TOL, FLOOR};
use dualphoton::experiment::{self, Run};
use dualphoton::io::plot::{line_chart, Axes, Series};
use serde::Serialize;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

#[derive(Parser)]
#[command(about = "Values, derivatives and energy on stiff and extreme scenes; invalid scenes are rejected")]
struct Args {
    /// Output directory.
    #[arg(long, default_value = "results/stability")]
    out: PathBuf,
    /// Seed of every random stream (photons, pixels, gradient directions).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Smaller images, fewer photons and cameras: a quick check that the binary works.
    #[arg(long)]
    smoke: bool,
}

/// One line of report.csv (numbers to 4 significant digits, empty where not measured).
#[derive(Serialize)]
struct Row<'a> {
    case: &'a str,
    kind: &'static str,
    passed: bool,
    values_finite: Option<bool>,
    derivatives_finite: Option<bool>,
    fd_rel_error: Option<String>,
    fwd_rev_error: Option<String>,
    energy_in: Option<String>,
    energy_single_out: Option<String>,
    energy_single_expected: Option<String>,
    energy_out: Option<String>,
    seconds: String,
    note: &'a str,
}

impl<'a> From<&'a Outcome> for Row<'a> {
    fn from(o: &'a Outcome) -> Self {
        let sci = |v: Option<f64>| v.map(|x| format!("{x:.3e}"));
        Row {
            case: &o.case,
            kind: o.kind.name(),
            passed: o.passed,
            values_finite: o.values_finite,
            derivatives_finite: o.derivatives_finite,
            fd_rel_error: sci(o.fd_rel_error),
            fwd_rev_error: sci(o.fwd_rev_error),
            energy_in: sci(o.energy_in),
            energy_single_out: sci(o.energy_single_out),
            energy_single_expected: sci(o.energy_single_expected),
            energy_out: sci(o.energy_out),
            seconds: format!("{:.3}", o.seconds),
            note: &o.note,
        }
    }
}

/// What produced the report.
#[derive(Serialize)]
struct Manifest<'a> {
    settings: &'a Settings,
    smoke: bool,
    cases: usize,
    passed: usize,
}

fn main() -> std::process::ExitCode {
    experiment::main(run)
}

fn run(args: Args) -> Result<()> {
    let settings = Settings::new(args.smoke, args.seed);
    let run = Run::start(&args.out)?;
    let scratch = std::env::temp_dir().join(format!("dualphoton-stability-{}", std::process::id()));
    let rows = run_all(&settings, &scratch, &mut |r| eprintln!("{}", progress(r)));
    let seconds = run.seconds();
    write_csv(&run.path("report.csv"), &rows)?;
    plot(&run.path("fd_error.svg"), &rows)?;
    std::fs::write(run.path("summary.md"), summary(&rows, &args, &settings, seconds))?;
    let passed = rows.iter().filter(|r| r.passed).count();
    let manifest = Manifest { settings: &settings, smoke: args.smoke, cases: rows.len(), passed };
    run.write_manifest_timed(&manifest, seconds)?;
    let failed: Vec<&str> = rows.iter().filter(|r| !r.passed).map(|r| r.case.as_str()).collect();
    eprintln!("{} cases, {} failed, {seconds:.1} s; report in {}", rows.len(), failed.len(), args.out.display());
    if !failed.is_empty() {
        return Err(Error(format!("stability: failed cases: {}", failed.join("; "))));
    }
    Ok(())
}

fn progress(r: &Outcome) -> String {
    let err = r.fd_rel_error.map_or("-".into(), |e| format!("{e:.1e}"));
    format!("{:<4} {:<32} fd {err:>8} {:>6.2} s  {}", if r.passed { "ok" } else { "FAIL" }, r.case, r.seconds, r.note)
}

fn write_csv(path: &Path, rows: &[Outcome]) -> Result<()> {
    let csv_err = |e: csv::Error| Error(format!("report.csv: {e}"));
    let mut csv = csv::Writer::from_path(path).map_err(csv_err)?;
    for r in rows {
        csv.serialize(Row::from(r)).map_err(csv_err)?;
    }
    Ok(csv.flush()?)
}

fn plot(path: &Path, rows: &[Outcome]) -> Result<()> {
    let extreme: Vec<&Outcome> = rows.iter().filter(|r| r.kind == Kind::Extreme).collect();
    let point = |i: usize, e: Option<f64>| (i as f64, e.unwrap_or(f64::NAN).max(1e-16));
    let series = |name: &str, f: fn(&Outcome) -> Option<f64>| Series {
        name: name.into(),
        points: extreme.iter().enumerate().map(|(i, r)| point(i, f(r))).collect(),
        markers: true,
    };
    line_chart(
        path,
        &Axes {
            title: "Forward mode vs finite differences and reverse mode, per case (0 drawn at 1e-16)",
            x: "case (row of report.csv)",
            y: "max relative error at the probe voxels",
            log_x: false,
            log_y: true,
        },
        &[
            series("|fwd - FD| / |FD|", |r| r.fd_rel_error),
            series("|fwd - rev| / |rev|", |r| r.fwd_rev_error),
            Series {
                name: "FD tolerance".into(),
                points: vec![(0.0, FD_TOL), (extreme.len().max(2) as f64 - 1.0, FD_TOL)],
                markers: false,
            },
        ],
    )
}

fn flag(v: Option<bool>) -> String {
    v.map_or(String::new(), |b| b.to_string())
}

fn summary(rows: &[Outcome], args: &Args, s: &Settings, seconds: f64) -> String {
    let extreme = rows.iter().filter(|r| r.kind == Kind::Extreme).count();
    let passed = rows.iter().filter(|r| r.passed).count();
    let mut md = format!(
        "# Numerical stability on stiff and extreme cases\n\n\
         {passed} of {} cases pass ({extreme} extreme scenes, {} invalid inputs); {seconds:.1} s on {} threads.\n\n\
         Base scene: {g}^3 blob in the unit box, sigma_t_scale 20, albedo 0.9, g 0.6, orders 1-3, one light, \
         two {r}x{r} cameras, {p} photons, seed {seed}; each case changes one thing. \
         `fd` is the largest relative error of forward mode against Richardson-extrapolated finite differences \
         of the same frozen estimator at the probe voxels (centre, densest, edge; floor {FLOOR:.0e} of the largest \
         gradient entry; tolerance {FD_TOL:.0e}, x10 for one-sided differences at density 0), `fwd-rev` the same \
         against reverse mode. The energy check renders the case with {ec} cameras of {er}x{er} on a sphere, \
         {ep} photons and {eo} orders (see `dualphoton::eval::energy`).\n\n\
         | case | passed | values finite | derivatives finite | fd | fwd-rev | s | note |\n|---|---|---|---|---|---|---|---|\n",
        rows.len(),
        rows.len() - extreme,
        rayon::current_num_threads(),
        g = s.grid,
        r = s.res,
        p = s.photons,
        seed = s.seed,
        ec = s.energy_cameras,
        er = s.energy_res,
        ep = s.energy_photons,
        eo = s.energy_order,
    );
    let short = |v: Option<f64>| v.map_or("-".into(), |e| format!("{e:.1e}"));
    for r in rows {
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {} | {} | {:.2} | {} |",
            r.case,
            if r.passed { "yes" } else { "**NO**" },
            flag(r.values_finite),
            flag(r.derivatives_finite),
            short(r.fd_rel_error),
            short(r.fwd_rev_error),
            r.seconds,
            r.note.replace('|', "/"),
        );
    }
    md.push_str(&findings(rows));
    let _ = writeln!(
        md,
        "\nRegenerate: `cargo run --release --bin stability`{} (writes report.csv, fd_error.svg, this file, manifest.json).",
        if args.smoke { " -- --smoke" } else { "" }
    );
    md
}

/// What the table shows, from its numbers.
fn findings(rows: &[Outcome]) -> String {
    let extreme: Vec<&Outcome> = rows.iter().filter(|r| r.kind == Kind::Extreme).collect();
    let worst = |f: &dyn Fn(&Outcome) -> Option<f64>| {
        extreme.iter().filter_map(|r| f(r).map(|e| (e, r.case.as_str()))).fold((0.0, "-"), |a, b| {
            if b.0 > a.0 {
                b
            } else {
                a
            }
        })
    };
    let (fd, fd_case) = worst(&|r| r.fd_rel_error);
    let (fr, fr_case) = worst(&|r| r.fwd_rev_error);
    let (slow, slow_case) = worst(&|r| Some(r.seconds));
    let finite = extreme.iter().all(|r| r.values_finite == Some(true) && r.derivatives_finite == Some(true));
    let invalid = rows.len() - extreme.len();
    let rejected = rows.iter().filter(|r| r.kind == Kind::Invalid && r.passed).count();
    let mut out = String::from("\n## What it shows\n\n");
    let _ = writeln!(
        out,
        "- Values and derivatives (reverse mode on every voxel, forward mode at the probes and in one random-direction \
         pass over every voxel) are {} in every extreme case.",
        if finite { "finite (images >= 0)" } else { "**not** finite" }
    );
    let _ = writeln!(
        out,
        "- Forward mode matches finite differences of the frozen estimator to {fd:.1e} at worst ({fd_case}) and \
         reverse mode to {fr:.1e} ({fr_case}): the frozen estimator stays smooth and its derivatives exact \
         from a nearly transparent medium (sigma_t_scale 1e-12) to optical depth 1e4, on grids from 1^3 to \
         4x8x16, with or without photons."
    );
    for r in extreme.iter().filter(|r| r.energy_in.is_some()) {
        let (input, out_all) = (r.energy_in.unwrap_or(0.0), r.energy_out.unwrap_or(0.0));
        let (single, expected) = (r.energy_single_out.unwrap_or(0.0), r.energy_single_expected.unwrap_or(0.0));
        let _ = writeln!(
            out,
            "- Energy, {}: {input:.4} W enter a first collision; single scattering leaves {single:.4} W against \
             {expected:.4} W expected (first-scattered minus second-collision power); all orders leave {out_all:.4} W.",
            r.case
        );
    }
    let _ = writeln!(
        out,
        "- The all-orders balance carries the photon kernel's bias: emission blurred from dense voxels into thinner \
         ones escapes more easily (a few % too much light at 8^3, less on finer grids), and in a medium much thicker \
         than a voxel (optical depth 1e2: 12.5 per voxel, mean free path 0.01 against voxels of 0.125) most \
         photons collide within a mean free path of the surface but the estimate spreads their emission over the \
         outer voxel, of which the cameras see only the first mean free path: too little light leaves there (set albedo 1 \
         in that case and 0.32 of the input leaves against at least 0.61 that must; a resolution limit of the \
         grid estimate, so the table checks only the upper bound at albedo 0.9). The single-scattering \
         balance, which involves no kernel, holds to about 1%.\n\
         - {rejected} of {invalid} invalid inputs are rejected, in memory and from a scene file, with a message naming the field \
         (non-finite numbers cannot be written in JSON, so the file path rejects them as `null`).\n\
         - Slowest case: {slow_case} ({slow:.2} s)."
    );
    out
}
