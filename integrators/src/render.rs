//! The render loop: tiles rendered in parallel, each pixel from its own
//! random stream (seed and pixel index), so that an image depends on the
//! seed and not on the threads; a progress bar, a time limit and a stop
//! flag (Ctrl-C) that keep what was rendered.

use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use aether_core::Pcg32;
use aether_strategies::scene::Scene;
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;

use aether_strategies::geometry::{ray_nanos, rays_cast};

use crate::bdpt::Bdpt;
use crate::direct::DirectLighting;
use crate::estimator::{Estimator, Splats};
use crate::film::{Film, SplatBuffer, is_valid};
use crate::gradient::{GradientPathTracer, render_gradients};
use crate::light::LightTracer;
use crate::mlt::{MltSettings, Variant, render_mlt};
use crate::path::PathTracer;

thread_local! {
    /// Each thread's splat list, reused from pixel to pixel so that light
    /// paths allocate only while it grows.
    static SCRATCH: std::cell::Cell<Splats> = const { std::cell::Cell::new(Vec::new()) };
}

/// Tiles are squares of this many pixels on a side.
const TILE: u32 = 16;

/// How to render.
#[derive(Clone, Debug)]
pub struct Settings {
    /// Samples per pixel.
    pub spp: u32,
    /// Seed of every pixel's random stream.
    pub seed: u64,
    /// Stop after this long, keeping what was rendered. The tiled
    /// integrators then render in rounds of growing samples per pixel, each
    /// round from its own seed, so that every pixel ends with about as many
    /// samples as time allowed (tiles not started when time runs out are
    /// skipped; gradient-domain tracing leaves out a round cut short, as
    /// its pairs of pixels need equal counts); Metropolis methods stop
    /// their chains.
    pub time_limit: Option<Duration>,
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
    let rounds = render_rounds(settings, |_, this| {
        let spp = this.spp;
        let pixel = |[x, y]: [u32; 2], rng: &mut Pcg32| {
            let mut scratch = SCRATCH.take();
            let (mut sum, mut dropped) = ([0.0f64; 3], 0u64);
            for _ in 0..spp {
                let c = estimator.sample([x, y], rng, &mut scratch).to_array();
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
            (sum, dropped)
        };
        let store = |tile: Tile<([f64; 3], u64)>| {
            let mut film = film
                .lock()
                .expect("no thread panics while holding the film");
            for ([x, y], (sum, dropped)) in tile {
                film.add_pixel(x, y, sum, spp, dropped);
            }
        };
        render_tiles(scene, this, stop, pixel, store)
    })?;
    let mut film = film.into_inner().expect("no thread panicked");
    let samples = film.samples();
    film.add_splats(&splats, samples);
    Ok(Rendered {
        film,
        seconds: rounds.seconds,
        samples,
        rays: rounds.rays,
        ray_seconds: rounds.ray_seconds,
        complete: rounds.complete,
    })
}

/// How a render in rounds went.
pub(crate) struct Rounds {
    /// Samples per pixel of the rounds kept (see [`render_rounds`]).
    pub(crate) spp: u32,
    pub(crate) rays: u64,
    pub(crate) ray_seconds: f64,
    pub(crate) seconds: f64,
    /// False if time or a stop request ended the render early.
    pub(crate) complete: bool,
}

/// Runs `round` (given the round's index and settings, returning its tile
/// run) for each round of `settings` ([`Settings::time_limit`]) until its
/// samples per pixel are taken, time runs out or a round is cut short.
/// The rounds kept are every finished one and the first even if cut: a
/// later round cut short is the caller's to keep or leave out.
pub(crate) fn render_rounds(
    settings: &Settings,
    mut round: impl FnMut(u64, &Settings) -> Result<TileRun, String>,
) -> Result<Rounds, String> {
    let start = Instant::now();
    let (mut done, mut rays, mut ray_seconds, mut cut) = (0u32, 0, 0.0, false);
    for index in 0u64.. {
        let Some(spp) = round_size(settings, done, start.elapsed()) else {
            break;
        };
        let run = round(index, &round_settings(settings, index, spp, start))?;
        (rays, ray_seconds) = (rays + run.rays, ray_seconds + run.ray_seconds);
        if run.complete || index == 0 {
            done += spp;
        }
        if !run.complete {
            cut = true;
            break;
        }
    }
    Ok(Rounds {
        spp: done,
        rays,
        ray_seconds,
        seconds: start.elapsed().as_secs_f64(),
        complete: !cut && done == settings.spp,
    })
}

/// The samples per pixel of the next round of a render that has taken
/// `done` of `settings.spp` in `elapsed`, or none when it is finished.
/// Without a time limit, one round takes them all. With one, rounds grow
/// from one sample per pixel to about half the time left, so that when
/// time runs out every pixel has about as many samples as any other (and
/// a huge `spp` means "until the time limit").
fn round_size(settings: &Settings, done: u32, elapsed: Duration) -> Option<u32> {
    let left = settings.spp - done;
    match settings.time_limit {
        _ if left == 0 => None,
        None => Some(left),
        Some(limit) if elapsed >= limit => None,
        Some(_) if done == 0 => Some(1),
        Some(limit) => {
            let per_sample = elapsed.as_secs_f64() / f64::from(done);
            let fits = (limit - elapsed).as_secs_f64() / per_sample / 2.0;
            Some((fits as u32).clamp(1, left))
        }
    }
}

/// The settings of round `round` of `spp` samples per pixel, of a render
/// that started at `start`: its own seed, and the time left.
fn round_settings(settings: &Settings, round: u64, spp: u32, start: Instant) -> Settings {
    Settings {
        spp,
        seed: round_seed(settings.seed, round),
        time_limit: settings
            .time_limit
            .map(|t| t.saturating_sub(start.elapsed())),
        ..settings.clone()
    }
}

/// The seed of round `round` of a render: the render's own for the first
/// (so a render without a time limit is one round with the seed asked
/// for), distant and distinct ones after it.
fn round_seed(seed: u64, round: u64) -> u64 {
    seed.wrapping_add(round.wrapping_mul(0x9e37_79b9_7f4a_7c15))
}

/// A finished tile: each pixel with what was computed for it.
pub type Tile<T> = Vec<([u32; 2], T)>;

/// How a tiled render went.
#[derive(Clone, Copy, Debug)]
pub struct TileRun {
    /// Wall-clock seconds.
    pub seconds: f64,
    /// Rays cast.
    pub rays: u64,
    /// Seconds spent casting them, summed over threads, when rays are timed
    /// ([`aether_strategies::geometry::time_rays`]); zero otherwise.
    pub ray_seconds: f64,
    /// False if the time limit or a stop request cut the render short.
    pub complete: bool,
}

/// The render loop shared by every integrator: the crop window's pixels by
/// tiles in parallel, `pixel` run for each with the pixel's own random
/// stream (from the seed and the pixel index only, so that the result does
/// not depend on the threads), and each finished tile's results handed to
/// `store`; with the settings' threads, progress bar, time limit and
/// `stop` flag (tiles not yet started when time runs out are skipped).
///
/// # Errors
/// If the worker threads cannot start.
pub fn render_tiles<T: Send>(
    scene: &Scene,
    settings: &Settings,
    stop: &AtomicBool,
    pixel: impl Fn([u32; 2], &mut Pcg32) -> T + Sync,
    store: impl Fn(Tile<T>) + Sync,
) -> Result<TileRun, String> {
    let w = scene.film.width;
    let [cx, cy, cw, ch] = scene.film.crop;
    let tiles: Vec<(u32, u32)> = (cy..cy + ch)
        .step_by(TILE as usize)
        .flat_map(|y| (cx..cx + cw).step_by(TILE as usize).map(move |x| (x, y)))
        .collect();
    let bar = if settings.progress {
        ProgressBar::new(tiles.len() as u64)
    } else {
        ProgressBar::hidden()
    };
    bar.set_style(
        ProgressStyle::with_template("{bar:40} {percent:>3}% {elapsed_precise} ETA {eta}")
            .expect("valid template"),
    );
    let (rays, nanos) = (AtomicU64::new(0), AtomicU64::new(0));
    let start = Instant::now();
    let out_of_time = || {
        stop.load(Ordering::Relaxed) || settings.time_limit.is_some_and(|t| start.elapsed() >= t)
    };
    let pool = settings.pool()?;
    let complete = pool.install(|| {
        tiles
            .par_iter()
            .map(|&(tx, ty)| {
                if out_of_time() {
                    return false;
                }
                let (rays_before, nanos_before) = (rays_cast(), ray_nanos());
                let mut local = Vec::new();
                for y in ty..(ty + TILE).min(cy + ch) {
                    for x in tx..(tx + TILE).min(cx + cw) {
                        let stream = u64::from(y) * u64::from(w) + u64::from(x);
                        let mut rng = Pcg32::new(settings.seed, stream);
                        local.push(([x, y], pixel([x, y], &mut rng)));
                    }
                }
                store(local);
                rays.fetch_add(rays_cast() - rays_before, Ordering::Relaxed);
                nanos.fetch_add(ray_nanos() - nanos_before, Ordering::Relaxed);
                bar.inc(1);
                true
            })
            .collect::<Vec<bool>>()
            .into_iter()
            .all(|done| done)
    });
    bar.finish_and_clear();
    Ok(TileRun {
        seconds: start.elapsed().as_secs_f64(),
        rays: rays.load(Ordering::Relaxed),
        ray_seconds: nanos.load(Ordering::Relaxed) as f64 * 1e-9,
        complete,
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

/// Runs `pass` with the settings of each pass (its own seed, no time limit
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
            // Distant, distinct seeds: each pass draws from fresh streams.
            seed: round_seed(settings.seed, u64::from(passes)),
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
        // The first round keeps the seed asked for; later ones get their own.
        assert_eq!(round_seed(7, 0), 7);
        assert_ne!(round_seed(7, 1), 7);
        assert_eq!(
            round_size(&Settings::new(10, 0), 0, Duration::ZERO),
            Some(10)
        );
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
