//! Learning the density: Adam, the training loop, whole reconstructions.

pub mod adam;
pub mod reconstruct;
pub mod train;
