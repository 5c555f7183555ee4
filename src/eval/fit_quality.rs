//! How well a density explains images: each camera's relative RMSE at 1x1,
//! 2x2 and 4x4 pixel blocks, next to the noise floor of the same
//! comparison. All renders are high quality (many photons and samples) so
//! that a misfit hidden by a training update's noise shows.
//!
//! With the true density known, truth and estimate are rendered with the
//! same seed (common random numbers, so most of the render noise cancels)
//! and the floor is the truth against itself rendered with another seed.
//! For user images without a truth, the estimate is compared with the
//! images themselves and the floor is the estimate against itself rendered
//! with another seed.

use crate::error::{Error, Result};
use crate::eval::metrics::block_rel_rmse;
use crate::image::Image;
use crate::render::render_photon;
use crate::scene::Scene;
use crate::volume::Grid;
use serde::Serialize;

/// The block sizes compared, in pixels per side.
pub const BLOCKS: [usize; 3] = [1, 2, 4];

/// Render settings of the comparison.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct FitQualitySettings {
    /// Photons per render.
    pub photons: u64,
    /// Camera samples per pixel.
    pub spp: u32,
    /// Seed of the compared renders (far from every training update's seed).
    pub seed: u64,
    /// Seed of the second render that measures the noise floor.
    pub floor_seed: u64,
}

impl Default for FitQualitySettings {
    fn default() -> Self {
        FitQualitySettings { photons: 1_000_000, spp: 8, seed: 251_000_001, floor_seed: 251_000_002 }
    }
}

/// What the estimate is compared with.
pub enum FitTarget<'a> {
    /// The true density: rendered with the estimate's seed (the comparison) and another (the floor).
    Truth(&'a Grid<f64>),
    /// Images of every camera, no truth: the floor is the estimate's own two-seed noise.
    Images(&'a [Image]),
}

/// One line of `fit_quality.csv`: one camera.
#[derive(Clone, Debug, Serialize)]
pub struct CameraFit {
    /// Camera index in the scene.
    pub camera: usize,
    /// `train` or `held-out`.
    pub role: &'static str,
    /// Relative RMSE of the estimate's image, per pixel.
    pub rel_rmse_1x1: f64,
    /// The same over 2x2 block means.
    pub rel_rmse_2x2: f64,
    /// The same over 4x4 block means.
    pub rel_rmse_4x4: f64,
    /// The noise floor per pixel (two seeds of the same density).
    pub floor_1x1: f64,
    /// The noise floor over 2x2 blocks.
    pub floor_2x2: f64,
    /// The noise floor over 4x4 blocks.
    pub floor_4x4: f64,
}

impl CameraFit {
    /// The misfit per pixel in units of the floor.
    pub fn pixel_ratio(&self) -> f64 {
        self.rel_rmse_1x1 / self.floor_1x1
    }
}

/// Renders `estimate` in `scene` (its cameras, lights and medium) at
/// `settings` and compares it with `target` camera by camera; the first
/// `n_train` cameras are the training ones.
pub fn fit_quality(
    scene: &Scene,
    estimate: &Grid<f64>,
    target: FitTarget,
    n_train: usize,
    settings: &FitQualitySettings,
) -> Result<Vec<CameraFit>> {
    let render = |density: &Grid<f64>, seed: u64| -> Vec<Image> {
        let mut s = scene.clone();
        s.density = density.clone();
        (s.render.photons, s.render.spp, s.render.seed) = (settings.photons, settings.spp, seed);
        render_photon(&s).images
    };
    let ours = render(estimate, settings.seed);
    let (reference, second) = match target {
        FitTarget::Truth(truth) => (render(truth, settings.seed), render(truth, settings.floor_seed)),
        FitTarget::Images(images) => {
            if images.len() != scene.cameras.len() {
                return Err(Error(format!("fit quality: {} images for {} cameras", images.len(), scene.cameras.len())));
            }
            (images.to_vec(), render(estimate, settings.floor_seed))
        }
    };
    // The floor compares two renders of one density: the truth's or, without one, the estimate's.
    let floor_of = if matches!(target, FitTarget::Truth(_)) { &reference } else { &ours };
    let rows = (0..scene.cameras.len())
        .map(|c| {
            let rel = |a: &Image, b: &Image, k: usize| {
                block_rel_rmse(std::slice::from_ref(a), std::slice::from_ref(b), None, BLOCKS[k])
            };
            CameraFit {
                camera: c,
                role: if c < n_train { "train" } else { "held-out" },
                rel_rmse_1x1: rel(&ours[c], &reference[c], 0),
                rel_rmse_2x2: rel(&ours[c], &reference[c], 1),
                rel_rmse_4x4: rel(&ours[c], &reference[c], 2),
                floor_1x1: rel(&second[c], &floor_of[c], 0),
                floor_2x2: rel(&second[c], &floor_of[c], 1),
                floor_4x4: rel(&second[c], &floor_of[c], 2),
            }
        })
        .collect();
    Ok(rows)
}

/// The Markdown table of `rows`, percentages with the floor beside each.
pub fn fit_quality_markdown(rows: &[CameraFit]) -> String {
    let mut md = String::from(
        "| camera | role | per pixel (floor) | 2x2 blocks (floor) | 4x4 blocks (floor) | pixel / floor |\n|---|---|---|---|---|---|\n",
    );
    for r in rows {
        let pct = |a: f64, f: f64| format!("{:.1} % ({:.1} %)", 100.0 * a, 100.0 * f);
        md += &format!(
            "| {} | {} | {} | {} | {} | {:.2} |\n",
            r.camera,
            r.role,
            pct(r.rel_rmse_1x1, r.floor_1x1),
            pct(r.rel_rmse_2x2, r.floor_2x2),
            pct(r.rel_rmse_4x4, r.floor_4x4),
            r.pixel_ratio()
        );
    }
    md
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eval::scenes;

    #[test]
    fn the_truth_fits_itself_exactly_and_a_wrong_density_does_not() {
        let scene = scenes::one_light_blob(10, 16);
        let settings = FitQualitySettings { photons: 20_000, spp: 2, seed: 1, floor_seed: 2 };
        let truth = scene.density.clone();
        let same = fit_quality(&scene, &truth, FitTarget::Truth(&truth), 1, &settings).unwrap();
        assert!(same.iter().all(|r| r.rel_rmse_1x1 == 0.0 && r.floor_1x1 > 0.0));
        let mut wrong = truth.clone();
        wrong.data.iter_mut().for_each(|v| *v *= 1.5);
        let off = fit_quality(&scene, &wrong, FitTarget::Truth(&truth), 1, &settings).unwrap();
        assert!(off.iter().all(|r| r.pixel_ratio() > 1.0), "{off:?}");
        assert_eq!(off[0].role, "train");
    }
}
