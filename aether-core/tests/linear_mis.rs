//! MIS costs time linear in path length: weighing every (s, t) technique
//! of a path of k vertices evaluates O(k) densities in all, not O(k) per
//! technique. Counted (densities evaluated in density mode), not timed, so
//! the test is exact on any machine.
//!
//! Each vertex of a bidirectional path has two densities that MIS needs
//! and sampling did not record: its density under the other side's
//! strategy, reversed, and, near the join, the connection's. A quadratic
//! scheme (each technique's product rebuilt from scratch) evaluates about
//! k² of them: doubling the length would quadruple the count.

use aether_core::harness::density_evaluations;
use aether_core::testing::{BidirectionalFixture, TestScene, TestVertex};
use aether_core::{
    DensityCache, Heuristic, Pcg32, RandomSequence, Split, StrategyRef, combine, weight_of_split,
};
use smallvec::SmallVec;

fn one<'a>(s: &'a dyn aether_core::DynStrategy<TestVertex>) -> StrategyRef<'a, TestVertex> {
    StrategyRef::One(s)
}

/// Mean densities evaluated to weigh every candidate of one path of
/// `length` vertices, by `combine` and by `weight_of_split` with a cache,
/// over paths whose subpaths were long enough for all length + 1 techniques.
fn evaluations(length: usize) -> (f64, f64, f64) {
    let scene = TestScene::open_box();
    let f = BidirectionalFixture::new(&scene);
    let camera = [one(&f.camera), one(&f.look), one(&f.bounce)];
    let light = [one(&f.light), one(&f.bounce)];
    let mut rng = Pcg32::new(7, 1);
    let mut out: SmallVec<[RandomSequence<'_, TestVertex>; 8]> = SmallVec::new();
    let mut cache = DensityCache::new();
    let (mut by_combine, mut by_split, mut uncached, mut paths) = (0u64, 0u64, 0u64, 0u64);
    while paths < 200 {
        f.sample_candidates(length, &mut rng, &mut out);
        if out.len() != length + 1 || out.iter().any(|c| !c.is_complete()) {
            continue;
        }
        let before = density_evaluations();
        // Each candidate is a path of its own (camera[..s] joined to the
        // light subpath's first length − s vertices), weighed against
        // every technique.
        let w = combine(&out, Heuristic::POWER);
        let after_combine = density_evaluations();

        let splits: Vec<Split<'_, TestVertex>> = (0..=length).map(|s| Split::new(s, &[])).collect();
        cache.clear();
        for (i, path) in out.iter().enumerate() {
            let (wi, _) = weight_of_split(
                path,
                &camera,
                &light,
                &splits,
                i,
                Heuristic::POWER,
                Some(&mut cache),
            );
            assert!((wi - w[i]).abs() < 1e-9, "technique {i}: {wi} vs {}", w[i]);
        }
        by_combine += after_combine - before;
        let after_split = density_evaluations();
        by_split += after_split - after_combine;
        // Without the cache each technique rebuilds its own products: the
        // quadratic scheme the counts must tell apart.
        for i in 0..out.len() {
            let _ = weight_of_split(&out[i], &camera, &light, &splits, i, Heuristic::POWER, None);
        }
        uncached += density_evaluations() - after_split;
        paths += 1;
    }
    let mean = |n: u64| n as f64 / paths as f64;
    (mean(by_combine), mean(by_split), mean(uncached))
}

#[test]
fn mis_evaluates_densities_linearly_in_path_length() {
    let counts: Vec<(usize, (f64, f64, f64))> = [4, 8, 16]
        .into_iter()
        .map(|k| (k, evaluations(k)))
        .collect();
    for &(k, (c, s, u)) in &counts {
        println!(
            "{k} vertices: combine {c:.1}, weight_of_split {s:.1} (uncached {u:.1}) densities per path"
        );
    }
    // Linear growth: the count per added vertex is the same from 4 to 8 as
    // from 8 to 16 (quadratic growth would double it), within 10 %.
    type Count = fn(&(f64, f64, f64)) -> f64;
    let slope = |a: usize, b: usize, f: Count| {
        (f(&counts[b].1) - f(&counts[a].1)) / (counts[b].0 - counts[a].0) as f64
    };
    for (name, f) in [
        ("combine", (|c: &(f64, f64, f64)| c.0) as Count),
        ("weight_of_split", |c: &(f64, f64, f64)| c.1),
    ] {
        let (short, long) = (slope(0, 1, f), slope(1, 2, f));
        println!(
            "{name}: {short:.2} densities per added vertex from 4 to 8, {long:.2} from 8 to 16"
        );
        assert!(long <= 1.1 * short, "{name}: {short} then {long}");
        // A bounded number per vertex: its two sides and the connection's.
        assert!(f(&counts[2].1) <= 6.0 * 16.0, "{name}: {}", f(&counts[2].1));
    }
    // The measure tells the schemes apart: without the cache the count per
    // added vertex grows with the length.
    let (short, long) = (slope(0, 1, |c| c.2), slope(1, 2, |c| c.2));
    println!("uncached: {short:.2} then {long:.2} per added vertex");
    assert!(long >= 1.5 * short, "uncached: {short} then {long}");
}
