//! Equal-time comparisons (Anderson et al. 2017): each integrator renders
//! whole passes for the same wall-clock time, and its RMSE and relMSE
//! against a long BDPT reference are printed.
//!
//! - Veach's bidirectional scene: BDPT and gradient-domain path tracing
//!   (L1 reconstruction) should beat path tracing.
//! - The keyhole box: BDPT should beat path tracing, and tridirectional
//!   tracing, which samples segments through the keyhole, BDPT.
//! - Aether's cbox-sphere: gradient-domain path tracing against path tracing.
//! - Veach's door: Veach's MLT, primary-sample-space MLT and multiplexed
//!   MLT against BDPT; and, with its opening declared a portal,
//!   tridirectional tracing against BDPT (the paper's own demonstration).
//!
//! ```text
//! cargo run --release -p examples --example equal_time -- \
//!     [--seconds 15] [--reference-seconds 240] [--scale 0.25] [--cache DIR] [--only NAME]
//! ```
//!
//! References are written to the cache folder (default
//! `target/equal-time`) and reused when present. Gradient-domain tracing's
//! time includes its reconstruction.

use std::collections::HashMap;
use std::path::PathBuf;

use aether_strategies::scene::Scene;
use examples::render_for;
use integrators::output::{Comparison, read_exr, write_exr};

/// A scene of the comparison, relative to the workspace, the integrators
/// compared on it and the claims checked: (a, b) for "a beats b".
struct Case {
    name: &'static str,
    /// The name of its reference image: the same image as another case's.
    reference: &'static str,
    file: &'static str,
    integrators: &'static [&'static str],
    claims: &'static [(&'static str, &'static str)],
}

const CASES: [Case; 5] = [
    Case {
        name: "veach_bidir",
        reference: "veach_bidir",
        file: "../shared/scenes/aether/veach_bidir/bidir-bdpt.xml",
        integrators: &["path", "bdpt", "gpt"],
        claims: &[("bdpt", "path"), ("gpt", "path")],
    },
    Case {
        name: "keyhole box",
        reference: "keyhole box",
        // Aether's keyhole box, its hole declared a portal (Aether hard-codes it).
        file: "scenes/cbox_tridir_keyhole.xml",
        integrators: &["path", "bdpt", "tridir"],
        claims: &[("bdpt", "path"), ("tridir", "bdpt")],
    },
    Case {
        name: "veach_door",
        reference: "veach_door",
        file: "../shared/scenes/aether/veach_door/door-bdpt.xml",
        integrators: &["bdpt", "mlt", "pssmlt", "mmlt"],
        claims: &[("mlt", "bdpt"), ("pssmlt", "bdpt"), ("mmlt", "bdpt")],
    },
    Case {
        name: "veach_door portal",
        // Where the Aether paper shows tridirectional tracing: the door's
        // opening declared a portal. BDPT ignores portals, so the image,
        // and its reference, are the door's.
        reference: "veach_door",
        file: "scenes/door_tridir.xml",
        integrators: &["bdpt", "tridir"],
        claims: &[("tridir", "bdpt")],
    },
    Case {
        name: "cbox-sphere",
        reference: "cbox-sphere",
        file: "../shared/scenes/aether/cbox-sphere/cbox-sphere-gpt.xml",
        integrators: &["path", "gpt"],
        claims: &[("gpt", "path")],
    },
];

struct Options {
    seconds: f64,
    reference_seconds: f64,
    scale: f64,
    cache: PathBuf,
    only: Option<String>,
}

fn options() -> Result<Options, String> {
    let root = examples::workspace();
    let mut o = Options {
        seconds: 15.0,
        reference_seconds: 240.0,
        scale: 0.25,
        cache: root.join("target/equal-time"),
        only: None,
    };
    let args: Vec<String> = std::env::args().skip(1).collect();
    for pair in args.chunks(2) {
        let [flag, value] = pair else {
            return Err(format!("{} needs a value", pair[0]));
        };
        let number = || examples::positive(flag, value);
        match flag.as_str() {
            "--seconds" => o.seconds = number()?,
            "--reference-seconds" => o.reference_seconds = number()?,
            "--scale" => o.scale = number()?.min(1.0),
            "--cache" => o.cache = PathBuf::from(value),
            "--only" => o.only = Some(value.clone()),
            _ => return Err(format!("unknown option {flag}")),
        }
    }
    Ok(o)
}

fn load(case: &Case, scale: f64) -> Result<Scene, String> {
    let mut scene = examples::load(case.file, scale)?;
    // Aether's integrators stop at depth 6 where a scene sets no limit.
    if scene.integrator.max_depth < 0 {
        scene.integrator.max_depth = 6;
    }
    Ok(scene)
}

fn compare(case: &Case, o: &Options) -> Result<(), String> {
    let mut scene = load(case, o.scale)?;
    let (w, h) = (scene.film.width, scene.film.height);
    let depth = scene.integrator.max_depth;
    let cached = o.cache.join(format!(
        "{}-{w}x{h}-depth{depth}-{}s.exr",
        case.reference.replace(' ', "_"),
        o.reference_seconds
    ));
    println!(
        "\n{} ({w}×{h}, max depth {depth}), {} s each",
        case.name, o.seconds
    );
    let reference = match read_exr(&cached) {
        Ok((rw, rh, image)) if (rw, rh) == (w, h) => {
            println!(
                "reference: BDPT, {} s, from {}",
                o.reference_seconds,
                cached.display()
            );
            image
        }
        _ => {
            println!(
                "reference: rendering BDPT for {} s ...",
                o.reference_seconds
            );
            // Its own streams: the compared BDPT render must not repeat its passes.
            let r = render_for(&mut scene, "bdpt", o.reference_seconds, 1_000_003)?;
            std::fs::create_dir_all(&o.cache).map_err(|e| format!("{}: {e}", o.cache.display()))?;
            write_exr(&cached, w, h, &r.image, r.passes, r.seconds)?;
            println!(
                "reference: {} spp, written to {}",
                r.passes,
                cached.display()
            );
            r.image
        }
    };
    println!(
        "{:<8} {:>6} {:>8} {:>11} {:>9} {:>11} {:>12} {:>12}",
        "", "spp", "seconds", "samples/s", "mean Δ", "RMSE", "RMSE at time", "relMSE at t"
    );
    let mut at_time = HashMap::new();
    for &integrator in case.integrators {
        if integrator == "tridir" && scene.portals.is_empty() {
            println!("{integrator:<8} (the scene has no portal)");
            continue;
        }
        let r = render_for(&mut scene, integrator, o.seconds, 17)?;
        let c = Comparison::of(&r.image, &reference).ok_or("the image sizes differ")?;
        // Passes end past the budget: scale the errors to the budget (variance ∝ 1/time).
        let scale = r.seconds / o.seconds;
        let (rmse, rel_mse) = (c.rmse * scale.sqrt(), c.rel_mse * scale);
        let rate = r.samples as f64 / r.seconds;
        println!(
            "{integrator:<8} {:>6} {:>8.1} {rate:>11.0} {:>+8.2}% {:>11.5} {rmse:>12.5} {rel_mse:>12.5}",
            r.passes,
            r.seconds,
            100.0 * c.relative_difference(),
            c.rmse
        );
        at_time.insert(integrator, (rmse, rel_mse));
    }
    let verdict = |a: &str, b: &str| {
        if let (Some(x), Some(y)) = (at_time.get(a), at_time.get(b)) {
            let yes = |better: bool| if better { "yes" } else { "no" };
            println!(
                "{a} beats {b}: RMSE {} ({:.5} vs {:.5}), relMSE {} ({:.5} vs {:.5})",
                yes(x.0 < y.0),
                x.0,
                y.0,
                yes(x.1 < y.1),
                x.1,
                y.1
            );
        }
    };
    for (a, b) in case.claims {
        verdict(a, b);
    }
    Ok(())
}

fn main() {
    let result = options().and_then(|o| {
        let wanted = |c: &&Case| {
            o.only
                .as_ref()
                .is_none_or(|n| c.name.starts_with(n.as_str()))
        };
        CASES
            .iter()
            .filter(wanted)
            .try_for_each(|case| compare(case, &o))
    });
    if let Err(e) = result {
        eprintln!("equal_time: {e}");
        std::process::exit(1);
    }
}
