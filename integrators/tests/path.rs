//! The path tracer through the render loop: a closed room that emits L and
//! reflects ρ everywhere is L / (1 − ρ) bright in every pixel.

use std::collections::HashMap;
use std::sync::atomic::AtomicBool;

use aether_strategies::scene::Scene;
use integrators::render::{Settings, render};

fn furnace_room() -> Scene {
    let dir = std::env::temp_dir().join(format!("aether-path-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // One file per call: the tests run in parallel.
    static NEXT: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let n = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let path = dir.join(format!("furnace{n}.xml"));
    std::fs::write(
        &path,
        "<scene version=\"0.5.0\">
            <integrator type=\"path\"><integer name=\"maxDepth\" value=\"-1\"/><integer name=\"rrDepth\" value=\"3\"/></integrator>
            <shape type=\"cube\"><boolean name=\"flipNormals\" value=\"true\"/>
                <bsdf type=\"diffuse\"><rgb name=\"reflectance\" value=\"0.5\"/></bsdf>
                <emitter type=\"area\"><rgb name=\"radiance\" value=\"1\"/></emitter></shape>
            <sensor type=\"perspective\"><float name=\"fov\" value=\"70\"/>
                <transform name=\"toWorld\"><lookat origin=\"0.1, 0.2, 0\" target=\"1, 0.3, 0.1\" up=\"0, 0, 1\"/></transform>
                <film type=\"hdrfilm\"><integer name=\"width\" value=\"16\"/><integer name=\"height\" value=\"12\"/>
                <rfilter type=\"tent\"/></film></sensor>
        </scene>",
    )
    .unwrap();
    Scene::load(&path, &HashMap::new()).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn the_path_tracer_renders_a_furnace_at_l_over_one_minus_rho() {
    let scene = furnace_room();
    assert_eq!(scene.integrator.name, "path");
    let settings = Settings {
        spp: 96,
        seed: 3,
        time_limit: None,
        threads: None,
        progress: false,
    };
    let r = render(&scene, &settings, &AtomicBool::new(false)).unwrap();
    assert!(r.complete);
    assert_eq!(r.film.dropped(), 0);
    let image = r.film.image();
    let n = image.len() as f64;
    let mean = image.iter().map(|c| f64::from(c[0])).sum::<f64>() / n;
    let var = image
        .iter()
        .map(|c| (f64::from(c[0]) - mean).powi(2))
        .sum::<f64>()
        / (n - 1.0);
    // Every pixel estimates the same value: the pixel spread is the noise.
    let error = (var / n).sqrt();
    println!("furnace: mean {mean:.5} ± {error:.5} over {n} pixels (expected 2)");
    assert!(error < 3e-3, "{error}");
    assert!((mean - 2.0).abs() < 1e-2, "{mean}");
}

#[test]
fn direct_lighting_stops_after_one_bounce() {
    let mut scene = furnace_room();
    scene.integrator.name = "direct".to_string();
    let settings = Settings {
        spp: 32,
        seed: 5,
        time_limit: None,
        threads: None,
        progress: false,
    };
    let r = render(&scene, &settings, &AtomicBool::new(false)).unwrap();
    let image = r.film.image();
    let n = image.len() as f64;
    let mean = image.iter().map(|c| f64::from(c[0])).sum::<f64>() / n;
    // Emission seen directly, plus one bounce of it: L + ρ L.
    println!("direct: mean {mean:.5} (expected 1.5)");
    assert!((mean - 1.5).abs() < 5e-3, "{mean}");
}
