//! The densities that the vertices of one sample's two subpaths keep for
//! [`Joins`](crate::Joins): each vertex's density under the other side's
//! strategies, given vertices of its own subpath, once per depth class;
//! and the density of a vertex of a join, kept or evaluated from the
//! vertices nearest it. In lists a thread reuses.

use std::cell::RefCell;

use smallvec::SmallVec;

use crate::density::{Density, PathDensity};
use crate::mis::DensityCache;
use crate::sequence::{RandomSequence, count_evaluation};
use crate::strategy::{Prefix, StrategyRef};
use crate::vertex::Vertex;

/// Where a strategy sits among a join's techniques, as densities kept by a
/// vertex name it: an entry of the camera-side or light-side list, or the
/// direct step.
pub(crate) const CAMERA: u32 = 0;
pub(crate) const LIGHT: u32 = 1 << 30;
pub(crate) const DIRECT: u32 = 2 << 30;
/// A camera-side entry replaced per pixel: never kept.
pub(crate) const VARYING: u32 = 3 << 30;

/// The densities a vertex keeps: (strategy tag, depth class, density).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Kept {
    entries: [(u32, u32, Density); 3],
    len: u8,
}

impl Kept {
    pub(crate) const EMPTY: Kept = Kept {
        entries: [(0, 0, Density::ZERO); 3],
        len: 0,
    };

    fn get(&self, tag: u32, class: u32) -> Option<Density> {
        let kept = &self.entries[..usize::from(self.len)];
        kept.iter()
            .find(|e| e.0 == tag && e.1 == class)
            .map(|e| e.2)
    }

    /// Keeps `d` if there is room (a vertex needs at most one per depth
    /// class a strategy distinguishes; evaluating again is only slower).
    fn keep(&mut self, tag: u32, class: u32, d: Density) {
        if let Some(e) = self.entries.get_mut(usize::from(self.len)) {
            *e = (tag, class, d);
            self.len += 1;
        }
    }
}

/// What the joins of one sample keep between weights, in lists a thread
/// reuses (inline lists per join allocated 0.85 times per sample of BDPT in
/// the built-in box, whose paths have no length limit; and held by the
/// joins, their 3 KB were copied with them).
#[derive(Debug, Default)]
pub(crate) struct Store {
    /// The joins whose densities these are (0: none).
    pub(crate) owner: u64,
    /// Entry k: the recorded density of the eye's first k vertices (as far
    /// as the eye records them), and of the light subpath's.
    pub(crate) eye_chain: Vec<PathDensity>,
    pub(crate) light_chain: Vec<PathDensity>,
    /// What each vertex of either subpath keeps.
    pub(crate) eye_kept: Vec<Kept>,
    pub(crate) light_kept: Vec<Kept>,
    /// For the join being weighed: camera-side densities of the vertices
    /// after the eye's, light-side ones of the eye's (and of a light
    /// sample), and the density of vertices k.. from the light.
    pub(crate) camera: Vec<Density>,
    pub(crate) light: Vec<Density>,
    pub(crate) suffix: Vec<PathDensity>,
    /// Factors of the joins the densities above cannot weigh.
    pub(crate) cache: DensityCache,
}

thread_local! {
    pub(crate) static STORE: RefCell<Store> = RefCell::new(Store::default());
}

/// Which subpath a vertex of a join comes from.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(crate) enum Place {
    Eye(usize),
    Light(usize),
    /// The last vertex of a join sampled by the direct step.
    Lamp,
}

/// The entry of `list` for position `i` (the last one repeats), with its index.
pub(crate) fn entry<'s, V>(
    list: &[StrategyRef<'s, V>],
    i: usize,
) -> Option<(u32, StrategyRef<'s, V>)> {
    let k = i.min(list.len().checked_sub(1)?);
    Some((k as u32, list[k]))
}

/// Entry k of the chain of `path` under `list`: its first k vertices'
/// recorded density, for as long as the path records one.
pub(crate) fn chain<V: Vertex>(
    path: &RandomSequence<'_, V>,
    list: &[StrategyRef<'_, V>],
    out: &mut Vec<PathDensity>,
) {
    out.clear();
    out.push(PathDensity::ONE);
    for i in 0..path.len() {
        match path.chain(i, entry(list, i).map(|e| e.1)) {
            Some(p) => out.push(p),
            None => break,
        }
    }
}

/// Where vertex `i` of the join of `s` eye vertices and `n − s` others comes from.
pub(crate) fn place(s: usize, n: usize, i: usize) -> Place {
    match i {
        i if i < s => Place::Eye(i),
        _ if n - s == 1 => Place::Lamp,
        i => Place::Light(n - 1 - i),
    }
}

/// The vertices of a join: the eye's first `s`, then `tail`, the other
/// `n − s` (a light sample, or the light subpath's first vertices, read
/// backwards from the join unless `in_path_order`).
#[derive(Clone, Copy)]
pub(crate) struct View<'a, V> {
    pub(crate) eye: &'a [V],
    pub(crate) tail: &'a [V],
    pub(crate) in_path_order: bool,
}

impl<'a, V: Clone> View<'a, V> {
    pub(crate) fn s(&self) -> usize {
        self.eye.len()
    }

    pub(crate) fn len(&self) -> usize {
        self.eye.len() + self.tail.len()
    }

    /// Vertex `i` in path order.
    pub(crate) fn at(&self, i: usize) -> &'a V {
        let (s, n) = (self.s(), self.len());
        match i {
            i if i < s => &self.eye[i],
            i if self.in_path_order => &self.tail[i - s],
            i => &self.tail[n - 1 - i],
        }
    }

    /// The `m` vertices nearest vertex `i` (before it, or after it if
    /// `reversed`), as a prefix of `len` vertices: a slice of one subpath
    /// where they lie in one, else copied into `copy`.
    fn nearest<'c>(
        &self,
        (i, m, reversed): (usize, usize, bool),
        len: usize,
        copy: &'c mut SmallVec<[V; 2]>,
    ) -> Prefix<'c, V>
    where
        'a: 'c,
    {
        let (s, n) = (self.s(), self.len());
        let range = if reversed { i + 1..i + 1 + m } else { i - m..i };
        let path_order = !reversed;
        if range.end <= s {
            return Prefix::nearest(&self.eye[range], reversed, len);
        }
        if range.start >= s && self.in_path_order {
            return Prefix::nearest(&self.tail[range.start - s..range.end - s], reversed, len);
        }
        if range.start >= s {
            // Read backwards: the order flips.
            let tail = &self.tail[n - range.end..n - range.start];
            return Prefix::nearest(tail, path_order, len);
        }
        // Across the join: copied in path order, which is nearest first
        // for a reversed step.
        copy.clear();
        // Pushed one by one: collected through an iterator, each vertex
        // went through the stack on its way.
        for j in range {
            copy.push(self.at(j).clone());
        }
        Prefix::nearest(copy, reversed, len)
    }
}

/// The density of vertex `i` of the join `view` under `strategy` (entry
/// `tag` of its list), forward or `reversed`: kept by the vertex if it and
/// the vertices the strategy remembers are of one subpath, and evaluated
/// from the nearest vertices otherwise. A varying camera entry (tagged
/// with no entry index) is never kept. The lookup inlines into the
/// join's loops; an evaluation is called (a call with its registers saved
/// cost every kept density about 40 instructions).
#[inline(always)]
pub(crate) fn factor<V: Vertex>(
    (eye_kept, light_kept): &mut (&mut [Kept], &mut [Kept]),
    view: &View<'_, V>,
    i: usize,
    strategy: StrategyRef<'_, V>,
    tag: u32,
    reversed: bool,
) -> Density {
    let (s, n) = (view.s(), view.len());
    let len = if reversed { n - 1 - i } else { i };
    let m = strategy.memory().min(len);
    // The strategy remembers vertices first..first + m: kept by vertex i
    // if they lie on its side of the join.
    let first = if reversed { i + 1 } else { i - m };
    let kept = match place(s, n, i) {
        _ if tag == VARYING => None,
        Place::Eye(k) if first + m <= s => eye_kept.get_mut(k),
        Place::Light(k) if first >= s => light_kept.get_mut(k),
        _ => None,
    };
    // The depth class is asked only of a density that can be kept: about
    // half of a join's are evaluated across it.
    match kept {
        Some(k) => {
            let class = strategy.depth_class(len) as u32;
            match k.get(tag, class) {
                Some(d) => d,
                None => {
                    let d = evaluate(view, (i, m, reversed), len, strategy);
                    k.keep(tag, class, d);
                    d
                }
            }
        }
        None => evaluate(view, (i, m, reversed), len, strategy),
    }
}

/// The density of vertex `i` of `view` under `strategy`, which remembers
/// the `m` vertices nearest it (before it, or after it if `reversed`), of
/// a prefix of `len`.
#[inline(never)]
fn evaluate<V: Vertex>(
    view: &View<'_, V>,
    (i, m, reversed): (usize, usize, bool),
    len: usize,
    strategy: StrategyRef<'_, V>,
) -> Density {
    count_evaluation();
    let mut copy = SmallVec::new();
    let prefix = view.nearest((i, m, reversed), len, &mut copy);
    strategy.density_of(prefix, std::slice::from_ref(view.at(i)))
}
