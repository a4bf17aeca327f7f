//! Loading every Aether scene: triangle, emitter and material counts, and
//! bad scenes with the message a user sees.

mod common;
use common::scenes;

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use aether_strategies::scene::{Emitter, Material, Scene};

/// (file, triangles, spheres, emitters, materials). The Cornell box and
/// cbox-sphere triangles follow from their mesh files (38; two spheres of
/// 1088 and six quads), mi.xml's from its five two-triangle meshes, and the
/// materials from the BSDFs the shapes reference; the veach_bidir and
/// veach_door triangle counts are regression values recorded from this loader.
const EXPECTED: &[(&str, usize, usize, usize, usize)] = &[
    ("cbox/cbox_path.xml", 38, 0, 1, 5),
    ("cbox/cbox_direct.xml", 38, 0, 1, 5),
    ("cbox/cbox_bidir.xml", 38, 0, 1, 5),
    ("cbox/cbox_mlt.xml", 38, 0, 1, 5),
    ("cbox/cbox_glass.xml", 38, 0, 1, 6),
    ("cbox-sphere/cbox-sphere-path.xml", 2 * 1088 + 12, 0, 1, 8),
    ("veach_mi/mi.xml", 12, 5, 5, 10),
    ("veach_bidir/bidir-path.xml", 3392, 0, 2, 11),
    ("veach_door/door-bdpt-aether.xml", 20764, 0, 1, 12),
];

#[test]
fn every_aether_scene_loads_with_its_counts() {
    let Some(dir) = scenes() else { return };
    let mut all = Vec::new();
    for entry in walk(&dir) {
        let scene = Scene::load(&entry, &HashMap::new()).unwrap_or_else(|e| panic!("{e}"));
        let name = entry.strip_prefix(&dir).unwrap().display().to_string();
        let spheres = scene.geometry.spheres().len();
        println!(
            "{name}: {} triangles, {spheres} spheres, {} emitters, {} materials, {}×{} at {} spp, {}",
            scene.geometry.triangle_count(),
            scene.emitters.len(),
            scene.materials.len(),
            scene.film.width,
            scene.film.height,
            scene.film.spp,
            scene.integrator.name
        );
        assert!(!scene.emitters.is_empty(), "{name} has no emitter");
        assert!(scene.geometry.triangle_count() + spheres > 0);
        for e in &scene.emitters {
            if let Emitter::Area { shape, .. } = e {
                assert!(
                    *shape < scene.shapes.len(),
                    "{name}: area light on shape {shape}"
                );
                assert_eq!(
                    scene.shapes[*shape].emitter.map(|i| &scene.emitters[i]),
                    Some(e)
                );
            }
        }
        all.push((name, scene));
    }
    assert!(all.len() >= 26, "{}", all.len());
    for &(file, triangles, spheres, emitters, materials) in EXPECTED {
        let (_, scene) = all
            .iter()
            .find(|(n, _)| n == file)
            .unwrap_or_else(|| panic!("{file} not loaded"));
        assert_eq!(scene.geometry.triangle_count(), triangles, "{file}");
        assert_eq!(scene.geometry.spheres().len(), spheres, "{file}");
        assert_eq!(scene.emitters.len(), emitters, "{file}");
        assert_eq!(scene.materials.len(), materials, "{file}");
    }
    let (_, cbox) = all.iter().find(|(n, _)| n == "cbox/cbox_path.xml").unwrap();
    // White, red, green, light, and the boxes' "box" material: five distinct BSDFs.
    assert_eq!(cbox.materials.len(), 5);
    assert!(matches!(cbox.materials[0], Material::Diffuse { .. }));
    let Emitter::Area { radiance, .. } = cbox.emitters[0] else {
        panic!()
    };
    assert!((radiance[0] - 20.71).abs() < 0.05, "{radiance:?}");
}

fn walk(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            out.extend(walk(&p));
        } else if p.extension().is_some_and(|x| x == "xml") {
            out.push(p);
        }
    }
    out.sort();
    out
}

fn load_str(xml: &str) -> String {
    let dir = std::env::temp_dir().join(format!("aether-scene-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(format!("s{}.xml", xml.len()));
    std::fs::write(&path, xml).unwrap();
    Scene::load(&path, &HashMap::new())
        .map(|_| ())
        .expect_err(xml)
        .to_string()
}

#[test]
fn bad_scenes_name_the_file_the_line_and_the_element() {
    let camera = "<sensor type=\"perspective\"/>";
    let e = load_str(&format!(
        "<scene>{camera}\n<shape type=\"obj\">\n<string name=\"filename\" value=\"nowhere.obj\"/>\n</shape></scene>"
    ));
    assert!(
        e.contains(":2: <shape type=\"obj\">") && e.contains("nowhere.obj"),
        "{e}"
    );
    let e = load_str(&format!(
        "<scene>{camera}\n<shape type=\"teapot\"/></scene>"
    ));
    assert!(
        e.contains(":2:") && e.contains("shape type 'teapot' is not supported"),
        "{e}"
    );
    let e = load_str(&format!(
        "<scene>{camera}\n<shape type=\"sphere\">\n<bsdf type=\"velvet\"/></shape></scene>"
    ));
    assert!(
        e.contains(":3: <bsdf type=\"velvet\">") && e.contains("not supported"),
        "{e}"
    );
    let e = load_str(&format!(
        "<scene>{camera}\n<shape type=\"sphere\"><float name=\"radius\" value=\"-1\"/></shape></scene>"
    ));
    assert!(e.contains("'radius' must be positive"), "{e}");
    let e = load_str(&format!(
        "<scene>{camera}\n<shape type=\"sphere\"><bsdf type=\"roughconductor\"><string name=\"material\" value=\"Unobtainium\"/></bsdf></shape></scene>"
    ));
    assert!(e.contains("metal 'Unobtainium' is not known"), "{e}");
    let e = load_str(&format!(
        "<scene>{camera}\n<emitter type=\"area\"/></scene>"
    ));
    assert!(e.contains("must be nested in a <shape>"), "{e}");
    let e = load_str("<scene>\n<shape type=\"sphere\"/></scene>");
    assert!(e.contains("no <sensor>"), "{e}");
    let e = load_str(
        "<scene><sensor type=\"perspective\">\n<film type=\"hdrfilm\"><integer name=\"width\" value=\"-5\"/></film></sensor></scene>",
    );
    assert!(
        e.contains(":2: <film type=\"hdrfilm\">")
            && e.contains("'width' must be a positive integer"),
        "{e}"
    );
    let e = load_str(
        "<scene><sensor type=\"perspective\"><film type=\"hdrfilm\">\n<rfilter type=\"lanczos\"/></film></sensor></scene>",
    );
    assert!(e.contains("filter 'lanczos' is not supported"), "{e}");
    let e = load_str("<scene><sensor type=\"fisheye\"/></scene>");
    assert!(e.contains("sensor type 'fisheye' is not supported"), "{e}");
    let e = load_str(&format!(
        "<scene>{camera}<integrator type=\"magic\"/></scene>"
    ));
    assert!(e.contains("integrator 'magic' is not known"), "{e}");
    let e = load_str(&format!(
        "<scene>{camera}\n<shape type=\"sphere\"><bsdf type=\"diffuse\"><texture name=\"reflectance\" type=\"bitmap\"><string name=\"filename\" value=\"missing.png\"/></texture></bsdf></shape></scene>"
    ));
    assert!(e.contains("missing.png does not exist"), "{e}");
    let dir = std::env::temp_dir().join(format!("aether-scene-{}", std::process::id()));
    std::fs::write(dir.join("broken.png"), b"not a png").unwrap();
    let e = load_str(&format!(
        "<scene>{camera}\n<shape type=\"sphere\"><bsdf type=\"diffuse\">\n<texture name=\"reflectance\" type=\"bitmap\"><string name=\"filename\" value=\"broken.png\"/></texture></bsdf></shape></scene>"
    ));
    assert!(
        e.contains(":3: <texture type=\"bitmap\">")
            && e.contains("broken.png: cannot read the image"),
        "{e}"
    );
}

#[test]
fn environment_maps_are_read_from_exr() {
    let dir = std::env::temp_dir().join(format!("aether-envmap-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    exr::prelude::write_rgb_file(dir.join("sky.exr"), 4, 2, |x, y| {
        (x as f32, y as f32, 0.5f32)
    })
    .unwrap();
    let xml = "<scene><sensor type=\"perspective\"/><emitter type=\"envmap\"><string name=\"filename\" value=\"sky.exr\"/><float name=\"scale\" value=\"2\"/></emitter></scene>";
    std::fs::write(dir.join("env.xml"), xml).unwrap();
    let scene = Scene::load(&dir.join("env.xml"), &HashMap::new()).unwrap();
    let Emitter::EnvMap { image, scale, .. } = &scene.emitters[0] else {
        panic!("{:?}", scene.emitters)
    };
    assert_eq!((image.width, image.height, *scale), (4, 2, 2.0));
    let (x, y) = (3, 1);
    assert_eq!(image.texels[y * 4 + x], [3.0, 1.0, 0.5]);
}

#[test]
fn the_keyhole_is_declared_as_a_portal() {
    let Some(dir) = scenes() else { return };
    let with_portal =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cbox_tridir_keyhole.xml");
    let scene = Scene::load(&with_portal, &HashMap::new()).unwrap_or_else(|e| panic!("{e}"));
    let plain = Scene::load(&dir.join("cbox/cbox_tridir.xml"), &HashMap::new()).unwrap();
    assert_eq!(scene.portals.len(), 1);
    assert!(plain.portals.is_empty());
    // The portal is not rendered: the geometry is that of the plain scene.
    assert_eq!(
        scene.geometry.triangle_count(),
        plain.geometry.triangle_count()
    );
    let hole = &scene.portals[0];
    // A small opening in the ceiling (about 0.33 on a side, at y ≈ 1.99).
    assert!(hole.area() > 0.05 && hole.area() < 0.2, "{}", hole.area());
    assert!(
        hole.positions.iter().all(|p| (p.y - 1.99).abs() < 0.05),
        "{:?}",
        hole.positions
    );
    let e = Scene::load(&write_temp("portal-sphere.xml", "<scene><sensor type=\"perspective\"/>\n<shape type=\"sphere\"><boolean name=\"portal\" value=\"true\"/></shape></scene>"), &HashMap::new()).unwrap_err();
    assert!(
        e.to_string().contains(":2:") && e.to_string().contains("a portal must be a mesh"),
        "{e}"
    );
}

fn write_temp(name: &str, text: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("aether-portal-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join(name), text).unwrap();
    dir.join(name)
}

#[test]
fn a_second_integrator_or_sensor_warns() {
    let xml = "<scene><integrator type=\"path\"/>\n<sensor type=\"perspective\"/>\n<integrator type=\"bdpt\"/>\n<sensor type=\"perspective\"/></scene>";
    let file = write_temp("second.xml", xml);
    let scene = Scene::load(&file, &HashMap::new()).unwrap();
    assert_eq!(scene.integrator.name, "path");
    let messages: Vec<String> = scene.warnings.iter().map(ToString::to_string).collect();
    assert_eq!(messages.len(), 2, "{messages:?}");
    let first = |line| format!("the scene's first <{line}> ({}:", file.display());
    assert!(messages[0].contains(":4: warning: <sensor type=\"perspective\"> is ignored"));
    assert!(messages[0].contains(&first("sensor")), "{messages:?}");
    assert!(messages[1].contains(":3: warning: <integrator type=\"bdpt\"> is ignored"));
    assert!(messages[1].contains(&first("integrator")), "{messages:?}");
}

#[test]
fn unused_properties_warn_and_flip_normals_flips() {
    let xml = "<scene><sensor type=\"perspective\"><float name=\"fov\" value=\"40\"/><float name=\"fob\" value=\"3\"/></sensor>\n<shape type=\"rectangle\"><boolean name=\"flipNormals\" value=\"true\"/></shape></scene>";
    let scene = Scene::load(&write_temp("unused.xml", xml), &HashMap::new()).unwrap();
    let messages: Vec<String> = scene.warnings.iter().map(ToString::to_string).collect();
    assert_eq!(messages.len(), 1, "{messages:?}");
    assert!(
        messages[0].contains(
            ":1: warning: the property 'fob' of <sensor type=\"perspective\"> is not used"
        ),
        "{messages:?}"
    );
    let [a, b, c] = scene.geometry.meshes()[0].corners(0);
    assert!(
        (b - a).cross(c - a).z < 0.0,
        "the rectangle faces -z once flipped"
    );
}

#[test]
fn gradient_domain_parameters_are_read_under_both_names() {
    use aether_strategies::scene::GradientSettings;
    let scene_with = |integrator: &str| {
        format!(
            "<scene><sensor type=\"perspective\"/>\n{integrator}\n<shape type=\"sphere\"/></scene>"
        )
    };
    let load = |name: &str, integrator: &str| {
        Scene::load(&write_temp(name, &scene_with(integrator)), &HashMap::new())
    };
    let aether = load(
        "aether-gpt.xml",
        "<integrator type=\"mygpt\"><float name=\"specularRoughnessThreshold\" value=\"0.1\"/><boolean name=\"doL1Reconstruction\" value=\"false\"/></integrator>",
    )
    .unwrap();
    assert_eq!(aether.integrator.name, "gpt");
    assert_eq!(
        aether.integrator.gradient,
        GradientSettings {
            roughness_threshold: 0.1,
            l1: false,
            alpha: 0.04
        }
    );
    assert!(aether.warnings.is_empty(), "{:?}", aether.warnings);
    let mitsuba = load(
        "mitsuba-gpt.xml",
        "<integrator type=\"gpt\"><float name=\"shiftThreshold\" value=\"0.05\"/><boolean name=\"reconstructL1\" value=\"true\"/><float name=\"reconstructAlpha\" value=\"0.2\"/></integrator>",
    )
    .unwrap();
    assert_eq!(
        mitsuba.integrator.gradient,
        GradientSettings {
            roughness_threshold: 0.05,
            l1: true,
            alpha: 0.2
        }
    );
    let e = load(
        "bad-gpt.xml",
        "<integrator type=\"gpt\"><float name=\"reconstructAlpha\" value=\"-1\"/></integrator>",
    )
    .map(|_| ())
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("bad-gpt.xml:2") && e.contains("reconstructAlpha must be positive"),
        "{e}"
    );
}

#[test]
fn metropolis_parameters_are_read_and_checked() {
    use aether_strategies::scene::MetropolisSettings;
    let load = |name: &str, integrator: &str| {
        let xml = format!(
            "<scene><sensor type=\"perspective\"/>\n{integrator}\n<shape type=\"sphere\"/></scene>"
        );
        Scene::load(&write_temp(name, &xml), &HashMap::new())
    };
    let aether = load(
        "aether-mlt.xml",
        "<integrator type=\"mymlt\"><integer name=\"directSamples\" value=\"16\"/><integer name=\"luminanceSamples\" value=\"5000\"/><boolean name=\"causticPerturbation\" value=\"false\"/><integer name=\"workUnits\" value=\"8\"/></integrator>",
    )
    .unwrap();
    assert_eq!(aether.integrator.name, "mlt");
    assert_eq!(
        aether.integrator.metropolis,
        MetropolisSettings {
            luminance_samples: 5000,
            large_step: 0.3,
            chains: 8,
            direct_samples: 16,
            mutations: [1.0, 1.0, 0.0, 1.0],
        }
    );
    assert!(aether.warnings.is_empty(), "{:?}", aether.warnings);
    let pssmlt = load(
        "pssmlt.xml",
        "<integrator type=\"pssmlt\"><float name=\"pLarge\" value=\"0.5\"/><integer name=\"chains\" value=\"4\"/></integrator>",
    )
    .unwrap();
    assert_eq!(pssmlt.integrator.name, "pssmlt");
    let m = pssmlt.integrator.metropolis;
    assert_eq!((m.large_step, m.chains, m.direct_samples), (0.5, 4, 0));
    for (file, integrator, message) in [
        (
            "bad-plarge.xml",
            "<integrator type=\"mmlt\"><float name=\"pLarge\" value=\"1.5\"/></integrator>",
            "pLarge must lie in [0, 1]",
        ),
        (
            "bad-chains.xml",
            "<integrator type=\"mlt\"><integer name=\"chains\" value=\"0\"/></integrator>",
            "chains must be a positive integer",
        ),
        (
            "bad-mix.xml",
            "<integrator type=\"mlt\"><boolean name=\"bidirectionalMutation\" value=\"false\"/></integrator>",
            "bidirectionalMutation cannot be off",
        ),
    ] {
        let e = load(file, integrator).map(|_| ()).unwrap_err().to_string();
        assert!(
            e.contains(&format!("{file}:2")) && e.contains(message),
            "{e}"
        );
    }
}
