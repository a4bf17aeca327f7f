//! The render loop: tiles rendered in parallel, each pixel from its own
//! random stream (seed and pixel index), so that an image depends on the
//! seed and not on the threads; a progress bar, a time limit and a stop
//! flag (Ctrl-C) that keep what was rendered.

use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use aether_strategies::scene::Scene;

use crate::bdpt::Bdpt;
use crate::direct::DirectLighting;
use crate::estimator::{Estimator, Splats};
use crate::film::{Film, SplatBuffer, is_valid};
use crate::gradient::{GradientPathTracer, render_gradients};
use crate::light::LightTracer;
use crate::mlt::{MltSettings, Variant, render_mlt};
use crate::path::PathTracer;

use crate::rounds::render_rounds;
pub use crate::rounds::{PixelSamples, Tile, TileRun, render_tiles, sample_stream};
use crate::shard::{Partial, Shard};

thread_local! {
    /// Each thread's splat list, reused from pixel to pixel so that light
    /// paths allocate only while it grows.
    static SCRATCH: std::cell::Cell<Splats> = const { std::cell::Cell::new(Vec::new()) };
}

/// How to render.
#[derive(Clone, Debug)]
pub struct Settings {
    /// Samples per pixel.
    pub spp: u32,
    /// Seed of every sample's random stream ([`sample_stream`]).
    pub seed: u64,
    /// The index of each pixel's first sample: 0, but for a part of a
    /// render (its samples are `first_sample .. first_sample + spp`).
    pub first_sample: u32,
    /// Stop after this long, keeping what was rendered. The tiled
    /// integrators then render in rounds of growing samples per pixel, each
    /// round from its own seed, so that every pixel ends with about as many
    /// samples as time allowed (tiles not started when time runs out are
    /// skipped; gradient-domain tracing leaves out a round cut short, as
    /// its pairs of pixels need equal counts); Metropolis methods stop
    /// their chains.
    pub time_limit: Option<Duration>,
    /// The part of the render to take ([`Shard::WHOLE`] for all of it): a
    /// share of each pixel's samples, or of the Metropolis chains.
    pub shard: Shard,
    /// Worker threads (`None`: all cores).
    pub threads: Option<usize>,
    /// Show a progress bar.
    pub progress: bool,
}

impl Settings {
    /// `spp` samples per pixel from the streams of `seed`, on all cores,
    /// with no time limit and no progress bar.
    ///
    /// ```
    /// use integrators::render::Settings;
    /// let settings = Settings { progress: true, ..Settings::new(16, 1) };
    /// assert_eq!((settings.spp, settings.threads), (16, None));
    /// ```
    #[must_use]
    pub fn new(spp: u32, seed: u64) -> Self {
        Settings {
            spp,
            seed,
            first_sample: 0,
            shard: Shard::WHOLE,
            time_limit: None,
            threads: None,
            progress: false,
        }
    }
}

impl Settings {
    /// The worker threads these settings ask for.
    ///
    /// # Errors
    /// If the threads cannot start.
    pub fn pool(&self) -> Result<rayon::ThreadPool, String> {
        let mut builder = rayon::ThreadPoolBuilder::new();
        if let Some(n) = self.threads {
            builder = builder.num_threads(n);
        }
        builder
            .build()
            .map_err(|e| format!("cannot start the worker threads: {e}"))
    }
}

/// What a render produced.
#[derive(Debug)]
pub struct Rendered {
    /// The film.
    pub film: Film,
    /// Wall-clock seconds.
    pub seconds: f64,
    /// Camera samples taken.
    pub samples: u64,
    /// Rays cast (camera and shadow rays).
    pub rays: u64,
    /// Seconds spent casting them, summed over threads, when rays are timed.
    pub ray_seconds: f64,
    /// False if the time limit or a stop request cut the render short.
    pub complete: bool,
    /// What a merge with the render's other parts needs
    /// ([`crate::parts`]).
    pub partial: Partial,
}

/// The estimator the scene's integrator names: `path`, `direct`, `light`,
/// `bdpt` or `tridir`.
///
/// # Errors
/// For other names (`gpt` and the Metropolis methods are not
/// [`Estimator`]s: see [`render`]), and
/// where the estimator cannot be built (no portal for `tridir`).
pub fn estimator(scene: &Scene) -> Result<Box<dyn Estimator + '_>, String> {
    Ok(match scene.integrator.name.as_str() {
        "path" => Box::new(PathTracer::new(scene)?),
        "direct" => Box::new(DirectLighting::new(scene)?),
        "light" => Box::new(LightTracer::new(scene)?),
        "bdpt" | "tridir" => Box::new(Bdpt::for_scene(scene)?),
        other => {
            return Err(format!(
                "the integrator '{other}' is not available here; use path, direct, light, bdpt, tridir (or gpt, mlt, pssmlt, mmlt through render)"
            ));
        }
    })
}

/// Renders `scene` with the integrator it names ([`estimator`],
/// gradient-domain path tracing for `gpt`, whose film then holds the
/// reconstruction, or a Metropolis method for `mlt`, `pssmlt` and `mmlt`,
/// with the scene's parameters and `settings.spp` mutations per pixel).
///
/// # Errors
/// As [`estimator`], or if the worker threads cannot start.
pub fn render(scene: &Scene, settings: &Settings, stop: &AtomicBool) -> Result<Rendered, String> {
    if Variant::named(&scene.integrator.name).is_some() {
        return render_mlt(scene, MltSettings::for_scene(scene), settings, stop);
    }
    if scene.integrator.name == "gpt" {
        let tracer = GradientPathTracer::new(scene)?;
        let g = render_gradients(scene, &tracer, settings, stop)?;
        return Ok(g.rendered(&g.reconstruct(&scene.integrator.gradient)));
    }
    render_with(scene, estimator(scene)?.as_ref(), settings, stop)
}

/// Renders `scene` with `estimator`: camera paths by tiles, each pixel from
/// its own random stream; light-path contributions go to the film's splat
/// buffer, whose sum is divided by the number of samples taken. With a
/// time limit the samples come in rounds ([`Settings::time_limit`]).
///
/// # Errors
/// If the worker threads cannot start.
pub fn render_with(
    scene: &Scene,
    estimator: &dyn Estimator,
    settings: &Settings,
    stop: &AtomicBool,
) -> Result<Rendered, String> {
    let (w, h) = (scene.film.width, scene.film.height);
    let film = Mutex::new(Film::new(w, h));
    let splats = SplatBuffer::new(w, h);
    let [_, _, cw, ch] = scene.film.crop;
    let pixels = u64::from(cw) * u64::from(ch);
    let rounds = render_rounds(settings, pixels, |_, this, bar| {
        let pixel = |p: [u32; 2], samples: PixelSamples<'_>| {
            let mut scratch = SCRATCH.take();
            let (mut sum, mut taken, mut dropped) = ([0.0f64; 3], 0u32, 0u64);
            for mut rng in samples {
                let c = estimator.sample(p, &mut rng, &mut scratch).to_array();
                taken += 1;
                if is_valid(c) {
                    for k in 0..3 {
                        sum[k] += f64::from(c[k]);
                    }
                } else {
                    dropped += 1;
                }
                for (p, c) in scratch.drain(..) {
                    splats.splat(p, c.to_array());
                }
            }
            SCRATCH.set(scratch);
            (sum, taken, dropped)
        };
        let store = |tile: Tile<([f64; 3], u32, u64)>| {
            let mut film = film
                .lock()
                .expect("no thread panics while holding the film");
            for ([x, y], (sum, taken, dropped)) in tile {
                film.add_pixel(x, y, sum, taken, dropped);
            }
        };
        render_tiles(scene, this, stop, bar, pixel, store)
    })?;
    let mut film = film.into_inner().expect("no thread panicked");
    let samples = film.samples();
    film.add_splats(&splats, samples);
    let mut partial = Partial::new(w, h);
    crate::parts::put_camera(&film, "", &mut partial);
    Ok(Rendered {
        partial,
        film,
        seconds: rounds.seconds,
        samples,
        rays: rounds.rays,
        ray_seconds: rounds.ray_seconds,
        complete: rounds.complete,
    })
}

/// What [`render_passes`] produced.
#[derive(Debug)]
pub struct Passes {
    /// The mean of the passes' images, row by row.
    pub image: Vec<[f32; 3]>,
    /// Passes rendered.
    pub passes: u32,
    /// Wall-clock seconds.
    pub seconds: f64,
    /// Camera samples taken.
    pub samples: u64,
    /// Rays cast.
    pub rays: u64,
}

/// Renders whole passes of `settings.spp` samples per pixel, each from its
/// own seed, until `budget` has passed (at least one pass, and the pass
/// under way is finished), and averages them: the image of an equal-time
/// comparison, in which every pixel has the same number of samples.
///
/// # Errors
/// If the worker threads cannot start.
pub fn render_passes(
    scene: &Scene,
    estimator: &dyn Estimator,
    settings: &Settings,
    budget: Duration,
    stop: &AtomicBool,
) -> Result<Passes, String> {
    let mut sum = vec![[0.0f64; 3]; scene.film.width as usize * scene.film.height as usize];
    let (mut samples, mut rays) = (0, 0);
    let (passes, seconds) = repeat_passes(settings, budget, stop, |pass| {
        let r = render_with(scene, estimator, pass, stop)?;
        for (s, c) in sum.iter_mut().zip(r.film.image()) {
            for k in 0..3 {
                s[k] += f64::from(c[k]);
            }
        }
        samples += r.samples;
        rays += r.rays;
        Ok(())
    })?;
    let n = f64::from(passes);
    Ok(Passes {
        image: sum.iter().map(|s| s.map(|v| (v / n) as f32)).collect(),
        passes,
        seconds,
        samples,
        rays,
    })
}

/// Runs `pass` with the settings of each pass (its own samples, no time limit
/// or progress bar) until `budget` has passed (at least once, and the pass
/// under way is finished) or `stop` is set; returns the number of passes
/// and the seconds they took.
///
/// # Errors
/// The first error of a pass.
pub fn repeat_passes(
    settings: &Settings,
    budget: Duration,
    stop: &AtomicBool,
    mut pass: impl FnMut(&Settings) -> Result<(), String>,
) -> Result<(u32, f64), String> {
    let start = Instant::now();
    let mut passes = 0u32;
    while passes == 0 || (start.elapsed() < budget && !stop.load(Ordering::Relaxed)) {
        pass(&Settings {
            // Each pass takes the samples after the last pass's.
            first_sample: settings
                .first_sample
                .saturating_add(passes.saturating_mul(settings.spp)),
            time_limit: None,
            progress: false,
            ..settings.clone()
        })?;
        passes += 1;
    }
    Ok((passes, start.elapsed().as_secs_f64()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cornell::cornell_box;
    use crate::rounds::round_size;

    #[test]
    fn same_seed_same_image_whatever_the_threads() {
        let scene = cornell_box(32, 32, 4);
        let stop = AtomicBool::new(false);
        let run = |threads| {
            let s = Settings {
                threads: Some(threads),
                ..Settings::new(4, 7)
            };
            render(&scene, &s, &stop).unwrap()
        };
        let (a, b) = (run(1), run(2));
        assert!(a.complete && b.complete);
        assert_eq!(a.film.image(), b.film.image());
        assert_eq!(a.samples, 32 * 32 * 4);
        // The box is lit: the mean of the image is well above zero and finite.
        let mean: f64 = a
            .film
            .image()
            .iter()
            .map(|c| f64::from(c[0] + c[1] + c[2]))
            .sum::<f64>()
            / (3.0 * 1024.0);
        assert!(mean > 0.05 && mean.is_finite(), "{mean}");
    }

    #[test]
    fn passes_average_to_the_image_of_their_samples() {
        let scene = cornell_box(16, 16, 1);
        let stop = AtomicBool::new(false);
        let s = Settings {
            threads: Some(2),
            ..Settings::new(2, 3)
        };
        let path = PathTracer::new(&scene).unwrap();
        let r = render_passes(&scene, &path, &s, Duration::ZERO, &stop).unwrap();
        assert_eq!((r.passes, r.samples), (1, 16 * 16 * 2));
        let one = render_with(&scene, &path, &s, &stop).unwrap();
        assert_eq!(
            r.image,
            one.film.image(),
            "one pass is the render of its seed"
        );
        let r = render_passes(&scene, &path, &s, Duration::from_millis(200), &stop).unwrap();
        assert!(r.passes > 1 && r.image.iter().all(|c| is_valid(*c)));
    }

    #[test]
    fn a_stop_request_keeps_what_was_rendered() {
        let scene = cornell_box(64, 64, 1);
        let stop = AtomicBool::new(true);
        let s = Settings {
            threads: Some(1),
            ..Settings::new(1, 1)
        };
        let r = render(&scene, &s, &stop).unwrap();
        assert!(!r.complete);
        assert_eq!(r.film.rendered_pixels(), 0);
    }

    #[test]
    fn a_time_limit_renders_every_pixel_in_rounds() {
        let scene = cornell_box(32, 32, 1);
        let stop = AtomicBool::new(false);
        // Far more samples than half a second allows: the render stops on
        // time, with every pixel at about the same count.
        let s = Settings {
            time_limit: Some(Duration::from_millis(500)),
            ..Settings::new(u32::MAX, 1)
        };
        let r = render(&scene, &s, &stop).unwrap();
        assert!(!r.complete);
        assert_eq!(r.film.rendered_pixels(), 32 * 32);
        assert_eq!(r.samples, r.film.samples());
        assert!(r.samples >= 2 * 32 * 32, "{} samples", r.samples);
        assert!(r.film.image().iter().flatten().all(|v| v.is_finite()));
        // Without a time limit, rounds double: 1, 1, 2, 4, then what is left.
        let plain = Settings::new(10, 0);
        let sizes: Vec<Option<u32>> = [0, 1, 2, 4, 8, 10]
            .map(|done| round_size(&plain, done, Duration::ZERO))
            .into();
        assert_eq!(sizes, [Some(1), Some(1), Some(2), Some(4), Some(2), None]);
        let timed = Settings {
            time_limit: Some(Duration::from_secs(10)),
            ..Settings::new(100, 0)
        };
        assert_eq!(round_size(&timed, 0, Duration::ZERO), Some(1));
        // One sample took 1 s: half of the 9 s left is 4 samples.
        assert_eq!(round_size(&timed, 1, Duration::from_secs(1)), Some(4));
        assert_eq!(round_size(&timed, 100, Duration::from_secs(1)), None);
        assert_eq!(round_size(&timed, 5, Duration::from_secs(10)), None);
    }
}
