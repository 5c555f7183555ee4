//! What a reconstruction is given: a scene (training cameras first), the
//! target images and, where known, the true density; and the paper's own
//! problem, the built-in plume seen by the paper's rig.

use super::paper;
use crate::data::plume::plume;
use crate::image::Image;
use crate::render::render_photon;
use crate::scene::{rig, Scene};
use crate::volume::Grid;

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

/// The main job's problem: the built-in plume (ground truth), the paper
/// rig around it (plus `extra_views` training cameras,
/// [`rig::extra_cameras`], placed before the held-out one), and the images
/// of all its cameras rendered with `photons` and [`paper::TARGET_SPP`]
/// samples per pixel (more than a training update uses; see [`target_render`]).
pub struct PaperProblem {
    /// Ground-truth density.
    pub truth: Grid<f64>,
    /// The rig with the ground truth; its render settings are the defaults.
    pub scene: Scene,
    /// Images of every camera: `..rig::HELD_OUT_CAMERA + extra_views` train, the rest are held out.
    pub images: Vec<Image>,
}

/// [`PaperProblem`] at `res`^3 from `seed`.
pub fn paper_problem(res: usize, seed: u64, photons: u64, extra_views: usize) -> PaperProblem {
    paper_problem_of(plume(res, seed), seed, photons, extra_views)
}

/// [`PaperProblem`] of any `truth` on the unit box (cubic, `res`^3; images
/// `res` x `res`), its target images rendered from `seed`.
pub fn paper_problem_of(truth: Grid<f64>, seed: u64, photons: u64, extra_views: usize) -> PaperProblem {
    let res = truth.shape[0];
    let mut scene = rig::paper_scene(truth.clone(), res);
    let at = rig::HELD_OUT_CAMERA;
    scene.cameras.splice(at..at, rig::extra_cameras(extra_views, res));
    let mut target = scene.clone();
    target_render(&mut target, seed, photons);
    let images = render_photon(&target).images;
    PaperProblem { truth, scene, images }
}

/// Sets `scene`'s render settings to those the target images of
/// [`paper_problem`] (from `seed`, with `photons`) are rendered with, so that
/// a saved scene renders them again.
pub fn target_render(scene: &mut Scene, seed: u64, photons: u64) {
    scene.render.photons = photons;
    scene.render.spp = paper::TARGET_SPP;
    scene.render.seed = paper::target_seed(seed);
}
