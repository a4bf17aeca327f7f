//! The first rung of the ladder: a strategy written once, its density for
//! any vertex, and the harness that verifies it.
//!
//! A diffuse bounce from the floor of the test box samples a cosine-weighted
//! direction and casts a ray. The same code gives the area density of any
//! vertex of the box, including one that light sampling produced.

use aether_core::harness::{Check, Grid, check_strategy};
use aether_core::testing::{Bounce, CameraPoint, LightSample, RectChart, TestScene, TestVertex};
use aether_core::{Heuristic, Pcg32, RandomSequence, combine};
use glam::Vec3;

fn main() {
    let scene = TestScene::open_box();
    let bounce = Bounce::new(&scene);
    let floor = TestVertex {
        shape: 0,
        ..TestVertex::on_surface(Vec3::new(0.1, -0.2, 0.0), Vec3::Z)
    };

    let report = check_strategy(
        &bounce,
        &[floor],
        &Grid::new(RectChart::new(&scene, 3), 16),
        &Check::default(),
    )
    .expect("the bounce's density is right");
    println!("bounce from the floor, binned on a wall: {report}");

    let (camera, light) = (CameraPoint::default(), LightSample::new(&scene));
    let mut rng = Pcg32::new(7, 0);
    let mut bsdf_path = RandomSequence::new();
    bsdf_path.append(&camera).append(&bounce).append(&bounce);
    bsdf_path.sample(&mut rng);
    let mut light_path = bsdf_path.slice(0..2);
    light_path.append(&light);
    light_path.sample(&mut rng);
    println!(
        "BSDF-sampled path density {}, light-sampled path density {}",
        bsdf_path.pdf(),
        light_path.pdf()
    );
    let weights = combine(&[bsdf_path, light_path], Heuristic::POWER);
    println!("power-heuristic weights: {weights:?}");
}
