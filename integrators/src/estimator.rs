//! What the render loop asks of an integrator: one sample of a pixel, with
//! the contributions its light paths make to other pixels.

use aether_core::{RandomSequence, UniformSource};
use aether_strategies::scattering::Roulette;
use aether_strategies::scene::Scene;
use aether_strategies::vertex::SceneVertex;
use glam::{DVec3, Vec3};

/// Contributions of light paths to pixels of the film, in the units of a
/// pixel's camera-path estimate: the render loop divides their sum by the
/// total number of samples taken.
pub type Splats = Vec<([u32; 2], Vec3)>;

/// The uniforms an estimator draws from: a pixel's seeded stream in the
/// render loop, or a Markov chain's replayed primary samples.
pub type Rng<'a> = dyn UniformSource + 'a;

/// An integrator as the render loop sees it.
pub trait Estimator: Sync {
    /// One sample of pixel `pixel`: the estimate carried by its camera path,
    /// with light-path contributions to any pixel pushed onto `splats`.
    fn sample(&self, pixel: [u32; 2], rng: &mut Rng, splats: &mut Splats) -> Vec3;
}

/// The longest paths, in vertices (`usize::MAX` for none), and the Russian
/// roulette that the scene's integrator settings ask for: Mitsuba's
/// `maxDepth` counts edges and `rrDepth` the vertices sampled without
/// roulette after the camera or light vertex.
#[must_use]
pub fn path_limits(scene: &Scene) -> (usize, Roulette) {
    let settings = &scene.integrator;
    let max_vertices =
        usize::try_from(settings.max_depth).map_or(usize::MAX, |d| d.saturating_add(1));
    let roulette = Roulette {
        start: usize::try_from(settings.rr_depth)
            .unwrap_or(usize::MAX)
            .saturating_add(1),
        probability: 0.95,
    };
    (max_vertices, roulette)
}

/// f / p for a path with integrand value `f`, or nothing where the path's
/// density vanishes (a grazing vertex, whose contribution vanishes with it)
/// or the ratio is not finite.
#[must_use]
pub fn estimate(f: DVec3, path: &RandomSequence<'_, SceneVertex>) -> DVec3 {
    let p = path.pdf().value();
    let e = f / p;
    if p > 0.0 && e.is_finite() {
        e
    } else {
        DVec3::ZERO
    }
}
