//! Metropolis light transport: Veach's path-space MLT ([`veach`]),
//! primary-sample-space MLT (Kelemen et al. 2002) and multiplexed MLT
//! (Hachisuka et al. 2014) on this project's BDPT ([`primary`]).
//!
//! All three run the same loop. A state contributes g to the image (a list
//! of pixels and colours); the chain's target is its luminance F = Y(Σ g).
//! The normalisation b = ∫F comes from independent bootstrap samples, which
//! also seed the chains (resampled in proportion to F, so that the chains
//! start near their stationary distribution). Each mutation proposes a
//! state and the acceptance probability a; both the current and the
//! proposed state are splatted with their expected weights (1 − a and a),
//! scaled by b / F. Multiplexed MLT keeps one state per path length
//! ("class") and picks the class of each mutation in proportion to its b,
//! so every mutation has the same weight b / M in the image.
//!
//! A fixed number of chains run in parallel with rayon, each from its own
//! random stream, so that an image depends on the seed and not on the
//! threads.

pub mod primary;
pub mod veach;

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::Instant;

use aether_core::{Pcg32, UniformSource};
use aether_strategies::geometry::{ray_nanos, rays_cast};
use aether_strategies::scene::Scene;
use aether_strategies::spectrum::luminance;
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;

use crate::estimator::Splats;
use crate::film::Film;
use crate::render::{Rendered, Settings};
use crate::shard::Partial;

/// Mutations between looks at the clock and the stop flag.
const CHECK_EVERY: u64 = 256;

/// Longest path, in vertices, for scenes that set no maximum depth: MLT
/// needs a finite set of lengths. Paths of 32 vertices carry a negligible
/// share of light in any scene with albedos below 0.9.
pub const UNLIMITED_VERTICES: usize = 32;

/// Which Metropolis method.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Variant {
    /// Veach's path-space MLT: bidirectional mutation and lens, caustic and
    /// multi-chain perturbations (`mlt`).
    Veach,
    /// Kelemen's primary-sample-space MLT over all of BDPT (`pssmlt`).
    Primary,
    /// Multiplexed MLT: primary sample space over one BDPT technique at a
    /// time, the technique part of the state (`mmlt`).
    Multiplexed,
}

impl Variant {
    /// The variant an integrator name asks for (`mlt`, `pssmlt`, `mmlt`).
    #[must_use]
    pub fn named(name: &str) -> Option<Variant> {
        match name {
            "mlt" => Some(Variant::Veach),
            "pssmlt" => Some(Variant::Primary),
            "mmlt" => Some(Variant::Multiplexed),
            _ => None,
        }
    }
}

/// The chains' parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MltSettings {
    /// The method.
    pub variant: Variant,
    /// Probability of a large step (primary sample space).
    pub large_step: f64,
    /// Independent chains (fixed, so that an image depends on the seed and
    /// not on the threads).
    pub chains: usize,
    /// Independent samples that estimate the normalisation and seed the
    /// chains (for multiplexed MLT, per path length).
    pub bootstrap: usize,
    /// Relative frequencies of Veach's bidirectional, lens, caustic and
    /// multi-chain mutations.
    pub mutations: [f64; 4],
    /// Samples per pixel of a separate direct-lighting pass (Veach's MLT;
    /// 0: none): the chains then leave out paths of up to two edges.
    pub direct_samples: u32,
}

impl Default for MltSettings {
    fn default() -> Self {
        MltSettings {
            variant: Variant::Primary,
            large_step: 0.3,
            chains: 16,
            bootstrap: 100_000,
            mutations: [1.0; 4],
            direct_samples: 0,
        }
    }
}

impl MltSettings {
    /// The settings `scene`'s integrator asks for (its name picks the
    /// variant; PSSMLT for integrators that are not Metropolis methods).
    #[must_use]
    pub fn for_scene(scene: &Scene) -> Self {
        let m = &scene.integrator.metropolis;
        MltSettings {
            variant: Variant::named(&scene.integrator.name).unwrap_or(Variant::Primary),
            large_step: m.large_step,
            chains: m.chains as usize,
            bootstrap: m.luminance_samples as usize,
            mutations: m.mutations,
            direct_samples: m.direct_samples,
        }
    }
}

/// A Markov chain over some state space, as the loop in [`run_chains`]
/// drives it.
pub(crate) trait Sampler: Sync {
    /// A state: a point of the space with its contributions and F.
    type State: Default + Send;

    /// Classes of states with chains of their own (path lengths for
    /// multiplexed MLT), each with its own normalisation.
    fn classes(&self) -> usize {
        1
    }

    /// F of an independent sample of `class` drawn from `stream` (summed
    /// over the sample's candidates). `stratum` counts the class's samples
    /// from a random offset: a sampler that picks a pixel may take pixel
    /// `stratum` mod their number, each pixel still picked with equal
    /// probability but the pixels evenly covered, which takes their
    /// variation out of the normalisation's error.
    fn bootstrap(&self, class: usize, stratum: u64, stream: &mut Pcg32) -> f64;

    /// Redraws the sample of `class` and `stratum` from `stream` and puts
    /// into `state` one of its candidates, picked with `rng` in proportion
    /// to F.
    fn start(
        &self,
        class: usize,
        stratum: u64,
        stream: &mut Pcg32,
        rng: &mut Pcg32,
        state: &mut Self::State,
    );

    /// Proposes a move from `current` into `proposal` and returns the
    /// acceptance probability (0 if the proposal failed).
    fn mutate(&self, current: &Self::State, proposal: &mut Self::State, rng: &mut Pcg32) -> f64;

    /// What `state` contributes, and its F.
    fn contributions<'a>(&self, state: &'a Self::State) -> (&'a Splats, f64);
}

/// F of a list of contributions: the sum of their luminances, zero if
/// that is not a finite non-negative number.
pub(crate) fn target(contributions: &Splats) -> f64 {
    let f: f64 = contributions
        .iter()
        .map(|(_, c)| luminance(c.to_array()))
        .sum();
    if f.is_finite() && f > 0.0 { f } else { 0.0 }
}

/// Renders `scene` with the Metropolis method of `mlt.variant`, with
/// `settings.spp` mutations per pixel of the crop window in `mlt.chains`
/// chains run in parallel; deterministic for a seed. The time limit and
/// `stop` end the chains early, and the image is normalised by the
/// mutations made. The result counts mutations as its samples (its time
/// includes the bootstrap). A time limit is a target, not a cut-off: the
/// bootstrap and each chain's first batch of mutations run whatever the
/// clock says, since without them there is no image, only black; `stop`
/// (an interrupt) ends even the bootstrap.
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
    let p = mlt.large_step;
    match mlt.variant {
        Variant::Primary => {
            let sampler = primary::Pssmlt::new(scene)?.with_large_step(p);
            run_chains(&sampler, scene, &mlt, settings, stop)
        }
        Variant::Multiplexed => {
            let sampler = primary::Mmlt::new(scene)?.with_large_step(p);
            run_chains(&sampler, scene, &mlt, settings, stop)
        }
        Variant::Veach => veach::render(scene, &mlt, settings, stop).map(|(r, _)| r),
    }
}

/// The Metropolis loop shared by every variant (see the module documentation).
pub(crate) fn run_chains<S: Sampler>(
    sampler: &S,
    scene: &Scene,
    mlt: &MltSettings,
    settings: &Settings,
    stop: &AtomicBool,
) -> Result<Rendered, String> {
    let start = Instant::now();
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
    let stopped = || stop.load(Ordering::Relaxed);
    let past_limit = || settings.time_limit.is_some_and(|t| start.elapsed() >= t);
    let seed = settings.seed;
    let classes = sampler.classes().max(1);
    let (image, mutations, rays, nanos, b_total) = pool.install(|| -> Result<_, String> {
        // Bootstrap: sample i belongs to class i mod classes, on stream i;
        // each class gets the number asked for (as pbrt-v3's MMLT does).
        let bootstrap = mlt.bootstrap.max(1) * classes;
        // Sample i is its class's (i / classes)-th, counted from an offset
        // drawn from the seed, so that any stratum is equally likely.
        let offset = u64::from(Pcg32::new(seed, u64::MAX).next_u32());
        let stratum = |i: u64| offset + i / classes as u64;
        let (boot_rays, boot_nanos) = (AtomicU64::new(0), AtomicU64::new(0));
        let fs: Vec<f64> = (0..bootstrap as u64)
            .into_par_iter()
            .map(|i| {
                if stopped() {
                    return 0.0;
                }
                let (rays, nanos) = (rays_cast(), ray_nanos());
                let c = i as usize % classes;
                let f = sampler.bootstrap(c, stratum(i), &mut Pcg32::new(seed, i));
                boot_rays.fetch_add(rays_cast() - rays, Ordering::Relaxed);
                boot_nanos.fetch_add(ray_nanos() - nanos, Ordering::Relaxed);
                f
            })
            .collect();
        // Per class: its samples' running sums (to pick seeds) and b.
        let mut cumulative = vec![Vec::new(); classes];
        let mut b = vec![0.0; classes];
        for (i, f) in fs.iter().enumerate() {
            let c = i % classes;
            b[c] += f;
            let last = cumulative[c].last().copied().unwrap_or(0.0);
            cumulative[c].push(last + f);
        }
        for (c, sum) in b.iter_mut().enumerate() {
            *sum /= cumulative[c].len().max(1) as f64;
        }
        let b_total: f64 = b.iter().sum();
        if stopped() {
            // Interrupted during the bootstrap: no chain has started.
            let black = vec![[0.0f64; 3]; w as usize * h as usize];
            return Ok((
                black,
                0,
                boot_rays.into_inner(),
                boot_nanos.into_inner(),
                0.0,
            ));
        }
        if !(b_total > 0.0 && b_total.is_finite()) {
            return Err("no bootstrap sample carries light: the image is black".to_string());
        }
        // A part of the render runs its share of the chains, each as the
        // whole render would (its own stream, the shared normalisation).
        let results: Vec<(Vec<[f64; 3]>, u64, [u64; 2])> = settings
            .shard
            .share(chains as u64)
            .into_par_iter()
            .map(|k| {
                let before = [rays_cast(), ray_nanos()];
                let mut rng = Pcg32::new(seed ^ 0x6d6c_745f_6368_6169, k);
                // Each class starts at a bootstrap sample picked in proportion to F.
                let mut current: Vec<S::State> = (0..classes)
                    .map(|c| {
                        let mut state = S::State::default();
                        let sums = &cumulative[c];
                        if let Some(&sum) = sums.last().filter(|&&s| s > 0.0) {
                            let target = f64::from(rng.next_f32()) * sum;
                            let j = sums.partition_point(|&s| s <= target).min(sums.len() - 1);
                            let i = (j * classes + c) as u64;
                            let stream = &mut Pcg32::new(seed, i);
                            sampler.start(c, stratum(i), stream, &mut rng, &mut state);
                        }
                        state
                    })
                    .collect();
                let mut proposal = S::State::default();
                let mut image = vec![[0.0f64; 3]; w as usize * h as usize];
                let mut splat = |state: &S::State, weight: f64| {
                    let (contributions, f) = sampler.contributions(state);
                    // A path whose F or contribution overflowed (reflectance
                    // far above one) is left out, as the estimators drop
                    // non-finite samples: no NaN reaches the image.
                    if weight > 0.0 && f > 0.0 && f.is_finite() {
                        let scale = weight / f;
                        for ([x, y], c) in contributions.iter().filter(|(_, c)| c.is_finite()) {
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
                        // The first batch runs whatever the clock says.
                        if stopped() || (done > 0 && past_limit()) {
                            break;
                        }
                        bar.inc(CHECK_EVERY.min(per_chain - done));
                    }
                    let c = if classes == 1 {
                        0
                    } else {
                        pick(b.iter().copied(), f64::from(rng.next_f32()) * b_total).unwrap_or(0)
                    };
                    let a = sampler.mutate(&current[c], &mut proposal, &mut rng);
                    splat(&current[c], 1.0 - a);
                    splat(&proposal, a);
                    if f64::from(rng.next_f32()) < a {
                        std::mem::swap(&mut current[c], &mut proposal);
                    }
                    done += 1;
                }
                (
                    image,
                    done,
                    [rays_cast() - before[0], ray_nanos() - before[1]],
                )
            })
            .collect();
        let mutations: u64 = results.iter().map(|r| r.1).sum();
        let rays = boot_rays.into_inner() + results.iter().map(|r| r.2[0]).sum::<u64>();
        let nanos = boot_nanos.into_inner() + results.iter().map(|r| r.2[1]).sum::<u64>();
        let mut image = vec![[0.0f64; 3]; w as usize * h as usize];
        for (chain, _, _) in &results {
            for (a, c) in image.iter_mut().zip(chain) {
                for k in 0..3 {
                    a[k] += c[k];
                }
            }
        }
        Ok((image, mutations, rays, nanos, b_total))
    })?;
    bar.finish_and_clear();
    let mut partial = Partial::new(w, h);
    partial.put_rgb("chain", &image);
    partial.totals.insert("mutations".into(), mutations as f64);
    partial
        .same
        .insert("normalisation".into(), b_total.to_string());
    let image = crate::parts::chain_image(&image, b_total, mutations as f64);
    let ours = settings.shard.share(chains as u64);
    Ok(Rendered {
        film: crop_film(scene, &image),
        seconds: start.elapsed().as_secs_f64(),
        samples: mutations,
        rays,
        ray_seconds: nanos as f64 * 1e-9,
        complete: mutations >= per_chain * (ours.end - ours.start),
        partial,
    })
}

/// The index whose share of `weights` holds `target` (in [0, Σ weights)),
/// or the last positive weight's where rounding leaves `target` past the
/// end; `None` if no weight is positive.
pub(crate) fn pick(weights: impl IntoIterator<Item = f64>, mut target: f64) -> Option<usize> {
    let mut last = None;
    for (i, w) in weights.into_iter().enumerate() {
        if w > 0.0 {
            if target < w {
                return Some(i);
            }
            target -= w;
            last = Some(i);
        }
    }
    last
}

/// A film holding `image` (row by row) at the pixels of `scene`'s crop
/// window.
pub(crate) fn crop_film(scene: &Scene, image: &[[f64; 3]]) -> Film {
    let (w, h) = (scene.film.width, scene.film.height);
    let [cx, cy, cw, ch] = scene.film.crop;
    let in_crop = |i: usize| {
        let (x, y) = (i as u32 % w, i as u32 / w);
        (cx..cx + cw).contains(&x) && (cy..cy + ch).contains(&y)
    };
    Film::from_image(w, h, image, in_crop)
}
