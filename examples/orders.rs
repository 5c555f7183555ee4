//! Diagnostic: photon mapping against the path tracer order by order on the
//! paper rig at 64^3. `cargo run --release --example orders -- [photons] [radius_voxels] [path_spp] [spp]`
use dualphoton::data::plume::plume;
use dualphoton::eval::metrics::{block_rel_rmse, rel_mean_diff};
use dualphoton::image::Image;
use dualphoton::render::path::{render_path, PathOptions};
use dualphoton::render::render_photon;
use dualphoton::scene::rig;
fn sub(a: &[Image], b: &[Image]) -> Vec<Image> {
    a.iter()
        .zip(b)
        .map(|(x, y)| Image { data: x.data.iter().zip(&y.data).map(|(p, q)| p - q).collect(), ..x.clone() })
        .collect()
}
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let photons: u64 = args.get(1).map(|s| s.parse().unwrap()).unwrap_or(300000);
    let radius: f64 = args.get(2).map(|s| s.parse().unwrap()).unwrap_or(2.0);
    let spp: u32 = args.get(3).map(|s| s.parse().unwrap()).unwrap_or(4096);
    let mut scene = rig::paper_scene(plume(64, 0), 64);
    scene.cameras.truncate(4);
    scene.render.photons = photons;
    scene.render.kernel_radius = Some(radius / 64.0);
    scene.render.spp = args.get(4).map(|s| s.parse().unwrap()).unwrap_or(1);
    let mut prev: Option<Vec<Image>> = None;
    for n in 1..=3u32 {
        let mut s = scene.clone();
        s.medium.max_order = n;
        let pm = render_photon(&s).images;
        let pm_n = match &prev {
            None => pm.clone(),
            Some(p) => sub(&pm, p),
        };
        prev = Some(pm);
        let pt = render_path(&s, &PathOptions { spp, seed: 7, max_order: Some(n), min_order: n });
        let e = block_rel_rmse(&pm_n, &pt.radiance, Some(&pt.std_err), 4);
        let d = rel_mean_diff(&pm_n, &pt.radiance);
        let tot: f64 = pt.radiance.iter().map(|i| i.data.iter().sum::<f64>()).sum();
        println!("order {n}: PT sum {tot:.3}, PM-PT sum diff {:+.2}%, block rel RMSE {:.2}%", 100.0 * d, 100.0 * e);
    }
}
