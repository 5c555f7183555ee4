//! The path-traced reference of the renderer studies (`bench_render`,
//! `error_vs_time`), cached on disk and keyed by the density's bits, so a
//! changed plume generator or order renders it anew.

use crate::error::Result;
use crate::eval::metrics::reference_noise;
use crate::image::Image;
use crate::io::manifest::{git_revision, write_json};
use crate::io::npy;
use crate::render::path::{render_path_with_progress, PathOptions};
use crate::scene::Scene;
use serde_json::json;
use std::path::Path;
use std::time::Instant;

/// Seed of the reference's paths.
pub const REF_SEED: u64 = 1234;

/// A converged path-traced reference and its per-pixel standard error.
pub struct Reference {
    /// Radiance per camera.
    pub radiance: Vec<Image>,
    /// Standard error of each pixel.
    pub std_err: Vec<Image>,
}

/// Loads the reference of `dir` if it was made from the same density,
/// order and `spp`, else renders it (seed [`REF_SEED`]) and saves it there.
pub fn reference(scene: &Scene, plume_seed: u64, spp: u32, dir: &Path) -> Result<Reference> {
    let manifest_path = dir.join("manifest.json");
    // The density's bits name it: a changed plume generator invalidates the reference.
    let fingerprint = scene
        .density
        .data
        .iter()
        .fold(0xcbf2_9ce4_8422_2325u64, |h, v| (h ^ v.to_bits()).wrapping_mul(0x100_0000_01b3));
    let wanted = json!({"spp": spp, "seed": REF_SEED, "plume_seed": plume_seed, "res": scene.density.shape[0],
                        "max_order": scene.medium.max_order, "density_fnv1a": format!("{fingerprint:016x}")});
    if let Ok(text) = std::fs::read_to_string(&manifest_path) {
        if let Ok(m) = serde_json::from_str::<serde_json::Value>(&text) {
            if m.get("key") == Some(&wanted) {
                let load = |name: String| -> Result<Image> {
                    let a = npy::read(&dir.join(name), "reference")?;
                    Ok(Image { width: a.shape[1], height: a.shape[0], data: a.data })
                };
                let n = scene.cameras.len();
                return Ok(Reference {
                    radiance: (0..n).map(|c| load(format!("cam{c}.npy"))).collect::<Result<_>>()?,
                    std_err: (0..n).map(|c| load(format!("cam{c}_stderr.npy"))).collect::<Result<_>>()?,
                });
            }
        }
    }
    std::fs::create_dir_all(dir)?;
    let start = Instant::now();
    let opts = PathOptions { spp, seed: REF_SEED, max_order: None, min_order: 1 };
    let progress = |done: usize, total: usize| {
        let t = start.elapsed().as_secs_f64();
        eprint!(
            "\r  reference: {done}/{total} pixels, {t:.0} s, ETA {:.0} s   ",
            t * (total - done) as f64 / done.max(1) as f64
        );
    };
    let r = render_path_with_progress(scene, &opts, &progress);
    eprintln!();
    let seconds = start.elapsed().as_secs_f64();
    // What the cache holds is float32: a fresh run uses the same rounded
    // images a later run reads back, so both measure the same errors.
    let as_f32 = |im: &Image| im.map(|v| v as f32 as f64);
    let stored = Reference {
        radiance: r.radiance.iter().map(as_f32).collect(),
        std_err: r.std_err.iter().map(as_f32).collect(),
    };
    for (c, (im, se)) in stored.radiance.iter().zip(&stored.std_err).enumerate() {
        npy::write_f32(&dir.join(format!("cam{c}.npy")), &[im.height, im.width], &im.data)?;
        npy::write_f32(&dir.join(format!("cam{c}_stderr.npy")), &[se.height, se.width], &se.data)?;
    }
    let noise = reference_noise(&stored.radiance, &stored.std_err, 4);
    write_json(
        &manifest_path,
        &json!({"key": wanted, "seconds": seconds, "samples": r.samples, "block_noise": noise, "git": git_revision()}),
    )?;
    Ok(stored)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eval::scenes::one_light_blob;

    #[test]
    fn a_fresh_reference_equals_the_cached_one() {
        let dir = std::env::temp_dir().join(format!("dualphoton-reference-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let scene = one_light_blob(8, 6);
        let fresh = reference(&scene, 7, 4, &dir).unwrap();
        let cached = reference(&scene, 7, 4, &dir).unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
        assert!(fresh.radiance.iter().flat_map(|im| &im.data).any(|&v| v > 0.0), "the scene renders black");
        assert_eq!(fresh.radiance, cached.radiance);
        assert_eq!(fresh.std_err, cached.std_err);
    }
}
