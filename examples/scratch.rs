use dualphoton::math::Vec3;
use dualphoton::render::render_photon;
use dualphoton::scene::rig;
use dualphoton::volume::Grid;
fn blob(n: usize) -> Grid<f64> {
    let mut g = Grid::new(Vec3::from_element(-0.5), Vec3::from_element(0.5), [n, n, n], vec![0.0; n * n * n]);
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let p = g.voxel_center(k, j, i);
                let a = (-(Vec3::new(p.x * 2.0, p.y * 0.7, p.z * 2.0).norm_squared()) / (2.0 * 0.18f64.powi(2))).exp();
                let v = 0.3 * a;
                let idx = g.index(k, j, i);
                g.data[idx] = if v < 0.01 { 0.0 } else { v };
            }
        }
    }
    g
}
fn main() {
    let res: usize = std::env::args().nth(1).map(|s| s.parse().unwrap()).unwrap_or(64);
    let mut scene = rig::paper_scene(blob(res), res);
    scene.cameras.truncate(4);
    for _ in 0..3 {
        let r = render_photon(&scene);
        let t = &r.timings;
        let mean: f64 = r.images.iter().map(|i| i.data.iter().sum::<f64>() / i.data.len() as f64).sum::<f64>() / 4.0;
        println!(
            "stored {} trace {:.3} gather {:.3} camera {:.3} total {:.3} mean {:.4}",
            r.stored_photons, t.trace, t.gather, t.camera, t.total, mean
        );
    }
}
