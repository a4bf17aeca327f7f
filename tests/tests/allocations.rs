//! No integrator allocates per sample once its threads are warm: the
//! heap allocations of a one-thread render of the built-in Cornell box at
//! many samples per pixel, less those of one at a single sample per pixel
//! (the render loop's fixed costs and the pools' warm-up cancel), stay
//! below one per hundred samples. Before the pooled buffers a path tracer
//! allocated 0.065 times per sample, BDPT 0.46 and tridirectional tracing
//! 1.7 (long paths and long technique lists outgrowing their inline
//! buffers). Counted, not timed: the count is the same on any machine up
//! to the few allocations by which thread start-up varies.

use std::alloc::System;
use std::sync::atomic::AtomicBool;

use integrators::cornell::cornell_box;
use integrators::render::{Settings, render};
use stats_alloc::{INSTRUMENTED_SYSTEM, Region, StatsAlloc};

#[global_allocator]
static GLOBAL: &StatsAlloc<System> = &INSTRUMENTED_SYSTEM;

/// Allocations and samples of a one-thread render of `integrator`.
fn allocations(integrator: &str, spp: u32) -> (usize, u64) {
    let mut scene = cornell_box(16, 16, spp);
    scene.integrator.name = integrator.to_string();
    // The Metropolis methods bootstrap with one sample per pixel, so that
    // `spp` counts their mutations.
    scene.integrator.metropolis.luminance_samples = 16 * 16;
    let settings = Settings {
        threads: Some(1),
        ..Settings::new(spp, 1)
    };
    let region = Region::new(GLOBAL);
    let rendered = render(&scene, &settings, &AtomicBool::new(false))
        .unwrap_or_else(|e| panic!("{integrator}: {e}"));
    (region.change().allocations, rendered.samples)
}

#[test]
fn no_integrator_allocates_per_sample_in_steady_state() {
    let all = [
        "direct", "path", "light", "bdpt", "tridir", "gpt", "mlt", "pssmlt", "mmlt",
    ];
    let mut report = Vec::new();
    for integrator in all {
        let (few, few_samples) = allocations(integrator, 1);
        let (many, many_samples) = allocations(integrator, 32);
        let samples = many_samples.saturating_sub(few_samples).max(1);
        let per_sample = many.saturating_sub(few) as f64 / samples as f64;
        report.push(format!(
            "{integrator} {per_sample:.4} ({many} - {few} over {samples})"
        ));
        assert!(
            samples > 4_000,
            "{integrator}: {samples} samples are too few to count"
        );
        assert!(
            per_sample < 0.01,
            "{integrator} allocates {per_sample:.4} times per sample: {report:?}"
        );
    }
    println!("allocations per sample: {report:#?}");
}
