//! Short programs that reproduce the Aether examples; see `examples/`.
//! This library holds what they share: loading an Aether scene at a chosen
//! resolution, rendering it to an EXR image and PNG preview, rendering any
//! integrator for a given time ([`render_for`]), and the [`reproduce`]
//! report.
#![deny(unsafe_code)]

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use aether_strategies::scene::Scene;
use integrators::estimator::Estimator;
use integrators::gradient::{GradientPathTracer, render_gradient_passes};
use integrators::mlt::{MltSettings, Variant, render_mlt};
use integrators::output::{write_exr, write_png};
use integrators::render::{Passes, Rendered, Settings, estimator, render_passes, render_with};

pub mod reproduce;

/// The workspace folder.
#[must_use]
pub fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// Loads `file` (relative to the workspace, like
/// `../shared/scenes/aether/cbox/cbox_path.xml`) with its film scaled by
/// `scale`.
///
/// # Errors
/// If the scene does not load; the message names the file.
pub fn load(file: &str, scale: f64) -> Result<Scene, String> {
    let mut scene =
        Scene::load(&workspace().join(file), &HashMap::new()).map_err(|e| e.to_string())?;
    let film = &mut scene.film;
    film.width = ((f64::from(film.width) * scale).round() as u32).max(1);
    film.height = ((f64::from(film.height) * scale).round() as u32).max(1);
    film.crop = [0, 0, film.width, film.height];
    Ok(scene)
}

/// Renders `scene` with `estimator` at `spp` samples per pixel and writes
/// `NAME.exr` and `NAME.png` into `target/examples`, printing where and how fast.
///
/// # Errors
/// If the render or a file fails.
pub fn render_to(
    scene: &Scene,
    estimator: &dyn Estimator,
    spp: u32,
    name: &str,
) -> Result<Rendered, String> {
    let settings = Settings {
        progress: true,
        ..Settings::new(spp, 1)
    };
    let r = render_with(scene, estimator, &settings, &AtomicBool::new(false))?;
    let dir = workspace().join("target/examples");
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let (w, h, image) = (scene.film.width, scene.film.height, r.film.image());
    write_exr(
        &dir.join(format!("{name}.exr")),
        w,
        h,
        &image,
        spp,
        r.seconds,
    )?;
    write_png(&dir.join(format!("{name}.png")), w, h, &image, 0.0)?;
    println!(
        "{name}: {w}×{h}, {spp} spp, {:.1} s, {:.0} samples/s -> {}",
        r.seconds,
        r.samples as f64 / r.seconds,
        dir.join(format!("{name}.png")).display()
    );
    Ok(r)
}

/// Renders `scene` with the integrator named `integrator` in whole passes
/// of one sample per pixel for `seconds` (at least one pass), from the
/// random streams that `seed` picks: the image of an equal-time comparison.
/// Gradient-domain tracing's image is its reconstruction, made within the
/// time.
///
/// # Errors
/// If the integrator is not known or cannot render the scene.
pub fn render_for(
    scene: &mut Scene,
    integrator: &str,
    seconds: f64,
    seed: u64,
) -> Result<Passes, String> {
    scene.integrator.name = integrator.into();
    let settings = Settings::new(1, seed);
    let stop = AtomicBool::new(false);
    let budget = Duration::from_secs_f64(seconds);
    if Variant::named(integrator).is_some() {
        return mlt_for(scene, budget, seed);
    }
    if integrator != "gpt" {
        return render_passes(scene, estimator(scene)?.as_ref(), &settings, budget, &stop);
    }
    let start = Instant::now();
    let tracer = GradientPathTracer::new(scene)?;
    let (g, passes) = render_gradient_passes(scene, &tracer, &settings, budget, &stop)?;
    Ok(Passes {
        image: g.reconstruct(&scene.integrator.gradient),
        passes,
        seconds: start.elapsed().as_secs_f64(),
        samples: g.samples,
        rays: g.rays,
    })
}

/// The Metropolis method `scene` names, for `budget`, its bootstrap (and
/// direct pass) included: four bootstrap samples per pixel (at most the
/// scene's luminanceSamples), then mutations until the time is up. Its
/// "passes" are mutations per pixel.
fn mlt_for(scene: &Scene, budget: Duration, seed: u64) -> Result<Passes, String> {
    let [_, _, cw, ch] = scene.film.crop;
    let pixels = u64::from(cw) * u64::from(ch);
    let named = MltSettings::for_scene(scene);
    let mlt = MltSettings {
        bootstrap: (4 * pixels).min(named.bootstrap as u64) as usize,
        ..named
    };
    let settings = Settings {
        time_limit: Some(budget),
        ..Settings::new(u32::MAX / 2, seed)
    };
    let r = render_mlt(scene, mlt, &settings, &AtomicBool::new(false))?;
    let mutations = r.samples;
    Ok(Passes {
        image: r.film.image(),
        passes: (mutations / pixels.max(1)) as u32,
        seconds: r.seconds,
        samples: r.samples,
        rays: r.rays,
    })
}

/// `value` of command-line option `flag` as a positive, finite number.
///
/// # Errors
/// Naming the option, if it is not one.
pub fn positive(flag: &str, value: &str) -> Result<f64, String> {
    match value.parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("{flag} needs a positive number, not '{value}'")),
    }
}
