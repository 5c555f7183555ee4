//! The rows of bench_render's CSV files.

use dualphoton::eval::sweep::{ShadowPoint, SweepPoint};
use serde::Serialize;

/// Stage times of the default render at one resolution (`timing.csv`).
#[derive(Serialize)]
pub struct TimingRow {
    pub res: usize,
    pub photons: u64,
    pub stored_photons: usize,
    pub trace_s: f64,
    pub gather_s: f64,
    pub shadows_s: f64,
    pub camera_s: f64,
    pub single_scattering_only_s: f64,
    pub total_s: f64,
    pub photons_per_s: f64,
    pub block_rel_rmse: f64,
    pub threads: usize,
}

/// Stage times of the default render of one blurred plume (all 5 cameras), or of
/// the built-in plume as `timing.csv` renders it (blur 0, the 4 training cameras).
#[derive(Serialize)]
pub struct BlurredRow {
    pub res: usize,
    pub blur_voxels: f64,
    pub occupied: f64,
    pub cameras: usize,
    pub trace_s: f64,
    pub gather_s: f64,
    pub shadows_s: f64,
    pub camera_s: f64,
    pub total_s: f64,
    pub threads: usize,
}

/// One way of finding the lights' transmittance on one scene and orders (`shadows.csv`).
#[derive(Serialize)]
pub struct ShadowRow {
    pub scene: String,
    pub res: usize,
    pub cameras: usize,
    pub orders: &'static str,
    pub shadows: String,
    pub voxels_per_node: usize,
    pub total_s: f64,
    pub grids_and_camera_s: f64,
    pub block_rel_rmse: f64,
    pub mean_rel_diff: f64,
    pub vs_marched: f64,
}

impl ShadowRow {
    pub fn new(scene: String, res: usize, cameras: usize, orders: &'static str, p: ShadowPoint) -> Self {
        let ShadowPoint { shadows, cell, seconds, camera_seconds, block_rel_rmse, mean_rel_diff, vs_marched } = p;
        ShadowRow {
            scene,
            res,
            cameras,
            orders,
            shadows,
            voxels_per_node: cell,
            total_s: seconds,
            grids_and_camera_s: camera_seconds,
            block_rel_rmse,
            mean_rel_diff,
            vs_marched,
        }
    }
}

/// One point of the photon-count and radius sweep (`sweep.csv`).
#[derive(Serialize)]
pub struct SweepRow {
    pub res: usize,
    pub photons: u64,
    pub radius_voxels: f64,
    pub radius: f64,
    pub total_s: f64,
    pub block_rel_rmse: f64,
    pub mean_rel_diff: f64,
}

impl SweepRow {
    pub fn new(res: usize, p: SweepPoint) -> Self {
        let SweepPoint { photons, radius_voxels, radius, seconds, block_rel_rmse, mean_rel_diff } = p;
        SweepRow { res, photons, radius_voxels, radius, total_s: seconds, block_rel_rmse, mean_rel_diff }
    }
}

/// Everything a run measures, in the order the files list it.
#[derive(Default)]
pub struct Tables {
    pub timing: Vec<TimingRow>,
    pub sweep: Vec<SweepRow>,
    pub shadows: Vec<ShadowRow>,
    pub blurred: Vec<BlurredRow>,
}
