//! MIS between techniques that differ only in how they sample a path's
//! last vertex: a path tracer's BSDF sampling and direct light sampling,
//! say. Their densities share every factor but the last, so a weight costs
//! one density per alternative, whatever the length of the path.

use smallvec::SmallVec;

use crate::density::{Density, Measure, PathDensity};
use crate::mis::Heuristic;
use crate::rng::UniformSource;
use crate::sequence::{RandomSequence, Span};
use crate::strategy::{DynStrategy, Prefix, Produced, StepKind, StrategyRef};
use crate::vertex::Vertex;

/// A vertex sampled beside a path, after its last vertex, by a strategy
/// other than the one the path goes on with (next-event estimation's light
/// sample), with the density that strategy gave it. The path is left as it
/// was; the next step weighs it ([`RandomSequence::append_sample_beside`]).
#[derive(Clone, Copy, Debug)]
pub struct Aside<V> {
    /// The vertex.
    pub vertex: V,
    /// Its density under the strategy that sampled it, conditioned on the
    /// path's vertices.
    pub density: Density,
}

impl<'s, V: Vertex> RandomSequence<'s, V> {
    /// Samples `strategy` once after this sequence's vertices without
    /// appending it: the vertex, with the density recorded while sampling
    /// it, or `None` if the step produced none (or the sequence stopped
    /// before its last step).
    #[inline(always)]
    pub fn sample_aside(
        &self,
        strategy: &dyn DynStrategy<V>,
        rng: &mut dyn UniformSource,
    ) -> Option<Aside<V>> {
        if !self.is_complete() {
            return None;
        }
        self.sample_after(self.len(), strategy, rng)
    }

    /// As [`sample_aside`](Self::sample_aside), after this sequence's first
    /// `len` vertices (a light sample from a prefix of a camera subpath,
    /// whether or not the subpath went on).
    ///
    /// # Panics
    /// If `len` is beyond the sequence's vertices.
    #[inline(always)]
    pub fn sample_after(
        &self,
        len: usize,
        strategy: &dyn DynStrategy<V>,
        rng: &mut dyn UniformSource,
    ) -> Option<Aside<V>> {
        let prefix = Prefix::forward(&self.vertices()[..len]);
        let mut out = Produced::<V>::new();
        let sampled = strategy.sample_step(prefix, rng, &mut out);
        let vertex = out.pop().filter(|_| sampled.kind == StepKind::Vertex)?;
        Some(Aside {
            vertex,
            density: sampled.density,
        })
    }

    /// Appends `strategy` and samples it, as
    /// [`append_sample`](Self::append_sample); with `aside`, a vertex
    /// sampled beside the same vertices by another strategy, also returns
    /// the MIS weight of `aside` between the two strategies (its own and
    /// `strategy`), over its density: what its estimate multiplies its
    /// integrand by (zero where that density vanishes, a grazing vertex
    /// whose contribution vanishes with it). `strategy`'s density for it
    /// comes from the distribution the step is sampled from (see
    /// [`append_sample_measuring`](Self::append_sample_measuring)).
    ///
    /// ```
    /// use aether_core::testing::{Bounce, CameraPoint, LightSample, LookDown, TestScene};
    /// use aether_core::{Heuristic, Pcg32, RandomSequence};
    ///
    /// let scene = TestScene::open_box();
    /// let (camera, look) = (CameraPoint::default(), LookDown::new(&scene));
    /// let (bounce, light) = (Bounce::new(&scene), LightSample::new(&scene));
    /// let mut rng = Pcg32::new(2, 0);
    /// let mut path = RandomSequence::new();
    /// path.append(&camera).append_sample(&look, &mut rng);
    /// let lamp = path.sample_aside(&light, &mut rng).expect("a point on the light");
    /// let (_, w_over_p) = path.append_sample_beside(&bounce, &mut rng, Some(&lamp), Heuristic::POWER);
    /// // The light sample's weight over its path's density: positive where it can be lit.
    /// assert!(w_over_p > 0.0 && w_over_p.is_finite());
    /// ```
    #[inline(always)]
    pub fn append_sample_beside(
        &mut self,
        strategy: &'s dyn DynStrategy<V>,
        rng: &mut dyn UniformSource,
        aside: Option<&Aside<V>>,
        heuristic: Heuristic,
    ) -> (bool, f64) {
        let Some(aside) = aside else {
            return (self.append_sample(strategy, rng), 0.0);
        };
        let n = self.len();
        let (sampled, by_step) = self.append_sample_measuring(strategy, rng, &aside.vertex);
        let last = [by_step, aside.density];
        let (w, p) = weight_of_step(self.pdf_of_prefix(n), &last, 1, heuristic);
        (sampled, p.weight_over(w))
    }
}

/// The MIS weight of `path` against the techniques that sample its
/// vertices but the last as `path` did (each step by the strategy that
/// sampled it, conditioned on the vertices before) and its last vertex by
/// one of `alternatives` (forward, conditioned on the vertices before it),
/// `alternatives[own]` being the technique that made `path`; and the
/// density of `path` under that technique.
///
/// The same weight as [`weight_of_split`](crate::weight_of_split) over
/// those techniques, factor for factor: the shared prefix is the running
/// product recorded while `path` was sampled, so only the last vertex's
/// density under each alternative is looked up (the one that sampled it
/// recorded its own). A path that is incomplete, empty, or ends inside a
/// multi-vertex step has weight and density zero.
///
/// ```
/// use aether_core::testing::{Bounce, CameraPoint, LightSample, LookDown, TestScene};
/// use aether_core::{DynStrategy, Heuristic, Pcg32, RandomSequence, StrategyRef, weight_of_last_step};
///
/// let scene = TestScene::open_box();
/// let (camera, look) = (CameraPoint::default(), LookDown::new(&scene));
/// let (bounce, light) = (Bounce::new(&scene), LightSample::new(&scene));
/// let mut path = RandomSequence::new();
/// path.append(&camera).append(&look).append(&light);
/// path.sample(&mut Pcg32::new(3, 0));
/// let alternatives = [&bounce as &dyn DynStrategy<_>, &light].map(StrategyRef::One);
/// let (w, p) = weight_of_last_step(&path, &alternatives, 1, Heuristic::POWER);
/// assert!(w > 0.0 && w <= 1.0 && p.value() > 0.0);
/// ```
#[must_use]
pub fn weight_of_last_step<'s, V: Vertex>(
    path: &RandomSequence<'_, V>,
    alternatives: &[StrategyRef<'s, V>],
    own: usize,
    heuristic: Heuristic,
) -> (f64, PathDensity) {
    let zero = PathDensity::ONE.times(Density::zero(Measure::Area));
    let n = path.len();
    if n == 0 || !path.is_complete() || own >= alternatives.len() || !path.single_step(n - 1) {
        return (0.0, zero);
    }
    let last: SmallVec<[Density; 4]> = alternatives
        .iter()
        .map(|&s| match s {
            StrategyRef::One(_) => path.factor(&Span::new(n - 1, 1, Some(s), false, 0), None),
            StrategyRef::Two(_) => Density::zero(Measure::Area),
        })
        .collect();
    weight_of_step(path.pdf_of_prefix(n - 1), &last, own, heuristic)
}

/// As [`weight_of_last_step`], from the densities it would look up: the
/// density `prefix` of the vertices before the last (the product the
/// techniques share, [`RandomSequence::pdf_of_prefix`]) and the last
/// vertex's density under each alternative, `last[own]` the one that
/// sampled it. For a vertex whose path is no longer at hand: a light
/// sample weighed after the next step was sampled from the same vertices,
/// its density under that step's strategy found while sampling
/// ([`RandomSequence::append_sample_measuring`]). The same arithmetic in
/// the same order, so the same bits.
///
/// ```
/// use aether_core::{Density, Heuristic, Measure, PathDensity, weight_of_step};
/// let prefix = PathDensity::ONE.times(Density::new(2.0, Measure::Area));
/// let last = [Density::new(1.0, Measure::Area), Density::new(3.0, Measure::Area)];
/// let (w, p) = weight_of_step(prefix, &last, 1, Heuristic::POWER);
/// assert!((w - 0.9).abs() < 1e-12 && p.value() == 6.0); // 3² / (1² + 3²)
/// ```
#[must_use]
pub fn weight_of_step(
    prefix: PathDensity,
    last: &[Density],
    own: usize,
    heuristic: Heuristic,
) -> (f64, PathDensity) {
    if own >= last.len() {
        return (0.0, PathDensity::ONE.times(Density::zero(Measure::Area)));
    }
    // Weighed as they are multiplied out, not stored: collected into a
    // list, two densities cost as much again as the heuristic itself.
    let own_density = prefix.times(last[own]);
    let densities = last.iter().map(|&d| prefix.times(d));
    (heuristic.weight_among(own_density, densities), own_density)
}
