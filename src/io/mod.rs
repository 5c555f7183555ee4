//! Files: `.npy` arrays, PNG previews, SVG plots and figures, CSV rows,
//! manifests and the machine's speed beside them.

pub mod figures;
pub mod manifest;
pub mod npy;
pub mod panels;
pub mod plot;
pub mod png;
pub mod rows;
pub mod speed_probe;
pub mod svg;
