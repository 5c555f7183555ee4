//! The participating medium: the density grid, its majorant blocks, the
//! phase function, and where densities come from (plume, ScalarFlow).

pub mod grid;
pub mod hull;
pub mod majorant;
pub mod phase;

pub use grid::{Grid, Stencil};
pub use majorant::Majorant;
pub mod plume;
pub mod scalarflow;
