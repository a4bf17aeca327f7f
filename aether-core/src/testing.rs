//! A tiny analytic scene, its vertex type and a few strategies, for
//! examples, doctests and the tests of this crate and of the crates that
//! build on it (the counterpart of obvhs's `test_util`).
//!
//! The scene is an open box: a floor and four walls of side 2 around the
//! origin (z from 0 to 2, no ceiling), a square light facing down at
//! z = 1.9, a point light, and a sphere.

use glam::Vec3;

use crate::distribution::Step;
use crate::frame::Frame;
use crate::harness::Parameterization;
use crate::primitives::{CosineHemisphere, DiscreteDistribution, UniformCone, UniformTriangle};
use smallvec::SmallVec;

use crate::rng::UniformSource;
use crate::sequence::RandomSequence;
use crate::strategy::{Prefix, Strategy};
use crate::surface::{DiracPoint, Intersect, OnSurface};
use crate::vertex::{Geometry, RayCaster, Vertex};
use crate::{Distribution, InFrame, Select};

/// A vertex of the test scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TestVertex {
    /// Position.
    pub position: Vec3,
    /// Where it lies.
    pub geometry: Geometry,
    /// Index of the shape it lies on (`u32::MAX` for points and infinity).
    pub shape: u32,
}

impl TestVertex {
    /// A vertex on a surface with unit normal `normal`, on no particular shape.
    #[must_use]
    pub fn on_surface(position: Vec3, normal: Vec3) -> Self {
        TestVertex {
            position,
            geometry: Geometry::Surface { normal },
            shape: u32::MAX,
        }
    }

    /// An isolated point (a pinhole, a point light).
    #[must_use]
    pub fn point(position: Vec3) -> Self {
        TestVertex {
            position,
            geometry: Geometry::Point,
            shape: u32::MAX,
        }
    }

    /// The vertex at infinity in unit `direction` (an environment or a
    /// directional light); its position is unused and set to zero.
    #[must_use]
    pub fn at_infinity(direction: Vec3) -> Self {
        TestVertex {
            position: Vec3::ZERO,
            geometry: Geometry::AtInfinity { direction },
            shape: u32::MAX,
        }
    }

    /// The geometric normal (+z for points and infinity).
    #[must_use]
    pub fn normal(&self) -> Vec3 {
        match self.geometry {
            Geometry::Surface { normal } => normal,
            _ => Vec3::Z,
        }
    }
}

impl crate::recycle::Recycle for TestVertex {
    type Static = Self;
}

impl Vertex for TestVertex {
    fn position(&self) -> Vec3 {
        self.position
    }
    fn geometry(&self) -> Geometry {
        self.geometry
    }
}

/// A shape of the test scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Shape {
    /// The parallelogram `corner + s·e1 + t·e2`, s, t ∈ [0, 1], normal e1 × e2.
    Rect {
        /// A corner.
        corner: Vec3,
        /// First edge.
        e1: Vec3,
        /// Second edge.
        e2: Vec3,
    },
    /// A sphere.
    Sphere {
        /// Centre.
        center: Vec3,
        /// Radius.
        radius: f32,
    },
}

impl Shape {
    /// Ray intersection in double precision, so that finite differences of
    /// hit points in tests are not dominated by rounding.
    fn hit(&self, o: Vec3, d: Vec3, t_min: f32) -> Option<(f32, Vec3)> {
        let (o, d, t_min) = (o.as_dvec3(), d.as_dvec3(), f64::from(t_min));
        match *self {
            Shape::Rect { corner, e1, e2 } => {
                let (corner, e1, e2) = (corner.as_dvec3(), e1.as_dvec3(), e2.as_dvec3());
                let n = e1.cross(e2);
                let denom = d.dot(n);
                if denom.abs() < 1e-12 {
                    return None;
                }
                let t = (corner - o).dot(n) / denom;
                if t <= t_min {
                    return None;
                }
                let p = o + t * d - corner;
                let (s, r) = (
                    p.dot(e1) / e1.length_squared(),
                    p.dot(e2) / e2.length_squared(),
                );
                ((0.0..=1.0).contains(&s) && (0.0..=1.0).contains(&r))
                    .then(|| (t as f32, n.normalize().as_vec3()))
            }
            Shape::Sphere { center, radius } => {
                let oc = o - center.as_dvec3();
                let r = f64::from(radius);
                let b = oc.dot(d);
                // The discriminant from the perpendicular distance, without cancellation.
                let perp = oc - b * d;
                let disc = r * r - perp.length_squared();
                if disc < 0.0 {
                    return None;
                }
                let sq = disc.sqrt();
                let t = [-b - sq, -b + sq].into_iter().find(|&t| t > t_min)?;
                Some((t as f32, ((oc + t * d) / r).as_vec3()))
            }
        }
    }
}

/// The test scene: shapes, the index of the emitting rectangle, a point light.
#[derive(Clone, Debug, PartialEq)]
pub struct TestScene {
    /// All shapes.
    pub shapes: Vec<Shape>,
    /// Index of the light rectangle in `shapes`.
    pub light: usize,
    /// Position of the point light.
    pub point_light: Vec3,
    /// The light rectangle's two triangles, chosen by area.
    light_triangles: DiscreteDistribution,
}

impl TestScene {
    /// The open box described in the module documentation.
    #[must_use]
    pub fn open_box() -> Self {
        let rect = |corner: Vec3, e1: Vec3, e2: Vec3| Shape::Rect { corner, e1, e2 };
        let shapes = vec![
            rect(Vec3::new(-1.0, -1.0, 0.0), Vec3::X * 2.0, Vec3::Y * 2.0),
            rect(Vec3::new(-1.0, -1.0, 0.0), Vec3::Z * 2.0, Vec3::X * 2.0),
            rect(Vec3::new(-1.0, 1.0, 0.0), Vec3::X * 2.0, Vec3::Z * 2.0),
            rect(Vec3::new(-1.0, -1.0, 0.0), Vec3::Y * 2.0, Vec3::Z * 2.0),
            rect(Vec3::new(1.0, -1.0, 0.0), Vec3::Z * 2.0, Vec3::Y * 2.0),
            rect(Vec3::new(-0.25, -0.25, 1.9), Vec3::Y * 0.5, Vec3::X * 0.5),
            Shape::Sphere {
                center: Vec3::new(0.4, 0.3, 0.35),
                radius: 0.35,
            },
        ];
        let light = 5;
        let light_triangles = DiscreteDistribution::new(&[1.0, 1.0]).expect("two equal triangles");
        TestScene {
            shapes,
            light,
            point_light: Vec3::new(-0.5, 0.5, 1.5),
            light_triangles,
        }
    }

    /// The vertex at a point of shape `shape` (used by samplers and charts).
    #[must_use]
    pub fn vertex_on(&self, shape: usize, p: Vec3) -> TestVertex {
        let normal = match self.shapes[shape] {
            Shape::Rect { e1, e2, .. } => e1.cross(e2).normalize(),
            Shape::Sphere { center, .. } => (p - center).normalize(),
        };
        TestVertex {
            position: p,
            geometry: Geometry::Surface { normal },
            shape: shape as u32,
        }
    }

    /// The two triangles of the light rectangle.
    #[must_use]
    pub fn light_triangle(&self, i: usize) -> UniformTriangle {
        let Shape::Rect { corner, e1, e2 } = self.shapes[self.light] else {
            unreachable!("the light is a rectangle")
        };
        if i == 0 {
            UniformTriangle::new(corner, corner + e1, corner + e1 + e2)
        } else {
            UniformTriangle::new(corner, corner + e1 + e2, corner + e2)
        }
    }

    /// Which of the light's two triangles a step's vertex lies on, if any:
    /// the choice a light sample by area made.
    #[must_use]
    pub fn light_triangle_of(&self, v: &Step<TestVertex>) -> Option<usize> {
        match v {
            Step::Vertex(v) if v.shape as usize == self.light => {
                (0..2).find(|&i| self.light_triangle(i).barycentrics(v.position).is_some())
            }
            _ => None,
        }
    }
}

impl RayCaster<TestVertex> for TestScene {
    fn cast(&self, from: &TestVertex, direction: Vec3) -> Option<TestVertex> {
        let o = from.position;
        let t_min = 1e-4 * o.abs().max_element().max(1.0);
        let mut best: Option<(f32, usize, Vec3)> = None;
        for (k, shape) in self.shapes.iter().enumerate() {
            // A ray cannot re-hit the plane it leaves.
            if k as u32 == from.shape && matches!(shape, Shape::Rect { .. }) {
                continue;
            }
            if let Some((t, n)) = shape.hit(o, direction, t_min) {
                if best.is_none_or(|b| t < b.0) {
                    best = Some((t, k, n));
                }
            }
        }
        best.map(|(t, k, n)| {
            let position = (o.as_dvec3() + f64::from(t) * direction.as_dvec3()).as_vec3();
            TestVertex {
                position,
                geometry: Geometry::Surface { normal: n },
                shape: k as u32,
            }
        })
    }
}

/// A pinhole: the Dirac point at `position`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraPoint {
    /// Where the pinhole is.
    pub position: Vec3,
}

impl Default for CameraPoint {
    fn default() -> Self {
        CameraPoint {
            position: Vec3::new(0.0, 0.0, 1.0),
        }
    }
}

impl Strategy<TestVertex> for CameraPoint {
    fn distribution<'a>(
        &'a self,
        _prefix: Prefix<'a, TestVertex>,
    ) -> impl Distribution<Value = Step<TestVertex>> + 'a {
        DiracPoint::new(TestVertex::point(self.position), 1.0)
    }
    fn memory(&self) -> usize {
        0
    }
}

/// A camera ray from the pinhole: a uniform direction in a cone of
/// half-angle 53° about −z, then a ray (it sees the floor and the walls).
#[derive(Clone, Copy, Debug)]
pub struct LookDown<'s> {
    scene: &'s TestScene,
}

impl<'s> LookDown<'s> {
    /// Camera rays in `scene`.
    #[must_use]
    pub fn new(scene: &'s TestScene) -> Self {
        LookDown { scene }
    }
}

impl Strategy<TestVertex> for LookDown<'_> {
    fn distribution<'a>(
        &'a self,
        prefix: Prefix<'a, TestVertex>,
    ) -> impl Distribution<Value = Step<TestVertex>> + 'a {
        let eye = prefix.last().expect("the pinhole");
        Intersect::new(
            eye,
            InFrame::new(Frame::from_normal(-Vec3::Z), UniformCone::new(0.6)),
            self.scene,
        )
    }
    fn memory(&self) -> usize {
        1
    }
}

/// A diffuse bounce: a cosine-weighted direction about the last vertex's
/// normal (on the side of the vertex before it, if any), then a ray.
#[derive(Clone, Copy, Debug)]
pub struct Bounce<'s> {
    scene: &'s TestScene,
}

impl<'s> Bounce<'s> {
    /// Bounces in `scene`.
    #[must_use]
    pub fn new(scene: &'s TestScene) -> Self {
        Bounce { scene }
    }
}

/// The normal at `x` flipped to the side of `towards` (when there is one).
#[must_use]
pub fn facing_normal(x: &TestVertex, towards: Option<&TestVertex>) -> Vec3 {
    let n = x.normal();
    match towards {
        Some(p)
            if matches!(x.geometry, Geometry::Surface { .. })
                && (p.position - x.position).dot(n) < 0.0 =>
        {
            -n
        }
        _ => n,
    }
}

impl Strategy<TestVertex> for Bounce<'_> {
    fn distribution<'a>(
        &'a self,
        prefix: Prefix<'a, TestVertex>,
    ) -> impl Distribution<Value = Step<TestVertex>> + 'a {
        let x = prefix.last().expect("a bounce leaves from a vertex");
        let n = facing_normal(x, prefix.back(1));
        Intersect::new(
            x,
            InFrame::new(Frame::from_normal(n), CosineHemisphere),
            self.scene,
        )
    }
    fn memory(&self) -> usize {
        2
    }
    fn depth_class(&self, _prefix_len: usize) -> usize {
        0
    }
}

/// Area sampling of the light rectangle: a triangle by area, a point on it.
/// The prefix is ignored, so it serves both as direct light sampling and as
/// the first vertex of a light subpath.
#[derive(Clone, Copy, Debug)]
pub struct LightSample<'s> {
    scene: &'s TestScene,
}

impl<'s> LightSample<'s> {
    /// Samples the light of `scene`.
    #[must_use]
    pub fn new(scene: &'s TestScene) -> Self {
        LightSample { scene }
    }
}

impl Strategy<TestVertex> for LightSample<'_> {
    fn distribution<'a>(
        &'a self,
        _prefix: Prefix<'a, TestVertex>,
    ) -> impl Distribution<Value = Step<TestVertex>> + 'a {
        let scene = self.scene;
        let on_light = move |i: usize| {
            OnSurface::new(scene.light_triangle(i), move |p| {
                Some(scene.vertex_on(scene.light, p))
            })
        };
        let which = move |v: &Step<TestVertex>| scene.light_triangle_of(v);
        Select::new(&scene.light_triangles, 2, on_light, which)
    }
    fn memory(&self) -> usize {
        0
    }
}

/// The strategies of a small bidirectional sampler on the test scene: a
/// camera subpath (pinhole, camera ray, bounces) and a light subpath (a
/// point on the light, bounces), joined into every (s, t) candidate.
#[derive(Clone, Copy, Debug)]
pub struct BidirectionalFixture<'s> {
    /// The pinhole.
    pub camera: CameraPoint,
    /// The camera ray.
    pub look: LookDown<'s>,
    /// Diffuse bounces, on both subpaths.
    pub bounce: Bounce<'s>,
    /// The first light vertex.
    pub light: LightSample<'s>,
}

impl<'s> BidirectionalFixture<'s> {
    /// The fixture on `scene`.
    #[must_use]
    pub fn new(scene: &'s TestScene) -> Self {
        BidirectionalFixture {
            camera: CameraPoint::default(),
            look: LookDown::new(scene),
            bounce: Bounce::new(scene),
            light: LightSample::new(scene),
        }
    }

    /// Samples a camera and a light subpath long enough for paths of
    /// `length` vertices and pushes every candidate
    /// `camera[..s] + reverse(light[..length − s])` that they allow into `out`,
    /// ordered by s.
    pub fn sample_candidates<'a>(
        &'a self,
        length: usize,
        rng: &mut impl UniformSource,
        out: &mut SmallVec<[RandomSequence<'a, TestVertex>; 8]>,
    ) {
        let mut camera = RandomSequence::new();
        camera.append(&self.camera).append(&self.look);
        let mut light = RandomSequence::new();
        light.append(&self.light);
        for _ in 2..length {
            camera.append(&self.bounce);
        }
        for _ in 1..length {
            light.append(&self.bounce);
        }
        camera.sample(rng);
        light.sample(rng);
        out.clear();
        for s in 0..=length {
            if s <= camera.len() && length - s <= light.len() {
                out.push(
                    camera
                        .slice(0..s)
                        .concat(&light.slice(0..length - s).reversed()),
                );
            }
        }
    }
}

/// A chart of a rectangle of the test scene, for chi-square tests of
/// vertex-valued strategies.
#[derive(Clone, Copy, Debug)]
pub struct RectChart<'s> {
    scene: &'s TestScene,
    shape: usize,
}

impl<'s> RectChart<'s> {
    /// The chart of rectangle `shape` of `scene`.
    #[must_use]
    pub fn new(scene: &'s TestScene, shape: usize) -> Self {
        debug_assert!(matches!(scene.shapes[shape], Shape::Rect { .. }));
        RectChart { scene, shape }
    }

    fn edges(&self) -> (Vec3, Vec3, Vec3) {
        match self.scene.shapes[self.shape] {
            Shape::Rect { corner, e1, e2 } => (corner, e1, e2),
            Shape::Sphere { .. } => unreachable!("checked in new"),
        }
    }
}

impl Parameterization<Step<TestVertex>> for RectChart<'_> {
    fn dims(&self) -> usize {
        2
    }
    fn value(&self, s: [f64; 2]) -> Option<Step<TestVertex>> {
        let (c, e1, e2) = self.edges();
        let p = c + e1 * s[0] as f32 + e2 * s[1] as f32;
        Some(Step::Vertex(self.scene.vertex_on(self.shape, p)))
    }
    fn coords(&self, v: &Step<TestVertex>) -> Option<[f64; 2]> {
        let Step::Vertex(v) = v else { return None };
        if v.shape as usize != self.shape {
            return None;
        }
        let (c, e1, e2) = self.edges();
        let d = (v.position - c).as_dvec3();
        Some([
            d.dot(e1.as_dvec3()) / f64::from(e1.length_squared()),
            d.dot(e2.as_dvec3()) / f64::from(e2.length_squared()),
        ])
    }
    fn jacobian(&self, _s: [f64; 2]) -> f64 {
        let (_, e1, e2) = self.edges();
        f64::from(e1.cross(e2).length())
    }
}

/// A chart of a spherical cap of a sphere of the test scene, about an
/// axis: ((1 − cos θ)/(1 − cos θ_cap), φ/2π).
#[derive(Clone, Copy, Debug)]
pub struct SphereChart<'s> {
    scene: &'s TestScene,
    shape: usize,
    frame: Frame,
    one_minus_cos_cap: f64,
}

impl<'s> SphereChart<'s> {
    /// The chart of the whole sphere `shape` of `scene`.
    #[must_use]
    pub fn new(scene: &'s TestScene, shape: usize) -> Self {
        debug_assert!(matches!(scene.shapes[shape], Shape::Sphere { .. }));
        SphereChart {
            scene,
            shape,
            frame: Frame::WORLD,
            one_minus_cos_cap: 2.0,
        }
    }

    /// The chart of the cap of sphere `shape` that is visible from `point`.
    #[must_use]
    pub fn visible_from(scene: &'s TestScene, shape: usize, point: Vec3) -> Self {
        let chart = Self::new(scene, shape);
        let (c, r) = chart.sphere();
        let d = point - c;
        let cos_cap = f64::from(r) / f64::from(d.length());
        SphereChart {
            frame: Frame::from_normal(d.normalize()),
            one_minus_cos_cap: 1.0 - cos_cap,
            ..chart
        }
    }

    fn sphere(&self) -> (Vec3, f32) {
        match self.scene.shapes[self.shape] {
            Shape::Sphere { center, radius } => (center, radius),
            Shape::Rect { .. } => unreachable!("checked in new"),
        }
    }
}

impl Parameterization<Step<TestVertex>> for SphereChart<'_> {
    fn dims(&self) -> usize {
        2
    }
    fn value(&self, s: [f64; 2]) -> Option<Step<TestVertex>> {
        let (c, r) = self.sphere();
        let omc = s[0] * self.one_minus_cos_cap;
        let sin = (omc * (2.0 - omc)).max(0.0).sqrt();
        let phi = std::f64::consts::TAU * s[1];
        let local = Vec3::new(
            (sin * phi.cos()) as f32,
            (sin * phi.sin()) as f32,
            (1.0 - omc) as f32,
        );
        Some(Step::Vertex(
            self.scene
                .vertex_on(self.shape, c + r * self.frame.to_world(local)),
        ))
    }
    fn coords(&self, v: &Step<TestVertex>) -> Option<[f64; 2]> {
        let Step::Vertex(v) = v else { return None };
        if v.shape as usize != self.shape {
            return None;
        }
        let (c, _) = self.sphere();
        let local = self.frame.to_local((v.position - c).normalize()).as_dvec3();
        let omc = if local.z > 0.0 {
            (local.x * local.x + local.y * local.y) / (1.0 + local.z)
        } else {
            1.0 - local.z
        };
        let s0 = omc / self.one_minus_cos_cap;
        let phi = local.y.atan2(local.x);
        (s0 <= 1.0).then_some([
            s0,
            if phi < 0.0 {
                phi / std::f64::consts::TAU + 1.0
            } else {
                phi / std::f64::consts::TAU
            },
        ])
    }
    fn jacobian(&self, _s: [f64; 2]) -> f64 {
        let r = f64::from(self.sphere().1);
        std::f64::consts::TAU * self.one_minus_cos_cap * r * r
    }
}
