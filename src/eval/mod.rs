//! Judging results, shared by tests and experiments: image and density
//! metrics, the cached path-traced reference, single scattering by
//! quadrature, small test scenes.

pub mod metrics;
pub mod quadrature;
pub mod reference;
pub mod scenes;
pub mod stats;
