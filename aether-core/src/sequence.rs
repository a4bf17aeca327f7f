//! `RandomSequence`: a path as a list of vertices, each with the strategy
//! that samples it and the direction it is sampled in.

use std::cell::Cell;
use std::ops::Range;
use std::sync::atomic::{AtomicU64, Ordering};

use smallvec::SmallVec;

use crate::density::{Density, Measure, PathDensity};
use crate::mis::FactorCache;
use crate::recycle::{Pooled, Recycle};
use crate::rng::UniformSource;
use crate::strategy::{DynPairStrategy, DynStrategy, Prefix, Produced, StepKind, StrategyRef};
use crate::vertex::Vertex;

/// Inline capacity of a sequence: paths up to this many vertices allocate nothing.
pub const INLINE_VERTICES: usize = 12;

static NEXT_ID_BLOCK: AtomicU64 = AtomicU64::new(1);

thread_local! {
    static NEXT_ID: Cell<(u64, u64)> = const { Cell::new((0, 0)) };
    static EVALUATIONS: Cell<u64> = const { Cell::new(0) };
}

/// The number of densities this thread has evaluated by running a
/// strategy in density mode for a path's vertices (densities recorded
/// while sampling, or found in a cache, do not count): what MIS costs,
/// counted rather than timed, so that a test can check that it grows
/// linearly with path length.
#[must_use]
pub fn density_evaluations() -> u64 {
    EVALUATIONS.with(Cell::get)
}

/// Counts one density evaluation for [`density_evaluations`].
pub(crate) fn count_evaluation() {
    EVALUATIONS.with(|c| c.set(c.get() + 1));
}

/// A fresh vertex identity. Ids come in per-thread blocks of 2³², so they
/// are unique across threads without contention; 0 is never used.
pub(crate) fn fresh_id() -> u64 {
    NEXT_ID.with(|c| {
        let (mut next, mut end) = c.get();
        if next == end {
            next = NEXT_ID_BLOCK.fetch_add(1, Ordering::Relaxed) << 32;
            end = next + (1 << 32);
        }
        c.set((next + 1, end));
        next
    })
}

/// A strategy's type, by its name. One type's name may sit at several
/// addresses (a copy per codegen unit that instantiates it): compared by
/// address alone, the density recorded while sampling was missed whenever
/// the path was evaluated from another unit, and evaluated again, from
/// vertices rounded since. Names compare by content after a pointer check,
/// and hash by length.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Kind(&'static str);

impl PartialEq for Kind {
    fn eq(&self, other: &Self) -> bool {
        std::ptr::eq(self.0, other.0) || self.0 == other.0
    }
}

impl Eq for Kind {}

impl std::hash::Hash for Kind {
    fn hash<H: std::hash::Hasher>(&self, state: &mut H) {
        self.0.len().hash(state);
    }
}

/// Identifies one density factor: a strategy evaluated for given target
/// vertices with given conditioning vertices at a given depth. Equal keys
/// have equal densities, whichever candidate path they occur in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(crate) struct FactorKey {
    strategy: usize,
    /// The strategy's depth class of the prefix length.
    depth: u32,
    instance: u64,
    targets: [u64; 2],
    cond: [u64; 2],
    /// Last, so that equality compares names only when all else matches.
    kind: Kind,
}

impl FactorKey {
    pub(crate) const EMPTY: FactorKey = FactorKey {
        strategy: 0,
        kind: Kind(""),
        depth: 0,
        instance: 0,
        targets: [0; 2],
        cond: [0; 2],
    };

    #[cfg(test)]
    pub(crate) fn test(i: u64) -> FactorKey {
        FactorKey {
            targets: [i, 0],
            ..Self::EMPTY
        }
    }

    /// The words folded in two multiplications: factor lookups hash on
    /// every MIS weight, and a multiplication per word chained eight
    /// multiplications. Ids differ in their low bits, so the high half of
    /// each product is folded into the low bits that index the table.
    pub(crate) fn hash64(&self) -> u64 {
        let a = self.targets[0]
            ^ self.cond[1].rotate_left(32)
            ^ (u64::from(self.depth) << 56)
            ^ (self.kind.0.len() as u64) << 44;
        let b = self.cond[0]
            ^ self.targets[1].rotate_left(32)
            ^ (self.strategy as u64).rotate_left(17)
            ^ self.instance.rotate_left(7);
        let h = (a.wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ b).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        h ^ (h >> 31)
    }
}

/// What names a strategy in a cache key: its address, type and instance.
fn identity<V>(s: StrategyRef<'_, V>) -> (usize, Kind, u64) {
    (s.address(), Kind(s.name()), s.instance())
}

/// The density a step's strategy (`by`) gave its vertices while sampling
/// them, with what it was conditioned on; the target is the slot's vertex
/// (and, for a pair, its `partner`). Matching these is what a cache key
/// would compare, without building or hashing one. It stays with the
/// vertex when other strategies are assigned to it, and serves them where
/// they ask for `by`'s density, so that every candidate of a path sees the
/// same number for it.
pub(crate) struct Recorded<'s, V> {
    by: StrategyRef<'s, V>,
    class: u32,
    cond: [u64; 2],
    partner: u64,
    density: Density,
}

impl<V> Recorded<'_, V> {
    /// The recorded density, if it was recorded by `span`'s strategy with
    /// the depth class, conditioning vertices and targets of `key` (the
    /// span's). As a cache key does, this leaves the direction out: a
    /// strategy sees only its conditioning vertices and depth, so a density
    /// is the same forward and reversed (and a strategy that misstates its
    /// memory shows, its two directions colliding).
    fn matching(&self, span: &Span<'_, V>, key: &FactorKey) -> Option<Density> {
        let matches =
            key.cond == self.cond && key.targets[1] == self.partner && key.depth == self.class;
        let a = self.by;
        let same = || {
            span.strategy
                .is_some_and(|b| a.same(&b) || identity(a) == span.identity)
        };
        (matches && same()).then_some(self.density)
    }
}

impl<V> Clone for Recorded<'_, V> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<V> Copy for Recorded<'_, V> {}

/// One vertex's bookkeeping.
pub(crate) struct Slot<'s, V> {
    pub(crate) strategy: Option<StrategyRef<'s, V>>,
    pub(crate) reversed: bool,
    /// Number of vertices of the step this vertex belongs to.
    pub(crate) arity: u8,
    /// Position within that step, in sampling order.
    pub(crate) part: u8,
    pub(crate) id: u64,
    /// For a vertex no strategy covers: true if it was given (a Dirac of
    /// mass one at itself), false if it was cut from a multi-vertex step
    /// (it has no density of its own).
    pub(crate) given: bool,
    /// The density recorded while sampling, on the step's first vertex.
    pub(crate) recorded: Option<Recorded<'s, V>>,
    /// A running product of recorded densities: for a vertex sampled
    /// forward, of its own and those of the vertices before it, each under
    /// the strategy that sampled it, while they were sampled one by one in
    /// one sequence; with the number of vertices it covers. The camera-side
    /// prefix product that MIS would otherwise rebuild factor by factor,
    /// or, once the sequence is reversed into the light end of a path, the
    /// light-side suffix product. Valid as such only while the vertices it
    /// covers start the path (forward) or end it (reversed): their densities
    /// depend on no other vertex. `None` for a given or cut vertex, a
    /// multi-vertex step, or a vertex copied without all it covers.
    pub(crate) chain: Option<(PathDensity, u16)>,
}

impl<V> Slot<'_, V> {
    /// Makes this vertex of a step that a slice splits strategy-less, with
    /// no density of its own.
    fn cut(&mut self) {
        *self = Slot {
            strategy: None,
            arity: 1,
            part: 0,
            given: false,
            recorded: None,
            chain: None,
            ..*self
        };
    }
}

impl<V> Clone for Slot<'_, V> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<V> Copy for Slot<'_, V> {}

impl<V: Recycle> Recycle for Slot<'_, V> {
    type Static = Slot<'static, V::Static>;
}

/// One step of a sequence seen as a factor of the path density.
pub(crate) struct Span<'s, V> {
    pub(crate) start: usize,
    pub(crate) arity: usize,
    pub(crate) strategy: Option<StrategyRef<'s, V>>,
    pub(crate) reversed: bool,
    pub(crate) fixed_id: u64,
    /// The strategy's memory and identity, read once rather than per factor.
    memory: usize,
    identity: (usize, Kind, u64),
}

impl<'s, V> Span<'s, V> {
    pub(crate) fn new(
        start: usize,
        arity: usize,
        strategy: Option<StrategyRef<'s, V>>,
        reversed: bool,
        fixed_id: u64,
    ) -> Self {
        let (memory, identity) = match strategy {
            Some(s) => (s.memory(), identity(s)),
            None => (0, (0, Kind(""), 0)),
        };
        Span {
            start,
            arity,
            strategy,
            reversed,
            fixed_id,
            memory,
            identity,
        }
    }
}

impl<V> Span<'_, V> {
    /// The same one-vertex step at `start`, in direction `reversed`: what
    /// MIS asks of each vertex in turn, without reading the strategy's
    /// identity again.
    pub(crate) fn at(mut self, start: usize, reversed: bool) -> Self {
        self.start = start;
        self.reversed = reversed;
        self
    }
}

impl<V> Clone for Span<'_, V> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<V> Copy for Span<'_, V> {}

impl<V> PartialEq for Span<'_, V> {
    fn eq(&self, other: &Self) -> bool {
        let same_strategy = match (self.strategy, other.strategy) {
            (Some(_), Some(_)) => self.identity == other.identity,
            (None, None) => self.fixed_id == other.fixed_id,
            _ => false,
        };
        same_strategy
            && self.start == other.start
            && self.arity == other.arity
            && self.reversed == other.reversed
    }
}

/// A path under construction or sampled: vertices, and for each the
/// strategy that samples it and whether it is sampled forward (conditioned
/// on the vertices before it) or reversed (on the vertices after it).
///
/// Sequences are built by [`append`](Self::append) and
/// [`sample`](Self::sample), and recombined by [`slice`](Self::slice),
/// [`concat`](Self::concat) and [`reversed`](Self::reversed), which keep
/// each vertex's strategy. [`pdf`](Self::pdf) is the density of the
/// sequence's own vertices; [`pdf_of`](Self::pdf_of) the density with
/// which this sequence's strategies would produce another path's vertices.
///
/// Vertices live inline up to [`INLINE_VERTICES`]; sampling, slicing and
/// density evaluation allocate nothing below that length.
///
/// ```
/// use aether_core::{Pcg32, RandomSequence};
/// use aether_core::testing::{Bounce, CameraPoint, LookDown, TestScene};
///
/// let scene = TestScene::open_box();
/// let (camera, look, bounce) = (CameraPoint::default(), LookDown::new(&scene), Bounce::new(&scene));
/// let mut path = RandomSequence::new();
/// path.append(&camera).append(&look).append(&bounce);
/// path.sample(&mut Pcg32::new(1, 0));
/// assert_eq!(path.len(), 3);
/// let p = path.pdf();
/// assert!(p.value() > 0.0 && p.dirac_order() == 1); // the camera point is a Dirac
/// ```
pub struct RandomSequence<'s, V: Recycle> {
    vertices: Pooled<[V; INLINE_VERTICES]>,
    slots: Pooled<[Slot<'s, V>; INLINE_VERTICES]>,
    pending: Pooled<[StrategyRef<'s, V>; INLINE_VERTICES]>,
    /// Steps whose sampling failed or never ran because an earlier one
    /// failed: the sequence keeps them as a technique, so that MIS can
    /// still weigh other paths by the densities they would have had.
    unsampled: Pooled<[StrategyRef<'s, V>; 4]>,
    end: Option<(StepKind, Density)>,
}

impl<V: Vertex> Clone for RandomSequence<'_, V> {
    fn clone(&self) -> Self {
        RandomSequence {
            vertices: self.vertices.clone(),
            slots: self.slots.clone(),
            pending: self.pending.clone(),
            unsampled: self.unsampled.clone(),
            end: self.end,
        }
    }
}

impl<V: Vertex + std::fmt::Debug> std::fmt::Debug for RandomSequence<'_, V> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mut l = f.debug_list();
        for (v, s) in self.vertices.iter().zip(&self.slots) {
            let name = s.strategy.map_or("given", |s| s.name());
            l.entry(&(name, if s.reversed { "reversed" } else { "forward" }, v));
        }
        l.finish()
    }
}

impl<V: Vertex> Default for RandomSequence<'_, V> {
    fn default() -> Self {
        Self::new()
    }
}

impl<'s, V: Vertex> RandomSequence<'s, V> {
    /// The empty sequence.
    #[must_use]
    pub fn new() -> Self {
        RandomSequence {
            vertices: Pooled::new(),
            slots: Pooled::new(),
            pending: Pooled::new(),
            unsampled: Pooled::new(),
            end: None,
        }
    }

    /// A sequence of given vertices that no strategy sampled. Under
    /// [`pdf_of`](Self::pdf_of) a given vertex acts as a Dirac of mass one
    /// at itself: it cancels against itself and excludes everything else.
    pub fn given(vertices: impl IntoIterator<Item = V>) -> Self {
        let mut s = Self::new();
        for v in vertices {
            s.vertices.push(v);
            s.slots.push(Slot {
                strategy: None,
                reversed: false,
                arity: 1,
                part: 0,
                id: fresh_id(),
                given: true,
                recorded: None,
                chain: None,
            });
        }
        s
    }

    /// Appends a strategy to be sampled by the next [`sample`](Self::sample).
    pub fn append(&mut self, strategy: &'s dyn DynStrategy<V>) -> &mut Self {
        self.pending.push(StrategyRef::One(strategy));
        self
    }

    pub(crate) fn pending_push(&mut self, strategy: StrategyRef<'s, V>) {
        self.pending.push(strategy);
    }

    /// Appends a two-vertex strategy (a portal segment) to be sampled by
    /// the next [`sample`](Self::sample).
    pub fn append_pair(&mut self, strategy: &'s dyn DynPairStrategy<V>) -> &mut Self {
        self.pending.push(StrategyRef::Two(strategy));
        self
    }

    /// Samples the appended strategies in order, each conditioned on the
    /// vertices before it. Stops at the first step that produces no vertex
    /// (Russian-roulette termination, a miss, a void sample) and records
    /// that event. The failed step and those after it stay in the sequence
    /// as unsampled steps: the sequence has no density as a path of its
    /// full length, but still counts as a technique in
    /// [`combine`](crate::combine) and [`pdf_of`](Self::pdf_of).
    pub fn sample(&mut self, rng: &mut dyn UniformSource) -> StepKind {
        // A sequence that already stopped samples nothing more.
        let mut result = if self.unsampled.is_empty() {
            StepKind::Vertex
        } else {
            self.end.map_or(StepKind::Void, |e| e.0)
        };
        // By index, not by taking the list: a step moves no list.
        for k in 0..self.pending.len() {
            let s = self.pending[k];
            if result == StepKind::Vertex {
                result = self.sample_step(s, rng, None).0;
                if result == StepKind::Vertex {
                    continue;
                }
            }
            self.unsampled.push(s);
        }
        self.pending.clear();
        result
    }

    /// Samples the appended strategies, then `strategy` again and again
    /// until a step produces no vertex or the sequence holds `max`
    /// vertices: a random walk, ended by Russian roulette, a miss or its
    /// length.
    ///
    /// ```
    /// use aether_core::testing::{Bounce, CameraPoint, LookDown, TestScene};
    /// use aether_core::{Pcg32, RandomSequence};
    ///
    /// let scene = TestScene::open_box();
    /// let (camera, look, bounce) = (CameraPoint::default(), LookDown::new(&scene), Bounce::new(&scene));
    /// let mut walk = RandomSequence::new();
    /// walk.append(&camera).append(&look).repeat(&bounce, 5, &mut Pcg32::new(7, 0));
    /// // Stopped by its length, or by a bounce out of the open box.
    /// assert!(walk.len() == 5 || !walk.is_complete());
    /// ```
    pub fn repeat(
        &mut self,
        strategy: &'s dyn DynStrategy<V>,
        max: usize,
        rng: &mut dyn UniformSource,
    ) -> &mut Self {
        self.sample(rng);
        while self.is_complete() && self.len() < max {
            self.append_sample(strategy, rng);
        }
        self
    }

    /// Appends `strategy` and samples it at once; returns true if it produced a vertex.
    // Inlined, with the step taken here rather than through the list of
    // appended strategies, so that where the caller's strategy is of a
    // known type the call through its table becomes a direct call.
    #[inline(always)]
    pub fn append_sample(
        &mut self,
        strategy: &'s dyn DynStrategy<V>,
        rng: &mut dyn UniformSource,
    ) -> bool {
        if self.flush(rng) != StepKind::Vertex {
            self.unsampled.push(StrategyRef::One(strategy));
            return false;
        }
        let step = StrategyRef::One(strategy);
        let (kind, _) = self.sample_step(step, rng, None);
        if kind != StepKind::Vertex {
            self.unsampled.push(step);
        }
        kind == StepKind::Vertex
    }

    /// Samples the strategies appended before (as [`sample`](Self::sample)),
    /// if any, or says how the sequence stands: the common case, nothing
    /// pending or unsampled, decided without a call.
    #[inline(always)]
    fn flush(&mut self, rng: &mut dyn UniformSource) -> StepKind {
        if self.pending.is_empty() && self.unsampled.is_empty() {
            StepKind::Vertex
        } else {
            self.sample(rng)
        }
    }

    /// Appends `strategy` and samples it at once, as
    /// [`append_sample`](Self::append_sample), and returns with the outcome
    /// the density with which `strategy` would have produced `other` in
    /// place of its vertex: what the MIS weight of a vertex that another
    /// strategy sampled after the same vertices needs of this one (see
    /// [`weight_of_step`](crate::weight_of_step)). Both come from one
    /// distribution, built once; the density is the one
    /// [`pdf_of`](Self::pdf_of) would find, to the bit.
    ///
    /// ```
    /// use aether_core::testing::{Bounce, CameraPoint, LightSample, LookDown, TestScene};
    /// use aether_core::{Pcg32, RandomSequence};
    ///
    /// let scene = TestScene::open_box();
    /// let (camera, look) = (CameraPoint::default(), LookDown::new(&scene));
    /// let (bounce, light) = (Bounce::new(&scene), LightSample::new(&scene));
    /// let mut rng = Pcg32::new(5, 0);
    /// let mut lit = RandomSequence::new();
    /// lit.append(&camera).append(&look).append(&light);
    /// lit.sample(&mut rng);
    /// let mut path = lit.clone();
    /// path.truncate(2);
    /// let (_, by_bounce) = path.append_sample_measuring(&bounce, &mut rng, &lit.vertices()[2]);
    /// // The density of the light's vertex under bounce sampling, as MIS finds it.
    /// let mut technique = RandomSequence::new();
    /// technique.append(&camera).append(&look).append(&bounce);
    /// let whole = technique.pdf_of(&lit).value();
    /// assert!(by_bounce.value() > 0.0);
    /// assert!((lit.pdf_of_prefix(2).value() * by_bounce.value() - whole).abs() <= 1e-12 * whole);
    /// ```
    #[inline(always)]
    pub fn append_sample_measuring(
        &mut self,
        strategy: &'s dyn DynStrategy<V>,
        rng: &mut dyn UniformSource,
        other: &V,
    ) -> (bool, Density) {
        let step = StrategyRef::One(strategy);
        // Steps appended before go first; a sequence that has stopped
        // samples nothing more, but the density is still asked for.
        if self.flush(rng) != StepKind::Vertex {
            self.unsampled.push(step);
            count_evaluation();
            return (
                false,
                strategy.density_of(Prefix::forward(&self.vertices), other),
            );
        }
        let (kind, density) = self.sample_step(step, rng, Some(other));
        if kind != StepKind::Vertex {
            self.unsampled.push(step);
        }
        (kind == StepKind::Vertex, density)
    }

    /// Samples one step; with `measure`, also returns the density with
    /// which the step's strategy would have produced that vertex in place
    /// of its own (zero without).
    #[inline(always)]
    fn sample_step(
        &mut self,
        strategy: StrategyRef<'s, V>,
        rng: &mut dyn UniformSource,
        measure: Option<&V>,
    ) -> (StepKind, Density) {
        let mut out = Produced::<V>::new();
        let prefix = Prefix::forward(&self.vertices);
        let (sampled, measured) = match (measure, strategy) {
            (Some(other), StrategyRef::One(s)) => {
                count_evaluation();
                s.sample_step_measuring(prefix, rng, &mut out, other)
            }
            _ => (
                strategy.sample_step(prefix, rng, &mut out),
                Density::zero(Measure::Area),
            ),
        };
        let (kind, density) = (sampled.kind, sampled.density);
        if kind != StepKind::Vertex {
            self.end = Some((kind, density));
            return (kind, measured);
        }
        let known = (sampled.memory, sampled.class);
        self.push_known_step(strategy, &mut out, density, known);
        (StepKind::Vertex, measured)
    }

    /// True if this sequence's first `n` vertices are `other`'s (the same
    /// sampled vertices, by identity).
    pub(crate) fn same_prefix(&self, other: &Self, n: usize) -> bool {
        n <= self.len()
            && n <= other.len()
            && self.slots[..n]
                .iter()
                .zip(&other.slots[..n])
                .all(|(a, b)| a.id == b.id)
    }

    /// Appends the vertices `out` that `strategy` sampled after this
    /// sequence's with `density`, recording it as sampling does.
    pub(crate) fn push_step(
        &mut self,
        strategy: StrategyRef<'s, V>,
        out: &mut Produced<V>,
        density: Density,
    ) {
        let start = self.vertices.len();
        let known = (strategy.memory(), strategy.depth_class(start));
        self.push_known_step(strategy, out, density, known);
    }

    /// As [`push_step`](Self::push_step), with the strategy's memory and
    /// the depth class of the step (`known`) as its sampling reported them.
    fn push_known_step(
        &mut self,
        strategy: StrategyRef<'s, V>,
        out: &mut Produced<V>,
        density: Density,
        (memory, class): (usize, usize),
    ) {
        let start = self.vertices.len();
        let arity = out.len();
        debug_assert!((1..=2).contains(&arity), "a step samples one vertex or two");
        // Each slot is built whole and pushed once: built in place field
        // by field, a path tracer's step cost a quarter more here.
        let ids = [fresh_id(), if arity == 2 { fresh_id() } else { 0 }];
        let (recorded, chain) = self.record(strategy, (start, memory, class), ids[1], density);
        let slot = |part: usize, recorded, chain| Slot {
            strategy: Some(strategy),
            reversed: false,
            arity: arity as u8,
            part: part as u8,
            id: ids[part],
            given: false,
            recorded,
            chain,
        };
        if arity == 1 {
            if let Some(v) = out.pop() {
                self.vertices.push(v);
            }
            self.slots.push(slot(0, recorded, chain));
        } else {
            self.vertices.extend(out.drain());
            self.slots.push(slot(0, recorded, None));
            self.slots.push(slot(1, None, None));
        }
    }

    /// What a step's first slot records of the density `strategy` (of
    /// `memory`, the step in depth class `class`) gave its vertices,
    /// sampled after the first `start`, the second being
    /// `partner` (0, an id never given, for a step of one vertex): the
    /// density with what it was conditioned on, if
    /// the strategy's memory is short enough to match it, and for a step
    /// of one vertex the running product it extends.
    #[allow(clippy::type_complexity)]
    fn record(
        &self,
        strategy: StrategyRef<'s, V>,
        (start, memory, class): (usize, usize, usize),
        partner: u64,
        density: Density,
    ) -> (Option<Recorded<'s, V>>, Option<(PathDensity, u16)>) {
        if memory > 2 {
            return (None, None);
        }
        let recorded = Recorded {
            by: strategy,
            class: class as u32,
            cond: self.ids_before(start, memory),
            partner,
            density,
        };
        let before = match start {
            _ if partner != 0 => None,
            0 => Some(PathDensity::ONE),
            _ => self.prefix_chain(start - 1),
        };
        let covers = u16::try_from(start + 1).ok();
        let chain = before.zip(covers).map(|(p, c)| (p.times(density), c));
        (Some(recorded), chain)
    }

    /// The product of the densities of vertices `0..=i` under the
    /// strategies that sampled them, if they were sampled forward one by
    /// one in a sequence that this one starts with.
    fn prefix_chain(&self, i: usize) -> Option<PathDensity> {
        let slot = self.slots.get(i)?;
        match slot.chain {
            Some((p, covers)) if !slot.reversed && usize::from(covers) == i + 1 => Some(p),
            _ => None,
        }
    }

    /// The product of the densities of vertices `i..len` under the
    /// strategies that sampled them, reversed, if they were sampled forward
    /// one by one in a sequence that this one ends with, reversed.
    fn suffix_product(&self, i: usize) -> Option<PathDensity> {
        let slot = self.slots.get(i)?;
        match slot.chain {
            Some((p, covers)) if slot.reversed && i + usize::from(covers) == self.len() => Some(p),
            _ => None,
        }
    }

    /// True if vertex `i` is sampled by `strategy` (the same object of the
    /// same type: a vtable copied into two codegen units only misses, and
    /// the factor is then looked up).
    fn sampled_by(&self, i: usize, strategy: Option<StrategyRef<'_, V>>) -> bool {
        match (self.slots.get(i).and_then(|s| s.strategy), strategy) {
            (Some(a), Some(b)) => a.same(&b),
            _ => false,
        }
    }

    /// The product of the densities of vertices `0..=i` under the
    /// strategies that sampled them, if vertex `i` and all before it were
    /// sampled forward in one sequence, one per step, and vertex `i` by
    /// `strategy`: what MIS's camera-side prefix product is there, without
    /// a factor looked up. Equal to that product factor by factor, since
    /// each recorded density is the one the factor would return.
    pub(crate) fn chain(
        &self,
        i: usize,
        strategy: Option<StrategyRef<'_, V>>,
    ) -> Option<PathDensity> {
        self.sampled_by(i, strategy)
            .then(|| self.prefix_chain(i))
            .flatten()
    }

    /// As [`chain`](Self::chain) for the light end: the product of the
    /// densities of vertices `i..len` under the strategies that sampled
    /// them, reversed, if they were sampled forward one by one in one
    /// sequence (a light subpath) and vertex `i` by `strategy`.
    pub(crate) fn suffix_chain(
        &self,
        i: usize,
        strategy: Option<StrategyRef<'_, V>>,
    ) -> Option<PathDensity> {
        self.sampled_by(i, strategy)
            .then(|| self.suffix_product(i))
            .flatten()
    }

    /// True if vertex `i` is a step of its own (not part of a pair).
    pub(crate) fn single_step(&self, i: usize) -> bool {
        self.slots.get(i).is_some_and(|s| s.arity == 1)
    }

    /// The density of vertices `0..len` under the strategies that sampled
    /// them, each conditioned on the vertices before it: the running
    /// product recorded while sampling where there is one, else factor by
    /// factor. What the techniques that share those vertices share (see
    /// [`weight_of_step`](crate::weight_of_step)).
    #[must_use]
    pub fn pdf_of_prefix(&self, len: usize) -> PathDensity {
        match len.checked_sub(1) {
            None => PathDensity::ONE,
            Some(i) => self
                .prefix_chain(i)
                .unwrap_or_else(|| self.pdf_of_steps(0..len)),
        }
    }

    /// Number of vertices.
    #[must_use]
    pub fn len(&self) -> usize {
        self.vertices.len()
    }

    /// True if every appended step produced its vertices.
    #[must_use]
    pub fn is_complete(&self) -> bool {
        self.unsampled.is_empty() && self.pending.is_empty()
    }

    /// The number of vertices of the paths this sequence's strategies
    /// produce: its length plus the vertices of unsampled and pending steps.
    #[must_use]
    pub fn technique_len(&self) -> usize {
        self.len()
            + self
                .unsampled
                .iter()
                .chain(&self.pending)
                .map(StrategyRef::arity)
                .sum::<usize>()
    }

    /// True if there are no vertices.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.vertices.is_empty()
    }

    /// The vertices in path order.
    #[must_use]
    pub fn vertices(&self) -> &[V] {
        &self.vertices
    }

    /// The event that ended sampling, with its probability (for instance
    /// [`StepKind::Terminated`] with mass 1 − q), if sampling ended early.
    #[must_use]
    pub fn end(&self) -> Option<(StepKind, Density)> {
        self.end
    }

    /// True if vertex `i` is sampled in reverse (by a light-side strategy).
    #[must_use]
    pub fn is_reversed(&self, i: usize) -> bool {
        self.slots[i].reversed
    }

    /// The name of the strategy that samples vertex `i` (`None` for a given vertex).
    #[must_use]
    pub fn strategy_name(&self, i: usize) -> Option<&'static str> {
        self.slots[i].strategy.map(|s| s.name())
    }

    /// The vertices in `range` with their strategies. The vertices of a
    /// multi-vertex step that the range cuts keep no strategy and have
    /// density zero: a technique that holds them cannot be weighed.
    ///
    /// # Panics
    /// If `range` is out of bounds, like slicing.
    #[must_use]
    pub fn slice(&self, range: Range<usize>) -> Self {
        let mut s = Self::new();
        s.extend_from(self, range, false);
        s
    }

    /// The leftmost position of the step that holds position `i`.
    fn span_start(&self, i: usize) -> usize {
        let mut k = 0;
        while k < self.slots.len() {
            let a = usize::from(self.slots[k].arity);
            if i < k + a {
                return k;
            }
            k += a;
        }
        i
    }

    /// This sequence followed by `other`.
    #[must_use]
    pub fn concat(&self, other: &Self) -> Self {
        let mut s = Self::new();
        s.extend_from(self, 0..self.len(), false)
            .extend_from(other, 0..other.len(), false);
        s
    }

    /// The sequence in reverse order, each strategy's direction flipped: a
    /// light subpath becomes the light end of a camera-to-light path.
    #[must_use]
    pub fn reversed(&self) -> Self {
        let mut s = Self::new();
        s.extend_from(self, 0..self.len(), true);
        s
    }

    /// Removes every vertex and step, keeping the storage; returns the
    /// sequence, to be refilled in place (`path.clear().extend_from(..)`).
    pub fn clear(&mut self) -> &mut Self {
        self.truncate(0);
        self
    }

    /// Keeps the first `len` vertices as a complete sequence, like
    /// `slice(0..len)` in place: later vertices, unsampled and pending steps
    /// and the recorded end go. The vertices of a multi-vertex step that
    /// the cut splits keep no strategy.
    pub fn truncate(&mut self, len: usize) {
        if len < self.len() {
            for k in self.span_start(len)..len {
                self.slots[k].cut();
            }
            self.vertices.truncate(len);
            self.slots.truncate(len);
        }
        self.unsampled.clear();
        self.pending.clear();
        self.end = None;
    }

    /// Appends `other`'s vertices in `range` with their strategies, in
    /// order or, if `reversed`, in reverse order with each strategy's
    /// direction flipped. Building a path from parts of subpaths this way
    /// copies each vertex once. The vertices of a multi-vertex step that
    /// the range cuts keep no strategy and have density zero.
    ///
    /// # Panics
    /// If `range` is out of bounds, like slicing.
    pub fn extend_from(&mut self, other: &Self, range: Range<usize>, reversed: bool) -> &mut Self {
        let base = self.len();
        self.vertices
            .extend(other.vertices[range.clone()].iter().cloned());
        self.slots.extend_from_slice(&other.slots[range.clone()]);
        let added = &mut self.slots[base..];
        // A running product survives a copy of every vertex it covers: the
        // vertex and those before it (forward) or after it (reversed).
        for (k, slot) in added.iter_mut().enumerate() {
            let j = range.start + k;
            if let Some((_, covers)) = slot.chain {
                let c = usize::from(covers);
                let first = if slot.reversed {
                    Some(j)
                } else {
                    (j + 1).checked_sub(c)
                };
                let copied = first.is_some_and(|f| f >= range.start && f + c <= range.end);
                if c == 0 || !copied {
                    slot.chain = None;
                }
            }
        }
        let mut k = 0;
        while k < added.len() {
            let arity = usize::from(added[k].arity);
            let origin = range.start + k;
            if arity > 1 && (k + arity > added.len() || other.span_start(origin) != origin) {
                added[k].cut();
                k += 1;
            } else {
                k += arity;
            }
        }
        if reversed {
            self.vertices[base..].reverse();
            self.slots[base..].reverse();
            for slot in &mut self.slots[base..] {
                slot.reversed = !slot.reversed;
            }
        }
        self
    }

    /// The same vertices assigned to other strategies: `steps` lists, in
    /// path order, each strategy and whether it is reversed. `None` if the
    /// strategies' vertex counts do not add up to this sequence's length.
    /// Vertex identities are kept, so densities cached for this path are
    /// reused.
    #[must_use]
    pub fn with_strategies(&self, steps: &[(StrategyRef<'s, V>, bool)]) -> Option<Self> {
        if steps.iter().map(|(s, _)| s.arity()).sum::<usize>() != self.len() {
            return None;
        }
        let mut s = Self {
            vertices: self.vertices.clone(),
            slots: self.slots.clone(),
            ..Self::new()
        };
        let mut k = 0;
        for &(strategy, reversed) in steps {
            let arity = strategy.arity();
            for p in 0..arity {
                let part = if reversed { arity - 1 - p } else { p };
                let slot = &mut s.slots[k + p];
                *slot = Slot {
                    strategy: Some(strategy),
                    reversed,
                    arity: arity as u8,
                    part: part as u8,
                    chain: None,
                    ..*slot
                };
            }
            k += arity;
        }
        Some(s)
    }

    /// The steps of this sequence, left to right.
    pub(crate) fn spans(&self) -> impl Iterator<Item = Span<'s, V>> + '_ {
        let mut k = 0;
        let sampled = std::iter::from_fn(move || {
            let slot = self.slots.get(k)?;
            // A cut vertex matches no id (ids are never 0): density zero.
            let fixed_id = if slot.given { slot.id } else { 0 };
            let span = Span::new(
                k,
                usize::from(slot.arity),
                slot.strategy,
                slot.reversed,
                fixed_id,
            );
            k += span.arity;
            Some(span)
        });
        let mut start = self.len();
        let unsampled = self.unsampled.iter().chain(&self.pending).map(move |s| {
            let span = Span::new(start, s.arity(), Some(*s), false, 0);
            start += span.arity;
            span
        });
        sampled.chain(unsampled)
    }

    /// The ids of the (at most two) `memory` vertices before position
    /// `start`, nearest first, zero where there are none: what a forward
    /// step is conditioned on.
    fn ids_before(&self, start: usize, memory: usize) -> [u64; 2] {
        let mut ids = [0u64; 2];
        for (k, id) in ids.iter_mut().take(memory.min(start)).enumerate() {
            *id = self.slots[start - 1 - k].id;
        }
        ids
    }

    /// The cache key of `span`'s density factor on this path, if the
    /// strategy's memory is short enough to cache: its strategy, depth
    /// class, target vertices (in sampling order) and conditioning ones.
    fn key(&self, span: &Span<'_, V>) -> Option<FactorKey> {
        let memory = span.memory;
        if memory > 2 {
            return None;
        }
        let end = span.start + span.arity;
        let mut targets = [0u64; 2];
        if span.arity == 1 {
            targets[0] = self.slots[span.start].id;
        } else {
            for (t, slot) in targets.iter_mut().zip(&self.slots[span.start..end]) {
                *t = slot.id;
            }
            if span.reversed {
                targets[..span.arity].reverse();
            }
        }
        let mut cond = [0u64; 2];
        let prefix_len = if span.reversed {
            for (k, c) in cond.iter_mut().take(memory).enumerate() {
                *c = self.slots.get(end + k).map_or(0, |s| s.id);
            }
            self.len() - end
        } else {
            cond = self.ids_before(span.start, memory);
            span.start
        };
        let class = span
            .strategy
            .map_or(prefix_len, |s| s.depth_class(prefix_len));
        Some(FactorKey {
            strategy: span.identity.0,
            kind: span.identity.1,
            depth: class as u32,
            instance: span.identity.2,
            targets,
            cond,
        })
    }

    /// The density of this path's vertices in `span`, under the span's
    /// strategy and direction, reusing the density recorded while sampling
    /// or a cached one where the key matches.
    pub(crate) fn factor(&self, span: &Span<'_, V>, cache: Option<&mut FactorCache>) -> Density {
        let end = span.start + span.arity;
        if end > self.len() {
            return Density::zero(Measure::Area);
        }
        let Some(strategy) = span.strategy else {
            return if self.slots[span.start].id == span.fixed_id {
                Density::dirac(1.0, Measure::Area)
            } else {
                Density::zero(Measure::Area)
            };
        };
        // A step's recorded density sits on its first vertex in sampling
        // order, which for a one-vertex step (nearly every factor) is it.
        let first = match span.arity {
            1 => span.start,
            _ => (span.start..end)
                .find(|&k| self.slots[k].part == 0)
                .unwrap_or(span.start),
        };
        // Borrowed, not copied: in BDPT the copy was a quarter of this
        // function's own instructions.
        let recorded = self.slots[first].recorded.as_ref();
        // With nothing recorded and no cache, no key is needed; a strategy
        // with a long memory records nothing and caches nothing.
        let key = match (&cache, recorded) {
            (None, None) => None,
            _ => self.key(span),
        };
        let Some(key) = key else {
            return self.evaluate(span, strategy);
        };
        if let Some(d) = recorded.and_then(|r| r.matching(span, &key)) {
            return d;
        }
        match cache {
            Some(cache) => cache.get_or_insert_with(key, || self.evaluate(span, strategy)),
            None => self.evaluate(span, strategy),
        }
    }

    /// Runs `span`'s strategy in density mode on this path's vertices.
    fn evaluate(&self, span: &Span<'_, V>, strategy: StrategyRef<'_, V>) -> Density {
        count_evaluation();
        let end = span.start + span.arity;
        if span.reversed {
            let prefix = Prefix::reversed(&self.vertices[end..]);
            if span.arity == 1 {
                strategy.density_of(prefix, &self.vertices[span.start..end])
            } else {
                let targets: SmallVec<[V; 2]> = self.vertices[span.start..end]
                    .iter()
                    .rev()
                    .cloned()
                    .collect();
                strategy.density_of(prefix, &targets)
            }
        } else {
            strategy.density_of(
                Prefix::forward(&self.vertices[..span.start]),
                &self.vertices[span.start..end],
            )
        }
    }

    /// As [`pdf_of`](Self::pdf_of), but every factor evaluated afresh: no
    /// recorded density and no cache. The MIS check compares against it.
    pub(crate) fn pdf_of_fresh(&self, path: &Self) -> PathDensity {
        if self.technique_len() != path.len() || !path.is_complete() {
            return PathDensity::ONE.times(Density::zero(Measure::Area));
        }
        self.spans().fold(PathDensity::ONE, |p, span| {
            let d = match span.strategy {
                Some(strategy) if span.start + span.arity <= path.len() => {
                    path.evaluate(&span, strategy)
                }
                _ => path.factor(&span, None),
            };
            p.times(d)
        })
    }

    /// The density of the vertices at `range` under the strategies that
    /// sampled them, each conditioned on this sequence's other vertices:
    /// the part of [`pdf`](Self::pdf) from the steps that start in `range`.
    #[must_use]
    pub fn pdf_of_steps(&self, range: Range<usize>) -> PathDensity {
        self.spans()
            .take_while(|span| span.start < self.len())
            .filter(|span| range.contains(&span.start))
            .fold(PathDensity::ONE, |p, span| {
                p.times(self.factor(&span, None))
            })
    }

    /// The density of this sequence's own vertices under its own
    /// strategies, in the product of the vertices' measures.
    #[must_use]
    pub fn pdf(&self) -> PathDensity {
        // Sampled one vertex per step from the start, the path's density is
        // the running product its last vertex carries, factor for factor.
        let chained = self.len().checked_sub(1).and_then(|i| self.prefix_chain(i));
        match chained {
            Some(p) if self.is_complete() => p,
            _ => self.pdf_of(self),
        }
    }

    /// The density with which this sequence's strategies, each in its
    /// direction, would produce the vertices of `path`: forward strategies
    /// conditioned on `path`'s earlier vertices, reversed ones on its later
    /// vertices. Unsampled steps count. Zero if the lengths or step
    /// structures differ, or if `path` is incomplete.
    #[must_use]
    pub fn pdf_of(&self, path: &Self) -> PathDensity {
        if self.technique_len() != path.len() || !path.is_complete() {
            return PathDensity::ONE.times(Density::zero(Measure::Area));
        }
        self.spans().fold(PathDensity::ONE, |p, span| {
            p.times(path.factor(&span, None))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::{FactorKey, Kind};

    #[test]
    fn a_type_name_copied_elsewhere_is_the_same_kind() {
        let name = std::any::type_name::<FactorKey>();
        let copy: &'static str = Box::leak(name.to_string().into_boxed_str());
        assert!(!std::ptr::eq(name, copy));
        let key = |kind| FactorKey {
            kind,
            ..FactorKey::test(7)
        };
        assert_eq!(key(Kind(name)), key(Kind(copy)));
        assert_eq!(key(Kind(name)).hash64(), key(Kind(copy)).hash64());
        assert_ne!(key(Kind(name)), key(Kind("another strategy")));
    }
}
