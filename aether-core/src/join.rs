//! A join of two subpaths described by its parts, not built: the camera
//! side's first vertices, then a light sample or the light subpath's first
//! vertices read backwards; what [`Joins`](crate::Joins) weighs.

use crate::kept::View;
use crate::last_step::Aside;
use crate::recycle::Recycle;
use crate::sequence::RandomSequence;
use crate::strategy::{Produced, StrategyRef};
use crate::vertex::Vertex;

/// A path joined from the first `n` vertices of a camera-side sequence
/// (`head`: a camera subpath, or one spliced with a portal segment) and
/// either a light sample (`lamp`, t = 1) or the first `t` vertices of a
/// light subpath, read backwards: what
/// [`Joins::join_weights`](crate::Joins::join_weights) weighs without
/// building the path.
pub struct Join<'a, 's, V: Recycle> {
    pub(crate) head: &'a RandomSequence<'s, V>,
    pub(crate) n: usize,
    pub(crate) light: &'a RandomSequence<'s, V>,
    pub(crate) t: usize,
    pub(crate) lamp: Option<&'a Aside<V>>,
}

impl<V: Recycle> Clone for Join<'_, '_, V> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<V: Recycle> Copy for Join<'_, '_, V> {}

impl<V: Recycle> std::fmt::Debug for Join<'_, '_, V> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (s, t, lamp) = (self.n, self.t, self.lamp.is_some());
        write!(f, "Join {{ s: {s}, t: {t}, light sample: {lamp} }}")
    }
}

impl<'a, 's, V: Vertex> Join<'a, 's, V> {
    /// `head`'s first `n` vertices, then `lamp` if given (and t is 1),
    /// else `light`'s first `t` read backwards.
    #[must_use]
    pub fn new(
        (head, n): (&'a RandomSequence<'s, V>, usize),
        (light, t): (&'a RandomSequence<'s, V>, usize),
        lamp: Option<&'a Aside<V>>,
    ) -> Self {
        Join {
            head,
            n,
            light,
            t: if lamp.is_some() { 1 } else { t },
            lamp,
        }
    }

    /// The number of vertices.
    #[must_use]
    pub fn len(&self) -> usize {
        self.n + self.t
    }

    /// True if the join has no vertices.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The camera-side vertices, then the rest.
    pub(crate) fn view(&self) -> View<'a, V> {
        View {
            eye: &self.head.vertices()[..self.n],
            tail: match self.lamp {
                Some(l) => std::slice::from_ref(&l.vertex),
                None => &self.light.vertices()[..self.t],
            },
            in_path_order: false,
        }
    }

    /// Vertex `i`, from the camera end.
    ///
    /// # Panics
    /// If `i` is not below [`len`](Self::len).
    #[must_use]
    pub fn vertex(&self, i: usize) -> &'a V {
        self.view().at(i)
    }

    /// The vertices, from the camera end.
    pub fn vertices(&self) -> impl Iterator<Item = &'a V> + '_ {
        (0..self.len()).map(|i| self.vertex(i))
    }

    /// Appends to `path`, the camera side, the rest of the joined path,
    /// with the strategies and recorded densities of its parts (the light
    /// sample's by `direct`).
    pub(crate) fn extend(
        &self,
        path: &mut RandomSequence<'s, V>,
        direct: Option<StrategyRef<'s, V>>,
    ) {
        match (self.lamp, direct) {
            (Some(l), Some(d)) => {
                let mut out = Produced::new();
                out.push(l.vertex.clone());
                path.push_step(d, &mut out, l.density);
            }
            // A light sample with no direct step to have sampled it: given.
            (Some(l), None) => {
                path.extend_from(&RandomSequence::given([l.vertex.clone()]), 0..1, false);
            }
            (None, _) => {
                path.extend_from(self.light, 0..self.t, true);
            }
        }
    }
}
