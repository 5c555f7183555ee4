//! The renderer's error against its run time: photon mapping over photon
//! counts and kernel radii, timed and compared with a path-traced reference
//! (block relative RMSE with the reference's noise removed). Shared by the
//! renderer benchmark and the error-against-time study.

use super::metrics::{block_rel_rmse, rel_mean_diff};
use super::reference::Reference;
use super::stats::median;
use crate::render::frozen::Timings;
use crate::render::{render_photon, PhotonRender};
use crate::scene::Scene;
use serde::Serialize;

/// Pixel block edge of the error measure: 4x4 blocks average out the
/// photon map's pixel noise that a kernel estimate does not claim to resolve.
pub const ERROR_BLOCK: usize = 4;

/// `repeats` renders of `scene` (at least one): the last render and every render's stage times.
pub fn timed(scene: &Scene, repeats: usize) -> (PhotonRender, Vec<Timings>) {
    let mut times = vec![];
    let mut last = None;
    for _ in 0..repeats.max(1) {
        let r = render_photon(scene);
        times.push(r.timings.clone());
        last = Some(r);
    }
    (last.expect("at least one render"), times)
}

/// The median of one stage's time over repeated renders.
pub fn median_of(times: &[Timings], stage: fn(&Timings) -> f64) -> f64 {
    median(&times.iter().map(stage).collect::<Vec<_>>())
}

/// The block relative RMSE of `images` against `reference`, its noise
/// removed. The benchmarks' references are path-traced plumes, never all
/// black; one that is would be a bug in the benchmark's scene.
pub fn error(images: &[crate::image::Image], reference: &Reference) -> f64 {
    block_rel_rmse(images, &reference.radiance, Some(&reference.std_err), ERROR_BLOCK)
        .expect("a benchmark's reference image is all black")
}

/// One photon-mapping configuration of a sweep.
#[derive(Clone, Debug, Serialize)]
pub struct SweepPoint {
    /// Photons emitted.
    pub photons: u64,
    /// Kernel radius in voxels (of the largest voxel edge).
    pub radius_voxels: f64,
    /// Kernel radius in world units.
    pub radius: f64,
    /// Median render time (s).
    pub seconds: f64,
    /// Block relative RMSE against the reference.
    pub block_rel_rmse: f64,
    /// Relative difference of the summed radiance.
    pub mean_rel_diff: f64,
}

/// Renders `scene` at every (radius, photons) pair, radii outermost, with
/// `repeats(photons)` timed renders each.
pub fn photon_sweep(
    scene: &Scene,
    reference: &Reference,
    photons: &[u64],
    radii_voxels: &[f64],
    repeats: impl Fn(u64) -> usize,
) -> Vec<SweepPoint> {
    let voxel = scene.density.voxel_size().max();
    let mut points = vec![];
    for &radius in radii_voxels {
        for &n in photons {
            let mut s = scene.clone();
            s.render.photons = n;
            s.render.kernel_radius = Some(radius * voxel);
            let (r, times) = timed(&s, repeats(n));
            let point = SweepPoint {
                photons: n,
                radius_voxels: radius,
                radius: radius * voxel,
                seconds: median_of(&times, |t| t.total),
                block_rel_rmse: error(&r.images, reference),
                mean_rel_diff: rel_mean_diff(&r.images, &reference.radiance),
            };
            eprintln!(
                "  {n} photons, radius {radius} voxels: {:.3} s, block rel RMSE {:.2} %",
                point.seconds,
                100.0 * point.block_rel_rmse
            );
            points.push(point);
        }
    }
    points
}

/// One way of finding the lights' transmittance on one scene, timed and
/// compared with the path-traced reference and with marched shadow rays.
#[derive(Clone, Debug, Serialize)]
pub struct ShadowPoint {
    /// Which way: `auto: grid` (the default: the grids, marched near the
    /// voxels too deep for them where there are any, counted), `grid, 1
    /// voxel` or `marched`.
    pub shadows: String,
    /// Voxels per light-depth node (0: marched).
    pub cell: usize,
    /// Median render time (s).
    pub seconds: f64,
    /// Median time of the light-depth grids and the camera rays (s).
    pub camera_seconds: f64,
    /// Block relative RMSE against the reference.
    pub block_rel_rmse: f64,
    /// Relative difference of the summed radiance.
    pub mean_rel_diff: f64,
    /// Block relative RMSE against the marched shadow rays' render (the
    /// same photons: the transmittance's own error; 0 for `marched`).
    pub vs_marched: f64,
}

/// Renders `scene` with the default shadows, with light-depth nodes at every
/// voxel, and with marched shadow rays; the photons are the same in all
/// three, so their differences are those of the transmittance alone.
pub fn shadow_comparison(scene: &Scene, reference: &Reference, repeats: usize) -> Vec<ShadowPoint> {
    use crate::render::thick::ThickVoxels;
    use crate::scene::Shadows;
    let variants =
        [("marched", Shadows::Marched, None), ("auto", Shadows::Auto, None), ("grid, 1 voxel", Shadows::Grid, Some(1))];
    let mut marched: Option<Vec<crate::image::Image>> = None;
    let mut points: Vec<ShadowPoint> = variants
        .into_iter()
        .map(|(name, shadows, cell)| {
            let mut s = scene.clone();
            s.render.shadows = shadows;
            s.render.shadow_cell = cell;
            let (r, times) = timed(&s, repeats);
            let scale = s.medium.sigma_t_scale;
            let cell = s.render.shadow_cell_for(&s.density, scale);
            let name = match (shadows, cell.and_then(|c| ThickVoxels::new(&s.density, scale, c))) {
                (Shadows::Auto, None) => "auto: grid".to_string(),
                (Shadows::Auto, Some(t)) => {
                    format!(
                        "auto: grid, marched near {} thick voxel{}",
                        t.count(),
                        if t.count() == 1 { "" } else { "s" }
                    )
                }
                _ => name.to_string(),
            };
            let vs_marched = marched.as_ref().map_or(0.0, |m| {
                block_rel_rmse(&r.images, m, None, ERROR_BLOCK).expect("a benchmark's render is all black")
            });
            let point = ShadowPoint {
                shadows: name.clone(),
                cell: cell.unwrap_or(0),
                seconds: median_of(&times, |t| t.total),
                camera_seconds: median_of(&times, |t| t.shadows + t.camera),
                block_rel_rmse: error(&r.images, reference),
                mean_rel_diff: rel_mean_diff(&r.images, &reference.radiance),
                vs_marched,
            };
            eprintln!(
                "  shadows {name}: {:.3} s, block rel RMSE {:.2} %, sum {:+.2} %, against marched {:.2} %",
                point.seconds,
                100.0 * point.block_rel_rmse,
                100.0 * point.mean_rel_diff,
                100.0 * point.vs_marched
            );
            if shadows == Shadows::Marched {
                marched = Some(r.images);
            }
            point
        })
        .collect();
    // Rows as before: the default first, marched last.
    points.rotate_left(1);
    points
}
