//! A whole reconstruction: visual hull from the training images, a latent
//! and decoder initialised inside it, training, and everything a reader
//! needs to check the result, written into one directory.

use super::problem::Problem;
use super::train::{train, LogRow, TrainSettings};
use crate::error::{Error, Result};
use crate::image::Image;
use crate::io::{figures, npy};
use crate::model::Decoder;
use crate::model::Model;
use crate::recon::hull::{visual_hull, SILHOUETTE_DILATION, SILHOUETTE_THRESHOLD};
use crate::render::render_photon;
use crate::scene::Scene;
use crate::volume::Grid;
use std::io::Write as _;
use std::path::Path;

/// Iterations whose camera-2 image goes into Fig. 6 (the last one is added).
pub const FIG6_ITERATIONS: [usize; 5] = [0, 10, 50, 100, 200];

/// What a reconstruction produced.
pub struct Reconstruction {
    /// The trained model (its mask is the hull).
    pub model: Model,
    /// The density before training.
    pub initial: Grid<f64>,
    /// The density after training.
    pub estimated: Grid<f64>,
    /// The training log.
    pub log: Vec<LogRow>,
    /// Images of every camera rendered from the estimate (final quality).
    pub final_images: Vec<Image>,
    /// Camera-2 images at [`FIG6_ITERATIONS`] (iteration, image).
    pub snapshots: Vec<(usize, Image)>,
}

/// Settings of a reconstruction beyond training.
#[derive(Clone, Debug)]
pub struct ReconstructSettings {
    /// Training.
    pub train: TrainSettings,
    /// Photons of the final renders.
    pub final_photons: u64,
    /// Samples per pixel of the final renders.
    pub final_spp: u32,
    /// Seed of the model's initial values.
    pub init_seed: u64,
}

/// The model before training: the visual hull of the training cameras
/// (the first `targets.len()` of the scene's) as its mask, a decoder for the
/// scene's cubic grid, latent and weights initialised from `init_seed`.
pub fn initial_model(scene: &Scene, targets: &[Image], init_seed: u64) -> Result<Model> {
    let n_train = targets.len();
    let mask =
        visual_hull(&scene.density, &scene.cameras[..n_train], targets, SILHOUETTE_THRESHOLD, SILHOUETTE_DILATION);
    if !mask.iter().any(|&m| m) {
        return Err(Error::new("visual hull: no voxel is inside every training silhouette (are the images black?)"));
    }
    let res = scene.density.shape[0];
    if scene.density.shape != [res, res, res] {
        return Err(Error(format!("volume.density: the decoder needs a cubic grid, got {:?}", scene.density.shape)));
    }
    let decoder = Decoder::paper_small(res).map_err(|e| Error(format!("volume.density: {e}")))?;
    let w = decoder.init(init_seed);
    let z = decoder.init_latent(init_seed);
    Ok(Model { decoder, z, w, mask })
}

/// Reconstructs the density of `scene` (cameras `0..targets.len()` train,
/// the rest are held out) from `targets` (+ `held_out` images), writing the
/// log as it goes to `out/log.csv`.
pub fn reconstruct(
    scene: &Scene,
    targets: &[Image],
    held_out: &[Image],
    truth: Option<&Grid<f64>>,
    settings: &ReconstructSettings,
    out: &Path,
    progress: &mut dyn FnMut(&LogRow),
) -> Result<Reconstruction> {
    let mut model = initial_model(scene, targets, settings.init_seed)?;
    let initial = model.density(&scene.density);

    let mut log = vec![];
    let mut snapshots = vec![];
    let mut csv =
        std::fs::File::create(out.join("log.csv")).map_err(|e| Error(format!("cannot write log.csv: {e}")))?;
    writeln!(
        csv,
        "iteration,train_loss,held_out_loss,held_out_rel_rmse,density_rel_l1,mean_density,max_density,wall_s"
    )?;
    let last = settings.train.iterations.saturating_sub(1);
    let problem = Problem { scene, targets, held_out, truth };
    train(&problem, &mut model, &settings.train, &mut |row, _, images| {
        let _ = writeln!(
            csv,
            "{},{:.9e},{:.9e},{:.6},{:.6},{:.6e},{:.6e},{:.3}",
            row.iteration,
            row.train_loss,
            row.held_out_loss,
            row.held_out_rel_rmse,
            row.density_rel_l1,
            row.mean_density,
            row.max_density,
            row.wall_s
        );
        if (FIG6_ITERATIONS.contains(&row.iteration) || row.iteration == last) && images.len() > 2 {
            snapshots.push((row.iteration, upscale(&images[2], targets[2].width)));
        }
        progress(row);
        log.push(row.clone());
    })?;
    let estimated = model.density(&scene.density);
    let mut final_scene = scene.clone();
    final_scene.density = estimated.clone();
    final_scene.render.photons = settings.final_photons;
    final_scene.render.spp = settings.final_spp;
    final_scene.render.seed = settings.train.seed.wrapping_add(777);
    let final_images = render_photon(&final_scene).images;
    Ok(Reconstruction { model, initial, estimated, log, final_images, snapshots })
}

/// Writes the arrays and figures of a reconstruction into `out`.
pub fn write_outputs(
    r: &Reconstruction,
    scene: &Scene,
    targets: &[Image],
    held_out: &[Image],
    truth: Option<&Grid<f64>>,
    out: &Path,
) -> Result<()> {
    let shape = &scene.density.shape;
    npy::write_f32(&out.join("density_initial.npy"), shape, &r.initial.data)?;
    npy::write_f32(&out.join("density_estimated.npy"), shape, &r.estimated.data)?;
    npy::write_u8(&out.join("hull.npy"), shape, &r.model.mask.iter().map(|&m| m as u8).collect::<Vec<_>>())?;
    if let Some(t) = truth {
        npy::write_f32(&out.join("density_gt.npy"), shape, &t.data)?;
        figures::density_scatter(
            &t.data,
            &r.initial.data,
            &r.estimated.data,
            &r.model.mask,
            &out.join("fig7_scatter.svg"),
        )?;
    }
    figures::loss_curves(&out.join("log.csv"), &out.join("fig5_loss.svg"))?;
    if targets.len() > 2 {
        let white = crate::image::auto_white(&targets[2].data);
        let mut strip: Vec<&Image> = r.snapshots.iter().map(|(_, i)| i).collect();
        strip.push(&targets[2]);
        figures::image_strip(&strip, white, &out.join("fig6_camera2.png"))?;
    }
    if let Some(h) = held_out.first() {
        figures::held_out_panel(h, &r.final_images[targets.len()], &out.join("fig8_held_out.png"))?;
    }
    Ok(())
}

/// `im` enlarged by pixel replication to `width` (a coarse update's image next to full-size ones).
fn upscale(im: &Image, width: usize) -> Image {
    let f = (width / im.width.max(1)).max(1);
    let (w, h) = (im.width * f, im.height * f);
    let data = (0..w * h).map(|p| im.data[(p / w / f) * im.width + (p % w) / f]).collect();
    Image { width: w, height: h, data }
}
