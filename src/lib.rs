//! # dualphoton
//!
//! Recovers the 3-D density of smoke and fog from photographs by
//! differentiating a photon-mapping renderer with forward-mode dual numbers.
//!
//! Data flow: a [`scene::Scene`] (density grid, medium, point lights,
//! pinhole cameras) is rendered by [`render`] into radiance images: single
//! scattering by ray marching, higher orders by photon mapping; an unbiased
//! path tracer is the reference. [`recon`] fits a density to images of
//! known cameras and lights (the paper's latent and decoder, or the
//! learned prior of [`prior`], then a per-voxel refinement), its gradients
//! from [`grad`]; [`capture`] fits real photographs, whose lights and
//! camera response are unknown and fitted too. Conventions (right-handed,
//! y up, voxel centres, units) are those of `docs/DESIGN.md` §1 and are
//! documented on the types that carry them; §6 says where each module
//! stands.

#![warn(missing_docs)]

pub mod ad;
pub mod capture;
pub mod data;
pub mod error;
pub mod eval;
pub mod experiment;
pub mod grad;
pub mod image;
pub mod io;
pub mod math;
pub mod model;
pub mod optim;
pub mod par;
pub mod prior;
pub mod process;
pub mod recon;
pub mod render;
pub mod rng;
pub mod scene;
pub mod volume;

pub use error::{Error, Result};
