//! Prints the lines of sampling code of each strategy (non-blank,
//! non-comment lines in the bodies of its `distribution` and of the
//! helpers it calls), and checks that each stays under 40.

use std::path::Path;

/// The lines of the function `name` (its signature through its closing
/// brace) in `source`, after the first occurrence of `after`.
fn function_lines(source: &str, after: &str, name: &str) -> usize {
    let start = source
        .find(after)
        .unwrap_or_else(|| panic!("{after} not found"));
    let rest = &source[start..];
    let at = rest
        .find(&format!("fn {name}"))
        .unwrap_or_else(|| panic!("fn {name} not found after {after}"));
    // The body: the lines after the one that opens it, up to its closing
    // brace (the signature is boilerplate, not sampling code).
    let mut depth = 0i32;
    let mut opened = false;
    let mut count = 0;
    for line in rest[at..].lines() {
        let code = line.trim();
        let counted = opened && !code.is_empty() && !code.starts_with("//");
        for c in code.chars() {
            match c {
                '{' => {
                    depth += 1;
                    opened = true;
                }
                '}' => depth -= 1,
                _ => {}
            }
        }
        if opened && depth == 0 {
            break;
        }
        if counted {
            count += 1;
        }
    }
    count
}

/// A function of a source file: (source, the text it follows, its name).
type Part<'a> = (&'a str, &'a str, &'a str);

#[test]
fn each_strategy_is_under_forty_lines_of_sampling_code() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let read = |f: &str| std::fs::read_to_string(src.join(f)).unwrap();
    let (camera, lights, scattering, portal, bsdf, lobes) = (
        read("camera.rs"),
        read("lights.rs"),
        read("scattering.rs"),
        read("portal.rs"),
        read("bsdf/mod.rs"),
        read("bsdf/lobes.rs"),
    );
    let strategies: [(&str, Vec<Part>); 8] = [
        (
            "camera position",
            vec![(&camera, "for CameraPosition", "distribution")],
        ),
        (
            "camera direction",
            vec![
                (&camera, "for CameraDirection", "distribution"),
                (&camera, "impl Camera", "directions"),
                (&camera, "impl Camera", "shift"),
            ],
        ),
        (
            "emitter position",
            vec![(&lights, "for EmitterPosition", "distribution")],
        ),
        // A point on light e: the composition both emitter position and
        // direct emitter sampling select from.
        (
            "points on a light",
            vec![(&lights, "impl<'s> Lights<'s>", "points")],
        ),
        (
            "emitter direction",
            vec![(&lights, "for EmitterDirection", "distribution")],
        ),
        (
            "direct emitter",
            vec![
                (&lights, "for DirectEmitter", "distribution"),
                (&lights, "for OnlySphere", "cast"),
            ],
        ),
        (
            "BSDF sampling",
            vec![
                (&scattering, "for BsdfSampling", "distribution"),
                (&bsdf, "impl<'s> Bsdf<'s>", "sampling"),
            ],
        ),
        (
            "portal segment",
            vec![(&portal, "for PortalSegment", "distribution")],
        ),
    ];
    for (name, parts) in &strategies {
        let lines: usize = parts
            .iter()
            .map(|(s, after, f)| function_lines(s, after, f))
            .sum();
        println!("{name:>18}: {lines:>3} lines");
        assert!(lines < 40, "{name} has {lines} lines of sampling code");
    }
    // The lobes every material samples, shared by the BSDF strategy of
    // camera and light paths (emitter position shares its light table with
    // direct emitter sampling in the same way).
    let material_lobes = function_lines(&lobes, "impl Lobes", "of")
        + ["diffuse", "mirror", "glossy", "transmit", "normals"]
            .iter()
            .map(|f| function_lines(&lobes, "use crate::scene", f))
            .sum::<usize>();
    println!(
        "    material lobes: {material_lobes:>3} lines (seven material types, shared by camera and light paths)"
    );
    println!(
        "(direct emitter sampling also reuses the light points counted under emitter position)"
    );
}
