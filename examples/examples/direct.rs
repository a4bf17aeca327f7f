//! Aether's direct-lighting example: the Cornell box lit by light sampling
//! and BSDF sampling at the first hit, weighed by MIS
//! (`../shared/scenes/aether/cbox/cbox_direct.xml`).
//!
//! `cargo run --release -p examples --example direct`

use examples::{load, render_to};
use integrators::direct::DirectLighting;

fn run() -> Result<(), String> {
    let scene = load("../shared/scenes/aether/cbox/cbox_direct.xml", 0.5)?;
    render_to(&scene, &DirectLighting::new(&scene)?, 64, "direct")?;
    Ok(())
}

fn main() {
    if let Err(e) = run() {
        eprintln!("direct: {e}");
        std::process::exit(1);
    }
}
