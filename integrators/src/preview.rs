//! A direct-lighting estimator that stands in until the integrators are
//! written in the sampling language: every material is treated as diffuse
//! (its constant albedo, or grey), area lights are sampled by area and
//! power, point lights directly. It exists so that `aether render` works
//! end to end; its images are not the scene's full light transport.

use aether_core::primitives::DiscreteDistribution;
use aether_core::{Pcg32, UniformSource};
use aether_strategies::geometry::{Hit, Primitive};
use aether_strategies::scene::{Emitter, Material, Scene, Texture};
use aether_strategies::spectrum::luminance;
use glam::Vec3;

enum Light {
    Triangle {
        mesh: usize,
        triangle: usize,
        radiance: Vec3,
    },
    Sphere {
        sphere: usize,
        radiance: Vec3,
    },
    Point {
        position: Vec3,
        intensity: Vec3,
    },
}

/// The stand-in estimator.
pub struct Preview<'s> {
    scene: &'s Scene,
    lights: Vec<Light>,
    choice: Option<DiscreteDistribution>,
}

impl std::fmt::Debug for Preview<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Preview")
            .field("lights", &self.lights.len())
            .finish()
    }
}

impl<'s> Preview<'s> {
    /// Prepares the lights of `scene`.
    #[must_use]
    pub fn new(scene: &'s Scene) -> Self {
        let mut lights = Vec::new();
        let mut weights = Vec::new();
        let meshes = scene.geometry.meshes().len();
        for e in &scene.emitters {
            match *e {
                Emitter::Area { radiance, shape } if shape < meshes => {
                    let mesh = &scene.geometry.meshes()[shape];
                    for t in 0..mesh.triangles.len() {
                        weights.push(mesh.triangle_area(t) * luminance(radiance));
                        lights.push(Light::Triangle {
                            mesh: shape,
                            triangle: t,
                            radiance: Vec3::from(radiance),
                        });
                    }
                }
                Emitter::Area { radiance, shape } => {
                    let s = scene.geometry.spheres()[shape - meshes];
                    weights.push(
                        4.0 * std::f64::consts::PI
                            * f64::from(s.radius).powi(2)
                            * luminance(radiance),
                    );
                    lights.push(Light::Sphere {
                        sphere: shape - meshes,
                        radiance: Vec3::from(radiance),
                    });
                }
                Emitter::Point {
                    position,
                    intensity,
                } => {
                    weights.push(4.0 * std::f64::consts::PI * luminance(intensity));
                    lights.push(Light::Point {
                        position,
                        intensity: Vec3::from(intensity),
                    });
                }
                _ => {}
            }
        }
        let choice = DiscreteDistribution::new(&weights).ok();
        Preview {
            scene,
            lights,
            choice,
        }
    }

    fn shape_of(&self, hit: &Hit) -> usize {
        match hit.primitive {
            Primitive::Triangle { mesh, .. } => mesh as usize,
            Primitive::Sphere(s) => self.scene.geometry.meshes().len() + s as usize,
        }
    }

    fn albedo(&self, shape: usize) -> Vec3 {
        let material = &self.scene.materials[self.scene.shapes[shape].material];
        let constant = |t: &Texture| {
            if let Texture::Constant(c) = t {
                Vec3::from(*c)
            } else {
                Vec3::splat(0.5)
            }
        };
        match material {
            Material::Diffuse { reflectance } => constant(reflectance),
            Material::Plastic {
                diffuse_reflectance,
                ..
            } => constant(diffuse_reflectance),
            _ => Vec3::splat(0.5),
        }
    }

    /// Radiance along the ray; `rays` counts the rays cast.
    pub fn radiance(&self, origin: Vec3, dir: Vec3, rng: &mut Pcg32, rays: &mut u64) -> [f32; 3] {
        *rays += 1;
        let Some(hit) = self.scene.geometry.intersect(origin, dir, f32::INFINITY) else {
            return [0.0; 3];
        };
        let shape = self.shape_of(&hit);
        let mut n = hit.geometric_normal;
        let mut l = Vec3::ZERO;
        if let Some(Emitter::Area { radiance, .. }) = self.scene.shapes[shape]
            .emitter
            .map(|e| &self.scene.emitters[e])
        {
            if n.dot(-dir) > 0.0 {
                l += Vec3::from(*radiance);
            }
        }
        if n.dot(dir) > 0.0 {
            n = -n;
        }
        let Some(choice) = &self.choice else {
            return l.to_array();
        };
        let (i, _) = choice.select(rng.next_f32());
        let p_choice = choice.probability(i);
        let (u, v) = (rng.next_f32(), rng.next_f32());
        let (point, normal, emitted, p_area) = match &self.lights[i] {
            Light::Triangle {
                mesh,
                triangle,
                radiance,
            } => {
                let m = &self.scene.geometry.meshes()[*mesh];
                let [a, b, c] = m.corners(*triangle);
                let su = u.sqrt();
                let p = (1.0 - su) * a + su * (1.0 - v) * b + su * v * c;
                (
                    p,
                    (b - a).cross(c - a).normalize(),
                    *radiance,
                    1.0 / m.triangle_area(*triangle),
                )
            }
            Light::Sphere { sphere, radiance } => {
                let s = self.scene.geometry.spheres()[*sphere];
                let z = 1.0 - 2.0 * u;
                let r = (1.0 - z * z).max(0.0).sqrt();
                let phi = std::f32::consts::TAU * v;
                let nrm = Vec3::new(r * phi.cos(), r * phi.sin(), z);
                (
                    s.center + s.radius * nrm,
                    nrm,
                    *radiance,
                    1.0 / (4.0 * std::f64::consts::PI * f64::from(s.radius).powi(2)),
                )
            }
            Light::Point {
                position,
                intensity,
            } => (*position, Vec3::ZERO, *intensity, 0.0),
        };
        let to_light = point - hit.position;
        let dist2 = to_light.length_squared();
        let wl = to_light / dist2.sqrt();
        let cos_x = n.dot(wl);
        if cos_x <= 0.0 {
            return l.to_array();
        }
        let geometry = if p_area == 0.0 {
            // A point light: intensity over squared distance.
            f64::from(cos_x) / f64::from(dist2) / p_choice
        } else {
            let cos_y = normal.dot(-wl);
            if cos_y <= 0.0 {
                return l.to_array();
            }
            f64::from(cos_x) * f64::from(cos_y) / f64::from(dist2) / (p_area * p_choice)
        };
        *rays += 1;
        let light_error = Vec3::splat(1e-5 * point.abs().max_element().max(1.0));
        if !self.scene.geometry.visible(
            (hit.position, hit.error, n),
            (
                point,
                light_error,
                if normal == Vec3::ZERO { -wl } else { normal },
            ),
        ) {
            return l.to_array();
        }
        let f = self.albedo(shape) / std::f32::consts::PI;
        (l + f * emitted * geometry as f32).to_array()
    }
}
