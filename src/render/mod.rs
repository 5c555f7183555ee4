//! Renderers: single scattering by ray marching, orders 2..max_order by
//! photon mapping, and an unbiased volumetric path tracer as the reference.
//! Renderers compute images; they write no files.

pub mod path;

pub mod camera_rays;
pub mod light_depth;
pub mod march;
pub mod photon;
pub mod photons;
pub mod splat;
pub mod thick;

pub use photon::{render_photon, PhotonRender};
pub mod emission;
pub mod frozen;
