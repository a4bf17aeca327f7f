//! A strategy taken for a share of the samples only: the choice is a
//! discrete event of the language, so its probability enters every density
//! of the strategy and no estimator or MIS weight multiplies it in by hand.

use crate::choice::RussianRoulette;
use crate::distribution::{Distribution, Step};
use crate::strategy::{PairStrategy, Prefix, Strategy};
use crate::vertex::Vertex;

/// `inner`, taken with probability `q` at each use and otherwise skipped
/// (the step ends as [`Step::Terminated`], with mass 1 − q). Tridirectional
/// tracing samples its portal segments this way for a quarter of the
/// samples: the segment's density then carries the quarter, so MIS counts
/// the portal techniques as the fraction of a sample they are.
///
/// Density: q · p_inner(value).
///
/// ```
/// use aether_core::{Pcg32, RandomSequence, Sometimes, StepKind};
/// use aether_core::testing::{CameraPoint, LookDown, TestScene};
/// let scene = TestScene::open_box();
/// let (pinhole, rarely) = (CameraPoint::default(), Sometimes::new(0.25, LookDown::new(&scene)));
/// let taken = (0..1000)
///     .filter(|&i| {
///         let mut path = RandomSequence::new();
///         path.append(&pinhole).append(&rarely);
///         path.sample(&mut Pcg32::new(3, i)) == StepKind::Vertex
///     })
///     .count();
/// assert!((200..300).contains(&taken), "{taken}");
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sometimes<S> {
    q: f64,
    inner: S,
}

impl<S> Sometimes<S> {
    /// Takes `inner` with probability `q`, clamped to [0, 1].
    pub fn new(q: f64, inner: S) -> Self {
        Sometimes {
            q: q.clamp(0.0, 1.0),
            inner,
        }
    }

    /// The probability that the strategy is taken.
    #[must_use]
    pub fn probability(&self) -> f64 {
        self.q
    }

    /// The strategy taken.
    pub fn inner(&self) -> &S {
        &self.inner
    }
}

impl<V: Vertex, S: Strategy<V>> Strategy<V> for Sometimes<S> {
    fn distribution<'a>(
        &'a self,
        prefix: Prefix<'a, V>,
    ) -> impl Distribution<Value = Step<V>> + 'a {
        RussianRoulette::new(self.q, self.inner.distribution(prefix))
    }
    fn memory(&self) -> usize {
        self.inner.memory()
    }
    fn depth_class(&self, prefix_len: usize) -> usize {
        self.inner.depth_class(prefix_len)
    }
    fn instance(&self) -> u64 {
        self.inner.instance()
    }
}

impl<V: Vertex, S: PairStrategy<V>> PairStrategy<V> for Sometimes<S> {
    fn distribution<'a>(
        &'a self,
        prefix: Prefix<'a, V>,
    ) -> impl Distribution<Value = Step<(V, V)>> + 'a {
        RussianRoulette::new(self.q, self.inner.distribution(prefix))
    }
    fn memory(&self) -> usize {
        self.inner.memory()
    }
    fn depth_class(&self, prefix_len: usize) -> usize {
        self.inner.depth_class(prefix_len)
    }
    fn instance(&self) -> u64 {
        self.inner.instance()
    }
}
