//! Blocks that produce vertices: the `intersect` primitive, points sampled
//! on a surface, Dirac points, vertices at infinity and the parallel rays
//! of distant lights.

use glam::{DVec2, Vec2, Vec3};

use crate::density::{Density, Measure};
use crate::distribution::{Distribution, Sample, Step, Uniforms};
use crate::frame::Frame;
use crate::vertex::{Geometry, RayCaster, Vertex};

/// The `intersect` primitive: casts a ray from `from` along a sampled
/// direction and returns the vertex it hits.
///
/// Density: the direction's solid-angle density times |cos θₓ| / r² at the
/// hit point, in area measure (Dirac components included), the direction
/// and r measured from where the caster starts the ray
/// ([`RayCaster::origin`]). In density mode
/// the given vertex is used instead of tracing: a vertex at infinity keeps
/// its solid-angle density, and an isolated point (a point light, a
/// pinhole) has density zero, since no ray can hit it.
///
/// ```
/// use aether_core::{Distribution, Frame, InFrame, Intersect, Step};
/// use aether_core::primitives::CosineHemisphere;
/// use aether_core::testing::TestScene;
/// use glam::Vec3;
///
/// let scene = TestScene::open_box();
/// let from = scene.vertex_on(0, Vec3::new(0.2, 0.1, 0.0));
/// let bounce = Intersect::new(&from, InFrame::new(Frame::from_normal(Vec3::Z), CosineHemisphere), &scene);
/// let hit = bounce.sample(&[0.9, 0.1]).unwrap();
/// assert!(matches!(hit.value, Step::Vertex(_)));
/// assert_eq!(bounce.density(&hit.value), hit.density);
/// ```
#[derive(Debug)]
pub struct Intersect<'a, V, D, R> {
    from: &'a V,
    directions: D,
    scene: R,
}

impl<'a, V: Vertex, D: Distribution<Value = Vec3>, R: RayCaster<V>> Intersect<'a, V, D, R> {
    /// Rays from `from` along world directions drawn from `directions`.
    #[inline(always)]
    pub fn new(from: &'a V, directions: D, scene: R) -> Self {
        Intersect {
            from,
            directions,
            scene,
        }
    }
}

/// Converts a solid-angle density at `from` into the measure of vertex `v`.
/// Returns `None` if `v` cannot be reached by a ray (an isolated point).
fn direction_to(from: Vec3, v: &impl Vertex) -> Option<(Vec3, f64)> {
    match v.geometry() {
        Geometry::Surface { normal } => {
            let d = (v.position() - from).as_dvec3();
            let r2 = d.length_squared();
            if r2 == 0.0 {
                return None;
            }
            let dir = d / r2.sqrt();
            Some((dir.as_vec3(), normal.as_dvec3().dot(dir).abs() / r2))
        }
        Geometry::AtInfinity { direction } => Some((direction, 1.0)),
        Geometry::Point => None,
    }
}

fn measure_of(v: &impl Vertex) -> Measure {
    match v.geometry() {
        Geometry::AtInfinity { .. } => Measure::SolidAngle,
        _ => Measure::Area,
    }
}

impl<V: Vertex, D: Distribution<Value = Vec3>, R: RayCaster<V>> Distribution
    for Intersect<'_, V, D, R>
{
    type Value = Step<V>;
    fn dims(&self) -> usize {
        self.directions.dims()
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<Step<V>>> {
        let w = self.directions.sample(u)?;
        match self.scene.cast_from(self.from, w.value) {
            (origin, Some(hit)) => {
                let (_, factor) = direction_to(origin, &hit)?;
                let density = w.density.convert(factor, measure_of(&hit));
                Some(Sample::new(Step::Vertex(hit), density))
            }
            (_, None) => Some(Sample::new(
                Step::Missed,
                Density::zero(Measure::SolidAngle),
            )),
        }
    }
    fn density(&self, v: &Step<V>) -> Density {
        let Step::Vertex(v) = v else {
            return Density::zero(Measure::Area);
        };
        // Measured from the origin the caster starts the ray that reaches
        // `v` from (past `from`'s rounding error), so that densities
        // describe the rays cast: on edges a few offsets long, and through
        // near-specular lobes, the difference matters.
        match self
            .scene
            .origin_reaching(self.from, v)
            .and_then(|o| direction_to(o, v))
        {
            Some((dir, factor)) => self.directions.density(&dir).convert(factor, measure_of(v)),
            None => Density::zero(Measure::Area),
        }
    }
    fn invert(&self, v: &Step<V>) -> Option<Uniforms> {
        let Step::Vertex(v) = v else { return None };
        let (dir, _) = direction_to(self.scene.origin_reaching(self.from, v)?, v)?;
        self.directions.invert(&dir)
    }
    fn has_overlapping_branches(&self) -> bool {
        self.directions.has_overlapping_branches()
    }
}

/// Turns points sampled on a surface (by area) into vertices, with
/// `at(point)` building the vertex there (its normal, material, emitter).
///
/// Density: the point's area density, for target vertices on a surface;
/// zero for isolated points and vertices at infinity.
pub struct OnSurface<D, F> {
    points: D,
    at: F,
}

impl<D, F> std::fmt::Debug for OnSurface<D, F> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("OnSurface").finish_non_exhaustive()
    }
}

impl<V: Vertex, D: Distribution<Value = Vec3>, F: Fn(Vec3) -> Option<V>> OnSurface<D, F> {
    /// Vertices at the points of `points`.
    pub fn new(points: D, at: F) -> Self {
        OnSurface { points, at }
    }
}

impl<V: Vertex, D: Distribution<Value = Vec3>, F: Fn(Vec3) -> Option<V>> Distribution
    for OnSurface<D, F>
{
    type Value = Step<V>;
    fn dims(&self) -> usize {
        self.points.dims()
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<Step<V>>> {
        let p = self.points.sample(u)?;
        let v = (self.at)(p.value)?;
        Some(Sample::new(Step::Vertex(v), p.density))
    }
    fn density(&self, v: &Step<V>) -> Density {
        on_a_surface(v).map_or(Density::zero(Measure::Area), |p| self.points.density(&p))
    }
    fn invert(&self, v: &Step<V>) -> Option<Uniforms> {
        on_a_surface(v).and_then(|p| self.points.invert(&p))
    }
    fn has_overlapping_branches(&self) -> bool {
        self.points.has_overlapping_branches()
    }
}

/// The position of a step's vertex if it lies on a surface: what a point
/// sampled by area can be (isolated points and vertices at infinity
/// cannot).
pub(crate) fn on_a_surface<V: Vertex>(v: &Step<V>) -> Option<Vec3> {
    match v {
        Step::Vertex(v) if matches!(v.geometry(), Geometry::Surface { .. }) => Some(v.position()),
        _ => None,
    }
}

/// A Dirac point: a point light's position, a pinhole. It reads no uniforms.
///
/// Density: a Dirac component of the given mass at the vertex, zero for any
/// other vertex (matched by position, relative to the scene's scale).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DiracPoint<V> {
    vertex: V,
    mass: f64,
}

impl<V: Vertex> DiracPoint<V> {
    /// The point `vertex`, produced with probability `mass`.
    pub fn new(vertex: V, mass: f64) -> Self {
        DiracPoint { vertex, mass }
    }
}

impl<V: Vertex> Distribution for DiracPoint<V> {
    type Value = Step<V>;
    fn dims(&self) -> usize {
        0
    }
    fn sample(&self, _u: &[f32]) -> Option<Sample<Step<V>>> {
        Some(Sample::new(
            Step::Vertex(self.vertex.clone()),
            Density::dirac(self.mass, Measure::Area),
        ))
    }
    fn density(&self, v: &Step<V>) -> Density {
        match v {
            Step::Vertex(v) if matches!(v.geometry(), Geometry::Point) => {
                let p = self.vertex.position();
                let scale = p.abs().max_element().max(1.0);
                if (v.position() - p).length() <= 1e-5 * scale {
                    Density::dirac(self.mass, Measure::Area)
                } else {
                    Density::zero(Measure::Area)
                }
            }
            _ => Density::zero(Measure::Area),
        }
    }
    fn invert(&self, v: &Step<V>) -> Option<Uniforms> {
        (!self.density(v).is_zero()).then(Uniforms::new)
    }
}

/// Vertices at infinity in sampled directions: an environment or a
/// directional light, sampled as an emitter or directly from a shading
/// point. `at(direction)` builds the vertex, whose geometry must be
/// [`Geometry::AtInfinity`] in that direction.
///
/// Density: the direction's solid-angle density (Dirac order kept) for a
/// vertex at infinity; zero, in solid angle, for any other vertex.
///
/// ```
/// use aether_core::{AtInfinity, Distribution, Geometry, Step};
/// use aether_core::primitives::{Equirect, UniformSquare};
/// use aether_core::testing::TestVertex;
///
/// let sky = AtInfinity::new(Equirect::new(UniformSquare), TestVertex::at_infinity);
/// let s = sky.sample(&[0.2, 0.4]).unwrap();
/// let Step::Vertex(v) = s.value else { unreachable!() };
/// assert!(matches!(v.geometry, Geometry::AtInfinity { .. }));
/// // Density mode recovers sin θ from the single-precision direction.
/// let p = sky.density(&s.value).value();
/// assert!((p - s.density.value()).abs() < 1e-6 * p);
/// ```
pub struct AtInfinity<D, F> {
    directions: D,
    at: F,
}

impl<D, F> std::fmt::Debug for AtInfinity<D, F> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("AtInfinity").finish_non_exhaustive()
    }
}

impl<V: Vertex, D: Distribution<Value = Vec3>, F: Fn(Vec3) -> V> AtInfinity<D, F> {
    /// Vertices `at(w)` for the world directions w of `directions`.
    pub fn new(directions: D, at: F) -> Self {
        AtInfinity { directions, at }
    }
}

impl<V: Vertex, D: Distribution<Value = Vec3>, F: Fn(Vec3) -> V> Distribution for AtInfinity<D, F> {
    type Value = Step<V>;
    fn dims(&self) -> usize {
        self.directions.dims()
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<Step<V>>> {
        let w = self.directions.sample(u)?;
        let v = (self.at)(w.value);
        debug_assert!(
            matches!(v.geometry(), Geometry::AtInfinity { direction }
                if direction.dot(w.value) >= 1.0 - 1e-5),
            "at({}) must build the vertex at infinity in that direction",
            w.value
        );
        Some(Sample::new(Step::Vertex(v), w.density))
    }
    fn density(&self, v: &Step<V>) -> Density {
        match v {
            Step::Vertex(v) => match v.geometry() {
                Geometry::AtInfinity { direction } => self.directions.density(&direction),
                _ => Density::zero(Measure::SolidAngle),
            },
            _ => Density::zero(Measure::SolidAngle),
        }
    }
    fn invert(&self, v: &Step<V>) -> Option<Uniforms> {
        match v {
            Step::Vertex(v) => match v.geometry() {
                Geometry::AtInfinity { direction } => self.directions.invert(&direction),
                _ => None,
            },
            _ => None,
        }
    }
    fn has_overlapping_branches(&self) -> bool {
        self.directions.has_overlapping_branches()
    }
}

/// Parallel rays from a distant source: points on a disk facing the source
/// just outside the scene, cast along −`toward` (the "far disk" of a
/// directional light or of an environment emitting into the scene).
///
/// With the frame (s, t, `toward`) of [`Frame::from_normal`], the disk
/// point q leaves from center + radius · toward + q.x s + q.y t, from the
/// vertex `at` builds there. The disk must cover the scene's projection
/// (radius at least the bounding sphere's). A ray that escapes, or ends at
/// an isolated point or at infinity, is a miss.
///
/// Density: p(q) · |n · toward| in area measure at a hit with normal n,
/// where q is the hit projected onto the disk (parallel projection:
/// dA_disk = |cos| dA_hit); zero for isolated points, vertices at infinity
/// and points beyond the disk.
///
/// ```
/// use aether_core::{Distribution, ParallelRays, Step};
/// use aether_core::primitives::UniformDisk;
/// use aether_core::testing::{TestScene, TestVertex};
/// use glam::Vec3;
///
/// let scene = TestScene::open_box();
/// let sun = ParallelRays::new(Vec3::Z, Vec3::new(0.0, 0.0, 1.0), 2.0,
///     UniformDisk::new(2.0), TestVertex::point, &scene);
/// // Straight down onto the floor (shape 0), between the light and the sphere.
/// let hit = sun.sample(&[0.6, 0.45]).unwrap();
/// assert!(matches!(hit.value, Step::Vertex(v) if v.shape == 0));
/// assert_eq!(sun.density(&hit.value), hit.density);
/// ```
pub struct ParallelRays<D, F, R> {
    frame: Frame,
    center: Vec3,
    radius: f32,
    points: D,
    at: F,
    scene: R,
}

impl<D, F, R> std::fmt::Debug for ParallelRays<D, F, R> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ParallelRays")
            .field("frame", &self.frame)
            .field("center", &self.center)
            .field("radius", &self.radius)
            .finish_non_exhaustive()
    }
}

impl<V, D, F, R> ParallelRays<D, F, R>
where
    V: Vertex,
    D: Distribution<Value = Vec2>,
    F: Fn(Vec3) -> V,
    R: RayCaster<V>,
{
    /// Rays along −`toward` (a unit direction from the scene towards the
    /// source) from the disk points of `points`, on the disk of `radius`
    /// facing `toward` at distance `radius` from `center`.
    pub fn new(toward: Vec3, center: Vec3, radius: f32, points: D, at: F, scene: R) -> Self {
        ParallelRays {
            frame: Frame::from_normal(toward),
            center,
            radius,
            points,
            at,
            scene,
        }
    }

    /// The disk point a vertex projects to and |cos| at it, or `None` for
    /// vertices no ray of the disk can hit.
    fn project(&self, v: &V) -> Option<(Vec2, f64)> {
        let Geometry::Surface { normal } = v.geometry() else {
            return None;
        };
        let d = (v.position() - self.center).as_dvec3();
        let toward = self.frame.n.as_dvec3();
        let r = f64::from(self.radius);
        // Rays start on the disk and only travel away from the source.
        if d.dot(toward) > r * (1.0 + 1e-4) {
            return None;
        }
        let q = DVec2::new(
            d.dot(self.frame.s.as_dvec3()),
            d.dot(self.frame.t.as_dvec3()),
        );
        Some((q.as_vec2(), normal.as_dvec3().dot(toward).abs()))
    }
}

impl<V, D, F, R> Distribution for ParallelRays<D, F, R>
where
    V: Vertex,
    D: Distribution<Value = Vec2>,
    F: Fn(Vec3) -> V,
    R: RayCaster<V>,
{
    type Value = Step<V>;
    fn dims(&self) -> usize {
        self.points.dims()
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<Step<V>>> {
        let q = self.points.sample(u)?;
        let Frame { s, t, n } = self.frame;
        let origin = self.center.as_dvec3()
            + f64::from(self.radius) * n.as_dvec3()
            + f64::from(q.value.x) * s.as_dvec3()
            + f64::from(q.value.y) * t.as_dvec3();
        let hit = self.scene.cast(&(self.at)(origin.as_vec3()), -n);
        let Some((v, normal)) = hit.and_then(|v| match v.geometry() {
            Geometry::Surface { normal } => Some((v, normal)),
            _ => None,
        }) else {
            return Some(Sample::new(Step::Missed, Density::zero(Measure::Area)));
        };
        let cos = normal.as_dvec3().dot(n.as_dvec3()).abs();
        Some(Sample::new(
            Step::Vertex(v),
            q.density.convert(cos, Measure::Area),
        ))
    }
    fn density(&self, v: &Step<V>) -> Density {
        let Step::Vertex(v) = v else {
            return Density::zero(Measure::Area);
        };
        match self.project(v) {
            Some((q, cos)) => self.points.density(&q).convert(cos, Measure::Area),
            None => Density::zero(Measure::Area),
        }
    }
    fn invert(&self, v: &Step<V>) -> Option<Uniforms> {
        let Step::Vertex(v) = v else { return None };
        self.points.invert(&self.project(v)?.0)
    }
    fn has_overlapping_branches(&self) -> bool {
        self.points.has_overlapping_branches()
    }
}

/// The density of a line (a point by area and a direction by solid angle)
/// as a density of its two end points in the product of their areas.
fn line_to_area_product(point: Density, direction: Density, factor: f64) -> Density {
    let dirac = Density::dirac(1.0, Measure::Discrete);
    let scaled = point.convert(direction.value() * factor, Measure::AreaProduct);
    if direction.is_dirac() {
        scaled * dirac
    } else {
        scaled
    }
}

/// A segment through a portal: a point y sampled on the portal (by area)
/// and a direction ω (by solid angle); rays cast both ways from y give the
/// two vertices (x_a behind, x_b ahead), in path order.
///
/// Density, in the product of the two vertices' area measures:
/// p(y) p(ω) |cos θ_a| |cos θ_b| / (|cos θ_y| ‖x_a − x_b‖²), the change from
/// the line measure |cos θ_y| dA(y) dω to dA(x_a) dA(x_b). In density mode y
/// is where the line through the two vertices crosses the portal plane.
/// Vertices at infinity and isolated points have density zero.
pub struct Segment<P, D, F, R> {
    points: P,
    directions: D,
    plane: (Vec3, Vec3),
    at: F,
    scene: R,
}

impl<P, D, F, R> std::fmt::Debug for Segment<P, D, F, R> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Segment")
            .field("plane", &self.plane)
            .finish_non_exhaustive()
    }
}

impl<V, P, D, F, R> Segment<P, D, F, R>
where
    V: Vertex,
    P: Distribution<Value = Vec3>,
    D: Distribution<Value = Vec3>,
    F: Fn(Vec3) -> V,
    R: RayCaster<V>,
{
    /// Points from `points` on the portal plane through `origin` with unit
    /// `normal`, directions from `directions`; `at(y)` is the vertex rays
    /// leave from.
    pub fn new(points: P, directions: D, origin: Vec3, normal: Vec3, at: F, scene: R) -> Self {
        Segment {
            points,
            directions,
            plane: (origin, normal),
            at,
            scene,
        }
    }

    /// y and ω for a pair of vertices, with the line-measure factor.
    fn line(&self, a: &V, b: &V) -> Option<(Vec3, Vec3, f64)> {
        let (Geometry::Surface { normal: na }, Geometry::Surface { normal: nb }) =
            (a.geometry(), b.geometry())
        else {
            return None;
        };
        let (pa, pb) = (a.position().as_dvec3(), b.position().as_dvec3());
        let d = pb - pa;
        let r2 = d.length_squared();
        let w = d / r2.sqrt();
        let (o, n) = (self.plane.0.as_dvec3(), self.plane.1.as_dvec3());
        let cos_y = n.dot(w);
        if cos_y == 0.0 || r2 == 0.0 {
            return None;
        }
        let t = (o - pa).dot(n) / cos_y;
        if !(0.0..=r2.sqrt()).contains(&t) {
            return None;
        }
        let y = pa + t * w;
        let factor = na.as_dvec3().dot(w).abs() * nb.as_dvec3().dot(w).abs() / (cos_y.abs() * r2);
        Some((y.as_vec3(), w.as_vec3(), factor))
    }
}

impl<V, P, D, F, R> Distribution for Segment<P, D, F, R>
where
    V: Vertex,
    P: Distribution<Value = Vec3>,
    D: Distribution<Value = Vec3>,
    F: Fn(Vec3) -> V,
    R: RayCaster<V>,
{
    type Value = Step<(V, V)>;
    fn dims(&self) -> usize {
        self.points.dims() + self.directions.dims()
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<Step<(V, V)>>> {
        let k = self.points.dims();
        let y = self.points.sample(&u[..k])?;
        let w = self.directions.sample(&u[k..])?;
        let from = (self.at)(y.value);
        let (Some(b), Some(a)) = (
            self.scene.cast(&from, w.value),
            self.scene.cast(&from, -w.value),
        ) else {
            return Some(Sample::new(
                Step::Missed,
                Density::zero(Measure::AreaProduct),
            ));
        };
        // End points at infinity, or a line that rounding moved off the
        // portal, have no area-product density: a void sample.
        let (_, _, factor) = self.line(&a, &b)?;
        Some(Sample::new(
            Step::Vertex((a, b)),
            line_to_area_product(y.density, w.density, factor),
        ))
    }
    fn density(&self, v: &Step<(V, V)>) -> Density {
        let Step::Vertex((a, b)) = v else {
            return Density::zero(Measure::AreaProduct);
        };
        match self.line(a, b) {
            Some((y, w, factor)) => {
                line_to_area_product(self.points.density(&y), self.directions.density(&w), factor)
            }
            None => Density::zero(Measure::AreaProduct),
        }
    }
    fn invert(&self, v: &Step<(V, V)>) -> Option<Uniforms> {
        let Step::Vertex((a, b)) = v else { return None };
        let (y, w, _) = self.line(a, b)?;
        let mut u = self.points.invert(&y)?;
        u.extend(self.directions.invert(&w)?);
        Some(u)
    }
    fn has_overlapping_branches(&self) -> bool {
        self.points.has_overlapping_branches() || self.directions.has_overlapping_branches()
    }
}
