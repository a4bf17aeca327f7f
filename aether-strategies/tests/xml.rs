//! Reading Mitsuba XML: every Aether scene, and a catalogue of bad input,
//! each with the message a user sees.

mod common;
use common::scenes;

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use aether_strategies::scene::xml::{Category, SpectrumValue, Value, read_scene, read_scene_str};

fn xml_files(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for entry in std::fs::read_dir(dir).unwrap() {
        let p = entry.unwrap().path();
        if p.is_dir() {
            out.extend(xml_files(&p));
        } else if p.extension().is_some_and(|e| e == "xml") {
            out.push(p);
        }
    }
    out.sort();
    out
}

#[test]
fn every_aether_scene_reads() {
    let Some(dir) = scenes() else { return };
    let files = xml_files(&dir);
    assert!(files.len() >= 26, "{files:?}");
    for f in &files {
        let scene = read_scene(f, &HashMap::new()).unwrap_or_else(|e| panic!("{e}"));
        let count = |c| scene.root.children_of(c).count();
        assert_eq!(count(Category::Sensor), 1, "{}", f.display());
        assert_eq!(count(Category::Integrator), 1, "{}", f.display());
        assert!(count(Category::Shape) > 0, "{}", f.display());
        for w in &scene.warnings {
            println!("{w}");
        }
    }
}

#[test]
fn cornell_box_structure() {
    let Some(dir) = scenes() else { return };
    let scene = read_scene(&dir.join("cbox/cbox_path.xml"), &HashMap::new()).unwrap();
    let shapes: Vec<_> = scene.root.children_of(Category::Shape).collect();
    assert_eq!(shapes.len(), 8);
    let light = shapes[0];
    assert_eq!(light.children_of(Category::Emitter).count(), 1);
    let emitter = light.children_of(Category::Emitter).next().unwrap();
    let Value::Spectrum(SpectrumValue::Sampled(s)) = &emitter.property("radiance").unwrap().value
    else {
        panic!()
    };
    assert_eq!(
        s,
        &[(400.0, 0.0), (500.0, 8.0), (600.0, 15.6), (700.0, 18.4)]
    );
    // The referenced BSDF is the declared object.
    assert_eq!(
        light
            .children_of(Category::Bsdf)
            .next()
            .unwrap()
            .id
            .as_deref(),
        Some("light")
    );
    let t = light.transform("toWorld").unwrap();
    assert!(
        (t.transform_point3(glam::Vec3::ZERO) - glam::Vec3::new(0.0, -0.5, 0.0)).length() < 1e-6
    );
    let sensor = scene.root.children_of(Category::Sensor).next().unwrap();
    assert!((sensor.float("fov", 0.0).unwrap() - 39.3077).abs() < 1e-9);
    let to_world = sensor.transform("toWorld").unwrap();
    assert!(
        (to_world.transform_point3(glam::Vec3::ZERO) - glam::Vec3::new(278.0, 273.0, -800.0))
            .length()
            < 1e-3
    );
    assert!((to_world.transform_vector3(glam::Vec3::Z) - glam::Vec3::Z).length() < 1e-6);
}

/// Parses `xml` as the file `bad.xml`, expecting an error that contains
/// every fragment of `expected` and the line.
fn rejects(xml: &str, line: u32, expected: &[&str]) {
    let e = read_scene_str(xml, Path::new("/scenes/bad.xml"), &HashMap::new()).expect_err(xml);
    let text = e.to_string();
    assert!(
        text.starts_with(&format!("/scenes/bad.xml:{line}:")),
        "{text}"
    );
    for fragment in expected {
        assert!(text.contains(fragment), "'{text}' lacks '{fragment}'");
    }
}

#[test]
fn bad_input_names_the_file_the_line_and_the_element() {
    rejects(
        "<scene>\n<shape type=\"obj\">\n</scene>",
        3,
        &["malformed XML"],
    );
    rejects("<world/>", 1, &["<world>", "root element must be <scene>"]);
    rejects(
        "<scene>\n  <bsdf id=\"a\"/>\n</scene>",
        2,
        &["<bsdf id=\"a\">", "'type' attribute is missing"],
    );
    rejects(
        "<scene>\n<sensor type=\"perspective\">\n<float name=\"fov\" value=\"4o\"/>\n</sensor>\n</scene>",
        3,
        &["<float name=\"fov\">", "'4o' is not a number"],
    );
    rejects(
        "<scene><sensor type=\"perspective\">\n<float name=\"fov\" value=\"nan\"/></sensor></scene>",
        2,
        &["not a finite number"],
    );
    rejects(
        "<scene>\n<shape type=\"obj\">\n<ref id=\"white\"/>\n</shape>\n</scene>",
        3,
        &["<ref id=\"white\">", "no object with id 'white'"],
    );
    rejects(
        "<scene>\n<bsdf type=\"diffuse\" id=\"a\"/>\n<bsdf type=\"diffuse\" id=\"a\"/>\n</scene>",
        3,
        &["id 'a' is declared twice"],
    );
    rejects(
        "<scene>\n<include filename=\"missing.xml\"/>\n</scene>",
        2,
        &["<include>", "/scenes/missing.xml does not exist"],
    );
    rejects(
        "<scene>\n<integrator type=\"path\">\n<integer name=\"maxDepth\" value=\"$depth\"/>\n</integrator>\n</scene>",
        3,
        &["'$depth' has no value"],
    );
    rejects(
        "<scene><film type=\"hdrfilm\">\n<boolean name=\"banner\" value=\"yes\"/></film></scene>",
        2,
        &["'yes' is not 'true' or 'false'"],
    );
    rejects(
        "<scene><bsdf type=\"diffuse\">\n<rgb name=\"reflectance\" value=\"0.5 0.2\"/></bsdf></scene>",
        2,
        &["one or three numbers"],
    );
    rejects(
        "<scene><shape type=\"obj\"><transform name=\"toWorld\">\n<matrix value=\"1 0 0 0 1\"/></transform></shape></scene>",
        2,
        &["<matrix>", "16 or 9 numbers, not 5"],
    );
    rejects(
        "<scene><sensor type=\"perspective\"><transform name=\"toWorld\">\n<lookat origin=\"0 0 0\" target=\"0 0 0\"/></transform></sensor></scene>",
        2,
        &["do not define a frame"],
    );
    rejects(
        "<scene><shape type=\"obj\"><transform name=\"toWorld\">\n<scale value=\"0\"/></transform></shape></scene>",
        1,
        &["singular"],
    );
    rejects(
        "<scene><emitter type=\"area\">\n<spectrum name=\"radiance\" value=\"500:1, 400:2\"/></emitter></scene>",
        2,
        &["wavelengths must increase"],
    );
    rejects("<scene>\n<scene/>\n</scene>", 2, &["cannot be nested"]);
    rejects(
        "<scene><shape type=\"sphere\">\n<float name=\"radius\" value=\"1\" x=\"2\"/>\n<ref/></shape></scene>",
        3,
        &["<ref>", "'id' attribute is missing"],
    );
    rejects(
        "<scene><emitter type=\"area\">\n<blackbody name=\"radiance\" temperature=\"5000\"/></emitter></scene>",
        2,
        &["<blackbody> is not supported"],
    );
}

#[test]
fn unknown_elements_warn_and_defaults_substitute() {
    let xml = "<scene>\n<default name=\"spp\" value=\"16\"/>\n<sampler type=\"independent\">\n<integer name=\"sampleCount\" value=\"$spp\"/>\n<wobble/>\n</sampler>\n</scene>";
    let scene = read_scene_str(xml, Path::new("/s/a.xml"), &HashMap::new()).unwrap();
    let sampler = scene.root.children_of(Category::Sampler).next().unwrap();
    assert_eq!(sampler.integer("sampleCount", 1).unwrap(), 16);
    assert_eq!(scene.warnings.len(), 1);
    assert_eq!(
        scene.warnings[0].to_string(),
        "/s/a.xml:5: warning: unknown element <wobble> is ignored"
    );
    // A parameter given by the caller overrides the default.
    let params = HashMap::from([("spp".to_string(), "4".to_string())]);
    let scene = read_scene_str(xml, Path::new("/s/a.xml"), &params).unwrap();
    assert_eq!(
        scene
            .root
            .children_of(Category::Sampler)
            .next()
            .unwrap()
            .integer("sampleCount", 1)
            .unwrap(),
        4
    );
    // A property set twice keeps the later value, with a warning.
    let twice = read_scene_str("<scene><film type=\"hdrfilm\">\n<integer name=\"width\" value=\"2\"/>\n<integer name=\"width\" value=\"3\"/></film></scene>", Path::new("/s/b.xml"), &HashMap::new()).unwrap();
    assert_eq!(
        twice
            .root
            .children_of(Category::Film)
            .next()
            .unwrap()
            .integer("width", 0)
            .unwrap(),
        3
    );
    assert!(
        twice.warnings[0]
            .to_string()
            .contains("/s/b.xml:3: warning: the property 'width' is set again (first at line 2)"),
        "{}",
        twice.warnings[0]
    );
    // Asking for the wrong type names the property.
    let e = sampler
        .float("sampleCount", 0.0)
        .map(|_| ())
        .and_then(|()| sampler.boolean("sampleCount", false).map(|_| ()))
        .unwrap_err();
    assert!(
        e.to_string()
            .contains("expects a boolean for 'sampleCount'"),
        "{e}"
    );
}

#[test]
fn includes_are_read_relative_to_the_file() {
    let dir = std::env::temp_dir().join(format!("aether-xml-{}", std::process::id()));
    std::fs::create_dir_all(dir.join("sub")).unwrap();
    std::fs::write(
        dir.join("sub/materials.xml"),
        "<scene><bsdf type=\"diffuse\" id=\"grey\"/></scene>",
    )
    .unwrap();
    std::fs::write(dir.join("main.xml"), "<scene><include filename=\"sub/materials.xml\"/><shape type=\"sphere\"><ref id=\"grey\"/></shape></scene>").unwrap();
    let scene = read_scene(&dir.join("main.xml"), &HashMap::new()).unwrap();
    let shape = scene.root.children_of(Category::Shape).next().unwrap();
    assert_eq!(
        shape
            .children_of(Category::Bsdf)
            .next()
            .unwrap()
            .id
            .as_deref(),
        Some("grey")
    );
    std::fs::write(
        dir.join("loop.xml"),
        "<scene>\n<include filename=\"loop.xml\"/></scene>",
    )
    .unwrap();
    let e = read_scene(&dir.join("loop.xml"), &HashMap::new()).unwrap_err();
    assert!(e.to_string().contains("includes itself"), "{e}");
}
