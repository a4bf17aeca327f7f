//! The benchmark suite of the integrators: for each integrator and scene
//! (the built-in Cornell box, and from ../shared, when present, Aether's
//! cbox-sphere, Veach's bidirectional scene and Veach's door), samples per
//! second and rays per second on all cores, the share of time spent in ray
//! casting, heap allocations per sample, and the speed-up of all cores over
//! one; then BDPT's time at maximum depth 16 over depth 8 at equal samples.
//! Printed as a table and written as CSV (`target/bench/integrators.csv`).
//!
//! `cargo bench -p integrators`. Set `AETHER_BENCH_SIZE` for another film
//! width (default 128), `AETHER_BENCH_SPP` for another number of samples
//! per pixel (default 4) and `AETHER_BENCH_RUNS` for another number of runs
//! (default 3).
//!
//! - Throughput: the median of the runs, taken in turn on all cores and on
//!   one (all, one, all, one, ...), so that a burst of load from another
//!   process on a shared machine moves one run of each, not a whole column;
//!   BDPT's depth ratio alternates the two depths the same way.
//! - Ray share: every ray is timed in a separate render (timing costs a
//!   few percent, so the throughput columns come from an untimed render),
//!   and the time summed over threads is divided by threads × wall time.
//! - Allocations per sample: the difference in heap allocations between a
//!   one-thread render at the given sample count and one at a single
//!   sample per pixel, over the difference in samples, so that the render
//!   loop's fixed costs (film, tiles, threads) cancel.
//! - Gradient-domain tracing's times leave out its reconstruction.
//! - Metropolis rows (Veach's MLT, PSSMLT, multiplexed MLT) count
//!   mutations as samples, after a bootstrap of one sample per pixel.

use std::alloc::System;
use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::Path;
use std::sync::atomic::AtomicBool;

use aether_strategies::geometry::time_rays;
use aether_strategies::scene::Scene;
use integrators::cornell::cornell_box;
use integrators::render::{Rendered, Settings, render};
use stats_alloc::{INSTRUMENTED_SYSTEM, Region, StatsAlloc};

#[global_allocator]
static GLOBAL: &StatsAlloc<System> = &INSTRUMENTED_SYSTEM;

fn env_or(name: &str, default: u32) -> u32 {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

fn run(
    scene: &mut Scene,
    integrator: &str,
    spp: u32,
    threads: Option<usize>,
) -> Result<Rendered, String> {
    scene.integrator.name = integrator.to_string();
    // Metropolis methods bootstrap with one sample per pixel, so that the
    // rows measure mutations.
    scene.integrator.metropolis.luminance_samples = scene.film.width * scene.film.height;
    let settings = Settings {
        threads,
        ..Settings::new(spp, 1)
    };
    render(scene, &settings, &AtomicBool::new(false))
}

/// One row of the suite.
struct Row {
    samples_per_second: f64,
    rays_per_second: f64,
    ray_share: f64,
    allocations_per_sample: f64,
    one_thread: f64,
}

/// The middle value (the mean of the two middle ones for an even count).
fn median(mut values: Vec<f64>) -> f64 {
    values.sort_by(f64::total_cmp);
    let n = values.len();
    match n {
        0 => f64::NAN,
        _ if n % 2 == 1 => values[n / 2],
        _ => 0.5 * (values[n / 2 - 1] + values[n / 2]),
    }
}

/// Samples/s and rays/s on all cores, and samples/s on one: medians of
/// `runs` runs of each, alternating. Also the heap allocations and samples
/// of the first one-thread run.
fn throughput(
    scene: &mut Scene,
    integrator: &str,
    spp: u32,
    runs: u32,
) -> Result<([f64; 3], (usize, u64)), String> {
    let mut rates: [Vec<f64>; 3] = Default::default();
    let mut first = None;
    for _ in 0..runs.max(1) {
        let all = run(scene, integrator, spp, None)?;
        rates[0].push(all.samples as f64 / all.seconds);
        rates[1].push(all.rays as f64 / all.seconds);
        let region = Region::new(GLOBAL);
        let one = run(scene, integrator, spp, Some(1))?;
        first.get_or_insert((region.change().allocations, one.samples));
        rates[2].push(one.samples as f64 / one.seconds);
    }
    Ok((rates.map(median), first.unwrap_or_default()))
}

fn measure(scene: &mut Scene, integrator: &str, spp: u32, runs: u32) -> Result<Row, String> {
    let ([samples_per_second, rays_per_second, one_thread], (allocations, samples)) =
        throughput(scene, integrator, spp, runs)?;
    time_rays(true);
    let timed = run(scene, integrator, spp, None);
    time_rays(false);
    let timed = timed?;
    let threads = rayon::current_num_threads() as f64;
    let small = Region::new(GLOBAL);
    let one_spp = run(scene, integrator, 1, Some(1))?;
    let small = small.change().allocations;
    Ok(Row {
        samples_per_second,
        rays_per_second,
        ray_share: timed.ray_seconds / (threads * timed.seconds),
        // Fixed costs vary by an allocation or two: no negative rates.
        allocations_per_sample: ((allocations as f64 - small as f64)
            / (samples as f64 - one_spp.samples as f64).max(1.0))
        .max(0.0),
        one_thread,
    })
}

fn table(
    label: &str,
    scene: &mut Scene,
    (spp, runs): (u32, u32),
    integrators: &[&str],
    csv: &mut String,
) {
    println!(
        "\n{label} ({}×{}, {spp} spp, max depth {}, medians of {runs} runs)",
        scene.film.width, scene.film.height, scene.integrator.max_depth
    );
    println!(
        "{:<8} {:>12} {:>9} {:>10} {:>12} {:>14} {:>8}",
        "", "samples/s", "Mrays/s", "ray share", "allocs/spl", "1-thread smp/s", "scaling"
    );
    for name in integrators {
        match measure(scene, name, spp, runs) {
            Ok(r) => {
                println!(
                    "{name:<8} {:>12.0} {:>9.2} {:>9.0}% {:>12.3} {:>14.0} {:>7.2}×",
                    r.samples_per_second,
                    r.rays_per_second / 1e6,
                    100.0 * r.ray_share,
                    r.allocations_per_sample,
                    r.one_thread,
                    r.samples_per_second / r.one_thread
                );
                let _ = writeln!(
                    csv,
                    "{label},{name},{},{},{spp},{:.0},{:.0},{:.4},{:.4},{:.0},{:.3}",
                    scene.film.width,
                    scene.film.height,
                    r.samples_per_second,
                    r.rays_per_second,
                    r.ray_share,
                    r.allocations_per_sample,
                    r.one_thread,
                    r.samples_per_second / r.one_thread
                );
            }
            Err(e) => println!("{name:<8} {e}"),
        }
    }
}

/// A scene from ../shared at `width` pixels, if it is there.
fn shared(file: &str, width: u32) -> Result<Scene, String> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../shared/scenes/aether")
        .join(file);
    let mut scene = Scene::load(&path, &HashMap::new()).map_err(|e| e.to_string())?;
    scene
        .film
        .scale_to_width(width)
        .map_err(|e| e.to_string())?;
    // Aether's integrators stop at depth 6 where a scene sets no limit.
    if scene.integrator.max_depth < 0 {
        scene.integrator.max_depth = 6;
    }
    Ok(scene)
}

fn main() {
    let size = env_or("AETHER_BENCH_SIZE", 128);
    let spp = env_or("AETHER_BENCH_SPP", 4);
    let runs = env_or("AETHER_BENCH_RUNS", 3).max(1);
    let mut csv = String::from(
        "scene,integrator,width,height,spp,samples_per_second,rays_per_second,ray_share,allocations_per_sample,one_thread_samples_per_second,scaling\n",
    );
    let all = [
        "direct", "path", "light", "bdpt", "tridir", "gpt", "mlt", "pssmlt", "mmlt",
    ];
    let mut cbox = cornell_box(size, size, spp);
    table(
        "built-in Cornell box",
        &mut cbox,
        (spp, runs),
        &all,
        &mut csv,
    );
    let others = [
        ("cbox-sphere", "cbox-sphere/cbox-sphere-path.xml"),
        ("Veach's bidirectional scene", "veach_bidir/bidir-bdpt.xml"),
        ("Veach's door", "veach_door/door-bdpt.xml"),
    ];
    for (label, file) in others {
        match shared(file, size) {
            Ok(mut scene) => table(label, &mut scene, (spp, runs), &all, &mut csv),
            Err(e) => println!("\n{label} skipped: {e}"),
        }
    }

    let mut times: [Vec<f64>; 2] = Default::default();
    for _ in 0..runs {
        for (i, depth) in [8, 16].into_iter().enumerate() {
            cbox.integrator.max_depth = depth;
            times[i].push(run(&mut cbox, "bdpt", spp, None).map_or(f64::NAN, |r| r.seconds));
        }
    }
    let seconds = times.map(median);
    println!(
        "\nBDPT on the Cornell box, max depth 16 over max depth 8 (medians of {runs}): \
         {:.2} s / {:.2} s = {:.2}",
        seconds[1],
        seconds[0],
        seconds[1] / seconds[0]
    );
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/bench");
    let file = dir.join("integrators.csv");
    match std::fs::create_dir_all(&dir).and_then(|()| std::fs::write(&file, csv)) {
        Ok(()) => println!("written to {}", file.display()),
        Err(e) => println!("cannot write {}: {e}", file.display()),
    }
}
