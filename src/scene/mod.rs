//! Scenes: the medium, point lights, cameras and render knobs, read from and
//! written to a JSON file with the density in a `.npy` ([`file`](mod@file)), plus the
//! paper's rig.

pub mod camera;
pub(crate) mod fields;
pub mod file;
pub mod rig;
pub mod validate;

pub use camera::{Camera, Lens};

use crate::math::Vec3;
use crate::volume::Grid;

/// Optical properties shared by the whole volume.
#[derive(Clone, Debug, PartialEq)]
pub struct Medium {
    /// Extinction per unit density per unit length: `sigma_t = sigma_t_scale * density`; >= 0.
    pub sigma_t_scale: f64,
    /// Single-scattering albedo `sigma_s / sigma_t`, in [0, 1].
    pub albedo: f64,
    /// Henyey-Greenstein asymmetry, in (-1, 1); > 0 scatters forward.
    pub g: f64,
    /// Most scattering events on a path; 1 = single scattering only.
    pub max_order: u32,
    /// Radiance per unit extinction that every point sends towards the
    /// camera whatever the lights: a camera ray gains `sigma_t * emission`
    /// per unit length (attenuated like the rest), so without lights the
    /// image is `emission * (1 - T)`. It is the emission-absorption image
    /// model, and in a lit scene an ambient light scattered once without
    /// shadowing. 0 (the default): none.
    pub emission: f64,
}

/// An isotropic point light.
#[derive(Clone, Debug, PartialEq)]
pub struct Light {
    /// Position (world units).
    pub position: Vec3,
    /// Radiant intensity (W/sr), >= 0.
    pub intensity: f64,
}

/// Most photons one render may store: 2^30. The photon map keeps every
/// stored photon in memory, at least 72 bytes each (64 for the photon, 8
/// for its kernel's offset, more for the kernel's weights), so 2^30 of them
/// already need over 72 GiB; a photon stores up to `max_order - 1`.
pub const MAX_STORED_PHOTONS: u64 = 1 << 30;

/// The project's own render knobs; every one has a default.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderSettings {
    /// Photons emitted in all (split among lights by the power that reaches
    /// the volume); at most [`RenderSettings::max_photons`].
    pub photons: u64,
    /// Photon gathering radius (world units); default one voxel size (results/bench_render: as accurate as 1.5 or 2, and faster).
    pub kernel_radius: Option<f64>,
    /// Ray-marching step (world units); default half the smallest voxel size.
    pub step: Option<f64>,
    /// Seed of every random stream.
    pub seed: u64,
    /// Camera samples per pixel of the photon-mapping renderer (stratified).
    pub spp: u32,
    /// Samples per pixel of the reference path tracer.
    pub path_spp: u32,
    /// How the camera rays' single scattering finds the light's transmittance.
    pub shadows: Shadows,
    /// Voxels per node of the light-depth grids along each axis; default
    /// [`RenderSettings::shadow_cell_for`].
    pub shadow_cell: Option<u32>,
    /// Ray-marching step of photon flights (world units); default the
    /// smallest voxel size (twice the camera rays' default step).
    pub photon_step: Option<f64>,
}

/// How the photon-mapping renderer computes the transmittance from a
/// camera-ray sample to a light.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Shadows {
    /// `grid`, but camera-ray samples near a voxel whose optical depth over
    /// one light-depth node spacing exceeds 1 (`GRID_MAX_DEPTH`: beyond it
    /// the interpolation bias is large) march their shadow rays
    /// ([`crate::render::thick`]).
    #[default]
    Auto,
    /// Per light, the optical depth at the nodes of a grid, marched once per
    /// render and read trilinearly: fast, with an interpolation bias that
    /// grows with the optical depth across a node spacing.
    Grid,
    /// A shadow ray marched from every sample: no interpolation, far slower.
    Marched,
}

/// Largest optical depth across one light-depth node spacing of a voxel
/// whose neighbourhood `auto` shadows read from the grid. Interpolating the
/// depth linearly across a density edge misses it by up to a quarter of
/// this: transmittance off by up to 22 % in a shell one spacing thick at
/// the edges of the densest smoke. What that does to whole images is
/// measured in results/bench_render (the paper's plume: 0.43 at 64^3).
pub const GRID_MAX_DEPTH: f64 = 1.0;

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            photons: 300_000,
            kernel_radius: None,
            step: None,
            seed: 0,
            spp: 4,
            path_spp: 256,
            shadows: Shadows::Auto,
            shadow_cell: None,
            photon_step: None,
        }
    }
}

impl RenderSettings {
    /// The most photons a render of a medium with `max_order` may emit:
    /// [`MAX_STORED_PHOTONS`] shared among the `max_order - 1` photons each
    /// may store (max_order 1, which stores none, counts as 2: each emitted
    /// photon still has an 8-byte index).
    pub fn max_photons(max_order: u32) -> u64 {
        MAX_STORED_PHOTONS / u64::from(max_order.max(2) - 1)
    }

    /// The kernel radius to use on `density` (explicit or default).
    pub fn kernel_radius_for(&self, density: &Grid<f64>) -> f64 {
        self.kernel_radius.unwrap_or_else(|| density.voxel_size().max())
    }

    /// The ray-marching step to use on `density` (explicit or default).
    pub fn step_for(&self, density: &Grid<f64>) -> f64 {
        self.step.unwrap_or_else(|| 0.5 * density.voxel_size().min())
    }

    /// The photon flights' marching step on `density` (explicit or default).
    pub fn photon_step_for(&self, density: &Grid<f64>) -> f64 {
        self.photon_step.unwrap_or_else(|| density.voxel_size().min())
    }

    /// The light-depth grids' node spacing on `density` in voxels, or
    /// `None` for marched shadow rays. Explicit `shadow_cell`, else one
    /// node per voxel up to 64 voxels a side and coarser beyond, keeping
    /// about 64 nodes a side (results/bench_render: at 128^3 a node every 2
    /// voxels is as accurate as every voxel, at a sixth of the cost); under
    /// `auto`, refined until the densest voxel's optical depth across a
    /// spacing is at most [`GRID_MAX_DEPTH`], down to one voxel (where
    /// voxels stay too deep, samples near them march:
    /// [`crate::render::thick`]).
    pub fn shadow_cell_for(&self, density: &Grid<f64>, sigma_t_scale: f64) -> Option<usize> {
        let coarse = (density.shape.iter().max().unwrap() / 64).max(1);
        let cell = self.shadow_cell.map_or(coarse, |c| c.max(1) as usize);
        match self.shadows {
            Shadows::Marched => None,
            Shadows::Grid => Some(cell),
            Shadows::Auto => {
                let densest = density.max_value();
                Some((1..=cell).rev().find(|&c| densest <= grid_density_limit(density, sigma_t_scale, c)).unwrap_or(1))
            }
        }
    }
}

/// The largest density whose optical depth across `cell` voxels of
/// `density`'s grid (extinction `sigma_t_scale` per unit density) is at
/// most [`GRID_MAX_DEPTH`]: the one test of what the light-depth grids
/// interpolate well, for the node spacing and for `auto`'s thick voxels.
pub fn grid_density_limit(density: &Grid<f64>, sigma_t_scale: f64, cell: usize) -> f64 {
    GRID_MAX_DEPTH / (sigma_t_scale * density.voxel_size().max() * cell as f64)
}

/// A complete, validated scene.
#[derive(Clone, Debug)]
pub struct Scene {
    /// Density on the volume's box (`Grid::lo`, `Grid::hi` are `bbox_min`, `bbox_max`).
    pub density: Grid<f64>,
    /// Optical properties.
    pub medium: Medium,
    /// Point lights.
    pub lights: Vec<Light>,
    /// Cameras, in file order (`cam0`, `cam1`, ...).
    pub cameras: Vec<Camera>,
    /// Render knobs.
    pub render: RenderSettings,
}
