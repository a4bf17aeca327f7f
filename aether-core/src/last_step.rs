//! MIS between techniques that differ only in how they sample a path's
//! last vertex: a path tracer's BSDF sampling and direct light sampling,
//! say. Their densities share every factor but the last, so a weight costs
//! one density per alternative, whatever the length of the path.

use smallvec::SmallVec;

use crate::density::{Density, Measure, PathDensity};
use crate::mis::Heuristic;
use crate::sequence::{RandomSequence, Span};
use crate::strategy::StrategyRef;
use crate::vertex::Vertex;

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
    // In an array where they fit: collected into a list, two densities
    // cost as much again as the heuristic itself.
    let mut inline = [PathDensity::ONE; 4];
    let spilled: SmallVec<[PathDensity; 4]>;
    let densities = match inline.get_mut(..last.len()) {
        Some(d) => {
            for (p, &l) in d.iter_mut().zip(last) {
                *p = prefix.times(l);
            }
            &*d
        }
        None => {
            spilled = last.iter().map(|&d| prefix.times(d)).collect();
            &spilled[..]
        }
    };
    (heuristic.weight(densities, own), densities[own])
}
