//! Aether's path-tracing example: the Cornell box by BSDF sampling with
//! Russian roulette and light sampling at every vertex, weighed by MIS
//! (`../shared/scenes/aether/cbox/cbox_path.xml`).
//!
//! `cargo run --release -p examples --example path`

use examples::{load, render_to};
use integrators::path::PathTracer;

fn run() -> Result<(), String> {
    let scene = load("../shared/scenes/aether/cbox/cbox_path.xml", 0.5)?;
    render_to(&scene, &PathTracer::new(&scene)?, 64, "path")?;
    Ok(())
}

fn main() {
    if let Err(e) = run() {
        eprintln!("path: {e}");
        std::process::exit(1);
    }
}
