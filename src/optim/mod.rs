//! Learning the density: Adam and the training loop.

pub mod adam;
pub mod train;
