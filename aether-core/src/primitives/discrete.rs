use std::fmt;

use smallvec::{SmallVec, smallvec};

use crate::density::{Density, Measure};
use crate::distribution::{Distribution, Sample, Uniforms, below_one};

/// Why a discrete distribution could not be built.
#[derive(Clone, Debug, PartialEq)]
pub enum DiscreteError {
    /// No weights were given.
    Empty,
    /// Weight `index` is negative, NaN or infinite.
    InvalidWeight {
        /// Position of the weight.
        index: usize,
        /// Its value.
        value: f64,
    },
    /// All weights are zero.
    ZeroTotal,
}

impl fmt::Display for DiscreteError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DiscreteError::Empty => write!(f, "a discrete distribution needs at least one weight"),
            DiscreteError::InvalidWeight { index, value } => {
                write!(
                    f,
                    "weight {index} is {value}; weights must be finite and non-negative"
                )
            }
            DiscreteError::ZeroTotal => write!(f, "all weights are zero"),
        }
    }
}

impl std::error::Error for DiscreteError {}

/// A distribution over `0..n` proportional to given weights.
///
/// Sampling is a binary search over the CDF (O(log n)); the probability of a
/// known outcome is a table lookup (O(1)), so that the density of a light or
/// a triangle that a vertex lies on is looked up, never enumerated. Up to
/// two outcomes are stored inline: lobe choices, built at every scattering
/// event, allocate nothing and stay small to move (a light's or a
/// texture's table, built once per scene, lives on the heap).
///
/// Density: the probability of the outcome, in counting measure.
///
/// ```
/// use aether_core::{Distribution, primitives::DiscreteDistribution};
/// let d = DiscreteDistribution::new(&[1.0, 3.0]).unwrap();
/// assert_eq!(d.probability(1), 0.75);
/// assert_eq!(d.sample(&[0.9]).unwrap().value, 1);
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct DiscreteDistribution {
    /// cdf[i] = P(outcome < i); cdf[n] = 1.
    cdf: SmallVec<[f64; 3]>,
    pmf: SmallVec<[f64; 2]>,
}

impl DiscreteDistribution {
    /// Normalises `weights` into a distribution.
    pub fn new(weights: &[f64]) -> Result<Self, DiscreteError> {
        if weights.is_empty() {
            return Err(DiscreteError::Empty);
        }
        // One pass to check and sum; lobe choices (one or two weights) are
        // built at every scattering event, so the tables are filled in place.
        let mut total = 0.0;
        for (index, &value) in weights.iter().enumerate() {
            if !(value.is_finite() && value >= 0.0) {
                return Err(DiscreteError::InvalidWeight { index, value });
            }
            total += value;
        }
        if total <= 0.0 {
            return Err(DiscreteError::ZeroTotal);
        }
        let n = weights.len();
        if n == 1 {
            // w / w: a certain outcome (most lobe choices).
            return Ok(DiscreteDistribution {
                cdf: SmallVec::from_buf_and_len([0.0, 1.0, 0.0], 2),
                pmf: SmallVec::from_buf_and_len([1.0, 0.0], 1),
            });
        }
        let mut pmf: SmallVec<[f64; 2]> = SmallVec::from_elem(0.0, n);
        let mut cdf: SmallVec<[f64; 3]> = SmallVec::from_elem(0.0, n + 1);
        let mut acc = 0.0;
        for (i, w) in weights.iter().enumerate() {
            pmf[i] = w / total;
            acc += w;
            cdf[i + 1] = acc / total;
        }
        cdf[n] = 1.0;
        Ok(DiscreteDistribution { cdf, pmf })
    }

    /// Number of outcomes.
    #[must_use]
    pub fn len(&self) -> usize {
        self.pmf.len()
    }

    /// True if there are no outcomes (never, for a constructed distribution).
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.pmf.is_empty()
    }

    /// Probability of outcome `i` (zero out of range).
    #[must_use]
    pub fn probability(&self, i: usize) -> f64 {
        self.pmf.get(i).copied().unwrap_or(0.0)
    }

    /// Selects an outcome with `u` and remaps `u` to a fresh uniform in
    /// `[0, 1)` that the chosen branch can reuse.
    #[must_use]
    pub fn select(&self, u: f32) -> (usize, f32) {
        if self.pmf.len() == 1 {
            // A certain outcome (most lobe choices, a box filter's one
            // cell): `u` is already its remapped uniform, the value the
            // division below would return, without a division's latency on
            // every scattering event.
            return (0, below_one(u.max(0.0)));
        }
        let u64 = f64::from(u);
        // First i with cdf[i + 1] > u: outcomes of zero probability are
        // skipped. The CDF is sorted, so that is the number of entries at
        // most u: counted in one pass for a few outcomes (a light's
        // triangles, a BSDF's lobes), whose binary search mispredicted its
        // branch on every other sample (2.7 % of a path tracer's time for
        // 0.9 % of its instructions); searched for many.
        let cdf = &self.cdf[1..];
        let below = if cdf.len() <= 16 {
            cdf.iter().map(|&c| usize::from(c <= u64)).sum()
        } else {
            cdf.partition_point(|&c| c <= u64)
        };
        let i = below.min(self.len() - 1);
        let remapped = (u64 - self.cdf[i]) / self.pmf[i];
        (i, below_one(remapped.max(0.0) as f32))
    }

    /// The uniform that [`select`](Self::select) maps to outcome `i` with
    /// remapped uniform `rest`: the inverse of the selection.
    #[must_use]
    pub fn unselect(&self, i: usize, rest: f32) -> f32 {
        below_one((self.cdf[i] + f64::from(rest) * self.pmf[i]) as f32)
    }
}

impl Distribution for DiscreteDistribution {
    type Value = usize;
    fn dims(&self) -> usize {
        1
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<usize>> {
        let (i, _) = self.select(u[0]);
        Some(Sample::new(i, Density::discrete(self.pmf[i])))
    }
    fn density(&self, i: &usize) -> Density {
        Density::new(self.probability(*i), Measure::Discrete)
    }
    fn invert(&self, i: &usize) -> Option<Uniforms> {
        (self.probability(*i) > 0.0).then(|| smallvec![self.unselect(*i, 0.5)])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zero_weights_are_never_selected() {
        let d = DiscreteDistribution::new(&[0.0, 1.0, 0.0, 1.0]).unwrap();
        for k in 0..1000 {
            let (i, r) = d.select(k as f32 / 1000.0);
            assert!(i == 1 || i == 3);
            assert!((0.0..1.0).contains(&r));
        }
    }

    #[test]
    fn a_certain_outcome_keeps_its_uniform() {
        let d = DiscreteDistribution::new(&[2.5]).unwrap();
        for u in [0.0, 1e-9, 0.3, 0.5, 0.999_999_9, 1.0, -0.0, f32::NAN] {
            // What the general case computes for outcome 0.
            let general = below_one(((f64::from(u) - d.cdf[0]) / d.pmf[0]).max(0.0) as f32);
            assert_eq!(d.select(u).1.to_bits(), general.to_bits(), "u = {u}");
        }
    }

    #[test]
    fn select_and_unselect_are_inverse() {
        let d = DiscreteDistribution::new(&[0.2, 0.5, 0.3]).unwrap();
        for u in [0.0, 0.1, 0.25, 0.69, 0.71, 0.999] {
            let (i, r) = d.select(u);
            assert!((d.unselect(i, r) - u).abs() < 1e-6);
        }
    }

    #[test]
    fn bad_weights_are_reported() {
        assert_eq!(DiscreteDistribution::new(&[]), Err(DiscreteError::Empty));
        assert!(matches!(
            DiscreteDistribution::new(&[1.0, f64::NAN]),
            Err(DiscreteError::InvalidWeight { index: 1, .. })
        ));
        assert_eq!(
            DiscreteDistribution::new(&[0.0]),
            Err(DiscreteError::ZeroTotal)
        );
    }
}
