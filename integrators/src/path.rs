//! Path tracing in the sampling language: BSDF sampling with Russian
//! roulette, direct light sampling at every vertex, and MIS between the two
//! ways each light vertex could have been sampled.

use aether_core::{
    DynStrategy, Heuristic, Pcg32, RandomSequence, Split, StepKind, StrategyRef, weight_of_split,
};
use aether_strategies::bsdf::Transport;
use aether_strategies::camera::Camera;
use aether_strategies::integrand::Integrand;
use aether_strategies::lights::Lights;
use aether_strategies::scattering::{BsdfSampling, Roulette};
use aether_strategies::scene::Scene;
use aether_strategies::vertex::SceneVertex;
use glam::{DVec3, Vec3};

use crate::estimator::{Estimator, Splats, estimate, path_limits};

/// A unidirectional path tracer with next-event estimation.
#[derive(Debug)]
pub struct PathTracer<'s> {
    scene: &'s Scene,
    camera: Camera,
    lights: Option<Lights<'s>>,
    max_depth: usize,
    roulette: Roulette,
    heuristic: Heuristic,
}

impl<'s> PathTracer<'s> {
    /// The path tracer of `scene`, with its integrator's maximum depth (in
    /// edges; −1 for none) and Russian-roulette depth, and the power heuristic.
    ///
    /// # Errors
    /// If the camera cannot be built (an unknown pixel filter).
    pub fn new(scene: &'s Scene) -> Result<Self, String> {
        let (max_vertices, roulette) = path_limits(scene);
        Ok(PathTracer {
            scene,
            camera: Camera::new(scene)?,
            lights: Lights::new(scene),
            max_depth: max_vertices.saturating_sub(1),
            roulette,
            heuristic: Heuristic::POWER,
        })
    }

    /// Direct lighting: the same tracer stopped after the first bounce
    /// (light sampling and BSDF sampling at the first hit, weighed by MIS).
    ///
    /// # Errors
    /// As [`PathTracer::new`].
    pub fn direct(scene: &'s Scene) -> Result<Self, String> {
        Ok(PathTracer {
            max_depth: 2,
            ..PathTracer::new(scene)?
        })
    }
}

impl Estimator for PathTracer<'_> {
    fn sample(&self, pixel: [u32; 2], rng: &mut Pcg32, _splats: &mut Splats) -> Vec3 {
        let Some(lights) = &self.lights else {
            return Vec3::ZERO;
        };
        let (lens, look) = (
            self.camera.position(),
            self.camera.direction(self.scene, pixel),
        );
        let bsdf = BsdfSampling::new(self.scene, Transport::Radiance, self.roulette);
        let direct = lights.direct();
        let f = Integrand::new(self.scene, &self.camera, lights);
        let camera = [&lens as &dyn DynStrategy<_>, &look, &bsdf].map(StrategyRef::One);
        let mut path = RandomSequence::new();
        path.append(&lens).append(&look);
        if path.sample(rng) != StepKind::Vertex {
            return Vec3::ZERO;
        }
        let mut radiance = Vec3::ZERO;
        loop {
            let k = path.len() - 1;
            // Emission reached by the last step (direct sampling cannot see
            // what the camera sees first).
            let emitted = f.evaluate(pixel, path.vertices(), &[]);
            if emitted != DVec3::ZERO {
                let w = if k == 1 {
                    1.0
                } else {
                    weight(&path, &camera, &direct, 0, self.heuristic)
                };
                radiance += estimate(emitted * w, &path).as_vec3();
            }
            if k >= self.max_depth {
                break;
            }
            let mut to_light = path.clone();
            to_light.append(&direct);
            if to_light.sample(rng) == StepKind::Vertex {
                let lit = f.evaluate(pixel, to_light.vertices(), &[k]);
                if lit != DVec3::ZERO {
                    let w = weight(&to_light, &camera, &direct, 1, self.heuristic);
                    radiance += estimate(lit * w, &to_light).as_vec3();
                }
            }
            path.append(&bsdf);
            if path.sample(rng) != StepKind::Vertex {
                break;
            }
        }
        radiance
    }
}

/// The MIS weight of `path` as made by technique `own` of the two a path
/// tracer has for its last vertex: 0, BSDF sampling like the vertices
/// before it; 1, direct light sampling.
fn weight(
    path: &RandomSequence<'_, SceneVertex>,
    camera: &[StrategyRef<'_, SceneVertex>],
    direct: &dyn DynStrategy<SceneVertex>,
    own: usize,
    heuristic: Heuristic,
) -> f64 {
    let n = path.len();
    let by_light = [(StrategyRef::One(direct), false)];
    let splits = [Split::new(n, &[]), Split::new(n - 1, &by_light)];
    weight_of_split(path, camera, &[], &splits, own, heuristic).0
}
