//! Many independent estimates of the parameter gradient, for studying
//! estimators: every setting on the same frozen renders (one per seed), and
//! a high-sample `rev-full` reference. The statistics are `eval::stats`'.

use super::estimator::{parameter_gradient, Estimator, EstimatorSettings, ParamGradient};
use super::level::Level;
use crate::error::Result;
use crate::eval::stats::median;
use crate::grad::forward::Directions;
use crate::io::manifest::{peak_memory_mib, reset_peak_memory};
use crate::model::Model;
use crate::render::frozen::Frozen;
use crate::rng::{Purpose, Rng};
use std::time::Instant;

/// Per-seed estimates of one setting.
#[derive(Default)]
pub struct Samples {
    /// One dense estimate per seed with respect to the latent (empty when left out).
    pub latent: Vec<Vec<f64>>,
    /// The same for the decoder weights.
    pub weights: Vec<Vec<f64>>,
    /// Seconds per estimate, one per seed.
    pub seconds: Vec<f64>,
    /// The largest resident memory seen while estimating, MiB.
    pub peak_mib: f64,
}

impl Samples {
    fn push(&mut self, g: &ParamGradient, model: &Model) {
        self.latent.extend(g.latent.to_dense(model.z.len()));
        self.weights.extend(g.weights.to_dense(model.w.len()));
    }

    /// The estimates of one part: 0 the latent, 1 the weights.
    pub fn part(&self, p: usize) -> &[Vec<f64>] {
        [&self.latent, &self.weights][p]
    }
}

/// What [`sample_estimators`] measured.
pub struct Study {
    /// One entry per setting, in the order given.
    pub samples: Vec<Samples>,
    /// The reference: `rev-full` at more photons and samples, one estimate per reference seed.
    pub reference: Samples,
    /// Median seconds of the primal render that freezes each seed's estimator.
    pub primal_seconds: f64,
}

/// `seeds` estimates of every setting in `settings` at `model` (seed `i`
/// freezes one render shared by all settings), and `reference_seeds`
/// estimates by `rev-full` at `reference_factor` times the photons and
/// pixel samples. `seed` offsets every draw; `progress` hears each finished seed.
pub fn sample_estimators(
    level: &Level,
    model: &Model,
    settings: &[EstimatorSettings],
    seeds: usize,
    reference: (usize, u32),
    seed: u64,
    progress: &mut dyn FnMut(&str),
) -> Result<Study> {
    let decoded = model.density(&level.scene.density);
    let render = &level.scene.render;
    let (reference_seeds, f) = reference;

    let mut refs = Samples::default();
    let rev_full = EstimatorSettings { estimator: Estimator::RevFull, ..Default::default() };
    for r in 0..reference_seeds {
        let s = level.scene_at(&decoded, render.photons * f as u64, render.spp * f, 1_000_000 + seed * 1000 + r as u64);
        let frozen = Frozen::new(&s, Some(&level.support));
        refs.push(&parameter_gradient(level, model, &frozen, &rev_full, &mut Rng::from_seed(0))?, model);
        progress(&format!("reference {}/{reference_seeds}", r + 1));
    }

    let mut samples: Vec<Samples> = settings.iter().map(|_| Samples::default()).collect();
    let mut primal = vec![];
    for s in 0..seeds {
        let t = Instant::now();
        let seed = seed * 1000 + s as u64;
        let sc = level.scene_at(&decoded, render.photons, render.spp, seed);
        let frozen = Frozen::new(&sc, Some(&level.support));
        primal.push(t.elapsed().as_secs_f64());
        for (i, (setting, smp)) in settings.iter().zip(&mut samples).enumerate() {
            let mut rng = Rng::new(seed, Purpose::Gradient, 7_000 + i as u64);
            reset_peak_memory();
            let t = Instant::now();
            let g = parameter_gradient(level, model, &frozen, setting, &mut rng)?;
            smp.seconds.push(t.elapsed().as_secs_f64());
            smp.peak_mib = smp.peak_mib.max(peak_memory_mib());
            smp.push(&g, model);
        }
        progress(&format!("seed {}/{seeds}", s + 1));
    }
    Ok(Study { samples, reference: refs, primal_seconds: median(&primal) })
}

/// The settings the gradient-variance study compares, by label: `rev-full`;
/// `rev-sub` at 1/4, 1, 4 and 16 times `px` pixels and `paths` photon paths
/// (the paper's subset second); `fwd-full` for the latent; `fwd-rand` with
/// Gaussian and orthonormal directions; the weights alone by random and by
/// guided directions. Each gives the latent's gradient, the weights' or
/// (reverse mode) both.
pub fn compared_settings(px: usize, paths: usize) -> Vec<(String, EstimatorSettings)> {
    use Directions::{Gaussian, Orthonormal};
    let s = EstimatorSettings { weight_directions: 0, ..EstimatorSettings::default() };
    let (sub, rand) = (
        EstimatorSettings { estimator: Estimator::RevSub, ..s },
        EstimatorSettings { estimator: Estimator::FwdRand, ..s },
    );
    let kind = |d| if d == Gaussian { "gaussian" } else { "orthonormal" };
    let mut m = vec![("rev-full".to_string(), EstimatorSettings { estimator: Estimator::RevFull, ..s })];
    for (p, q) in [(px / 4, paths / 4), (px, paths), (px * 4, paths * 4), (px * 16, paths * 16)] {
        m.push((format!("rev-sub {p}px/{q}paths"), EstimatorSettings { subset_pixels: p, subset_paths: q, ..sub }));
    }
    m.push(("fwd-full".into(), s));
    for (k, d) in [(1, Gaussian), (4, Gaussian), (8, Gaussian), (16, Gaussian), (4, Orthonormal), (16, Orthonormal)] {
        m.push((format!("fwd-rand {} K={k}", kind(d)), EstimatorSettings { lanes: k, directions: d, ..rand }));
    }
    // The weights alone (guided is fwd-full's default weight mode).
    for (k, d) in [(1, Gaussian), (16, Gaussian), (16, Orthonormal)] {
        let w = EstimatorSettings { latent: false, weight_directions: k, lanes: 16.min(k), directions: d, ..rand };
        m.push((format!("fwd-rand {} K={k}", kind(d)), w));
    }
    for k in [8, 16] {
        let w = EstimatorSettings { latent: false, weight_directions: k, lanes: 16.min(k), ..s };
        m.push((format!("fwd-guided K={k}"), w));
    }
    m
}

/// The forward-gradient theory's added noise `E|g_hat - g|^2 / |g|^2` over
/// `n` parameters: `(n+1)/K` for Gaussian directions, `n/K - 1` for
/// orthonormal ones, 0 for exact ones; `None` where it has no prediction.
pub fn forward_gradient_theory(s: &EstimatorSettings, n: usize) -> Option<f64> {
    let k = (if s.latent { s.lanes } else { s.weight_directions }) as f64;
    match (s.estimator, s.directions) {
        (Estimator::FwdRand, Directions::Gaussian) => Some((n as f64 + 1.0) / k),
        (Estimator::FwdRand, Directions::Orthonormal) => Some(n as f64 / k - 1.0),
        (Estimator::FwdFull, _) if s.latent && s.weight_directions == 0 => Some(0.0),
        _ => None,
    }
}
