//! Light tracing: paths from the lights, each vertex connected to the
//! camera and splatted where it lands on the film.

use aether_core::RandomSequence;
use aether_strategies::bsdf::Transport;
use aether_strategies::camera::Camera;
use aether_strategies::integrand::Integrand;
use aether_strategies::lights::Lights;
use aether_strategies::scattering::{BsdfSampling, Roulette};
use aether_strategies::scene::Scene;
use aether_strategies::subpath::{End, Subpath};
use glam::{DVec3, Vec3};

use crate::estimator::{Estimator, Rng, Splats, estimate, path_limits};

/// A light tracer. Lights seen directly are the one kind of path a light
/// path cannot reach through a pinhole, so the camera ray of each sample
/// finds them; every longer path comes from the light, and each path has one
/// technique, so no MIS is needed.
///
/// ```no_run
/// # fn f(scene: &aether_strategies::scene::Scene) -> Result<(), String> {
/// use integrators::estimator::Estimator;
/// let tracer = integrators::light::LightTracer::new(scene)?;
/// let mut splats = Vec::new();
/// let seen = tracer.sample([3, 4], &mut aether_core::Pcg32::new(0, 0), &mut splats);
/// # Ok(()) }
/// ```
#[derive(Debug)]
pub struct LightTracer<'s> {
    scene: &'s Scene,
    camera: Camera,
    lights: Option<Lights<'s>>,
    max_vertices: usize,
    roulette: Roulette,
}

impl<'s> LightTracer<'s> {
    /// The light tracer of `scene`, with its integrator's maximum depth and
    /// Russian-roulette depth.
    ///
    /// # Errors
    /// If the camera cannot be built (an unknown pixel filter).
    pub fn new(scene: &'s Scene) -> Result<Self, String> {
        let (max_vertices, roulette) = path_limits(scene);
        Ok(LightTracer {
            scene,
            camera: Camera::new(scene)?,
            lights: Lights::new(scene),
            max_vertices,
            roulette,
        })
    }
}

impl Estimator for LightTracer<'_> {
    fn sample(&self, pixel: [u32; 2], rng: &mut Rng, splats: &mut Splats) -> Vec3 {
        let Some(lights) = self.lights.as_ref().filter(|_| self.max_vertices >= 2) else {
            return Vec3::ZERO;
        };
        let f = Integrand::new(self.scene, &self.camera, lights);
        let (emit, leave) = (lights.position(), lights.direction());
        let gather = BsdfSampling::new(self.scene, Transport::Importance, self.roulette);
        let (position, look) = (
            self.camera.position(),
            self.camera.direction(self.scene, pixel),
        );
        let mut eye = RandomSequence::new();
        eye.append(&position).append(&look).sample(rng);
        let seen = estimate(f.evaluate(pixel, eye.vertices(), &[]), &eye);
        let mut light = RandomSequence::new();
        light.append(&emit).append(&leave).sample(rng);
        let mut lens = Subpath::new(f, End::Camera);
        lens.extend(&eye.vertices()[..eye.len().min(1)]);
        let mut lamp = Subpath::new(f, End::Light);
        let mut path = RandomSequence::new();
        while light.is_complete() && light.len() < self.max_vertices && !eye.is_empty() {
            let t = light.len();
            lamp.extend(&light.vertices()[lamp.len()..]);
            let through = match lamp.bsdf(t - 1) {
                Some(b) if !b.is_dirac() => lens.connect(1, &lamp, t),
                _ => DVec3::ZERO,
            };
            if through != DVec3::ZERO {
                path.clear();
                path.extend_from(&eye, 0..1, false)
                    .extend_from(&light, 0..t, true);
                let (v, through) = (path.vertices(), estimate(through, &path));
                let d = v[0].direction_to(&v[1]).unwrap_or(Vec3::Z);
                for j in self.camera.pixels_toward(&v[0], d) {
                    let w = through * self.camera.importance(j, &v[0], d);
                    splats.push((j, w.as_vec3()));
                }
            }
            light.append(&gather).sample(rng);
        }
        seen.as_vec3()
    }
}
