//! Judging results, shared by tests and experiments: image and density
//! metrics, how well a density explains images (fit quality), the cached path-traced reference, independent oracles of the
//! renderers (single-scattering quadrature, energy balance), small test
//! scenes and the stability study's cases.

pub mod density;
pub mod energy;
pub mod fit_quality;
pub mod metrics;
pub mod quadrature;
pub mod reference;
pub mod scenes;
pub mod stability;
pub mod stats;
pub mod sweep;
