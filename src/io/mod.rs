//! Files: `.npy` arrays, PNG previews, SVG plots and figures, CSV rows,
//! manifests and the machine's speed beside them, the index of `results/`.

pub mod figures;
pub mod manifest;
pub mod npy;
pub mod panels;
pub mod plot;
pub mod png;
pub mod results_index;
pub mod rows;
pub mod speed_probe;
pub mod svg;
