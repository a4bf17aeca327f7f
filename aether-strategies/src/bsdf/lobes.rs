//! The sampling of each material, written in the language's blocks so that
//! its densities come from the language.
//!
//! Directions are in the local shading frame (+z the shading normal), both
//! pointing away from the surface; `given` is the direction the path came
//! from, on the +z side.

use aether_core::primitives::{
    BeckmannNormals, CosineHemisphere, DiracDirection, DiscreteDistribution, GgxVisibleNormals,
    Reflect, Refract, SmoothRefraction,
};
use aether_core::{Density, Distribution, Either, Mixture, Sample, Uniforms};
use glam::Vec3;

use super::Transport;
use super::fresnel::fresnel_dielectric;
use crate::scene::{Material, MicrofacetKind, Roughness};

/// A microfacet normal distribution seen from `given`.
type Normals = Either<GgxVisibleNormals, BeckmannNormals>;

fn normals(r: Roughness, given: Vec3) -> Normals {
    match r.kind {
        MicrofacetKind::Ggx => Either::Left(GgxVisibleNormals::new(r.alpha[0], r.alpha[1], given)),
        MicrofacetKind::Beckmann => Either::Right(BeckmannNormals::new(r.alpha[0].max(r.alpha[1]))),
    }
}

/// One lobe of a BSDF's sampling.
type Lobe = Either<Either<CosineHemisphere, Dirac>, Either<Reflect<Normals>, Refract<Normals>>>;

/// A Dirac lobe: sampled in the solid angle it lies in, or refracted
/// from the one a path sampled the other way would use.
type Dirac = Either<DiracDirection, SmoothRefraction<DiracDirection>>;

fn diffuse() -> Lobe {
    Either::Left(Either::Left(CosineHemisphere))
}

fn mirror(given: Vec3) -> Lobe {
    Either::Left(Either::Right(Either::Left(DiracDirection::new(
        Vec3::new(-given.x, -given.y, given.z),
        1.0,
    ))))
}

fn glossy(r: Roughness, given: Vec3) -> Lobe {
    Either::Right(Either::Left(Reflect::new(given, normals(r, given))))
}

/// The smooth transmission lobe, for the direction `t` that `given`
/// refracts into. Path densities express every Dirac lobe in
/// the direction towards the light end of the path (the one camera paths
/// sample), so a light path, which samples the other direction, refracts
/// the direction it came from: the language carries the atom into the
/// refracted direction with Snell's Jacobian (dω_light / dω_camera, checked
/// by the harness). Then f / p is the same expression whichever end sampled
/// the refraction, and MIS compares like with like.
fn transmit(given: Vec3, t: Vec3, eta: f32, mode: Transport) -> Lobe {
    let dirac = match mode {
        Transport::Radiance => Either::Left(DiracDirection::new(t, 1.0)),
        Transport::Importance => {
            Either::Right(SmoothRefraction::new(DiracDirection::new(given, 1.0), eta))
        }
    };
    Either::Left(Either::Right(dirac))
}

/// Which lobe, with what it needs beyond the direction the path arrived
/// along: the lobes themselves (72 bytes each) are built where they are
/// sampled or evaluated. Built up front, they made [`Lobes`] 200 bytes,
/// written at every scattering event and every density of BSDF sampling
/// and copied through each layer of the strategy around it.
#[derive(Clone, Copy, Debug)]
enum Kind {
    Diffuse,
    Mirror,
    Glossy(Roughness),
    /// Smooth transmission into the refracted direction.
    Transmit(Vec3),
    RoughTransmit(Roughness),
}

/// The sampling of a material at a shading point, for the direction
/// `given` the path arrived along (local, z > 0), as lobes and their
/// probabilities.
#[derive(Debug)]
pub struct Lobes {
    choice: DiscreteDistribution,
    /// As many lobes as `choice` has outcomes (a single lobe is repeated):
    /// an array rather than a list, so that a density is no spill check
    /// away from its lobe.
    kinds: [Kind; 2],
    given: Vec3,
    eta: f32,
    mode: Transport,
}

impl Lobes {
    /// The lobes of `material` for `given` (z > 0), where `eta` = η_other /
    /// η_given-side is the relative index across the surface, and `mode` says
    /// which end of the path `given` leads to.
    #[must_use]
    #[inline(always)]
    pub fn of(material: &Material, given: Vec3, eta: f32, mode: Transport) -> Lobes {
        let lobes = |choice, kinds| Lobes {
            choice,
            kinds,
            given,
            eta,
            mode,
        };
        let single = |kind| {
            lobes(
                DiscreteDistribution::new(&[1.0]).expect("one weight"),
                [kind; 2],
            )
        };
        let pair = |p: f64, a, b| {
            lobes(
                DiscreteDistribution::new(&[p, 1.0 - p]).expect("positive"),
                [a, b],
            )
        };
        match material {
            Material::Diffuse { .. } => single(Kind::Diffuse),
            Material::Conductor {
                roughness: None, ..
            } => single(Kind::Mirror),
            Material::Conductor {
                roughness: Some(r), ..
            } => single(Kind::Glossy(*r)),
            Material::Dielectric { roughness, .. } => {
                let f = f64::from(fresnel_dielectric(given.z, eta)).clamp(1e-3, 1.0 - 1e-3);
                match roughness {
                    None => match aether_core::refract(given, Vec3::Z, eta) {
                        Some(t) => pair(f, Kind::Mirror, Kind::Transmit(t)),
                        None => single(Kind::Mirror),
                    },
                    Some(r) => pair(f, Kind::Glossy(*r), Kind::RoughTransmit(*r)),
                }
            }
            Material::Plastic { roughness, .. } => {
                let f = f64::from(fresnel_dielectric(given.z, eta)).clamp(0.05, 0.95);
                let specular = match roughness {
                    None => Kind::Mirror,
                    Some(r) => Kind::Glossy(*r),
                };
                pair(f, specular, Kind::Diffuse)
            }
            Material::BumpMap { inner, .. } | Material::TwoSided(inner) => {
                Lobes::of(inner, given, eta, mode)
            }
        }
    }

    /// Lobe `i`, built for the direction the path arrived along (the
    /// mixture asks for i < 2 only).
    #[inline(always)]
    fn lobe(&self, i: usize) -> Lobe {
        let given = self.given;
        match self.kinds[i & 1] {
            Kind::Diffuse => diffuse(),
            Kind::Mirror => mirror(given),
            Kind::Glossy(r) => glossy(r, given),
            Kind::Transmit(t) => transmit(given, t, self.eta, self.mode),
            Kind::RoughTransmit(r) => Either::Right(Either::Right(Refract::new(
                given,
                self.eta,
                normals(r, given),
            ))),
        }
    }

    fn mixture(&self) -> impl Distribution<Value = Vec3> + '_ {
        Mixture::new(&self.choice, 2, move |i| self.lobe(i))
    }
}

/// The directions the lobes sample, with the mixture's density.
impl Distribution for Lobes {
    type Value = Vec3;
    fn dims(&self) -> usize {
        self.mixture().dims()
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<Vec3>> {
        self.mixture().sample(u)
    }
    // Inline with the mixture, which builds the lobe it evaluates: out of
    // line, a density's match over the lobes ran apart from the caller
    // that knew the material.
    #[inline(always)]
    fn density(&self, w: &Vec3) -> Density {
        self.mixture().density(w)
    }
    fn invert(&self, w: &Vec3) -> Option<Uniforms> {
        self.mixture().invert(w)
    }
    fn has_overlapping_branches(&self) -> bool {
        self.choice.len() > 1
    }
}
