//! Each Metropolis method (Veach's path-space MLT, PSSMLT and multiplexed
//! MLT) converges to BDPT's image on the built-in Cornell box: per-pixel
//! differences consistent with the per-pixel variances over independent
//! renders (a t-test at level 1 % whose failure rate may not exceed 1 %
//! plus three binomial deviations), and image means within 1 % with a
//! standard error below a third of that.

use std::sync::OnceLock;
use std::sync::atomic::AtomicBool;

use aether_strategies::scene::Scene;

use integrators::cornell::cornell_box;
use integrators::mlt::{MltSettings, Variant, render_mlt};
use integrators::render::{Settings, render};
use tests::{Estimate, assert_agree};

const RENDERS: u32 = 8;

/// The box of the convergence tests.
fn scene() -> Scene {
    let mut scene = cornell_box(16, 16, 1);
    scene.integrator.max_depth = 5;
    scene.film.filter = "box".into();
    scene
}

/// BDPT's estimate of the box, rendered once for all three tests.
fn bdpt() -> &'static Estimate {
    static BDPT: OnceLock<Estimate> = OnceLock::new();
    BDPT.get_or_init(|| Estimate::of(&mut scene(), "bdpt", RENDERS, 128))
}

fn converges(variant: Variant, name: &str, mutations_per_pixel: u32) {
    let scene = scene();
    let stop = AtomicBool::new(false);
    let mlt = MltSettings {
        variant,
        bootstrap: 50_000,
        ..MltSettings::default()
    };
    let images: Vec<_> = (1..=u64::from(RENDERS))
        .map(|seed| {
            let settings = Settings::new(mutations_per_pixel, seed);
            let r = render_mlt(&scene, mlt, &settings, &stop).unwrap();
            assert!(r.complete);
            r.film.image()
        })
        .collect();
    let estimate = Estimate::from_images(name, &images);
    assert_agree("Cornell box", (&estimate, bdpt()), None, None, 1e-2);
}

#[test]
fn pssmlt_converges_to_bdpt_on_the_built_in_cornell_box() {
    converges(Variant::Primary, "pssmlt", 256);
}

#[test]
fn multiplexed_mlt_converges_to_bdpt_on_the_built_in_cornell_box() {
    converges(Variant::Multiplexed, "mmlt", 1024);
}

#[test]
fn veach_mlt_converges_to_bdpt_on_the_built_in_cornell_box() {
    converges(Variant::Veach, "mlt", 1024);
}

#[test]
fn every_variant_depends_on_the_seed_not_on_the_threads() {
    let scene = cornell_box(12, 12, 1);
    let stop = AtomicBool::new(false);
    for variant in [Variant::Veach, Variant::Primary, Variant::Multiplexed] {
        let mlt = MltSettings {
            variant,
            bootstrap: 2_000,
            chains: 4,
            ..MltSettings::default()
        };
        let run = |threads, seed| {
            let settings = Settings {
                threads: Some(threads),
                ..Settings::new(16, seed)
            };
            render_mlt(&scene, mlt, &settings, &stop)
                .unwrap()
                .film
                .image()
        };
        let one = run(1, 3);
        assert_eq!(one, run(2, 3), "{variant:?}");
        assert_ne!(one, run(2, 4), "{variant:?}");
        assert!(one.iter().flatten().all(|v| v.is_finite()), "{variant:?}");
    }
    // The render loop's dispatch by name reaches them too.
    for name in ["mlt", "pssmlt", "mmlt"] {
        let mut named = cornell_box(12, 12, 1);
        named.integrator.name = name.into();
        named.integrator.metropolis.luminance_samples = 500;
        let r = render(&named, &Settings::new(2, 1), &stop).unwrap();
        assert_eq!(r.samples, 2 * 12 * 12, "{name}: mutations");
    }
}

/// A time limit already past when the render starts (as on a loaded
/// machine with a short budget) still gives every variant a lit image: the
/// bootstrap and each chain's first batch of mutations run regardless (the
/// quick report's Veach-MLT door at 0.2 s came back black when they did not).
#[test]
fn a_time_limit_shorter_than_the_bootstrap_still_gives_an_image() {
    let scene = cornell_box(12, 12, 1);
    let stop = AtomicBool::new(false);
    for variant in [Variant::Veach, Variant::Primary, Variant::Multiplexed] {
        let mlt = MltSettings {
            variant,
            bootstrap: 20_000,
            chains: 4,
            ..MltSettings::default()
        };
        let settings = Settings {
            time_limit: Some(std::time::Duration::ZERO),
            ..Settings::new(64, 1)
        };
        let r = render_mlt(&scene, mlt, &settings, &stop).unwrap();
        let image = r.film.image();
        assert!(r.samples >= 4, "{variant:?}: {} mutations", r.samples);
        assert!(!r.complete, "{variant:?} cannot finish in no time");
        assert!(image.iter().flatten().all(|v| v.is_finite()), "{variant:?}");
        let lit = image.iter().filter(|p| p.iter().any(|&v| v > 0.0)).count();
        assert!(
            lit > image.len() / 2,
            "{variant:?}: {lit} of {} pixels lit",
            image.len()
        );
    }
}
