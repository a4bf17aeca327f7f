//! Primary sample space (Kelemen et al. 2002): the uniforms a sampler
//! consumes, kept as a point of the unit hypercube so that a Markov chain
//! can mutate them and replay the sampler on the result.

use crate::rng::{Pcg32, UniformSource};

/// The uniforms of one run of a sampler. [`replay`](Self::replay) hands
/// them out again in order; coordinates past the end are drawn fresh from
/// the chain's generator (uniform, as the target density of unused
/// coordinates is) and kept.
///
/// ```
/// use aether_core::{Pcg32, PrimarySamples, UniformSource};
/// let (mut u, mut chain) = (PrimarySamples::new(), Pcg32::new(1, 0));
/// let first = {
///     let mut r = u.replay(&mut chain);
///     (r.next_f32(), r.next_f32())
/// };
/// let mut r = u.replay(&mut chain);
/// assert_eq!((r.next_f32(), r.next_f32()), first); // replayed
/// let mut v = PrimarySamples::new();
/// v.copy_from(&u);
/// v.small_step(&mut chain);
/// assert_ne!(v.replay(&mut chain).next_f32(), first.0); // perturbed
/// ```
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PrimarySamples {
    values: Vec<f32>,
}

/// A [`PrimarySamples`] being replayed: a source of uniforms.
#[derive(Debug)]
pub struct Replay<'a> {
    values: &'a mut Vec<f32>,
    next: usize,
    fresh: &'a mut Pcg32,
}

impl PrimarySamples {
    /// Smallest and largest perturbation of a small step (Kelemen's s₁, s₂).
    const SMALL: (f32, f32) = (1.0 / 1024.0, 1.0 / 64.0);

    /// A point none of whose coordinates has been used yet.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// The uniforms from the first coordinate on, new ones drawn from `fresh`.
    pub fn replay<'a>(&'a mut self, fresh: &'a mut Pcg32) -> Replay<'a> {
        Replay {
            values: &mut self.values,
            next: 0,
            fresh,
        }
    }

    /// Coordinates used so far.
    #[must_use]
    pub fn len(&self) -> usize {
        self.values.len()
    }

    /// True before any coordinate is used.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.values.is_empty()
    }

    /// Becomes a copy of `other`, reusing this point's storage.
    pub fn copy_from(&mut self, other: &Self) {
        self.values.clone_from(&other.values);
    }

    /// A large step: an independent point (every coordinate drawn afresh
    /// when it is used).
    pub fn large_step(&mut self) {
        self.values.clear();
    }

    /// A small step: each coordinate moved by ±s₂·(s₁/s₂)^ξ, wrapped to
    /// [0, 1). The move is symmetric, so its transition densities cancel
    /// in the acceptance ratio.
    pub fn small_step(&mut self, rng: &mut Pcg32) {
        let (s1, s2) = Self::SMALL;
        for v in &mut self.values {
            let size = s2 * (s1 / s2).powf(rng.next_f32());
            let moved = if rng.next_f32() < 0.5 {
                *v + size
            } else {
                *v - size
            };
            *v = moved - moved.floor();
            if *v >= 1.0 {
                *v = 0.0;
            }
        }
    }
}

impl UniformSource for Replay<'_> {
    fn next_f32(&mut self) -> f32 {
        if self.next == self.values.len() {
            let fresh = self.fresh.next_f32();
            self.values.push(fresh);
        }
        self.next += 1;
        self.values[self.next - 1]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn small_steps_stay_in_the_unit_interval_and_near() {
        let (mut u, mut rng) = (PrimarySamples::new(), Pcg32::new(3, 0));
        let before: Vec<f32> = {
            let mut r = u.replay(&mut rng);
            (0..1000).map(|_| r.next_f32()).collect()
        };
        u.small_step(&mut rng);
        let mut r = u.replay(&mut rng);
        let after: Vec<f32> = (0..1000).map(|_| r.next_f32()).collect();
        for (a, b) in before.iter().zip(&after) {
            assert!((0.0..1.0).contains(b));
            let d = (a - b).abs().min(1.0 - (a - b).abs());
            assert!(d <= 1.0 / 64.0 + 1e-6 && d > 0.0, "{a} → {b}");
        }
        u.large_step();
        assert!(u.is_empty());
    }
}
