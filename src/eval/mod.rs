//! Judging results, shared by tests and experiments: image and density
//! metrics, the cached path-traced reference, small test scenes.

pub mod metrics;
pub mod reference;
pub mod scenes;
pub mod stats;
