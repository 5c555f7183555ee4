//! Diagnostic: share of a camera's photon estimate carried by the heaviest photons
//! (the heavy tail that camera-guided scattering cuts), on the paper rig at 64^3.
//! `cargo run --release --example tails`
use dualphoton::data::plume::plume;
use dualphoton::render::frozen::Frozen;
use dualphoton::scene::rig;
use dualphoton::volume::phase::hg_eval;
fn main() {
    let mut scene = rig::paper_scene(plume(64, 0), 64);
    scene.cameras.truncate(4);
    let f = Frozen::new(&scene, None);
    for order in [2u8, 3] {
        let cam = scene.cameras[2].position;
        let mut v: Vec<f64> = f
            .photons
            .iter()
            .filter(|p| p.order == order)
            .map(|p| {
                let w = (cam - p.pos).normalize();
                hg_eval(0.9, p.dir.dot(&w)) * p.power
            })
            .collect();
        v.sort_by(|a, b| b.total_cmp(a));
        let tot: f64 = v.iter().sum();
        let share = |f: f64| v[..((v.len() as f64 * f) as usize).max(1)].iter().sum::<f64>() / tot;
        println!(
            "order {order}: {} photons, top 0.1% {:.2}, top 1% {:.2}, top 10% {:.2}",
            v.len(),
            share(0.001),
            share(0.01),
            share(0.1)
        );
    }
}
