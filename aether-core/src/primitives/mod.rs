//! The closed set of primitives: each is an invertible map from the unit
//! square (or interval) with an analytic inverse and Jacobian.
//!
//! | family | types | measure |
//! |---|---|---|
//! | uniform | [`UniformInterval`], [`UniformSquare`] | length, area |
//! | discrete | [`DiscreteDistribution`] | counting |
//! | tabulated | [`PiecewiseConstant1D`], [`PiecewiseConstant2D`] | length, area |
//! | planar | [`UniformDisk`], [`UniformTriangle`] | area |
//! | directions | [`CosineHemisphere`], [`UniformHemisphere`], [`UniformSphere`], [`UniformCone`] | solid angle |
//! | perturbations | [`ExponentialDisk`] (plane offsets), [`ExponentialCone`] (directions about an axis), log-uniform in size | area, solid angle |
//! | microfacets | [`GgxVisibleNormals`], [`BeckmannNormals`] | solid angle |
//! | scattering | [`Reflect`], [`Refract`] (half-vector Jacobians), [`SmoothRefraction`] (Snell's Jacobian), [`DiracDirection`] | solid angle, Dirac |
//! | projections | [`Gnomonic`] (film plane → directions), [`Equirect`] (unit square → directions) | solid angle |
//! | embeddings | [`Affine2`] (plane → plane), [`Planar`] (plane → a plane in space), [`SpherePoint`] (directions → a sphere) | area |
//!
//! Every primitive is checked by the property harness in
//! [`harness`](crate::harness): recorded density against density mode,
//! against finite differences of the forward map, and by chi-square.

mod directions;
mod discrete;
mod microfacet;
mod perturbations;
mod piecewise;
mod planar;
mod projections;
mod scattering;
mod uniform;

pub use directions::{CosineHemisphere, UniformCone, UniformHemisphere, UniformSphere};
pub use discrete::{DiscreteDistribution, DiscreteError};
pub use microfacet::{BeckmannNormals, GgxVisibleNormals};
pub use perturbations::{ExponentialCone, ExponentialDisk};
pub use piecewise::{PiecewiseConstant1D, PiecewiseConstant2D};
pub use planar::{UniformDisk, UniformTriangle};
pub use projections::{Affine2, Equirect, Gnomonic, Planar, SpherePoint};
pub use scattering::{DiracDirection, Reflect, Refract, SmoothRefraction};
pub use uniform::{UniformCells, UniformInterval, UniformSquare};

use std::f64::consts::PI;

/// Angle of (x, y) mapped to [0, 1).
#[inline]
pub(crate) fn turn_fraction(y: f32, x: f32) -> f32 {
    let phi = f64::from(y).atan2(f64::from(x));
    let t = if phi < 0.0 {
        phi / (2.0 * PI) + 1.0
    } else {
        phi / (2.0 * PI)
    };
    crate::distribution::below_one(t as f32)
}
