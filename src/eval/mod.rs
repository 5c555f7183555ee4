//! Judging results, shared by tests and experiments: image and density
//! metrics, the cached path-traced reference, independent oracles of the
//! renderers (single-scattering quadrature, energy balance), small test
//! scenes and the stability study's cases.

pub mod energy;
pub mod metrics;
pub mod quadrature;
pub mod reference;
pub mod scenes;
pub mod stability;
pub mod stats;
pub mod sweep;
