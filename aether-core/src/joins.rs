//! MIS weights of bidirectional path tracing's joins, from the two sampled
//! subpaths: a vertex's density under the other side's strategies, given
//! vertices of its own subpath, is evaluated once per depth class and kept
//! by the vertex for every join; only the densities whose conditioning
//! vertices lie across the join are evaluated per join. The same densities
//! as [`weight_of_split`](crate::weight_of_split) over
//! [`Split::bidirectional`](crate::Split::bidirectional)'s techniques, found
//! without hashing a factor key or walking a path's bookkeeping.

use smallvec::SmallVec;

use crate::density::{Density, Measure, PathDensity};
use crate::join::Join;
use crate::kept::{CAMERA, DIRECT, Kept, LIGHT, STORE, Store, VARYING, View, chain, entry, factor};
use crate::mis::Heuristic;
use crate::recycle::Recycle;
use crate::sequence::{RandomSequence, Span, fresh_id};
use crate::split::{Split, Splits, samples_of, weight_of_split, weights_of_split_variants};
use crate::strategy::StrategyRef;
use crate::vertex::Vertex;

/// The MIS weights of the paths that join the first s vertices of a camera
/// subpath (`eye`) to the first t of a light subpath, read backwards, for
/// every (s, t) of one sample: the weights
/// [`weight_of_split`](crate::weight_of_split) gives them against
/// [`Split::bidirectional`](crate::Split::bidirectional)'s techniques, with
/// the strategy lists `camera` (which sampled `eye`) and `light` (which
/// sampled the light subpath), the `direct` step for a single light vertex,
/// a `portal` pair (tridirectional tracing), and the sample counts
/// `splats` and `through_lens`.
///
/// A join with t = 1 ends on a vertex the direct step sampled from the
/// eye's vertices (a light sample), not on the light subpath's first.
/// Without a portal, and with strategies that sample one vertex and
/// remember at most two, a join's weight comes from the densities the
/// subpaths' vertices keep ([`shortcuts`](Self::shortcuts) counts them);
/// otherwise from `weight_of_split`, its factors cached for the sample.
///
/// ```
/// use aether_core::testing::{BidirectionalFixture, TestScene};
/// use aether_core::{DynStrategy, Heuristic, Joins, Pcg32, RandomSequence, StrategyRef};
///
/// let scene = TestScene::open_box();
/// let f = BidirectionalFixture::new(&scene);
/// let mut rng = Pcg32::new(4, 0);
/// let (mut eye, mut light) = (RandomSequence::new(), RandomSequence::new());
/// eye.append(&f.camera).append(&f.look).repeat(&f.bounce, 4, &mut rng);
/// light.append(&f.light).repeat(&f.bounce, 3, &mut rng);
/// let camera = [&f.camera as &dyn DynStrategy<_>, &f.look, &f.bounce].map(StrategyRef::One);
/// let lights = [&f.light as &dyn DynStrategy<_>, &f.bounce].map(StrategyRef::One);
/// let subpaths = (&eye, &light);
/// let mut joins = Joins::new(subpaths, (&camera, &lights), (None, None), (1.0, false), Heuristic::POWER);
/// // Two camera vertices joined to two light vertices.
/// if eye.len() >= 2 && light.len() >= 2 {
///     let path = eye.slice(0..2).concat(&light.slice(0..2).reversed());
///     let (w, p) = joins.weight(2, &path);
///     assert!((0.0..=1.0).contains(&w) && p.value() >= 0.0);
///     assert_eq!(joins.shortcuts(), 1);
/// }
/// ```
pub struct Joins<'p, 's, V: Recycle> {
    eye: &'p RandomSequence<'s, V>,
    light: &'p RandomSequence<'s, V>,
    camera: SmallVec<[StrategyRef<'s, V>; 4]>,
    emitter: SmallVec<[StrategyRef<'s, V>; 4]>,
    direct: Option<StrategyRef<'s, V>>,
    splats: f64,
    through_lens: bool,
    heuristic: Heuristic,
    /// The portal pair strategy of tridirectional tracing's techniques.
    portal: Option<StrategyRef<'s, V>>,
    /// Names these joins' densities in the thread's store.
    id: u64,
    /// True if there is no portal and every strategy samples one vertex
    /// and remembers at most two: what the densities kept by vertices
    /// need.
    short: bool,
    /// Weights found from the kept densities so far.
    shortcuts: usize,
    /// The last joined path built for `weight_of_split`.
    built: std::cell::RefCell<RandomSequence<'s, V>>,
}

impl<V: Recycle> std::fmt::Debug for Joins<'_, '_, V> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Joins")
            .field("camera", &self.camera)
            .field("light", &self.emitter)
            .field("direct", &self.direct)
            .finish_non_exhaustive()
    }
}

impl<'p, 's, V: Vertex> Joins<'p, 's, V> {
    /// The joins of the subpaths `(eye, light)`, sampled by the strategy
    /// lists `(camera, light)` (the last entry of each repeating), with
    /// the `direct` step for single light vertices, the sample counts
    /// `(splats, through_lens)` of [`Split::bidirectional`](crate::Split::bidirectional),
    /// and `heuristic`.
    #[must_use]
    pub fn new(
        (eye, light): (&'p RandomSequence<'s, V>, &'p RandomSequence<'s, V>),
        (camera, emitter): (&[StrategyRef<'s, V>], &[StrategyRef<'s, V>]),
        (direct, portal): (Option<StrategyRef<'s, V>>, Option<StrategyRef<'s, V>>),
        (splats, through_lens): (f64, bool),
        heuristic: Heuristic,
    ) -> Self {
        let short = portal.is_none()
            && camera
                .iter()
                .chain(emitter)
                .chain(&direct)
                .all(|s| s.arity() == 1 && s.memory() <= 2);
        Joins {
            eye,
            light,
            camera: SmallVec::from_slice(camera),
            emitter: SmallVec::from_slice(emitter),
            direct,
            splats,
            through_lens,
            heuristic,
            portal,
            id: fresh_id(),
            short,
            shortcuts: 0,
            built: std::cell::RefCell::new(RandomSequence::new()),
        }
    }

    /// The MIS weight of `path` against every technique of
    /// [`Split::bidirectional`](crate::Split::bidirectional) for its
    /// length, `own` being the one that sampled it, and its density under
    /// `own`: s for the eye's first s vertices joined to the light
    /// subpath's first `path.len() − s`, read backwards (for t = 1, to a
    /// vertex the direct step sampled); with a portal, n + k for the eye's
    /// first k, a portal segment, and the rest from the light.
    pub fn weight(&mut self, own: usize, path: &RandomSequence<'_, V>) -> (f64, PathDensity) {
        self.weigh_any(own, path, None)[0]
    }

    /// As [`weight`](Self::weight) once for each strategy of `variants` in
    /// place of the camera-side entry `at`: the per-pixel weights of a
    /// join splatted to several pixels, as
    /// [`weights_of_split_variants`](crate::weights_of_split_variants)
    /// gives them (the camera's own entry as the one variant is the plain
    /// weight).
    pub fn weights(
        &mut self,
        own: usize,
        path: &RandomSequence<'_, V>,
        at: usize,
        variants: &[StrategyRef<'_, V>],
    ) -> SmallVec<[(f64, PathDensity); 16]> {
        let variants = self.varying(at, variants);
        self.weigh_any(own, path, variants)
    }

    /// `variants` in place of the camera-side entry `at`, or none if the
    /// one variant is that entry (the plain weight).
    fn varying<'v>(
        &self,
        at: usize,
        variants: &'v [StrategyRef<'v, V>],
    ) -> Option<(usize, &'v [StrategyRef<'v, V>])> {
        match (variants, self.camera.get(at)) {
            ([v], Some(c)) if v.same(c) => None,
            _ => Some((at, variants)),
        }
    }

    /// As [`weights`](Self::weights) for `join`, without building the
    /// path where the kept densities serve (a join of these joins' own
    /// subpaths, no portal); `own` indexes techniques as there.
    pub fn join_weights(
        &mut self,
        join: &Join<'_, 's, V>,
        own: usize,
        at: usize,
        variants: &[StrategyRef<'_, V>],
    ) -> SmallVec<[(f64, PathDensity); 16]> {
        let variants = self.varying(at, variants);
        self.weigh_join(join, own, variants)
    }

    /// As [`weight`](Self::weight) for `join`, as
    /// [`join_weights`](Self::join_weights) weighs it with the camera's own
    /// strategies: what a join weighed for its own pixel needs, without a
    /// list of variants to build and compare (comparing the one variant
    /// with the camera's own entry read back a pointer just stored, a
    /// stall of 6.5 % of BDPT's join weighing by perf).
    pub fn join_weight(&mut self, join: &Join<'_, 's, V>, own: usize) -> (f64, PathDensity) {
        self.weigh_join(join, own, None)[0]
    }

    fn weigh_join(
        &mut self,
        join: &Join<'_, 's, V>,
        own: usize,
        variants: Option<(usize, &[StrategyRef<'_, V>])>,
    ) -> SmallVec<[(f64, PathDensity); 16]> {
        let same = |a: &RandomSequence<'s, V>, b: &RandomSequence<'s, V>| std::ptr::eq(a, b);
        let ours = (join.n == 0 || same(join.head, self.eye))
            && (join.t < 2 || join.lamp.is_some() || same(join.light, self.light));
        if ours && own == join.n && variants.is_none_or(|(at, _)| own <= at) {
            let lamp = join.lamp.map(|l| l.density);
            if let Some(w) = self.weigh_view(&join.view(), lamp, variants) {
                self.shortcuts += 1;
                return w;
            }
        }
        // The joined path, its camera side kept for the next join of the
        // same one (building it for each join cost tridirectional tracing 8
        // % of its speed).
        let mut built = self.built.borrow_mut();
        if built.same_prefix(join.head, join.n) {
            built.truncate(join.n);
        } else {
            built.clear().extend_from(join.head, 0..join.n, false);
        }
        join.extend(&mut built, self.direct);
        self.by_splits(own, &built, variants)
    }

    /// How many weights came from the densities the vertices keep (the
    /// others, with a portal or long memories, from
    /// [`weights_of_split_variants`](crate::weights_of_split_variants)).
    #[must_use]
    pub fn shortcuts(&self) -> usize {
        self.shortcuts
    }

    fn weigh_any(
        &mut self,
        own: usize,
        path: &RandomSequence<'_, V>,
        variants: Option<(usize, &[StrategyRef<'_, V>])>,
    ) -> SmallVec<[(f64, PathDensity); 16]> {
        let n = path.len();
        if own <= n && variants.is_none_or(|(at, _)| own <= at) {
            if let Some(w) = self.weigh(own, path, variants) {
                self.shortcuts += 1;
                return w;
            }
        }
        self.by_splits(own, path, variants)
    }

    /// The weights of `path` from `weight_of_split` over the techniques'
    /// splits, with the sample's factors cached with its densities (none
    /// for a weight inside a weight, which finds the store in use).
    fn by_splits(
        &self,
        own: usize,
        path: &RandomSequence<'_, V>,
        variants: Option<(usize, &[StrategyRef<'_, V>])>,
    ) -> SmallVec<[(f64, PathDensity); 16]> {
        let mut splits = Splits::new();
        let (n, direct, portal) = (path.len(), self.direct, self.portal);
        let counts = (self.splats, self.through_lens);
        Split::bidirectional(n, direct, portal, counts.0, counts.1, &mut splits);
        let (camera, light, h) = (&self.camera[..], &self.emitter[..], self.heuristic);
        STORE.with(|store| {
            let mut store = store.try_borrow_mut().ok();
            if let Some(store) = store.as_mut() {
                self.take(store);
            }
            let cache = store.as_mut().map(|s| &mut s.cache);
            match variants {
                None => {
                    let mut w = SmallVec::new();
                    w.push(weight_of_split(path, camera, light, &splits, own, h, cache));
                    w
                }
                Some((at, v)) => {
                    weights_of_split_variants(path, camera, light, &splits, own, h, cache, at, v)
                }
            }
        })
    }

    fn weigh(
        &mut self,
        s: usize,
        path: &RandomSequence<'_, V>,
        variants: Option<(usize, &[StrategyRef<'_, V>])>,
    ) -> Option<SmallVec<[(f64, PathDensity); 16]>> {
        let (n, x) = (path.len(), path.vertices());
        if !path.is_complete() || n == 0 {
            let zero = PathDensity::ONE.times(Density::ZERO);
            let count = variants.map_or(1, |v| v.1.len());
            return Some(SmallVec::from_elem((0.0, zero), count));
        }
        let view = View {
            eye: &x[..s],
            tail: &x[s..],
            in_path_order: true,
        };
        // A light sample's density, as the direct step recorded it.
        let lamp = self
            .direct
            .filter(|_| n - s == 1)
            .map(|d| path.factor(&Span::new(n - 1, 1, Some(d), false, 0), None));
        self.weigh_view(&view, lamp, variants)
    }

    /// The weights of the join `view`, whose light sample (if it ends on
    /// one) has the direct step's density `lamp`, from the vertices' kept
    /// densities; `None` where they do not serve.
    fn weigh_view(
        &mut self,
        view: &View<'_, V>,
        lamp: Option<Density>,
        variants: Option<(usize, &[StrategyRef<'_, V>])>,
    ) -> Option<SmallVec<[(f64, PathDensity); 16]>> {
        if !self.short {
            return None;
        }
        // Another joins' store (a weight inside a weight) is left alone.
        STORE.with(|store| {
            let mut store = store.try_borrow_mut().ok()?;
            self.take(&mut store);
            self.weigh_in(&mut store, view, lamp, variants)
        })
    }

    /// Makes `store` these joins' if it is another's: the subpaths'
    /// chains, nothing kept.
    fn take(&self, store: &mut Store) {
        if store.owner == self.id {
            return;
        }
        store.owner = self.id;
        store.cache.clear();
        chain(self.eye, &self.camera, &mut store.eye_chain);
        chain(self.light, &self.emitter, &mut store.light_chain);
        store.eye_kept.clear();
        store.eye_kept.resize(self.eye.len(), Kept::EMPTY);
        store.light_kept.clear();
        store.light_kept.resize(self.light.len(), Kept::EMPTY);
    }

    fn weigh_in(
        &self,
        store: &mut Store,
        view: &View<'_, V>,
        lamp: Option<Density>,
        variants: Option<(usize, &[StrategyRef<'_, V>])>,
    ) -> Option<SmallVec<[(f64, PathDensity); 16]>> {
        let (s, n) = (view.s(), view.len());
        let t = n - s;
        if s >= store.eye_chain.len() || (t >= 2 && t >= store.light_chain.len()) {
            return None;
        }
        debug_assert!(
            (0..s).all(|i| view.at(i).position() == self.eye.vertices()[i].position())
                && (t < 2
                    || (s..n).all(|i| {
                        view.at(i).position() == self.light.vertices()[n - 1 - i].position()
                    })),
            "a join is the eye's first s vertices and the light subpath's first t, reversed"
        );
        let Store {
            eye_kept,
            light_kept,
            camera,
            light,
            suffix,
            light_chain,
            ..
        } = store;
        let kept = &mut (&mut eye_kept[..], &mut light_kept[..]);
        // Camera-side densities of the vertices after the eye's, and
        // light-side ones of the eye's (and of a light sample's).
        // Filled by extending, not pushing: one reservation per list, not a
        // check of its capacity per vertex.
        camera.clear();
        camera.extend((s..n).map(|i| {
            let varies = variants.is_some_and(|(at, _)| at == i);
            match entry(&self.camera, i) {
                Some((k, strategy)) if !varies => {
                    factor(kept, view, i, strategy, CAMERA | k, false)
                }
                // A varying entry is evaluated per variant below.
                _ => Density::ZERO,
            }
        }));
        // Read up to the light subpath's vertices (all of a join ending on
        // a light sample).
        let light_side = if t == 1 { n } else { s };
        light.clear();
        light.extend(
            (0..light_side).map(|i| match entry(&self.emitter, n - 1 - i) {
                Some((k, strategy)) => factor(kept, view, i, strategy, LIGHT | k, true),
                None => Density::ZERO,
            }),
        );
        // The direct step's density of the last vertex: recorded for a
        // light sample, else kept or evaluated.
        let direct = self.direct.map(|d| match (t, lamp) {
            (1, Some(density)) => density,
            _ => factor(kept, view, n - 1, d, DIRECT, false),
        });
        // The light subpath's own vertices carry their product; the eye's
        // multiply theirs in, last first.
        suffix.clear();
        suffix.resize(n + 1, PathDensity::ONE);
        for k in light_side..n {
            suffix[k] = light_chain[n - k];
        }
        for k in (0..light_side).rev() {
            suffix[k] = suffix[k + 1].times(light[k]);
        }
        let mut weights = SmallVec::new();
        let Some((at, variants)) = variants else {
            weights.push(self.weigh_one(store, s, direct));
            return Some(weights);
        };
        for &v in variants {
            if at < n {
                let kept = &mut (&mut store.eye_kept[..], &mut store.light_kept[..]);
                store.camera[at - s] = factor(kept, view, at, v, VARYING, false);
            }
            weights.push(self.weigh_one(store, s, direct));
        }
        Some(weights)
    }

    /// The weight of technique `s` and its density, from the camera-side
    /// densities of the vertices after the eye's and the light-side
    /// products in `store`, and the direct step's density of the last
    /// vertex.
    fn weigh_one(&self, store: &Store, s: usize, direct: Option<Density>) -> (f64, PathDensity) {
        let Store {
            eye_chain,
            camera,
            suffix,
            ..
        } = store;
        let n = suffix.len() - 1;
        // Technique k's density: the eye's first k vertices as they were
        // sampled, the camera side's densities of the rest up to the light
        // subpath's, then the light side's (the direct step's for a light
        // sample).
        let join = |k: usize, prefix: PathDensity| match direct {
            Some(d) if k + 1 == n => prefix.times(d),
            _ => prefix.times_path(suffix[k]),
        };
        // Each technique's samples, as Split::bidirectional counts them
        // (one for all but the first two).
        let counted = |k: usize, p: PathDensity| {
            let samples = match k {
                0 | 1 => samples_of(k, self.splats, self.through_lens),
                _ => return p,
            };
            if samples == 1.0 {
                p
            } else {
                p.times(Density::new(samples, Measure::Discrete))
            }
        };
        let own = join(s, eye_chain[s]);
        // Derived in turn and weighed as they come, not stored.
        let densities = (0..=n).scan(PathDensity::ONE, |prefix, k| {
            *prefix = match k {
                k if k <= s => eye_chain[k],
                k => prefix.times(camera[k - 1 - s]),
            };
            Some(counted(k, join(k, *prefix)))
        });
        (self.heuristic.weight_among(counted(s, own), densities), own)
    }
}
