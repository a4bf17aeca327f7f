//! Two-vertex steps: a segment through a portal, its Jacobian from the
//! line measure, and MIS between paths that contain it forward, reversed,
//! or not at all.

use aether_core::harness::{Check, Technique, check_mis, check_pointwise};
use aether_core::primitives::{UniformCone, UniformHemisphere, UniformTriangle};
use aether_core::testing::{Bounce, CameraPoint, LookDown, TestScene, TestVertex};
use aether_core::{
    Distribution, Either, Frame, Heuristic, InFrame, PairStrategy, Pcg32, Prefix, RandomSequence,
    Segment, Step, StepKind, combine,
};
use glam::Vec3;

/// A horizontal triangular opening at z = 1 in the middle of the box;
/// lines through it in uniform directions of the upper hemisphere, or of a
/// cone that keeps clear of grazing lines.
struct Portal<'s> {
    scene: &'s TestScene,
    opening: UniformTriangle,
    cone: Option<UniformCone>,
}

impl<'s> Portal<'s> {
    fn new(scene: &'s TestScene) -> Self {
        let opening = UniformTriangle::new(
            Vec3::new(-0.3, -0.3, 1.0),
            Vec3::new(0.3, -0.3, 1.0),
            Vec3::new(0.0, 0.4, 1.0),
        );
        Portal {
            scene,
            opening,
            cone: None,
        }
    }
}

impl PairStrategy<TestVertex> for Portal<'_> {
    fn distribution<'a>(
        &'a self,
        _prefix: Prefix<'a, TestVertex>,
    ) -> impl Distribution<Value = Step<(TestVertex, TestVertex)>> + 'a {
        let directions = match self.cone {
            Some(cone) => Either::Left(cone),
            None => Either::Right(UniformHemisphere),
        };
        Segment::new(
            self.opening,
            InFrame::new(Frame::WORLD, directions),
            Vec3::Z,
            Vec3::Z,
            |y| TestVertex::on_surface(y, Vec3::Z),
            self.scene,
        )
    }
    fn memory(&self) -> usize {
        0
    }
}

/// Lines that graze the portal (cos θ_y → 0) make the map from (y, ω) to
/// the end points nearly singular, below the resolution of single-precision
/// finite differences; the Jacobian is checked on lines within 72° of the
/// normal.
#[test]
fn segment_jacobian_is_the_line_measure() {
    let scene = TestScene::open_box();
    let portal = Portal {
        cone: Some(UniformCone::new(0.3)),
        ..Portal::new(&scene)
    };
    let d = portal.distribution(Prefix::forward(&[]));
    let report = check_pointwise(&d, &Check::default()).unwrap_or_else(|f| panic!("{f}"));
    println!("{report}");
    assert!(report.jacobian_checked > 200, "{report}");
}

#[test]
fn mis_with_forward_and_reversed_segments() {
    let scene = TestScene::open_box();
    let (camera, look, bounce, portal) = (
        CameraPoint::default(),
        LookDown::new(&scene),
        Bounce::new(&scene),
        Portal::new(&scene),
    );
    let techniques = [
        Technique::new()
            .forward(&camera)
            .forward(&look)
            .forward(&bounce),
        Technique::new().forward(&camera).forward_pair(&portal),
        Technique::new().forward(&camera).reversed_pair(&portal),
    ];
    for heuristic in [Heuristic::Balance, Heuristic::POWER] {
        let report = check_mis(&techniques, heuristic, 3000, &mut Pcg32::new(8, 8)).unwrap();
        println!("{heuristic:?}: {report:?}");
        assert!(report.paths > 3000, "{report:?}");
        assert!(report.mean_weights.iter().all(|&w| w > 0.01), "{report:?}");
    }

    // A bounce path through the opening is weighed against the segment.
    let mut rng = Pcg32::new(2, 5);
    let mut shared = 0;
    for _ in 0..20_000 {
        let Some(path) = techniques[0].sample(&mut rng) else {
            continue;
        };
        let as_segment = techniques[1].assign(&path).unwrap();
        let w = combine(&[path.clone(), as_segment.clone()], Heuristic::POWER);
        if w[0] > 0.0 && w[1] > 0.0 {
            shared += 1;
            assert!((w[0] + w[1] - 1.0).abs() < 1e-12);
            // Slicing through the pair turns its first vertex into a given one.
            let cut = as_segment.slice(0..2);
            assert_eq!(cut.strategy_name(1), None);
        }
    }
    assert!(
        shared > 50,
        "only {shared} bounce paths crossed the opening"
    );
}

#[test]
fn reversing_keeps_pair_densities() {
    let scene = TestScene::open_box();
    let portal = Portal::new(&scene);
    let mut rng = Pcg32::new(6, 0);
    let mut checked = 0;
    while checked < 100 {
        let mut s = RandomSequence::new();
        s.append_pair(&portal);
        if s.sample(&mut rng) != StepKind::Vertex {
            continue;
        }
        let p = s.pdf();
        let twice = s.reversed().reversed();
        assert_eq!(twice.pdf(), p);
        let reversed = s.reversed();
        // Reversed, the pair is conditioned on the (empty) suffix: the same density.
        assert_eq!(reversed.pdf().value(), p.value());
        checked += 1;
    }
}

/// Building paths in place (`truncate`, `extend_from`) gives the same
/// vertices and densities as `slice`, `concat` and `reversed`, and a cut
/// through a pair leaves its halves without density.
#[test]
fn building_in_place_matches_slicing() {
    let scene = TestScene::open_box();
    let (portal, camera, look, bounce) = (
        Portal::new(&scene),
        CameraPoint::default(),
        LookDown::new(&scene),
        Bounce::new(&scene),
    );
    let mut rng = Pcg32::new(11, 0);
    let mut checked = 0;
    while checked < 50 {
        let mut eye = RandomSequence::new();
        eye.append(&camera).append(&look).append(&bounce);
        let mut pair = RandomSequence::new();
        pair.append_pair(&portal).append(&bounce);
        if eye.sample(&mut rng) != StepKind::Vertex || pair.sample(&mut rng) != StepKind::Vertex {
            continue;
        }
        let expected = eye.slice(0..2).concat(&pair.reversed());
        let mut built = RandomSequence::new();
        built
            .extend_from(&eye, 0..2, false)
            .extend_from(&pair, 0..3, true);
        assert_eq!(built.vertices(), expected.vertices());
        assert_eq!(built.pdf(), expected.pdf());
        assert!(!built.pdf().is_zero());

        let mut truncated = pair.clone();
        truncated.truncate(1);
        assert_eq!(truncated.vertices(), pair.slice(0..1).vertices());
        assert!(truncated.pdf().is_zero(), "half a pair has no density");
        let mut whole = eye.clone();
        whole.append(&bounce).sample(&mut rng);
        whole.truncate(3);
        assert!(whole.is_complete());
        assert_eq!(whole.pdf(), eye.pdf());
        checked += 1;
    }
}
