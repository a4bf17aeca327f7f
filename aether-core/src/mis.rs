//! Multiple importance sampling: heuristics and `combine`.

use std::cell::RefCell;

use smallvec::SmallVec;

use crate::density::{Density, Measure, PathDensity};
use crate::sequence::{FactorKey, RandomSequence, Span};
use crate::strategy::StrategyRef;
use crate::vertex::Vertex;

/// MIS weights for up to this many candidates are returned inline.
pub type Weights = SmallVec<[f64; 16]>;

/// How MIS weighs the strategies that could have produced a path.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Heuristic {
    /// wᵢ = pᵢ / Σⱼ pⱼ.
    Balance,
    /// wᵢ = pᵢ^β / Σⱼ pⱼ^β.
    Power(f64),
}

impl Heuristic {
    /// Veach's power heuristic with β = 2.
    pub const POWER: Heuristic = Heuristic::Power(2.0);

    /// The weight of candidate `i` given the densities of its path under
    /// every candidate's strategies (`densities[i]` is its own).
    ///
    /// Dirac order comes first: a strategy whose density has more Dirac
    /// factors takes all the weight. Zero and non-finite densities are
    /// skipped. Computed as 1 / Σⱼ (pⱼ/pᵢ)^β, in f64.
    #[must_use]
    pub fn weight(self, densities: &[PathDensity], i: usize) -> f64 {
        let own = densities[i];
        if own.is_zero() {
            return 0.0;
        }
        let mut sum = 0.0;
        for &p in densities {
            let r = own.ratio_to(p);
            if r == f64::INFINITY {
                return 0.0;
            }
            sum += match self {
                Heuristic::Balance => r,
                Heuristic::Power(2.0) => r * r,
                Heuristic::Power(beta) => r.powf(beta),
            };
        }
        if sum.is_finite() && sum > 0.0 {
            1.0 / sum
        } else {
            0.0
        }
    }
}

/// A generation-stamped open-addressing table of density factors, reused
/// across calls so that steady-state MIS allocates nothing.
#[derive(Debug, Default)]
pub(crate) struct FactorCache {
    entries: Vec<(u32, FactorKey, Density)>,
    generation: u32,
    len: usize,
}

impl FactorCache {
    fn begin(&mut self) {
        self.generation = self.generation.wrapping_add(1);
        if self.generation == 0 {
            self.entries.iter_mut().for_each(|e| e.0 = 0);
            self.generation = 1;
        }
        self.len = 0;
        if self.entries.is_empty() {
            self.entries = vec![(0, FactorKey::EMPTY, Density::zero(Measure::Area)); 256];
        }
    }

    fn mask(&self) -> usize {
        self.entries.len() - 1
    }

    pub(crate) fn get(&self, key: &FactorKey) -> Option<Density> {
        if self.entries.is_empty() {
            return None;
        }
        let mut i = key.hash64() as usize & self.mask();
        loop {
            let (g, k, d) = &self.entries[i];
            if *g != self.generation {
                return None;
            }
            if k == key {
                return Some(*d);
            }
            i = (i + 1) & self.mask();
        }
    }

    pub(crate) fn insert(&mut self, key: FactorKey, density: Density) {
        if self.entries.is_empty() {
            self.begin();
        }
        if 2 * (self.len + 1) > self.entries.len() {
            self.grow();
        }
        let mut i = key.hash64() as usize & self.mask();
        while self.entries[i].0 == self.generation {
            if self.entries[i].1 == key {
                return;
            }
            i = (i + 1) & self.mask();
        }
        self.entries[i] = (self.generation, key, density);
        self.len += 1;
    }

    fn grow(&mut self) {
        let size = 2 * self.entries.len().max(128);
        let old = std::mem::replace(
            &mut self.entries,
            vec![(0, FactorKey::EMPTY, Density::zero(Measure::Area)); size],
        );
        self.len = 0;
        for (g, k, d) in old {
            if g == self.generation {
                self.insert(k, d);
            }
        }
    }
}

/// Density factors kept between MIS weights of different paths of one
/// sample, so that the densities that BDPT's connections share (a camera
/// vertex's reverse density given the camera vertices after it, say) are
/// evaluated once per sample rather than once per connection.
///
/// Factors are keyed by strategy (its address, type and
/// [`instance`](crate::Strategy::instance)), depth class, and the
/// identities of the target and conditioning vertices. Vertex identities
/// are never reused, but addresses are: between two
/// [`clear`](Self::clear)s, no strategy may be replaced at its address by
/// a different one of the same type and instance (clear once per sample,
/// and give strategies made in turn, like one per pixel, distinct instances).
///
/// ```
/// use aether_core::DensityCache;
/// let mut cache = DensityCache::new();
/// cache.clear(); // at the start of each sample
/// ```
#[derive(Debug, Default)]
pub struct DensityCache(FactorCache);

impl DensityCache {
    /// An empty cache.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// Forgets every factor, keeping the storage.
    pub fn clear(&mut self) {
        self.0.begin();
    }
}

/// Scratch reused by every `combine` on a thread.
#[derive(Debug, Default)]
struct Scratch {
    cache: FactorCache,
    densities: Vec<PathDensity>,
    /// For each candidate j > 0, the steps it has and candidate j − 1 has not
    /// (`added`), and the reverse (`removed`), as ranges into `spans`.
    diffs: Vec<(u32, u32, u32, u32)>,
    spans: Vec<SpanRecord>,
}

/// A step stored without lifetimes: candidate index and position, so that
/// the scratch can live in a thread-local.
#[derive(Clone, Copy, Debug)]
struct SpanRecord {
    candidate: u32,
    index: u32,
}

thread_local! {
    static SCRATCH: RefCell<Scratch> = RefCell::new(Scratch::default());
}

/// The MIS weight of each candidate path that one sample produced.
///
/// `candidates[i]` is a path together with the strategies that sampled it.
/// Its weight uses the density of its vertices under every candidate's
/// strategies (candidates of another length give zero). A candidate whose
/// sampling stopped early (a miss, Russian roulette) gets weight zero but
/// still counts as a technique for the others. Densities are
/// cached by (strategy, depth, target and conditioning vertices), so a
/// vertex shared by several candidates, such as a camera-subpath vertex in
/// BDPT, has its forward and reverse densities evaluated once; each
/// candidate's densities under all strategies then follow by multiplying in
/// and dividing out only the steps in which consecutive candidates differ
/// (Veach's ratio recursion). Order the candidates so that neighbours
/// differ little (by s in BDPT) for the cost to be linear in path length.
///
/// ```
/// use aether_core::{Heuristic, Pcg32, RandomSequence, combine};
/// use aether_core::testing::{Bounce, CameraPoint, LightSample, LookDown, TestScene};
///
/// let scene = TestScene::open_box();
/// let (camera, look, bounce, light) = (CameraPoint::default(), LookDown::new(&scene), Bounce::new(&scene), LightSample::new(&scene));
/// let mut rng = Pcg32::new(3, 0);
/// let mut eye = RandomSequence::new();
/// eye.append(&camera).append(&look);
/// eye.sample(&mut rng);
/// // The next vertex by BSDF sampling, or by sampling the light.
/// let (mut by_bsdf, mut by_light) = (eye.clone(), eye.clone());
/// by_bsdf.append(&bounce).sample(&mut rng);
/// by_light.append(&light).sample(&mut rng);
/// let w = combine(&[by_bsdf, by_light], Heuristic::POWER);
/// assert!(w[1] > 0.0 && w.iter().all(|w| (0.0..=1.0).contains(w)));
/// ```
pub fn combine<V: Vertex>(candidates: &[RandomSequence<'_, V>], heuristic: Heuristic) -> Weights {
    SCRATCH.with(|s| match s.try_borrow_mut() {
        Ok(mut scratch) => combine_with(candidates, heuristic, &mut scratch),
        Err(_) => combine_with(candidates, heuristic, &mut Scratch::default()),
    })
}

fn combine_with<V: Vertex>(
    candidates: &[RandomSequence<'_, V>],
    heuristic: Heuristic,
    scratch: &mut Scratch,
) -> Weights {
    let m = candidates.len();
    let Scratch {
        cache,
        densities,
        diffs,
        spans,
    } = scratch;
    cache.begin();
    diffs.clear();
    spans.clear();
    // Each candidate's steps, then the differences between neighbours.
    let steps: SmallVec<[SmallVec<[Span<'_, V>; 16]>; 16]> =
        candidates.iter().map(|c| c.spans().collect()).collect();
    for j in 1..m {
        let a = spans.len() as u32;
        let (added, removed) = (
            &mut SmallVec::<[u32; 8]>::new(),
            &mut SmallVec::<[u32; 8]>::new(),
        );
        difference(&steps[j - 1], &steps[j], removed, added);
        spans.extend(added.iter().map(|&index| SpanRecord {
            candidate: j as u32,
            index,
        }));
        let b = spans.len() as u32;
        spans.extend(removed.iter().map(|&index| SpanRecord {
            candidate: (j - 1) as u32,
            index,
        }));
        diffs.push((a, b, b, spans.len() as u32));
    }
    let span_of = |r: &SpanRecord| steps[r.candidate as usize][r.index as usize];
    let zero = PathDensity::ONE.times(Density::zero(Measure::Area));

    let mut weights = Weights::new();
    for (i, x) in candidates.iter().enumerate() {
        if !x.is_complete() {
            weights.push(0.0);
            continue;
        }
        densities.clear();
        // The factor in the running product for the step starting at each
        // position, so that a step leaving the product is divided out
        // without being evaluated again.
        let mut current: SmallVec<[Density; 16]> =
            SmallVec::from_elem(Density::zero(Measure::Area), x.len());
        let mut running: Option<PathDensity> = None;
        for j in 0..m {
            if candidates[j].technique_len() != x.len() {
                densities.push(zero);
                running = None;
                continue;
            }
            let mut p = match running {
                Some(p) if j > 0 => p,
                _ => PathDensity::ONE,
            };
            let (added, removed) = match running {
                Some(_) if j > 0 => {
                    let (a, b, c, d) = diffs[j - 1];
                    (
                        &spans[a as usize..b as usize],
                        &spans[c as usize..d as usize],
                    )
                }
                _ => (&[][..], &[][..]),
            };
            for s in removed.iter().map(span_of) {
                p = p.divided_by(current[s.start]);
            }
            let fresh = running.is_none() || j == 0;
            let entering = added
                .iter()
                .map(span_of)
                .chain(steps[j].iter().copied().filter(|_| fresh));
            for s in entering {
                let f = x.factor(&s, Some(cache));
                current[s.start] = f;
                p = p.times(f);
            }
            running = Some(p);
            densities.push(p);
        }
        weights.push(heuristic.weight(densities, i));
    }
    weights
}

/// The steps of `a` that `b` lacks (`only_a`) and those of `b` that `a`
/// lacks (`only_b`), as indices. Steps are ordered by their first vertex
/// and do not overlap, so equal steps start at the same vertex and one
/// merge walk finds them: time linear in the number of steps.
fn difference<V>(
    a: &[Span<'_, V>],
    b: &[Span<'_, V>],
    only_a: &mut SmallVec<[u32; 8]>,
    only_b: &mut SmallVec<[u32; 8]>,
) {
    let (mut i, mut j) = (0, 0);
    while i < a.len() || j < b.len() {
        match (a.get(i), b.get(j)) {
            (Some(x), Some(y)) if x.start == y.start => {
                if x != y {
                    only_a.push(i as u32);
                    only_b.push(j as u32);
                }
                i += 1;
                j += 1;
            }
            (Some(x), Some(y)) if x.start < y.start => {
                only_a.push(i as u32);
                i += 1;
            }
            (Some(_), None) => {
                only_a.push(i as u32);
                i += 1;
            }
            _ => {
                only_b.push(j as u32);
                j += 1;
            }
        }
    }
}

/// One technique of a path sampled from both ends: the first `camera`
/// vertices by camera-side strategies, then the `middle` steps (each
/// forward or reversed: direct light sampling, a portal segment), then
/// the remaining vertices by light-side strategies, reversed.
#[derive(Clone, Debug)]
pub struct Split<'s, V> {
    /// Vertices sampled from the camera.
    pub camera: usize,
    /// Steps between the camera and light subpaths.
    pub middle: SmallVec<[(StrategyRef<'s, V>, bool); 2]>,
    /// Samples this technique takes for each sample of the others (Veach's
    /// nᵢ; MIS weighs nᵢ pᵢ): a light path that splats to any pixel is
    /// one of as many as there are pixels, each pixel's camera path one.
    pub samples: f64,
}

impl<'s, V> Split<'s, V> {
    /// `camera` vertices from the camera, then the steps `middle`, one sample.
    #[must_use]
    pub fn new(camera: usize, middle: &[(StrategyRef<'s, V>, bool)]) -> Self {
        Split {
            camera,
            middle: SmallVec::from_slice(middle),
            samples: 1.0,
        }
    }
}

impl<'s, V> Split<'s, V> {
    /// Every technique of a bidirectional sampler for paths of `n`
    /// vertices: first, for s = 0..=n, s vertices from the camera and the
    /// rest from the light (index s), with `direct` sampling the last
    /// vertex when the light side would have one; then, with a `portal`
    /// pair strategy and the share of samples that use it, for k = 1..n − 2,
    /// k from the camera, the portal's two and the rest from the light
    /// (index n + k), again with `direct` for a single light vertex. The techniques with at most one camera vertex
    /// (splatted, not sampled per pixel) take `splats` samples each; s = 0,
    /// light paths that reach the camera, is sampled only `through_lens`
    /// (a pinhole cannot be hit), and takes no samples otherwise.
    ///
    /// ```
    /// use aether_core::Split;
    /// use aether_core::testing::{LightSample, TestScene, TestVertex};
    /// let scene = TestScene::open_box();
    /// let light = LightSample::new(&scene);
    /// let direct = Some((&light as &dyn aether_core::DynStrategy<_>).into());
    /// let splits = Split::<TestVertex>::bidirectional(4, direct, None, 64.0 * 64.0, false);
    /// assert_eq!(splits.len(), 5);
    /// assert_eq!((splits[3].camera, splits[3].middle.len()), (3, 1)); // direct light sampling
    /// assert_eq!(splits[1].samples, 4096.0); // light tracing, to any of 64 × 64 pixels
    /// assert_eq!(splits[0].samples, 0.0); // no light path hits a pinhole
    /// ```
    #[must_use]
    pub fn bidirectional(
        n: usize,
        direct: Option<StrategyRef<'s, V>>,
        portal: Option<(StrategyRef<'s, V>, f64)>,
        splats: f64,
        through_lens: bool,
    ) -> SmallVec<[Self; 24]> {
        let direct = |t: usize| direct.filter(|_| t == 1).map(|d| (d, false));
        let samples = |camera: usize| match camera {
            0 if !through_lens => 0.0,
            0 | 1 => splats,
            _ => 1.0,
        };
        let bidirectional = (0..=n).map(|s| Split {
            camera: s,
            middle: direct(n - s).into_iter().collect(),
            samples: samples(s),
        });
        let through_portal = (1..n.saturating_sub(1)).filter_map(|k| {
            let (portal, rate) = portal?;
            Some(Split {
                camera: k,
                middle: [(portal, false)]
                    .into_iter()
                    .chain(direct(n - k - 2))
                    .collect(),
                samples: rate * samples(k),
            })
        });
        bidirectional.chain(through_portal).collect()
    }
}

/// The MIS weight of `path`, sampled by `splits[own]`, against every
/// technique in `splits`, and the density of `path` under its own
/// technique.
///
/// `camera[i]` samples the vertex at position i of a camera subpath and
/// `light[i]` the vertex i steps from the light end of a light subpath; the
/// last entry of each repeats (BSDF sampling from there on); an empty list
/// samples nothing (a path tracer has no light-side strategies). Each vertex's
/// camera-side and light-side densities are evaluated at most once, and
/// each technique's density is a prefix product times its middle steps
/// times a suffix product: time linear in the length of the path.
///
/// Densities recorded while the subpaths were sampled are reused, so in BDPT
/// only the densities of each subpath's vertices under the other side's
/// strategies are evaluated.
#[must_use]
pub fn weight_of_split<'s, V: Vertex>(
    path: &RandomSequence<'_, V>,
    camera: &[StrategyRef<'s, V>],
    light: &[StrategyRef<'s, V>],
    splits: &[Split<'s, V>],
    own: usize,
    heuristic: Heuristic,
    cache: Option<&mut DensityCache>,
) -> (f64, PathDensity) {
    if !path.is_complete() || own >= splits.len() {
        return (0.0, PathDensity::ONE.times(Density::zero(Measure::Area)));
    }
    let mut densities = split_densities(path, camera, light, splits, cache);
    let density = densities[own];
    count(&mut densities, splits);
    (heuristic.weight(&densities, own), density)
}

/// Each technique's density times its number of samples, as MIS weighs them.
fn counted<V>(densities: &[PathDensity], splits: &[Split<'_, V>]) -> SmallVec<[PathDensity; 24]> {
    let mut counted: SmallVec<[PathDensity; 24]> = SmallVec::from_slice(densities);
    count(&mut counted, splits);
    counted
}

/// Multiplies each technique's density by its number of samples, in place.
fn count<V>(densities: &mut [PathDensity], splits: &[Split<'_, V>]) {
    for (p, s) in densities.iter_mut().zip(splits) {
        if s.samples != 1.0 {
            *p = p.times(Density::new(s.samples, Measure::Discrete));
        }
    }
}

/// As [`weight_of_split`] once for each strategy in `variants` taking the
/// place of `camera[at]`, the strategy of the camera-side vertex `at` (not
/// the last, repeating entry of `camera`): the per-pixel weights of a
/// path splatted to several pixels, whose camera-direction strategies
/// differ by pixel. The other densities are evaluated once; each variant
/// only rescales the techniques that sample vertex `at` from the camera.
/// No variants (a splat that lands off the film) give no weights.
///
/// # Panics
/// If `at` is not below `camera.len() - 1`.
#[allow(clippy::too_many_arguments)]
pub fn weights_of_split_variants<'s, V: Vertex>(
    path: &RandomSequence<'_, V>,
    camera: &[StrategyRef<'s, V>],
    light: &[StrategyRef<'s, V>],
    splits: &[Split<'s, V>],
    own: usize,
    heuristic: Heuristic,
    mut cache: Option<&mut DensityCache>,
    at: usize,
    variants: &[StrategyRef<'s, V>],
) -> SmallVec<[(f64, PathDensity); 16]> {
    assert!(
        at + 1 < camera.len(),
        "camera[{at}] repeats: it cannot vary"
    );
    let zero = PathDensity::ONE.times(Density::zero(Measure::Area));
    if variants.is_empty() || !path.is_complete() || own >= splits.len() || at >= path.len() {
        return variants.iter().map(|_| (0.0, zero)).collect();
    }
    let mut factor = |s: StrategyRef<'s, V>| {
        let span = Span::new(at, 1, Some(s), false, 0);
        path.factor(&span, cache.as_mut().map(|c| &mut c.0))
    };
    let at_vertex: SmallVec<[Density; 16]> = variants.iter().map(|&v| factor(v)).collect();
    // Densities with the first variant that can sample vertex `at`, rescaled for each.
    let base = at_vertex.iter().position(|d| !d.is_zero()).unwrap_or(0);
    let mut with_base: SmallVec<[StrategyRef<'s, V>; 4]> = camera.iter().copied().collect();
    with_base[at] = variants[base];
    let densities = split_densities(path, &with_base, light, splits, cache);
    let mut scaled: SmallVec<[PathDensity; 24]> = densities.clone();
    at_vertex
        .iter()
        .map(|&d| {
            for (k, split) in splits.iter().enumerate() {
                scaled[k] = if split.camera > at {
                    densities[k].divided_by(at_vertex[base]).times(d)
                } else {
                    densities[k]
                };
            }
            (
                heuristic.weight(&counted(&scaled, splits), own),
                scaled[own],
            )
        })
        .collect()
}

/// The density of `path` under each of `splits`, times its number of
/// samples (as MIS weighs them): the densities that
/// [`weight_of_split`] compares, for weights that also involve other paths
/// ([`weight_of_shift`](crate::weight_of_shift)).
#[must_use]
pub fn densities_of_split<'s, V: Vertex>(
    path: &RandomSequence<'_, V>,
    camera: &[StrategyRef<'s, V>],
    light: &[StrategyRef<'s, V>],
    splits: &[Split<'s, V>],
    cache: Option<&mut DensityCache>,
) -> SmallVec<[PathDensity; 24]> {
    if !path.is_complete() {
        let zero = PathDensity::ONE.times(Density::zero(Measure::Area));
        return splits.iter().map(|_| zero).collect();
    }
    let mut densities = split_densities(path, camera, light, splits, cache);
    count(&mut densities, splits);
    densities
}

/// The density of `path` under each of `splits`.
fn split_densities<'s, V: Vertex>(
    path: &RandomSequence<'_, V>,
    camera: &[StrategyRef<'s, V>],
    light: &[StrategyRef<'s, V>],
    splits: &[Split<'s, V>],
    mut cache: Option<&mut DensityCache>,
) -> SmallVec<[PathDensity; 24]> {
    let n = path.len();
    let zero = PathDensity::ONE.times(Density::zero(Measure::Area));
    let ends = |s: &Split<'s, V>| {
        let m: usize = s.middle.iter().map(|(x, _)| x.arity()).sum();
        (s.camera, s.camera + m)
    };
    let (mut reach, mut from) = (0, n);
    for s in splits {
        let (a, b) = ends(s);
        reach = reach.max(a.min(n));
        from = from.min(b);
    }
    let step = |list: &[StrategyRef<'s, V>], i: usize| {
        list.get(i.min(list.len().saturating_sub(1))).copied()
    };
    // A side with no strategies cannot sample its vertices: density zero.
    let mut factor = |span: Span<'s, V>| {
        let cache = cache.as_mut().map(|c| &mut c.0);
        match span.strategy {
            Some(_) => path.factor(&span, cache),
            None => Density::zero(Measure::Area),
        }
    };
    let one = |step: Option<StrategyRef<'s, V>>, i: usize, reversed: bool| {
        Span::new(i, 1, step, reversed, 0)
    };
    // prefix[i]: vertices 0..i from the camera; suffix[i]: i..n from the light.
    let mut prefix: SmallVec<[PathDensity; 16]> = SmallVec::new();
    prefix.push(PathDensity::ONE);
    // The leading vertices sampled by the camera strategies themselves
    // carry their prefix products: no factor is looked up for them.
    let mut chained = true;
    for i in 0..reach {
        let strategy = step(camera, i);
        let chain = if chained {
            path.chain(i, strategy)
        } else {
            None
        };
        chained = chain.is_some();
        let p = chain.unwrap_or_else(|| prefix[i].times(factor(one(strategy, i, false))));
        prefix.push(p);
    }
    // suffix[i - from]: vertices i..n from the light.
    let from = from.min(n);
    let mut suffix: SmallVec<[PathDensity; 16]> =
        SmallVec::from_elem(PathDensity::ONE, n + 1 - from);
    for i in (from..n).rev() {
        suffix[i - from] = suffix[i + 1 - from].times(factor(one(step(light, n - 1 - i), i, true)));
    }
    splits
        .iter()
        .map(|s| {
            let (a, b) = ends(s);
            if b > n {
                return zero;
            }
            let mut p = prefix[a];
            let mut start = a;
            for &(strategy, reversed) in &s.middle {
                p = p.times(factor(Span::new(
                    start,
                    strategy.arity(),
                    Some(strategy),
                    reversed,
                    0,
                )));
                start += strategy.arity();
            }
            p.times_path(suffix[b - from])
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn power_heuristic_of_two() {
        let a = PathDensity::ONE.times(Density::new(1.0, Measure::Area));
        let b = PathDensity::ONE.times(Density::new(3.0, Measure::Area));
        let w0 = Heuristic::POWER.weight(&[a, b], 0);
        let w1 = Heuristic::POWER.weight(&[a, b], 1);
        assert!((w0 - 0.1).abs() < 1e-12 && (w1 - 0.9).abs() < 1e-12);
        assert!((Heuristic::Balance.weight(&[a, b], 0) - 0.25).abs() < 1e-12);
    }

    #[test]
    fn cache_grows_and_forgets() {
        let mut c = FactorCache::default();
        c.begin();
        for i in 0..1000u64 {
            c.insert(
                FactorKey::test(i),
                Density::new(i as f64 + 1.0, Measure::Area),
            );
        }
        assert_eq!(c.get(&FactorKey::test(999)).unwrap().value(), 1000.0);
        c.begin();
        assert!(c.get(&FactorKey::test(999)).is_none());
    }
}
