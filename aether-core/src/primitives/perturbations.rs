//! The offsets of Veach's perturbations: most moves small, a few large, so
//! that a Metropolis chain both explores a feature and leaves it.

use std::f64::consts::PI;

use glam::{Vec2, Vec3};
use smallvec::smallvec;

use super::turn_fraction;
use crate::density::{Density, Measure};
use crate::distribution::{Distribution, Sample, Uniforms, below_one};

/// A radius r = r_max (r_min / r_max)^u between `r_min` and `r_max`, whose
/// logarithm is uniform: Veach's lens and caustic perturbation sizes.
#[derive(Clone, Copy, Debug, PartialEq)]
struct LogRadius {
    max: f64,
    /// ln(r_max / r_min) > 0.
    log_ratio: f64,
}

impl LogRadius {
    fn new(min: f64, max: f64) -> Self {
        debug_assert!(min > 0.0 && max > min);
        LogRadius {
            max,
            log_ratio: (max / min).ln(),
        }
    }
    fn at(&self, u: f32) -> f64 {
        self.max * (-self.log_ratio * f64::from(u)).exp()
    }
    fn inverse(&self, r: f64) -> Option<f32> {
        let u = (self.max / r).ln() / self.log_ratio;
        (0.0..=1.0).contains(&u).then(|| below_one(u as f32))
    }
}

/// Offsets in the plane whose length r is log-uniform in [r_min, r_max]
/// and whose direction is uniform: Veach's lens perturbation, in pixels.
///
/// Density: 1 / (2π r² ln(r_max / r_min)) in area measure, zero outside
/// the annulus.
///
/// ```
/// use aether_core::{Distribution, primitives::ExponentialDisk};
/// let d = ExponentialDisk::new(0.1, 10.0);
/// let s = d.sample(&[0.5, 0.25]).unwrap();
/// assert!((s.value.length() - 1.0).abs() < 1e-5); // the geometric mean of 0.1 and 10
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExponentialDisk {
    radius: LogRadius,
}

impl ExponentialDisk {
    /// Offsets between `r_min` and `r_max` (0 < r_min < r_max).
    #[must_use]
    pub fn new(r_min: f32, r_max: f32) -> Self {
        ExponentialDisk {
            radius: LogRadius::new(f64::from(r_min), f64::from(r_max)),
        }
    }

    fn pdf(&self, r: f64) -> Density {
        Density::new(
            1.0 / (2.0 * PI * r * r * self.radius.log_ratio),
            Measure::Area,
        )
    }
}

impl Distribution for ExponentialDisk {
    type Value = Vec2;
    fn dims(&self) -> usize {
        2
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<Vec2>> {
        let r = self.radius.at(u[0]);
        let phi = 2.0 * PI * f64::from(u[1]);
        let p = Vec2::new((r * phi.cos()) as f32, (r * phi.sin()) as f32);
        Some(Sample::new(p, self.pdf(r)))
    }
    fn density(&self, p: &Vec2) -> Density {
        let r = f64::from(p.length());
        match self.radius.inverse(r) {
            Some(_) => self.pdf(r),
            None => Density::zero(Measure::Area),
        }
    }
    fn invert(&self, p: &Vec2) -> Option<Uniforms> {
        let u0 = self.radius.inverse(f64::from(p.length()))?;
        Some(smallvec![u0, turn_fraction(p.y, p.x)])
    }
}

/// Directions about +z whose angle θ to the axis is log-uniform in
/// [θ_min, θ_max] (θ_max ≤ π) and whose azimuth is uniform: Veach's caustic
/// and multi-chain perturbations of a direction.
///
/// Density: 1 / (2π sin θ · θ ln(θ_max / θ_min)) in solid angle.
///
/// ```
/// use aether_core::{Distribution, primitives::ExponentialCone};
/// let d = ExponentialCone::new(1e-4, 0.1);
/// let w = d.sample(&[0.0, 0.5]).unwrap().value;
/// assert!((w.z.acos() - 0.1).abs() < 1e-3);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExponentialCone {
    angle: LogRadius,
}

impl ExponentialCone {
    /// Angles between `theta_min` and `theta_max` radians.
    #[must_use]
    pub fn new(theta_min: f64, theta_max: f64) -> Self {
        ExponentialCone {
            angle: LogRadius::new(theta_min, theta_max.min(PI)),
        }
    }

    fn pdf(&self, theta: f64) -> Density {
        let sin = theta.sin();
        Density::new(
            1.0 / (2.0 * PI * sin * theta * self.angle.log_ratio),
            Measure::SolidAngle,
        )
    }

    /// θ of a unit direction, accurate for small angles.
    fn theta(w: Vec3) -> f64 {
        let sin = (f64::from(w.x).powi(2) + f64::from(w.y).powi(2)).sqrt();
        sin.atan2(f64::from(w.z))
    }
}

impl Distribution for ExponentialCone {
    type Value = Vec3;
    fn dims(&self) -> usize {
        2
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<Vec3>> {
        let theta = self.angle.at(u[0]);
        let phi = 2.0 * PI * f64::from(u[1]);
        let (sin, cos) = theta.sin_cos();
        let w = Vec3::new(
            (sin * phi.cos()) as f32,
            (sin * phi.sin()) as f32,
            cos as f32,
        );
        Some(Sample::new(w, self.pdf(theta)))
    }
    fn density(&self, w: &Vec3) -> Density {
        let theta = Self::theta(*w);
        match self.angle.inverse(theta) {
            Some(_) => self.pdf(theta),
            None => Density::zero(Measure::SolidAngle),
        }
    }
    fn invert(&self, w: &Vec3) -> Option<Uniforms> {
        let u0 = self.angle.inverse(Self::theta(*w))?;
        Some(smallvec![u0, turn_fraction(w.y, w.x)])
    }
}
