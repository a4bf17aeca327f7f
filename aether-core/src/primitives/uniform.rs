use glam::Vec2;
use smallvec::smallvec;

use crate::density::{Density, Measure};
use crate::distribution::{Distribution, Sample, Uniforms, below_one};

/// The uniform distribution on `[a, b)`.
///
/// Density: 1 / (b − a) in length measure.
///
/// ```
/// use aether_core::{Distribution, primitives::UniformInterval};
/// let d = UniformInterval::new(2.0, 4.0);
/// assert_eq!(d.sample(&[0.5]).unwrap().value, 3.0);
/// assert_eq!(d.density(&3.0).value(), 0.5);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UniformInterval {
    a: f32,
    b: f32,
}

impl UniformInterval {
    /// The interval `[a, b)`; `a < b`.
    #[must_use]
    pub fn new(a: f32, b: f32) -> Self {
        debug_assert!(a < b, "empty interval [{a}, {b})");
        UniformInterval { a, b }
    }

    fn pdf(&self) -> Density {
        Density::new(1.0 / f64::from(self.b - self.a), Measure::Length)
    }
}

impl Distribution for UniformInterval {
    type Value = f32;
    fn dims(&self) -> usize {
        1
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<f32>> {
        Some(Sample::new(self.a + u[0] * (self.b - self.a), self.pdf()))
    }
    fn density(&self, x: &f32) -> Density {
        if (self.a..self.b).contains(x) {
            self.pdf()
        } else {
            Density::zero(Measure::Length)
        }
    }
    fn invert(&self, x: &f32) -> Option<Uniforms> {
        (self.a..self.b)
            .contains(x)
            .then(|| smallvec![below_one((x - self.a) / (self.b - self.a))])
    }
}

/// The uniform distribution on the unit square: the identity map.
///
/// Density: 1 in area measure.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct UniformSquare;

impl Distribution for UniformSquare {
    type Value = Vec2;
    fn dims(&self) -> usize {
        2
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<Vec2>> {
        Some(Sample::new(
            Vec2::new(u[0], u[1]),
            Density::new(1.0, Measure::Area),
        ))
    }
    fn density(&self, p: &Vec2) -> Density {
        let inside = (0.0..1.0).contains(&p.x) && (0.0..1.0).contains(&p.y);
        Density::new(if inside { 1.0 } else { 0.0 }, Measure::Area)
    }
    fn invert(&self, p: &Vec2) -> Option<Uniforms> {
        let inside = (0.0..1.0).contains(&p.x) && (0.0..1.0).contains(&p.y);
        inside.then(|| smallvec![p.x, p.y])
    }
}
