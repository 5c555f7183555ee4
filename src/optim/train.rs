//! The training loop (issue 4): a 64-d latent and a small decoder produce
//! the density inside the visual hull; Adam minimises the image MSE of the
//! training cameras. Each update re-traces the photons with a fresh seed
//! (detached sampling at the current density), so the noise averages out
//! over iterations.
//!
//! Gradients per estimator:
//! - `fwd-full` (default): the latent's gradient is exact, from 64
//!   coordinate directions through decoder and renderer in chunks of K dual
//!   lanes; the decoder weights get `weight_directions` directional
//!   derivatives per update ([`WeightDirections`]).
//! - `fwd-rand`: K random directions for the latent and for the weights.
//! - `rev-full` / `rev-sub`: reverse mode through the renderer (the paper's
//!   approximate learning for `rev-sub`), then the decoder's own
//!   vector-Jacobian product: exact (or unbiased) for latent and weights.

use crate::ad::dual::with_tangents;
use crate::ad::Real;
use crate::error::Result;
use crate::grad::forward::{directional, random_directions, Directions};
use crate::grad::loss::mse;
use crate::grad::reverse::{reverse_gradient, Subset};
use crate::grad::Estimator;
use crate::model::Decoder;
use crate::optim::adam::Adam;
use crate::render::frozen::Frozen;
use crate::render::Image;
use crate::rng::{Purpose, Rng};
use crate::scene::Scene;
use crate::volume::Grid;
use num_dual::DualSVec64;
use std::time::Instant;

/// How the decoder weights get their directional derivatives in forward mode.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WeightDirections {
    /// Exact partial derivatives of a block of weights, cycling through all of them.
    Coordinates,
    /// Random orthonormal directions; the step uses the projection of the
    /// gradient onto their span (scaled to be unbiased: `n/K Σ (g·q) q`).
    Orthonormal,
    /// A guessed direction first, then random ones, orthonormalised; the
    /// step is the exact projection of the gradient onto their span
    /// (`Σ (g·q) q`: biased, but always a descent direction). The guess is
    /// the decoder's vector-Jacobian product of the image residuals
    /// back-projected along the camera rays (attenuated, not differentiated
    /// through the renderer): cheap, and far better aligned with the
    /// gradient than a random direction in 31,000 dimensions.
    Guided,
}

/// Everything a training run is set up with.
#[derive(Clone, Debug)]
pub struct TrainSettings {
    /// Adam updates.
    pub iterations: usize,
    /// Gradient estimator.
    pub estimator: Estimator,
    /// Dual lanes per forward pass (1, 2, 4, 8 or 16).
    pub lanes: usize,
    /// Directions for the decoder weights per update (forward estimators; 0 freezes the weights).
    pub weight_directions: usize,
    /// How those directions are chosen.
    pub weight_mode: WeightDirections,
    /// Adam step for the latent.
    pub lr_latent: f64,
    /// Adam step for the decoder weights.
    pub lr_weights: f64,
    /// Photons per update (the images of the targets may use more).
    pub photons: u64,
    /// Camera samples per pixel per update.
    pub spp: u32,
    /// `rev-sub`: pixels and photon paths differentiated per update.
    pub subset_pixels: usize,
    /// `rev-sub`: photon paths differentiated per update.
    pub subset_paths: usize,
    /// Seed of everything random in training.
    pub seed: u64,
    /// Share of the updates made at half resolution (grid and images pooled
    /// 2x) before the full resolution: coarse to fine, about 6x cheaper per update.
    pub coarse_fraction: f64,
}

impl Default for TrainSettings {
    fn default() -> Self {
        TrainSettings {
            iterations: 250,
            estimator: Estimator::FwdFull,
            lanes: 16,
            weight_directions: 8,
            weight_mode: WeightDirections::Guided,
            lr_latent: 0.05,
            lr_weights: 0.01,
            photons: 50_000,
            spp: 2,
            subset_pixels: 1000,
            subset_paths: 5000,
            seed: 0,
            coarse_fraction: 0.8,
        }
    }
}

/// The parameters being learned.
#[derive(Clone, Debug)]
pub struct Model {
    /// The decoder architecture.
    pub decoder: Decoder,
    /// Latent code.
    pub z: Vec<f64>,
    /// Decoder weights.
    pub w: Vec<f64>,
    /// Voxels that may hold smoke (the visual hull).
    pub mask: Vec<bool>,
}

impl Model {
    /// Shape of the decoder's grid.
    pub fn decoder_shape(&self) -> [usize; 3] {
        let r = self.decoder.res();
        [r, r, r]
    }

    /// The density grid on `like`'s geometry.
    pub fn density(&self, like: &Grid<f64>) -> Grid<f64> {
        Grid::new(like.lo, like.hi, like.shape, self.decoder.forward(&self.z, &self.w, &self.mask))
    }
}

/// One line of the training log.
#[derive(Clone, Debug, Default)]
pub struct LogRow {
    /// Update number (0-based; the row is measured before the update).
    pub iteration: usize,
    /// Training MSE (this update's render).
    pub train_loss: f64,
    /// MSE of the held-out camera, if any.
    pub held_out_loss: f64,
    /// Relative RMSE of the held-out image.
    pub held_out_rel_rmse: f64,
    /// Relative L1 density error over the hull, if the ground truth is known.
    pub density_rel_l1: f64,
    /// Mean density over the hull.
    pub mean_density: f64,
    /// Max density over the hull.
    pub max_density: f64,
    /// Seconds since the start of training.
    pub wall_s: f64,
}

/// What the training loop needs to know about the problem.
pub struct Problem<'a> {
    /// The scene: training cameras first, then held-out ones; its density is replaced every update.
    pub scene: &'a Scene,
    /// Target images of the training cameras (the first `targets.len()` cameras).
    pub targets: &'a [Image],
    /// Target images of the remaining (held-out) cameras.
    pub held_out: &'a [Image],
    /// Ground-truth density, for the log only.
    pub truth: Option<&'a Grid<f64>>,
}

/// Relative L1 error `|a - b|_1 / |b|_1` over the masked voxels.
pub fn rel_l1(a: &[f64], b: &[f64], mask: &[bool]) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for i in 0..a.len() {
        if mask[i] {
            num += (a[i] - b[i]).abs();
            den += b[i].abs();
        }
    }
    if den == 0.0 {
        0.0
    } else {
        num / den
    }
}

/// Relative RMSE of `ours` against `reference`.
pub fn rel_rmse(ours: &[f64], reference: &[f64]) -> f64 {
    let num: f64 = ours.iter().zip(reference).map(|(a, b)| (a - b).powi(2)).sum();
    let den: f64 = reference.iter().map(|b| b * b).sum();
    if den == 0.0 {
        0.0
    } else {
        (num / den).sqrt()
    }
}

/// One resolution the loop renders at.
struct Level {
    /// Scene at this resolution (its density is replaced every update).
    scene: Scene,
    /// Training targets at this resolution.
    targets: Vec<Image>,
    /// Held-out targets at this resolution.
    held_out: Vec<Image>,
    /// True if densities are the decoder's grid averaged over 2x2x2 blocks.
    pooled: bool,
    /// Where the density may be non-zero (the hull, pooled like the density).
    support: Grid<f64>,
}

impl Level {
    fn full(problem: &Problem, mask: &[bool]) -> Level {
        let d = &problem.scene.density;
        let support = Grid::new(d.lo, d.hi, d.shape, mask.iter().map(|&m| f64::from(u8::from(m))).collect());
        Level {
            scene: problem.scene.clone(),
            targets: problem.targets.to_vec(),
            held_out: problem.held_out.to_vec(),
            pooled: false,
            support,
        }
    }

    /// Half resolution, or `None` if a grid or image edge is odd or too small.
    fn half(problem: &Problem, mask: &[bool]) -> Option<Level> {
        let full = Level::full(problem, mask);
        let even = |n: usize| n % 2 == 0 && n >= 8;
        if !full.scene.density.shape.iter().all(|&n| even(n))
            || !full.scene.cameras.iter().all(|c| even(c.width) && even(c.height))
        {
            return None;
        }
        let mut scene = full.scene.clone();
        scene.density = pool(&full.scene.density);
        for c in &mut scene.cameras {
            c.width /= 2;
            c.height /= 2;
        }
        let support = pool(&full.support);
        Some(Level {
            scene,
            targets: full.targets.iter().map(halve).collect(),
            held_out: full.held_out.iter().map(halve).collect(),
            pooled: true,
            support,
        })
    }

    /// The density this level renders, from the decoder's grid values.
    fn grid<R: Real>(&self, fine: Grid<R>) -> Grid<R> {
        if self.pooled {
            pool(&fine)
        } else {
            fine
        }
    }

    /// `dL/d(decoder grid)` from `dL/d(this level's grid)`.
    fn pull_back(&self, grad: Vec<f64>, fine_shape: [usize; 3]) -> Vec<f64> {
        if !self.pooled {
            return grad;
        }
        let [nz, ny, nx] = fine_shape;
        let (cy, cx) = (ny / 2, nx / 2);
        let mut out = vec![0.0; nz * ny * nx];
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    out[(k * ny + j) * nx + i] = grad[((k / 2) * cy + j / 2) * cx + i / 2] * 0.125;
                }
            }
        }
        out
    }
}

/// The 2x2x2 block means of an even-shaped grid (same box).
pub fn pool<R: Real>(g: &Grid<R>) -> Grid<R> {
    let [nz, ny, nx] = g.shape;
    let (cz, cy, cx) = (nz / 2, ny / 2, nx / 2);
    let mut data = Vec::with_capacity(cz * cy * cx);
    for k in 0..cz {
        for j in 0..cy {
            for i in 0..cx {
                let mut s = R::cst(0.0);
                for c in 0..8 {
                    s += g.data[g.index(2 * k + (c >> 2), 2 * j + ((c >> 1) & 1), 2 * i + (c & 1))];
                }
                data.push(s * 0.125);
            }
        }
    }
    Grid::new(g.lo, g.hi, [cz, cy, cx], data)
}

/// The 2x2 block means of an even-sized image: what a camera of half the resolution sees.
pub fn halve(im: &Image) -> Image {
    let (w, h) = (im.width / 2, im.height / 2);
    let mut data = Vec::with_capacity(w * h);
    for y in 0..h {
        for x in 0..w {
            let at = |dx: usize, dy: usize| im.data[(2 * y + dy) * im.width + 2 * x + dx];
            data.push(0.25 * (at(0, 0) + at(1, 0) + at(0, 1) + at(1, 1)));
        }
    }
    Image { width: w, height: h, data }
}

/// Trains `model` in place; `observe(row, model, images)` sees every log row
/// with the model before the update and this update's rendered images.
pub fn train(
    problem: &Problem,
    model: &mut Model,
    settings: &TrainSettings,
    observe: &mut dyn FnMut(&LogRow, &Model, &[Image]),
) -> Result<()> {
    let start = Instant::now();
    let mut adam_z = Adam::new(model.z.len(), settings.lr_latent);
    let mut adam_w = Adam::new(model.w.len(), settings.lr_weights);
    let fine = Level::full(problem, &model.mask);
    let coarse = if settings.coarse_fraction > 0.0 { Level::half(problem, &model.mask) } else { None };
    let coarse_updates = (settings.coarse_fraction.clamp(0.0, 1.0) * settings.iterations as f64).round() as usize;
    let mut rng = Rng::new(settings.seed, Purpose::Gradient, 1_000_000);
    let mut next_weight = 0usize;
    for it in 0..settings.iterations {
        let level = match &coarse {
            Some(c) if it < coarse_updates => c,
            _ => &fine,
        };
        let decoded = model.density(&problem.scene.density);
        let mut scene = level.scene.clone();
        scene.density = level.grid(decoded.clone());
        scene.render.photons = settings.photons;
        scene.render.spp = settings.spp;
        scene.render.seed = settings.seed.wrapping_mul(1_000_003).wrapping_add(it as u64);
        let frozen = Frozen::new(&scene, Some(&level.support));
        let row = log_row(it, problem, level, model, &decoded, &frozen, start.elapsed().as_secs_f64());
        observe(&row, model, &frozen.images);
        let (gz, gw) = gradient(level, model, &frozen, settings, &mut rng, &mut next_weight)?;
        adam_z.step_sparse(&mut model.z, &gz.0, &gz.1);
        adam_w.step_sparse(&mut model.w, &gw.0, &gw.1);
    }
    Ok(())
}

fn log_row(
    it: usize,
    problem: &Problem,
    level: &Level,
    model: &Model,
    decoded: &Grid<f64>,
    frozen: &Frozen,
    wall_s: f64,
) -> LogRow {
    let n = level.targets.len();
    let images: Vec<Vec<f64>> = frozen.images.iter().map(|i| i.data.clone()).collect();
    let train_loss = mse(&images[..n], &level.targets);
    let (held_out_loss, held_out_rel_rmse) = if level.held_out.is_empty() {
        (0.0, 0.0)
    } else {
        let ours: Vec<f64> = images[n..].iter().flatten().copied().collect();
        let theirs: Vec<f64> = level.held_out.iter().flat_map(|i| i.data.iter().copied()).collect();
        (mse(&images[n..], &level.held_out), rel_rmse(&ours, &theirs))
    };
    let d = &decoded.data;
    let hull: Vec<f64> = d.iter().zip(&model.mask).filter(|(_, &m)| m).map(|(v, _)| *v).collect();
    LogRow {
        iteration: it,
        train_loss,
        held_out_loss,
        held_out_rel_rmse,
        density_rel_l1: problem.truth.map_or(f64::NAN, |t| rel_l1(d, &t.data, &model.mask)),
        mean_density: hull.iter().sum::<f64>() / hull.len().max(1) as f64,
        max_density: hull.iter().fold(0.0, |a: f64, &b| a.max(b)),
        wall_s,
    }
}

/// (indices, gradient) pairs for the latent and for the weights.
type Sparse = (Vec<usize>, Vec<f64>);

fn gradient(
    level: &Level,
    model: &Model,
    frozen: &Frozen,
    settings: &TrainSettings,
    rng: &mut Rng,
    next_weight: &mut usize,
) -> Result<(Sparse, Sparse)> {
    let all = |n: usize| (0..n).collect::<Vec<_>>();
    match settings.estimator {
        Estimator::RevFull | Estimator::RevSub => {
            let subset = if settings.estimator == Estimator::RevFull {
                Subset::full()
            } else {
                Subset {
                    pixels: Some(settings.subset_pixels),
                    paths: Some(settings.subset_paths),
                    seed: rng.below(u64::MAX),
                }
            };
            let g = reverse_gradient(frozen, &level.targets, subset).grad;
            let g = level.pull_back(g, model.decoder_shape());
            let (dz, dw) = model.decoder.backward(&model.z, &model.w, &model.mask, &g);
            Ok(((all(dz.len()), dz), (all(dw.len()), dw)))
        }
        Estimator::FwdFull => {
            let dz = crate::with_lanes!(settings.lanes, latent_gradient(level, model, frozen));
            let gw = match settings.weight_mode {
                WeightDirections::Coordinates => {
                    let n = model.w.len();
                    let idx: Vec<usize> =
                        (0..settings.weight_directions.min(n)).map(|k| (*next_weight + k) % n).collect();
                    *next_weight = (*next_weight + idx.len()) % n.max(1);
                    let dirs: Vec<Vec<f64>> = idx
                        .iter()
                        .map(|&i| {
                            let mut e = vec![0.0; n];
                            e[i] = 1.0;
                            e
                        })
                        .collect();
                    let d = weight_derivatives(level, model, frozen, &dirs, settings.lanes)?;
                    (idx, d)
                }
                WeightDirections::Orthonormal => {
                    random_weight_gradient(level, model, frozen, settings, Directions::Orthonormal, rng)?
                }
                WeightDirections::Guided => guided_weight_gradient(level, model, frozen, settings, rng)?,
            };
            Ok(((all(dz.len()), dz), gw))
        }
        Estimator::FwdRand => {
            let dz = random_latent_gradient(level, model, frozen, settings, rng)?;
            let gw = random_weight_gradient(level, model, frozen, settings, Directions::Gaussian, rng)?;
            Ok(((all(dz.len()), dz), gw))
        }
    }
}

/// The decoder's output with K tangents, as the level's grid for the renderer.
fn tangent_grid<const K: usize>(
    level: &Level,
    model: &Model,
    z: &[DualSVec64<K>],
    w: &[DualSVec64<K>],
) -> Grid<DualSVec64<K>> {
    let d = &level.scene.density;
    let shape = model.decoder_shape();
    level.grid(Grid::new(d.lo, d.hi, shape, model.decoder.forward(z, w, &model.mask)))
}

/// Exact `dL/dz` from all latent coordinates, K per pass.
fn latent_gradient<const K: usize>(level: &Level, model: &Model, frozen: &Frozen) -> Vec<f64> {
    let n = model.z.len();
    let w: Vec<DualSVec64<K>> = model.w.iter().map(|&v| DualSVec64::from_re(v)).collect();
    let mut grad = Vec::with_capacity(n);
    for first in (0..n).step_by(K) {
        let z: Vec<DualSVec64<K>> = (0..n)
            .map(|i| {
                if i >= first && i < first + K {
                    let mut e = [0.0; K];
                    e[i - first] = 1.0;
                    with_tangents(model.z[i], e)
                } else {
                    DualSVec64::from_re(model.z[i])
                }
            })
            .collect();
        let density = tangent_grid(level, model, &z, &w);
        let (_, d) = directional(frozen, &density, &level.targets);
        grad.extend_from_slice(&d[..K.min(n - first)]);
    }
    grad
}

/// Directional derivatives of the loss along weight-space directions `dirs`.
fn weight_derivatives(
    level: &Level,
    model: &Model,
    frozen: &Frozen,
    dirs: &[Vec<f64>],
    lanes: usize,
) -> Result<Vec<f64>> {
    fn pass<const K: usize>(level: &Level, model: &Model, frozen: &Frozen, dirs: &[Vec<f64>]) -> Vec<f64> {
        let z: Vec<DualSVec64<K>> = model.z.iter().map(|&v| DualSVec64::from_re(v)).collect();
        let mut out = vec![];
        for chunk in dirs.chunks(K) {
            let w: Vec<DualSVec64<K>> = (0..model.w.len())
                .map(|i| with_tangents(model.w[i], std::array::from_fn(|k| chunk.get(k).map_or(0.0, |d| d[i]))))
                .collect();
            let density = tangent_grid(level, model, &z, &w);
            let (_, d) = directional(frozen, &density, &level.targets);
            out.extend_from_slice(&d[..chunk.len()]);
        }
        out
    }
    Ok(crate::with_lanes!(lanes, pass(level, model, frozen, dirs)))
}

/// A random-direction estimate of `dL/dw` from `weight_directions` directions.
fn random_weight_gradient(
    level: &Level,
    model: &Model,
    frozen: &Frozen,
    settings: &TrainSettings,
    kind: Directions,
    rng: &mut Rng,
) -> Result<Sparse> {
    let n = model.w.len();
    let k = settings.weight_directions.min(n);
    if k == 0 {
        return Ok((vec![], vec![]));
    }
    let (dirs, factor) = directions(n, k, kind, rng);
    let d = weight_derivatives(level, model, frozen, &dirs, settings.lanes)?;
    Ok(((0..n).collect(), combine(&dirs, &d, factor)))
}

/// `factor * Σ_k d_k dirs_k`: a gradient estimate from directional derivatives.
fn combine(dirs: &[Vec<f64>], d: &[f64], factor: f64) -> Vec<f64> {
    let mut g = vec![0.0; dirs.first().map_or(0, |v| v.len())];
    for (dk, dir) in d.iter().zip(dirs) {
        g.iter_mut().zip(dir).for_each(|(a, b)| *a += factor * dk * b);
    }
    g
}

/// K random directions over `n` coordinates (any K) and the unbiasing factor.
fn directions(n: usize, k: usize, kind: Directions, rng: &mut Rng) -> (Vec<Vec<f64>>, f64) {
    let mut dirs = vec![];
    for _ in 0..k.div_ceil(16) {
        dirs.extend(random_directions::<16>(n, kind, rng).0);
    }
    dirs.truncate(k);
    // Orthonormal blocks of 16 are independent of each other; E[q q^T] = I/n for each, so n/K stays unbiased.
    let factor = match kind {
        Directions::Gaussian => 1.0 / k as f64,
        Directions::Orthonormal => n as f64 / k as f64,
    };
    (dirs, factor)
}

/// `fwd-rand` for the latent: K Gaussian directions.
fn random_latent_gradient(
    level: &Level,
    model: &Model,
    frozen: &Frozen,
    settings: &TrainSettings,
    rng: &mut Rng,
) -> Result<Vec<f64>> {
    fn pass<const K: usize>(level: &Level, model: &Model, frozen: &Frozen, rng: &mut Rng) -> Vec<f64> {
        let n = model.z.len();
        let (dirs, factor) = random_directions::<K>(n, Directions::Gaussian, rng);
        let z: Vec<DualSVec64<K>> =
            (0..n).map(|i| with_tangents(model.z[i], std::array::from_fn(|k| dirs[k][i]))).collect();
        let w: Vec<DualSVec64<K>> = model.w.iter().map(|&v| DualSVec64::from_re(v)).collect();
        let density = tangent_grid(level, model, &z, &w);
        let (_, d) = directional(frozen, &density, &level.targets);
        (0..n).map(|i| factor * (0..K).map(|k| d[k] * dirs[k][i]).sum::<f64>()).collect()
    }
    Ok(crate::with_lanes!(settings.lanes, pass(level, model, frozen, rng)))
}

/// The image residuals of the training cameras back-projected onto the
/// level's voxels along the pixel-centre rays, attenuated by the camera
/// transmittance: a guess of `dL/drho` that needs no renderer derivative.
fn back_projection(level: &Level, frozen: &Frozen) -> Vec<f64> {
    let d = &level.scene.density;
    let scale = level.scene.medium.sigma_t_scale;
    let rays = frozen.camera_rays(d, None);
    let mut g = vec![0.0; d.len()];
    for (c, target) in level.targets.iter().enumerate() {
        let cam = &level.scene.cameras[c];
        for p in 0..cam.pixels() {
            let r = frozen.images[c].data[p] - target.data[p];
            if r == 0.0 {
                continue;
            }
            let ray = cam.ray((p % cam.width) as f64 + 0.5, (p / cam.width) as f64 + 0.5);
            let mut t = 1.0;
            rays.marcher.steps(&ray, f64::INFINITY, 0.5, |s| {
                let x = ray.at(s.sample);
                if let Some(st) = d.stencil(&x) {
                    for k in 0..8 {
                        g[st.index[k]] += r * t * s.h * st.weight[k];
                    }
                }
                t *= (-d.at(&x) * scale * s.h).exp();
                t > 1e-6
            });
        }
    }
    g
}

/// [`WeightDirections::Guided`]: the projection of `dL/dw` onto a guessed
/// direction and `weight_directions - 1` random ones, from exact forward-mode
/// directional derivatives.
fn guided_weight_gradient(
    level: &Level,
    model: &Model,
    frozen: &Frozen,
    settings: &TrainSettings,
    rng: &mut Rng,
) -> Result<Sparse> {
    let n = model.w.len();
    let k = settings.weight_directions.min(n);
    if k == 0 {
        return Ok((vec![], vec![]));
    }
    let g_rho = level.pull_back(back_projection(level, frozen), model.decoder_shape());
    let (_, guess) = model.decoder.backward(&model.z, &model.w, &model.mask, &g_rho);
    let mut dirs = vec![guess];
    if k > 1 {
        dirs.extend(directions(n, k - 1, Directions::Gaussian, rng).0);
    }
    // Gram-Schmidt, guess first; drop directions that vanish.
    let mut basis: Vec<Vec<f64>> = vec![];
    for mut v in dirs {
        for b in &basis {
            let dot: f64 = v.iter().zip(b).map(|(a, c)| a * c).sum();
            v.iter_mut().zip(b).for_each(|(a, c)| *a -= dot * c);
        }
        let norm = v.iter().map(|a| a * a).sum::<f64>().sqrt();
        if norm > 0.0 && norm.is_finite() {
            v.iter_mut().for_each(|a| *a /= norm);
            basis.push(v);
        }
    }
    let d = weight_derivatives(level, model, frozen, &basis, settings.lanes)?;
    Ok(((0..n).collect(), combine(&basis, &d, 1.0)))
}
