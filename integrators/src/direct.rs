//! Direct lighting: at the first surface the camera sees, one light sample
//! and one BSDF sample, each weighed by MIS against the other.

use aether_core::{DynStrategy, Heuristic, RandomSequence, StrategyRef};
use aether_strategies::bsdf::Transport;
use aether_strategies::camera::Camera;
use aether_strategies::integrand::Integrand;
use aether_strategies::lights::Lights;
use aether_strategies::scattering::{BsdfSampling, Roulette};
use aether_strategies::scene::Scene;
use aether_strategies::subpath::{End, Subpath};
use glam::{DVec3, Vec3};

use crate::estimator::{Estimator, Rng, Splats};
use crate::path::weight;

/// Direct lighting with MIS between light and BSDF sampling (paths of at
/// most two edges: lights seen directly and lights reflected once).
///
/// ```no_run
/// # fn f(scene: &aether_strategies::scene::Scene) -> Result<(), String> {
/// use integrators::estimator::Estimator;
/// let direct = integrators::direct::DirectLighting::new(scene)?;
/// let radiance = direct.sample([3, 4], &mut aether_core::Pcg32::new(0, 0), &mut Vec::new());
/// # Ok(()) }
/// ```
#[derive(Debug)]
pub struct DirectLighting<'s> {
    scene: &'s Scene,
    camera: Camera,
    lights: Option<Lights<'s>>,
    heuristic: Heuristic,
}

impl<'s> DirectLighting<'s> {
    /// Direct lighting of `scene`, with the power heuristic.
    ///
    /// # Errors
    /// If the camera cannot be built (an unknown pixel filter).
    pub fn new(scene: &'s Scene) -> Result<Self, String> {
        Ok(DirectLighting {
            scene,
            camera: Camera::new(scene)?,
            lights: Lights::new(scene),
            heuristic: Heuristic::POWER,
        })
    }
}

impl Estimator for DirectLighting<'_> {
    fn sample(&self, pixel: [u32; 2], rng: &mut Rng, _splats: &mut Splats) -> Vec3 {
        let Some(lights) = &self.lights else {
            return Vec3::ZERO;
        };
        let lens = self.camera.position();
        let look = self.camera.direction(self.scene, pixel);
        let bsdf = BsdfSampling::new(self.scene, Transport::Radiance, Roulette::NEVER);
        let (direct, h) = (lights.direct(), self.heuristic);
        let f = Integrand::new(self.scene, &self.camera, lights);
        let camera = [&lens as &dyn DynStrategy<_>, &look, &bsdf].map(StrategyRef::One);
        let mut path = RandomSequence::new();
        if !path.append(&lens).append_sample(&look, rng) {
            return Vec3::ZERO;
        }
        let eye = Subpath::of(f, End::Camera, path.vertices());
        let importance = f.importance(pixel, path.vertices());
        // What the camera sees first has one technique.
        let mut radiance = eye.emitted(2) * weight(&path, &camera, &direct, 0, h);
        let lamp = eye.connectible(1).then(|| path.sample_aside(&direct, rng));
        let lit = lamp
            .flatten()
            .map_or(DVec3::ZERO, |l| eye.connect_lamp(2, &l.vertex));
        let lamp = lamp.flatten().filter(|_| lit != DVec3::ZERO);
        // The BSDF sample weighs the light sample.
        let (sampled, w) = path.append_sample_beside(&bsdf, rng, lamp.as_ref(), h);
        radiance += lit * w;
        if sampled {
            let emitted = Subpath::of(f, End::Camera, path.vertices()).emitted(3);
            radiance += emitted * weight(&path, &camera, &direct, 0, h);
        }
        (radiance * importance).as_vec3()
    }
}
