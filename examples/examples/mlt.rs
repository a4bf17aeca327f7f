//! Aether's Metropolis example: Veach's door
//! (`../shared/scenes/aether/veach_door/door-mlt-aether.xml`) by Veach's
//! path-space MLT, whose light enters the room through a door ajar. The
//! chain moves by the bidirectional mutation and the lens, caustic and
//! multi-chain perturbations, each written once as sampling code
//! (`aether_strategies::mutations`); the acceptance probability uses
//! T(y | x) and T(x | y), which the language derives by running that code in
//! density mode. Prints how often each mutation was tried and accepted, and
//! writes the image to `target/examples`.
//!
//! `cargo run --release -p examples --example mlt [-- --seconds 30 --scale 0.5]`

use std::sync::atomic::AtomicBool;
use std::time::Duration;

use examples::{load, positive, workspace};
use integrators::mlt::{MltSettings, veach};
use integrators::output::{write_exr, write_png};
use integrators::render::Settings;

fn run() -> Result<(), String> {
    let (mut seconds, mut scale) = (30.0, 0.5);
    let args: Vec<String> = std::env::args().skip(1).collect();
    for pair in args.chunks(2) {
        match pair {
            [flag, value] if flag == "--seconds" => seconds = positive(flag, value)?,
            [flag, value] if flag == "--scale" => scale = positive(flag, value)?.min(1.0),
            _ => return Err(format!("unknown option {}", pair.join(" "))),
        }
    }
    let scene = load(
        "../shared/scenes/aether/veach_door/door-mlt-aether.xml",
        scale,
    )?;
    let mlt = MltSettings::for_scene(&scene);
    let settings = Settings {
        progress: true,
        time_limit: Some(Duration::from_secs_f64(seconds)),
        ..Settings::new(u32::MAX / 2, 1)
    };
    let (r, statistics) = veach::render(&scene, &mlt, &settings, &AtomicBool::new(false))?;
    println!("mutation          tried   with light   mean acceptance");
    for (kind, tried, lit, accepted) in statistics.rows() {
        println!(
            "{:<14} {tried:>9} {lit:>12} {accepted:>17.3}",
            format!("{kind:?}")
        );
    }
    let (w, h) = (scene.film.width, scene.film.height);
    let dir = workspace().join("target/examples");
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let image = r.film.image();
    write_exr(&dir.join("mlt.exr"), w, h, &image, 1, r.seconds)?;
    write_png(&dir.join("mlt.png"), w, h, &image, 0.0)?;
    println!(
        "mlt: {w}×{h}, {:.1} s, {:.0} mutations/s -> {}",
        r.seconds,
        r.samples as f64 / r.seconds,
        dir.join("mlt.png").display()
    );
    Ok(())
}

fn main() {
    if let Err(e) = run() {
        eprintln!("mlt: {e}");
        std::process::exit(1);
    }
}
