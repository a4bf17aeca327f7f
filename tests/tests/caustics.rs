//! Veach's MLT where its perturbations apply: the caustic room
//! ([`tests::caustic_room`]), a smooth glass sphere focusing a small light
//! onto a diffuse floor, seen directly and in a smooth mirror sphere.
//!
//! With each mutation alone and with all four, Veach's MLT agrees with
//! BDPT: image means within 0.5 % (a standard error below a third of that)
//! and per-pixel differences consistent with the per-pixel variances over
//! 8 independent renders (a t-test at level 1 %, whose failure rate may not
//! exceed 1 % plus three binomial deviations). A Metropolis image's pixels
//! share one normalisation, so the error of its mean is measured from how
//! the renders' means vary, not from its pixels' variances. Each perturbation's
//! acceptance rate there is printed and must be non-zero.
//!
//! A perturbation alone never changes a path's length or its light vertex,
//! so its chain is not ergodic: the image is right only because the chains
//! start from paths resampled in proportion to their contribution. Many
//! short chains make that start-up distribution the target's.

use std::sync::OnceLock;
use std::sync::atomic::AtomicBool;

use aether_strategies::mutations::Kind;
use aether_strategies::scene::Scene;
use integrators::mlt::veach;
use integrators::mlt::{MltSettings, Variant};
use integrators::render::Settings;
use tests::{Estimate, assert_agree, caustic_room};

const RENDERS: u32 = 8;

/// 16 × 12 pixels, paths of up to 6 edges.
fn scene() -> Scene {
    caustic_room(16, 12, 6)
}

fn bdpt() -> &'static Estimate {
    static BDPT: OnceLock<Estimate> = OnceLock::new();
    BDPT.get_or_init(|| Estimate::of(&mut scene(), "bdpt", RENDERS, 1536))
}

/// Veach's MLT with the mutation frequencies `mix` (bidirectional, lens,
/// caustic, multi-chain) agrees with BDPT; returns each mutation's
/// proposals and mean acceptance over the renders.
fn agrees(name: &str, mix: [f64; 4], mutations_per_pixel: u32) -> [(Kind, u64, f64); 4] {
    let scene = scene();
    let stop = AtomicBool::new(false);
    let mlt = MltSettings {
        variant: Variant::Veach,
        bootstrap: 40_000,
        chains: 1024,
        mutations: mix,
        ..MltSettings::default()
    };
    let mut rows = Kind::ALL.map(|k| (k, 0, 0.0));
    let images: Vec<_> = (1..=u64::from(RENDERS))
        .map(|seed| {
            let settings = Settings::new(mutations_per_pixel, seed);
            let (r, statistics) = veach::render(&scene, &mlt, &settings, &stop).unwrap();
            assert!(r.complete);
            for (row, (_, n, _, a)) in rows.iter_mut().zip(statistics.rows()) {
                row.2 += a * n as f64;
                row.1 += n;
            }
            r.film.image()
        })
        .collect();
    for row in &mut rows {
        row.2 /= row.1.max(1) as f64;
        println!(
            "{name}: {:?}: {} proposals, mean acceptance {:.3}",
            row.0, row.1, row.2
        );
    }
    let estimate = Estimate {
        correlated_pixels: true,
        ..Estimate::from_images(name, &images)
    };
    assert_agree("caustic room", (&estimate, bdpt()), None, None, 5e-3);
    rows
}

/// The acceptance of `kind` in `rows` is positive.
fn accepted(rows: &[(Kind, u64, f64); 4], kind: Kind) {
    let (_, n, a) = rows[kind as usize];
    assert!(n > 0 && a > 0.0, "{kind:?}: {n} proposals, acceptance {a}");
}

#[test]
fn veach_mlt_with_all_mutations_agrees_with_bdpt_on_a_caustic() {
    let rows = agrees("all four", [1.0; 4], 256);
    for kind in Kind::ALL {
        accepted(&rows, kind);
    }
}

#[test]
fn veach_mlt_with_each_mutation_alone_agrees_with_bdpt_on_a_caustic() {
    for (i, kind) in Kind::ALL.into_iter().enumerate() {
        let mut mix = [0.0; 4];
        mix[i] = 1.0;
        let rows = agrees(&format!("{kind:?} alone"), mix, 256);
        accepted(&rows, kind);
    }
}
