//! Learning the density: Adam, the training loop, whole reconstructions.

pub mod adam;
pub mod level;
pub mod param_grad;
pub mod reconstruct;
pub mod train;
