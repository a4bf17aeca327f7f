//! Primary-sample-space Metropolis light transport (Kelemen et al. 2002)
//! on this project's BDPT: a Markov chain over the uniforms that one BDPT
//! sample consumes, the first two of which pick the pixel.
//!
//! One sample contributes g(u) to the image: its camera estimate times the
//! number of pixels to the pixel it picked, and its light-path splats where
//! they land, so that E[g(u)] is the image. The chain's target is the
//! luminance F(u) = Y(Σ g(u)); its normalisation b = E[F] comes from
//! independent bootstrap samples, which also seed the chains (resampled in
//! proportion to F, so that the chains start in their stationary
//! distribution). Each mutation is a large step (a fresh point) or a small
//! one (every coordinate perturbed); both are symmetric, so the acceptance
//! is min(1, F(u′) / F(u)), and both the current and the proposed sample
//! are splatted with their expected weights.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use aether_core::{Pcg32, PrimarySamples, UniformSource};
use aether_strategies::geometry::rays_cast;
use aether_strategies::scene::Scene;
use aether_strategies::spectrum::luminance;
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;

use crate::bdpt::Bdpt;
use crate::estimator::{Estimator, Splats};
use crate::film::Film;
use crate::render::{Rendered, Settings};

/// Mutations between looks at the clock and the stop flag.
const CHECK_EVERY: u64 = 256;

/// The chain's parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MltSettings {
    /// Probability of a large step.
    pub large_step: f64,
    /// Independent chains (fixed, so that an image depends on the seed and
    /// not on the threads).
    pub chains: usize,
    /// Independent samples that estimate the normalisation and seed the chains.
    pub bootstrap: usize,
}

impl Default for MltSettings {
    fn default() -> Self {
        MltSettings {
            large_step: 0.3,
            chains: 16,
            bootstrap: 100_000,
        }
    }
}

/// PSSMLT over BDPT.
#[derive(Debug)]
pub struct Pssmlt<'s> {
    scene: &'s Scene,
    bdpt: Bdpt<'s>,
}

/// One evaluated point of primary sample space: its contributions to the
/// image and their luminance.
#[derive(Clone, Debug, Default)]
struct State {
    samples: PrimarySamples,
    contributions: Splats,
    f: f64,
}

impl<'s> Pssmlt<'s> {
    /// PSSMLT on the BDPT of `scene`.
    ///
    /// # Errors
    /// If BDPT cannot be built for the scene.
    pub fn new(scene: &'s Scene) -> Result<Self, String> {
        Ok(Pssmlt {
            scene,
            bdpt: Bdpt::new(scene)?,
        })
    }

    /// Runs BDPT on the point `state.samples` (drawing any coordinate it
    /// lacks from `fresh`) and records its contributions and luminance.
    fn evaluate(&self, state: &mut State, fresh: &mut Pcg32) {
        let [cx, cy, cw, ch] = self.scene.film.crop;
        let pixels = f64::from(cw) * f64::from(ch);
        let mut u = state.samples.replay(fresh);
        let pick = |u: f32, n: u32| ((u * n as f32) as u32).min(n - 1);
        let pixel = [cx + pick(u.next_f32(), cw), cy + pick(u.next_f32(), ch)];
        state.contributions.clear();
        let camera = self.bdpt.sample(pixel, &mut u, &mut state.contributions);
        // A pixel picked with probability 1 / pixels: its estimate counts
        // that many times.
        state.contributions.push((pixel, camera * pixels as f32));
        state.f = state
            .contributions
            .iter()
            .map(|(_, c)| luminance(c.to_array()))
            .sum();
        if !state.f.is_finite() || state.f < 0.0 {
            state.f = 0.0;
            state.contributions.clear();
        }
    }
}

/// Renders `scene` by PSSMLT with `settings.spp` mutations per pixel of
/// the crop window, in `mlt.chains` chains run in parallel; deterministic
/// for a seed. The time limit and `stop` end the chains early, and the
/// image is normalised by the mutations made.
///
/// # Errors
/// If BDPT cannot be built, the scene is black (no bootstrap sample
/// carries light), or the worker threads cannot start.
pub fn render_mlt(
    scene: &Scene,
    mlt: MltSettings,
    settings: &Settings,
    stop: &AtomicBool,
) -> Result<Rendered, String> {
    let start = Instant::now();
    let tracer = Pssmlt::new(scene)?;
    let (w, h) = (scene.film.width, scene.film.height);
    let [_, _, cw, ch] = scene.film.crop;
    let pool = settings.pool()?;
    let chains = mlt.chains.max(1);
    let total = u64::from(settings.spp) * u64::from(cw) * u64::from(ch);
    let per_chain = total.div_ceil(chains as u64);
    let bar = if settings.progress {
        ProgressBar::new(per_chain * chains as u64)
    } else {
        ProgressBar::hidden()
    };
    bar.set_style(
        ProgressStyle::with_template("{bar:40} {percent:>3}% {elapsed_precise} ETA {eta}")
            .expect("valid template"),
    );
    let out_of_time = || {
        stop.load(Ordering::Relaxed) || settings.time_limit.is_some_and(|t| start.elapsed() >= t)
    };
    let seed = settings.seed;
    let (image, mutations, samples, rays) = pool.install(|| -> Result<_, String> {
        // Bootstrap: F of independent points, each from its own stream.
        let bootstrap = mlt.bootstrap.max(1);
        let fs: Vec<f64> = (0..bootstrap as u64)
            .into_par_iter()
            .map(|i| {
                let mut state = State::default();
                tracer.evaluate(&mut state, &mut Pcg32::new(seed, i));
                state.f
            })
            .collect();
        let sum: f64 = fs.iter().sum();
        if !(sum > 0.0 && sum.is_finite()) {
            return Err("no bootstrap sample carries light: the image is black".to_string());
        }
        let b = sum / bootstrap as f64;
        let cumulative: Vec<f64> = fs
            .iter()
            .scan(0.0, |acc, f| {
                *acc += f;
                Some(*acc)
            })
            .collect();
        let results: Vec<(Vec<[f64; 3]>, u64, u64)> = (0..chains as u64)
            .into_par_iter()
            .map(|k| {
                let rays_before = rays_cast();
                let mut rng = Pcg32::new(seed ^ 0x6d6c_745f_6368_6169, k);
                // The chain starts at a bootstrap point picked in proportion to F.
                let target = f64::from(rng.next_f32()) * sum;
                let i = cumulative
                    .partition_point(|&c| c <= target)
                    .min(bootstrap - 1);
                let mut current = State::default();
                tracer.evaluate(&mut current, &mut Pcg32::new(seed, i as u64));
                let mut proposal = State::default();
                let mut image = vec![[0.0f64; 3]; w as usize * h as usize];
                let mut splat = |state: &State, weight: f64| {
                    if weight > 0.0 && state.f > 0.0 {
                        let scale = weight / state.f;
                        for ([x, y], c) in &state.contributions {
                            let p = &mut image[(y * w + x) as usize];
                            for (a, v) in p.iter_mut().zip(c.to_array()) {
                                *a += scale * f64::from(v);
                            }
                        }
                    }
                };
                let mut done = 0u64;
                while done < per_chain {
                    if done % CHECK_EVERY == 0 {
                        if out_of_time() {
                            break;
                        }
                        bar.inc(CHECK_EVERY.min(per_chain - done));
                    }
                    proposal.samples.copy_from(&current.samples);
                    if f64::from(rng.next_f32()) < mlt.large_step {
                        proposal.samples.large_step();
                    } else {
                        proposal.samples.small_step(&mut rng);
                    }
                    tracer.evaluate(&mut proposal, &mut rng);
                    let accept = if current.f > 0.0 {
                        (proposal.f / current.f).min(1.0)
                    } else {
                        1.0
                    };
                    splat(&current, 1.0 - accept);
                    splat(&proposal, accept);
                    if f64::from(rng.next_f32()) < accept {
                        std::mem::swap(&mut current, &mut proposal);
                    }
                    done += 1;
                }
                (image, done, rays_cast() - rays_before)
            })
            .collect();
        let mutations: u64 = results.iter().map(|r| r.1).sum();
        let rays: u64 = results.iter().map(|r| r.2).sum();
        let mut image = vec![[0.0f64; 3]; w as usize * h as usize];
        for (chain, _, _) in &results {
            for (a, c) in image.iter_mut().zip(chain) {
                for k in 0..3 {
                    a[k] += c[k];
                }
            }
        }
        let scale = b / mutations.max(1) as f64;
        for a in &mut image {
            *a = a.map(|v| v * scale);
        }
        Ok((image, mutations, bootstrap as u64 + mutations, rays))
    })?;
    bar.finish_and_clear();
    let [cx, cy, _, _] = scene.film.crop;
    let in_crop = |i: usize| {
        let (x, y) = (i as u32 % w, i as u32 / w);
        (cx..cx + cw).contains(&x) && (cy..cy + ch).contains(&y)
    };
    let film = Film::from_image(w, h, &image, in_crop);
    Ok(Rendered {
        film,
        seconds: start.elapsed().as_secs_f64(),
        samples,
        rays,
        ray_seconds: 0.0,
        complete: mutations >= total,
    })
}
