//! Files: `.npy` arrays, PNG previews.

pub mod npy;
pub mod png;
