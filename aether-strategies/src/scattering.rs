//! Scattering at a surface vertex as a strategy: the BSDF's lobes, chosen
//! and sampled in the language, then a ray, with Russian roulette.

use aether_core::{Distribution, Intersect, Prefix, RussianRoulette, Step, Strategy};

use crate::bsdf::{Bsdf, Transport};
use crate::scene::Scene;
use crate::vertex::SceneVertex;

/// Russian roulette: from the `start`-th vertex of a path on, a step goes
/// on with probability min(`probability`, albedo), the albedo being the
/// largest channel of the surface's reflectance ([`Bsdf::albedo`]). The
/// event is part of the density; it depends only on the vertex scattered
/// at, so densities stay memoryless and paths in dark scenes stay short.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Roulette {
    /// Vertices sampled without roulette (the camera or light vertex counts).
    pub start: usize,
    /// Largest probability of going on once roulette applies.
    pub probability: f64,
}

impl Roulette {
    /// No roulette: every step goes on.
    pub const NEVER: Roulette = Roulette {
        start: usize::MAX,
        probability: 1.0,
    };
}

/// BSDF sampling: at the last vertex, a lobe and a direction from the BSDF
/// given the direction the path arrived from, then a ray. `mode` says which
/// end of the path it grows from (it changes only how Dirac refraction is
/// recorded; see [`crate::bsdf::Lobes`]).
///
/// ```
/// # fn f(scene: &aether_strategies::scene::Scene) {
/// use aether_strategies::bsdf::Transport;
/// use aether_strategies::scattering::{BsdfSampling, Roulette};
/// let bounce = BsdfSampling::new(scene, Transport::Radiance, Roulette { start: 4, probability: 0.8 });
/// # }
/// ```
#[derive(Clone, Copy, Debug)]
pub struct BsdfSampling<'s> {
    scene: &'s Scene,
    mode: Transport,
    roulette: Roulette,
}

impl<'s> BsdfSampling<'s> {
    /// BSDF sampling over `scene` for paths grown in `mode`.
    #[must_use]
    pub fn new(scene: &'s Scene, mode: Transport, roulette: Roulette) -> Self {
        BsdfSampling {
            scene,
            mode,
            roulette,
        }
    }
}

impl Strategy<SceneVertex> for BsdfSampling<'_> {
    fn distribution<'a>(
        &'a self,
        prefix: Prefix<'a, SceneVertex>,
    ) -> impl Distribution<Value = Step<SceneVertex>> + 'a {
        let x = prefix.last().expect("a vertex to scatter at");
        let from = prefix.back(1).expect("a direction to scatter from");
        let bsdf = Bsdf::at(self.scene, x);
        let q = match &bsdf {
            Some(b) if prefix.len() >= self.roulette.start => {
                self.roulette.probability.min(f64::from(b.albedo()))
            }
            _ => 1.0,
        };
        let lobes = bsdf
            .zip(x.direction_to(from))
            .map(|(bsdf, given)| bsdf.sampling(given, self.mode));
        RussianRoulette::new(q, lobes.map(|d| Intersect::new(x, d, self.scene)))
    }
    fn memory(&self) -> usize {
        2
    }
    // Only roulette reads the depth, and only whether it has started.
    fn depth_class(&self, prefix_len: usize) -> usize {
        usize::from(prefix_len >= self.roulette.start)
    }
}
