use std::f64::consts::PI;

use glam::{DVec3, Vec3};
use smallvec::smallvec;

use super::turn_fraction;
use crate::density::{Density, Measure};
use crate::distribution::{Distribution, Sample, Uniforms, below_one};

/// GGX (Trowbridge–Reitz) microfacet normals sampled from the distribution
/// of normals visible from `wi` (Heitz 2018), in the local frame (+z is the
/// macro-surface normal). Anisotropic roughness (αx, αy).
///
/// Density: D_wi(m) = G₁(wi) max(0, wi·m) D(m) / cos θ_i in solid angle.
///
/// Limitations: `wi` must lie above the surface (wi.z > 0); BSDFs flip
/// directions into the upper hemisphere before sampling.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GgxVisibleNormals {
    ax: f64,
    ay: f64,
    wi: DVec3,
}

impl GgxVisibleNormals {
    /// The visible normals seen from unit `wi` (wi.z > 0) for roughness `ax`, `ay` > 0.
    #[must_use]
    pub fn new(ax: f32, ay: f32, wi: Vec3) -> Self {
        debug_assert!(ax > 0.0 && ay > 0.0 && wi.z > 0.0);
        GgxVisibleNormals {
            ax: f64::from(ax),
            ay: f64::from(ay),
            wi: wi.as_dvec3().normalize(),
        }
    }

    /// The GGX normal distribution D(m).
    #[must_use]
    pub fn ndf(&self, m: DVec3) -> f64 {
        if m.z <= 0.0 {
            return 0.0;
        }
        let t = (m.x / self.ax).powi(2) + (m.y / self.ay).powi(2) + m.z * m.z;
        1.0 / (PI * self.ax * self.ay * t * t)
    }

    /// Smith's masking term G₁(w).
    #[must_use]
    pub fn g1(&self, w: DVec3) -> f64 {
        let tan2 = ((self.ax * w.x).powi(2) + (self.ay * w.y).powi(2)) / (w.z * w.z);
        2.0 / (1.0 + (1.0 + tan2).sqrt())
    }

    fn pdf(&self, m: DVec3) -> f64 {
        let dot = self.wi.dot(m);
        if dot <= 0.0 || m.z <= 0.0 {
            return 0.0;
        }
        self.g1(self.wi) * dot * self.ndf(m) / self.wi.z
    }

    /// The hemisphere configuration: stretched view direction and its frame.
    fn stretched_frame(&self) -> (DVec3, DVec3, DVec3) {
        let vh = DVec3::new(self.ax * self.wi.x, self.ay * self.wi.y, self.wi.z).normalize();
        let len2 = vh.x * vh.x + vh.y * vh.y;
        let t1 = if len2 > 0.0 {
            DVec3::new(-vh.y, vh.x, 0.0) / len2.sqrt()
        } else {
            DVec3::X
        };
        let t2 = vh.cross(t1);
        (vh, t1, t2)
    }
}

impl Distribution for GgxVisibleNormals {
    type Value = Vec3;
    fn dims(&self) -> usize {
        2
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<Vec3>> {
        let (vh, t1v, t2v) = self.stretched_frame();
        let r = f64::from(u[0]).sqrt();
        let phi = 2.0 * PI * f64::from(u[1]);
        let t1 = r * phi.cos();
        let s = 0.5 * (1.0 + vh.z);
        let t2 = (1.0 - s) * (1.0 - t1 * t1).max(0.0).sqrt() + s * r * phi.sin();
        let nh = t1 * t1v + t2 * t2v + (1.0 - t1 * t1 - t2 * t2).max(0.0).sqrt() * vh;
        let m = DVec3::new(self.ax * nh.x, self.ay * nh.y, nh.z.max(0.0)).normalize();
        let p = self.pdf(m);
        (p > 0.0).then(|| Sample::new(m.as_vec3(), Density::new(p, Measure::SolidAngle)))
    }
    fn density(&self, m: &Vec3) -> Density {
        Density::new(self.pdf(m.as_dvec3().normalize()), Measure::SolidAngle)
    }
    fn invert(&self, m: &Vec3) -> Option<Uniforms> {
        let m = m.as_dvec3().normalize();
        if self.pdf(m) <= 0.0 {
            return None;
        }
        let (vh, t1v, t2v) = self.stretched_frame();
        let nh = DVec3::new(m.x / self.ax, m.y / self.ay, m.z).normalize();
        let t1 = nh.dot(t1v);
        let s = 0.5 * (1.0 + vh.z);
        let t2 = (nh.dot(t2v) - (1.0 - s) * (1.0 - t1 * t1).max(0.0).sqrt()) / s;
        let r2 = t1 * t1 + t2 * t2;
        (r2 <= 1.0 + 1e-6)
            .then(|| smallvec![below_one(r2 as f32), turn_fraction(t2 as f32, t1 as f32)])
    }
}

/// Beckmann microfacet normals sampled by D(m) cos θ_m (isotropic α):
/// tan² θ = −α² ln(1 − u₀), φ = 2π u₁.
///
/// Density: D(m) cos θ_m in solid angle, with
/// D(m) = exp(−tan² θ / α²) / (π α² cos⁴ θ).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BeckmannNormals {
    alpha: f64,
}

impl BeckmannNormals {
    /// Normals of roughness `alpha` > 0.
    #[must_use]
    pub fn new(alpha: f32) -> Self {
        debug_assert!(alpha > 0.0);
        BeckmannNormals {
            alpha: f64::from(alpha),
        }
    }

    /// The Beckmann normal distribution D(m).
    #[must_use]
    pub fn ndf(&self, m: DVec3) -> f64 {
        if m.z <= 0.0 {
            return 0.0;
        }
        let cos2 = m.z * m.z;
        let tan2 = (1.0 - cos2).max(0.0) / cos2;
        let a2 = self.alpha * self.alpha;
        (-tan2 / a2).exp() / (PI * a2 * cos2 * cos2)
    }
}

impl Distribution for BeckmannNormals {
    type Value = Vec3;
    fn dims(&self) -> usize {
        2
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<Vec3>> {
        let tan2 = -self.alpha * self.alpha * (-f64::from(u[0])).ln_1p();
        let cos = 1.0 / (1.0 + tan2).sqrt();
        let sin = (tan2 / (1.0 + tan2)).sqrt();
        let phi = 2.0 * PI * f64::from(u[1]);
        let m = DVec3::new(sin * phi.cos(), sin * phi.sin(), cos);
        let p = self.ndf(m) * cos;
        (p > 0.0).then(|| Sample::new(m.as_vec3(), Density::new(p, Measure::SolidAngle)))
    }
    fn density(&self, m: &Vec3) -> Density {
        let m = m.as_dvec3().normalize();
        Density::new(self.ndf(m) * m.z, Measure::SolidAngle)
    }
    fn invert(&self, m: &Vec3) -> Option<Uniforms> {
        let md = m.as_dvec3().normalize();
        if md.z <= 0.0 {
            return None;
        }
        let tan2 = (md.x * md.x + md.y * md.y) / (md.z * md.z);
        let u0 = -(-tan2 / (self.alpha * self.alpha)).exp_m1();
        Some(smallvec![below_one(u0 as f32), turn_fraction(m.y, m.x)])
    }
}
