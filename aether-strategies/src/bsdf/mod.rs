//! BSDFs at a shading point: their values, and their sampling written in
//! the language's blocks (so that their densities come from the language).
//!
//! Values follow the flow of light: [`Bsdf::eval`] takes the direction
//! towards the light end of the path and the one towards the camera end,
//! whichever end sampled them. It is the physical BSDF, including the
//! (η_o/η_i)² scaling of radiance at refraction and Veach's shading-normal
//! correction |ω_light·n_s| / |ω_light·n_g| (so that geometry terms use
//! geometric normals). Light paths therefore need no adjoint BSDF of their
//! own: the adjoint is this same function with its arguments read in the
//! other order, and [`Transport`] only changes how Dirac refraction masses
//! are recorded (see [`Lobes`]).

mod bump;
mod fresnel;
mod lobes;
mod microfacet;

use std::cell::Cell;
use std::f32::consts::PI;

use aether_core::primitives::DiracDirection;
use aether_core::{Distribution, Frame, InFrame, Recycle};
use glam::{Vec2, Vec3};

pub use fresnel::{fresnel_conductor, fresnel_dielectric, fresnel_diffuse_reflectance};
pub use lobes::Lobes;
pub use microfacet::{normal_density, shadowing, smith_g1};

use crate::scene::{Material, Roughness, Scene, Texture};
use crate::vertex::{SceneVertex, Site};

/// Which end of the path a sampled direction leads away from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Transport {
    /// Camera paths: the sampled direction leads towards the light.
    Radiance,
    /// Light paths: the sampled direction leads towards the camera.
    Importance,
}

/// The BSDF of a surface vertex: its material, shading frame (bump-mapped
/// where the material says so), geometric normal and texture coordinates.
///
/// ```
/// # use aether_strategies::bsdf::Bsdf;
/// # fn f(scene: &aether_strategies::scene::Scene, v: &aether_strategies::vertex::SceneVertex) {
/// let bsdf = Bsdf::at(scene, v).expect("a surface vertex");
/// let to_light = glam::Vec3::Z;
/// let to_camera = glam::Vec3::new(0.0, 0.6, 0.8);
/// let f = bsdf.eval(to_light, to_camera); // RGB, per steradian
/// # }
/// ```
#[derive(Clone, Copy, Debug)]
pub struct Bsdf<'s> {
    material: &'s Material,
    two_sided: bool,
    frame: Frame,
    geometric_normal: Vec3,
    uv: Vec2,
}

impl Recycle for Bsdf<'_> {
    type Static = Bsdf<'static>;
}

impl Material {
    /// True if its values at a point depend on the point's texture
    /// coordinates (a texture that varies, a bump map).
    #[must_use]
    pub fn reads_uv(&self) -> bool {
        match self {
            Material::Diffuse { reflectance } => reflectance.varies(),
            Material::Plastic {
                diffuse_reflectance,
                ..
            } => diffuse_reflectance.varies(),
            Material::Dielectric { .. } | Material::Conductor { .. } => false,
            Material::BumpMap { .. } => true,
            Material::TwoSided(inner) => inner.reads_uv(),
        }
    }

    /// True if every lobe is rougher than `threshold` (microfacet α along
    /// both axes), looking through two-sided and bump-map wrappers: see
    /// [`Bsdf::is_rougher_than`]. Roughness is not textured, so this holds
    /// for every point of a shape.
    #[must_use]
    pub fn is_rougher_than(&self, threshold: f32) -> bool {
        let rough =
            |r: &Option<Roughness>| r.is_some_and(|r| r.alpha[0].min(r.alpha[1]) > threshold);
        match self {
            Material::Conductor { roughness, .. }
            | Material::Dielectric { roughness, .. }
            | Material::Plastic { roughness, .. } => rough(roughness),
            Material::Diffuse { .. } => true,
            Material::BumpMap { inner, .. } | Material::TwoSided(inner) => {
                inner.is_rougher_than(threshold)
            }
        }
    }
}

impl<'s> Bsdf<'s> {
    /// The BSDF at `v`, or `None` if it is not on a surface.
    #[must_use]
    pub fn at(scene: &'s Scene, v: &SceneVertex) -> Option<Bsdf<'s>> {
        let Site::Surface { shape, .. } = v.site else {
            return None;
        };
        let material = &scene.materials[scene.shapes[shape as usize].material];
        if matches!(material, Material::TwoSided(_) | Material::BumpMap { .. })
            || anisotropic(material)
        {
            return Some(Self::wrapped(scene, v, material));
        }
        Some(Bsdf {
            material,
            two_sided: false,
            frame: Frame::from_normal(v.shading_normal),
            geometric_normal: v.geometric_normal,
            uv: v.uv,
        })
    }

    /// [`at`](Self::at) for a material under two-sided or bump-map
    /// wrappers, or an anisotropic one: out of line, so that the plain
    /// case (built at every vertex, and again for every density of BSDF
    /// sampling) compiles small.
    #[cold]
    #[inline(never)]
    fn wrapped(scene: &'s Scene, v: &SceneVertex, mut material: &'s Material) -> Bsdf<'s> {
        let mut two_sided = false;
        let mut normal = v.shading_normal;
        loop {
            match material {
                Material::TwoSided(inner) => {
                    two_sided = true;
                    material = inner;
                }
                Material::BumpMap { height, inner } => {
                    normal = bump::perturbed_normal(scene, v, normal, height);
                    material = inner;
                }
                _ => break,
            }
        }
        Bsdf {
            material,
            two_sided,
            // Only anisotropic lobes care where the tangent points.
            frame: if anisotropic(material) {
                shading_frame(scene, v, normal)
            } else {
                Frame::from_normal(normal)
            },
            geometric_normal: v.geometric_normal,
            uv: v.uv,
        }
    }

    /// The material (under any two-sided or bump-map wrappers).
    #[must_use]
    pub fn material(&self) -> &'s Material {
        self.material
    }

    /// The shading normal.
    #[must_use]
    pub fn shading_normal(&self) -> Vec3 {
        self.frame.n
    }

    /// True if every lobe is a Dirac lobe (smooth metal and glass), so that
    /// no connection can end here.
    #[must_use]
    pub fn is_dirac(&self) -> bool {
        matches!(
            self.material,
            Material::Conductor {
                roughness: None,
                ..
            } | Material::Dielectric {
                roughness: None,
                ..
            }
        )
    }

    /// True if every lobe is rougher than `threshold` (microfacet α along
    /// both axes), so that a path may reach or leave this vertex along any
    /// direction and keep a comparable value: where a gradient-domain shift
    /// may reconnect. Diffuse surfaces always are; smooth ones never.
    #[must_use]
    pub fn is_rougher_than(&self, threshold: f32) -> bool {
        self.material.is_rougher_than(threshold)
    }

    /// A rough measure of how much of the light arriving here the surface
    /// scatters: the largest channel of its reflectance (one for glass, at
    /// least the coat's share for plastic). Russian roulette goes on with at
    /// most this probability, so that dark surfaces end paths early; it
    /// depends on this vertex alone, so the roulette stays part of a
    /// memoryless density.
    #[must_use]
    pub fn albedo(&self) -> f32 {
        let max = |c: [f32; 3]| c[0].max(c[1]).max(c[2]);
        match self.material {
            Material::Diffuse { reflectance } => max(reflectance.eval(self.uv.to_array())),
            Material::Conductor {
                specular_reflectance,
                ..
            } => max(*specular_reflectance),
            Material::Plastic {
                diffuse_reflectance,
                specular_reflectance,
                ..
            } => max(diffuse_reflectance.eval(self.uv.to_array()))
                .max(0.1 * max(*specular_reflectance)),
            Material::Dielectric { .. } | Material::BumpMap { .. } | Material::TwoSided(_) => 1.0,
        }
    }

    /// f(ω_light → ω_camera) for unit world directions pointing away from
    /// the surface, with the shading-normal correction. Dirac lobes give
    /// their coefficient (per unit Dirac mass in the solid angle of
    /// `to_light`) when the pair matches within [`DiracDirection::TOLERANCE`].
    #[must_use]
    pub fn eval(&self, to_light: Vec3, to_camera: Vec3) -> Vec3 {
        let cos_geometric = to_light.dot(self.geometric_normal).abs();
        if cos_geometric == 0.0 {
            return Vec3::ZERO;
        }
        // The diffuse lobe reads only the cosines: the rest of the local
        // directions (four dot products) only for the other lobes, out of
        // line (inlined whole, the microfacet lobes made every evaluation
        // pay for their frame).
        let n = self.frame.n;
        let flip = |z: f32, wo_z: f32| if self.two_sided && wo_z < 0.0 { -z } else { z };
        let (zi, zo) = (to_light.dot(n), to_camera.dot(n));
        let (zi, zo) = (flip(zi, zo), flip(zo, zo));
        let f = match self.material {
            Material::Diffuse { reflectance } => diffuse(reflectance, self.uv, zi, zo),
            material => {
                let local =
                    |v: Vec3, z: f32| Vec3::new(v.dot(self.frame.s), v.dot(self.frame.t), z);
                eval_local(material, self.uv, local(to_light, zi), local(to_camera, zo))
            }
        };
        f * (zi.abs() / cos_geometric)
    }

    /// The distribution of the next direction for a path that arrived along
    /// `given` (a unit world direction pointing away from the surface).
    #[must_use]
    #[inline(always)]
    pub fn sampling(&self, given: Vec3, mode: Transport) -> InFrame<Lobes> {
        let mut frame = self.frame;
        let mut local = frame.to_local(given);
        let mut eta = match self.material {
            Material::Dielectric {
                int_ior, ext_ior, ..
            }
            | Material::Plastic {
                int_ior, ext_ior, ..
            } => int_ior / ext_ior,
            _ => 1.0,
        };
        if local.z < 0.0 {
            // Seen from behind: the mirrored frame keeps the lobes' +z
            // convention (and stays right-handed).
            frame = Frame {
                s: frame.s,
                t: -frame.t,
                n: -frame.n,
            };
            local = Vec3::new(local.x, -local.y, -local.z);
            if matches!(self.material, Material::Dielectric { .. }) {
                eta = 1.0 / eta;
            }
        }
        InFrame::new(frame, Lobes::of(self.material, local, eta, mode))
    }
}

/// The shading frame about `normal`, its first axis along ∂p/∂u where the
/// surface has texture coordinates (anisotropic roughness follows it, as in
/// Mitsuba), otherwise any.
fn shading_frame(scene: &Scene, v: &SceneVertex, normal: Vec3) -> Frame {
    let along_u = bump::tangents(scene, v)
        .and_then(|(dpdu, _)| (dpdu - normal * normal.dot(dpdu)).try_normalize());
    match along_u {
        Some(s) => Frame {
            s,
            t: normal.cross(s),
            n: normal,
        },
        None => Frame::from_normal(normal),
    }
}

fn anisotropic(material: &Material) -> bool {
    match material {
        Material::Dielectric { roughness, .. }
        | Material::Conductor { roughness, .. }
        | Material::Plastic { roughness, .. } => {
            roughness.is_some_and(|r| r.alpha[0] != r.alpha[1])
        }
        _ => false,
    }
}

fn rgb(c: [f32; 3]) -> Vec3 {
    Vec3::from_array(c)
}

fn is_mirror(wi: Vec3, wo: Vec3) -> bool {
    !DiracDirection::new(Vec3::new(-wi.x, -wi.y, wi.z), 1.0)
        .density(&wo)
        .is_zero()
}

/// The internal diffuse reflectance of a coat, memoised per thread: a scene
/// has few distinct indices, and the integral costs hundreds of Fresnel terms.
fn internal_diffuse_reflectance(eta: f32) -> f32 {
    thread_local! {
        static LAST: Cell<(u32, f32)> = const { Cell::new((u32::MAX, 0.0)) };
    }
    LAST.with(|last| {
        let (key, value) = last.get();
        if key == eta.to_bits() {
            return value;
        }
        let value = fresnel_diffuse_reflectance(1.0 / eta);
        last.set((eta.to_bits(), value));
        value
    })
}

/// The diffuse lobe's f(wi → wo) in the shading frame (zero unless both
/// leave the front side).
#[inline]
fn diffuse(reflectance: &Texture, uv: Vec2, cos_i: f32, cos_o: f32) -> Vec3 {
    if cos_i > 0.0 && cos_o > 0.0 {
        rgb(reflectance.eval(uv.to_array())) / PI
    } else {
        Vec3::ZERO
    }
}

/// The radiance BSDF f(wi → wo) in the shading frame: light arrives from
/// `wi` and leaves along `wo`.
#[inline(never)]
fn eval_local(material: &Material, uv: Vec2, wi: Vec3, wo: Vec3) -> Vec3 {
    let reflection = wi.z > 0.0 && wo.z > 0.0;
    match material {
        Material::Diffuse { reflectance } => diffuse(reflectance, uv, wi.z, wo.z),
        Material::Conductor {
            ior,
            specular_reflectance,
            roughness,
        } if reflection => {
            let fresnel = |c: f32| match ior {
                Some((eta, k)) => fresnel_conductor(c, rgb(*eta), rgb(*k)),
                None => Vec3::ONE,
            };
            let tint = rgb(*specular_reflectance);
            match roughness {
                None if is_mirror(wi, wo) => fresnel(wi.z) * tint / wi.z,
                None => Vec3::ZERO,
                Some(r) => {
                    let h = (wi + wo).normalize();
                    fresnel(wi.dot(h)) * tint * normal_density(*r, h) * shadowing(*r, wi, wo, h)
                        / (4.0 * wi.z * wo.z)
                }
            }
        }
        Material::Dielectric {
            int_ior,
            ext_ior,
            roughness,
        } => {
            if wi.z == 0.0 || wo.z == 0.0 {
                return Vec3::ZERO;
            }
            // Work from wi's side: eta is η(wo's medium on transmission) / η(wi's).
            let (wi, wo, eta) = if wi.z > 0.0 {
                (wi, wo, int_ior / ext_ior)
            } else {
                let flip = |w: Vec3| Vec3::new(w.x, w.y, -w.z);
                (flip(wi), flip(wo), ext_ior / int_ior)
            };
            Vec3::splat(dielectric(*roughness, wi, wo, eta))
        }
        Material::Plastic {
            diffuse_reflectance,
            specular_reflectance,
            int_ior,
            ext_ior,
            roughness,
        } if reflection => {
            let eta = int_ior / ext_ior;
            let (fi, fo) = (fresnel_dielectric(wi.z, eta), fresnel_dielectric(wo.z, eta));
            let specular = match roughness {
                // On the mirror direction the Dirac lobe is all there is (the
                // diffuse part has measure zero there, and adding it would
                // count it once per specular sample).
                None if is_mirror(wi, wo) => return rgb(*specular_reflectance) * (fi / wi.z),
                None => 0.0,
                Some(r) => {
                    let h = (wi + wo).normalize();
                    fresnel_dielectric(wi.dot(h), eta)
                        * normal_density(*r, h)
                        * shadowing(*r, wi, wo, h)
                        / (4.0 * wi.z * wo.z)
                }
            };
            // Mitsuba's coat: light refracts in, scatters diffusely with
            // internal reflections summed as a geometric series, refracts out.
            let base = rgb(diffuse_reflectance.eval(uv.to_array()))
                / (1.0 - internal_diffuse_reflectance(eta));
            rgb(*specular_reflectance) * specular
                + base * ((1.0 - fi) * (1.0 - fo) / (eta * eta * PI))
        }
        Material::TwoSided(inner) | Material::BumpMap { inner, .. } => {
            eval_local(inner, uv, wi, wo)
        }
        _ => Vec3::ZERO,
    }
}

/// A dielectric interface seen from wi's side (wi.z > 0), `eta` the
/// relative index of the other side.
fn dielectric(roughness: Option<crate::scene::Roughness>, wi: Vec3, wo: Vec3, eta: f32) -> f32 {
    match roughness {
        None if wo.z > 0.0 => {
            if is_mirror(wi, wo) {
                fresnel_dielectric(wi.z, eta) / wi.z
            } else {
                0.0
            }
        }
        None => match aether_core::refract(wi, Vec3::Z, eta) {
            Some(t) if !DiracDirection::new(t, 1.0).density(&wo).is_zero() => {
                (1.0 - fresnel_dielectric(wi.z, eta)) * eta * eta / wi.z
            }
            _ => 0.0,
        },
        Some(r) if wo.z > 0.0 => {
            let h = (wi + wo).normalize();
            fresnel_dielectric(wi.dot(h), eta) * normal_density(r, h) * shadowing(r, wi, wo, h)
                / (4.0 * wi.z * wo.z)
        }
        Some(r) => {
            // Walter et al. 2007: the generalised half vector of refraction.
            let mut h = -(wi + eta * wo).normalize();
            if h.z < 0.0 {
                h = -h;
            }
            let (ci, co) = (wi.dot(h), wo.dot(h));
            if ci <= 0.0 || co >= 0.0 {
                return 0.0;
            }
            let denom = ci + eta * co;
            (ci * co).abs() / (wi.z * wo.z).abs()
                * eta
                * eta
                * (1.0 - fresnel_dielectric(ci, eta))
                * normal_density(r, h)
                * shadowing(r, wi, wo, h)
                / (denom * denom)
        }
    }
}
