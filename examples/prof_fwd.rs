use dualphoton::grad::forward::{random_gradient, Directions};
use dualphoton::render::frozen::Frozen;
use dualphoton::rng::Rng;
use dualphoton::scene::rig;
use dualphoton::volume::plume::plume;
fn main() {
    let mut truth = rig::paper_scene(plume(64, 0), 64);
    truth.cameras.truncate(4);
    let targets = Frozen::new(&truth, None).images;
    let mut scene = truth.clone();
    scene.density.data.iter_mut().for_each(|v| *v *= 0.5);
    let frozen = Frozen::new(&scene, None);
    let reach = frozen.reachable_voxels();
    let t = std::time::Instant::now();
    let p = frozen.photon_powers(&scene.density.map(num_dual::DualSVec64::<8>::from_re));
    println!("replay const {:.3}", t.elapsed().as_secs_f64());
    drop(p);
    for _ in 0..3 {
        let t = std::time::Instant::now();
        random_gradient::<8>(&frozen, &reach, &targets, Directions::Gaussian, &mut Rng::from_seed(1));
        println!("fwd-rand 8: {:.3}", t.elapsed().as_secs_f64());
    }
}
