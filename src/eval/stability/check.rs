//! Running one case of the stability study: values, derivatives three ways
//! (reverse mode, forward mode, finite differences of the same frozen
//! estimator) and the energy balance of an extreme scene; both rejections
//! (in memory and from a scene file) of an invalid one.

use super::{Case, InvalidCase, Kind, Outcome, Settings};
use crate::eval::energy::energy;
use crate::grad::finite_diff::finite_difference;
use crate::grad::forward::{random_gradient, Directions};
use crate::grad::forward_at;
use crate::grad::reverse::{reverse_gradient, Subset};
use crate::image::Image;
use crate::render::frozen::Frozen;
use crate::rng::Rng;
use crate::scene::file::{load, save, validate};
use crate::scene::Scene;
use crate::volume::Grid;
use std::path::Path;
use std::time::Instant;

/// Relative error allowed between forward mode and Richardson-extrapolated
/// central differences (O(h^4)); one-sided differences (O(h^2)) get 10 times this.
pub const FD_TOL: f64 = 1e-4;
/// ... and between forward and reverse mode (the same sums in another order).
pub const FWD_REV_TOL: f64 = 1e-8;
/// Relative errors are divided by at least this share of the largest gradient entry.
pub const FLOOR: f64 = 1e-6;

/// Targets with non-zero residuals everywhere: half the image plus half its
/// mean (a constant where the image is black, so zero-density cases still
/// have a gradient).
fn targets(images: &[Image], scene: &Scene) -> Vec<Image> {
    let light: f64 = scene.lights.iter().map(|l| l.intensity).sum();
    images
        .iter()
        .map(|im| {
            let mean = im.data.iter().sum::<f64>() / im.data.len() as f64;
            let base = if mean > 0.0 { 0.5 * mean } else { 1e-3 * light };
            Image { data: im.data.iter().map(|v| 0.5 * v + base).collect(), ..im.clone() }
        })
        .collect()
}

/// Probe voxels: the centre, the densest one, one on the face towards camera 0 (deduplicated).
fn probes(d: &Grid<f64>) -> Vec<(usize, &'static str)> {
    let [nz, ny, nx] = d.shape;
    let densest = (0..d.len()).max_by(|&a, &b| d.data[a].total_cmp(&d.data[b])).unwrap_or(0);
    let mut out: Vec<(usize, &str)> = vec![];
    for (v, name) in
        [(d.index(nz / 2, ny / 2, nx / 2), "centre"), (densest, "densest"), (d.index(nz - 1, ny / 2, nx / 2), "edge")]
    {
        if !out.iter().any(|o| o.0 == v) {
            out.push((v, name));
        }
    }
    out
}

/// `|a - b| / max(|b|, floor)`, 0 when equal (infinities included).
fn relative(a: f64, b: f64, floor: f64) -> f64 {
    if a == b {
        0.0
    } else {
        (a - b).abs() / b.abs().max(floor)
    }
}

/// Checks one extreme scene: images finite and >= 0; the reverse-mode
/// gradient (every voxel) and forward-mode derivatives (probe voxels, and
/// one random-direction pass over every voxel) finite; at the probes
/// (centre, densest, edge) forward mode within [`FD_TOL`] of finite
/// differences (one-sided where the density is 0) and within
/// [`FWD_REV_TOL`] of reverse mode; the energy balance if the case asks.
pub fn check_case(case: &Case, s: &Settings) -> Outcome {
    let started = Instant::now();
    let scene = &case.scene;
    let mut row = Outcome::new(&case.name, Kind::Extreme);
    let mut notes: Vec<String> = vec![];
    if !case.note.is_empty() {
        notes.push(case.note.into());
    }
    if let Err(e) = validate(scene) {
        row.note = format!("valid scene rejected: {e}");
        return row;
    }
    let frozen = Frozen::new(scene, case.support.as_ref());
    let values_finite = frozen.images.iter().all(|im| im.data.iter().all(|v| v.is_finite() && *v >= 0.0));
    let targets = targets(&frozen.images, scene);

    let rev = reverse_gradient(&frozen, &targets, Subset::full());
    let probes = probes(&scene.density);
    let voxels: Vec<usize> = probes.iter().map(|p| p.0).collect();
    let fwd = forward_at(&frozen, &targets, &voxels, 4).unwrap_or_else(|_| vec![f64::NAN; voxels.len()]);
    let reach = frozen.reachable_voxels();
    let mut rng = Rng::from_seed(s.seed);
    let random = random_gradient::<4>(&frozen, &reach, &targets, Directions::Gaussian, &mut rng);
    let derivatives_finite = rev.loss.is_finite()
        && rev.grad.iter().all(|g| g.is_finite())
        && fwd.iter().all(|g| g.is_finite())
        && random.iter().all(|g| g.is_finite());

    // Errors relative to each entry, with a floor of FLOOR times the largest entry.
    let scale = rev.grad.iter().fold(0.0f64, |m, g| m.max(g.abs()));
    let floor = (FLOOR * scale).max(f64::MIN_POSITIVE);
    let (mut fd_err, mut fwd_rev, mut one_sided, mut zero) = (0.0f64, 0.0f64, vec![], vec![]);
    for (k, &(v, name)) in probes.iter().enumerate() {
        let fd = finite_difference(&frozen, &targets, v);
        fd_err = fd_err.max(relative(fwd[k], fd.value, floor));
        fwd_rev = fwd_rev.max(relative(fwd[k], rev.grad[v], floor));
        if fd.one_sided {
            one_sided.push(name);
        }
        if fd.value == 0.0 && fwd[k] == 0.0 {
            zero.push(name);
        }
    }
    if !one_sided.is_empty() {
        notes.push(format!("one-sided FD at density 0 ({})", one_sided.join(", ")));
    }
    if scale == 0.0 {
        notes.push("gradient is exactly 0 (nothing the cameras see depends on the density)".into());
    } else if !zero.is_empty() {
        notes.push(format!("FD and forward mode exactly 0 at {} (not seen by the cameras)", zero.join(", ")));
    }
    let fd_ok = fd_err <= if one_sided.is_empty() { FD_TOL } else { 10.0 * FD_TOL };
    let mut energy_ok = true;
    if case.energy {
        let e = energy(scene, &s.energy());
        energy_ok = e.passes(scene.medium.albedo);
        notes.push(e.describe(scene.medium.albedo));
        row.energy_in = Some(e.input);
        row.energy_single_out = Some(e.single_out);
        row.energy_single_expected = Some(e.single_expected(scene.medium.albedo));
        row.energy_out = Some(e.output);
    }
    if !values_finite {
        notes.push("image not finite or negative".into());
    }
    if !derivatives_finite {
        notes.push("derivative not finite".into());
    }
    if !fd_ok {
        notes.push(format!("forward mode differs from FD by {fd_err:.1e}"));
    }
    if fwd_rev > FWD_REV_TOL {
        notes.push(format!("forward and reverse differ by {fwd_rev:.1e}"));
    }
    row.passed = values_finite && derivatives_finite && fd_ok && fwd_rev <= FWD_REV_TOL && energy_ok;
    row.values_finite = Some(values_finite);
    row.derivatives_finite = Some(derivatives_finite);
    row.fd_rel_error = Some(fd_err);
    row.fwd_rev_error = Some(fwd_rev);
    row.seconds = started.elapsed().as_secs_f64();
    row.note = notes.join("; ");
    row
}

/// An invalid scene passes if the in-memory validation rejects it with a
/// message naming its field, and loading it from a scene file saved in
/// `scratch` (a directory of its own, removed afterwards) rejects it too.
pub fn check_invalid(case: &InvalidCase, scratch: &Path) -> Outcome {
    let started = Instant::now();
    let from_memory = validate(&case.scene);
    let from_file = save(&case.scene, scratch, "scene").and_then(|_| load(&scratch.join("scene.json")));
    let _ = std::fs::remove_dir_all(scratch);
    let mut row = Outcome::new(&case.name, Kind::Invalid);
    row.passed = matches!(&from_memory, Err(e) if e.0.contains(case.field)) && from_file.is_err();
    row.note = match (&from_memory, &from_file) {
        (Err(a), Err(b)) if a == b => a.0.clone(),
        // The scratch directory's name changes from run to run: keep it out of the report.
        (Err(a), Err(b)) => format!("{a} (file: {})", b.0.replace(&scratch.display().to_string(), "<tmp>")),
        (Ok(_), _) => "NOT rejected by scene::file::validate".into(),
        (_, Ok(_)) => "NOT rejected when loading the scene file".into(),
    };
    row.seconds = started.elapsed().as_secs_f64();
    row
}
