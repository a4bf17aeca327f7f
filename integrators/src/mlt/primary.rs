//! Metropolis in primary sample space: a chain over the uniforms one BDPT
//! sample consumes, mutated by Kelemen's large steps (a fresh point) and
//! small steps (every coordinate perturbed). Both are symmetric, so the
//! acceptance is min(1, F(u′) / F(u)).
//!
//! * [`Pssmlt`] (Kelemen et al. 2002): the first two coordinates pick the
//!   pixel; a sample contributes its camera estimate, times the number of
//!   pixels, to that pixel, plus its light-path splats, so that E[g(u)] is
//!   the image.
//! * [`Mmlt`] (Hachisuka et al. 2014): one chain state per path length; the
//!   first coordinate picks the technique (s, t), so the chain moves between
//!   techniques, and a sample evaluates that one technique alone, weighed
//!   by MIS against the others of its length and multiplied by their
//!   number.

use aether_core::{Pcg32, PrimarySamples, UniformSource};
use aether_strategies::scene::Scene;

use super::{Sampler, UNLIMITED_VERTICES, target};
use crate::bdpt::Bdpt;
use crate::estimator::{Estimator, Splats};

/// One evaluated point of primary sample space.
#[derive(Clone, Debug, Default)]
pub struct State {
    samples: PrimarySamples,
    contributions: Splats,
    f: f64,
}

/// The pixel two uniforms pick in `scene`'s crop window, and the number of
/// pixels there.
pub(super) fn pixel(scene: &Scene, u: &mut dyn UniformSource) -> ([u32; 2], f32) {
    let [cx, cy, cw, ch] = scene.film.crop;
    let pick = |u: f32, n: u32| ((u * n as f32) as u32).min(n - 1);
    let p = [cx + pick(u.next_f32(), cw), cy + pick(u.next_f32(), ch)];
    (p, cw as f32 * ch as f32)
}

/// A large or a small step from `current` into `proposal`, its evaluation
/// by `evaluate`, and the acceptance probability.
fn step(
    large_step: f64,
    current: &State,
    proposal: &mut State,
    rng: &mut Pcg32,
    evaluate: impl FnOnce(&mut State, &mut Pcg32),
) -> f64 {
    proposal.samples.copy_from(&current.samples);
    if f64::from(rng.next_f32()) < large_step {
        proposal.samples.large_step();
    } else {
        proposal.samples.small_step(rng);
    }
    evaluate(proposal, rng);
    if current.f > 0.0 {
        (proposal.f / current.f).min(1.0)
    } else {
        1.0
    }
}

/// PSSMLT over BDPT.
#[derive(Debug)]
pub struct Pssmlt<'s> {
    scene: &'s Scene,
    bdpt: Bdpt<'s>,
    large_step: f64,
}

impl<'s> Pssmlt<'s> {
    /// PSSMLT on the BDPT of `scene`, with the scene's large-step probability.
    ///
    /// # Errors
    /// If BDPT cannot be built for the scene.
    pub fn new(scene: &'s Scene) -> Result<Self, String> {
        Ok(Pssmlt {
            scene,
            bdpt: Bdpt::new(scene)?,
            large_step: scene.integrator.metropolis.large_step,
        })
    }

    /// With large steps of probability `p`.
    #[must_use]
    pub fn with_large_step(self, p: f64) -> Self {
        Pssmlt {
            large_step: p,
            ..self
        }
    }

    /// Runs BDPT on the point `state.samples` (drawing any coordinate it
    /// lacks from `fresh`) and records its contributions and F.
    fn evaluate(&self, state: &mut State, fresh: &mut Pcg32) {
        let mut u = state.samples.replay(fresh);
        let (pixel, pixels) = pixel(self.scene, &mut u);
        state.contributions.clear();
        let camera = self.bdpt.sample(pixel, &mut u, &mut state.contributions);
        // A pixel picked with probability 1 / pixels: its estimate counts
        // that many times.
        state.contributions.push((pixel, camera * pixels));
        state.f = target(&state.contributions);
    }
}

impl Sampler for Pssmlt<'_> {
    type State = State;

    fn bootstrap(&self, _class: usize, stream: &mut Pcg32) -> f64 {
        let mut state = State::default();
        self.evaluate(&mut state, stream);
        state.f
    }

    fn start(&self, _class: usize, stream: &mut Pcg32, _rng: &mut Pcg32, state: &mut State) {
        state.samples = PrimarySamples::new();
        self.evaluate(state, stream);
    }

    fn mutate(&self, current: &State, proposal: &mut State, rng: &mut Pcg32) -> f64 {
        step(self.large_step, current, proposal, rng, |s, r| {
            self.evaluate(s, r);
        })
    }

    fn contributions<'a>(&self, state: &'a State) -> (&'a Splats, f64) {
        (&state.contributions, state.f)
    }
}

/// Multiplexed MLT over BDPT: one class per path length.
#[derive(Debug)]
pub struct Mmlt<'s> {
    scene: &'s Scene,
    bdpt: Bdpt<'s>,
    large_step: f64,
    max_vertices: usize,
}

impl<'s> Mmlt<'s> {
    /// Multiplexed MLT on the BDPT of `scene`, with the scene's large-step
    /// probability, for paths of 2 up to the scene's maximum number of
    /// vertices ([`UNLIMITED_VERTICES`] if it sets none).
    ///
    /// # Errors
    /// If BDPT cannot be built for the scene.
    pub fn new(scene: &'s Scene) -> Result<Self, String> {
        let bdpt = Bdpt::new(scene)?;
        Ok(Mmlt {
            scene,
            max_vertices: bdpt.max_vertices().min(UNLIMITED_VERTICES),
            bdpt,
            large_step: scene.integrator.metropolis.large_step,
        })
    }

    /// With large steps of probability `p`.
    #[must_use]
    pub fn with_large_step(self, p: f64) -> Self {
        Mmlt {
            large_step: p,
            ..self
        }
    }

    /// Evaluates `state.samples` as a path of `class + 2` vertices: the
    /// first coordinate picks the technique, the next two the pixel.
    fn evaluate(&self, class: usize, state: &mut State, fresh: &mut Pcg32) {
        let n = class + 2;
        let mut u = state.samples.replay(fresh);
        let techniques = self.bdpt.techniques(n);
        let first = n + 1 - techniques;
        let s = first + ((u.next_f32() * techniques as f32) as usize).min(techniques - 1);
        let (pixel, pixels) = pixel(self.scene, &mut u);
        state.contributions.clear();
        let camera = self
            .bdpt
            .sample_technique(pixel, (n, s), &mut u, &mut state.contributions);
        // The technique was picked with probability 1 / techniques.
        let count = techniques as f32;
        for (_, c) in &mut state.contributions {
            *c *= count;
        }
        if camera != glam::Vec3::ZERO {
            state.contributions.push((pixel, camera * pixels * count));
        }
        state.f = target(&state.contributions);
    }
}

/// The class a state belongs to is kept with it.
#[derive(Clone, Debug, Default)]
pub struct ClassState {
    class: usize,
    state: State,
}

impl Sampler for Mmlt<'_> {
    type State = ClassState;

    fn classes(&self) -> usize {
        self.max_vertices.saturating_sub(1).max(1)
    }

    fn bootstrap(&self, class: usize, stream: &mut Pcg32) -> f64 {
        let mut state = State::default();
        self.evaluate(class, &mut state, stream);
        state.f
    }

    fn start(&self, class: usize, stream: &mut Pcg32, _rng: &mut Pcg32, state: &mut ClassState) {
        state.class = class;
        state.state.samples = PrimarySamples::new();
        self.evaluate(class, &mut state.state, stream);
    }

    fn mutate(&self, current: &ClassState, proposal: &mut ClassState, rng: &mut Pcg32) -> f64 {
        let class = current.class;
        proposal.class = class;
        step(
            self.large_step,
            &current.state,
            &mut proposal.state,
            rng,
            |s, r| {
                self.evaluate(class, s, r);
            },
        )
    }

    fn contributions<'a>(&self, state: &'a ClassState) -> (&'a Splats, f64) {
        (&state.state.contributions, state.state.f)
    }
}
