//! Check (d): MIS partition of unity, and `combine` against direct evaluation.

use smallvec::SmallVec;

use crate::mis::{Heuristic, combine};
use crate::rng::UniformSource;
use crate::sequence::RandomSequence;
use crate::strategy::{DynPairStrategy, DynStrategy, StrategyRef};
use crate::vertex::Vertex;

/// A way of sampling a whole path: strategies in path order, each forward
/// (sampled from the camera end) or reversed (sampled from the light end).
pub struct Technique<'s, V> {
    steps: SmallVec<[(StrategyRef<'s, V>, bool); 8]>,
}

impl<V> std::fmt::Debug for Technique<'_, V> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_list()
            .entries(
                self.steps
                    .iter()
                    .map(|(s, r)| (s.name(), if *r { "reversed" } else { "forward" })),
            )
            .finish()
    }
}

impl<V: Vertex> Default for Technique<'_, V> {
    fn default() -> Self {
        Self::new()
    }
}

impl<'s, V: Vertex> Technique<'s, V> {
    /// The empty technique.
    #[must_use]
    pub fn new() -> Self {
        Technique {
            steps: SmallVec::new(),
        }
    }

    /// Appends a step sampled from the camera end.
    #[must_use]
    pub fn forward(mut self, s: &'s dyn DynStrategy<V>) -> Self {
        self.steps.push((StrategyRef::One(s), false));
        self
    }

    /// Appends a two-vertex step sampled from the camera end.
    #[must_use]
    pub fn forward_pair(mut self, s: &'s dyn DynPairStrategy<V>) -> Self {
        self.steps.push((StrategyRef::Two(s), false));
        self
    }

    /// Appends a step sampled from the light end.
    #[must_use]
    pub fn reversed(mut self, s: &'s dyn DynStrategy<V>) -> Self {
        self.steps.push((StrategyRef::One(s), true));
        self
    }

    /// Appends a two-vertex step sampled from the light end.
    #[must_use]
    pub fn reversed_pair(mut self, s: &'s dyn DynPairStrategy<V>) -> Self {
        self.steps.push((StrategyRef::Two(s), true));
        self
    }

    /// Samples a path: the forward steps from the start, the reversed
    /// steps from the end (last first), joined. `None` if a step failed.
    pub fn sample<R: UniformSource>(&self, rng: &mut R) -> Option<RandomSequence<'s, V>> {
        let mut camera = RandomSequence::new();
        let mut light = RandomSequence::new();
        for &(s, reversed) in &self.steps {
            if !reversed {
                camera.pending_push(s);
            }
        }
        for &(s, reversed) in self.steps.iter().rev() {
            if reversed {
                light.pending_push(s);
            }
        }
        let complete = camera.sample(rng) == crate::StepKind::Vertex
            && light.sample(rng) == crate::StepKind::Vertex;
        complete.then(|| camera.concat(&light.reversed()))
    }

    /// The same vertices as `path`, assigned to this technique's strategies.
    #[must_use]
    pub fn assign(&self, path: &RandomSequence<'s, V>) -> Option<RandomSequence<'s, V>> {
        path.with_strategies(&self.steps)
    }
}

/// What [`check_mis`] measured.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MisReport {
    /// Paths checked.
    pub paths: usize,
    /// Largest |Σ w − 1|.
    pub max_partition_error: f64,
    /// Largest difference between the weights of `combine` and those from
    /// densities evaluated afresh.
    pub max_density_error: f64,
    /// For each technique, its mean weight over all checked paths.
    pub mean_weights: Vec<f64>,
}

/// Samples `paths_per_technique` paths with each technique and checks, for
/// each path, that the MIS weights of all techniques on it sum to one
/// within 1e-9, that the sampling technique's own density is positive, and
/// that [`combine`]'s weights (from recorded, cached and incrementally
/// updated densities) equal those from densities evaluated afresh, to 1e-5.
///
/// The check verifies the MIS bookkeeping, not the densities themselves:
/// those are what [`check`](super::check) verifies for each strategy.
pub fn check_mis<V: Vertex + std::fmt::Debug, R: UniformSource>(
    techniques: &[Technique<'_, V>],
    heuristic: Heuristic,
    paths_per_technique: usize,
    rng: &mut R,
) -> Result<MisReport, String> {
    let mut report = MisReport {
        mean_weights: vec![0.0; techniques.len()],
        ..MisReport::default()
    };
    for (t, technique) in techniques.iter().enumerate() {
        for _ in 0..paths_per_technique {
            let Some(path) = technique.sample(rng) else {
                continue;
            };
            let candidates: Vec<_> = techniques.iter().filter_map(|q| q.assign(&path)).collect();
            if candidates.len() != techniques.len() {
                return Err(format!(
                    "technique {t} produced a path of {} vertices that another technique cannot take",
                    path.len()
                ));
            }
            let weights = combine(&candidates, heuristic);
            let sum: f64 = weights.iter().sum();
            // Direct evaluation: every factor afresh, without the densities
            // recorded while sampling or cached between candidates, so that a
            // wrong cache key (a strategy that misstates its memory) shows.
            let direct: Vec<_> = candidates.iter().map(|c| c.pdf_of_fresh(&path)).collect();
            if direct[t].is_zero() {
                return Err(format!(
                    "technique {t} sampled a path that its own density calls impossible: {path:?}"
                ));
            }
            if (sum - 1.0).abs() > 1e-9 {
                return Err(format!(
                    "weights {weights:?} sum to {sum} on a path of technique {t}; densities {direct:?}"
                ));
            }
            for (i, w) in weights.iter().enumerate() {
                let w_direct = heuristic.weight(&direct, i);
                // Densities recorded while sampling come from the forward map
                // and agree with density mode to about 1e-7 (single-precision
                // geometry), so the weights are compared to 1e-5.
                let err = (w - w_direct).abs();
                if err > 1e-5 {
                    return Err(format!(
                        "combine gives weight {w} to technique {i}, direct evaluation {w_direct}"
                    ));
                }
                report.max_density_error = report.max_density_error.max(err);
                report.mean_weights[i] += w;
            }
            report.max_partition_error = report.max_partition_error.max((sum - 1.0).abs());
            report.paths += 1;
        }
    }
    let total = report.paths.max(1) as f64;
    report.mean_weights.iter_mut().for_each(|w| *w /= total);
    Ok(report)
}
