//! The participating medium: the density grid, its majorant blocks and the
//! Henyey-Greenstein phase function.

pub mod blur;
pub mod grid;
pub mod majorant;
pub mod phase;

pub use grid::{Grid, Stencil};
pub use majorant::Majorant;
