//! The harness on composed strategies: a cosine bounce onto a plane, direct
//! sampling of a sphere light by its cone, a GGX reflection onto a plane,
//! light sampling by area over two triangles (by points, and by points
//! with their barycentrics), a bounce with Russian
//! roulette, whose termination is an event of probability 1 − q, and a
//! strategy taken for a share of the samples ([`Sometimes`]).

use aether_core::harness::{Check, Grid, check_strategy};
use aether_core::primitives::{
    CosineHemisphere, DiscreteDistribution, GgxVisibleNormals, Reflect, UniformCone,
};
use aether_core::testing::{
    Bounce, LightSample, RectChart, SphereChart, TestScene, TestVertex, facing_normal,
};
use aether_core::{
    Distribution, Frame, InFrame, Intersect, OnTriangle, Prefix, RussianRoulette, Select,
    Sometimes, Step, Strategy,
};
use glam::Vec3;

const FLOOR: usize = 0;
const WALL_X: usize = 3;
const SPHERE: usize = 6;

fn floor_point(scene: &TestScene) -> TestVertex {
    scene.vertex_on(FLOOR, Vec3::new(-0.5, -0.5, 0.0))
}

/// Direct sampling of the sphere as a light: a uniform direction in the
/// cone it subtends, then a ray.
struct SphereLight<'s>(&'s TestScene);

impl Strategy<TestVertex> for SphereLight<'_> {
    fn distribution<'a>(
        &'a self,
        prefix: Prefix<'a, TestVertex>,
    ) -> impl Distribution<Value = Step<TestVertex>> + 'a {
        let x = prefix.last().expect("a shading point");
        let aether_core::testing::Shape::Sphere { center, radius } = self.0.shapes[SPHERE] else {
            unreachable!()
        };
        let to_center = center - x.position;
        let cone = UniformCone::subtended(
            f64::from(radius * radius),
            f64::from(to_center.length_squared()),
        );
        Intersect::new(
            x,
            InFrame::new(Frame::from_normal(to_center.normalize()), cone),
            self.0,
        )
    }
    fn memory(&self) -> usize {
        1
    }
}

/// Glossy reflection: GGX visible normals about the shading normal,
/// reflected, then a ray.
struct Glossy<'s>(&'s TestScene, f32);

impl Strategy<TestVertex> for Glossy<'_> {
    fn distribution<'a>(
        &'a self,
        prefix: Prefix<'a, TestVertex>,
    ) -> impl Distribution<Value = Step<TestVertex>> + 'a {
        let x = prefix.last().expect("a shading point");
        let from = prefix.back(1).expect("an incoming direction");
        let frame = Frame::from_normal(facing_normal(x, Some(from)));
        let wi = frame.to_local((from.position - x.position).normalize());
        let lobe = Reflect::new(wi, GgxVisibleNormals::new(self.1, self.1, wi));
        Intersect::new(x, InFrame::new(frame, lobe), self.0)
    }
    fn memory(&self) -> usize {
        2
    }
}

/// A diffuse bounce continued with probability q.
struct RouletteBounce<'s>(&'s TestScene, f64);

impl Strategy<TestVertex> for RouletteBounce<'_> {
    fn distribution<'a>(
        &'a self,
        prefix: Prefix<'a, TestVertex>,
    ) -> impl Distribution<Value = Step<TestVertex>> + 'a {
        let x = prefix.last().expect("a shading point");
        let frame = Frame::from_normal(facing_normal(x, prefix.back(1)));
        RussianRoulette::new(
            self.1,
            Intersect::new(x, InFrame::new(frame, CosineHemisphere), self.0),
        )
    }
    // The side it turns to reads the vertex before the last.
    fn memory(&self) -> usize {
        2
    }
}

fn passes<S: Strategy<TestVertex>>(
    s: &S,
    prefix: &[TestVertex],
    chart: &impl aether_core::harness::Chart<Step<TestVertex>>,
) -> aether_core::harness::Report {
    let r = check_strategy(s, prefix, chart, &Check::default()).unwrap_or_else(|f| panic!("{f}"));
    println!("{r}");
    r
}

#[test]
fn cosine_bounce_onto_a_wall() {
    let scene = TestScene::open_box();
    let r = passes(
        &Bounce::new(&scene),
        &[floor_point(&scene)],
        &Grid::new(RectChart::new(&scene, WALL_X), 16),
    );
    assert!(r.jacobian_checked > 100, "{r}");
    assert!(
        r.integral > 0.05 && r.integral < 0.5,
        "the wall takes part of the hemisphere: {r}"
    );
}

#[test]
fn sphere_light_by_cone_then_intersect() {
    let scene = TestScene::open_box();
    let x = floor_point(&scene);
    let r = passes(
        &SphereLight(&scene),
        &[x],
        &Grid::new(SphereChart::visible_from(&scene, SPHERE, x.position), 16),
    );
    assert!(
        (r.integral - 1.0).abs() < 2e-3,
        "every cone direction hits the visible cap: {r}"
    );
}

#[test]
fn ggx_reflection_then_intersect() {
    let scene = TestScene::open_box();
    let camera = TestVertex::point(Vec3::new(0.6, 0.2, 1.2));
    let r = passes(
        &Glossy(&scene, 0.35),
        &[camera, floor_point(&scene)],
        &Grid::new(RectChart::new(&scene, WALL_X), 16),
    );
    assert!(r.jacobian_checked > 100, "{r}");
}

#[test]
fn light_sampling_by_area_over_triangles() {
    let scene = TestScene::open_box();
    let r = passes(
        &LightSample::new(&scene),
        &[floor_point(&scene)],
        &Grid::new(RectChart::new(&scene, scene.light), 16),
    );
    assert!((r.integral - 1.0).abs() < 1e-6, "{r}");
}

/// [`LightSample`] with its points built from their barycentrics, which
/// must give back the sampled point; its two triangles are equal.
struct BarycentricLight<'s>(&'s TestScene, DiscreteDistribution);

impl Strategy<TestVertex> for BarycentricLight<'_> {
    fn distribution<'a>(
        &'a self,
        _prefix: Prefix<'a, TestVertex>,
    ) -> impl Distribution<Value = Step<TestVertex>> + 'a {
        let scene = self.0;
        let on_light = move |i: usize| {
            let triangle = scene.light_triangle(i);
            OnTriangle::new(triangle, move |p, b| {
                let [p0, p1, p2] = triangle.corners();
                let q = b[0] * p0 + b[1] * p1 + b[2] * p2;
                assert!((q - p).length() < 1e-5, "{b:?} give {q}, not {p}");
                Some(scene.vertex_on(scene.light, q))
            })
        };
        let which = move |v: &Step<TestVertex>| scene.light_triangle_of(v);
        Select::new(&self.1, 2, on_light, which)
    }
    fn memory(&self) -> usize {
        0
    }
}

#[test]
fn light_sampling_by_barycentrics_over_triangles() {
    let scene = TestScene::open_box();
    let halves = DiscreteDistribution::new(&[1.0, 1.0]).expect("two weights");
    let r = passes(
        &BarycentricLight(&scene, halves),
        &[floor_point(&scene)],
        &Grid::new(RectChart::new(&scene, scene.light), 16),
    );
    assert!((r.integral - 1.0).abs() < 1e-6, "{r}");
    assert!(r.jacobian_checked > 100, "{r}");
}

#[test]
fn russian_roulette_termination_is_an_event() {
    let scene = TestScene::open_box();
    let q = 0.7;
    let s = RouletteBounce(&scene, q);
    let x = floor_point(&scene);
    passes(&s, &[x], &Grid::new(RectChart::new(&scene, WALL_X), 16));
    // The terminated event carries 1 − q; a continued vertex carries q.
    let d = s.distribution(Prefix::forward(std::slice::from_ref(&x)));
    assert!((d.density(&Step::Terminated).value() - (1.0 - q)).abs() < 1e-12);
    let hit = d.sample(&[0.2, 0.5]).expect("continued").value;
    let plain = Bounce::new(&scene)
        .distribution(Prefix::forward(std::slice::from_ref(&x)))
        .density(&hit);
    assert!((d.density(&hit).value() - q * plain.value()).abs() < 1e-12 * plain.value());
}

#[test]
fn a_strategy_taken_sometimes_carries_its_share() {
    let scene = TestScene::open_box();
    let x = floor_point(&scene);
    for q in [0.5, 0.9] {
        let s = Sometimes::new(q, Bounce::new(&scene));
        let r = passes(&s, &[x], &Grid::new(RectChart::new(&scene, WALL_X), 16));
        assert!(r.jacobian_checked > 100, "{r}");
        let d = s.distribution(Prefix::forward(std::slice::from_ref(&x)));
        assert!((d.density(&Step::Terminated).value() - (1.0 - q)).abs() < 1e-12);
        let hit = d.sample(&[0.1, 0.5]).expect("taken").value;
        let plain = Bounce::new(&scene)
            .distribution(Prefix::forward(std::slice::from_ref(&x)))
            .density(&hit);
        assert!((d.density(&hit).value() - q * plain.value()).abs() < 1e-12 * plain.value());
    }
}

#[test]
fn density_mode_casts_no_rays() {
    /// A scene whose ray caster must never be called.
    struct NoRays;
    impl aether_core::RayCaster<TestVertex> for NoRays {
        fn cast(&self, _: &TestVertex, _: Vec3) -> Option<TestVertex> {
            panic!("density mode cast a ray")
        }
    }
    let scene = TestScene::open_box();
    let x = floor_point(&scene);
    let hit = Bounce::new(&scene)
        .distribution(Prefix::forward(std::slice::from_ref(&x)))
        .sample(&[0.3, 0.3])
        .unwrap();
    let blind = Intersect::new(
        &x,
        InFrame::new(Frame::from_normal(Vec3::Z), CosineHemisphere),
        NoRays,
    );
    assert_eq!(blind.density(&hit.value), hit.density);
}
