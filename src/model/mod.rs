//! The learned density model (PAPER.md §Method 1): a latent code `z` and a
//! small decoder `D(z; w)` whose output is the density grid the renderer
//! consumes. This module owns the architecture, the parameter layout, the
//! initialisation and both derivative paths of the decoder: forward mode
//! (generic over [`Real`](crate::ad::Real)) and a hand-written reverse-mode
//! vector-Jacobian product. It knows nothing of rendering or optimisation.

pub mod decoder;

pub use decoder::*;
