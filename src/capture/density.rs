//! The density a frame's fit moves: what its Adam steps act on (the
//! density, its logarithm inside the hull, or the paper's latent and
//! decoder), where a fit starts (an optical depth across the hull, spread
//! evenly or by the photographs), and how one level's density carries to
//! the next. [`super::fit`] runs the stages.

use super::settings::{FitSettings, StartShape};
use crate::error::{Error, Result};
use crate::image::Image;
use crate::math::{inside_box, Vec3};
use crate::model::{Decoder, Model};
use crate::optim::Adam;
use crate::prior::Prior;
use crate::recon::train::TrainSettings;
use crate::scene::Camera;
use crate::volume::Grid;
use std::path::Path;

/// What a stage's Adam steps move.
pub(super) enum Params {
    /// The density itself, projected to >= 0.
    Density(Adam),
    /// The density's logarithm inside the hull.
    Log(Adam, Vec<f64>),
    /// A decoder: the density is `scale` times its output. The paper's
    /// model moves its weights too; the learned prior holds them
    /// (`weights` None) and pulls its latent towards 0, the training
    /// plumes' mean, by `penalty` times the latent in the latent's gradient.
    Decoder { model: Box<Model>, scale: f64, latent: Adam, weights: Option<Adam>, penalty: f64 },
}

impl Params {
    /// One Adam step along `grad` (d loss / d density), `density` set to where it leads.
    pub(super) fn step(&mut self, density: &mut Grid<f64>, hull: &[bool], grad: &[f64]) {
        match self {
            Params::Density(adam) => {
                adam.step(&mut density.data, grad);
                density.data.iter_mut().for_each(|d| *d = d.max(0.0));
            }
            Params::Log(adam, log_values) => {
                // d L / d ln(rho) = rho d L / d rho.
                let log_grad: Vec<f64> = grad.iter().zip(&density.data).map(|(g, d)| g * d).collect();
                adam.step(log_values, &log_grad);
                from_log(density, log_values, hull);
            }
            Params::Decoder { model, scale, latent, weights, penalty } => {
                let grad_out: Vec<f64> = grad.iter().map(|g| g * *scale).collect();
                let (mut grad_z, grad_w) = model.decoder.backward(&model.z, &model.w, &model.mask, &grad_out);
                grad_z.iter_mut().zip(&model.z).for_each(|(g, z)| *g += *penalty * z);
                latent.step(&mut model.z, &grad_z);
                if let Some(weights) = weights {
                    weights.step(&mut model.w, &grad_w);
                }
                let out = model.decoder.forward(&model.z, &model.w, &model.mask);
                density.data = out.iter().map(|v| v * *scale).collect();
            }
        }
    }
}

/// A per-voxel stage from `density`: its steps on the logarithm or on the density.
pub(super) fn voxel_params(mut density: Grid<f64>, hull: &[bool], settings: &FitSettings) -> (Grid<f64>, Params) {
    let mean = mean_inside(&density, hull).max(f64::MIN_POSITIVE);
    let params = if settings.log_density {
        let log_values = to_log(&mut density, hull, mean);
        Params::Log(Adam::new(density.len(), settings.lr), log_values)
    } else {
        Params::Density(Adam::new(density.len(), settings.lr * mean))
    };
    (density, params)
}

/// The decoder's stage: the paper's model from scratch (seeded by the fit's
/// seed) on `grid`, its output scaled to the start's optical depth, with the
/// paper's Adam steps for latent and weights.
pub(super) fn decoder_start(grid: &Grid<f64>, hull: &[bool], settings: &FitSettings) -> Result<(Grid<f64>, Params)> {
    let decoder = Decoder::paper_small(settings.resolution)?;
    let model =
        Model { z: decoder.init_latent(settings.seed), w: decoder.init(settings.seed), mask: hull.to_vec(), decoder };
    let paper = TrainSettings::default();
    let (latent, weights) = (Adam::new(model.z.len(), paper.lr_latent), Adam::new(model.w.len(), paper.lr_weights));
    decoded_start(grid, model, latent, Some(weights), 0.0, settings)
}

/// The learned prior's stage: its decoder (weights held) at the training
/// plumes' mean latent, 0, on `grid`, its output scaled to the start's
/// optical depth; Adam steps and latent penalty as Table 1's prior fit,
/// the penalty relative to `image_power`, the photographs' mean square.
pub(super) fn prior_start(
    grid: &Grid<f64>,
    hull: &[bool],
    settings: &FitSettings,
    image_power: f64,
) -> Result<(Grid<f64>, Params)> {
    let prior = Prior::load(&crate::prior::default_dir()?)?;
    prior.check_grid(grid.shape)?;
    let z = vec![0.0; prior.decoder.latent()];
    let model = Model { z, w: prior.w, mask: hull.to_vec(), decoder: prior.decoder };
    let fit = TrainSettings::prior();
    let penalty = fit.latent_penalty_slope(image_power, model.z.len());
    let latent = Adam::new(model.z.len(), fit.lr_latent);
    decoded_start(grid, model, latent, None, penalty, settings)
}

/// A decoder's stage from `model` as it is, its output scaled to the start's optical depth.
fn decoded_start(
    grid: &Grid<f64>,
    model: Model,
    latent: Adam,
    weights: Option<Adam>,
    penalty: f64,
    settings: &FitSettings,
) -> Result<(Grid<f64>, Params)> {
    let out = model.decoder.forward(&model.z, &model.w, &model.mask);
    if !out.iter().any(|&v| v > 0.0) {
        return Err(Error(
            "the decoder's first output is 0 everywhere in the hull (the paper's decoder: try another seed)".into(),
        ));
    }
    let scale = depth_scale(grid, &out, settings.start_depth);
    let density = Grid::new(grid.lo, grid.hi, grid.shape, out.iter().map(|v| v * scale).collect());
    Ok((density, Params::Decoder { model: Box::new(model), scale, latent, weights, penalty }))
}

/// A cube of `n` voxels a side, centred on the box `lo`..`hi`, its edge the box's longest.
pub(super) fn cube_around(lo: &Vec3, hi: &Vec3, n: usize) -> Grid<f64> {
    let half = (hi - lo).max() / 2.0;
    let centre = (lo + hi) / 2.0;
    let corner = Vec3::new(half, half, half);
    Grid::new(centre - corner, centre + corner, [n, n, n], vec![0.0; n * n * n])
}

/// Whether each voxel's centre lies in the box `lo`..`hi`: every voxel of
/// a level's grid; the decoder's cube reaches past the box's shorter edges.
pub(super) fn in_box(grid: &Grid<f64>, lo: &Vec3, hi: &Vec3) -> Vec<bool> {
    let all = vec![true; grid.len()];
    let inside = over_hull(grid, &all, |c| if inside_box(&c, lo, hi) { 1.0 } else { 0.0 });
    inside.iter().map(|&v| v > 0.0).collect()
}

/// The grid's shape (Z, Y, X) over `lo..hi` with `longest` voxels along the
/// longest edge and cubic voxels as near as whole numbers allow.
pub(super) fn grid_shape(lo: &Vec3, hi: &Vec3, longest: usize) -> [usize; 3] {
    let e = hi - lo;
    let max = e.x.max(e.y).max(e.z);
    let n = |x: f64| ((x / max * longest as f64).round() as usize).max(1);
    [n(e.z), n(e.y), n(e.x)]
}

/// Per voxel, the start's relative density (0 outside the hull).
pub(super) fn start_shape(
    grid: &Grid<f64>,
    hull: &[bool],
    cameras: &[Camera],
    photos: &[Image],
    shape: StartShape,
) -> Vec<f64> {
    let out = over_hull(grid, hull, |centre| {
        let seen = cameras.iter().zip(photos).map(|(camera, photo)| match camera.pixel_of(&centre) {
            Some((x, y)) => photo.data[y * photo.width + x].max(0.0),
            None => 0.0,
        });
        match shape {
            StartShape::Even => 1.0,
            StartShape::Darkest => seen.fold(f64::INFINITY, f64::min),
            StartShape::GeometricMean => {
                let logs: Vec<f64> = seen.map(|v| v.max(1e-6).ln()).collect();
                (logs.iter().sum::<f64>() / logs.len().max(1) as f64).exp()
            }
        }
    });
    // Where every view is dark, the even start.
    if out.iter().all(|&v| v <= 0.0) {
        return hull.iter().map(|&h| if h { 1.0 } else { 0.0 }).collect();
    }
    out
}

/// The start: `shape` scaled so that its mean over the voxels where it is
/// positive is an optical depth of `depth` across their mean chord (their
/// volume over their largest cross-section, roughly). A made capture's
/// truth is set to the fit's start depth by it too.
pub fn start_density(grid: &Grid<f64>, shape: &[f64], depth: f64) -> Grid<f64> {
    let rho = depth_scale(grid, shape, depth);
    Grid::new(grid.lo, grid.hi, grid.shape, shape.iter().map(|&s| s * rho).collect())
}

/// The built-in plume of `seed` (`res` voxels a side) stretched over the
/// box `lo`..`hi` at an optical depth of `depth` across it, by
/// [`start_density`]: a made capture's truth, rebuilt from its seed by
/// whatever asks what the truth's density would give.
pub fn plume_in_box(lo: Vec3, hi: Vec3, res: usize, seed: u64, depth: f64) -> Grid<f64> {
    let unit = crate::data::plume::plume(res, seed);
    let grid = Grid::new(lo, hi, unit.shape, unit.data);
    start_density(&grid, &grid.data, depth)
}

/// A made capture's truth (`data`: its info.json or the folder holding
/// it): the plume's grid edge and frame 0's seed, from the manifest
/// `made_capture` wrote in the folder above; [`plume_in_box`] of seed +
/// frame rebuilds a frame's density.
pub fn made_truth(data: &Path) -> Result<(usize, u64)> {
    let folder = if data.is_dir() { data } else { data.parent().unwrap_or(Path::new(".")) };
    let path = folder.join("..").join("manifest.json");
    let text = std::fs::read_to_string(&path)
        .map_err(|e| Error(format!("{}: {e} (not a made capture: made_capture writes it)", path.display())))?;
    let json: serde_json::Value = serde_json::from_str(&text).map_err(|e| Error(format!("{}: {e}", path.display())))?;
    match (json["res"].as_u64(), json["seed"].as_u64()) {
        (Some(res), Some(seed)) => Ok((res as usize, seed)),
        _ => Err(Error(format!("{}: no res and seed: not made_capture's manifest", path.display()))),
    }
}

/// The factor on `shape` that makes [`start_density`] of it.
fn depth_scale(grid: &Grid<f64>, shape: &[f64], depth: f64) -> f64 {
    let inside = shape.iter().filter(|&&s| s > 0.0).count().max(1) as f64;
    let mean = shape.iter().sum::<f64>() / inside;
    let v = grid.voxel_size();
    let voxel = (v.x * v.y * v.z).cbrt();
    let chord = inside.cbrt() * voxel;
    depth / chord / mean
}

/// `coarse` sampled at `grid`'s voxel centres (trilinear), 0 outside `hull`.
pub(super) fn upsample(coarse: &Grid<f64>, grid: &Grid<f64>, hull: &[bool]) -> Grid<f64> {
    Grid::new(grid.lo, grid.hi, grid.shape, over_hull(grid, hull, |centre| coarse.at(&centre)))
}

/// `value` at the centre of every voxel of `grid` inside `hull`, 0 outside.
fn over_hull(grid: &Grid<f64>, hull: &[bool], value: impl Fn(Vec3) -> f64) -> Vec<f64> {
    let [nz, ny, nx] = grid.shape;
    let mut out = vec![0.0; grid.len()];
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let idx = grid.index(k, j, i);
                if hull[idx] {
                    out[idx] = value(grid.voxel_center(k, j, i));
                }
            }
        }
    }
    out
}

/// What Adam moves with `log_density`: the logarithm of `density` inside
/// `hull`, a voxel at 0 raised to a thousandth of `mean` first (`density`
/// is set to what the logarithm gives back).
fn to_log(density: &mut Grid<f64>, hull: &[bool], mean: f64) -> Vec<f64> {
    let log_values: Vec<f64> =
        density.data.iter().zip(hull).map(|(&d, &h)| if h { d.max(1e-3 * mean).ln() } else { 0.0 }).collect();
    from_log(density, &log_values, hull);
    log_values
}

/// `density` from its logarithm inside `hull`, 0 outside.
fn from_log(density: &mut Grid<f64>, log_values: &[f64], hull: &[bool]) {
    for ((d, &u), &h) in density.data.iter_mut().zip(log_values).zip(hull) {
        *d = if h { u.exp() } else { 0.0 };
    }
}

/// Mean density over the hull's voxels.
fn mean_inside(density: &Grid<f64>, hull: &[bool]) -> f64 {
    let (sum, n) =
        density.data.iter().zip(hull).filter(|(_, &h)| h).fold((0.0, 0usize), |(s, n), (d, _)| (s + d, n + 1));
    sum / n.max(1) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The learned prior's steps move its latent alone, pulled towards 0 by
    /// the penalty where the images' gradient is 0; its weights are held.
    #[test]
    fn the_learned_prior_moves_its_latent_and_holds_its_weights() {
        let (lo, hi) = (Vec3::new(-0.4, -0.5, -0.4), Vec3::new(0.4, 0.5, 0.4));
        let grid = cube_around(&lo, &hi, 64);
        let hull = in_box(&grid, &lo, &hi);
        let settings = FitSettings { prior: 1, ..FitSettings::default() };
        let (mut density, mut params) = prior_start(&grid, &hull, &settings, 1.0).unwrap();
        let held = Prior::load(&crate::prior::default_dir().unwrap()).unwrap().w;
        let Params::Decoder { model, .. } = &params else { panic!("not a decoder's stage") };
        assert!(model.z.iter().all(|&z| z == 0.0), "the prior starts at the training plumes' mean");
        // Less density everywhere in the hull: the latent moves.
        let grad: Vec<f64> = hull.iter().map(|&h| if h { 1.0 } else { 0.0 }).collect();
        let before: f64 = density.data.iter().sum();
        params.step(&mut density, &hull, &grad);
        let Params::Decoder { model, .. } = &mut params else { unreachable!() };
        assert!(model.z.iter().any(|&z| z != 0.0) && model.w == held, "the latent moves, the weights do not");
        assert!(density.data.iter().sum::<f64>() < before, "a step against more density gave more");
        // Without the images' gradient the penalty alone pulls the latent back.
        let (mut density, mut params) = prior_start(&grid, &hull, &settings, 1.0).unwrap();
        let Params::Decoder { model, .. } = &mut params else { unreachable!() };
        model.z = vec![1.0; model.z.len()];
        params.step(&mut density, &hull, &vec![0.0; grid.len()]);
        let Params::Decoder { model, .. } = &params else { unreachable!() };
        assert!(model.z.iter().all(|&z| z < 1.0), "the penalty did not pull the latent towards 0");
    }
}
