//! Metropolis proposals as values the harness bins: a mutation's proposals
//! from a fixed path, as a distribution of paths whose density is the
//! transition density the language derives.

use aether_core::{
    ChainPath, Coords, Density, Distribution, Embed, Measure, Mutation, Pcg32, Sample, Uniforms,
    propose, transition_density,
};
use aether_strategies::bsdf::Bsdf;
use aether_strategies::mutations::Kind;
use aether_strategies::scene::{Material, Scene};
use aether_strategies::vertex::SceneVertex;
use integrators::mlt::MltSettings;
use integrators::mlt::veach::VeachMlt;

/// A proposal, as a value the harness bins.
#[derive(Clone, Debug)]
pub struct Proposal(pub ChainPath<SceneVertex>);

impl Embed for Proposal {
    fn embed(&self, coords: &mut Coords) -> usize {
        for v in self.0.vertices() {
            v.position.embed(coords);
        }
        2
    }
}

/// The proposals of `mutation` from `x`, with density T(y | x).
#[derive(Debug)]
pub struct Proposals<'a, M> {
    /// The mutation.
    pub mutation: &'a M,
    /// The path it mutates.
    pub x: &'a ChainPath<SceneVertex>,
}

impl<M: Mutation<SceneVertex>> Distribution for Proposals<'_, M> {
    type Value = Proposal;
    /// The uniforms seed the stream the mutation draws from, as many as
    /// its code asks for.
    fn dims(&self) -> usize {
        4
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<Proposal>> {
        let bits = |i: usize| u64::from(u[i].to_bits());
        let mut rng = Pcg32::new(bits(0) << 32 | bits(1), bits(2) << 32 | bits(3));
        let (y, _) = propose(self.mutation, self.x, &mut rng)?;
        // Only the histogram is checked: the density of a sample is not
        // read, beyond its being continuous.
        Some(Sample {
            value: Proposal(y),
            density: Density::new(1.0, Measure::Area),
        })
    }
    fn density(&self, y: &Proposal) -> Density {
        Density::new(
            transition_density(self.mutation, self.x, &y.0).value(),
            Measure::Area,
        )
    }
    fn invert(&self, _: &Proposal) -> Option<Uniforms> {
        None
    }
}

/// What a vertex between the camera and the light of a path lies on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum On {
    /// A diffuse surface.
    Diffuse,
    /// A smooth conductor.
    Mirror,
}

impl On {
    /// True if `v` lies on such a surface of `scene`.
    #[must_use]
    pub fn holds(self, scene: &Scene, v: &SceneVertex) -> bool {
        match Bsdf::at(scene, v).map(|b| b.material()) {
            Some(Material::Diffuse { .. }) => self == On::Diffuse,
            Some(Material::Conductor { .. }) => self == On::Mirror,
            _ => false,
        }
    }
}

/// The first path of `scene` (of those 4,000 BDPT samples find) that runs
/// camera, vertices on `middle` in order, light, and that the mutation
/// `kind` applies to.
///
/// # Panics
/// If there is none, or Veach's MLT cannot be set up for the scene.
#[must_use]
pub fn path_over(scene: &Scene, middle: &[On], kind: Kind) -> ChainPath<SceneVertex> {
    let mlt = VeachMlt::new(scene, &MltSettings::default()).unwrap();
    let mutations = mlt.mutations();
    (0..4_000)
        .flat_map(|i| mlt.seed_paths(&mut Pcg32::new(33, i)))
        .find(|p| {
            let v = p.vertices();
            v.len() == middle.len() + 2
                && middle.iter().zip(&v[1..]).all(|(on, v)| on.holds(scene, v))
                && mutations.weights(v)[kind as usize] > 0.0
        })
        .unwrap_or_else(|| panic!("no path camera, {middle:?}, light that {kind:?} applies to"))
}
