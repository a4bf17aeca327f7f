//! Rendering in rounds: every render takes its samples per pixel in rounds
//! of growing size over the whole crop window, so that a stop request, a
//! time limit or a signal leaves every pixel with about as many samples as
//! any other, and the image written then is the whole image at the counts
//! each pixel got.
//!
//! A sample's random stream is keyed by the seed, the pixel and the
//! sample's index only ([`sample_stream`]): the value of a sample does not
//! depend on the rounds, on the threads, or on which process of a sharded
//! render took it.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use aether_core::Pcg32;
use aether_strategies::geometry::{ray_nanos, rays_cast};
use aether_strategies::scene::Scene;
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;

use crate::render::Settings;

/// Tiles are squares of this many pixels on a side.
const TILE: u32 = 16;

/// The random stream of sample `index` of pixel `pixel` (its row-major
/// index in the film) under `seed`.
#[must_use]
pub fn sample_stream(seed: u64, pixel: u64, index: u32) -> Pcg32 {
    // SplitMix64 of the seed and the index: distant starting points on the
    // pixel's stream, so that samples of one pixel do not overlap.
    let mut z = seed ^ u64::from(index).wrapping_mul(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    Pcg32::new(z ^ (z >> 31), pixel)
}

/// The samples of one pixel in one round, as their random streams, in
/// order of index; the iterator ends early when a stop is requested
/// (between two samples), and says so to the round.
#[derive(Debug)]
pub struct PixelSamples<'a> {
    seed: u64,
    pixel: u64,
    next: u32,
    end: u32,
    stop: &'a AtomicBool,
    cut: &'a AtomicBool,
}

impl PixelSamples<'_> {
    /// The number of samples this round asks of the pixel.
    #[must_use]
    pub fn asked(&self) -> u32 {
        self.end - self.next
    }
}

impl Iterator for PixelSamples<'_> {
    type Item = Pcg32;

    fn next(&mut self) -> Option<Pcg32> {
        if self.next >= self.end {
            return None;
        }
        if self.stop.load(Ordering::Relaxed) {
            self.cut.store(true, Ordering::Relaxed);
            return None;
        }
        self.next += 1;
        Some(sample_stream(self.seed, self.pixel, self.next - 1))
    }
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

/// Runs `round` (given the round's index and settings, whose samples are
/// `first_sample .. first_sample + spp` of every pixel, and the progress
/// bar, returning its tile run) on the settings' worker threads until
/// `settings.spp` samples per pixel are taken, time runs out or a round is
/// cut short. The rounds kept are every finished one and the first even if
/// cut: a later round cut short is the caller's to keep or leave out.
///
/// # Errors
/// If the worker threads cannot start, or the first error of a round.
pub(crate) fn render_rounds(
    settings: &Settings,
    pixels: u64,
    mut round: impl FnMut(u64, &Settings, &ProgressBar) -> Result<TileRun, String> + Send,
) -> Result<Rounds, String> {
    // A part of the render takes its share of each pixel's samples.
    let share = settings.shard.share(u64::from(settings.spp));
    let settings = &Settings {
        first_sample: settings.first_sample + share.start as u32,
        spp: (share.end - share.start) as u32,
        shard: crate::shard::Shard::WHOLE,
        ..settings.clone()
    };
    let start = Instant::now();
    let bar = progress_bar(settings, pixels);
    let pool = settings.pool()?;
    let (mut done, mut rays, mut ray_seconds, mut cut) = (0u32, 0, 0.0, false);
    pool.install(|| -> Result<(), String> {
        for index in 0u64.. {
            let Some(spp) = round_size(settings, done, start.elapsed()) else {
                break;
            };
            let this = Settings {
                spp,
                first_sample: settings.first_sample + done,
                time_limit: settings
                    .time_limit
                    .map(|t| t.saturating_sub(start.elapsed())),
                ..settings.clone()
            };
            let run = round(index, &this, &bar)?;
            (rays, ray_seconds) = (rays + run.rays, ray_seconds + run.ray_seconds);
            if run.complete || index == 0 {
                done += spp;
            }
            if !run.complete {
                cut = true;
                break;
            }
        }
        Ok(())
    })?;
    bar.finish_and_clear();
    Ok(Rounds {
        spp: done,
        rays,
        ray_seconds,
        seconds: start.elapsed().as_secs_f64(),
        complete: !cut && done == settings.spp,
    })
}

/// A bar over the samples of every pixel, or over the time limit.
fn progress_bar(settings: &Settings, pixels: u64) -> ProgressBar {
    if !settings.progress {
        return ProgressBar::hidden();
    }
    let bar = match settings.time_limit {
        Some(t) => ProgressBar::new(t.as_millis() as u64),
        None => ProgressBar::new(u64::from(settings.spp) * pixels),
    };
    bar.set_style(
        ProgressStyle::with_template("{bar:40} {percent:>3}% {elapsed_precise} ETA {eta}")
            .expect("valid template"),
    );
    bar
}

/// The samples per pixel of the next round of a render that has taken
/// `done` of `settings.spp` in `elapsed`, or none when it is finished.
/// Without a time limit, rounds double (1, 1, 2, 4, …), so that a stop
/// request finds every pixel at about the same count, for at most one
/// round's worth of work more than a single pass would take. With a time
/// limit, they grow to about half the time left (a huge `spp` means "until
/// the time limit").
pub(crate) fn round_size(settings: &Settings, done: u32, elapsed: Duration) -> Option<u32> {
    let left = settings.spp - done;
    match settings.time_limit {
        _ if left == 0 => None,
        _ if done == 0 => Some(1),
        None => Some(done.min(left)),
        Some(limit) if elapsed >= limit => None,
        Some(limit) => {
            let per_sample = elapsed.as_secs_f64() / f64::from(done);
            let fits = (limit - elapsed).as_secs_f64() / per_sample / 2.0;
            Some((fits as u32).clamp(1, left))
        }
    }
}

/// One round over the crop window's pixels, by tiles in parallel on the
/// current worker threads: `pixel` is run for each with the pixel's
/// samples of this round ([`PixelSamples`]), and each finished tile's
/// results are handed to `store`. Tiles not yet started when time runs out
/// or `stop` is set are skipped; a pixel under way stops between samples.
///
/// # Errors
/// None yet: the signature leaves room for a failing store.
pub fn render_tiles<T: Send>(
    scene: &Scene,
    settings: &Settings,
    stop: &AtomicBool,
    bar: &ProgressBar,
    pixel: impl Fn([u32; 2], PixelSamples<'_>) -> T + Sync,
    store: impl Fn(Tile<T>) + Sync,
) -> Result<TileRun, String> {
    let w = scene.film.width;
    let [cx, cy, cw, ch] = scene.film.crop;
    let tiles: Vec<(u32, u32)> = (cy..cy + ch)
        .step_by(TILE as usize)
        .flat_map(|y| (cx..cx + cw).step_by(TILE as usize).map(move |x| (x, y)))
        .collect();
    let (rays, nanos) = (AtomicU64::new(0), AtomicU64::new(0));
    let cut = AtomicBool::new(false);
    let start = Instant::now();
    let timed = settings.time_limit.is_some();
    let out_of_time = || {
        stop.load(Ordering::Relaxed) || settings.time_limit.is_some_and(|t| start.elapsed() >= t)
    };
    let first = settings.first_sample;
    let end = first + settings.spp;
    let started = bar.elapsed();
    let all_started = tiles
        .par_iter()
        .map(|&(tx, ty)| {
            if out_of_time() {
                return false;
            }
            let (rays_before, nanos_before) = (rays_cast(), ray_nanos());
            // One allocation per tile and round, not one per doubling.
            let mut local = Vec::with_capacity((TILE * TILE) as usize);
            for y in ty..(ty + TILE).min(cy + ch) {
                for x in tx..(tx + TILE).min(cx + cw) {
                    let samples = PixelSamples {
                        seed: settings.seed,
                        pixel: u64::from(y) * u64::from(w) + u64::from(x),
                        next: first,
                        end,
                        stop,
                        cut: &cut,
                    };
                    local.push(([x, y], pixel([x, y], samples)));
                }
            }
            let pixels = local.len() as u64;
            store(local);
            rays.fetch_add(rays_cast() - rays_before, Ordering::Relaxed);
            nanos.fetch_add(ray_nanos() - nanos_before, Ordering::Relaxed);
            if timed {
                bar.set_position(bar.elapsed().as_millis() as u64);
            } else {
                bar.inc(pixels * u64::from(settings.spp));
            }
            true
        })
        .collect::<Vec<bool>>()
        .into_iter()
        .all(|done| done);
    if timed {
        bar.set_position((started + start.elapsed()).as_millis() as u64);
    }
    Ok(TileRun {
        seconds: start.elapsed().as_secs_f64(),
        rays: rays.load(Ordering::Relaxed),
        ray_seconds: nanos.load(Ordering::Relaxed) as f64 * 1e-9,
        complete: all_started && !cut.load(Ordering::Relaxed),
    })
}
