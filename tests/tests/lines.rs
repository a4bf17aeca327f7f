//! Prints the lines of code of each strategy and each integrator
//! (non-blank, non-comment lines in the bodies of its functions), and
//! checks them against their budgets: strategies under 40, and the logic of
//! the integrators (sampling, MIS, estimate; not the render loop) at most
//! direct 35, path 50, BDPT 80, tridirectional BDPT + 20, gradient-domain
//! tracing's estimator 120 and its shift 90; each Metropolis mutation
//! under 40, and each Metropolis method's sampler (PSSMLT 40, multiplexed
//! MLT 60, Veach's MLT 80 beyond its mutations).

use std::path::Path;

use tests::{function_lines, lines_between};

/// A function of a source file: (source, the text it follows, its name).
type Part<'a> = (&'a str, &'a str, &'a str);

#[test]
fn each_strategy_is_under_forty_lines_of_sampling_code() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("../aether-strategies/src");
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

#[test]
fn each_integrator_stays_within_its_budget() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("../integrators/src");
    let read = |f: &str| std::fs::read_to_string(src.join(f)).unwrap();
    let (path, light, bdpt) = (read("path.rs"), read("light.rs"), read("bdpt.rs"));
    // f / p, for the light tracer.
    let estimate = function_lines(&read("estimator.rs"), "pub fn path_limits", "estimate");
    let count = |source: &str, parts: &[(&str, &str)]| -> usize {
        parts
            .iter()
            .map(|(after, f)| function_lines(source, after, f))
            .sum()
    };
    let path_lines = count(
        &path,
        &[("for PathTracer", "sample"), ("for PathTracer", "weight")],
    );
    let light_lines = count(&light, &[("for LightTracer", "sample")]) + estimate;
    // Direct lighting shares the path tracer's MIS weight.
    let weight = function_lines(&path, "impl Estimator for PathTracer", "weight");
    let direct_lines = function_lines(&read("direct.rs"), "for DirectLighting", "sample") + weight;
    // The portal's part of the sampling loop, and its strategy and
    // technique index in the weights.
    let tridir_lines = lines_between(
        &bdpt,
        "let Some(portal) = self.portal.as_ref() else",
        "\n        radiance.as_vec3()\n    }\n}",
    ) + 2;
    // BDPT: its subpaths, joins, estimates and MIS weights; not its
    // outputs beside the image (`observe`: the (s, t) images and MLT's
    // seed paths), as the render loop is not counted either.
    let bdpt_lines = count(
        &bdpt,
        &[
            ("Samples `first`", "walk"),
            ("impl Bdpt<'_>", "sample_into"),
            ("impl<'s> Bdpt<'s>", "join"),
            ("impl<'s> Bdpt<'s>", "contribute"),
            ("impl<'s> Bdpt<'s>", "reach_lens"),
            ("impl<'s> Bdpt<'s>", "joins"),
            ("impl Split", "index"),
        ],
    ) - tridir_lines;
    // Gradient-domain tracing: its estimator (the base path, its MIS
    // weights against the shifted paths, the pairs' sums), and the shift it
    // uses (replay, reconnection, the offsets' direct lighting).
    let gpt_lines = function_lines(
        &read("gradient.rs"),
        "impl<'s> GradientPathTracer<'s>",
        "sample",
    );
    let shift = read("shift.rs");
    let shift_lines = count(
        &shift,
        &[
            ("impl<'s> Shift<'s>", "start"),
            ("impl<'a> Offsets<'a>", "emitted"),
            ("impl<'a> Offsets<'a>", "connect_lamp"),
            ("impl<'a> Offsets<'a>", "advance"),
            ("fn once", "advance"),
        ],
    );
    let rows = [
        ("direct", direct_lines, 35),
        ("path", path_lines, 50),
        ("light", light_lines, 50),
        ("BDPT", bdpt_lines, 80),
        ("tridirectional, beyond BDPT", tridir_lines, 20),
        ("gradient-domain estimator", gpt_lines, 120),
        ("gradient-domain shift", shift_lines, 90),
    ];
    for (name, lines, budget) in rows {
        println!("{name:>28}: {lines:>3} lines (budget {budget})");
    }
    assert!(direct_lines <= 35, "direct has {direct_lines} lines");
    assert!(path_lines <= 50, "path has {path_lines} lines");
    assert!(tridir_lines <= 20, "the portal adds {tridir_lines} lines");
    assert!(light_lines <= 50, "light has {light_lines} lines");
    assert!(bdpt_lines <= 80, "BDPT has {bdpt_lines} lines");
    assert!(gpt_lines <= 120, "GPT's estimator has {gpt_lines} lines");
    assert!(shift_lines <= 90, "GPT's shift has {shift_lines} lines");
}

/// Each of Veach's mutations reads as its algorithm: at most 40 lines of
/// proposal in its own function (its small named helpers, such as where a
/// specular chain ends, are not counted, as the integrators' are not).
#[test]
fn each_metropolis_mutation_is_under_forty_lines() {
    let file = Path::new(env!("CARGO_MANIFEST_DIR")).join("../aether-strategies/src/mutations.rs");
    let source = std::fs::read_to_string(file).unwrap();
    let after = "impl<'a, 's> Mutations<'a, 's>";
    let rows = [
        (
            "bidirectional",
            function_lines(&source, after, "bidirectional"),
        ),
        ("lens", function_lines(&source, after, "lens")),
        ("caustic", function_lines(&source, after, "caustic")),
        ("multi-chain", function_lines(&source, after, "multi_chain")),
    ];
    for (name, lines) in rows {
        println!("{name:>14} mutation: {lines:>3} lines (budget 40)");
    }
    for (name, lines) in rows {
        assert!(lines <= 40, "the {name} mutation has {lines} lines");
    }
}

/// Each Metropolis method's sampler reads as its algorithm: what it
/// evaluates, how it starts a chain and how it proposes and accepts
/// (Veach's mutations are budgeted above; the chains' loop, shared by all
/// three, is the render loop and not counted).
#[test]
fn each_metropolis_method_stays_within_its_budget() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("../integrators/src/mlt");
    let read = |f: &str| std::fs::read_to_string(src.join(f)).unwrap();
    let (primary, veach) = (read("primary.rs"), read("veach.rs"));
    let count = |source: &str, parts: &[(&str, &str)]| -> usize {
        parts
            .iter()
            .map(|(after, f)| function_lines(source, after, f))
            .sum()
    };
    let sampler = |name: &str| {
        [
            (format!("impl<'s> {name}<'s>"), "evaluate"),
            (format!("impl Sampler for {name}<'_>"), "bootstrap"),
            (format!("impl Sampler for {name}<'_>"), "start"),
            (format!("impl Sampler for {name}<'_>"), "mutate"),
        ]
    };
    let lines = |source: &str, parts: &[(String, &str)]| {
        let parts: Vec<(&str, &str)> = parts.iter().map(|(a, f)| (a.as_str(), *f)).collect();
        count(source, &parts)
    };
    // Both primary-sample-space methods share the small step.
    let step = function_lines(&primary, "fn draw", "step");
    let veach_parts = [
        ("impl<'s> VeachMlt<'s>", "evaluate"),
        ("impl<'s> VeachMlt<'s>", "seed_weight"),
        ("impl Sampler for VeachMlt<'_>", "bootstrap"),
        ("impl Sampler for VeachMlt<'_>", "start"),
        ("impl Sampler for VeachMlt<'_>", "mutate"),
    ];
    let rows = [
        ("PSSMLT", lines(&primary, &sampler("Pssmlt")) + step, 40),
        (
            "multiplexed MLT",
            lines(&primary, &sampler("Mmlt")) + step,
            60,
        ),
        (
            "Veach's MLT, beyond its mutations",
            count(&veach, &veach_parts),
            80,
        ),
    ];
    for (name, lines, budget) in rows {
        println!("{name:>34}: {lines:>3} lines (budget {budget})");
    }
    for (name, lines, budget) in rows {
        assert!(
            lines <= budget,
            "{name} has {lines} lines (budget {budget})"
        );
    }
}
