//! Judging results, shared by tests and experiments: image and density
//! metrics, the cached path-traced reference.

pub mod metrics;
pub mod reference;
pub mod stats;
pub mod sweep;
