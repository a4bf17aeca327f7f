use std::f64::consts::PI;

use glam::{Vec2, Vec3};
use smallvec::smallvec;

use super::{UniformDisk, turn_fraction};
use crate::density::{Density, Measure};
use crate::distribution::{Distribution, Sample, Uniforms, below_one};

fn solid_angle(p: f64) -> Density {
    Density::new(p, Measure::SolidAngle)
}

/// Directions about +z with density proportional to cos θ: Malley's method
/// (the concentric disk lifted to the hemisphere).
///
/// Density: cos θ / π in solid angle.
///
/// ```
/// use aether_core::{Distribution, primitives::CosineHemisphere};
/// let w = CosineHemisphere.sample(&[0.3, 0.8]).unwrap();
/// assert!((w.density.value() - f64::from(w.value.z) / std::f64::consts::PI).abs() < 1e-6);
/// ```
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CosineHemisphere;

impl Distribution for CosineHemisphere {
    type Value = Vec3;
    fn dims(&self) -> usize {
        2
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<Vec3>> {
        let d = UniformDisk::concentric([u[0], u[1]]);
        let z = (1.0 - d.length_squared()).max(0.0).sqrt();
        let w = Vec3::new(d.x, d.y, z);
        Some(Sample::new(w, solid_angle(f64::from(z) / PI)))
    }
    fn density(&self, w: &Vec3) -> Density {
        solid_angle(f64::from(w.z).max(0.0) / PI)
    }
    fn invert(&self, w: &Vec3) -> Option<Uniforms> {
        if w.z <= 0.0 {
            return None;
        }
        UniformDisk::concentric_inverse(Vec2::new(w.x, w.y)).map(|u| smallvec![u[0], u[1]])
    }
}

/// Uniform directions on the hemisphere about +z.
///
/// Density: 1 / (2π) in solid angle.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct UniformHemisphere;

impl Distribution for UniformHemisphere {
    type Value = Vec3;
    fn dims(&self) -> usize {
        2
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<Vec3>> {
        Some(Sample::new(
            zone_direction(f64::from(u[0]), u[1]),
            solid_angle(1.0 / (2.0 * PI)),
        ))
    }
    fn density(&self, w: &Vec3) -> Density {
        solid_angle(if w.z >= 0.0 { 1.0 / (2.0 * PI) } else { 0.0 })
    }
    fn invert(&self, w: &Vec3) -> Option<Uniforms> {
        (w.z >= 0.0).then(|| smallvec![below_one(w.z), turn_fraction(w.y, w.x)])
    }
}

/// Uniform directions on the whole sphere.
///
/// Density: 1 / (4π) in solid angle.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct UniformSphere;

impl Distribution for UniformSphere {
    type Value = Vec3;
    fn dims(&self) -> usize {
        2
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<Vec3>> {
        let z = 1.0 - 2.0 * f64::from(u[0]);
        Some(Sample::new(
            zone_direction(z, u[1]),
            solid_angle(1.0 / (4.0 * PI)),
        ))
    }
    fn density(&self, _w: &Vec3) -> Density {
        solid_angle(1.0 / (4.0 * PI))
    }
    fn invert(&self, w: &Vec3) -> Option<Uniforms> {
        Some(smallvec![
            below_one((1.0 - w.z) / 2.0),
            turn_fraction(w.y, w.x)
        ])
    }
}

/// The direction with cosine `z` and azimuth `2π u`.
fn zone_direction(z: f64, u: f32) -> Vec3 {
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * f64::from(u);
    Vec3::new((r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32)
}

/// Uniform directions in the cone of half-angle θ_max about +z.
///
/// The cone is stored by 1 − cos θ_max in double precision, and directions
/// are built from sin θ, so that the tiny cones of distant sphere lights keep
/// their resolution in single precision.
///
/// Density: 1 / (2π (1 − cos θ_max)) in solid angle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UniformCone {
    one_minus_cos_max: f64,
}

impl UniformCone {
    /// The cone with cos θ_max = `cos_max` ∈ [−1, 1).
    #[must_use]
    pub fn new(cos_max: f64) -> Self {
        debug_assert!((-1.0..1.0).contains(&cos_max));
        UniformCone {
            one_minus_cos_max: 1.0 - cos_max,
        }
    }

    /// The cone subtended by a sphere of squared radius `r2` seen from
    /// squared distance `d2 > r2`: sin² θ_max = r² / d², without cancellation.
    #[must_use]
    pub fn subtended(r2: f64, d2: f64) -> Self {
        let sin2 = (r2 / d2).clamp(0.0, 1.0);
        UniformCone {
            one_minus_cos_max: sin2 / (1.0 + (1.0 - sin2).sqrt()),
        }
    }

    /// cos θ_max.
    #[must_use]
    pub fn cos_max(&self) -> f64 {
        1.0 - self.one_minus_cos_max
    }

    fn pdf(&self) -> f64 {
        1.0 / (2.0 * PI * self.one_minus_cos_max)
    }
}

impl Distribution for UniformCone {
    type Value = Vec3;
    fn dims(&self) -> usize {
        2
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<Vec3>> {
        let one_minus_cos = f64::from(u[0]) * self.one_minus_cos_max;
        let sin = (one_minus_cos * (2.0 - one_minus_cos)).max(0.0).sqrt();
        let phi = 2.0 * PI * f64::from(u[1]);
        let w = Vec3::new(
            (sin * phi.cos()) as f32,
            (sin * phi.sin()) as f32,
            (1.0 - one_minus_cos) as f32,
        );
        Some(Sample::new(w, solid_angle(self.pdf())))
    }
    fn density(&self, w: &Vec3) -> Density {
        solid_angle(if one_minus_cos(*w) <= self.one_minus_cos_max {
            self.pdf()
        } else {
            0.0
        })
    }
    fn invert(&self, w: &Vec3) -> Option<Uniforms> {
        let u0 = one_minus_cos(*w) / self.one_minus_cos_max;
        (u0 <= 1.0).then(|| smallvec![below_one(u0 as f32), turn_fraction(w.y, w.x)])
    }
}

/// 1 − cos θ of a unit direction, accurate for small θ.
fn one_minus_cos(w: Vec3) -> f64 {
    let z = f64::from(w.z);
    let sin2 = f64::from(w.x).powi(2) + f64::from(w.y).powi(2);
    if z > 0.0 { sin2 / (1.0 + z) } else { 1.0 - z }
}
