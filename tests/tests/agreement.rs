//! Agreement between integrators: path, light (where it can), BDPT and
//! tridirectional tracing converge to the same image on four scenes: the
//! built-in Cornell box, a room lit by a shaded point light with a mirror
//! sphere, a thin-lens view of a room, and a room lit through an opening.
//!
//! Each integrator renders a small image several times with independent
//! seeds. Per-pixel differences must be consistent with the per-pixel
//! variances: a t-test at level 1 % whose failure rate may not exceed 1 %
//! plus three binomial deviations. Image means must agree within 0.5 %,
//! with standard errors below a third of that (pixels that see a light
//! are left out of the means: their edge noise would need far more
//! samples; the per-pixel test covers them).

use aether_strategies::bsdf::Bsdf;
use aether_strategies::lights::Lights;
use aether_strategies::scene::Scene;
use integrators::cornell::cornell_box;
use tests::{Estimate, assert_agree, scene_from, seeing};

const RENDERS: u32 = 8;

/// A closed room two units wide, diffuse inside, seen by `sensor`, with
/// `content` (shapes and lights) and the integrator's depth limit.
fn room(sensor: &str, content: &str) -> String {
    format!(
        r#"<scene version="0.5.0">
            <integrator type="path"><integer name="maxDepth" value="4"/></integrator>
            <shape type="cube"><boolean name="flipNormals" value="true"/>
                <bsdf type="diffuse"><rgb name="reflectance" value="0.6, 0.55, 0.5"/></bsdf></shape>
            {content}
            <sensor type="{sensor}"><float name="fov" value="60"/>
                <float name="apertureRadius" value="0.08"/><float name="focusDistance" value="1.2"/>
                <transform name="toWorld"><lookat origin="0.1, -0.1, 0.95" target="-0.1, -0.5, 0" up="0, 1, 0"/></transform>
                <film type="hdrfilm"><integer name="width" value="20"/><integer name="height" value="20"/>
                <rfilter type="box"/></film></sensor>
        </scene>"#
    )
}

/// Estimates of each integrator, each compared with the first: image means
/// within 0.5 % (pixels that see a light left out of the means), and the
/// per-pixel test.
fn check(name: &str, scene: &mut Scene, integrators: &[(&str, u32)], skip: &[(&str, Vec<bool>)]) {
    let lights = Lights::new(scene).expect("a lit scene");
    let edges = seeing(scene, |v| lights.emitter_of(v).is_some());
    let (first, spp) = integrators[0];
    let reference = Estimate::of(scene, first, RENDERS, spp);
    for &(integrator, spp) in &integrators[1..] {
        let other = Estimate::of(scene, integrator, RENDERS, spp);
        let mask = skip
            .iter()
            .find(|(n, _)| *n == integrator)
            .map(|(_, m)| &m[..]);
        assert_agree(name, (&other, &reference), mask, Some(&edges), 5e-3);
    }
}

/// Pixels whose camera rays see a purely specular surface first: light
/// tracing cannot reach a pinhole through them.
fn seeing_mirrors(scene: &Scene) -> Vec<bool> {
    seeing(scene, |v| Bsdf::at(scene, v).is_some_and(|b| b.is_dirac()))
}

#[test]
fn integrators_agree_on_the_built_in_cornell_box() {
    let mut scene = cornell_box(20, 20, 1);
    scene.integrator.max_depth = 4;
    scene.film.filter = "box".into();
    let all = [("path", 768), ("bdpt", 128), ("light", 768), ("tridir", 96)];
    check("Cornell box", &mut scene, &all, &[]);
}

#[test]
fn integrators_agree_with_a_point_light_and_a_mirror_sphere() {
    // A small shade between the point light and the mirror keeps the light
    // from seeing it: a point light seen in a mirror is a path no path
    // tracer can sample. The rest of the room is lit directly; the shade is
    // black, so that it does not become a bright source right by the light.
    let content = r#"
        <shape type="sphere"><point name="center" x="-0.35" y="-0.65" z="-0.2"/><float name="radius" value="0.35"/>
            <bsdf type="conductor"><string name="material" value="none"/></bsdf></shape>
        <shape type="sphere"><point name="center" x="0.45" y="-0.7" z="0.1"/><float name="radius" value="0.3"/>
            <bsdf type="diffuse"><rgb name="reflectance" value="0.2, 0.6, 0.3"/></bsdf></shape>
        <shape type="rectangle"><transform name="toWorld"><scale value="0.08"/>
            <lookat origin="-0.045, 0.657, -0.026" target="-0.27, -0.309, -0.155" up="1, 0, 0"/></transform>
            <bsdf type="twosided"><bsdf type="diffuse"><rgb name="reflectance" value="0"/></bsdf></bsdf></shape>
        <emitter type="point"><point name="position" x="0" y="0.85" z="0"/><rgb name="intensity" value="3"/></emitter>"#;
    let mut scene = scene_from(&room("perspective", content), &[]);
    let mirrors = seeing_mirrors(&scene);
    assert!(mirrors.iter().any(|&m| m), "the camera sees the mirror");
    let all = [("bdpt", 256), ("path", 1024), ("light", 1024)];
    check(
        "point light and mirror",
        &mut scene,
        &all,
        &[("light", mirrors)],
    );
}

#[test]
fn integrators_agree_through_a_thin_lens() {
    let content = r#"
        <shape type="sphere"><point name="center" x="-0.3" y="-0.7" z="-0.3"/><float name="radius" value="0.3"/>
            <bsdf type="diffuse"><rgb name="reflectance" value="0.7, 0.3, 0.2"/></bsdf></shape>
        <shape type="sphere"><point name="center" x="0" y="0.7" z="0"/><float name="radius" value="0.12"/>
            <emitter type="area"><rgb name="radiance" value="6"/></emitter></shape>"#;
    let mut scene = scene_from(&room("thinlens", content), &[]);
    assert!(scene.camera.aperture_radius > 0.0);
    let all = [("path", 512), ("bdpt", 64), ("light", 768)];
    check("thin lens", &mut scene, &all, &[]);
}

#[test]
fn integrators_agree_on_light_through_an_opening() {
    // A floor at y = 0.4 with a 0.8 × 0.8 opening; the light is above it.
    let partition = "v -1 0.4 -1\nv 1 0.4 -1\nv 1 0.4 1\nv -1 0.4 1\n\
        v -0.4 0.4 -0.4\nv 0.4 0.4 -0.4\nv 0.4 0.4 0.4\nv -0.4 0.4 0.4\n\
        f 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n";
    let opening = "v -0.4 0.4 -0.4\nv 0.4 0.4 -0.4\nv 0.4 0.4 0.4\nv -0.4 0.4 0.4\nf 1 2 3 4\n";
    let content = r#"
        <shape type="obj"><string name="filename" value="partition.obj"/>
            <bsdf type="twosided"><bsdf type="diffuse"/></bsdf></shape>
        <shape type="obj"><string name="filename" value="opening.obj"/><boolean name="portal" value="true"/></shape>
        <shape type="sphere"><point name="center" x="0.3" y="0.75" z="0.2"/><float name="radius" value="0.1"/>
            <emitter type="area"><rgb name="radiance" value="30"/></emitter></shape>"#;
    let files = [("partition.obj", partition), ("opening.obj", opening)];
    let mut scene = scene_from(&room("perspective", content), &files);
    assert_eq!(scene.portals.len(), 1);
    let all = [
        ("path", 1024),
        ("bdpt", 256),
        ("tridir", 128),
        ("light", 2048),
    ];
    check("opening", &mut scene, &all, &[]);
}
