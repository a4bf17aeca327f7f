//! What the language costs: nanoseconds per sample and per density
//! evaluation for each primitive, and for a 5-vertex path with all its
//! BDPT candidates combined.
//!
//! Run with `cargo bench -p aether-core --bench language`.

use std::hint::black_box;
use std::time::Instant;

use aether_core::primitives::*;
use aether_core::testing::{BidirectionalFixture, TestScene, TestVertex};
use aether_core::{
    Distribution, Frame, Heuristic, InFrame, Pcg32, Prefix, RandomSequence, UniformSource, combine,
};
use glam::Vec3;
use smallvec::SmallVec;

const N: usize = 400_000;

/// Median of five timings of `f`, in nanoseconds per call over `n` calls.
fn time(n: usize, mut f: impl FnMut(usize)) -> f64 {
    let mut runs: Vec<f64> = (0..5)
        .map(|_| {
            let start = Instant::now();
            for i in 0..n {
                f(i);
            }
            start.elapsed().as_nanos() as f64 / n as f64
        })
        .collect();
    runs.sort_by(f64::total_cmp);
    runs[2]
}

fn primitive<D>(name: &str, d: &D) -> (f64, f64)
where
    D: Distribution,
    D::Value: Clone,
{
    let mut rng = Pcg32::new(1, 0);
    let dims = d.dims().max(1);
    let uniforms: Vec<f32> = (0..N * dims).map(|_| rng.next_f32()).collect();
    let values: Vec<D::Value> = (0..N)
        .filter_map(|i| {
            d.sample(&uniforms[i * dims..(i + 1) * dims])
                .map(|s| s.value)
        })
        .collect();
    let sample = time(N, |i| {
        black_box(d.sample(black_box(&uniforms[i * dims..(i + 1) * dims])));
    });
    let density = time(values.len(), |i| {
        black_box(d.density(black_box(&values[i])));
    });
    println!(
        "{name:<34} {sample:>8.1} {density:>10.1} {:>8.2}",
        density / sample
    );
    (sample, density)
}

fn main() {
    println!(
        "{:<34} {:>8} {:>10} {:>8}",
        "ns per call", "sample", "density", "ratio"
    );
    let wi = Vec3::new(0.3, -0.4, 0.866).normalize();
    let mut worst: f64 = 0.0;
    let mut track = |(s, d): (f64, f64)| worst = worst.max(d / s);
    track(primitive(
        "UniformInterval",
        &UniformInterval::new(0.0, 2.0),
    ));
    track(primitive(
        "DiscreteDistribution (64)",
        &DiscreteDistribution::new(&(1..=64).map(f64::from).collect::<Vec<_>>()).unwrap(),
    ));
    track(primitive("UniformDisk", &UniformDisk::UNIT));
    track(primitive("CosineHemisphere", &CosineHemisphere));
    track(primitive("UniformHemisphere", &UniformHemisphere));
    track(primitive("UniformSphere", &UniformSphere));
    track(primitive("UniformCone", &UniformCone::new(0.8)));
    track(primitive(
        "UniformTriangle",
        &UniformTriangle::new(Vec3::ZERO, Vec3::X, Vec3::Y),
    ));
    track(primitive(
        "GgxVisibleNormals",
        &GgxVisibleNormals::new(0.3, 0.2, wi),
    ));
    track(primitive("BeckmannNormals", &BeckmannNormals::new(0.3)));
    track(primitive(
        "Reflect(GGX)",
        &Reflect::new(wi, GgxVisibleNormals::new(0.3, 0.3, wi)),
    ));
    track(primitive(
        "Refract(GGX)",
        &Refract::new(wi, 1.5, GgxVisibleNormals::new(0.3, 0.3, wi)),
    ));
    track(primitive(
        "InFrame(CosineHemisphere)",
        &InFrame::new(Frame::from_normal(wi), CosineHemisphere),
    ));
    let table: Vec<f64> = (0..64 * 32)
        .map(|i| f64::from((i * 7919) % 97 + 1))
        .collect();
    track(primitive(
        "PiecewiseConstant2D (64×32)",
        &PiecewiseConstant2D::new(&table, 64, 32).unwrap(),
    ));
    println!("worst density/sample ratio over primitives: {worst:.2}");

    // A 5-vertex path: camera subpath sampled, its density evaluated again
    // from scratch, then every BDPT candidate of length 5 combined.
    let scene = TestScene::open_box();
    let fixture = BidirectionalFixture::new(&scene);
    let (camera, look, bounce) = (&fixture.camera, &fixture.look, &fixture.bounce);
    let mut rng = Pcg32::new(3, 0);
    let camera_path = |rng: &mut Pcg32| {
        let mut cam = RandomSequence::new();
        cam.append(camera)
            .append(look)
            .append(bounce)
            .append(bounce)
            .append(bounce);
        cam.sample(rng);
        cam
    };
    let sample = time(N / 4, |_| {
        black_box(camera_path(&mut rng));
    });
    let mut paths = Vec::new();
    while paths.len() < 1000 {
        let cam = camera_path(&mut rng);
        if cam.len() == 5 {
            paths.push(cam);
        }
    }
    let strategies: [&dyn aether_core::DynStrategy<TestVertex>; 5] =
        [camera, look, bounce, bounce, bounce];
    let density = time(N / 4, |i| {
        let v = paths[i % paths.len()].vertices();
        let mut p = 1.0;
        for (k, s) in strategies.iter().enumerate() {
            p *= s.density_of(Prefix::forward(&v[..k]), &v[k]).value();
        }
        black_box(p);
    });
    // Sampling: both subpaths of a 5-vertex BDPT sample and its 6 (s, t)
    // candidates. Density evaluation: their combine, which evaluates every
    // candidate's vertices under every candidate's strategies.
    let mut candidates = SmallVec::new();
    let bdpt_sample = time(N / 4, |_| {
        fixture.sample_candidates(5, &mut rng, &mut candidates);
        black_box(&candidates);
    });
    let sets: Vec<SmallVec<[RandomSequence<'_, TestVertex>; 8]>> = (0..256)
        .map(|_| {
            let mut c = SmallVec::new();
            while c.len() < 6 {
                fixture.sample_candidates(5, &mut rng, &mut c);
            }
            c
        })
        .collect();
    let bdpt_combine = time(N / 4, |i| {
        black_box(combine(&sets[i % sets.len()], Heuristic::POWER));
    });
    println!();
    println!(
        "5-vertex camera path: sample {sample:.0} ns (with ray casts), density from scratch {density:.0} ns, ratio {:.2}",
        density / sample
    );
    println!(
        "5-vertex BDPT sample: subpaths and 6 candidates {bdpt_sample:.0} ns, their combine {bdpt_combine:.0} ns, ratio {:.2}",
        bdpt_combine / bdpt_sample
    );
}
