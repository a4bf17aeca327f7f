//! Each kind of bad input that once crashed the reader or the renderer, or
//! passed silently, is now an error naming the file, the line and the
//! element (or a warning, for a scene that renders black).

use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};

use aether_strategies::scene::Scene;
use aether_strategies::scene::xml::SceneError;

/// Writes `xml` as `scene.xml` in a fresh folder, with `files` beside it.
fn write(xml: &str, files: &[(&str, &str)]) -> PathBuf {
    static NEXT: AtomicUsize = AtomicUsize::new(0);
    let n = NEXT.fetch_add(1, Ordering::Relaxed);
    let dir = std::env::temp_dir().join(format!("aether-bad-{}-{n}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for (name, text) in files {
        std::fs::write(dir.join(name), text).unwrap();
    }
    let path = dir.join("scene.xml");
    std::fs::write(&path, xml).unwrap();
    path
}

fn load(xml: &str, files: &[(&str, &str)]) -> Result<Scene, SceneError> {
    Scene::load(&write(xml, files), &HashMap::new())
}

/// A scene with a camera and `body`.
fn scene(body: &str) -> String {
    format!(
        r#"<scene version="0.5.0">
<sensor type="perspective"><film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/></film></sensor>
{body}
</scene>"#
    )
}

/// The error, checked to name the scene file and a line.
fn error(result: Result<Scene, SceneError>) -> String {
    let e = result.map(|_| ()).expect_err("the scene is refused");
    let text = e.to_string();
    assert!(
        text.contains("scene.xml:"),
        "names the file and line: {text}"
    );
    text
}

const LIGHT: &str = r#"<shape type="sphere"><emitter type="area"/></shape>"#;

#[test]
fn huge_coordinates_are_refused_before_the_bvh() {
    let obj = "v 1e20 0 0\nv -1e20 0 0\nv 0 1e20 0\nf 1 2 3\n";
    let body =
        format!(r#"{LIGHT}<shape type="obj"><string name="filename" value="big.obj"/></shape>"#);
    let e = error(load(&scene(&body), &[("big.obj", obj)]));
    assert!(
        e.contains("<shape type=\"obj\">") && e.contains("beyond"),
        "{e}"
    );
    for transform in [r#"<scale value="1e17"/>"#, r#"<translate x="3.4e38"/>"#] {
        let body = format!(
            r#"{LIGHT}<shape type="rectangle"><transform name="toWorld">{transform}</transform></shape>"#
        );
        let e = error(load(&scene(&body), &[]));
        assert!(e.contains("<shape type=\"rectangle\">"), "{e}");
    }
    // Large but ordinary scenes still load.
    let body = format!(
        r#"{LIGHT}<shape type="rectangle"><transform name="toWorld"><scale value="1e6"/></transform></shape>"#
    );
    load(&scene(&body), &[]).unwrap();
}

#[test]
fn devices_and_folders_are_not_read_as_files() {
    let devices = [
        ("obj", "/dev/zero", "not a regular file"),
        ("serialized", "/dev/urandom", "not a regular file"),
        ("obj", ".", "is a directory"),
        ("obj", "missing.obj", "does not exist"),
    ];
    for (kind, file, says) in devices {
        if file.starts_with("/dev") && !std::path::Path::new(file).exists() {
            continue;
        }
        let body = format!(
            r#"{LIGHT}<shape type="{kind}"><string name="filename" value="{file}"/></shape>"#
        );
        let e = error(load(&scene(&body), &[]));
        assert!(
            e.contains(says) && e.contains(&format!("<shape type=\"{kind}\">")),
            "{e}"
        );
    }
    // A device named by `mtllib` is not read: the mesh loads without it.
    let obj = "mtllib /dev/zero\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    let body =
        format!(r#"{LIGHT}<shape type="obj"><string name="filename" value="m.obj"/></shape>"#);
    load(&scene(&body), &[("m.obj", obj)]).unwrap();
    // An include or a texture that is a folder or a device says so.
    let e = error(load(&scene(r#"<include filename="."/>"#), &[]));
    assert!(e.contains("is a directory"), "{e}");
    if std::path::Path::new("/dev/zero").exists() {
        let e = error(load(&scene(r#"<include filename="/dev/zero"/>"#), &[]));
        assert!(e.contains("not a regular file"), "{e}");
    }
}

#[test]
fn deep_nesting_is_an_error_not_a_stack_overflow() {
    for (open, close) in [
        (r#"<shape type="obj">"#, "</shape>"),
        (r#"<bsdf type="twosided">"#, "</bsdf>"),
    ] {
        let body = format!("{}{}", open.repeat(8000), close.repeat(8000));
        let e = error(load(&scene(&body), &[]));
        assert!(e.contains("nested more than"), "{e}");
    }
}

#[test]
fn a_film_too_large_to_hold_is_refused() {
    let xml = r#"<scene version="0.5.0"><sensor type="perspective"><film type="hdrfilm">
<integer name="width" value="64"/><integer name="height" value="2147483647"/></film></sensor></scene>"#;
    let e = error(load(xml, &[]));
    assert!(
        e.contains("<film type=\"hdrfilm\">") && e.contains("GiB"),
        "{e}"
    );
    let mut ok = load(&scene(LIGHT), &[]).unwrap();
    assert!(ok.film.scale_to_width(100_000).is_err());
    assert!(ok.film.scale_to_width(u32::MAX).is_err());
    assert_eq!(
        (ok.film.width, ok.film.height),
        (8, 8),
        "unchanged when refused"
    );
}

#[test]
fn negative_or_zero_emission_is_not_silent() {
    for emitter in [
        r#"<emitter type="area"><spectrum name="radiance" value="-1"/></emitter>"#,
        r#"<emitter type="area"><rgb name="radiance" value="1, -1e30, 1"/></emitter>"#,
        r#"<emitter type="area"><float name="scale" value="-1e30"/></emitter>"#,
        r#"<emitter type="area"><float name="scale" value="1e30"/><spectrum name="radiance" value="1e30"/></emitter>"#,
    ] {
        let body = format!(r#"<shape type="sphere">{emitter}</shape>"#);
        let e = error(load(&scene(&body), &[]));
        assert!(e.contains("<emitter type=\"area\">"), "{e}");
    }
    let body = r#"<shape type="sphere"><emitter type="area"><spectrum name="radiance" value="0"/></emitter></shape>"#;
    let black = load(&scene(body), &[]).unwrap();
    assert!(
        black
            .warnings
            .iter()
            .any(|w| w.message.contains("emits nothing")),
        "{:?}",
        black.warnings
    );
}

#[test]
fn unreadable_text_is_placed_where_it_is() {
    // Invalid UTF-8 on line 3, at a byte offset.
    let path = write("", &[]);
    std::fs::write(&path, b"<scene>\n<!-- a -->\n<x \xff/>\n</scene>").unwrap();
    let e = Scene::load(&path, &HashMap::new()).map(|_| ()).unwrap_err();
    assert_eq!(e.location.line, 3, "{e}");
    assert!(e.to_string().contains("byte 22 (column 4)"), "{e}");
    // Truncated: the end of the file, not line 1.
    let text = scene(LIGHT);
    let e = error(load(&text[..text.len() - 12], &[]));
    let last = text[..text.len() - 12].lines().count();
    assert!(e.contains(&format!("scene.xml:{last}:")), "{e}");
    // A missing file is the file, with no line.
    let missing = path.with_file_name("none.xml");
    let e = Scene::load(&missing, &HashMap::new())
        .map(|_| ())
        .unwrap_err();
    assert_eq!(
        e.to_string(),
        format!(
            "{}: cannot read the scene file: {} does not exist",
            missing.display(),
            missing.display()
        )
    );
    // The root element is named as written.
    let e = error(load("<scene version=\"0.5.0\"></scene>", &[]));
    assert!(e.contains("<scene>") && !e.contains("type=\"\""), "{e}");
}

#[test]
fn indices_of_refraction_stay_where_their_ratio_fits_in_f32() {
    // 1e-40 is positive and finite in f32 but subnormal: 1.5 / 1e-40 is
    // infinite, and Fresnel's reflectance a NaN (the fuzzer's mutant 2184
    // of cbox-sphere-gpt.xml panicked choosing a lobe).
    for (name, value) in [("extIOR", "1e-40"), ("intIOR", "1e-3"), ("intIOR", "1e3")] {
        let body = format!(
            r#"{LIGHT}<shape type="sphere"><bsdf type="dielectric"><float name="{name}" value="{value}"/></bsdf></shape>"#
        );
        let e = error(load(&scene(&body), &[]));
        assert!(
            e.contains("<bsdf type=\"dielectric\">") && e.contains("index of refraction"),
            "{e}"
        );
    }
    let body = format!(
        r#"{LIGHT}<shape type="sphere"><bsdf type="dielectric"><float name="intIOR" value="0.5"/></bsdf></shape>"#
    );
    load(&scene(&body), &[]).expect("an index below one is a valid interface");
}

#[test]
fn transforms_must_be_invertible_in_single_precision() {
    // 1e-40 is not zero in f64, but subnormal in f32, where normals are
    // transformed by an inverse that is then infinite (the fuzzer's
    // mutant 10885 of door-mlt.xml panicked building a shading frame).
    for m in [
        "1e-40 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1",
        "0 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1",
    ] {
        let body = format!(
            r#"{LIGHT}<shape type="sphere"><transform name="toWorld"><matrix value="{m}"/></transform></shape>"#
        );
        let e = error(load(&scene(&body), &[]));
        assert!(e.contains("singular"), "{e}");
    }
}
