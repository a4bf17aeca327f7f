//! Changes of variables that carry a planar or spherical distribution onto
//! another space: the film plane of a camera onto directions, the unit
//! square of an environment map onto the sphere, the plane onto an aperture
//! in space, directions onto a sphere's surface, and affine maps of the plane.

use std::f64::consts::PI;

use glam::{DVec2, DVec3, Vec2, Vec3};

use super::turn_fraction;
use crate::density::{Density, Measure};
use crate::distribution::{Distribution, Sample, Uniforms};

/// Directions through the points of the plane z = 1 (shifted by `shift`):
/// the film-plane to direction change of variables of a pinhole camera.
///
/// The direction through film point q is normalize(q.x + shift.x, q.y +
/// shift.y, 1); its inverse is q = d.xy / d.z − shift, defined for d.z > 0.
///
/// Density: p(q) / cos³θ in solid angle (cos θ = d.z), Dirac order kept.
///
/// ```
/// use aether_core::{Distribution, Measure};
/// use aether_core::primitives::{Affine2, Gnomonic, UniformSquare};
/// use glam::Vec2;
///
/// // A 90° square field of view: the film [−1, 1]² at distance 1.
/// let film = Affine2::new(UniformSquare, Vec2::splat(2.0), Vec2::splat(-1.0));
/// let camera = Gnomonic::new(film, Vec2::ZERO);
/// let ray = camera.sample(&[0.5, 0.5]).unwrap();
/// assert_eq!(ray.value, glam::Vec3::Z);
/// // On the axis cos θ = 1: the film's density 1/4, now per steradian.
/// assert!((ray.density.value() - 0.25).abs() < 1e-6);
/// assert_eq!(ray.density.measure(), Measure::SolidAngle);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gnomonic<D> {
    points: D,
    shift: Vec2,
}

impl<D: Distribution<Value = Vec2>> Gnomonic<D> {
    /// Directions through the points of `points` on the plane z = 1, moved
    /// by `shift` (the principal point offset of a camera).
    pub fn new(points: D, shift: Vec2) -> Self {
        Gnomonic { points, shift }
    }

    /// The film point of a direction, and cos θ, or `None` behind the film.
    fn film_point(&self, d: Vec3) -> Option<(Vec2, f64)> {
        let d = d.as_dvec3();
        if d.z <= 0.0 {
            return None;
        }
        let q = DVec2::new(d.x / d.z, d.y / d.z) - self.shift.as_dvec2();
        Some((q.as_vec2(), d.z / d.length()))
    }
}

impl<D: Distribution<Value = Vec2>> Distribution for Gnomonic<D> {
    type Value = Vec3;
    fn dims(&self) -> usize {
        self.points.dims()
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<Vec3>> {
        let q = self.points.sample(u)?;
        let x = q.value.as_dvec2() + self.shift.as_dvec2();
        // The distance to the film point is 1 / cos θ.
        let len = (1.0 + x.length_squared()).sqrt();
        let d = DVec3::new(x.x, x.y, 1.0) / len;
        Some(Sample::new(
            d.as_vec3(),
            q.density.convert(len * len * len, Measure::SolidAngle),
        ))
    }
    fn density(&self, d: &Vec3) -> Density {
        match self.film_point(*d) {
            Some((q, cos)) => self
                .points
                .density(&q)
                .convert(1.0 / (cos * cos * cos), Measure::SolidAngle),
            None => Density::zero(Measure::SolidAngle),
        }
    }
    fn invert(&self, d: &Vec3) -> Option<Uniforms> {
        let (q, _) = self.film_point(*d)?;
        self.points.invert(&q)
    }
    fn has_overlapping_branches(&self) -> bool {
        self.points.has_overlapping_branches()
    }
}

/// An affine map of the plane with a diagonal linear part: x ⊙ `scale` +
/// `offset` (a film rectangle from the unit square, a mirrored axis).
///
/// Density: p(x) / |scale.x · scale.y| in the inner measure, Dirac order kept.
///
/// ```
/// use aether_core::Distribution;
/// use aether_core::primitives::{Affine2, UniformSquare};
/// use glam::Vec2;
///
/// let r = Affine2::new(UniformSquare, Vec2::new(4.0, -0.5), Vec2::new(-2.0, 1.0));
/// let s = r.sample(&[0.25, 0.5]).unwrap();
/// assert_eq!(s.value, Vec2::new(-1.0, 0.75));
/// assert_eq!(s.density.value(), 0.5);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Affine2<D> {
    inner: D,
    scale: Vec2,
    offset: Vec2,
}

impl<D: Distribution<Value = Vec2>> Affine2<D> {
    /// Points of `inner` scaled componentwise by `scale` (nonzero, either
    /// sign), then moved by `offset`.
    pub fn new(inner: D, scale: Vec2, offset: Vec2) -> Self {
        debug_assert!(
            scale.x != 0.0 && scale.y != 0.0,
            "scale {scale} is singular"
        );
        Affine2 {
            inner,
            scale,
            offset,
        }
    }

    fn jacobian(&self) -> f64 {
        (f64::from(self.scale.x) * f64::from(self.scale.y)).abs()
    }

    fn preimage(&self, p: Vec2) -> Vec2 {
        ((p.as_dvec2() - self.offset.as_dvec2()) / self.scale.as_dvec2()).as_vec2()
    }
}

impl<D: Distribution<Value = Vec2>> Distribution for Affine2<D> {
    type Value = Vec2;
    fn dims(&self) -> usize {
        self.inner.dims()
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<Vec2>> {
        let s = self.inner.sample(u)?;
        let p = s.value.as_dvec2() * self.scale.as_dvec2() + self.offset.as_dvec2();
        Some(Sample::new(
            p.as_vec2(),
            s.density.scale(1.0 / self.jacobian()),
        ))
    }
    fn density(&self, p: &Vec2) -> Density {
        self.inner
            .density(&self.preimage(*p))
            .scale(1.0 / self.jacobian())
    }
    fn invert(&self, p: &Vec2) -> Option<Uniforms> {
        self.inner.invert(&self.preimage(*p))
    }
    fn has_overlapping_branches(&self) -> bool {
        self.inner.has_overlapping_branches()
    }
}

/// The equirectangular map of the unit square onto the sphere of
/// directions, in Mitsuba 3's environment-map convention (y up):
/// φ = 2π u, θ = π v, d = (sin θ sin φ, cos θ, −sin θ cos φ).
///
/// Its inverse is u = atan2(d.x, −d.z) / 2π wrapped into [0, 1) and
/// v = θ / π, with θ taken as atan2(√(d.x² + d.z²), d.y) so that it stays
/// accurate near the poles.
///
/// Density: p(u, v) / (2π² sin θ) in solid angle, Dirac order kept.
///
/// ```
/// use aether_core::Distribution;
/// use aether_core::primitives::{Equirect, UniformSquare};
///
/// let sky = Equirect::new(UniformSquare);
/// let up = sky.sample(&[0.3, 0.001]).unwrap().value;
/// assert!(up.y > 0.99);
/// // The horizon in the middle row, straight ahead (−z) at u = 0.
/// let ahead = sky.sample(&[0.0, 0.5]).unwrap();
/// assert!((ahead.value - glam::Vec3::NEG_Z).length() < 1e-6);
/// let p = 1.0 / (2.0 * std::f64::consts::PI.powi(2));
/// assert!((ahead.density.value() - p).abs() < 1e-9);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Equirect<D> {
    inner: D,
}

impl<D: Distribution<Value = Vec2>> Equirect<D> {
    /// Directions of the points (u, v) of `inner` on the unit square.
    pub fn new(inner: D) -> Self {
        Equirect { inner }
    }

    /// (u, v) of a direction and sin θ.
    fn coords(d: Vec3) -> (Vec2, f64) {
        let d = d.as_dvec3().normalize();
        let sin = d.x.hypot(d.z);
        let v = (sin.atan2(d.y) / PI) as f32;
        let u = turn_fraction(d.x as f32, -d.z as f32);
        (Vec2::new(u, v), sin)
    }

    fn jacobian(sin: f64) -> f64 {
        2.0 * PI * PI * sin
    }
}

impl<D: Distribution<Value = Vec2>> Distribution for Equirect<D> {
    type Value = Vec3;
    fn dims(&self) -> usize {
        self.inner.dims()
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<Vec3>> {
        let s = self.inner.sample(u)?;
        let phi = 2.0 * PI * f64::from(s.value.x);
        let theta = PI * f64::from(s.value.y);
        let (sin, cos) = theta.sin_cos();
        let d = DVec3::new(sin * phi.sin(), cos, -sin * phi.cos());
        Some(Sample::new(
            d.as_vec3(),
            s.density
                .convert(1.0 / Self::jacobian(sin), Measure::SolidAngle),
        ))
    }
    fn density(&self, d: &Vec3) -> Density {
        let (uv, sin) = Self::coords(*d);
        self.inner
            .density(&uv)
            .convert(1.0 / Self::jacobian(sin), Measure::SolidAngle)
    }
    fn invert(&self, d: &Vec3) -> Option<Uniforms> {
        self.inner.invert(&Self::coords(*d).0)
    }
    fn has_overlapping_branches(&self) -> bool {
        self.inner.has_overlapping_branches()
    }
}

/// Points of the plane placed in space on the plane through `origin`
/// spanned by the orthonormal `e1`, `e2`: origin + x e1 + y e2 (a thin
/// lens's aperture, a disk light).
///
/// A point is on the plane if its distance to it is at most 1e-4 times the
/// larger of 1, |origin| and its distance from origin: the rounding of
/// single-precision positions grows with their magnitude.
///
/// Density: p(x, y) in area measure, unchanged (an isometry); zero off the plane.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Planar<D> {
    inner: D,
    origin: Vec3,
    e1: Vec3,
    e2: Vec3,
}

impl<D: Distribution<Value = Vec2>> Planar<D> {
    /// Points of `inner` on the plane through `origin` with orthonormal axes `e1`, `e2`.
    pub fn new(inner: D, origin: Vec3, e1: Vec3, e2: Vec3) -> Self {
        debug_assert!(
            (e1.length_squared() - 1.0).abs() < 1e-3
                && (e2.length_squared() - 1.0).abs() < 1e-3
                && e1.dot(e2).abs() < 1e-3,
            "axes {e1}, {e2} are not orthonormal"
        );
        Planar {
            inner,
            origin,
            e1,
            e2,
        }
    }

    /// Plane coordinates of a point, or `None` off the plane.
    fn coords(&self, p: Vec3) -> Option<Vec2> {
        let d = (p - self.origin).as_dvec3();
        let (e1, e2) = (self.e1.as_dvec3(), self.e2.as_dvec3());
        let q = DVec2::new(d.dot(e1), d.dot(e2));
        let off = (d - q.x * e1 - q.y * e2).length();
        let scale = 1f64.max(f64::from(self.origin.length())).max(q.length());
        (off <= 1e-4 * scale).then(|| q.as_vec2())
    }
}

impl<D: Distribution<Value = Vec2>> Distribution for Planar<D> {
    type Value = Vec3;
    fn dims(&self) -> usize {
        self.inner.dims()
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<Vec3>> {
        let s = self.inner.sample(u)?;
        let q = s.value.as_dvec2();
        let p = self.origin.as_dvec3() + q.x * self.e1.as_dvec3() + q.y * self.e2.as_dvec3();
        Some(Sample::new(p.as_vec3(), s.density))
    }
    fn density(&self, p: &Vec3) -> Density {
        match self.coords(*p) {
            Some(q) => self.inner.density(&q),
            None => Density::zero(Measure::Area),
        }
    }
    fn invert(&self, p: &Vec3) -> Option<Uniforms> {
        self.inner.invert(&self.coords(*p)?)
    }
    fn has_overlapping_branches(&self) -> bool {
        self.inner.has_overlapping_branches()
    }
}

/// Points on the sphere of `radius` about `center` in the unit directions
/// of an inner distribution: center + radius · d.
///
/// A point is on the sphere if its distance to the centre is within 1e-4
/// of the radius, relatively (plus the rounding of the centre's magnitude).
///
/// Density: p(d) / radius² in area measure, Dirac order kept; zero off the sphere.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpherePoint<D> {
    directions: D,
    center: Vec3,
    radius: f32,
}

impl<D: Distribution<Value = Vec3>> SpherePoint<D> {
    /// Points of the sphere (`center`, positive `radius`) in the directions of `directions`.
    pub fn new(directions: D, center: Vec3, radius: f32) -> Self {
        debug_assert!(radius > 0.0, "radius {radius} is not positive");
        SpherePoint {
            directions,
            center,
            radius,
        }
    }

    /// The direction of a point from the centre, or `None` off the sphere.
    fn direction(&self, p: Vec3) -> Option<Vec3> {
        let d = (p - self.center).as_dvec3();
        let len = d.length();
        let r = f64::from(self.radius);
        // Single-precision points far from the origin are rounded by about
        // 1e-7 of their magnitude, whatever the radius.
        let tolerance = 1e-4 * r + 1e-6 * f64::from(self.center.abs().max_element());
        ((len - r).abs() <= tolerance && len > 0.0).then(|| (d / len).as_vec3())
    }

    fn area_factor(&self) -> f64 {
        1.0 / f64::from(self.radius).powi(2)
    }
}

impl<D: Distribution<Value = Vec3>> Distribution for SpherePoint<D> {
    type Value = Vec3;
    fn dims(&self) -> usize {
        self.directions.dims()
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<Vec3>> {
        let w = self.directions.sample(u)?;
        let p = self.center.as_dvec3() + f64::from(self.radius) * w.value.as_dvec3();
        Some(Sample::new(
            p.as_vec3(),
            w.density.convert(self.area_factor(), Measure::Area),
        ))
    }
    fn density(&self, p: &Vec3) -> Density {
        match self.direction(*p) {
            Some(w) => self
                .directions
                .density(&w)
                .convert(self.area_factor(), Measure::Area),
            None => Density::zero(Measure::Area),
        }
    }
    fn invert(&self, p: &Vec3) -> Option<Uniforms> {
        self.directions.invert(&self.direction(*p)?)
    }
    fn has_overlapping_branches(&self) -> bool {
        self.directions.has_overlapping_branches()
    }
}
