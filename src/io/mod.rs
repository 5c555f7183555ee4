//! Files: `.npy` arrays, PNG previews, SVG plots and figures, manifests.

pub mod figures;
pub mod manifest;
pub mod npy;
pub mod panels;
pub mod plot;
pub mod png;
pub mod svg;
