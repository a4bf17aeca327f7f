use glam::{DVec3, Vec3};

use crate::density::{Density, Measure};
use crate::distribution::{Distribution, Sample, Uniforms};

/// Reflection of `wi` about normals drawn from `normals`: the microfacet
/// reflection block.
///
/// Density: p_m(m) / (4 |wo · m|) in solid angle, with m the half vector
/// of `wi` and `wo` (the half-vector Jacobian).
///
/// A normal that faces away from `wi` gives a void sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Reflect<D> {
    wi: Vec3,
    normals: D,
}

impl<D: Distribution<Value = Vec3>> Reflect<D> {
    /// Reflects unit `wi` (pointing away from the surface) about normals from `normals`.
    pub fn new(wi: Vec3, normals: D) -> Self {
        Reflect { wi, normals }
    }
}

impl<D: Distribution<Value = Vec3>> Distribution for Reflect<D> {
    type Value = Vec3;
    fn dims(&self) -> usize {
        self.normals.dims()
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<Vec3>> {
        let m = self.normals.sample(u)?;
        let wi = self.wi.as_dvec3();
        let md = m.value.as_dvec3();
        let c = wi.dot(md);
        if c <= 0.0 {
            return None;
        }
        let wo = (2.0 * c * md - wi).normalize();
        Some(Sample::new(wo.as_vec3(), m.density.scale(1.0 / (4.0 * c))))
    }
    fn density(&self, wo: &Vec3) -> Density {
        let h = self.wi.as_dvec3() + wo.as_dvec3();
        if h.length_squared() < 1e-12 {
            return Density::zero(Measure::SolidAngle);
        }
        let m = h.normalize();
        let c = wo.as_dvec3().dot(m);
        self.normals.density(&m.as_vec3()).scale(1.0 / (4.0 * c))
    }
    fn invert(&self, wo: &Vec3) -> Option<Uniforms> {
        let h = self.wi + *wo;
        (h.length_squared() > 1e-12)
            .then(|| self.normals.invert(&h.normalize()))
            .flatten()
    }
}

/// Refraction of `wi` through normals drawn from `normals`, for relative
/// index `eta` = η_transmitted / η_incident: the microfacet transmission block.
///
/// Density: p_m(m) η² |wo·m| / (wi·m + η wo·m)² in solid angle (Walter et
/// al. 2007), with m the generalised half vector −(wi + η wo), oriented
/// towards `wi`. Total internal reflection gives a void sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Refract<D> {
    wi: Vec3,
    eta: f32,
    normals: D,
}

impl<D: Distribution<Value = Vec3>> Refract<D> {
    /// Refracts unit `wi` (pointing away from the surface) with relative index `eta`.
    pub fn new(wi: Vec3, eta: f32, normals: D) -> Self {
        debug_assert!(
            eta > 0.0 && eta != 1.0,
            "refraction needs a relative index other than 1"
        );
        Refract { wi, eta, normals }
    }

    fn jacobian(&self, wo: DVec3, m: DVec3) -> f64 {
        let eta = f64::from(self.eta);
        let wi = self.wi.as_dvec3();
        let denom = wi.dot(m) + eta * wo.dot(m);
        eta * eta * wo.dot(m).abs() / (denom * denom)
    }
}

impl<D: Distribution<Value = Vec3>> Distribution for Refract<D> {
    type Value = Vec3;
    fn dims(&self) -> usize {
        self.normals.dims()
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<Vec3>> {
        let m = self.normals.sample(u)?;
        let md = m.value.as_dvec3();
        let wi = self.wi.as_dvec3();
        let c = wi.dot(md);
        if c <= 0.0 {
            return None;
        }
        let eta = f64::from(self.eta);
        let sin2_t = (1.0 - c * c).max(0.0) / (eta * eta);
        if sin2_t >= 1.0 {
            return None;
        }
        let wo = (-wi / eta + (c / eta - (1.0 - sin2_t).sqrt()) * md).normalize();
        Some(Sample::new(
            wo.as_vec3(),
            m.density.scale(self.jacobian(wo, md)),
        ))
    }
    fn density(&self, wo: &Vec3) -> Density {
        match self.half_vector(*wo) {
            Some(m) => self
                .normals
                .density(&m.as_vec3())
                .scale(self.jacobian(wo.as_dvec3(), m)),
            None => Density::zero(Measure::SolidAngle),
        }
    }
    fn invert(&self, wo: &Vec3) -> Option<Uniforms> {
        self.half_vector(*wo)
            .and_then(|m| self.normals.invert(&m.as_vec3()))
    }
}

impl<D> Refract<D> {
    /// The generalised half vector, if `wo` is on the far side of it from `wi`.
    fn half_vector(&self, wo: Vec3) -> Option<DVec3> {
        let (wi, wo) = (self.wi.as_dvec3(), wo.as_dvec3());
        let h = -(wi + f64::from(self.eta) * wo);
        if h.length_squared() < 1e-12 {
            return None;
        }
        let mut m = h.normalize();
        if m.dot(wi) < 0.0 {
            m = -m;
        }
        (wi.dot(m) > 0.0 && wo.dot(m) < 0.0).then_some(m)
    }
}

/// A Dirac direction (a specular lobe, a directional light) with discrete `mass`.
///
/// Density: a Dirac component of the given mass at `direction`, zero
/// elsewhere. A direction counts as the same if it is within
/// [`DiracDirection::TOLERANCE`] (1 − cos) of the lobe's: vertices are stored
/// in single precision and offset against self-intersection, so exact
/// equality would miss the paths the lobe itself produced.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DiracDirection {
    direction: Vec3,
    mass: f64,
}

impl DiracDirection {
    /// 1 − cos of the largest angle at which a direction still matches (about 0.08°).
    pub const TOLERANCE: f64 = 1e-6;

    /// The Dirac lobe in unit `direction` with probability `mass`.
    #[must_use]
    pub fn new(direction: Vec3, mass: f64) -> Self {
        DiracDirection { direction, mass }
    }
}

impl Distribution for DiracDirection {
    type Value = Vec3;
    fn dims(&self) -> usize {
        0
    }
    fn sample(&self, _u: &[f32]) -> Option<Sample<Vec3>> {
        Some(Sample::new(
            self.direction,
            Density::dirac(self.mass, Measure::SolidAngle),
        ))
    }
    fn density(&self, w: &Vec3) -> Density {
        let cos = self.direction.as_dvec3().dot(w.as_dvec3().normalize());
        if 1.0 - cos <= Self::TOLERANCE {
            Density::dirac(self.mass, Measure::SolidAngle)
        } else {
            Density::zero(Measure::SolidAngle)
        }
    }
    fn invert(&self, w: &Vec3) -> Option<Uniforms> {
        (!self.density(w).is_zero()).then(Uniforms::new)
    }
}

/// The directions of `inner` (unit, +z side of the local frame) carried
/// through a smooth interface with normal +z by Snell's law, for relative
/// index `eta` = η_other / η_+z: smooth transmission as a change of
/// variables.
///
/// Density: that of the pre-image ω under `inner`, times the Jacobian
/// |dω / dω_t| = η² |cos θt| / |cos θ| (from η² cos θ dω = η_t² cos θt dω_t
/// in radiance units). A Dirac `inner` of mass m becomes a Dirac of mass
/// m η² |cos θt| / |cos θ|: the lobe of a path that sampled ω_t measured in
/// the solid angle of ω, as a path sampled the other way measures it.
///
/// A direction that total internal reflection keeps on the +z side gives
/// a void sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SmoothRefraction<D> {
    inner: D,
    eta: f32,
}

impl<D: Distribution<Value = Vec3>> SmoothRefraction<D> {
    /// Refracts the directions of `inner` for relative index `eta`.
    pub fn new(inner: D, eta: f32) -> Self {
        SmoothRefraction { inner, eta }
    }

    /// |dω / dω_t| for a direction `w` on the +z side and its refraction `t`.
    fn jacobian(&self, w: Vec3, t: Vec3) -> f64 {
        let eta = f64::from(self.eta);
        eta * eta * f64::from(t.z).abs() / f64::from(w.z).abs()
    }

    /// The direction on the +z side that refracts into `t` (on the −z side).
    fn preimage(&self, t: Vec3) -> Option<Vec3> {
        if t.z >= 0.0 {
            return None;
        }
        crate::refract(t, -Vec3::Z, 1.0 / self.eta).filter(|w| w.z > 0.0)
    }
}

impl<D: Distribution<Value = Vec3>> Distribution for SmoothRefraction<D> {
    type Value = Vec3;
    fn dims(&self) -> usize {
        self.inner.dims()
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<Vec3>> {
        let s = self.inner.sample(u)?;
        let t = crate::refract(s.value, Vec3::Z, self.eta)?;
        Some(Sample::new(t, s.density.scale(self.jacobian(s.value, t))))
    }
    fn density(&self, t: &Vec3) -> Density {
        match self.preimage(*t) {
            Some(w) => self.inner.density(&w).scale(self.jacobian(w, *t)),
            None => Density::zero(Measure::SolidAngle),
        }
    }
    fn invert(&self, t: &Vec3) -> Option<Uniforms> {
        self.inner.invert(&self.preimage(*t)?)
    }
}
