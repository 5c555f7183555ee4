//! Files: `.npy` arrays, PNG previews, SVG plots.

pub mod figures;
pub mod manifest;
pub mod npy;
pub mod plot;
pub mod png;
pub mod rows;
