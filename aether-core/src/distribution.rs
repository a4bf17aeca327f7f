//! The one trait every building block implements: a map from uniforms to
//! values, its inverse, and the density it induces.

use glam::{Vec2, Vec3};
use smallvec::SmallVec;

use crate::density::Density;

/// A point of the unit hypercube: the uniforms a block consumes.
pub type Uniforms = SmallVec<[f32; 8]>;

/// Coordinates of a value embedded in ℝᵏ, used by the Jacobian check.
pub type Coords = SmallVec<[f64; 8]>;

/// A sampled value and the density recorded while sampling it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample<T> {
    /// The value.
    pub value: T,
    /// Its density, computed forward from the Jacobian at the uniforms used.
    pub density: Density,
}

impl<T> Sample<T> {
    /// Pairs a value with its density.
    pub fn new(value: T, density: Density) -> Self {
        Sample { value, density }
    }

    /// Maps the value, keeping the density (for measure-preserving relabelings).
    pub fn map<U>(self, f: impl FnOnce(T) -> U) -> Sample<U> {
        Sample {
            value: f(self.value),
            density: self.density,
        }
    }
}

/// The outcome of a strategy step: a vertex, or an event that ends the path.
///
/// Russian-roulette termination is an event with a probability, so its
/// density is defined (the discrete mass 1 − q); a miss is an outcome whose
/// density is not needed and is reported as zero.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Step<T> {
    /// The strategy produced a value (a vertex, or a tuple of vertices).
    Vertex(T),
    /// Russian roulette ended the path.
    Terminated,
    /// The ray left the scene without hitting anything.
    Missed,
}

impl<T> Step<T> {
    /// The vertex, if there is one.
    pub fn vertex(self) -> Option<T> {
        match self {
            Step::Vertex(v) => Some(v),
            _ => None,
        }
    }

    /// Maps the vertex.
    pub fn map<U>(self, f: impl FnOnce(T) -> U) -> Step<U> {
        match self {
            Step::Vertex(v) => Step::Vertex(f(v)),
            Step::Terminated => Step::Terminated,
            Step::Missed => Step::Missed,
        }
    }
}

/// A distribution written as an invertible map from the unit hypercube.
///
/// `sample` runs the map forward from uniforms and records the density from
/// the forward Jacobian; `density` runs it backward from a value (by the
/// blocks' analytic inverses) and must give the same density: the property
/// harness checks both against finite differences and histograms. Only the
/// primitives and combinators of this crate implement it by hand; strategies
/// compose them.
///
/// The density of a value is the sum, over its pre-images, of the discrete
/// probability of the choices taken divided by the Jacobian determinant
/// measured against the value's measure.
pub trait Distribution {
    /// What is sampled: a scalar, a direction, a point, a vertex step.
    type Value;

    /// The number of uniforms `sample` reads.
    fn dims(&self) -> usize;

    /// Maps `u` (of length at least [`dims`](Self::dims), each in `[0, 1)`)
    /// to a value and its density. `None` is a void sample: the map is not
    /// defined there (a microfacet normal facing away, total internal
    /// reflection), which is a loss of probability mass, not a value.
    fn sample(&self, u: &[f32]) -> Option<Sample<Self::Value>>;

    /// The density with which `sample` produces `value`, computed without
    /// casting rays. Zero if `value` cannot be produced.
    fn density(&self, value: &Self::Value) -> Density;

    /// Uniforms that `sample` maps to `value` (one pre-image), or `None`.
    fn invert(&self, value: &Self::Value) -> Option<Uniforms>;

    /// True if distinct branches of the map can produce the same value, so
    /// that the density is a sum over several pre-images (a lobe mixture).
    /// The Jacobian check then verifies the branches one at a time.
    fn has_overlapping_branches(&self) -> bool {
        false
    }
}

impl<D: Distribution + ?Sized> Distribution for &D {
    type Value = D::Value;
    fn dims(&self) -> usize {
        (**self).dims()
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<D::Value>> {
        (**self).sample(u)
    }
    fn density(&self, value: &D::Value) -> Density {
        (**self).density(value)
    }
    fn invert(&self, value: &D::Value) -> Option<Uniforms> {
        (**self).invert(value)
    }
    fn has_overlapping_branches(&self) -> bool {
        (**self).has_overlapping_branches()
    }
}

/// Embeds a value in ℝᵏ so that its measure is the one induced by the
/// embedding (area on a surface, solid angle on the sphere of directions).
///
/// The returned integer is the dimension of the manifold the value lives on
/// (2 for points on surfaces and for directions, 0 for discrete values and
/// Dirac points).
pub trait Embed {
    /// Writes the coordinates and returns the manifold dimension.
    fn embed(&self, coords: &mut Coords) -> usize;
}

impl Embed for f32 {
    fn embed(&self, coords: &mut Coords) -> usize {
        coords.push(f64::from(*self));
        1
    }
}

impl Embed for usize {
    fn embed(&self, _coords: &mut Coords) -> usize {
        0
    }
}

impl Embed for Vec2 {
    fn embed(&self, coords: &mut Coords) -> usize {
        coords.extend([f64::from(self.x), f64::from(self.y)]);
        2
    }
}

/// A `Vec3` is a point on a surface or a unit direction: a 2-manifold in ℝ³
/// either way, so the induced measure is area or solid angle.
impl Embed for Vec3 {
    fn embed(&self, coords: &mut Coords) -> usize {
        coords.extend([f64::from(self.x), f64::from(self.y), f64::from(self.z)]);
        2
    }
}

/// Clamps a remapped uniform below one, where rounding can push it.
#[inline]
pub(crate) fn below_one(u: f32) -> f32 {
    u.min(1.0 - f32::EPSILON / 2.0)
}

/// True if every uniform lies in the unit interval (pre-images outside it
/// do not count).
#[inline]
pub(crate) fn in_unit_cube(u: &[f32]) -> bool {
    u.iter().all(|&x| (0.0..=1.0).contains(&x))
}
