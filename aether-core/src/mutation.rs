//! Mutations: Metropolis proposals written once as sampling code, whose
//! transition density T(y | x) the language derives by running the same
//! code in density mode on the pair (x, y).
//!
//! A mutation reads the current path x and builds the proposal y from two
//! ends: an eye side grown forward from the camera and a light side grown
//! backward from the light, each by *copying* vertices of x or *sampling*
//! new ones with strategies (which may themselves be built from x, like a
//! perturbation about one of x's directions). Discrete decisions go
//! through [`Mutator::choose`].
//!
//! In sampling mode the [`Mutator`] draws uniforms. In density mode it is
//! given y as well and re-runs the code for every branch of its discrete
//! choices (an odometer, as Aether's `PdfContext`); along a branch each
//! sampling call returns y's vertex at that place and multiplies in its
//! density under the strategy, and each copy checks that y holds the very
//! vertex of x there (vertices keep identities across mutations). A branch
//! counts only if it copies exactly the vertices y shares with x: copied
//! vertices are Dirac in both directions and cancel in the acceptance
//! ratio, and a sampled vertex cannot coincide with a copied one. T(y | x)
//! is the sum over the branches, so a mutation that picks among
//! sub-mutations gets the mixture density for free.

use std::ops::Range;

use smallvec::SmallVec;

use crate::density::{Density, Measure, PathDensity};
use crate::rng::UniformSource;
use crate::sequence::{INLINE_VERTICES, fresh_id};
use crate::strategy::{DynStrategy, Prefix, Produced, StepKind};
use crate::vertex::Vertex;

/// A path as the state of a Markov chain: its vertices, camera first, each
/// with an identity that survives the mutations that copy it.
#[derive(Clone, Debug)]
pub struct ChainPath<V> {
    vertices: SmallVec<[V; INLINE_VERTICES]>,
    ids: SmallVec<[u64; INLINE_VERTICES]>,
}

impl<V> Default for ChainPath<V> {
    fn default() -> Self {
        ChainPath {
            vertices: SmallVec::new(),
            ids: SmallVec::new(),
        }
    }
}

impl<V: Vertex> ChainPath<V> {
    /// A path of new vertices (camera first).
    pub fn new(vertices: impl IntoIterator<Item = V>) -> Self {
        let vertices: SmallVec<[V; INLINE_VERTICES]> = vertices.into_iter().collect();
        let ids = vertices.iter().map(|_| fresh_id()).collect();
        ChainPath { vertices, ids }
    }

    /// The vertices, camera first.
    #[must_use]
    pub fn vertices(&self) -> &[V] {
        &self.vertices
    }

    /// Number of vertices.
    #[must_use]
    pub fn len(&self) -> usize {
        self.vertices.len()
    }

    /// True for the empty path.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.vertices.is_empty()
    }

    /// This path with vertex `i` replaced by the new vertex `v` (a new
    /// identity: it is not the vertex it replaces), or `None` if there is
    /// no vertex `i`.
    #[must_use]
    pub fn with_vertex(&self, i: usize, v: V) -> Option<Self> {
        let mut moved = self.clone();
        *moved.vertices.get_mut(i)? = v;
        moved.ids[i] = fresh_id();
        Some(moved)
    }

    /// True if the edge from vertex `i` to `i + 1` is an edge of `other`,
    /// both ends copied from it (so that it needs no new visibility test).
    #[must_use]
    pub fn edge_copied_from(&self, i: usize, other: &ChainPath<V>) -> bool {
        let (Some(a), Some(b)) = (self.ids.get(i), self.ids.get(i + 1)) else {
            return false;
        };
        other.ids.windows(2).any(|w| w[0] == *a && w[1] == *b)
    }

    /// True if vertex `i` of this path is vertex `j` of `other` (copied, not
    /// merely at the same place).
    #[must_use]
    pub fn shares(&self, i: usize, other: &ChainPath<V>, j: usize) -> bool {
        self.ids.get(i).is_some_and(|a| other.ids.get(j) == Some(a))
    }
}

/// A Metropolis proposal as sampling code over a [`Mutator`].
///
/// `propose` returns `None` where the code gives up (a ray that escapes, a
/// path the mutation does not apply to, a check that fails); in density mode
/// that ends the branch with density zero.
///
/// ```
/// use aether_core::{ChainPath, Mutation, Mutator, Pcg32, RandomSequence, propose, transition_density};
/// use aether_core::testing::{Bounce, CameraPoint, LookDown, TestScene, TestVertex};
///
/// /// Keeps the camera and its first hit, then bounces once more.
/// struct Rebounce<'s>(Bounce<'s>);
/// impl Mutation<TestVertex> for Rebounce<'_> {
///     fn propose(&self, x: &ChainPath<TestVertex>, m: &mut Mutator<'_, TestVertex>) -> Option<()> {
///         m.copy_eye(x, 0..2)?;
///         m.eye(&self.0)
///     }
/// }
///
/// let scene = TestScene::open_box();
/// let (camera, look, bounce) = (CameraPoint::default(), LookDown::new(&scene), Bounce::new(&scene));
/// let mut path = RandomSequence::new();
/// path.append(&camera).append(&look).append(&bounce).sample(&mut Pcg32::new(2, 0));
/// let x = ChainPath::new(path.vertices().iter().copied());
/// let mutation = Rebounce(bounce);
/// let (y, _) = propose(&mutation, &x, &mut Pcg32::new(3, 0)).expect("the box is closed below");
/// assert!(y.shares(1, &x, 1) && !y.shares(2, &x, 2));
/// assert!(transition_density(&mutation, &x, &y).value() > 0.0);
/// ```
pub trait Mutation<V: Vertex> {
    /// Builds the proposal from the current path `x` through `m`.
    fn propose(&self, x: &ChainPath<V>, m: &mut Mutator<'_, V>) -> Option<()>;
}

enum Mode<'m, V> {
    Sample(&'m mut dyn UniformSource),
    Density {
        target: &'m ChainPath<V>,
        source: &'m ChainPath<V>,
    },
}

/// What mutation code samples with: the sampling or the density context.
///
/// In sampling mode it holds the proposal's two sides. In density mode the
/// sides are prefixes and suffixes of y, so it keeps only their lengths.
pub struct Mutator<'m, V> {
    mode: Mode<'m, V>,
    /// Sampling mode: the eye side, and the light side in light-to-camera order.
    eye: ChainPath<V>,
    light: ChainPath<V>,
    eye_len: usize,
    light_len: usize,
    density: PathDensity,
    /// Density mode: the branch of each discrete choice, and its count.
    choices: SmallVec<[(usize, usize); 8]>,
    depth: usize,
    length: Option<usize>,
}

impl<V> std::fmt::Debug for Mutator<'_, V> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mode = match self.mode {
            Mode::Sample(_) => "sample",
            Mode::Density { .. } => "density",
        };
        f.debug_struct("Mutator")
            .field("mode", &mode)
            .field("eye", &self.eye_len)
            .field("light", &self.light_len)
            .finish_non_exhaustive()
    }
}

/// The index `u · Σ weights` falls in (only positive weights count).
fn pick(weights: &[f64], total: f64, u: f32) -> Option<usize> {
    let mut u = f64::from(u) * total;
    let last = weights.iter().rposition(|w| *w > 0.0)?;
    for (k, &w) in weights.iter().enumerate().take(last) {
        if w > 0.0 {
            if u < w {
                return Some(k);
            }
            u -= w;
        }
    }
    Some(last)
}

fn positive_total(weights: &[f64]) -> Option<f64> {
    let total: f64 = weights.iter().filter(|w| **w > 0.0).sum();
    (total > 0.0 && total.is_finite()).then_some(total)
}

impl<'m, V: Vertex> Mutator<'m, V> {
    fn new(mode: Mode<'m, V>) -> Self {
        Mutator {
            mode,
            eye: ChainPath::default(),
            light: ChainPath::default(),
            eye_len: 0,
            light_len: 0,
            density: PathDensity::ONE,
            choices: SmallVec::new(),
            depth: 0,
            length: None,
        }
    }

    /// Multiplies in the probability of alternative `k`; `None` if it has none.
    fn chosen(&mut self, weights: &[f64], total: f64, k: usize) -> Option<usize> {
        let w = *weights.get(k)?;
        if w.is_nan() || w <= 0.0 {
            return None;
        }
        self.density = self.density.times(Density::discrete(w / total));
        Some(k)
    }

    /// Picks one of `weights.len()` alternatives with probability
    /// proportional to its weight; `None` if all weights are zero.
    pub fn choose(&mut self, weights: &[f64]) -> Option<usize> {
        let total = positive_total(weights)?;
        let k = match &mut self.mode {
            Mode::Sample(rng) => pick(weights, total, rng.next_f32())?,
            Mode::Density { .. } => {
                if self.depth == self.choices.len() {
                    self.choices.push((0, weights.len()));
                }
                self.choices[self.depth].1 = weights.len();
                let k = self.choices[self.depth].0;
                self.depth += 1;
                k
            }
        };
        self.chosen(weights, total, k)
    }

    /// One of `n` alternatives, uniformly; `None` if `n` is zero.
    pub fn choose_uniform(&mut self, n: usize) -> Option<usize> {
        let weights: SmallVec<[f64; 16]> = (0..n).map(|_| 1.0).collect();
        self.choose(&weights)
    }

    /// Picks the proposal's number of vertices, with probability
    /// proportional to `weights[n]`: [`choose`](Self::choose) followed by
    /// [`expect_len`](Self::expect_len). Density mode reads the choice off
    /// y's length instead of trying every branch (the others would fail).
    pub fn choose_length(&mut self, weights: &[f64]) -> Option<usize> {
        let total = positive_total(weights)?;
        let n = match &mut self.mode {
            Mode::Sample(rng) => pick(weights, total, rng.next_f32())?,
            Mode::Density { target, .. } => target.len(),
        };
        self.chosen(weights, total, n)?;
        self.expect_len(n)?;
        Some(n)
    }

    /// Starts the eye side with x's first `e` vertices, `e` chosen with
    /// probability proportional to `weights[e]`: [`choose`](Self::choose)
    /// followed by [`copy_eye`](Self::copy_eye). Density mode reads `e` off
    /// y as the number of leading vertices it shares with x: a shorter copy
    /// would have to sample one of them, a longer one copy a vertex y does
    /// not have, and both branches fail.
    pub fn copy_eye_prefix(&mut self, x: &ChainPath<V>, weights: &[f64]) -> Option<usize> {
        if self.eye_len > 0 {
            return None;
        }
        let total = positive_total(weights)?;
        let e = match &mut self.mode {
            Mode::Sample(rng) => pick(weights, total, rng.next_f32())?,
            Mode::Density { target, .. } => target
                .ids
                .iter()
                .zip(&x.ids)
                .take_while(|(a, b)| a == b)
                .count(),
        };
        self.chosen(weights, total, e)?;
        self.copy(x, 0..e, false)?;
        Some(e)
    }

    /// Fails the branch unless `condition` holds (in density mode the
    /// condition reads y's vertices, which makes the check symmetric).
    pub fn require(&mut self, condition: bool) -> Option<()> {
        condition.then_some(())
    }

    /// Declares the number of vertices of the proposal: density mode prunes
    /// the branches that cannot produce y early, and sampling mode checks it
    /// when the proposal is done.
    pub fn expect_len(&mut self, n: usize) -> Option<()> {
        self.length = Some(n);
        match self.mode {
            Mode::Density { target, .. } => (target.len() == n).then_some(()),
            Mode::Sample(_) => Some(()),
        }
    }

    /// The eye side so far: the proposal's first vertices.
    #[must_use]
    pub fn eye_side(&self) -> &[V] {
        match self.mode {
            Mode::Sample(_) => &self.eye.vertices,
            Mode::Density { target, .. } => &target.vertices[..self.eye_len],
        }
    }

    /// The number of vertices on the light side so far.
    #[must_use]
    pub fn light_len(&self) -> usize {
        self.light_len
    }

    /// The `j`-th vertex of the light side, counted from the light (0 is
    /// the proposal's last vertex).
    ///
    /// # Panics
    /// If the light side has no `j`-th vertex.
    #[must_use]
    pub fn light_vertex(&self, j: usize) -> &V {
        assert!(
            j < self.light_len,
            "the light side has {} vertices",
            self.light_len
        );
        match self.mode {
            Mode::Sample(_) => &self.light.vertices[j],
            Mode::Density { target, .. } => &target.vertices[target.len() - 1 - j],
        }
    }

    /// Where the next vertex of the eye or the light side goes in y, if y
    /// has room for it (density mode only).
    fn target_slot(&self, target: &ChainPath<V>, light: bool) -> Option<usize> {
        if self.eye_len + self.light_len >= target.len() {
            return None;
        }
        Some(if light {
            target.len() - 1 - self.light_len
        } else {
            self.eye_len
        })
    }

    /// Adds a vertex to a side (kept only in sampling mode).
    fn push(&mut self, light: bool, v: Option<(V, u64)>) {
        let (side, len) = if light {
            (&mut self.light, &mut self.light_len)
        } else {
            (&mut self.eye, &mut self.eye_len)
        };
        *len += 1;
        if let Some((v, id)) = v {
            side.vertices.push(v);
            side.ids.push(id);
        }
    }

    fn copy(&mut self, x: &ChainPath<V>, range: Range<usize>, light: bool) -> Option<()> {
        if range.end > x.len() {
            return None;
        }
        for i in 0..range.len() {
            let k = if light {
                range.end - 1 - i
            } else {
                range.start + i
            };
            match self.mode {
                Mode::Density { target, .. } => {
                    let slot = self.target_slot(target, light)?;
                    if target.ids[slot] != x.ids[k] {
                        return None;
                    }
                    self.push(light, None);
                }
                Mode::Sample(_) => self.push(light, Some((x.vertices[k].clone(), x.ids[k]))),
            }
        }
        Some(())
    }

    /// Copies x's vertices in `range` to the end of the eye side.
    pub fn copy_eye(&mut self, x: &ChainPath<V>, range: Range<usize>) -> Option<()> {
        self.copy(x, range, false)
    }

    /// Copies x's vertices in `range` (path order) to the light side, so
    /// that they end the proposal in the same order.
    pub fn copy_light(&mut self, x: &ChainPath<V>, range: Range<usize>) -> Option<()> {
        self.copy(x, range, true)
    }

    fn sample(&mut self, strategy: &dyn DynStrategy<V>, light: bool) -> Option<()> {
        match &mut self.mode {
            Mode::Sample(rng) => {
                let side = if light { &self.light } else { &self.eye };
                let mut out = Produced::<V>::new();
                let sampled =
                    strategy.sample_step(Prefix::forward(&side.vertices), &mut **rng, &mut out);
                let (kind, density) = (sampled.kind, sampled.density);
                if kind != StepKind::Vertex || density.is_zero() {
                    return None;
                }
                self.density = self.density.times(density);
                let v = out.pop()?;
                self.push(light, Some((v, fresh_id())));
            }
            Mode::Density { target, source } => {
                let (target, source) = (*target, *source);
                let slot = self.target_slot(target, light)?;
                // A vertex y shares with x is a copy, never a sample.
                if source.ids.contains(&target.ids[slot]) {
                    return None;
                }
                let prefix = if light {
                    Prefix::reversed(&target.vertices[slot + 1..])
                } else {
                    Prefix::forward(&target.vertices[..slot])
                };
                let d = strategy.density_of(prefix, &target.vertices[slot]);
                if d.is_zero() {
                    return None;
                }
                self.density = self.density.times(d);
                self.push(light, None);
            }
        }
        Some(())
    }

    /// Samples the next eye-side vertex with `strategy`, conditioned on the
    /// eye side so far.
    pub fn eye(&mut self, strategy: &dyn DynStrategy<V>) -> Option<()> {
        self.sample(strategy, false)
    }

    /// Samples the next light-side vertex with `strategy`, conditioned on
    /// the light side so far (nearest the new vertex first, as a light
    /// subpath's strategy sees it).
    pub fn light(&mut self, strategy: &dyn DynStrategy<V>) -> Option<()> {
        self.sample(strategy, true)
    }

    /// Resets the sides for the next branch, and moves the odometer on:
    /// false once every branch has run.
    fn next_branch(&mut self) -> bool {
        self.eye_len = 0;
        self.light_len = 0;
        self.density = PathDensity::ONE;
        self.length = None;
        // Choices past the last one this branch reached belong to no branch.
        self.choices.truncate(self.depth);
        self.depth = 0;
        while let Some((k, n)) = self.choices.last_mut() {
            *k += 1;
            if *k < *n {
                return true;
            }
            self.choices.pop();
        }
        false
    }

    /// The proposal: the eye side followed by the light side reversed.
    fn joined(&self) -> ChainPath<V> {
        let mut y = self.eye.clone();
        y.vertices.extend(self.light.vertices.iter().rev().cloned());
        y.ids.extend(self.light.ids.iter().rev().copied());
        y
    }
}

/// Runs `mutation` on `x` in sampling mode: the proposed path and the
/// density of the branch that produced it (one term of T(y | x)), or `None`
/// if the mutation gave up.
pub fn propose<V: Vertex>(
    mutation: &(impl Mutation<V> + ?Sized),
    x: &ChainPath<V>,
    rng: &mut dyn UniformSource,
) -> Option<(ChainPath<V>, PathDensity)> {
    let mut m = Mutator::new(Mode::Sample(rng));
    mutation.propose(x, &mut m)?;
    let y = m.joined();
    if m.length.is_some_and(|n| n != y.len()) || y.is_empty() {
        return None;
    }
    Some((y, m.density))
}

/// T(y | x): the density with which `mutation` proposes `y` from `x`,
/// summed over the branches of its discrete choices, with the vertices y
/// copies from x as Dirac factors of mass one (so that T(y | x) and
/// T(x | y) share them). Zero if no branch produces `y`.
pub fn transition_density<V: Vertex>(
    mutation: &(impl Mutation<V> + ?Sized),
    x: &ChainPath<V>,
    y: &ChainPath<V>,
) -> PathDensity {
    let mut total = PathDensity::ONE.times(Density::zero(Measure::Discrete));
    let mut m = Mutator::new(Mode::Density {
        target: y,
        source: x,
    });
    loop {
        let done = mutation.propose(x, &mut m);
        let complete = m.eye_len + m.light_len == y.len();
        if done.is_some() && complete && m.length.is_none_or(|n| n == y.len()) {
            total = total.plus(m.density);
        }
        if !m.next_branch() {
            return total;
        }
    }
}

/// The Metropolis–Hastings acceptance probability of moving from x to y:
/// min(1, F(y) T(x | y) / (F(x) T(y | x))) for the target F (1 if F(x) is
/// zero, 0 if the move cannot be reversed).
///
/// `forward` is T(y | x) and `backward` T(x | y), as
/// [`transition_density`] gives them.
#[must_use]
pub fn acceptance(f_x: f64, f_y: f64, forward: PathDensity, backward: PathDensity) -> f64 {
    if f_x.is_nan() || f_x <= 0.0 {
        return 1.0;
    }
    if forward.is_zero() {
        return 0.0;
    }
    // The values, not Dirac orders: F(y) T(x | y) and F(x) T(y | x) carry
    // the same Dirac factors (those of copied vertices, y's new ones and
    // x's replaced ones), F per unit Dirac mass and T in masses.
    let a = f_y * backward.value() / (f_x * forward.value());
    if a.is_nan() { 0.0 } else { a.clamp(0.0, 1.0) }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Pcg32;
    use crate::sequence::RandomSequence;
    use crate::testing::{Bounce, CameraPoint, LightSample, LookDown, TestScene, TestVertex};

    /// On paths that end on the light: keeps the camera and maybe its first
    /// hit (a choice), resamples the vertices up to the light from the eye
    /// and the light vertex by area; or, on the other branch, keeps all but
    /// the light vertex and resamples that from the light side.
    struct Resample<'s> {
        look: LookDown<'s>,
        bounce: Bounce<'s>,
        light: LightSample<'s>,
    }

    impl Mutation<TestVertex> for Resample<'_> {
        fn propose(
            &self,
            x: &ChainPath<TestVertex>,
            m: &mut Mutator<'_, TestVertex>,
        ) -> Option<()> {
            let n = x.len();
            m.expect_len(n)?;
            if m.choose(&[1.0, 3.0])? == 0 {
                let keep = 1 + m.choose_uniform(2)?;
                m.copy_eye(x, 0..keep)?;
                for i in keep..n - 1 {
                    m.eye(if i == 1 { &self.look } else { &self.bounce })?;
                }
            } else {
                m.copy_eye(x, 0..n - 1)?;
            }
            m.light(&self.light)
        }
    }

    fn start(scene: &TestScene, seed: u64) -> ChainPath<TestVertex> {
        let (camera, look, bounce) = (
            CameraPoint::default(),
            LookDown::new(scene),
            Bounce::new(scene),
        );
        let light = LightSample::new(scene);
        let mut path = RandomSequence::new();
        path.append(&camera)
            .append(&look)
            .append(&bounce)
            .append(&light);
        path.sample(&mut Pcg32::new(seed, 0));
        ChainPath::new(path.vertices().iter().copied())
    }

    #[test]
    fn density_mode_reproduces_the_sampled_branch_and_reverses() {
        let scene = TestScene::open_box();
        let mutation = Resample {
            look: LookDown::new(&scene),
            bounce: Bounce::new(&scene),
            light: LightSample::new(&scene),
        };
        let mut checked = 0;
        for seed in 0..200 {
            let x = start(&scene, seed);
            if x.len() != 4 {
                continue;
            }
            let Some((y, sampled)) = propose(&mutation, &x, &mut Pcg32::new(seed, 1)) else {
                continue;
            };
            // Only one branch copies exactly the vertices y shares with x.
            let forward = transition_density(&mutation, &x, &y);
            let rel = (forward.value() / sampled.value() - 1.0).abs();
            // Geometry is single precision: a density recomputed from the vertex
            // agrees with the sampled one to about 1e-6.
            assert!(
                rel < 1e-5,
                "seed {seed}: T(y|x) {forward} vs sampled {sampled}"
            );
            // The mutation's own code can undo the move.
            let backward = transition_density(&mutation, &y, &x);
            assert!(backward.value() > 0.0, "seed {seed}: no way back");
            // Detailed balance with a made-up target f = |x₁ − x₂|.
            let f = |p: &ChainPath<TestVertex>| {
                f64::from((p.vertices()[1].position - p.vertices()[2].position).length())
            };
            let (fx, fy) = (f(&x), f(&y));
            let flow = fx * forward.value() * acceptance(fx, fy, forward, backward);
            let back = fy * backward.value() * acceptance(fy, fx, backward, forward);
            assert!(
                (flow / back - 1.0).abs() < 1e-6,
                "seed {seed}: {flow} vs {back}"
            );
            checked += 1;
        }
        assert!(checked > 50, "only {checked} proposals checked");
    }

    #[test]
    fn a_vertex_sampled_anew_never_counts_as_copied() {
        let scene = TestScene::open_box();
        let mutation = Resample {
            look: LookDown::new(&scene),
            bounce: Bounce::new(&scene),
            light: LightSample::new(&scene),
        };
        let x = (0..50)
            .map(|s| start(&scene, s))
            .find(|x| x.len() == 4)
            .unwrap();
        // y = x itself: every branch would have to sample a vertex x has.
        assert!(transition_density(&mutation, &x, &x).is_zero());
    }
}
