//! `Joins` gives every join of a camera and a light subpath the weight and
//! density that `weight_of_split` gives the joined path over
//! `Split::bidirectional`'s techniques: joins to light subpath vertices,
//! to a light sample of the direct step (t = 1), camera paths that found
//! the light (t = 0) and light paths that reached the camera (s = 0, 1,
//! per-pixel variants of the camera ray), with and without a lens to reach.

use aether_core::testing::{BidirectionalFixture, LookDown, TestScene, TestVertex};
use aether_core::{
    DynStrategy, Heuristic, Join, Joins, PathDensity, Pcg32, RandomSequence, Split, Splits,
    StrategyRef, weight_of_split, weights_of_split_variants,
};

fn one<'a>(s: &'a dyn DynStrategy<TestVertex>) -> StrategyRef<'a, TestVertex> {
    StrategyRef::One(s)
}

fn close(a: (f64, PathDensity), b: (f64, PathDensity), what: &str) {
    let near = |x: f64, y: f64| (x - y).abs() <= 1e-9 * x.abs().max(y.abs()) + 1e-300;
    assert!(near(a.0, b.0), "{what}: weight {} vs {}", a.0, b.0);
    assert!(
        near(a.1.value(), b.1.value()) && a.1.dirac_order() == b.1.dirac_order(),
        "{what}: density {:?} vs {:?}",
        a.1,
        b.1
    );
}

#[test]
fn joins_weigh_as_split_weights_do() {
    let scene = TestScene::open_box();
    let f = BidirectionalFixture::new(&scene);
    // The light sample doubles as the direct step (it ignores the path).
    let direct = one(&f.light);
    let camera = [one(&f.camera), one(&f.look), one(&f.bounce)];
    let light = [one(&f.light), one(&f.bounce)];
    let other_look = LookDown::new(&scene);
    let mut rng = Pcg32::new(11, 3);
    let (mut checked, mut shared, mut weighed) = ([0usize; 4], 0usize, 0usize);
    for sample in 0..300 {
        let through_lens = sample % 2 == 0;
        let counts = (64.0, through_lens);
        let mut eye = RandomSequence::new();
        eye.append(&f.camera)
            .append(&f.look)
            .repeat(&f.bounce, 5, &mut rng);
        let mut lights = RandomSequence::new();
        lights.append(&f.light).repeat(&f.bounce, 4, &mut rng);
        let subpaths = (&eye, &lights);
        let steps = (Some(direct), None);
        let mut joins = Joins::new(subpaths, (&camera, &light), steps, counts, Heuristic::POWER);
        for s in 0..=eye.len() {
            for t in 0..=lights.len() {
                let n = s + t;
                if n < 2 {
                    continue;
                }
                // The joined path, and the same join described by its parts.
                // A light sample, drawn twice from one state of the
                // generator: beside the eye and appended to its prefix.
                let mut again = rng.clone();
                let lamp = match t {
                    1 if s >= 1 => eye.sample_after(s, &f.light, &mut rng),
                    _ => None,
                };
                let path = match (t, &lamp) {
                    (0, _) => eye.slice(0..s),
                    (1, Some(_)) => {
                        let mut path = eye.slice(0..s);
                        assert!(path.append_sample(&f.light, &mut again));
                        path
                    }
                    (1, None) => continue,
                    _ => eye.slice(0..s).concat(&lights.slice(0..t).reversed()),
                };
                let join = Join::new((&eye, s), (&lights, t), lamp.as_ref());
                assert_eq!(join.len(), n);
                assert!(join.vertices().zip(path.vertices()).all(|(a, b)| a == b));
                let mut splits = Splits::new();
                Split::bidirectional(n, Some(direct), None, counts.0, counts.1, &mut splits);
                let h = Heuristic::POWER;
                let what = format!("(s, t) = ({s}, {t})");
                if s >= 2 {
                    let by_split = weight_of_split(&path, &camera, &light, &splits, s, h, None);
                    let by_joins = joins.weight(s, &path);
                    close(by_joins, by_split, &what);
                    let by_parts = joins.join_weights(&join, s, 1, &[one(&f.look)]);
                    close(by_parts[0], by_split, &format!("{what}, by its parts"));
                    shared += usize::from(by_joins.0 > 0.0 && by_joins.0 < 1.0);
                    checked[t.min(3)] += 1;
                } else {
                    // Splatted: the camera ray's strategy varies by pixel.
                    let variants = [one(&f.look), one(&other_look)];
                    let by_split = weights_of_split_variants(
                        &path, &camera, &light, &splits, s, h, None, 1, &variants,
                    );
                    let by_joins = joins.weights(s, &path, 1, &variants);
                    let by_parts = joins.join_weights(&join, s, 1, &variants);
                    for ((a, b), c) in by_joins.iter().zip(&by_split).zip(&by_parts) {
                        close(*a, *b, &format!("splat {what}"));
                        close(*c, *b, &format!("splat {what}, by its parts"));
                        shared += usize::from(a.0 > 0.0 && a.0 < 1.0);
                    }
                    assert_eq!(by_joins.len(), by_split.len());
                    assert_eq!(by_parts.len(), by_split.len());
                    checked[3] += 1;
                }
            }
        }
        // Every join took the shortcut, from its path and from its parts.
        let joined = checked.iter().sum::<usize>();
        assert_eq!(joins.shortcuts(), 2 * (joined - weighed), "sample {sample}");
        weighed = joined;
    }
    // Every kind of join was met, and often, and many weights are shared
    // between techniques (neither 0 nor 1).
    assert!(
        checked.iter().all(|&c| c > 50),
        "joins checked: {checked:?}"
    );
    assert!(shared > 500, "{shared} weights strictly between 0 and 1");
    eprintln!("joins checked {checked:?}, {shared} shared weights");
}

/// Diffuse bounces continued by Russian roulette from the `start`-th vertex
/// on: their densities change with the depth, so a vertex's density under
/// the other side's strategies depends on the length of the path it is
/// joined into (the depth classes the joins keep their sums by).
struct RouletteBounce<'s> {
    bounce: aether_core::testing::Bounce<'s>,
    start: usize,
}

impl aether_core::Strategy<TestVertex> for RouletteBounce<'_> {
    fn distribution<'a>(
        &'a self,
        prefix: aether_core::Prefix<'a, TestVertex>,
    ) -> impl aether_core::Distribution<Value = aether_core::Step<TestVertex>> + 'a {
        let q = if prefix.len() >= self.start { 0.6 } else { 1.0 };
        aether_core::RussianRoulette::new(q, self.bounce.distribution(prefix))
    }
    fn memory(&self) -> usize {
        2
    }
    fn depth_class(&self, prefix_len: usize) -> usize {
        usize::from(prefix_len >= self.start)
    }
}

#[test]
fn joins_weigh_as_split_weights_do_when_densities_change_with_depth() {
    let scene = TestScene::open_box();
    let f = BidirectionalFixture::new(&scene);
    let bounce = RouletteBounce {
        bounce: f.bounce,
        start: 3,
    };
    let direct = one(&f.light);
    let camera = [one(&f.camera), one(&f.look), one(&bounce)];
    let light = [one(&f.light), one(&bounce)];
    let mut rng = Pcg32::new(5, 9);
    let (mut checked, mut between, mut lamps) = (0usize, 0usize, 0usize);
    for sample in 0..300 {
        let mut eye = RandomSequence::new();
        eye.append(&f.camera)
            .append(&f.look)
            .repeat(&bounce, 6, &mut rng);
        let mut lights = RandomSequence::new();
        lights.append(&f.light).repeat(&bounce, 6, &mut rng);
        let steps = (Some(direct), None);
        let lists = (&camera[..], &light[..]);
        let mut joins = Joins::new(
            (&eye, &lights),
            lists,
            steps,
            (64.0, true),
            Heuristic::POWER,
        );
        let mut joined = 0;
        for s in 2..=eye.len() {
            for t in 0..=7 {
                if t > lights.len() {
                    continue;
                }
                let n = s + t;
                // A light sample (t = 1), drawn twice from one state of the
                // generator: beside the eye and appended to its prefix.
                let mut again = rng.clone();
                let lamp = match t {
                    1 => eye.sample_after(s, &f.light, &mut rng),
                    _ => None,
                };
                let path = match (t, &lamp) {
                    (1, Some(_)) => {
                        let mut path = eye.slice(0..s);
                        assert!(path.append_sample(&f.light, &mut again));
                        lamps += 1;
                        path
                    }
                    (1, None) => continue,
                    _ => eye.slice(0..s).concat(&lights.slice(0..t).reversed()),
                };
                let join = Join::new((&eye, s), (&lights, t), lamp.as_ref());
                let mut splits = Splits::new();
                Split::bidirectional(n, Some(direct), None, 64.0, true, &mut splits);
                let h = Heuristic::POWER;
                let by_split = weight_of_split(&path, &camera, &light, &splits, s, h, None);
                let what = format!("(s, t) = ({s}, {t})");
                close(joins.weight(s, &path), by_split, &what);
                let by_parts = joins.join_weights(&join, s, 1, &[one(&f.look)]);
                close(by_parts[0], by_split, &format!("{what}, by its parts"));
                checked += 1;
                joined += 1;
                between += usize::from(by_split.0 > 0.0 && by_split.0 < 1.0);
            }
        }
        // Every join took the kept densities' shortcut, from its path and
        // from its parts (not the reference it is compared with).
        assert_eq!(joins.shortcuts(), 2 * joined, "sample {sample}");
    }
    // Long paths, both sides of the roulette's start, light samples, many
    // shared weights.
    assert!(
        checked > 2000 && between > 1000 && lamps > 300,
        "{checked} joins, {between} shared, {lamps} light samples"
    );
}
