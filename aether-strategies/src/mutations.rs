//! Veach's path mutations (thesis, chapter 11) as sampling code: the
//! bidirectional mutation and the lens, caustic and multi-chain
//! perturbations. Each is written once over a [`Mutator`]; the language
//! derives T(y | x) from the same code ([`aether_core::transition_density`]),
//! and [`Mutations`] mixes them with a discrete choice, so its density is
//! the mixture's.
//!
//! "Specular" means every lobe at most as rough as a threshold (Beckmann or
//! GGX α), as in Aether: near-specular vertices are followed, not
//! connected, by the perturbations.

use aether_core::primitives::{ExponentialCone, ExponentialDisk};
use aether_core::{
    ChainPath, Distribution, Frame, InFrame, Intersect, Mutation, Mutator, Prefix, Step, Strategy,
};
use glam::Vec3;
use smallvec::SmallVec;

use crate::bsdf::Transport;
use crate::camera::{Camera, FilmDirection, PerturbedFilm};
use crate::lights::Lights;
use crate::scattering::{BsdfSampling, Roulette};
use crate::scene::Scene;
use crate::vertex::{SceneVertex, Site};

/// The mutations' mix and sizes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MutationSettings {
    /// Relative frequency of the bidirectional mutation (0 turns it off).
    pub bidirectional: f64,
    /// Relative frequency of the lens perturbation.
    pub lens: f64,
    /// Relative frequency of the caustic perturbation.
    pub caustic: f64,
    /// Relative frequency of the multi-chain perturbation.
    pub multi_chain: f64,
    /// Vertices at most this rough count as specular.
    pub roughness_threshold: f32,
    /// Smallest and largest lens perturbation, in pixels.
    pub lens_offsets: (f32, f32),
    /// Smallest and largest multi-chain direction perturbation, in radians.
    pub chain_angles: (f64, f64),
    /// Longest path, in vertices (camera and light included).
    pub max_vertices: usize,
}

impl MutationSettings {
    /// The smallest turn of a direction a perturbation makes, in radians:
    /// vertices are single precision, so a direction recovered from two of
    /// them is good to about 1e-7 rad, and the density of a turn of θ
    /// (∝ 1/θ²) to 2·1e-7/θ; at 1e-4 rad that is 0.2 %.
    pub const MIN_ANGLE: f64 = 1e-4;

    /// Veach's and Aether's defaults for a film of `width` × `height`
    /// pixels: all four mutations equally often, lens offsets from 0.1
    /// pixel to the radius of a disk covering 5 % of the film, multi-chain
    /// angles up to 0.1°, specular below roughness 0.02. The smallest
    /// angle is [`MIN_ANGLE`] rather than Veach's 1e-4°.
    ///
    /// [`MIN_ANGLE`]: MutationSettings::MIN_ANGLE
    #[must_use]
    pub fn new(width: u32, height: u32, max_vertices: usize) -> Self {
        let area = f64::from(width) * f64::from(height);
        let r_max = (0.05 * area / std::f64::consts::PI).sqrt().max(1.0) as f32;
        MutationSettings {
            bidirectional: 1.0,
            lens: 1.0,
            caustic: 1.0,
            multi_chain: 1.0,
            roughness_threshold: 0.02,
            lens_offsets: (0.1, r_max),
            chain_angles: (Self::MIN_ANGLE, 0.1f64.to_radians()),
            max_vertices,
        }
    }
}

/// A direction perturbed about `axis` by an [`ExponentialCone`] from the
/// last vertex, then a ray: the caustic and multi-chain perturbations.
#[derive(Clone, Copy, Debug)]
pub struct PerturbedDirection<'s> {
    scene: &'s Scene,
    axis: Vec3,
    cone: ExponentialCone,
}

impl<'s> PerturbedDirection<'s> {
    /// Directions about the unit vector `axis`, at angles of `cone`.
    #[must_use]
    pub fn new(scene: &'s Scene, axis: Vec3, cone: ExponentialCone) -> Self {
        PerturbedDirection { scene, axis, cone }
    }
}

impl Strategy<SceneVertex> for PerturbedDirection<'_> {
    fn distribution<'a>(
        &'a self,
        prefix: Prefix<'a, SceneVertex>,
    ) -> impl Distribution<Value = Step<SceneVertex>> + 'a {
        let x = prefix.last().expect("a vertex to leave from");
        Intersect::new(
            x,
            InFrame::new(Frame::from_normal(self.axis), self.cone),
            self.scene,
        )
    }
    fn memory(&self) -> usize {
        1
    }
}

/// Which shapes are specular: every lobe of their material at most as rough
/// as a threshold. Decided once per scene, since roughness is not textured.
#[derive(Clone, Debug)]
pub struct Specular {
    shapes: Vec<bool>,
}

impl Specular {
    /// The classification of `scene`'s shapes by `threshold`.
    #[must_use]
    pub fn of(scene: &Scene, threshold: f32) -> Self {
        Specular {
            shapes: scene
                .shapes
                .iter()
                .map(|s| !scene.materials[s.material].is_rougher_than(threshold))
                .collect(),
        }
    }

    /// True if `v` lies on a specular surface (lights, points and the lens
    /// are not specular).
    #[must_use]
    pub fn at(&self, v: &SceneVertex) -> bool {
        match v.site {
            Site::Surface { shape, .. } => {
                self.shapes.get(shape as usize).copied().unwrap_or(false)
            }
            _ => false,
        }
    }
}

/// 2^−|d|, the falloff of Veach's deletion and length choices.
fn falloff(d: i64) -> f64 {
    // The bits of 2^−k: exponent 1023 − k, no mantissa.
    f64::from_bits((1023 - d.unsigned_abs().min(1000)) << 52)
}

/// Veach's four mutations over a scene, chosen in proportion to their
/// frequencies among those that apply to the current path.
#[derive(Debug)]
pub struct Mutations<'a, 's> {
    scene: &'s Scene,
    camera: &'a Camera,
    lights: &'a Lights<'s>,
    specular: &'a Specular,
    settings: MutationSettings,
    eye_bsdf: BsdfSampling<'s>,
    light_bsdf: BsdfSampling<'s>,
}

/// Which mutation a proposal used.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// Delete a subpath and sample a new one from both ends.
    Bidirectional,
    /// Move the film point, follow the specular chain after it.
    Lens,
    /// Turn the direction that leaves the first diffuse vertex from the
    /// light toward the camera, follow the specular chain to the camera side.
    Caustic,
    /// A lens perturbation continued through every later specular chain.
    MultiChain,
}

impl Kind {
    /// Every kind, in the order of [`Mutations::weights`].
    pub const ALL: [Kind; 4] = [
        Kind::Bidirectional,
        Kind::Lens,
        Kind::Caustic,
        Kind::MultiChain,
    ];
}

impl<'a, 's> Mutations<'a, 's> {
    /// The mutations for paths of `scene` seen by `camera` and lit by
    /// `lights`, with its shapes classified by `specular` (made with
    /// `settings.roughness_threshold`).
    #[must_use]
    pub fn new(
        scene: &'s Scene,
        camera: &'a Camera,
        lights: &'a Lights<'s>,
        specular: &'a Specular,
        settings: MutationSettings,
    ) -> Self {
        Mutations {
            scene,
            camera,
            lights,
            specular,
            settings,
            eye_bsdf: BsdfSampling::new(scene, Transport::Radiance, Roulette::NEVER),
            light_bsdf: BsdfSampling::new(scene, Transport::Importance, Roulette::NEVER),
        }
    }

    /// The settings.
    #[must_use]
    pub fn settings(&self) -> &MutationSettings {
        &self.settings
    }

    /// True if `v` is at most as rough as the threshold.
    fn specular(&self, v: &SceneVertex) -> bool {
        self.specular.at(v)
    }

    /// The end of the specular chain that starts at vertex `from`: the first
    /// vertex at or after it that is not specular, or the path's last.
    fn chain_end(&self, v: &[SceneVertex], from: usize) -> usize {
        (from..v.len() - 1)
            .find(|&i| !self.specular(&v[i]))
            .unwrap_or(v.len() - 1)
    }

    /// True if `chain` (consecutive vertices) is specular but for its
    /// last, which is not unless `last_free` (the path's light vertex).
    fn keeps_chain(&self, chain: &[SceneVertex], last_free: bool) -> bool {
        let Some((last, inner)) = chain.split_last() else {
            return false;
        };
        inner.iter().all(|v| self.specular(v)) && (last_free || !self.specular(last))
    }

    /// The frequencies of the four mutations for the current path `x`
    /// (zero where one does not apply), in the order of [`Kind::ALL`].
    #[must_use]
    pub fn weights(&self, x: &[SceneVertex]) -> [f64; 4] {
        let s = &self.settings;
        let n = x.len();
        if n < 2 {
            return [0.0; 4];
        }
        let k = self.chain_end(x, 1);
        let caustic = n >= 4 && !self.specular(&x[1]) && self.chain_end(x, 2) >= 3;
        let junction = k + 2 < n && self.specular(&x[k + 1]);
        [
            s.bidirectional,
            s.lens,
            if caustic { s.caustic } else { 0.0 },
            if junction { s.multi_chain } else { 0.0 },
        ]
    }

    /// The strategy of a new eye-side vertex at path index `i`.
    fn eye_strategy<'m>(
        &'m self,
        i: usize,
        film: &'m FilmDirection<'a>,
        lens: &'m crate::camera::CameraPosition<'a>,
    ) -> &'m dyn aether_core::DynStrategy<SceneVertex> {
        match i {
            0 => lens,
            1 => film,
            _ => &self.eye_bsdf,
        }
    }

    /// Veach's bidirectional mutation: delete the kd − 1 vertices between a
    /// kept eye prefix and a kept light suffix (kd ∝ 2^−|kd−2|, the prefix
    /// length uniform), pick a new length l′ ∝ 2^−|l′−l| and split the
    /// vertices to add uniformly between the two sides. A single new light
    /// vertex is sampled by direct emitter sampling from the eye side.
    fn bidirectional(
        &self,
        x: &ChainPath<SceneVertex>,
        m: &mut Mutator<'_, SceneVertex>,
    ) -> Option<()> {
        let n = x.len();
        // A pinhole's vertex is a Dirac point: it is always kept.
        let lo = usize::from(!self.camera.has_lens());
        let deletions: SmallVec<[f64; 16]> =
            (1..=n + 1 - lo).map(|kd| falloff(kd as i64 - 2)).collect();
        let kd = 1 + m.choose(&deletions)?;
        // The kept eye prefix, uniform over lo ..= n + 1 − kd.
        let prefixes: SmallVec<[f64; 16]> = (0..=n + 1 - kd)
            .map(|e| if e >= lo { 1.0 } else { 0.0 })
            .collect();
        let eye = m.copy_eye_prefix(x, &prefixes)?;
        let light = n + 1 - kd - eye;
        m.copy_light(x, n - light..n)?;
        let kept = eye + light;
        // At least two vertices and the kept ones, and a new one if only
        // one edge was deleted (else the proposal would be the path itself).
        let allowed = |l: usize| l >= kept.max(2) && (kd > 1 || l > kept);
        let lengths: SmallVec<[f64; 40]> = (0..=self.settings.max_vertices)
            .map(|l| f64::from(u8::from(allowed(l))) * falloff(l as i64 - n as i64))
            .collect();
        let length = m.choose_length(&lengths)?;
        let added = length - kept;
        let on_eye = m.choose_uniform(added + 1)?;
        let on_light = added - on_eye;
        let film = FilmDirection::new(self.camera, self.scene);
        let lens = self.camera.position();
        for i in eye..eye + on_eye {
            m.eye(self.eye_strategy(i, &film, &lens))?;
        }
        if light == 0 && on_light == 1 {
            return m.eye(&self.lights.direct());
        }
        let (start, leave) = (self.lights.position(), self.lights.direction());
        for j in light..light + on_light {
            match j {
                0 => m.light(&start)?,
                1 => m.light(&leave)?,
                _ => m.light(&self.light_bsdf)?,
            }
        }
        Some(())
    }

    /// The lens perturbation: move the film point of the first edge by an
    /// [`ExponentialDisk`] offset, follow the specular chain from the first
    /// hit with BSDF sampling to its first non-specular vertex, and connect
    /// that to the rest of the path. Returns the index of that vertex.
    fn lens(&self, x: &ChainPath<SceneVertex>, m: &mut Mutator<'_, SceneVertex>) -> Option<usize> {
        let v = x.vertices();
        let n = v.len();
        let k = self.chain_end(v, 1);
        m.copy_eye(x, 0..1)?;
        let center = self.camera.raster(&v[0], v[0].direction_to(&v[1])?)?;
        let (r_min, r_max) = self.settings.lens_offsets;
        let look = PerturbedFilm::new(
            self.camera,
            self.scene,
            center,
            ExponentialDisk::new(r_min, r_max),
        );
        m.eye(&look)?;
        for _ in 2..=k {
            m.eye(&self.eye_bsdf)?;
        }
        let ok = self.keeps_chain(&m.eye_side()[1..=k], k == n - 1);
        m.require(ok)?;
        Some(k)
    }

    /// The caustic perturbation, for paths whose first hit x₁ is not
    /// specular and is lit through a specular chain x₂ … x_{k−1} from x_k:
    /// turn the direction x_k → x_{k−1} by an [`ExponentialCone`] angle
    /// scaled so that x₁ moves about as far as a lens perturbation would
    /// move it, follow the chain back to a new x₁, and connect that to the
    /// camera.
    fn caustic(&self, x: &ChainPath<SceneVertex>, m: &mut Mutator<'_, SceneVertex>) -> Option<()> {
        let v = x.vertices();
        let n = v.len();
        let k = self.chain_end(v, 2);
        m.require(n >= 4 && k >= 3 && !self.specular(&v[1]) && !v[k].is_at_infinity())?;
        let length =
            |a: &SceneVertex, b: &SceneVertex| f64::from((a.position - b.position).length());
        let chain: f64 = (1..k).map(|i| length(&v[i], &v[i + 1])).sum();
        // An angle at x_k moves x₁ by about angle · chain; a film offset of
        // r pixels moves it by r · pixel angle · |x₀x₁|.
        let scale = f64::from(self.camera.pixel_angle()) * length(&v[0], &v[1]) / chain;
        let (r_min, r_max) = self.settings.lens_offsets;
        let min = (f64::from(r_min) * scale).max(MutationSettings::MIN_ANGLE);
        let max = (f64::from(r_max) * scale).min(0.5);
        m.require(min > 0.0 && max > min && max.is_finite())?;
        let cone = ExponentialCone::new(min, max);
        m.copy_light(x, k..n)?;
        let turn = PerturbedDirection::new(self.scene, v[k].direction_to(&v[k - 1])?, cone);
        m.light(&turn)?;
        for _ in 1..k - 1 {
            m.light(&self.light_bsdf)?;
        }
        // The light side holds x_{n−1} … x_k, then the new y_{k−1} … y₁: y₁
        // is its vertex n − 2 from the light.
        let ok = !self.specular(m.light_vertex(n - 2))
            && (n - k..n - 2).all(|j| self.specular(m.light_vertex(j)));
        m.require(ok)?;
        m.copy_eye(x, 0..1)
    }

    /// The multi-chain perturbation: a lens perturbation, then at every
    /// non-specular vertex followed by a specular chain, a small turn of
    /// the direction into the chain, followed to the chain's end.
    fn multi_chain(
        &self,
        x: &ChainPath<SceneVertex>,
        m: &mut Mutator<'_, SceneVertex>,
    ) -> Option<()> {
        let v = x.vertices();
        let n = v.len();
        let mut k = self.lens(x, m)?;
        let (a, b) = self.settings.chain_angles;
        let cone = ExponentialCone::new(a, b);
        let mut junctions = 0;
        while k + 2 < n && self.specular(&v[k + 1]) {
            let turn = PerturbedDirection::new(self.scene, v[k].direction_to(&v[k + 1])?, cone);
            m.eye(&turn)?;
            let end = self.chain_end(v, k + 1);
            for _ in k + 2..=end {
                m.eye(&self.eye_bsdf)?;
            }
            let ok = self.keeps_chain(&m.eye_side()[k + 1..=end], end == n - 1);
            m.require(ok)?;
            k = end;
            junctions += 1;
        }
        m.require(junctions > 0)?;
        m.copy_light(x, k + 1..n)
    }
}

impl Mutations<'_, '_> {
    /// The mutation `kind` from `x`.
    fn run(
        &self,
        kind: Kind,
        x: &ChainPath<SceneVertex>,
        m: &mut Mutator<'_, SceneVertex>,
    ) -> Option<()> {
        match kind {
            Kind::Bidirectional => self.bidirectional(x, m),
            Kind::Lens => {
                let k = self.lens(x, m)?;
                m.copy_light(x, k + 1..x.len())
            }
            Kind::Caustic => self.caustic(x, m),
            Kind::MultiChain => self.multi_chain(x, m),
        }
    }
}

impl Mutation<SceneVertex> for Mutations<'_, '_> {
    fn propose(&self, x: &ChainPath<SceneVertex>, m: &mut Mutator<'_, SceneVertex>) -> Option<()> {
        let kind = Kind::ALL[m.choose(&self.weights(x.vertices()))?];
        self.run(kind, x, m)
    }
}

/// One of the mutations alone (for tests and for studying each): the
/// mixture restricted to `kind`.
#[derive(Debug)]
pub struct Only<'m, 'a, 's> {
    /// The mutations.
    pub mutations: &'m Mutations<'a, 's>,
    /// The one to run.
    pub kind: Kind,
}

impl Mutation<SceneVertex> for Only<'_, '_, '_> {
    fn propose(&self, x: &ChainPath<SceneVertex>, m: &mut Mutator<'_, SceneVertex>) -> Option<()> {
        self.mutations.run(self.kind, x, m)
    }
}

#[cfg(test)]
mod tests {
    use super::falloff;

    #[test]
    fn falloff_halves_per_step() {
        for d in -40i64..40 {
            assert_eq!(falloff(d), 0.5f64.powi(d.abs() as i32), "{d}");
        }
    }
}
