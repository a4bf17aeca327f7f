//! BSDFs at a shading point: their values, and their sampling written in
//! the language's blocks (so their densities come from the language).
//!
//! Directions are in the local shading frame (+z the shading normal), both
//! pointing away from the surface.

use aether_core::primitives::{
    BeckmannNormals, CosineHemisphere, DiracDirection, DiscreteDistribution, GgxVisibleNormals,
    Reflect, Refract,
};
use aether_core::{Distribution, Either, Mixture};
use glam::{DVec3, Vec3};

use crate::scene::{Material, MicrofacetKind, Roughness};

/// Unpolarised Fresnel reflectance of a dielectric interface; `cos_i` on
/// the side `eta` = η_other / η_this is relative to. Total internal
/// reflection gives 1.
#[must_use]
pub fn fresnel_dielectric(cos_i: f32, eta: f32) -> f32 {
    let cos_i = cos_i.clamp(-1.0, 1.0).abs();
    let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    let rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    0.5 * (rs * rs + rp * rp)
}

/// Fresnel reflectance of a conductor with complex index η + ik, per channel.
#[must_use]
pub fn fresnel_conductor(cos_i: f32, eta: Vec3, k: Vec3) -> Vec3 {
    let c = f64::from(cos_i.clamp(0.0, 1.0));
    let (eta, k) = (eta.as_dvec3(), k.as_dvec3());
    let c2 = c * c;
    let s2 = 1.0 - c2;
    let t0 = eta * eta - k * k - DVec3::splat(s2);
    let a2b2 = (t0 * t0 + 4.0 * eta * eta * k * k).map(f64::sqrt);
    let a = (0.5 * (a2b2 + t0)).map(|x| x.max(0.0).sqrt());
    let t1 = a2b2 + DVec3::splat(c2);
    let t2 = 2.0 * c * a;
    let rs = (t1 - t2) / (t1 + t2);
    let t3 = c2 * a2b2 + DVec3::splat(s2 * s2);
    let t4 = t2 * s2;
    let rp = rs * (t3 - t4) / (t3 + t4);
    (0.5 * (rp + rs)).as_vec3()
}

/// A microfacet normal distribution seen from `wi`.
type Normals = Either<GgxVisibleNormals, BeckmannNormals>;

fn normals(r: Roughness, wi: Vec3) -> Normals {
    match r.kind {
        MicrofacetKind::Ggx => Either::Left(GgxVisibleNormals::new(r.alpha[0], r.alpha[1], wi)),
        MicrofacetKind::Beckmann => Either::Right(BeckmannNormals::new(r.alpha[0].max(r.alpha[1]))),
    }
}

/// One lobe of a BSDF's sampling.
type Lobe =
    Either<Either<CosineHemisphere, DiracDirection>, Either<Reflect<Normals>, Refract<Normals>>>;

fn diffuse() -> Lobe {
    Either::Left(Either::Left(CosineHemisphere))
}

fn mirror(wi: Vec3) -> Lobe {
    Either::Left(Either::Right(DiracDirection::new(
        Vec3::new(-wi.x, -wi.y, wi.z),
        1.0,
    )))
}

fn transmit(wi: Vec3, eta: f32) -> Option<Lobe> {
    aether_core::refract(wi, Vec3::Z, eta)
        .map(|d| Either::Left(Either::Right(DiracDirection::new(d, 1.0))))
}

/// The sampling of a material at a shading point, for incident direction
/// `wi` (local, z > 0 on the side it arrives from), as lobes and their
/// probabilities. `eta` for dielectrics is the relative index across the
/// surface from `wi`'s side.
#[derive(Debug)]
pub struct Lobes {
    choice: DiscreteDistribution,
    lobes: Vec<Lobe>,
}

impl Lobes {
    /// The lobes of `material` for `wi` (z > 0), `eta` = η_t / η_i.
    #[must_use]
    pub fn of(material: &Material, wi: Vec3, eta: f32) -> Lobes {
        let single = |lobe| Lobes {
            choice: DiscreteDistribution::new(&[1.0]).expect("one weight"),
            lobes: vec![lobe],
        };
        match material {
            Material::Diffuse { .. } => single(diffuse()),
            Material::Conductor {
                roughness: None, ..
            } => single(mirror(wi)),
            Material::Conductor {
                roughness: Some(r), ..
            } => single(Either::Right(Either::Left(Reflect::new(
                wi,
                normals(*r, wi),
            )))),
            Material::Dielectric { roughness, .. } => {
                let f = f64::from(fresnel_dielectric(wi.z, eta));
                let (reflect, refract): (Lobe, Option<Lobe>) = match roughness {
                    None => (mirror(wi), transmit(wi, eta)),
                    Some(r) => (
                        Either::Right(Either::Left(Reflect::new(wi, normals(*r, wi)))),
                        Some(Either::Right(Either::Right(Refract::new(
                            wi,
                            eta,
                            normals(*r, wi),
                        )))),
                    ),
                };
                match refract {
                    Some(t) if f < 1.0 => Lobes {
                        choice: DiscreteDistribution::new(&[f.max(1e-3), (1.0 - f).max(1e-3)])
                            .expect("positive"),
                        lobes: vec![reflect, t],
                    },
                    _ => single(reflect),
                }
            }
            Material::Plastic { roughness, .. } => {
                let f = f64::from(fresnel_dielectric(wi.z, eta)).clamp(0.05, 0.95);
                let specular = match roughness {
                    None => mirror(wi),
                    Some(r) => Either::Right(Either::Left(Reflect::new(wi, normals(*r, wi)))),
                };
                Lobes {
                    choice: DiscreteDistribution::new(&[f, 1.0 - f]).expect("positive"),
                    lobes: vec![specular, diffuse()],
                }
            }
            Material::BumpMap { inner, .. } | Material::TwoSided(inner) => {
                Lobes::of(inner, wi, eta)
            }
        }
    }

    /// The directions these lobes sample, with the mixture's density.
    pub fn distribution(&self) -> impl Distribution<Value = Vec3> + '_ {
        Mixture::new(&self.choice, 2, move |i| self.lobes[i])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fresnel_limits() {
        assert!((fresnel_dielectric(1.0, 1.5) - 0.04).abs() < 1e-4);
        assert_eq!(fresnel_dielectric(0.1, 1.0 / 1.5), 1.0);
        assert!(fresnel_dielectric(0.0, 1.5) > 0.99);
        // A conductor with k = 0 is a dielectric.
        let c = fresnel_conductor(0.7, Vec3::splat(1.5), Vec3::ZERO);
        assert!((c.x - fresnel_dielectric(0.7, 1.5)).abs() < 1e-5);
        // Aluminium reflects most light at normal incidence.
        let al = fresnel_conductor(
            1.0,
            Vec3::new(1.6575, 0.880405, 0.521244),
            Vec3::new(9.22381, 6.2695, 4.837),
        );
        assert!(al.min_element() > 0.85, "{al}");
    }
}
