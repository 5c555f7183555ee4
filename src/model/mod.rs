//! The learned density model: a latent code `z` and a small decoder
//! `D(z; w)` whose output is the density grid the renderer consumes. This
//! module owns the architecture and parameter layout (`decoder`), the sparse
//! layout of the grids a mask needs (`layout`), the transposed-convolution
//! kernel and its adjoint (`conv`), and the two derivative paths of the
//! decoder (`passes`): forward mode (generic over [`Real`](crate::ad::Real))
//! and a hand-written reverse-mode vector-Jacobian product. It knows nothing
//! of rendering or optimisation.

mod conv;
pub mod decoder;
mod layout;
mod passes;

pub use decoder::*;

use crate::volume::Grid;

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

/// Standard normal test data, deterministic from `seed`.
#[cfg(test)]
fn normals(seed: u64, n: usize) -> Vec<f64> {
    let mut rng = crate::rng::Rng::new(seed, crate::rng::Purpose::Scene, 77);
    (0..n).map(|_| rng.normal()).collect()
}

/// A ball of voxels around the grid centre, radius `r` voxels.
#[cfg(test)]
fn ball(res: usize, r: f64) -> Vec<bool> {
    let c = (res as f64 - 1.0) / 2.0;
    let mut m = vec![false; res * res * res];
    for z in 0..res {
        for y in 0..res {
            for x in 0..res {
                let d2 = (z as f64 - c).powi(2) + (y as f64 - c).powi(2) + (x as f64 - c).powi(2);
                m[(z * res + y) * res + x] = d2 <= r * r;
            }
        }
    }
    m
}
