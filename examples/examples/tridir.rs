//! Aether's tridirectional example: the keyhole Cornell box, lit through a
//! hole in its ceiling, by BDPT plus segments sampled through the hole and
//! spliced between camera and light subpaths
//! (`scenes/cbox_tridir_keyhole.xml`, which declares the hole of
//! `../shared/scenes/aether/cbox/cbox_tridir.xml` a portal). Its equal-time
//! comparison with BDPT is the `equal_time` example.
//!
//! `cargo run --release -p examples --example tridir`

use examples::{load, render_to};
use integrators::bdpt::Bdpt;

fn run() -> Result<(), String> {
    let mut scene = load("scenes/cbox_tridir_keyhole.xml", 0.5)?;
    // Aether's integrators stop at depth 6 where a scene sets no limit.
    scene.integrator.max_depth = 6;
    render_to(&scene, &Bdpt::tridirectional(&scene)?, 64, "tridir")?;
    Ok(())
}

fn main() {
    if let Err(e) = run() {
        eprintln!("tridir: {e}");
        std::process::exit(1);
    }
}
