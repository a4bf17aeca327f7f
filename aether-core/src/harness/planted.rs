//! Planted faults: a distribution whose density is misreported, to show
//! that a check catches the mistake (a dropped Jacobian, a branch counted
//! twice) that a hand-written density could make.

use crate::density::Density;
use crate::distribution::{Distribution, Sample, Uniforms};

/// `distribution` sampled as it is, its density multiplied by
/// `factor(value)`.
///
/// ```
/// use aether_core::harness::{Check, Grid, SphereDirections, Misreported, check};
/// use aether_core::primitives::CosineHemisphere;
/// let doubled = Misreported { distribution: CosineHemisphere, factor: |_: &glam::Vec3| 2.0 };
/// assert!(check(&doubled, &Grid::new(SphereDirections, 16), &Check::default()).is_err());
/// ```
#[derive(Clone, Copy, Debug)]
pub struct Misreported<D, F> {
    /// What is sampled.
    pub distribution: D,
    /// The factor the density is off by, at a value.
    pub factor: F,
}

impl<D: Distribution, F: Fn(&D::Value) -> f64> Distribution for Misreported<D, F> {
    type Value = D::Value;
    fn dims(&self) -> usize {
        self.distribution.dims()
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<D::Value>> {
        let s = self.distribution.sample(u)?;
        let density = s.density.scale((self.factor)(&s.value));
        Some(Sample {
            value: s.value,
            density,
        })
    }
    fn density(&self, value: &D::Value) -> Density {
        self.distribution.density(value).scale((self.factor)(value))
    }
    fn invert(&self, value: &D::Value) -> Option<Uniforms> {
        self.distribution.invert(value)
    }
    fn has_overlapping_branches(&self) -> bool {
        self.distribution.has_overlapping_branches()
    }
}
