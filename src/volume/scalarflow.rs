//! ScalarFlow loader (placeholder, being written).

use super::Grid;
use crate::error::{Error, Result};
use std::path::Path;

/// Not yet implemented.
pub fn load_scalarflow(path: &Path, _res: usize) -> Result<Grid<f64>> {
    Err(Error(format!("--from-scalarflow: {}: not supported yet", path.display())))
}
