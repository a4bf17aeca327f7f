//! Discrete events as probabilities: a choice identified by lookup, a
//! mixture summed over its branches, and Russian roulette.

use std::borrow::Borrow;

use crate::density::{Density, Measure};
use crate::distribution::{Distribution, Sample, Step, Uniforms};
use crate::primitives::DiscreteDistribution;

/// Runs `f` on a copy of `u` whose first uniform is `first`, kept on the
/// stack: every discrete choice and roulette step of a sample remaps one.
#[inline]
fn sample_with_first<T>(u: &[f32], first: f32, f: impl FnOnce(&[f32]) -> T) -> T {
    let mut buffer = [0.0f32; 8];
    if u.len() > buffer.len() {
        return f(&with_first(u, first));
    }
    let n = u.len().max(1);
    // Element by element up to the buffer's length, not as one slice copy,
    // which became a call to memcpy of a few bytes at every choice.
    for (i, x) in buffer.iter_mut().enumerate().skip(1) {
        if let Some(&v) = u.get(i) {
            *x = v;
        }
    }
    buffer[0] = first;
    f(&buffer[..n])
}

/// Replaces `u[0]` by `first` in a copy of `u`.
fn with_first(u: &[f32], first: f32) -> Uniforms {
    let mut v = Uniforms::from_slice(u);
    if v.is_empty() {
        v.push(first);
    } else {
        v[0] = first;
    }
    v
}

/// A discrete choice among branches whose values tell which branch made
/// them (a light among lights, a triangle among triangles): the density of a
/// value looks its branch's probability up instead of enumerating.
///
/// The first uniform selects the branch and is remapped for reuse by it.
///
/// Density: P(branch) · p_branch(value).
pub struct Select<C, F, W> {
    choice: C,
    dims: usize,
    branch: F,
    which: W,
}

impl<C, F, W> std::fmt::Debug for Select<C, F, W> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Select")
            .field("dims", &self.dims)
            .finish_non_exhaustive()
    }
}

impl<C, F, W, D> Select<C, F, W>
where
    C: Borrow<DiscreteDistribution>,
    F: Fn(usize) -> D,
    D: Distribution,
    W: Fn(&D::Value) -> Option<usize>,
{
    /// Chooses branch `i` with `choice`'s probability, then samples
    /// `branch(i)`, which reads at most `dims` uniforms. `which` names the
    /// branch a value came from (`None`: no branch could have produced it).
    pub fn new(choice: C, dims: usize, branch: F, which: W) -> Self {
        Select {
            choice,
            dims: dims.max(1),
            branch,
            which,
        }
    }
}

impl<C, F, W, D> Distribution for Select<C, F, W>
where
    C: Borrow<DiscreteDistribution>,
    F: Fn(usize) -> D,
    D: Distribution,
    W: Fn(&D::Value) -> Option<usize>,
{
    type Value = D::Value;
    fn dims(&self) -> usize {
        self.dims
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<D::Value>> {
        let choice = self.choice.borrow();
        let (i, rest) = choice.select(u[0]);
        let branch = (self.branch)(i);
        debug_assert!(
            branch.dims() <= self.dims,
            "branch {i} reads more uniforms than declared"
        );
        let s = sample_with_first(u, rest, |u| branch.sample(u))?;
        Some(Sample::new(
            s.value,
            Density::discrete(choice.probability(i)) * s.density,
        ))
    }
    fn density(&self, v: &D::Value) -> Density {
        match (self.which)(v) {
            Some(i) => {
                let p = self.choice.borrow().probability(i);
                if p == 0.0 {
                    return Density::zero(Measure::Discrete);
                }
                Density::discrete(p) * (self.branch)(i).density(v)
            }
            None => Density::zero(Measure::Discrete),
        }
    }
    fn invert(&self, v: &D::Value) -> Option<Uniforms> {
        let i = (self.which)(v)?;
        let choice = self.choice.borrow();
        if choice.probability(i) == 0.0 {
            return None;
        }
        let mut u = (self.branch)(i).invert(v)?;
        let rest = u.first().copied().unwrap_or(0.5);
        let first = choice.unselect(i, rest);
        if u.is_empty() {
            u.push(first);
        } else {
            u[0] = first;
        }
        Some(u)
    }
}

/// A mixture of branches that can produce the same value (the lobes of a
/// BSDF): the density of a value sums over every branch.
///
/// Density: Σᵢ P(i) · pᵢ(value).
pub struct Mixture<C, F> {
    choice: C,
    dims: usize,
    branch: F,
}

impl<C, F> std::fmt::Debug for Mixture<C, F> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Mixture")
            .field("dims", &self.dims)
            .finish_non_exhaustive()
    }
}

impl<C, F, D> Mixture<C, F>
where
    C: Borrow<DiscreteDistribution>,
    F: Fn(usize) -> D,
    D: Distribution,
{
    /// Chooses branch `i` with `choice`'s probability, then samples
    /// `branch(i)`, which reads at most `dims` uniforms.
    pub fn new(choice: C, dims: usize, branch: F) -> Self {
        Mixture {
            choice,
            dims: dims.max(1),
            branch,
        }
    }
}

impl<C, F, D> Distribution for Mixture<C, F>
where
    C: Borrow<DiscreteDistribution>,
    F: Fn(usize) -> D,
    D: Distribution,
{
    type Value = D::Value;
    fn dims(&self) -> usize {
        self.dims
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<D::Value>> {
        let choice = self.choice.borrow();
        let (i, rest) = choice.select(u[0]);
        let s = sample_with_first(u, rest, |u| (self.branch)(i).sample(u))?;
        // The recorded density is the mixture's, not the chosen branch's:
        // MIS and estimators need the density of the value. With one
        // branch the two agree (the harness holds every branch to it), and
        // evaluating the branch again cost a diffuse bounce a frame change
        // and a density.
        if choice.len() == 1 {
            let density = Density::discrete(choice.probability(0)) * s.density;
            return Some(Sample::new(s.value, density));
        }
        let density = self.density(&s.value);
        Some(Sample::new(s.value, density))
    }
    #[inline]
    fn density(&self, v: &D::Value) -> Density {
        let choice = self.choice.borrow();
        // One branch (a diffuse or a rough metal's single lobe) is a sum of
        // one term: the general loop and its sum cost 64 of the 865
        // instructions of a density of BSDF sampling (callgrind).
        if choice.len() == 1 {
            let d = Density::discrete(choice.probability(0)) * (self.branch)(0).density(v);
            // What the sum below gives: nothing, in counting measure.
            return if d.is_zero() {
                Density::zero(Measure::Discrete)
            } else {
                d
            };
        }
        (0..choice.len())
            .filter(|&i| choice.probability(i) > 0.0)
            .map(|i| Density::discrete(choice.probability(i)) * (self.branch)(i).density(v))
            .fold(Density::zero(Measure::Discrete), |a, b| a + b)
    }
    fn invert(&self, v: &D::Value) -> Option<Uniforms> {
        // The pre-image in the branch that contributes most: a branch whose
        // density is merely positive may be so unlikely there that its
        // inverse does not survive rounding.
        let choice = self.choice.borrow();
        let best = (0..choice.len())
            .filter(|&i| choice.probability(i) > 0.0)
            .map(|i| {
                let d = Density::discrete(choice.probability(i)) * (self.branch)(i).density(v);
                (i, d)
            })
            .filter(|(_, d)| !d.is_zero())
            .max_by(|(_, a), (_, b)| {
                a.dirac_order()
                    .cmp(&b.dirac_order())
                    .then(a.value().total_cmp(&b.value()))
            })?;
        let i = best.0;
        let u = (self.branch)(i).invert(v)?;
        Some(with_first(
            &u,
            choice.unselect(i, u.first().copied().unwrap_or(0.5)),
        ))
    }
    fn has_overlapping_branches(&self) -> bool {
        true
    }
}

/// Russian roulette: continue with probability `q` into `inner`, otherwise
/// end the path. Both outcomes carry their probability: a continued step's
/// density includes q, and [`Step::Terminated`] has mass 1 − q.
///
/// The first uniform decides and is remapped for reuse by `inner`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RussianRoulette<D> {
    q: f64,
    inner: D,
}

impl<D> RussianRoulette<D> {
    /// Continues with probability `q` ∈ [0, 1].
    #[inline(always)]
    pub fn new(q: f64, inner: D) -> Self {
        RussianRoulette {
            q: q.clamp(0.0, 1.0),
            inner,
        }
    }
}

impl<T, D: Distribution<Value = Step<T>>> Distribution for RussianRoulette<D> {
    type Value = Step<T>;
    fn dims(&self) -> usize {
        self.inner.dims().max(1)
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<Step<T>>> {
        if f64::from(u[0]) >= self.q {
            return Some(Sample::new(
                Step::Terminated,
                Density::discrete(1.0 - self.q),
            ));
        }
        let rest = crate::distribution::below_one((f64::from(u[0]) / self.q) as f32);
        let s = sample_with_first(u, rest, |u| self.inner.sample(u))?;
        let density = match s.value {
            Step::Terminated => self.density(&s.value),
            _ => s.density.scale(self.q),
        };
        Some(Sample::new(s.value, density))
    }
    fn density(&self, v: &Step<T>) -> Density {
        let continued = self.inner.density(v).scale(self.q);
        match v {
            Step::Terminated => Density::discrete(1.0 - self.q) + continued,
            _ => continued,
        }
    }
    fn invert(&self, v: &Step<T>) -> Option<Uniforms> {
        if matches!(v, Step::Terminated) && self.q < 1.0 {
            return Some(with_first(
                &[],
                crate::distribution::below_one((self.q + (1.0 - self.q) / 2.0) as f32),
            ));
        }
        if self.q == 0.0 {
            return None;
        }
        let u = self.inner.invert(v)?;
        let first = crate::distribution::below_one(
            (f64::from(u.first().copied().unwrap_or(0.5)) * self.q) as f32,
        );
        Some(with_first(&u, first))
    }
    fn has_overlapping_branches(&self) -> bool {
        self.inner.has_overlapping_branches()
    }
}
