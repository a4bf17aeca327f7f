//! Aether's gradient-domain example: cbox-sphere by gradient-domain path
//! tracing (`../shared/scenes/aether/cbox-sphere/cbox-sphere-gpt.xml`).
//! Every path is shifted into the four neighbouring pixels by replaying
//! its random numbers and reconnecting at the first pair of rough
//! vertices; the shift's Jacobian and the MIS weights between the pixels
//! come from the sampling language. Writes the primal image, the two
//! gradient images and the L1 reconstruction to `target/examples`.
//!
//! `cargo run --release -p examples --example gpt`

use std::sync::atomic::AtomicBool;

use examples::{load, workspace};
use integrators::gradient::{GradientPathTracer, render_gradients};
use integrators::output::{write_exr, write_png};
use integrators::render::Settings;

fn run() -> Result<(), String> {
    let scene = load(
        "../shared/scenes/aether/cbox-sphere/cbox-sphere-gpt.xml",
        0.5,
    )?;
    let spp = 64;
    let settings = Settings {
        progress: true,
        ..Settings::new(spp, 1)
    };
    let tracer = GradientPathTracer::new(&scene)?;
    let g = render_gradients(&scene, &tracer, &settings, &AtomicBool::new(false))?;
    let reconstruction = g.reconstruct(&scene.integrator.gradient);
    let dir = workspace().join("target/examples");
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    for (name, image) in [
        ("gpt", &reconstruction),
        ("gpt-primal", &g.primal),
        ("gpt-dx", &g.dx),
        ("gpt-dy", &g.dy),
    ] {
        write_exr(
            &dir.join(format!("{name}.exr")),
            g.width,
            g.height,
            image,
            spp,
            g.seconds,
        )?;
        // Gradients are signed: the previews show magnitudes.
        let preview: Vec<[f32; 3]> = image.iter().map(|c| c.map(f32::abs)).collect();
        write_png(
            &dir.join(format!("{name}.png")),
            g.width,
            g.height,
            &preview,
            0.0,
        )?;
    }
    println!(
        "gpt: {}×{}, {spp} spp, {:.1} s, {:.0} samples/s -> {}",
        g.width,
        g.height,
        g.seconds,
        g.samples as f64 / g.seconds,
        dir.join("gpt.png").display()
    );
    Ok(())
}

fn main() {
    if let Err(e) = run() {
        eprintln!("gpt: {e}");
        std::process::exit(1);
    }
}
