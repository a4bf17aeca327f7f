//! Techniques of paths sampled from both ends ([`Split`]) and their MIS
//! weights from prefix and suffix products: time linear in path length,
//! and no allocation once a thread's buffers have grown to its longest path.

use std::cell::RefCell;

use smallvec::SmallVec;

use crate::density::{Density, Measure, PathDensity};
use crate::mis::{DensityCache, Heuristic};
use crate::recycle::{Pooled, Recycle};
use crate::sequence::{RandomSequence, Span};
use crate::strategy::StrategyRef;
use crate::vertex::Vertex;

/// Buffers of the products, reused by every weight on a thread.
#[derive(Debug, Default)]
struct Scratch {
    prefix: Vec<PathDensity>,
    suffix: Vec<PathDensity>,
    densities: Vec<PathDensity>,
    scaled: Vec<PathDensity>,
}

thread_local! {
    static SCRATCH: RefCell<Scratch> = RefCell::new(Scratch::default());
}

/// Runs `f` with this thread's buffers (fresh ones if they are in use).
fn with_scratch<T>(f: impl FnOnce(&mut Scratch) -> T) -> T {
    SCRATCH.with(|s| match s.try_borrow_mut() {
        Ok(mut scratch) => f(&mut scratch),
        Err(_) => f(&mut Scratch::default()),
    })
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

impl<'s, V: Recycle> Split<'s, V> {
    /// Every technique of a bidirectional sampler for paths of `n`
    /// vertices: first, for s = 0..=n, s vertices from the camera and the
    /// rest from the light (index s), with `direct` sampling the last
    /// vertex when the light side would have one; then, with a `portal`
    /// pair strategy, for k = 1..n − 2, k from the camera, the portal's two
    /// and the rest from the light (index n + k), again with `direct` for a
    /// single light vertex. A portal taken for a share of the samples only
    /// says so in its density ([`Sometimes`](crate::Sometimes)). The
    /// techniques with at most one camera vertex
    /// (splatted, not sampled per pixel) take `splats` samples each; s = 0,
    /// light paths that reach the camera, is sampled only `through_lens`
    /// (a pinhole cannot be hit), and takes no samples otherwise. They are
    /// pushed to `splits`, in that order: the list is large (returned by
    /// value, its copy cost BDPT 1.4 % of its instructions).
    ///
    /// ```
    /// use aether_core::Split;
    /// use aether_core::testing::{LightSample, TestScene, TestVertex};
    /// let scene = TestScene::open_box();
    /// let light = LightSample::new(&scene);
    /// let direct = Some((&light as &dyn aether_core::DynStrategy<_>).into());
    /// let mut splits = aether_core::Splits::new();
    /// Split::<TestVertex>::bidirectional(4, direct, None, 64.0 * 64.0, false, &mut splits);
    /// assert_eq!(splits.len(), 5);
    /// assert_eq!((splits[3].camera, splits[3].middle.len()), (3, 1)); // direct light sampling
    /// assert_eq!(splits[1].samples, 4096.0); // light tracing, to any of 64 × 64 pixels
    /// assert_eq!(splits[0].samples, 0.0); // no light path hits a pinhole
    /// ```
    pub fn bidirectional(
        n: usize,
        direct: Option<StrategyRef<'s, V>>,
        portal: Option<StrategyRef<'s, V>>,
        splats: f64,
        through_lens: bool,
        splits: &mut Splits<'s, V>,
    ) {
        let samples = |camera: usize| samples_of(camera, splats, through_lens);
        // Pushed one by one: built from an iterator chain, with each
        // middle collected, the list cost BDPT 2 % of its instructions.
        let split = |camera: usize, first: Option<StrategyRef<'s, V>>, t: usize| {
            let middle = match (first, direct.filter(|_| t == 1)) {
                (None, None) => SmallVec::new(),
                (Some(a), None) | (None, Some(a)) => SmallVec::from_buf_and_len([(a, false); 2], 1),
                (Some(a), Some(b)) => SmallVec::from_buf([(a, false), (b, false)]),
            };
            Split {
                camera,
                middle,
                samples: samples(camera),
            }
        };
        for s in 0..=n {
            splits.push(split(s, None, n - s));
        }
        if portal.is_some() {
            for k in 1..n.saturating_sub(1) {
                splits.push(split(k, portal, n - k - 2));
            }
        }
    }
}

/// A list of techniques, inline up to the number BDPT has for paths of
/// 12 vertices with portals, as [`Split::bidirectional`] fills.
pub type Splits<'s, V> = Pooled<[Split<'s, V>; 24]>;

impl<V: Recycle> Recycle for Split<'_, V> {
    type Static = Split<'static, V::Static>;
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
    with_scratch(|scratch| {
        split_densities(path, camera, light, splits, cache, scratch);
        let densities = &mut scratch.densities;
        let density = densities[own];
        count(densities, splits);
        (heuristic.weight(densities, own), density)
    })
}

/// The samples a bidirectional technique with `camera` vertices from the
/// camera takes for each of the others' ([`Split::samples`]): `splats` for
/// those splatted to any pixel (at most one camera vertex), none for a
/// light path reaching a pinhole (`through_lens` false), one otherwise.
pub(crate) fn samples_of(camera: usize, splats: f64, through_lens: bool) -> f64 {
    match camera {
        0 if !through_lens => 0.0,
        0 | 1 => splats,
        _ => 1.0,
    }
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
    // The camera's own strategy as the one variant (a path sampled for
    // its own pixel) is the plain weight.
    if let ([v], Some(c)) = (variants, camera.get(at)) {
        if v.same(c) {
            return [weight_of_split(
                path, camera, light, splits, own, heuristic, cache,
            )]
            .into_iter()
            .collect();
        }
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
    with_scratch(|scratch| {
        split_densities(path, &with_base, light, splits, cache, scratch);
        let Scratch {
            densities, scaled, ..
        } = scratch;
        at_vertex
            .iter()
            .map(|&d| {
                scaled.clear();
                scaled.extend(splits.iter().zip(densities.iter()).map(|(split, &p)| {
                    if split.camera > at {
                        p.divided_by(at_vertex[base]).times(d)
                    } else {
                        p
                    }
                }));
                let own_density = scaled[own];
                count(scaled, splits);
                (heuristic.weight(scaled, own), own_density)
            })
            .collect()
    })
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
    with_scratch(|scratch| {
        split_densities(path, camera, light, splits, cache, scratch);
        count(&mut scratch.densities, splits);
        SmallVec::from_slice(&scratch.densities)
    })
}

/// The density of `path` under each of `splits`, into `scratch.densities`.
fn split_densities<'s, V: Vertex>(
    path: &RandomSequence<'_, V>,
    camera: &[StrategyRef<'s, V>],
    light: &[StrategyRef<'s, V>],
    splits: &[Split<'s, V>],
    mut cache: Option<&mut DensityCache>,
    scratch: &mut Scratch,
) {
    let Scratch {
        prefix,
        suffix,
        densities,
        ..
    } = scratch;
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
    // The strategy of a list at position i (the last one repeats), and, for
    // a factor to look up, its span: the repeating last step's is read once
    // and moved to each vertex it samples, rather than built from its
    // strategy's identity there (the chained vertices need no span).
    let entry = |list: &[StrategyRef<'s, V>], i: usize| {
        list.get(i.min(list.len().saturating_sub(1))).copied()
    };
    let last =
        |list: &[StrategyRef<'s, V>]| list.last().map(|&s| Span::new(0, 1, Some(s), false, 0));
    let (camera_last, light_last) = (last(camera), last(light));
    // Entry k of `list` as the span of vertex i.
    let one = |(list, last): (&[StrategyRef<'s, V>], Option<Span<'s, V>>), k, i, reversed| match (
        list.get(k),
        last,
    ) {
        (Some(&s), _) if k + 1 < list.len() => Span::new(i, 1, Some(s), reversed, 0),
        (_, Some(last)) => last.at(i, reversed),
        _ => Span::new(i, 1, None, reversed, 0),
    };
    // A side with no strategies cannot sample its vertices: density zero.
    let mut factor = |span: Span<'s, V>| {
        let cache = cache.as_mut().map(|c| &mut c.0);
        match span.strategy {
            Some(_) => path.factor(&span, cache),
            None => Density::zero(Measure::Area),
        }
    };
    // prefix[i]: vertices 0..i from the camera; suffix[i]: i..n from the light.
    prefix.clear();
    prefix.push(PathDensity::ONE);
    // The leading vertices sampled by the camera strategies themselves
    // carry their prefix products: no factor is looked up for them.
    let mut chained = true;
    for i in 0..reach {
        let chain = if chained {
            path.chain(i, entry(camera, i))
        } else {
            None
        };
        chained = chain.is_some();
        let p = chain
            .unwrap_or_else(|| prefix[i].times(factor(one((camera, camera_last), i, i, false))));
        prefix.push(p);
    }
    // suffix[i - from]: vertices i..n from the light.
    let from = from.min(n);
    suffix.clear();
    suffix.resize(n + 1 - from, PathDensity::ONE);
    // The trailing vertices sampled by the light strategies themselves
    // carry their suffix products, as the leading ones their prefixes.
    let mut chained = true;
    for i in (from..n).rev() {
        let k = n - 1 - i;
        let chain = if chained {
            path.suffix_chain(i, entry(light, k))
        } else {
            None
        };
        chained = chain.is_some();
        suffix[i - from] = chain.unwrap_or_else(|| {
            suffix[i + 1 - from].times(factor(one((light, light_last), k, i, true)))
        });
    }
    densities.clear();
    densities.extend(splits.iter().map(|s| {
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
    }));
}
