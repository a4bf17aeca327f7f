//! Gradient-domain path tracing converges to the path tracer's image: on
//! the built-in Cornell box and on Aether's cbox-sphere scene, its primal
//! image agrees with path tracing pixel by pixel (a t-test at level 1 %
//! whose failure rate may not exceed 1 % plus three binomial deviations)
//! and in the mean (within 1 %, with a standard error below a third of
//! that); its gradients agree pixel by pixel with the differences of
//! neighbouring path-traced pixels; its L2 reconstruction keeps the
//! primal's mean, and its L1 reconstruction's mean is within 1 % of the
//! path tracer's (with a standard error below 0.5 %). Pixels that see the light are left out of the means, as
//! in the agreement tests. Each test takes about a minute.

use std::collections::HashMap;
use std::path::Path;
use std::sync::atomic::AtomicBool;

use aether_strategies::lights::Lights;
use aether_strategies::scene::Scene;
use integrators::cornell::cornell_box;
use integrators::gradient::{GradientPathTracer, render_gradients};
use integrators::poisson::differences;
use integrators::render::{Settings, render};
use tests::{Estimate, agreement, assert_agree, seeing};

const RENDERS: u32 = 8;

fn check(name: &str, scene: &mut Scene, gpt_spp: u32, path_spp: u32) {
    let lights = Lights::new(scene).expect("a lit scene");
    let edges = seeing(scene, |v| lights.emitter_of(v).is_some());
    let w = scene.film.width as usize;
    let stop = AtomicBool::new(false);
    let mut images: [Vec<Vec<[f32; 3]>>; 4] = Default::default();
    let tracer = GradientPathTracer::new(scene).unwrap();
    for seed in 1..=u64::from(RENDERS) {
        let g = render_gradients(scene, &tracer, &Settings::new(gpt_spp, seed), &stop).unwrap();
        assert_eq!(g.dropped, 0, "{name}: samples were dropped");
        let mut l2 = scene.integrator.gradient;
        l2.l1 = false;
        let l1 = g.reconstruct(&scene.integrator.gradient);
        let l2 = g.reconstruct(&l2);
        // The L2 solution keeps the primal's mean: the gradient terms'
        // normal equations sum to zero over the image.
        let mean = |image: &[[f32; 3]]| image.iter().flatten().map(|&v| f64::from(v)).sum::<f64>();
        let (m2, mp) = (mean(&l2), mean(&g.primal));
        assert!(
            (m2 / mp - 1.0).abs() < 1e-5,
            "{name}: L2 mean {m2}, primal {mp}"
        );
        for (k, image) in [g.primal, g.dx, g.dy, l1].into_iter().enumerate() {
            assert!(image.iter().flatten().all(|v| v.is_finite()));
            images[k].push(image);
        }
    }
    let [primal, dx, dy, l1] = ["GPT primal", "GPT dx", "GPT dy", "GPT L1"]
        .map(|label| label)
        .into_iter()
        .zip(&images)
        .map(|(label, images)| Estimate::from_images(label, images))
        .collect::<Vec<_>>()
        .try_into()
        .unwrap();
    scene.integrator.name = "path".into();
    let paths: Vec<Vec<[f32; 3]>> = (1..=u64::from(RENDERS))
        .map(|seed| {
            render(scene, &Settings::new(path_spp, 100 + seed), &stop)
                .unwrap()
                .film
                .image()
        })
        .collect();
    let path = Estimate::from_images("path", &paths);
    let (path_dx, path_dy): (Vec<_>, Vec<_>) =
        paths.iter().map(|p| differences(p, w as u32)).unzip();
    let (path_dx, path_dy) = (
        Estimate::from_images("path dx", &path_dx),
        Estimate::from_images("path dy", &path_dy),
    );

    assert_agree(name, (&primal, &path), None, Some(&edges), 1e-2);
    for (gradient, reference) in [(&dx, &path_dx), (&dy, &path_dy)] {
        let r = agreement(gradient, reference, None, None);
        let rate = r.failures as f64 / r.tested as f64;
        println!(
            "{name}: {}: {} of {} pixels fail the 1 % test ({:.2} %, allowed {:.2} %)",
            gradient.integrator,
            r.failures,
            r.tested,
            100.0 * rate,
            100.0 * r.allowed
        );
        assert!(
            r.tested > w * w / 2 && rate <= r.allowed,
            "{name}: {}",
            gradient.integrator
        );
    }
    // L1 is biased at finite sample counts (a median rather than a mean
    // of the noise), but consistent: its mean must be within 1 % of the
    // path tracer's, with a standard error that resolves 1 % at 2σ (its
    // per-render noise is larger than the primal's).
    let r = agreement(&l1, &path, None, Some(&edges));
    println!(
        "{name}: GPT L1 mean differs from path by {:+.3} % ± {:.3} %",
        100.0 * r.relative_difference,
        100.0 * r.relative_error
    );
    assert!(r.relative_difference.abs() < 1e-2 && r.relative_error < 0.5e-2);
}

#[test]
fn gradient_domain_tracing_converges_on_the_built_in_cornell_box() {
    let mut scene = cornell_box(24, 24, 1);
    scene.film.filter = "box".into();
    check("Cornell box", &mut scene, 256, 1024);
}

#[test]
fn gradient_domain_tracing_converges_on_cbox_sphere() {
    let file = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../shared/scenes/aether/cbox-sphere/cbox-sphere-gpt.xml");
    let mut scene = Scene::load(&file, &HashMap::new()).unwrap_or_else(|e| panic!("{e}"));
    let film = &mut scene.film;
    (film.width, film.height, film.crop) = (24, 24, [0, 0, 24, 24]);
    check("cbox-sphere", &mut scene, 512, 768);
}
