//! The paper's numbers and choices, in one place: its Table 1, which
//! iterations and camera its Fig. 6 shows, and how the target images and
//! the final renders of the main job are made (samples, seeds). The
//! reconstruction, the `fit` command and the Table 1 experiment read them
//! from here.

/// One row of the paper's Table 1: density statistics over the hull voxels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Table1Row {
    /// Which density the row describes.
    pub name: &'static str,
    /// Mean density over the hull voxels (extinction per unit length, as the grid stores it).
    pub mean: f64,
    /// Maximum density over the hull voxels.
    pub max: f64,
}

/// The paper's Table 1 (128^3 grid, 68,771 hull voxels).
pub const TABLE1: [Table1Row; 3] = [
    Table1Row { name: "before training", mean: 0.0045, max: 0.0209 },
    Table1Row { name: "after training", mean: 0.0417, max: 1.6234 },
    Table1Row { name: "ground truth", mean: 0.0432, max: 1.3585 },
];

/// Iterations whose image Fig. 6 shows; the last iteration and the ground
/// truth are added after them.
pub const FIG6_ITERATIONS: [usize; 5] = [0, 10, 50, 100, 200];

/// The camera Fig. 6 shows (a training camera of the paper's rig).
pub const FIG6_CAMERA: usize = 2;

/// Photons of the main job's target images (far more than a training update's).
pub const TARGET_PHOTONS: u64 = 1_000_000;

/// Camera samples per pixel of the target images and of the final renders.
pub const TARGET_SPP: u32 = 8;

/// The target images are rendered with seed `seed + TARGET_SEED_OFFSET`, so
/// that their photons are not those of any training update.
pub const TARGET_SEED_OFFSET: u64 = 4242;

/// The final renders of an estimate use seed `training seed + FINAL_SEED_OFFSET`:
/// other photons than the targets' and the training updates'.
pub const FINAL_SEED_OFFSET: u64 = 777;

/// Seed of the target images of a problem made from `seed`.
pub fn target_seed(seed: u64) -> u64 {
    seed.wrapping_add(TARGET_SEED_OFFSET)
}

/// Seed of the final renders after training with `training_seed`.
pub fn final_seed(training_seed: u64) -> u64 {
    training_seed.wrapping_add(FINAL_SEED_OFFSET)
}
