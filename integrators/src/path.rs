//! Path tracing in the sampling language: BSDF sampling with Russian
//! roulette, direct light sampling at every vertex, and MIS between the two
//! ways each light vertex could have been sampled.

use aether_core::{
    DynStrategy, Heuristic, RandomSequence, Split, StrategyRef, weight_of_last_step,
};
use aether_strategies::bsdf::Transport;
use aether_strategies::camera::Camera;
use aether_strategies::integrand::Integrand;
use aether_strategies::lights::Lights;
use aether_strategies::scattering::{BsdfSampling, Roulette};
use aether_strategies::scene::Scene;
use aether_strategies::subpath::{End, Subpath};
use aether_strategies::vertex::SceneVertex;
use glam::{DVec3, Vec3};

use crate::estimator::{Estimator, Rng, Splats, path_limits};

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
}

impl Estimator for PathTracer<'_> {
    fn sample(&self, pixel: [u32; 2], rng: &mut Rng, _splats: &mut Splats) -> Vec3 {
        let Some(lights) = &self.lights else {
            return Vec3::ZERO;
        };
        let lens = self.camera.position();
        let look = self.camera.direction(self.scene, pixel);
        let bsdf = BsdfSampling::new(self.scene, Transport::Radiance, self.roulette);
        let direct = lights.direct();
        let f = Integrand::new(self.scene, &self.camera, lights);
        let camera = [&lens as &dyn DynStrategy<_>, &look, &bsdf].map(StrategyRef::One);
        let mut path = RandomSequence::new();
        if !path.append(&lens).append_sample(&look, rng) {
            return Vec3::ZERO;
        }
        let importance = f.importance(pixel, path.vertices());
        // Built in place: `Subpath::of` returns about 2.5 KB, copied once per
        // sample (1 % of this tracer's instructions).
        let mut eye = Subpath::new(f, End::Camera);
        eye.extend(path.vertices());
        let mut radiance = DVec3::ZERO;
        loop {
            let n = path.len();
            // Emission reached by the last step (direct sampling cannot see
            // what the camera sees first).
            let emitted = eye.emitted(n);
            if emitted != DVec3::ZERO {
                radiance +=
                    emitted * importance * weight(&path, &camera, &direct, 0, self.heuristic);
            }
            if n > self.max_depth {
                break;
            }
            // A light sample beside the path (a specular vertex sees no light
            // by sampling it), weighed by the step the path goes on with.
            // Read in place: each copy of a light sample moved 96 bytes.
            let lamp = match eye.connectible(n - 1) {
                true => path.sample_aside(&direct, rng),
                false => None,
            };
            let lit = lamp
                .as_ref()
                .map_or(DVec3::ZERO, |l| eye.connect_lamp(n, &l.vertex));
            let lamp = lamp.as_ref().filter(|_| lit != DVec3::ZERO);
            let (next, w) = path.append_sample_beside(&bsdf, rng, lamp, self.heuristic);
            radiance += lit * importance * w;
            if !next {
                break;
            }
            eye.push(path.vertices()[n]);
        }
        radiance.as_vec3()
    }
}

/// The MIS weight of `path` as made by technique `own` of the two a path
/// tracer has for its last vertex (0, the camera-side strategy that sampled
/// the vertices before it; 1, direct light sampling), over its density:
/// zero where the density vanishes (a grazing vertex, whose contribution
/// vanishes with it).
pub(crate) fn weight(
    path: &RandomSequence<'_, SceneVertex>,
    camera: &[StrategyRef<'_, SceneVertex>],
    direct: &dyn DynStrategy<SceneVertex>,
    own: usize,
    heuristic: Heuristic,
) -> f64 {
    let n = path.len();
    let Some(&by_camera) = camera.get((n.max(1) - 1).min(camera.len().saturating_sub(1))) else {
        return 0.0;
    };
    let alternatives = [by_camera, StrategyRef::One(direct)];
    let (w, p) = weight_of_last_step(path, &alternatives[..technique_count(n)], own, heuristic);
    p.weight_over(w)
}

/// How many techniques a path tracer has for paths of `n` vertices: two,
/// but one for what the camera sees first, which direct sampling cannot
/// see through the lens.
fn technique_count(n: usize) -> usize {
    if n == 2 { 1 } else { 2 }
}

/// A path tracer's techniques for paths of `n` vertices: BSDF sampling
/// throughout (index 0), and direct light sampling (`by_light`) for the
/// last vertex (index 1), except for what the camera sees first, which
/// direct sampling cannot see through the lens. An array and its length
/// rather than a collected list: collecting two techniques and returning
/// them cost a path tracer 3 % of its instructions in copies.
pub(crate) fn techniques<'s>(
    n: usize,
    by_light: &[(StrategyRef<'s, SceneVertex>, bool)],
) -> ([Split<'s, SceneVertex>; 2], usize) {
    let count = technique_count(n);
    ([Split::new(n, &[]), Split::new(n - 1, by_light)], count)
}
