//! Where densities come from: the built-in plume generator and the loader
//! of real ScalarFlow frames. Both produce a [`Grid`](crate::volume::Grid)
//! on the unit box.

pub mod plume;
pub mod scalarflow;
