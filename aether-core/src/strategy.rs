//! Strategies: sampling code written once, run to sample and to evaluate densities.

use crate::density::{Density, Measure};
use crate::distribution::{Coords, Distribution, Embed, Step, Uniforms};
use crate::recycle::Recycle;
use crate::rng::UniformSource;
use crate::vertex::{Geometry, Vertex};

/// The vertices a strategy conditions on, most recent first.
///
/// For a forward strategy these are the path's earlier vertices; for a
/// reversed one (a light-subpath strategy inside a camera-to-light path)
/// they are the later vertices, nearest first. Strategies read them through
/// this view and never see the direction.
#[derive(Debug)]
pub struct Prefix<'a, V> {
    vertices: &'a [V],
    reversed: bool,
    /// The number of conditioning vertices, of which `vertices` are the
    /// nearest (all of them, but for a strategy of short memory evaluated
    /// where the rest are not at hand: see [`Prefix::nearest`]).
    len: usize,
}

impl<V> Clone for Prefix<'_, V> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<V> Copy for Prefix<'_, V> {}

impl<'a, V> Prefix<'a, V> {
    /// Vertices in path order: the last one is the most recent.
    #[must_use]
    pub fn forward(vertices: &'a [V]) -> Self {
        Prefix {
            vertices,
            reversed: false,
            len: vertices.len(),
        }
    }

    /// Vertices in reverse path order: the first one is the most recent.
    #[must_use]
    pub fn reversed(vertices: &'a [V]) -> Self {
        Prefix {
            vertices,
            reversed: true,
            len: vertices.len(),
        }
    }

    /// The `nearest` vertices of a prefix of `len` (nearest first if
    /// `reversed`, in path order otherwise): all a strategy whose memory
    /// is `nearest.len()` reads of the prefix, besides its length.
    pub(crate) fn nearest(nearest: &'a [V], reversed: bool, len: usize) -> Self {
        debug_assert!(nearest.len() <= len);
        Prefix {
            vertices: nearest,
            reversed,
            len,
        }
    }

    /// Number of conditioning vertices (the depth of the step).
    #[must_use]
    pub fn len(&self) -> usize {
        self.len
    }

    /// True at the start of a path.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The `k`-th most recent vertex (0 = the last one).
    #[must_use]
    pub fn back(&self, k: usize) -> Option<&'a V> {
        if k >= self.vertices.len() {
            return None;
        }
        if self.reversed {
            self.vertices.get(k)
        } else {
            self.vertices.get(self.vertices.len() - 1 - k)
        }
    }

    /// The most recent vertex.
    #[must_use]
    pub fn last(&self) -> Option<&'a V> {
        self.back(0)
    }
}

/// A sampling strategy for one vertex, written once as a composition of
/// the language's blocks.
///
/// [`distribution`](Self::distribution) builds, from the conditioning
/// vertices only, the distribution of the next vertex. The framework runs it
/// forward to sample, and backward to evaluate the density of any vertex
/// (including vertices other strategies produced), without casting rays. A
/// strategy therefore never writes a pdf.
///
/// # Example
/// ```
/// use aether_core::{Distribution, Frame, InFrame, Intersect, Prefix, Step, Strategy};
/// use aether_core::primitives::CosineHemisphere;
/// use aether_core::testing::{TestScene, TestVertex};
///
/// /// Diffuse bounce: a cosine-distributed direction about the normal, then a ray.
/// struct Bounce<'s>(&'s TestScene);
///
/// impl<'s> Strategy<TestVertex> for Bounce<'s> {
///     fn distribution<'a>(&'a self, prefix: Prefix<'a, TestVertex>) -> impl Distribution<Value = Step<TestVertex>> + 'a {
///         let x = prefix.last().expect("a bounce needs a vertex to leave from");
///         Intersect::new(x, InFrame::new(Frame::from_normal(x.normal()), CosineHemisphere), self.0)
///     }
///     fn memory(&self) -> usize { 1 }
/// }
/// ```
pub trait Strategy<V: Vertex> {
    /// The distribution of the next vertex after `prefix`.
    fn distribution<'a>(&'a self, prefix: Prefix<'a, V>)
    -> impl Distribution<Value = Step<V>> + 'a;

    /// How many of the most recent conditioning vertices the distribution
    /// reads (besides the prefix length). Densities of strategies that read
    /// at most two are cached and shared between MIS candidates; the
    /// default, "all of them", is always correct but never cached.
    fn memory(&self) -> usize {
        usize::MAX
    }

    /// The prefix lengths a density depends on, as classes: densities for
    /// prefix lengths in the same class must be equal. The default, each
    /// length its own class, is always correct; a strategy whose density
    /// ignores the length (or, like Russian roulette from a fixed depth on,
    /// only compares it with a threshold) says so here, so that MIS reuses
    /// its densities across candidates of different lengths.
    fn depth_class(&self, prefix_len: usize) -> usize {
        prefix_len
    }

    /// What tells this strategy apart from other values of its type that
    /// may take its place in memory, such as the pixel of a per-pixel
    /// camera strategy made for each pixel in turn. Cached densities are
    /// keyed by the strategy's address, type and this value.
    fn instance(&self) -> u64 {
        0
    }
}

/// A strategy that samples two vertices at once (a portal segment). The
/// density is a joint density in the product of the two vertices' measures.
pub trait PairStrategy<V: Vertex> {
    /// The joint distribution of the next two vertices after `prefix`, in
    /// path order.
    fn distribution<'a>(
        &'a self,
        prefix: Prefix<'a, V>,
    ) -> impl Distribution<Value = Step<(V, V)>> + 'a;

    /// As [`Strategy::memory`].
    fn memory(&self) -> usize {
        usize::MAX
    }

    /// The prefix lengths a density depends on, as classes: densities for
    /// prefix lengths in the same class must be equal. The default, each
    /// length its own class, is always correct; a strategy whose density
    /// ignores the length (or, like Russian roulette from a fixed depth on,
    /// only compares it with a threshold) says so here, so that MIS reuses
    /// its densities across candidates of different lengths.
    fn depth_class(&self, prefix_len: usize) -> usize {
        prefix_len
    }

    /// What tells this strategy apart from other values of its type that
    /// may take its place in memory, such as the pixel of a per-pixel
    /// camera strategy made for each pixel in turn. Cached densities are
    /// keyed by the strategy's address, type and this value.
    fn instance(&self) -> u64 {
        0
    }
}

/// What a step of a sequence produced.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StepKind {
    /// One or more vertices.
    Vertex,
    /// Russian roulette ended the path.
    Terminated,
    /// The ray escaped.
    Missed,
    /// The map was undefined at the uniforms drawn (total internal
    /// reflection, a microfacet facing away).
    Void,
}

/// What one step of a strategy produced, and what recording its density
/// needs from the strategy: its memory and the depth class of the prefix
/// it followed, read by the strategy's own code while it sampled. (Asked
/// through the strategy's table afterwards, these two calls went to a
/// different strategy at each step of a path and mispredicted almost
/// every time.)
#[derive(Clone, Copy, Debug)]
pub struct Sampled {
    /// What the step produced.
    pub kind: StepKind,
    /// Its density (of the step's vertices if it produced them).
    pub density: Density,
    /// As [`Strategy::memory`].
    pub memory: usize,
    /// As [`Strategy::depth_class`] for the prefix's length.
    pub class: usize,
}

/// The vertices one step produced, in sampling order: one, or two for a
/// pair strategy. Two plain slots, not an inline list: a list asks where
/// its items live (inline or on the heap) at every push and pop (path
/// tracing ran 1.2 % fewer instructions without those questions).
#[derive(Debug)]
pub struct Produced<V> {
    first: Option<V>,
    second: Option<V>,
}

impl<V> Default for Produced<V> {
    fn default() -> Self {
        Produced {
            first: None,
            second: None,
        }
    }
}

impl<V> Produced<V> {
    /// No vertices yet.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds the next vertex. A step produces at most two: a third push
    /// replaces the second (debug builds panic).
    #[inline(always)]
    pub fn push(&mut self, v: V) {
        debug_assert!(
            self.second.is_none(),
            "a step produces at most two vertices"
        );
        match self.first {
            None => self.first = Some(v),
            Some(_) => self.second = Some(v),
        }
    }

    /// How many vertices there are.
    #[must_use]
    pub fn len(&self) -> usize {
        usize::from(self.first.is_some()) + usize::from(self.second.is_some())
    }

    /// True if there are none.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.first.is_none()
    }

    /// Takes the last vertex added.
    #[inline(always)]
    pub fn pop(&mut self) -> Option<V> {
        self.second.take().or_else(|| self.first.take())
    }

    /// Takes the vertices, in the order they were added.
    pub fn drain(&mut self) -> impl Iterator<Item = V> {
        self.first.take().into_iter().chain(self.second.take())
    }
}

/// The type-erased form of a [`Strategy`] that sequences store; implemented
/// for every strategy, not meant to be implemented by hand.
pub trait DynStrategy<V> {
    /// As [`Strategy::memory`].
    fn memory(&self) -> usize;
    /// As [`Strategy::depth_class`].
    fn depth_class(&self, prefix_len: usize) -> usize;
    /// As [`Strategy::instance`].
    fn instance(&self) -> u64;
    /// The strategy's type name, for reports and cache keys.
    fn name(&self) -> &'static str;
    /// Samples one step, pushing its vertex to `out`; what it produced,
    /// with the strategy's memory and depth class ([`Sampled`]).
    fn sample_step(
        &self,
        prefix: Prefix<'_, V>,
        rng: &mut dyn UniformSource,
        out: &mut Produced<V>,
    ) -> Sampled;
    /// The density of `target`.
    fn density_of(&self, prefix: Prefix<'_, V>, target: &V) -> Density;
    /// As [`sample_step`](Self::sample_step), and with it
    /// [`density_of`](Self::density_of) `other` after the same prefix, from
    /// one distribution: a vertex that another strategy produced there
    /// (direct light sampling's, say), whose MIS weight needs this
    /// strategy's density for it. The same numbers as the two calls, with
    /// the distribution built once.
    fn sample_step_measuring(
        &self,
        prefix: Prefix<'_, V>,
        rng: &mut dyn UniformSource,
        out: &mut Produced<V>,
        other: &V,
    ) -> (Sampled, Density);
}

/// The type-erased form of a [`PairStrategy`]; implemented for every pair
/// strategy, not meant to be implemented by hand.
pub trait DynPairStrategy<V> {
    /// As [`PairStrategy::memory`].
    fn memory(&self) -> usize;
    /// As [`PairStrategy::depth_class`].
    fn depth_class(&self, prefix_len: usize) -> usize;
    /// As [`PairStrategy::instance`].
    fn instance(&self) -> u64;
    /// The strategy's type name, for reports and cache keys.
    fn name(&self) -> &'static str;
    /// Samples one step, pushing its two vertices to `out` in sampling
    /// order; what it produced, with the strategy's memory and depth class
    /// ([`Sampled`]).
    fn sample_step(
        &self,
        prefix: Prefix<'_, V>,
        rng: &mut dyn UniformSource,
        out: &mut Produced<V>,
    ) -> Sampled;
    /// The joint density of `first` and `second` (in sampling order).
    fn density_of(&self, prefix: Prefix<'_, V>, first: &V, second: &V) -> Density;
}

fn draw(dims: usize, rng: &mut dyn UniformSource) -> Uniforms {
    (0..dims).map(|_| rng.next_f32()).collect()
}

/// Samples `d` once, handing its vertices to `push`: what it produced, with
/// the memory and depth class of the strategy it belongs to.
fn run<T, D: Distribution<Value = Step<T>>>(
    d: &D,
    rng: &mut dyn UniformSource,
    push: impl FnOnce(T),
    (memory, class): (usize, usize),
) -> Sampled {
    // Up to eight uniforms are drawn into the stack, more into a list.
    let dims = d.dims();
    let mut buffer = [0.0f32; 8];
    let list;
    let u: &[f32] = if dims <= buffer.len() {
        rng.fill(&mut buffer[..dims]);
        &buffer[..dims]
    } else {
        list = draw(dims, rng);
        &list
    };
    let (kind, density) = match d.sample(u) {
        Some(s) => match s.value {
            Step::Vertex(v) => {
                push(v);
                (StepKind::Vertex, s.density)
            }
            Step::Terminated => (StepKind::Terminated, s.density),
            Step::Missed => (StepKind::Missed, s.density),
        },
        None => (StepKind::Void, Density::zero(Measure::Discrete)),
    };
    Sampled {
        kind,
        density,
        memory,
        class,
    }
}

impl<V: Vertex, S: Strategy<V>> DynStrategy<V> for S {
    fn memory(&self) -> usize {
        Strategy::memory(self)
    }
    fn depth_class(&self, prefix_len: usize) -> usize {
        Strategy::depth_class(self, prefix_len)
    }
    fn instance(&self) -> u64 {
        Strategy::instance(self)
    }
    fn name(&self) -> &'static str {
        std::any::type_name::<S>()
    }
    fn sample_step(
        &self,
        prefix: Prefix<'_, V>,
        rng: &mut dyn UniformSource,
        out: &mut Produced<V>,
    ) -> Sampled {
        step(self, prefix, rng, out, None).0
    }
    fn density_of(&self, prefix: Prefix<'_, V>, target: &V) -> Density {
        self.distribution(prefix)
            .density(&Step::Vertex(target.clone()))
    }
    fn sample_step_measuring(
        &self,
        prefix: Prefix<'_, V>,
        rng: &mut dyn UniformSource,
        out: &mut Produced<V>,
        other: &V,
    ) -> (Sampled, Density) {
        step(self, prefix, rng, out, Some(other))
    }
}

/// One step of `strategy` (with its memory and depth class, see
/// [`Sampled`]), and the density of `other` from the same distribution if
/// asked. One body for both entry points, kept out of
/// line: with a copy in each, the compiler stopped inlining the
/// distribution's sampling into either, which cost more than the second
/// distribution saved.
#[inline(never)]
fn step<V: Vertex, S: Strategy<V> + ?Sized>(
    strategy: &S,
    prefix: Prefix<'_, V>,
    rng: &mut dyn UniformSource,
    out: &mut Produced<V>,
    other: Option<&V>,
) -> (Sampled, Density) {
    let d = strategy.distribution(prefix);
    let other = other.map_or(Density::zero(Measure::Area), |v| {
        d.density(&Step::Vertex(v.clone()))
    });
    let traits = (strategy.memory(), strategy.depth_class(prefix.len()));
    (run(&d, rng, |v| out.push(v), traits), other)
}

impl<V: Vertex, S: PairStrategy<V>> DynPairStrategy<V> for S {
    fn memory(&self) -> usize {
        PairStrategy::memory(self)
    }
    fn depth_class(&self, prefix_len: usize) -> usize {
        PairStrategy::depth_class(self, prefix_len)
    }
    fn instance(&self) -> u64 {
        PairStrategy::instance(self)
    }
    fn name(&self) -> &'static str {
        std::any::type_name::<S>()
    }
    fn sample_step(
        &self,
        prefix: Prefix<'_, V>,
        rng: &mut dyn UniformSource,
        out: &mut Produced<V>,
    ) -> Sampled {
        let traits = (
            PairStrategy::memory(self),
            PairStrategy::depth_class(self, prefix.len()),
        );
        let push = |(a, b)| {
            out.push(a);
            out.push(b);
        };
        run(&self.distribution(prefix), rng, push, traits)
    }
    fn density_of(&self, prefix: Prefix<'_, V>, first: &V, second: &V) -> Density {
        self.distribution(prefix)
            .density(&Step::Vertex((first.clone(), second.clone())))
    }
}

/// A stored strategy: one that samples a vertex or one that samples two.
pub enum StrategyRef<'s, V> {
    /// A single-vertex strategy.
    One(&'s dyn DynStrategy<V>),
    /// A two-vertex strategy.
    Two(&'s dyn DynPairStrategy<V>),
}

impl<V> Clone for StrategyRef<'_, V> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<V> Copy for StrategyRef<'_, V> {}

impl<V: Recycle> Recycle for StrategyRef<'_, V> {
    type Static = StrategyRef<'static, V::Static>;
}

impl<V> std::fmt::Debug for StrategyRef<'_, V> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl<'s, V> From<&'s dyn DynStrategy<V>> for StrategyRef<'s, V> {
    fn from(s: &'s dyn DynStrategy<V>) -> Self {
        StrategyRef::One(s)
    }
}

impl<'s, V> From<&'s dyn DynPairStrategy<V>> for StrategyRef<'s, V> {
    fn from(s: &'s dyn DynPairStrategy<V>) -> Self {
        StrategyRef::Two(s)
    }
}

impl<V> StrategyRef<'_, V> {
    /// Vertices per step.
    #[must_use]
    pub fn arity(&self) -> usize {
        match self {
            StrategyRef::One(_) => 1,
            StrategyRef::Two(_) => 2,
        }
    }

    /// As [`Strategy::memory`].
    #[must_use]
    pub fn memory(&self) -> usize {
        match self {
            StrategyRef::One(s) => s.memory(),
            StrategyRef::Two(s) => s.memory(),
        }
    }

    /// As [`Strategy::depth_class`].
    #[must_use]
    pub fn depth_class(&self, prefix_len: usize) -> usize {
        match self {
            StrategyRef::One(s) => s.depth_class(prefix_len),
            StrategyRef::Two(s) => s.depth_class(prefix_len),
        }
    }

    /// The strategy's type name.
    #[must_use]
    pub fn name(&self) -> &'static str {
        match self {
            StrategyRef::One(s) => s.name(),
            StrategyRef::Two(s) => s.name(),
        }
    }

    /// As [`Strategy::instance`].
    #[must_use]
    pub fn instance(&self) -> u64 {
        match self {
            StrategyRef::One(s) => s.instance(),
            StrategyRef::Two(s) => s.instance(),
        }
    }

    /// True if both are the same strategy object (a copy of its vtable in
    /// another codegen unit only misses: callers fall back to comparing
    /// densities).
    pub(crate) fn same(&self, other: &Self) -> bool {
        #[allow(ambiguous_wide_pointer_comparisons)]
        match (self, other) {
            (StrategyRef::One(a), StrategyRef::One(b)) => std::ptr::eq(*a, *b),
            (StrategyRef::Two(a), StrategyRef::Two(b)) => std::ptr::eq(*a, *b),
            _ => false,
        }
    }

    /// The address of the strategy object, which with the name identifies it.
    pub(crate) fn address(&self) -> usize {
        match self {
            StrategyRef::One(s) => std::ptr::from_ref(*s).cast::<()>() as usize,
            StrategyRef::Two(s) => std::ptr::from_ref(*s).cast::<()>() as usize,
        }
    }

    pub(crate) fn sample_step(
        &self,
        prefix: Prefix<'_, V>,
        rng: &mut dyn UniformSource,
        out: &mut Produced<V>,
    ) -> Sampled {
        match self {
            StrategyRef::One(s) => s.sample_step(prefix, rng, out),
            StrategyRef::Two(s) => s.sample_step(prefix, rng, out),
        }
    }

    /// The density of `targets`, given in sampling order.
    pub(crate) fn density_of(&self, prefix: Prefix<'_, V>, targets: &[V]) -> Density {
        match self {
            StrategyRef::One(s) => s.density_of(prefix, &targets[0]),
            StrategyRef::Two(s) => s.density_of(prefix, &targets[0], &targets[1]),
        }
    }
}

/// Embeds a vertex by its geometry: position on a surface, direction at
/// infinity, nothing for an isolated point.
fn embed_vertex<V: Vertex>(v: &V, coords: &mut Coords) -> usize {
    match v.geometry() {
        Geometry::Surface { .. } => v.position().embed(coords),
        Geometry::AtInfinity { direction } => direction.embed(coords),
        Geometry::Point => {
            // No manifold, but distinct points must stay distinct atoms.
            v.position().embed(coords);
            0
        }
    }
}

/// A vertex step embeds as its vertex (or vertices).
impl<V: Vertex> Embed for Step<V> {
    fn embed(&self, coords: &mut Coords) -> usize {
        match self {
            Step::Vertex(v) => embed_vertex(v, coords),
            _ => 0,
        }
    }
}

impl<V: Vertex> Embed for Step<(V, V)> {
    fn embed(&self, coords: &mut Coords) -> usize {
        match self {
            Step::Vertex((a, b)) => embed_vertex(a, coords) + embed_vertex(b, coords),
            _ => 0,
        }
    }
}
