//! Every integrator through the render loop: a closed room that emits L and
//! reflects ρ everywhere is L / (1 − ρ) bright in every pixel.

use std::sync::atomic::AtomicBool;

use aether_strategies::scene::Scene;
use integrators::render::{Settings, render};
use tests::scene_from;

fn furnace_room() -> Scene {
    scene_from(
        r#"<scene version="0.5.0">
            <integrator type="path"><integer name="maxDepth" value="-1"/><integer name="rrDepth" value="3"/></integrator>
            <shape type="cube"><boolean name="flipNormals" value="true"/>
                <bsdf type="diffuse"><rgb name="reflectance" value="0.5"/></bsdf>
                <emitter type="area"><rgb name="radiance" value="1"/></emitter></shape>
            <shape type="rectangle"><boolean name="portal" value="true"/></shape>
            <sensor type="perspective"><float name="fov" value="70"/>
                <transform name="toWorld"><lookat origin="0.1, 0.2, 0" target="1, 0.3, 0.1" up="0, 0, 1"/></transform>
                <film type="hdrfilm"><integer name="width" value="16"/><integer name="height" value="12"/>
                <rfilter type="tent"/></film></sensor>
        </scene>"#,
        &[],
    )
}

/// Renders the furnace room with `integrator` and returns the mean of the
/// red channel and its standard error (every pixel estimates the same
/// value, so the spread between pixels is the noise).
fn furnace(integrator: &str, spp: u32) -> (f64, f64, u64) {
    let mut scene = furnace_room();
    scene.integrator.name = integrator.to_string();
    let settings = Settings::new(spp, 3);
    let r = render(&scene, &settings, &AtomicBool::new(false)).unwrap();
    assert!(r.complete);
    let image = r.film.image();
    let n = image.len() as f64;
    let mean = image.iter().map(|c| f64::from(c[0])).sum::<f64>() / n;
    let var = image
        .iter()
        .map(|c| (f64::from(c[0]) - mean).powi(2))
        .sum::<f64>()
        / (n - 1.0);
    let error = (var / n).sqrt();
    println!("{integrator}: mean {mean:.5} ± {error:.5} over {n} pixels (expected 2)");
    (mean, error, r.film.dropped())
}

/// Within four standard errors of 2 (and the error itself small).
fn assert_furnace(integrator: &str, spp: u32) {
    let (mean, error, dropped) = furnace(integrator, spp);
    assert_eq!(dropped, 0);
    assert!(error < 6e-3, "{integrator}: {error}");
    assert!(
        (mean - 2.0).abs() < 4.0 * error + 1e-3,
        "{integrator}: {mean} ± {error}"
    );
}

#[test]
fn the_path_tracer_renders_a_furnace_at_l_over_one_minus_rho() {
    assert_furnace("path", 96);
}

#[test]
fn bdpt_renders_a_furnace_at_l_over_one_minus_rho() {
    assert_furnace("bdpt", 64);
}

#[test]
fn the_light_tracer_renders_a_furnace_at_l_over_one_minus_rho() {
    assert_furnace("light", 512);
}

#[test]
fn tridirectional_tracing_renders_a_furnace_at_l_over_one_minus_rho() {
    assert_furnace("tridir", 40);
}

#[test]
fn direct_lighting_stops_after_one_bounce() {
    let mut scene = furnace_room();
    scene.integrator.name = "direct".to_string();
    let settings = Settings::new(32, 5);
    let r = render(&scene, &settings, &AtomicBool::new(false)).unwrap();
    let image = r.film.image();
    let n = image.len() as f64;
    let mean = image.iter().map(|c| f64::from(c[0])).sum::<f64>() / n;
    // Emission seen directly, plus one bounce of it: L + ρ L.
    println!("direct: mean {mean:.5} (expected 1.5)");
    assert!((mean - 1.5).abs() < 5e-3, "{mean}");
}
