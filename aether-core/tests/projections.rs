//! The harness on the projection blocks: a camera's film plane onto
//! directions (Gnomonic), affine maps of the plane, an environment map onto
//! the sphere (Equirect), an aperture in space (Planar), directions onto a
//! sphere (SpherePoint), vertices at infinity (environment, directional and
//! Dirac lights) and the parallel rays of a distant light's far disk.

use std::f64::consts::{PI, TAU};

use aether_core::harness::{
    Chart, Check, Grid, Parameterization, Report, SphereDirections, check, check_strategy,
};
use aether_core::primitives::{
    Affine2, CosineHemisphere, DiracDirection, Equirect, Gnomonic, PiecewiseConstant2D, Planar,
    SpherePoint, UniformCone, UniformDisk,
};
use aether_core::testing::{RectChart, TestScene, TestVertex};
use aether_core::{
    AtInfinity, Distribution, Embed, Frame, Geometry, InFrame, Measure, ParallelRays, Prefix, Step,
    Strategy,
};
use glam::{Vec2, Vec3};

const FLOOR: usize = 0;

fn run<D>(name: &str, d: &D, chart: &impl Chart<D::Value>) -> Report
where
    D: Distribution,
    D::Value: Embed + std::fmt::Debug,
{
    let r = check(d, chart, &Check::default()).unwrap_or_else(|f| panic!("{name}: {f}"));
    println!("{name}: {r}");
    r
}

/// A table with zero, dim and bright cells, so that densities vary by cell.
fn table(width: usize, height: usize) -> PiecewiseConstant2D {
    let values: Vec<f64> = (0..width * height)
        .map(|i| ((i * 7919) % 13) as f64 + if i % 5 == 0 { 0.0 } else { 0.5 })
        .collect();
    PiecewiseConstant2D::new(&values, width, height).expect("a positive table")
}

/// Directions of the cone about +z with cos θ ≥ `0`, by
/// ((1 − cos θ)/(1 − cos θ_max), φ/2π): an equal-area chart unrelated to
/// the gnomonic map.
struct ConeChart(f64);

impl Parameterization<Vec3> for ConeChart {
    fn dims(&self) -> usize {
        2
    }
    fn value(&self, s: [f64; 2]) -> Option<Vec3> {
        let omc = s[0] * (1.0 - self.0);
        let sin = (omc * (2.0 - omc)).sqrt();
        let phi = TAU * s[1];
        Some(Vec3::new(
            (sin * phi.cos()) as f32,
            (sin * phi.sin()) as f32,
            (1.0 - omc) as f32,
        ))
    }
    fn coords(&self, w: &Vec3) -> Option<[f64; 2]> {
        let w = w.as_dvec3().normalize();
        let omc = if w.z > 0.0 {
            (w.x * w.x + w.y * w.y) / (1.0 + w.z)
        } else {
            1.0 - w.z
        };
        Some([omc / (1.0 - self.0), turn(w.y, w.x)])
    }
    fn jacobian(&self, _s: [f64; 2]) -> f64 {
        TAU * (1.0 - self.0)
    }
}

fn turn(y: f64, x: f64) -> f64 {
    let phi = y.atan2(x);
    if phi < 0.0 {
        phi / TAU + 1.0
    } else {
        phi / TAU
    }
}

/// The rectangle [min, max] of the plane.
struct Rect2 {
    min: Vec2,
    max: Vec2,
}

impl Parameterization<Vec2> for Rect2 {
    fn dims(&self) -> usize {
        2
    }
    fn value(&self, s: [f64; 2]) -> Option<Vec2> {
        let (min, size) = (self.min.as_dvec2(), (self.max - self.min).as_dvec2());
        Some((min + glam::DVec2::new(s[0], s[1]) * size).as_vec2())
    }
    fn coords(&self, p: &Vec2) -> Option<[f64; 2]> {
        let s = (p.as_dvec2() - self.min.as_dvec2()) / (self.max - self.min).as_dvec2();
        Some([s.x, s.y])
    }
    fn jacobian(&self, _s: [f64; 2]) -> f64 {
        let size = (self.max - self.min).as_dvec2();
        size.x * size.y
    }
}

/// The rectangle corner + s₀ a + s₁ b in space, with orthogonal edges.
struct SpaceRect {
    corner: Vec3,
    a: Vec3,
    b: Vec3,
}

impl Parameterization<Vec3> for SpaceRect {
    fn dims(&self) -> usize {
        2
    }
    fn value(&self, s: [f64; 2]) -> Option<Vec3> {
        Some(
            (self.corner.as_dvec3() + s[0] * self.a.as_dvec3() + s[1] * self.b.as_dvec3())
                .as_vec3(),
        )
    }
    fn coords(&self, p: &Vec3) -> Option<[f64; 2]> {
        let d = (*p - self.corner).as_dvec3();
        let (a, b) = (self.a.as_dvec3(), self.b.as_dvec3());
        Some([d.dot(a) / a.length_squared(), d.dot(b) / b.length_squared()])
    }
    fn jacobian(&self, _s: [f64; 2]) -> f64 {
        self.a.as_dvec3().cross(self.b.as_dvec3()).length()
    }
}

/// The sphere (centre, radius) by the equal-area chart of directions.
struct SphereSurface(Vec3, f32);

impl Parameterization<Vec3> for SphereSurface {
    fn dims(&self) -> usize {
        2
    }
    fn value(&self, s: [f64; 2]) -> Option<Vec3> {
        let w = SphereDirections.value(s)?;
        Some((self.0.as_dvec3() + f64::from(self.1) * w.as_dvec3()).as_vec3())
    }
    fn coords(&self, p: &Vec3) -> Option<[f64; 2]> {
        SphereDirections.coords(&(*p - self.0))
    }
    fn jacobian(&self, _s: [f64; 2]) -> f64 {
        4.0 * PI * f64::from(self.1).powi(2)
    }
}

/// Vertices at infinity, charted by their directions.
struct Sky<P>(P);

impl<P: Parameterization<Vec3>> Parameterization<Step<TestVertex>> for Sky<P> {
    fn dims(&self) -> usize {
        self.0.dims()
    }
    fn value(&self, s: [f64; 2]) -> Option<Step<TestVertex>> {
        Some(Step::Vertex(TestVertex::at_infinity(self.0.value(s)?)))
    }
    fn coords(&self, v: &Step<TestVertex>) -> Option<[f64; 2]> {
        match v {
            Step::Vertex(TestVertex {
                geometry: Geometry::AtInfinity { direction },
                ..
            }) => self.0.coords(direction),
            _ => None,
        }
    }
    fn jacobian(&self, s: [f64; 2]) -> f64 {
        self.0.jacobian(s)
    }
}

/// The part [min, max] of the test scene's floor.
struct FloorPatch<'s> {
    scene: &'s TestScene,
    min: Vec2,
    max: Vec2,
}

impl Parameterization<Step<TestVertex>> for FloorPatch<'_> {
    fn dims(&self) -> usize {
        2
    }
    fn value(&self, s: [f64; 2]) -> Option<Step<TestVertex>> {
        let p = Rect2 {
            min: self.min,
            max: self.max,
        }
        .value(s)?;
        Some(Step::Vertex(
            self.scene.vertex_on(FLOOR, Vec3::new(p.x, p.y, 0.0)),
        ))
    }
    fn coords(&self, v: &Step<TestVertex>) -> Option<[f64; 2]> {
        let Step::Vertex(v) = v else { return None };
        (v.shape as usize == FLOOR).then_some(())?;
        Rect2 {
            min: self.min,
            max: self.max,
        }
        .coords(&v.position.truncate())
    }
    fn jacobian(&self, _s: [f64; 2]) -> f64 {
        let size = (self.max - self.min).as_dvec2();
        size.x * size.y
    }
}

#[test]
fn gnomonic_camera_over_a_tabulated_film() {
    // The film [−0.6, 0.4] × [−0.4, 0.6]: off-centre, corners at cos θ ≈ 0.76.
    let camera = Gnomonic::new(table(12, 8), Vec2::new(-0.6, -0.4));
    let r = run("gnomonic", &camera, &Grid::new(ConeChart(0.7), 16));
    assert!(r.jacobian_checked > 300, "{r}");
    assert!((r.integral - 1.0).abs() < 2e-3, "{r}");
    // Behind the film there is nothing.
    assert!(camera.density(&Vec3::new(0.1, 0.0, -0.9)).is_zero());
    assert!(camera.invert(&Vec3::new(0.1, 0.0, -0.9)).is_none());
    assert_eq!(camera.density(&Vec3::NEG_Z).measure(), Measure::SolidAngle);
}

#[test]
fn gnomonic_wide_angle_through_an_affine_film() {
    // A 3 × 2 film at distance 1 (about 113° across), shifted sideways.
    let film = Affine2::new(table(6, 5), Vec2::new(3.0, 2.0), Vec2::new(-1.5, -1.0));
    let camera = Gnomonic::new(film, Vec2::new(0.2, 0.0));
    let r = run("gnomonic wide", &camera, &Grid::new(ConeChart(0.4), 16));
    assert!(r.jacobian_checked > 300, "{r}");
    assert!((r.integral - 1.0).abs() < 2e-3, "{r}");
    // At the principal point's film position the density is p(q) / cos³θ with cos θ = 1.
    let axis = camera.density(&Vec3::Z).value();
    let q = Vec2::new(-0.2, 0.0);
    let film = Affine2::new(table(6, 5), Vec2::new(3.0, 2.0), Vec2::new(-1.5, -1.0));
    assert!((axis - film.density(&q).value()).abs() < 1e-9 * axis);
}

#[test]
fn affine2_with_a_mirrored_axis() {
    let d = Affine2::new(table(12, 8), Vec2::new(2.0, -0.5), Vec2::new(-1.0, 0.25));
    let r = run(
        "affine2",
        &d,
        &Grid::new(
            Rect2 {
                min: Vec2::new(-1.0, -0.25),
                max: Vec2::new(1.0, 0.25),
            },
            24,
        ),
    );
    assert!(r.jacobian_checked > 300, "{r}");
    assert!((r.integral - 1.0).abs() < 2e-3, "{r}");
    assert!(d.density(&Vec2::new(0.0, 0.3)).is_zero());
}

#[test]
fn equirect_environment_map() {
    let sky = Equirect::new(table(16, 8));
    let r = run("equirect", &sky, &Grid::new(SphereDirections, 16));
    assert!(r.jacobian_checked > 300, "{r}");
    assert!((r.integral - 1.0).abs() < 2e-3, "{r}");
}

#[test]
fn equirect_follows_mitsubas_convention() {
    use aether_core::primitives::UniformSquare;
    let sky = Equirect::new(UniformSquare);
    let at = |u: f32, v: f32| sky.sample(&[u, v]).unwrap().value;
    let close = |a: Vec3, b: Vec3| (a - b).length() < 1e-6;
    assert!(close(at(0.0, 0.5), Vec3::NEG_Z));
    assert!(close(at(0.25, 0.5), Vec3::X));
    assert!(close(at(0.5, 0.5), Vec3::Z));
    assert!(close(at(0.75, 0.5), Vec3::NEG_X));
    assert!(at(0.3, 1e-4).y > 0.9999);
    assert!(at(0.3, 1.0 - 1e-4).y < -0.9999);
    // The inverse wraps u into [0, 1) and keeps θ accurate near the pole.
    let u = sky
        .invert(&Vec3::new(-1e-3, 0.0, -1.0).normalize())
        .unwrap();
    assert!(u[0] > 0.999 && u[0] < 1.0, "{u:?}");
    let w = Vec3::new(3e-4, 1.0, -2e-4).normalize();
    let u = sky.invert(&w).unwrap();
    let theta = 3e-4f64.hypot(2e-4);
    assert!((f64::from(u[1]) - theta / PI).abs() < 1e-9, "{u:?}");
    // Density 1 / (2π² sin θ) for the uniform square.
    let p = sky.density(&w).value();
    assert!((p * 2.0 * PI * PI * theta - 1.0).abs() < 1e-4, "{p}");
}

#[test]
fn planar_aperture_of_a_thin_lens() {
    let frame = Frame::from_normal(Vec3::new(0.3, 0.2, -1.0).normalize());
    let origin = Vec3::new(0.2, -0.1, 1.5);
    let lens = Planar::new(UniformDisk::new(0.3), origin, frame.s, frame.t);
    // A square of side 0.7 about the centre, turned by 30° in the plane.
    let (sin, cos) = 30f32.to_radians().sin_cos();
    let (a, b) = (
        cos * frame.s + sin * frame.t,
        -sin * frame.s + cos * frame.t,
    );
    let chart = SpaceRect {
        corner: origin - 0.35 * a - 0.35 * b,
        a: 0.7 * a,
        b: 0.7 * b,
    };
    let r = run("planar", &lens, &Grid::new(chart, 16));
    assert!(r.jacobian_checked > 400, "{r}");
    assert!((r.integral - 1.0).abs() < 2e-3, "{r}");
    let on = origin + 0.1 * frame.s - 0.2 * frame.t;
    assert!((lens.density(&on).value() - 1.0 / (PI * 0.09)).abs() < 1e-6);
    assert!(lens.density(&(on + 1e-3 * frame.n)).is_zero());
    assert!(lens.invert(&(on + 1e-3 * frame.n)).is_none());
}

#[test]
fn sphere_point_by_cosine_directions() {
    let (center, radius) = (Vec3::new(0.4, 0.3, 0.35), 0.35);
    let frame = Frame::from_normal(Vec3::new(-0.5, 0.2, 0.8).normalize());
    let d = SpherePoint::new(InFrame::new(frame, CosineHemisphere), center, radius);
    let r = run(
        "sphere point",
        &d,
        &Grid::new(SphereSurface(center, radius), 16),
    );
    assert!(r.jacobian_checked > 300, "{r}");
    assert!((r.integral - 1.0).abs() < 2e-3, "{r}");
    let p = center + radius * frame.n;
    let expected = 1.0 / (PI * f64::from(radius).powi(2));
    assert!((d.density(&p).value() - expected).abs() < 1e-5 * expected);
    assert!(d.density(&(center + 1.01 * radius * frame.n)).is_zero());
    assert!(d.invert(&(center + 0.99 * radius * frame.n)).is_none());
}

#[test]
fn sphere_point_of_a_cone() {
    // A cap of a large sphere far from the origin.
    let (center, radius) = (Vec3::new(30.0, -20.0, 10.0), 4.0);
    let frame = Frame::from_normal(Vec3::new(0.2, 0.9, -0.1).normalize());
    let d = SpherePoint::new(InFrame::new(frame, UniformCone::new(-0.2)), center, radius);
    run(
        "sphere point (cone)",
        &d,
        &Grid::new(SphereSurface(center, radius), 16),
    );
}

/// An environment light sampled by its map, whatever the prefix.
struct EnvironmentLight(PiecewiseConstant2D);

impl Strategy<TestVertex> for EnvironmentLight {
    fn distribution<'a>(
        &'a self,
        _prefix: Prefix<'a, TestVertex>,
    ) -> impl Distribution<Value = Step<TestVertex>> + 'a {
        AtInfinity::new(Equirect::new(&self.0), TestVertex::at_infinity)
    }
    fn memory(&self) -> usize {
        0
    }
}

#[test]
fn at_infinity_environment_light() {
    let scene = TestScene::open_box();
    let x = scene.vertex_on(FLOOR, Vec3::new(-0.5, -0.5, 0.0));
    let r = check_strategy(
        &EnvironmentLight(table(16, 8)),
        &[x],
        &Grid::new(Sky(SphereDirections), 16),
        &Check::default(),
    )
    .unwrap_or_else(|f| panic!("{f}"));
    println!("at infinity (environment): {r}");
    assert!(r.jacobian_checked > 300, "{r}");
    assert!((r.integral - 1.0).abs() < 2e-3, "{r}");
    // Only vertices at infinity have a density, in solid angle.
    let env = AtInfinity::new(Equirect::new(table(16, 8)), TestVertex::at_infinity);
    for v in [x, TestVertex::point(Vec3::ONE)] {
        let p = env.density(&Step::Vertex(v));
        assert!(p.is_zero() && p.measure() == Measure::SolidAngle);
        assert!(env.invert(&Step::Vertex(v)).is_none());
    }
}

#[test]
fn at_infinity_directional_cone() {
    // A sun of 25° half-angle low in the sky.
    let frame = Frame::from_normal(Vec3::new(0.7, -0.3, 0.4).normalize());
    let sun = AtInfinity::new(
        InFrame::new(frame, UniformCone::new(25f64.to_radians().cos())),
        TestVertex::at_infinity,
    );
    let r = run(
        "at infinity (cone)",
        &sun,
        &Grid::new(Sky(SphereDirections), 32),
    );
    assert!(r.jacobian_checked > 400, "{r}");
}

#[test]
fn at_infinity_dirac_direction() {
    let w = Vec3::new(0.0, 0.6, 0.8);
    let sun = AtInfinity::new(DiracDirection::new(w, 1.0), TestVertex::at_infinity);
    let r = run(
        "at infinity (Dirac)",
        &sun,
        &Grid::new(Sky(SphereDirections), 8),
    );
    assert_eq!(r.jacobian_checked, 0);
    assert!((r.integral - 1.0).abs() < 1e-9, "{r}");
    let p = sun.density(&Step::Vertex(TestVertex::at_infinity(w)));
    assert!(p.is_dirac() && p.measure() == Measure::SolidAngle);
    let off = TestVertex::at_infinity(Vec3::new(0.0, 0.8, 0.6));
    assert!(sun.density(&Step::Vertex(off)).is_zero());
}

/// A directional light: parallel rays from a disk of radius 2 about the
/// box's centre, whatever the prefix.
struct Sun<'s> {
    scene: &'s TestScene,
    toward: Vec3,
}

impl Strategy<TestVertex> for Sun<'_> {
    fn distribution<'a>(
        &'a self,
        _prefix: Prefix<'a, TestVertex>,
    ) -> impl Distribution<Value = Step<TestVertex>> + 'a {
        ParallelRays::new(
            self.toward,
            Vec3::new(0.0, 0.0, 1.0),
            2.0,
            UniformDisk::new(2.0),
            TestVertex::point,
            self.scene,
        )
    }
    fn memory(&self) -> usize {
        0
    }
}

#[test]
fn parallel_rays_from_above_onto_a_lit_floor_patch() {
    let scene = TestScene::open_box();
    let toward = Vec3::new(0.3, -0.2, 1.0).normalize();
    // The patch sees the source past the walls, the light and the sphere:
    // the density mode knows nothing of occlusion, so the chart must not
    // include shadows.
    let chart = FloorPatch {
        scene: &scene,
        min: Vec2::new(-1.0, -0.5),
        max: Vec2::new(0.3, -0.1),
    };
    let sun = Sun {
        scene: &scene,
        toward,
    };
    let r = check_strategy(&sun, &[], &Grid::new(chart, 16), &Check::default())
        .unwrap_or_else(|f| panic!("{f}"));
    println!("parallel rays (from above, floor patch): {r}");
    // Half of the disk's rays pass outside the box and miss.
    assert!(r.jacobian_checked > 150, "{r}");
    // p_A = |cos| / (π r²) on the floor, over 1.3 × 0.4.
    let expected = 0.52 * f64::from(toward.z) / (PI * 4.0);
    assert!((r.integral - expected).abs() < 1e-3 * expected, "{r}");
    // Isolated points, vertices at infinity and points beyond the disk: zero.
    let d = sun.distribution(Prefix::forward(&[]));
    for v in [
        TestVertex::point(Vec3::new(0.0, 0.0, 0.5)),
        TestVertex::at_infinity(-toward),
        TestVertex::on_surface(Vec3::new(0.0, 0.0, 1.0) + 2.1 * toward, Vec3::Z),
    ] {
        assert!(d.density(&Step::Vertex(v)).is_zero(), "{v:?}");
        assert!(d.invert(&Step::Vertex(v)).is_none(), "{v:?}");
    }
}

#[test]
fn parallel_rays_from_below_through_a_tabulated_disk() {
    // From below, nothing stands between the disk and the floor's underside:
    // the whole floor is charted. The source's radiance varies over a table
    // covering the disk.
    let scene = TestScene::open_box();
    let toward = Vec3::new(0.3, -0.2, -1.0).normalize();
    let points = Affine2::new(table(8, 8), Vec2::splat(4.0), Vec2::splat(-2.0));
    let rays = ParallelRays::new(
        toward,
        Vec3::new(0.0, 0.0, 1.0),
        2.0,
        points,
        TestVertex::point,
        &scene,
    );
    let r = run(
        "parallel rays (from below, whole floor)",
        &rays,
        &Grid::new(RectChart::new(&scene, FLOOR), 16),
    );
    assert!(r.jacobian_checked > 100, "{r}");
    assert!(r.integral > 0.05 && r.integral < 0.5, "{r}");
}
