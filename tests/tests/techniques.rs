//! BDPT's (s, t) techniques through a thin lens: every technique of a row
//! estimates the same light (its unweighted image has the row's mean), the
//! MIS-weighted images of a row add up to it, and s = 0, light paths that
//! reach the lens's aperture, is one of them.

use std::sync::atomic::AtomicBool;

use integrators::bdpt::Bdpt;
use integrators::render::{Settings, render_with};
use tests::scene_from;

const RENDERS: u64 = 6;

/// A diffuse room seen through a thin lens with a wide aperture (so that
/// light paths find it), lit by a small sphere.
fn thin_lens_room() -> aether_strategies::scene::Scene {
    scene_from(
        r#"<scene version="0.5.0">
            <integrator type="bdpt"><integer name="maxDepth" value="2"/></integrator>
            <shape type="cube"><boolean name="flipNormals" value="true"/>
                <bsdf type="diffuse"><rgb name="reflectance" value="0.6, 0.55, 0.5"/></bsdf></shape>
            <shape type="sphere"><point name="center" x="0" y="0.6" z="0"/><float name="radius" value="0.2"/>
                <emitter type="area"><rgb name="radiance" value="4"/></emitter></shape>
            <sensor type="thinlens"><float name="fov" value="70"/>
                <float name="apertureRadius" value="0.3"/><float name="focusDistance" value="1.2"/>
                <transform name="toWorld"><lookat origin="0, -0.2, 0.9" target="0, -0.3, 0" up="0, 1, 0"/></transform>
                <film type="hdrfilm"><integer name="width" value="12"/><integer name="height" value="12"/>
                <rfilter type="box"/></film></sensor>
        </scene>"#,
        &[],
    )
}

/// Mean over pixels and channels of image `(s, t)`, weighted and
/// unweighted, for each of `RENDERS` renders.
fn technique_means(s: usize, t: usize) -> Vec<[f64; 2]> {
    let scene = thin_lens_room();
    (1..=RENDERS)
        .map(|seed| {
            let bdpt = Bdpt::new(&scene).unwrap().with_technique_images(3);
            let settings = Settings::new(256, seed);
            let r = render_with(&scene, &bdpt, &settings, &AtomicBool::new(false)).unwrap();
            let images = bdpt
                .technique_images()
                .unwrap()
                .images(s, t, r.samples)
                .unwrap();
            images.map(|image| {
                let sum: f64 = image.iter().flatten().map(|&c| f64::from(c)).sum();
                sum / image.len() as f64
            })
        })
        .collect()
}

/// Mean and standard error over renders.
fn stats(values: impl Iterator<Item = f64> + Clone) -> (f64, f64) {
    let n = values.clone().count() as f64;
    let mean = values.clone().sum::<f64>() / n;
    let var = values.map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, (var / n).sqrt())
}

#[test]
fn light_paths_that_reach_the_lens_are_a_technique() {
    // Paths of three vertices: lens, wall, light.
    let rows: Vec<_> = (0..=3).map(|s| technique_means(s, 3 - s)).collect();
    let unweighted: Vec<(f64, f64)> = rows.iter().map(|r| stats(r.iter().map(|m| m[1]))).collect();
    let weighted_sum = stats((0..RENDERS as usize).map(|i| rows.iter().map(|r| r[i][0]).sum()));
    for (s, (m, e)) in unweighted.iter().enumerate() {
        println!("s = {s}, t = {}: unweighted {m:.5} ± {e:.5}", 3 - s);
    }
    println!(
        "weighted sum: {:.5} ± {:.5}",
        weighted_sum.0, weighted_sum.1
    );
    // s = 2, t = 1 (direct light sampling) is the reference: the least noisy here.
    let (reference, reference_error) = unweighted[2];
    let (lens, lens_error) = unweighted[0];
    assert!(lens > 0.0, "light paths reached the lens");
    let within = |m: f64, e: f64| {
        (m - reference).abs() < 4.0 * (e * e + reference_error * reference_error).sqrt()
    };
    assert!(
        within(lens, lens_error),
        "s = 0: {lens} ± {lens_error} vs {reference}"
    );
    assert!(
        within(weighted_sum.0, weighted_sum.1),
        "weighted: {weighted_sum:?} vs {reference}"
    );
    let weighted_lens = stats(rows[0].iter().map(|m| m[0]));
    assert!(weighted_lens.0 > 0.0, "s = 0 carries weight");
}
