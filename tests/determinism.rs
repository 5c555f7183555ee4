//! Results depend on the seed only: bit-identical for any number of threads.

mod common;

use dualphoton::math::Vec3;
use dualphoton::render::render_photon;
use dualphoton::scene::Light;

fn in_pool<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap().install(f)
}

#[test]
fn photon_images_are_bit_identical_with_one_and_two_threads() {
    let lights = vec![
        Light { position: Vec3::new(1.5, 0.5, 2.0), intensity: 200.0 },
        Light { position: Vec3::new(-2.0, 0.0, 1.0), intensity: 100.0 },
    ];
    let cams = vec![common::camera(2.5, 30.0, 16), common::camera(2.0, 40.0, 12)];
    let mut scene = common::scene(common::blob(16), common::medium(0.9, 0.7, 3), lights, cams);
    scene.render.photons = 20_000;
    scene.render.seed = 5;
    let one = in_pool(1, || render_photon(&scene));
    let two = in_pool(2, || render_photon(&scene));
    assert!(one.stored_photons > 1000);
    for (a, b) in one.images.iter().zip(&two.images) {
        assert!(a.data.iter().any(|v| *v > 0.0));
        assert_eq!(
            a.data.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
            b.data.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
        );
    }
    scene.render.seed = 6;
    let other = in_pool(2, || render_photon(&scene));
    assert_ne!(one.images[0].data, other.images[0].data, "a different seed must give different noise");
}

/// The derivatives a gradient is made of are the same bits with 1, 2 and 3
/// threads: forward-mode lanes through the frozen estimator (photon
/// powers, the photon estimate, light-depth grids, every camera's pixels).
#[test]
fn forward_mode_derivatives_are_bit_identical_for_any_thread_count() {
    use dualphoton::grad::forward::{coordinate_tangents, directional};
    use dualphoton::render::frozen::Frozen;
    let lights = vec![Light { position: Vec3::new(1.5, 0.5, 2.0), intensity: 200.0 }];
    let cams = vec![common::camera(2.5, 30.0, 12), common::camera(2.0, 40.0, 10)];
    let mut scene = common::scene(common::blob(12), common::medium(0.9, 0.7, 3), lights, cams);
    scene.render.photons = 5_000;
    scene.render.seed = 9;
    let mut targets = render_photon(&scene).images;
    targets.iter_mut().for_each(|t| t.data.iter_mut().for_each(|v| *v *= 0.9));
    let d = &scene.density;
    let voxels: Vec<usize> = (0..d.len()).filter(|&v| d.data[v] > 0.0).step_by(7).take(4).collect();
    let run = |threads| {
        in_pool(threads, || {
            let frozen = Frozen::new(&scene, None);
            let (loss, lanes) = directional::<4>(&frozen, &coordinate_tangents(d, &voxels), &targets);
            [loss, lanes[0], lanes[1], lanes[2], lanes[3]].map(f64::to_bits)
        })
    };
    let one = run(1);
    assert!(one[1..].iter().any(|&b| f64::from_bits(b) != 0.0), "the lanes carry derivatives");
    assert_eq!(run(2), one);
    assert_eq!(run(3), one);
}
