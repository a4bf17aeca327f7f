//! MIS: partition of unity (d), Dirac lobes and point lights, exact
//! cancellation of Dirac masses, BDPT-style candidates against direct
//! evaluation, and unbiasedness of a two-strategy estimator.

use aether_core::harness::{Technique, check_mis};
use aether_core::primitives::{CosineHemisphere, DiracDirection, DiscreteDistribution};
use aether_core::testing::{
    Bounce, CameraPoint, LightSample, LookDown, TestScene, TestVertex, facing_normal,
};
use aether_core::{
    DiracPoint, Distribution, Either, Frame, Geometry, Heuristic, InFrame, Intersect, Mixture,
    OnSurface, Pcg32, Prefix, RandomSequence, Select, Step, Strategy, combine, reflect,
};
use glam::Vec3;

/// A BSDF with a diffuse lobe and a mirror lobe (a Dirac).
struct DiffuseAndMirror<'s> {
    scene: &'s TestScene,
    lobes: DiscreteDistribution,
}

impl Strategy<TestVertex> for DiffuseAndMirror<'_> {
    fn distribution<'a>(
        &'a self,
        prefix: Prefix<'a, TestVertex>,
    ) -> impl Distribution<Value = Step<TestVertex>> + 'a {
        let x = prefix.last().expect("a shading point");
        let from = prefix.back(1).expect("an incoming direction");
        let n = facing_normal(x, Some(from));
        let wi = (from.position - x.position).normalize();
        let lobe = move |i: usize| match i {
            0 => Either::Left(InFrame::new(Frame::from_normal(n), CosineHemisphere)),
            _ => Either::Right(DiracDirection::new(reflect(wi, n), 1.0)),
        };
        Intersect::new(x, Mixture::new(&self.lobes, 2, lobe), self.scene)
    }
    fn memory(&self) -> usize {
        2
    }
}

/// Light selection by power between the area light (two triangles) and the
/// point light, then a point on the chosen light.
struct Lights<'s> {
    scene: &'s TestScene,
    choice: DiscreteDistribution,
}

impl<'s> Lights<'s> {
    fn new(scene: &'s TestScene, point_light_probability: f64) -> Self {
        let area = (1.0 - point_light_probability) / 2.0;
        Lights {
            scene,
            choice: DiscreteDistribution::new(&[area, area, point_light_probability]).unwrap(),
        }
    }
}

impl Strategy<TestVertex> for Lights<'_> {
    fn distribution<'a>(
        &'a self,
        _prefix: Prefix<'a, TestVertex>,
    ) -> impl Distribution<Value = Step<TestVertex>> + 'a {
        let scene = self.scene;
        let branch = move |i: usize| match i {
            0 | 1 => Either::Left(OnSurface::new(scene.light_triangle(i), move |p| {
                Some(scene.vertex_on(scene.light, p))
            })),
            _ => Either::Right(DiracPoint::new(TestVertex::point(scene.point_light), 1.0)),
        };
        let which = move |v: &Step<TestVertex>| match v {
            Step::Vertex(v) if v.shape as usize == scene.light => {
                (0..2).find(|&i| scene.light_triangle(i).barycentrics(v.position).is_some())
            }
            Step::Vertex(v) if v.geometry == Geometry::Point => Some(2),
            _ => None,
        };
        Select::new(&self.choice, 2, branch, which)
    }
    fn memory(&self) -> usize {
        0
    }
}

fn is_on_light(scene: &TestScene, v: &TestVertex) -> bool {
    v.shape as usize == scene.light
}

#[test]
fn dirac_lobe_and_point_light_partition_of_unity() {
    let scene = TestScene::open_box();
    let (camera, look) = (CameraPoint::default(), LookDown::new(&scene));
    let bsdf = DiffuseAndMirror {
        scene: &scene,
        lobes: DiscreteDistribution::new(&[0.6, 0.4]).unwrap(),
    };
    let lights = Lights::new(&scene, 0.3);
    let techniques = [
        Technique::new()
            .forward(&camera)
            .forward(&look)
            .forward(&bsdf),
        Technique::new()
            .forward(&camera)
            .forward(&look)
            .forward(&lights),
    ];
    for heuristic in [Heuristic::Balance, Heuristic::POWER] {
        let report = check_mis(&techniques, heuristic, 2000, &mut Pcg32::new(11, 0)).unwrap();
        println!("{heuristic:?}: {report:?}");
        assert!(report.paths > 3000 && report.max_partition_error < 1e-9);
    }

    // The cases Dirac orders decide, found by sampling.
    let mut rng = Pcg32::new(5, 1);
    let (mut point_light, mut mirror_to_light, mut diffuse_to_light) = (0, 0, 0);
    for _ in 0..20_000 {
        let mut cam = RandomSequence::new();
        cam.append(&camera).append(&look);
        if cam.sample(&mut rng) != aether_core::StepKind::Vertex {
            continue;
        }
        let (mut via_bsdf, mut via_light) = (cam.clone(), cam.clone());
        via_bsdf.append(&bsdf);
        via_light.append(&lights);
        if via_light.sample(&mut rng) == aether_core::StepKind::Vertex
            && via_light.vertices()[2].geometry == Geometry::Point
        {
            // A point light: BSDF sampling cannot hit it.
            let as_bsdf = techniques[0].assign(&via_light).unwrap();
            let w = combine(&[as_bsdf, via_light.clone()], Heuristic::POWER);
            assert_eq!(w.as_slice(), &[0.0, 1.0]);
            point_light += 1;
        }
        if via_bsdf.sample(&mut rng) == aether_core::StepKind::Vertex
            && is_on_light(&scene, &via_bsdf.vertices()[2])
        {
            let as_light = techniques[1].assign(&via_bsdf).unwrap();
            let w = combine(&[via_bsdf.clone(), as_light], Heuristic::POWER);
            let p = via_bsdf.pdf();
            if p.dirac_order() == 2 {
                // Pinhole and mirror: the light technique has one Dirac fewer.
                assert_eq!(w.as_slice(), &[1.0, 0.0]);
                mirror_to_light += 1;
            } else {
                assert!(
                    w[0] > 0.0 && w[0] < 1.0 && (w[0] + w[1] - 1.0).abs() < 1e-12,
                    "{w:?}"
                );
                diffuse_to_light += 1;
            }
        }
    }
    println!(
        "point light {point_light}, mirror to light {mirror_to_light}, diffuse to light {diffuse_to_light}"
    );
    assert!(point_light > 100 && mirror_to_light > 10 && diffuse_to_light > 10);
}

#[test]
fn dirac_masses_cancel_exactly() {
    let scene = TestScene::open_box();
    let (camera, look) = (CameraPoint::default(), LookDown::new(&scene));
    let (a, b) = (Lights::new(&scene, 0.3), Lights::new(&scene, 0.1));
    let mut rng = Pcg32::new(9, 0);
    let mut checked = 0;
    while checked < 50 {
        let mut path = RandomSequence::new();
        path.append(&camera).append(&look).append(&a);
        if path.sample(&mut rng) != aether_core::StepKind::Vertex
            || path.vertices()[2].geometry != Geometry::Point
        {
            continue;
        }
        let under_b = Technique::new()
            .forward(&camera)
            .forward(&look)
            .forward(&b)
            .assign(&path)
            .unwrap();
        let wb = combine(&[path.clone(), under_b.clone()], Heuristic::Balance);
        assert!(
            (wb[0] - 0.75).abs() < 1e-12 && (wb[1] - 0.25).abs() < 1e-12,
            "{wb:?}"
        );
        let wp = combine(&[path, under_b], Heuristic::POWER);
        assert!((wp[0] - 0.9).abs() < 1e-12, "{wp:?}");
        checked += 1;
    }
}

#[test]
fn bdpt_candidates_match_direct_evaluation() {
    let scene = TestScene::open_box();
    let (camera, look, bounce, light) = (
        CameraPoint::default(),
        LookDown::new(&scene),
        Bounce::new(&scene),
        LightSample::new(&scene),
    );
    // All (s, t) splits of a four-vertex path, ordered by s.
    let techniques = [
        Technique::new()
            .reversed(&bounce)
            .reversed(&bounce)
            .reversed(&bounce)
            .reversed(&light),
        Technique::new()
            .forward(&camera)
            .reversed(&bounce)
            .reversed(&bounce)
            .reversed(&light),
        Technique::new()
            .forward(&camera)
            .forward(&look)
            .reversed(&bounce)
            .reversed(&light),
        Technique::new()
            .forward(&camera)
            .forward(&look)
            .forward(&bounce)
            .reversed(&light),
        Technique::new()
            .forward(&camera)
            .forward(&look)
            .forward(&bounce)
            .forward(&bounce),
    ];
    for heuristic in [Heuristic::Balance, Heuristic::POWER, Heuristic::Power(3.0)] {
        let report = check_mis(&techniques, heuristic, 400, &mut Pcg32::new(21, 3)).unwrap();
        println!("{heuristic:?}: {report:?}");
        assert!(report.paths > 500, "{report:?}");
        assert!(report.mean_weights.iter().all(|&w| w > 0.0));
    }
    // On paths through the pinhole, s = 0 (a light path hitting a point) has weight zero.
    let mut rng = Pcg32::new(4, 4);
    let mut checked = 0;
    while checked < 200 {
        let Some(path) = techniques[3].sample(&mut rng) else {
            continue;
        };
        let candidates: Vec<_> = techniques
            .iter()
            .map(|t| t.assign(&path).unwrap())
            .collect();
        let w = combine(&candidates, Heuristic::POWER);
        assert_eq!(w[0], 0.0);
        assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        checked += 1;
    }
}

/// ∫ over the light of cos θₓ cos θ_y / (π r²) dA(y) from a floor point,
/// estimated by BSDF sampling and light sampling combined with MIS, against
/// a long light-sampling reference. Unbiased weights give the same mean.
#[test]
fn mis_estimator_is_unbiased() {
    let scene = TestScene::open_box();
    let (bounce, light) = (Bounce::new(&scene), LightSample::new(&scene));
    let x = scene.vertex_on(0, Vec3::new(0.3, -0.4, 0.0));
    let f = |y: &TestVertex| {
        if y.shape as usize != scene.light {
            return 0.0;
        }
        let d = y.position - x.position;
        let r2 = f64::from(d.length_squared());
        let w = d.normalize();
        f64::from(w.z.max(0.0)) * f64::from((-w).dot(y.normal()).max(0.0))
            / (std::f64::consts::PI * r2)
    };
    let base = RandomSequence::given([x]);
    let mut rng = Pcg32::new(77, 0);
    let n = 200_000;
    let (mut sum, mut sum2) = (0.0, 0.0);
    for _ in 0..n {
        let (mut a, mut b) = (base.clone(), base.clone());
        a.append(&bounce);
        b.append(&light);
        a.sample(&mut rng);
        b.sample(&mut rng);
        // A bounce that escapes contributes nothing, but still weighs the light sample.
        let w = combine(&[a.clone(), b.clone()], Heuristic::POWER);
        let mut estimate = 0.0;
        for (path, w) in [(&a, w[0]), (&b, w[1])] {
            if path.is_complete() {
                estimate += w * f(&path.vertices()[1]) / path.pdf().value();
            }
        }
        sum += estimate;
        sum2 += estimate * estimate;
    }
    let mean = sum / f64::from(n);
    let sigma = ((sum2 / f64::from(n) - mean * mean) / f64::from(n)).sqrt();
    // Reference: light sampling alone, many more samples.
    let (mut reference, m) = (0.0, 2_000_000);
    let d = light.distribution(Prefix::forward(std::slice::from_ref(&x)));
    for _ in 0..m {
        use aether_core::UniformSource;
        let s = d.sample(&[rng.next_f32(), rng.next_f32()]).unwrap();
        if let Step::Vertex(y) = s.value {
            reference += f(&y) / s.density.value();
        }
    }
    reference /= f64::from(m);
    println!("MIS {mean} ± {sigma}, reference {reference}");
    assert!(
        (mean - reference).abs() < 4.0 * sigma,
        "MIS {mean} ± {sigma} vs {reference}"
    );
}

#[test]
fn a_stopped_sequence_samples_nothing_more() {
    let scene = TestScene::open_box();
    let f = aether_core::testing::BidirectionalFixture::new(&scene);
    let mut rng = Pcg32::new(12, 0);
    // Bounces from the pinhole go up and often escape the open box.
    let mut checked = 0;
    while checked < 20 {
        let mut s = RandomSequence::new();
        s.append(&f.camera).append(&f.bounce).append(&f.bounce);
        if s.sample(&mut rng) == aether_core::StepKind::Vertex {
            continue;
        }
        let (len, technique) = (s.len(), s.technique_len());
        assert_eq!(technique, 3);
        s.append(&f.light);
        assert_ne!(s.sample(&mut rng), aether_core::StepKind::Vertex);
        assert_eq!(s.len(), len, "nothing is sampled after a failure");
        assert_eq!(s.technique_len(), 4);
        assert!(s.pdf().is_zero() && !s.is_complete());
        checked += 1;
    }
}

fn one<'a>(
    s: &'a dyn aether_core::DynStrategy<TestVertex>,
) -> aether_core::StrategyRef<'a, TestVertex> {
    aether_core::StrategyRef::One(s)
}

/// `weight_of_split`, which builds no candidate sequences, gives the
/// weights and own densities that `combine` gives for the same BDPT
/// candidates, with or without densities cached across candidates.
#[test]
fn weights_of_splits_match_combine_on_bdpt_candidates() {
    use aether_core::{Split, weight_of_split};
    let scene = TestScene::open_box();
    let f = aether_core::testing::BidirectionalFixture::new(&scene);
    let camera = [one(&f.camera), one(&f.look), one(&f.bounce)];
    let light = [one(&f.light), one(&f.bounce)];
    let mut rng = Pcg32::new(21, 0);
    let mut out = smallvec::SmallVec::new();
    let mut compared = 0;
    let mut cache = aether_core::DensityCache::new();
    for length in 2..7 {
        for _ in 0..200 {
            f.sample_candidates(length, &mut rng, &mut out);
            cache.clear();
            // Each candidate's split: its leading camera-side vertices.
            let splits: Vec<Split<'_, TestVertex>> = out
                .iter()
                .map(|c| {
                    let camera = (0..c.len()).take_while(|&i| !c.is_reversed(i)).count();
                    Split::new(camera, &[])
                })
                .collect();
            let expected = combine(&out, Heuristic::POWER);
            for (i, path) in out.iter().enumerate() {
                let (w, p) =
                    weight_of_split(path, &camera, &light, &splits, i, Heuristic::POWER, None);
                // Densities shared with the other candidates, from the cache.
                let (w_cached, p_cached) = weight_of_split(
                    path,
                    &camera,
                    &light,
                    &splits,
                    i,
                    Heuristic::POWER,
                    Some(&mut cache),
                );
                assert_eq!((w_cached, p_cached), (w, p));
                // The same weights with camera[1] varied, as splats vary it per pixel.
                let variants = [one(&f.look), one(&f.bounce)];
                let varied = aether_core::weights_of_split_variants(
                    path,
                    &camera,
                    &light,
                    &splits,
                    i,
                    Heuristic::POWER,
                    Some(&mut cache),
                    1,
                    &variants,
                );
                for (v, &(w_v, p_v)) in variants.iter().zip(&varied) {
                    let with = [camera[0], *v, camera[2]];
                    let expected =
                        weight_of_split(path, &with, &light, &splits, i, Heuristic::POWER, None);
                    assert!((w_v - expected.0).abs() < 1e-9, "{w_v} vs {}", expected.0);
                    let same = p_v.is_zero() && expected.1.is_zero()
                        || (p_v.value() / expected.1.value() - 1.0).abs() < 1e-9;
                    assert!(same, "{p_v} vs {}", expected.1);
                }
                let own = path.pdf();
                assert!(
                    (w - expected[i]).abs() < 1e-9,
                    "{length}: {w} vs {}",
                    expected[i]
                );
                let same =
                    own.is_zero() && p.is_zero() || (p.value() / own.value() - 1.0).abs() < 1e-9;
                assert!(same, "{p} vs {own}");
                compared += 1;
            }
        }
    }
    assert!(compared > 1000, "{compared}");
}

/// `weight_of_last_step` gives, bit for bit, the weights and own densities
/// that `weight_of_split` gives for a path tracer's two techniques (BSDF
/// sampling throughout, or direct light sampling of the last vertex), on
/// paths made by either, of every length.
#[test]
fn last_step_weights_match_splits_for_a_path_tracer() {
    use aether_core::{Split, weight_of_last_step, weight_of_split};
    let scene = TestScene::open_box();
    let (camera, look) = (CameraPoint::default(), LookDown::new(&scene));
    let (bounce, light) = (Bounce::new(&scene), LightSample::new(&scene));
    let strategies = [one(&camera), one(&look), one(&bounce)];
    let by_light = [(one(&light), false)];
    let mut rng = Pcg32::new(5, 0);
    let mut compared = [0; 2];
    for _ in 0..400 {
        let mut path = RandomSequence::new();
        path.append(&camera).append(&look);
        path.repeat(&bounce, 3 + (rng.next_u32() % 5) as usize, &mut rng);
        // Paths ended by a miss, and those that stopped at the camera's
        // first vertex, have no last step to choose.
        if !path.is_complete() || path.len() < 3 {
            continue;
        }
        let n = path.len();
        for (own, count) in compared.iter_mut().enumerate() {
            path.truncate(n - 1);
            let last: &dyn aether_core::DynStrategy<TestVertex> =
                if own == 0 { &bounce } else { &light };
            if !path.append_sample(last, &mut rng) {
                continue;
            }
            let splits = [Split::new(n, &[]), Split::new(n - 1, &by_light)];
            let expected = weight_of_split(
                &path,
                &strategies,
                &[],
                &splits,
                own,
                Heuristic::POWER,
                None,
            );
            let alternatives = [one(&bounce), one(&light)];
            let found = weight_of_last_step(&path, &alternatives, own, Heuristic::POWER);
            assert_eq!(
                found.0.to_bits(),
                expected.0.to_bits(),
                "{n} vertices, technique {own}"
            );
            assert_eq!(found.1.value().to_bits(), expected.1.value().to_bits());
            *count += 1;
        }
    }
    assert!(compared[0] > 100 && compared[1] > 100, "{compared:?}");
}

/// A light sample set aside and weighed by the next bounce
/// (`sample_aside`, `append_sample_beside`) has the weight
/// `weight_of_last_step` gives it on its own path, to the bit; the aside
/// is the vertex `append_sample` would have drawn, and the bounce too, from
/// the same uniforms.
#[test]
fn asides_weigh_as_the_last_step_and_sample_the_same() {
    use aether_core::weight_of_last_step;
    let scene = TestScene::open_box();
    let (camera, look) = (CameraPoint::default(), LookDown::new(&scene));
    let (bounce, light) = (Bounce::new(&scene), LightSample::new(&scene));
    let alternatives = [one(&bounce), one(&light)];
    let mut rng = Pcg32::new(9, 0);
    let mut compared = 0;
    for _ in 0..400 {
        let mut path = RandomSequence::new();
        path.append(&camera).append(&look);
        path.repeat(&bounce, 2 + (rng.next_u32() % 5) as usize, &mut rng);
        if !path.is_complete() {
            continue;
        }
        let (mut lit, mut twin) = (path.clone(), rng.clone());
        let Some(lamp) = path.sample_aside(&light, &mut rng) else {
            continue;
        };
        assert!(lit.append_sample(&light, &mut twin));
        assert_eq!(lit.vertices().last(), Some(&lamp.vertex));
        let (w, p) = weight_of_last_step(&lit, &alternatives, 1, Heuristic::POWER);
        let mut plain = path.clone();
        let (sampled, found) =
            path.append_sample_beside(&bounce, &mut rng, Some(&lamp), Heuristic::POWER);
        assert_eq!(found.to_bits(), p.weight_over(w).to_bits());
        assert_eq!(plain.append_sample(&bounce, &mut twin), sampled);
        assert_eq!(plain.vertices(), path.vertices());
        assert_eq!(twin.next_u32(), rng.next_u32(), "the same uniforms drawn");
        compared += 1;
    }
    assert!(compared > 200, "{compared}");
}
