//! Veach's path-space Metropolis light transport (Veach and Guibas 1997).
//!
//! The state is a path; it moves by Veach's mutations
//! ([`aether_strategies::mutations::Mutations`]), and the acceptance uses
//! T(y | x) and T(x | y) that the language derives from the mutations' own
//! sampling code. The chains start from paths a BDPT pass found, picked in
//! proportion to their MIS-weighted contribution; the same pass estimates
//! the normalisation. Optionally, direct lighting (paths of one and two
//! edges) is rendered separately, as Veach did, and left out of the chains.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use aether_core::{ChainPath, Pcg32, UniformSource, acceptance, propose, transition_density};
use aether_strategies::camera::Camera;
use aether_strategies::integrand::Integrand;
use aether_strategies::lights::Lights;
use aether_strategies::mutations::{Kind, MutationSettings, Mutations, Only, Specular};
use aether_strategies::scene::Scene;
use aether_strategies::spectrum::luminance;
use aether_strategies::vertex::SceneVertex;
use glam::DVec3;
use smallvec::SmallVec;

use super::primary::Pixels;
use super::{MltSettings, Sampler, UNLIMITED_VERTICES, crop_film, pick, run_chains, target};
use crate::bdpt::{Bdpt, SeedPath};
use crate::direct::DirectLighting;
use crate::estimator::Splats;
use crate::render::{Rendered, Settings, render_with};

thread_local! {
    /// The paths of one BDPT seed sample, reused.
    static SEEDS: std::cell::RefCell<(Vec<SeedPath>, Splats)> =
        const { std::cell::RefCell::new((Vec::new(), Vec::new())) };
}

/// A path with what it contributes to the image and its luminance F.
#[derive(Clone, Debug, Default)]
pub struct State {
    path: ChainPath<SceneVertex>,
    contributions: Splats,
    f: f64,
}

/// How each mutation fared: proposals made, proposals that produced a path
/// carrying light, and the sum of their acceptance probabilities.
#[derive(Debug, Default)]
pub struct Statistics {
    counts: [[AtomicU64; 3]; 4],
}

/// Acceptance probabilities are summed in units of 2⁻³².
const FIXED: f64 = 4_294_967_296.0;

impl Statistics {
    fn record(&self, kind: Kind, produced: bool, accept: f64) {
        let c = &self.counts[kind as usize];
        c[0].fetch_add(1, Ordering::Relaxed);
        if produced {
            c[1].fetch_add(1, Ordering::Relaxed);
            c[2].fetch_add((accept * FIXED) as u64, Ordering::Relaxed);
        }
    }

    /// For each mutation: proposals, proposals that produced a path
    /// carrying light, and the mean acceptance probability over all
    /// proposals.
    #[must_use]
    pub fn rows(&self) -> [(Kind, u64, u64, f64); 4] {
        Kind::ALL.map(|k| {
            let c = &self.counts[k as usize];
            let n = c[0].load(Ordering::Relaxed);
            let accepted = c[2].load(Ordering::Relaxed) as f64 / FIXED;
            (
                k,
                n,
                c[1].load(Ordering::Relaxed),
                accepted / n.max(1) as f64,
            )
        })
    }
}

/// Veach's MLT on a scene.
#[derive(Debug)]
pub struct VeachMlt<'s> {
    scene: &'s Scene,
    camera: Camera,
    lights: Lights<'s>,
    bdpt: Bdpt<'s>,
    settings: MutationSettings,
    specular: Specular,
    /// The pixels bootstrap samples are taken at.
    pixels: Pixels,
    /// Paths of at most this many vertices are rendered by a separate
    /// direct-lighting pass (0: none).
    direct_vertices: usize,
    statistics: Statistics,
}

impl<'s> VeachMlt<'s> {
    /// Veach's MLT of `scene` with the mutation mix of `mlt`.
    ///
    /// # Errors
    /// If the scene has no light, or the camera or BDPT cannot be built.
    pub fn new(scene: &'s Scene, mlt: &MltSettings) -> Result<Self, String> {
        let lights = Lights::new(scene).ok_or("Metropolis light transport needs a light")?;
        let bdpt = Bdpt::new(scene)?;
        let max = bdpt.max_vertices().min(UNLIMITED_VERTICES);
        let mut settings = MutationSettings::new(scene.film.width, scene.film.height, max);
        [
            settings.bidirectional,
            settings.lens,
            settings.caustic,
            settings.multi_chain,
        ] = mlt.mutations;
        settings.roughness_threshold = scene.integrator.gradient.roughness_threshold;
        Ok(VeachMlt {
            specular: Specular::of(scene, settings.roughness_threshold),
            pixels: Pixels::of(scene),
            scene,
            camera: Camera::new(scene)?,
            lights,
            bdpt,
            settings,
            direct_vertices: if mlt.direct_samples > 0 { 3 } else { 0 },
            statistics: Statistics::default(),
        })
    }

    /// How each mutation fared so far.
    #[must_use]
    pub fn statistics(&self) -> &Statistics {
        &self.statistics
    }

    /// The mutations, borrowing this sampler's camera and lights.
    #[must_use]
    pub fn mutations(&self) -> Mutations<'_, 's> {
        Mutations::new(
            self.scene,
            &self.camera,
            &self.lights,
            &self.specular,
            self.settings,
        )
    }

    /// The contributions and F of `state.path`. Edges copied from `from`
    /// keep their visibility; every other edge is tested.
    fn evaluate(&self, state: &mut State, from: Option<&ChainPath<SceneVertex>>) {
        state.contributions.clear();
        state.f = 0.0;
        let v = state.path.vertices();
        let n = v.len();
        if n < 2 || n <= self.direct_vertices || n > self.settings.max_vertices {
            return;
        }
        let connections: SmallVec<[usize; 12]> = (0..n - 1)
            .filter(|&i| from.is_none_or(|x| !state.path.edge_copied_from(i, x)))
            .collect();
        let f = Integrand::new(self.scene, &self.camera, &self.lights);
        let through = f.throughput(v, &connections);
        let Some(d) = v[0].direction_to(&v[1]).filter(|_| through != DVec3::ZERO) else {
            return;
        };
        for j in self.camera.pixels_toward(&v[0], d) {
            let c = through * self.camera.importance(j, &v[0], d);
            if c.is_finite() && c != DVec3::ZERO {
                state.contributions.push((j, c.as_vec3()));
            }
        }
        state.f = target(&state.contributions);
    }

    /// The chain's target F of `path`: the luminance of its contributions
    /// to every pixel. Edges copied from `from` are taken as visible.
    #[must_use]
    pub fn target(
        &self,
        path: &ChainPath<SceneVertex>,
        from: Option<&ChainPath<SceneVertex>>,
    ) -> f64 {
        let mut state = State {
            path: path.clone(),
            ..State::default()
        };
        self.evaluate(&mut state, from);
        state.f
    }

    /// The paths one BDPT sample drawn from `stream` finds, with F > 0:
    /// the candidates the chains start from.
    pub fn seed_paths(&self, stream: &mut Pcg32) -> Vec<ChainPath<SceneVertex>> {
        let seeds = self.seed_sample(None, stream, |seeds| {
            seeds
                .iter()
                .filter(|s| self.seed_weight(s) > 0.0)
                .map(|s| ChainPath::new(s.vertices.iter().copied()))
                .collect::<Vec<_>>()
        });
        seeds
            .into_iter()
            .filter(|p| self.target(p, None) > 0.0)
            .collect()
    }

    /// The share of F a BDPT seed path carries: its weighted contribution,
    /// counted once per pixel for paths of the sample's own pixel (picked
    /// with probability one over their number).
    fn seed_weight(&self, seed: &SeedPath) -> f64 {
        if seed.vertices.len() <= self.direct_vertices {
            return 0.0;
        }
        let picked = if seed.splat {
            1.0
        } else {
            self.pixels.probability()
        };
        let y = luminance(seed.weighted.as_vec3().to_array()) / picked;
        if y.is_finite() && y > 0.0 { y } else { 0.0 }
    }

    /// Runs one BDPT sample from `stream` at the pixel of `stratum` (or
    /// one the stream picks), and hands its paths to `use_seeds`.
    fn seed_sample<T>(
        &self,
        stratum: Option<u64>,
        stream: &mut Pcg32,
        use_seeds: impl FnOnce(&[SeedPath]) -> T,
    ) -> T {
        let pixel = match stratum {
            Some(k) => self.pixels.stratum(k),
            None => self.pixels.pick(stream).0,
        };
        SEEDS.with_borrow_mut(|(seeds, splats)| {
            seeds.clear();
            splats.clear();
            self.bdpt.sample_seeds(pixel, stream, splats, seeds);
            use_seeds(seeds)
        })
    }
}

impl Sampler for VeachMlt<'_> {
    type State = State;

    fn bootstrap(&self, _class: usize, stratum: u64, stream: &mut Pcg32) -> f64 {
        self.seed_sample(Some(stratum), stream, |seeds| {
            seeds.iter().map(|s| self.seed_weight(s)).sum()
        })
    }

    fn start(
        &self,
        _class: usize,
        stratum: u64,
        stream: &mut Pcg32,
        rng: &mut Pcg32,
        state: &mut State,
    ) {
        let path = self.seed_sample(Some(stratum), stream, |seeds| {
            let weights = seeds.iter().map(|s| self.seed_weight(s));
            let target = f64::from(rng.next_f32()) * weights.clone().sum::<f64>();
            pick(weights, target).map(|i| ChainPath::new(seeds[i].vertices.iter().copied()))
        });
        state.path = path.unwrap_or_default();
        self.evaluate(state, None);
    }

    fn mutate(&self, current: &State, proposal: &mut State, rng: &mut Pcg32) -> f64 {
        let mutations = self.mutations();
        // Picking the mutation here, as the mixture's own code would, lets
        // the chain count how each fares; T is still the mixture's.
        let weights = mutations.weights(current.path.vertices());
        let target = f64::from(rng.next_f32()) * weights.iter().sum::<f64>();
        let kind = pick(weights, target).map(|k| Kind::ALL[k]);
        let proposed = kind.and_then(|kind| {
            let only = Only {
                mutations: &mutations,
                kind,
            };
            propose(&only, &current.path, rng)
        });
        let (Some(kind), Some((y, _))) = (kind, proposed) else {
            proposal.contributions.clear();
            proposal.f = 0.0;
            // Where no mutation applies (one alone, for a path it does not
            // fit), the chain stays, and no mutation is charged with it.
            if let Some(kind) = kind {
                self.statistics.record(kind, false, 0.0);
            }
            return 0.0;
        };
        proposal.path = y;
        self.evaluate(proposal, Some(&current.path));
        if proposal.f == 0.0 {
            self.statistics.record(kind, false, 0.0);
            return 0.0;
        }
        let forward = transition_density(&mutations, &current.path, &proposal.path);
        let backward = transition_density(&mutations, &proposal.path, &current.path);
        let a = acceptance(current.f, proposal.f, forward, backward);
        self.statistics.record(kind, true, a);
        a
    }

    fn contributions<'a>(&self, state: &'a State) -> (&'a Splats, f64) {
        (&state.contributions, state.f)
    }
}

/// Renders `scene` by Veach's MLT, plus the separate direct-lighting pass
/// if `mlt` asks for one; also returns how each mutation fared.
///
/// # Errors
/// As [`render_mlt`](super::render_mlt).
pub fn render(
    scene: &Scene,
    mlt: &MltSettings,
    settings: &Settings,
    stop: &AtomicBool,
) -> Result<(Rendered, Statistics), String> {
    let sampler = VeachMlt::new(scene, mlt)?;
    let rendered = render_with_direct(&sampler, scene, mlt, settings, stop)?;
    Ok((rendered, sampler.statistics))
}

fn render_with_direct(
    sampler: &VeachMlt<'_>,
    scene: &Scene,
    mlt: &MltSettings,
    settings: &Settings,
    stop: &AtomicBool,
) -> Result<Rendered, String> {
    if mlt.direct_samples == 0 {
        return run_chains(sampler, scene, mlt, settings, stop);
    }
    // The direct pass first, so that the chains get what is left of the time.
    let direct = DirectLighting::new(scene)?;
    let pass = Settings {
        spp: mlt.direct_samples,
        progress: false,
        ..settings.clone()
    };
    let lit = render_with(scene, &direct, &pass, stop)?;
    let rest = Settings {
        time_limit: settings
            .time_limit
            .map(|t| t.saturating_sub(std::time::Duration::from_secs_f64(lit.seconds))),
        ..settings.clone()
    };
    let chains = run_chains(sampler, scene, mlt, &rest, stop)?;
    let image = crate::parts::with_direct(&chains.film.image(), &lit.film.image());
    let mut partial = chains.partial;
    crate::parts::put_prefixed(&lit.partial, "direct.", &mut partial);
    Ok(Rendered {
        partial,
        film: crop_film(scene, &image),
        seconds: chains.seconds + lit.seconds,
        samples: chains.samples,
        rays: chains.rays + lit.rays,
        ray_seconds: chains.ray_seconds + lit.ray_seconds,
        complete: chains.complete && lit.complete,
    })
}
