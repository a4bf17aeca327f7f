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

use aether_core::primitives::UniformCells;
use aether_core::{Distribution, Pcg32, PrimarySamples, Sample, UniformSource};
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

/// The pixels of a scene's crop window, each picked with equal
/// probability by two uniforms: a sample's camera estimate counts once per
/// pixel because its density says so, not by a factor written here.
#[derive(Clone, Copy, Debug)]
pub(super) struct Pixels {
    origin: [u32; 2],
    cells: UniformCells,
}

impl Pixels {
    /// The crop window of `scene`.
    pub(super) fn of(scene: &Scene) -> Self {
        let [cx, cy, cw, ch] = scene.film.crop;
        Pixels {
            origin: [cx, cy],
            cells: UniformCells::new(cw, ch),
        }
    }

    /// The pixel the next two uniforms of `u` pick, and its probability.
    pub(super) fn pick(&self, u: &mut dyn UniformSource) -> ([u32; 2], f64) {
        let s = draw(&self.cells, u);
        (self.pixel(s.value), s.density.value())
    }

    /// Pixel `stratum` mod their number, in rows: each pixel with
    /// [`probability`](Self::probability), for a stratum that is equally
    /// likely any of them.
    pub(super) fn stratum(&self, stratum: u64) -> [u32; 2] {
        self.pixel((stratum % self.cells.len() as u64) as usize)
    }

    /// The pixel of cell `index` of the crop window.
    fn pixel(&self, index: usize) -> [u32; 2] {
        let [x, y] = self.cells.cell(index);
        [self.origin[0] + x, self.origin[1] + y]
    }

    /// The probability of each pixel.
    pub(super) fn probability(&self) -> f64 {
        self.cells.density(&0).value()
    }
}

/// A sample of `d` from the next uniforms of `u`.
fn draw<D: Distribution>(d: &D, u: &mut dyn UniformSource) -> Sample<D::Value> {
    let uniforms = [u.next_f32(), u.next_f32()];
    d.sample(&uniforms[..d.dims()])
        .expect("a uniform choice always samples")
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
    pixels: Pixels,
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
            pixels: Pixels::of(scene),
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
        let (pixel, p) = self.pixels.pick(&mut u);
        state.contributions.clear();
        let camera = self.bdpt.sample(pixel, &mut u, &mut state.contributions);
        state.contributions.push((pixel, camera / p as f32));
        state.f = target(&state.contributions);
    }
}

impl Sampler for Pssmlt<'_> {
    type State = State;

    fn bootstrap(&self, _class: usize, _stratum: u64, stream: &mut Pcg32) -> f64 {
        let mut state = State::default();
        self.evaluate(&mut state, stream);
        state.f
    }

    fn start(
        &self,
        _class: usize,
        _stratum: u64,
        stream: &mut Pcg32,
        _rng: &mut Pcg32,
        state: &mut State,
    ) {
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
    pixels: Pixels,
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
            pixels: Pixels::of(scene),
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
        let technique = draw(&UniformCells::new(techniques as u32, 1), &mut u);
        let s = n + 1 - techniques + technique.value;
        let (pixel, p) = self.pixels.pick(&mut u);
        state.contributions.clear();
        let camera = self
            .bdpt
            .sample_technique(pixel, (n, s), &mut u, &mut state.contributions);
        let chosen = technique.density.value() as f32;
        for (_, c) in &mut state.contributions {
            *c /= chosen;
        }
        if camera != glam::Vec3::ZERO {
            state
                .contributions
                .push((pixel, camera / (p as f32 * chosen)));
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

    fn bootstrap(&self, class: usize, _stratum: u64, stream: &mut Pcg32) -> f64 {
        let mut state = State::default();
        self.evaluate(class, &mut state, stream);
        state.f
    }

    fn start(
        &self,
        class: usize,
        _stratum: u64,
        stream: &mut Pcg32,
        _rng: &mut Pcg32,
        state: &mut ClassState,
    ) {
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
