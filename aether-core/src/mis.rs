//! Multiple importance sampling: heuristics and `combine`.

use std::cell::RefCell;

use smallvec::SmallVec;

use crate::density::{Density, Measure, PathDensity, is_finite};
use crate::sequence::{FactorKey, RandomSequence, Span};
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
        self.weight_among(densities[i], densities.iter().copied())
    }

    /// As [`weight`](Self::weight), for the candidate whose own density is
    /// `own`, given every candidate's density (its own among them) one at
    /// a time: a caller that derives them in turn need not store them.
    #[must_use]
    pub(crate) fn weight_among(
        self,
        own: PathDensity,
        densities: impl IntoIterator<Item = PathDensity>,
    ) -> f64 {
        if own.is_zero() {
            return 0.0;
        }
        let mut sum = 0.0;
        for p in densities {
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
        if is_finite(sum) && sum > 0.0 {
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

    /// Where `key` sits in the table (`Ok`), or the free entry its probe
    /// ends at (`Err`). The table is never full: it grows at half.
    /// Inlined: called out of line it cost BDPT 1.4 % more instructions.
    #[inline]
    fn probe(&self, key: &FactorKey) -> Result<usize, usize> {
        let mut i = key.hash64() as usize & self.mask();
        while self.entries[i].0 == self.generation {
            if self.entries[i].1 == *key {
                return Ok(i);
            }
            i = (i + 1) & self.mask();
        }
        Err(i)
    }

    #[cfg(test)]
    fn get(&self, key: &FactorKey) -> Option<Density> {
        if self.entries.is_empty() {
            return None;
        }
        self.probe(key).ok().map(|i| self.entries[i].2)
    }

    /// The density cached for `key`, or `evaluate`'s, cached: one hash
    /// and one probe where a lookup and an insertion took two of each.
    pub(crate) fn get_or_insert_with(
        &mut self,
        key: FactorKey,
        evaluate: impl FnOnce() -> Density,
    ) -> Density {
        if self.entries.is_empty() {
            self.begin();
        }
        match self.probe(&key) {
            Ok(i) => self.entries[i].2,
            Err(free) => {
                let density = evaluate();
                if 2 * (self.len + 1) > self.entries.len() {
                    self.insert(key, density);
                } else {
                    self.entries[free] = (self.generation, key, density);
                    self.len += 1;
                }
                density
            }
        }
    }

    pub(crate) fn insert(&mut self, key: FactorKey, density: Density) {
        if self.entries.is_empty() {
            self.begin();
        }
        if 2 * (self.len + 1) > self.entries.len() {
            self.grow();
        }
        if let Err(free) = self.probe(&key) {
            self.entries[free] = (self.generation, key, density);
            self.len += 1;
        }
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
pub struct DensityCache(pub(crate) FactorCache);

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

    #[test]
    fn a_factor_is_evaluated_once_and_found_after() {
        let mut c = FactorCache::default();
        let mut evaluations = 0;
        // Enough keys to grow the table while inserting.
        for round in 0..2 {
            for i in 0..1000u64 {
                let d = c.get_or_insert_with(FactorKey::test(i), || {
                    evaluations += 1;
                    Density::new(i as f64 + 1.0, Measure::Area)
                });
                assert_eq!(d.value(), i as f64 + 1.0, "round {round}, key {i}");
            }
        }
        assert_eq!(evaluations, 1000);
        c.begin();
        let d = c.get_or_insert_with(FactorKey::test(5), || Density::new(-1.0, Measure::Area));
        assert!(d.is_zero(), "forgotten after begin");
    }
}
