//! Speed of each integrator: samples per second and rays per second on the
//! built-in Cornell box and on Veach's door (from ../shared, when present),
//! and the cost of BDPT at maximum depth 16 over depth 8 at equal samples.
//! (Gradient-domain tracing's time excludes its reconstruction.)
//!
//! `cargo bench -p integrators` (all cores). Set `AETHER_BENCH_SIZE` for
//! another film width (default 128) and `AETHER_BENCH_SPP` for another
//! number of samples per pixel (default 4).

use std::collections::HashMap;
use std::path::Path;
use std::sync::atomic::AtomicBool;

use aether_strategies::scene::Scene;
use integrators::cornell::cornell_box;
use integrators::render::{Rendered, Settings, render};

fn env_or(name: &str, default: u32) -> u32 {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

fn run(scene: &mut Scene, integrator: &str, spp: u32) -> Result<Rendered, String> {
    scene.integrator.name = integrator.to_string();
    let settings = Settings::new(spp, 1);
    render(scene, &settings, &AtomicBool::new(false))
}

fn table(label: &str, scene: &mut Scene, spp: u32, integrators: &[&str]) {
    println!(
        "\n{label} ({}×{}, {spp} spp, max depth {})",
        scene.film.width, scene.film.height, scene.integrator.max_depth
    );
    println!(
        "{:<8} {:>9} {:>12} {:>10}",
        "", "seconds", "samples/s", "Mrays/s"
    );
    for name in integrators {
        match run(scene, name, spp) {
            Ok(r) => println!(
                "{name:<8} {:>9.2} {:>12.0} {:>10.2}",
                r.seconds,
                r.samples as f64 / r.seconds,
                r.rays as f64 / r.seconds / 1e6
            ),
            Err(e) => println!("{name:<8} {e}"),
        }
    }
}

fn main() {
    let size = env_or("AETHER_BENCH_SIZE", 128);
    let spp = env_or("AETHER_BENCH_SPP", 4);
    let all = ["direct", "path", "light", "bdpt", "tridir", "gpt"];
    let mut cbox = cornell_box(size, size, spp);
    table("built-in Cornell box", &mut cbox, spp, &all);

    let door = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../shared/scenes/aether/veach_door/door-bdpt.xml");
    match Scene::load(&door, &HashMap::new()) {
        Ok(mut scene) => {
            let aspect = f64::from(scene.film.height) / f64::from(scene.film.width);
            scene.film.width = size;
            scene.film.height = ((f64::from(size) * aspect).round() as u32).max(1);
            scene.film.crop = [0, 0, scene.film.width, scene.film.height];
            table(
                "Veach's door",
                &mut scene,
                spp,
                &["path", "light", "bdpt", "gpt"],
            );
        }
        Err(e) => println!("\nVeach's door skipped: {e}"),
    }

    let mut seconds = [0.0; 2];
    for (i, depth) in [8, 16].into_iter().enumerate() {
        cbox.integrator.max_depth = depth;
        seconds[i] = run(&mut cbox, "bdpt", spp).map_or(f64::NAN, |r| r.seconds);
    }
    println!(
        "\nBDPT on the Cornell box, max depth 16 over max depth 8: {:.2} s / {:.2} s = {:.2}",
        seconds[1],
        seconds[0],
        seconds[1] / seconds[0]
    );
}
