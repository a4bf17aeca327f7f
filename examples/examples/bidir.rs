//! Aether's bidirectional example: Veach's lamp scene by BDPT over every
//! (s, t), with the pyramid of its techniques, weighed by MIS and
//! unweighted, for paths of up to five vertices
//! (`../shared/scenes/aether/veach_bidir/bidir-bdpt.xml`).
//!
//! `cargo run --release -p examples --example bidir`

use examples::{load, render_to, workspace};
use integrators::bdpt::Bdpt;

fn run() -> Result<(), String> {
    let scene = load("../shared/scenes/aether/veach_bidir/bidir-bdpt.xml", 0.25)?;
    let bdpt = Bdpt::new(&scene)?.with_technique_images(5);
    let r = render_to(&scene, &bdpt, 64, "bidir")?;
    let pyramid = workspace().join("target/examples/bidir-pyramid");
    let images = bdpt.technique_images().ok_or("no technique images")?;
    images.write(&pyramid, r.samples, 64, scene.aperture().is_some())?;
    println!("(s, t) images: {}", pyramid.display());
    Ok(())
}

fn main() {
    if let Err(e) = run() {
        eprintln!("bidir: {e}");
        std::process::exit(1);
    }
}
