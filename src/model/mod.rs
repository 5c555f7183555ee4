//! The learned density model (PAPER.md §Method 1): a latent code `z` and a
//! small decoder `D(z; w)` whose output is the density grid the renderer
//! consumes. This module owns the architecture, the parameter layout, the
//! initialisation and both derivative paths of the decoder: forward mode
//! (generic over [`Real`](crate::ad::Real)) and a hand-written reverse-mode
//! vector-Jacobian product. It knows nothing of rendering or optimisation.

pub mod decoder;

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
