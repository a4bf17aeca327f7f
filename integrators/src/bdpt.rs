//! Bidirectional path tracing over every (s, t), and tridirectional path
//! tracing (Anderson et al. 2017).
//!
//! A path of s + t vertices joins the first s vertices of a camera subpath
//! to the first t vertices of a light subpath, read backwards: t = 0 is a
//! camera path that found a light, t = 1 samples a point on a light from the
//! camera subpath's last vertex, and s = 1 connects the light subpath to the
//! camera, splatted to the pixels whose filter covers it. Tridirectional
//! tracing adds, for every length, the paths that splice one portal segment
//! between a camera prefix and a light prefix. Every path is weighed by MIS
//! against every technique that could have produced it, each technique being
//! no more than a list of strategies ([`aether_core::weight_of`]).

use aether_core::{DynStrategy, Heuristic, Pcg32, RandomSequence, StrategyRef, weight_of_split};
use aether_strategies::bsdf::{Bsdf, Transport};
use aether_strategies::camera::{Camera, CameraDirection, CameraPosition};
use aether_strategies::integrand::Integrand;
use aether_strategies::lights::{DirectEmitter, EmitterDirection, EmitterPosition, Lights};
use aether_strategies::portal::PortalSegment;
use aether_strategies::scattering::{BsdfSampling, Roulette};
use aether_strategies::scene::Scene;
use aether_strategies::vertex::SceneVertex;
use glam::{DVec3, Vec3};
use smallvec::SmallVec;

use crate::estimator::{Estimator, Splats, path_limits};
use crate::techniques::TechniqueImages;

type Path<'a> = RandomSequence<'a, SceneVertex>;

/// Where a technique splits a path: `Bdpt(s)` samples the first s vertices
/// from the camera and the rest from the light; `Portal(k)` samples the
/// first k from the camera, the next two as a portal segment, the rest from
/// the light.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Split {
    Bdpt(usize),
    Portal(usize),
}

/// Bidirectional (and, with a portal, tridirectional) path tracing.
///
/// ```no_run
/// # fn f(scene: &aether_strategies::scene::Scene) -> Result<(), String> {
/// use aether_core::Pcg32;
/// use integrators::bdpt::Bdpt;
/// use integrators::estimator::Estimator;
/// let bdpt = Bdpt::new(scene)?;
/// let mut splats = Vec::new();
/// let radiance = bdpt.sample([10, 20], &mut Pcg32::new(1, 0), &mut splats);
/// # Ok(()) }
/// ```
#[derive(Debug)]
pub struct Bdpt<'s> {
    scene: &'s Scene,
    camera: Camera,
    lights: Option<Lights<'s>>,
    portal: Option<PortalSegment<'s>>,
    max_vertices: usize,
    roulette: Roulette,
    heuristic: Heuristic,
    images: Option<TechniqueImages>,
}

/// The strategies of one sample.
struct Kit<'a, 's> {
    lens: CameraPosition<'a>,
    look: CameraDirection<'a>,
    scatter: BsdfSampling<'s>,
    emit: EmitterPosition<'a, 's>,
    leave: EmitterDirection<'a, 's>,
    gather: BsdfSampling<'s>,
    direct: DirectEmitter<'a, 's>,
}

impl<'s> Bdpt<'s> {
    /// BDPT for `scene`, with its integrator's maximum depth and Russian
    /// roulette depth, and the power heuristic.
    ///
    /// # Errors
    /// If the camera cannot be built (an unknown pixel filter).
    pub fn new(scene: &'s Scene) -> Result<Self, String> {
        let (max_vertices, roulette) = path_limits(scene);
        Ok(Bdpt {
            scene,
            camera: Camera::new(scene)?,
            lights: Lights::new(scene),
            portal: None,
            max_vertices,
            roulette,
            heuristic: Heuristic::POWER,
            images: None,
        })
    }

    /// Tridirectional path tracing: BDPT plus the segments through the
    /// scene's first portal.
    ///
    /// # Errors
    /// If the scene declares no portal, or it is not planar.
    pub fn tridirectional(scene: &'s Scene) -> Result<Self, String> {
        if scene.portals.is_empty() {
            return Err("tridirectional path tracing needs a portal: a shape with <boolean name=\"portal\" value=\"true\"/>".into());
        }
        Ok(Bdpt {
            portal: Some(PortalSegment::new(scene, 0)?),
            ..Bdpt::new(scene)?
        })
    }

    /// Tridirectional tracing if the scene's integrator is `tridir`, BDPT otherwise.
    ///
    /// # Errors
    /// As [`Bdpt::new`] and [`Bdpt::tridirectional`].
    pub fn for_scene(scene: &'s Scene) -> Result<Self, String> {
        if scene.integrator.name == "tridir" {
            Bdpt::tridirectional(scene)
        } else {
            Bdpt::new(scene)
        }
    }

    /// Also records, for paths of up to `max_vertices` vertices, each (s, t)
    /// technique's contribution, weighted and unweighted.
    #[must_use]
    pub fn with_technique_images(self, max_vertices: usize) -> Self {
        let [w, h] = self.camera.size();
        Bdpt {
            images: Some(TechniqueImages::new(w, h, max_vertices)),
            ..self
        }
    }

    /// The (s, t) images, if asked for.
    #[must_use]
    pub fn technique_images(&self) -> Option<&TechniqueImages> {
        self.images.as_ref()
    }

    fn kit<'a>(&'a self, lights: &'a Lights<'s>, pixel: [u32; 2]) -> Kit<'a, 's> {
        let scene = self.scene;
        Kit {
            lens: self.camera.position(),
            look: self.camera.direction(scene, pixel),
            scatter: BsdfSampling::new(scene, Transport::Radiance, self.roulette),
            emit: lights.position(),
            leave: lights.direction(),
            gather: BsdfSampling::new(scene, Transport::Importance, self.roulette),
            direct: lights.direct(),
        }
    }

    /// True if a connection can end at `v`: not on a purely specular surface.
    fn connectible(&self, v: &SceneVertex) -> bool {
        Bsdf::at(self.scene, v).is_none_or(|b| !b.is_dirac())
    }
}

fn one<'a>(s: &'a dyn DynStrategy<SceneVertex>) -> StrategyRef<'a, SceneVertex> {
    StrategyRef::One(s)
}

/// Samples `first`, then `next` until a step fails or the path has `max` vertices.
fn walk<'a>(
    first: [&'a dyn DynStrategy<SceneVertex>; 2],
    next: &'a dyn DynStrategy<SceneVertex>,
    max: usize,
    rng: &mut Pcg32,
) -> Path<'a> {
    let mut path = RandomSequence::new();
    path.append(first[0]).append(first[1]).sample(rng);
    while path.is_complete() && path.len() < max {
        path.append(next).sample(rng);
    }
    path
}

/// `prefix` followed by a vertex sampled on a light from its last vertex.
fn directly<'a>(prefix: Path<'a>, direct: &'a DirectEmitter<'_, '_>, rng: &mut Pcg32) -> Path<'a> {
    let mut p = prefix;
    p.append(direct).sample(rng);
    p
}

impl Estimator for Bdpt<'_> {
    fn sample(&self, pixel: [u32; 2], rng: &mut Pcg32, splats: &mut Splats) -> Vec3 {
        let Some(lights) = self.lights.as_ref().filter(|_| self.max_vertices >= 2) else {
            return Vec3::ZERO;
        };
        let kit = self.kit(lights, pixel);
        let max = self.max_vertices;
        let cam = walk([&kit.lens, &kit.look], &kit.scatter, max, rng);
        let light = walk([&kit.emit, &kit.leave], &kit.gather, max - 1, rng);
        let (c, l) = (cam.vertices(), light.vertices());
        let mut radiance = DVec3::ZERO;
        for s in 1..=c.len() {
            let open = s == 1 || self.connectible(&c[s - 1]);
            for t in 0..=l.len().max(1).min(max - s) {
                let path = match t {
                    0 if s >= 2 && lights.emitter_of(&c[s - 1]).is_some() => cam.slice(0..s),
                    1 if open => directly(cam.slice(0..s), &kit.direct, rng),
                    2.. if open && self.connectible(&l[t - 1]) => {
                        cam.slice(0..s).concat(&light.slice(0..t).reversed())
                    }
                    _ => continue,
                };
                let joins: &[usize] = if t == 0 { &[] } else { &[s - 1] };
                radiance += self.contribute(&kit, &path, Split::Bdpt(s), joins, pixel, splats);
            }
        }
        if let Some(portal) = &self.portal {
            let mut segment = RandomSequence::new();
            if segment.append_pair(portal).sample(rng) == aether_core::StepKind::Vertex {
                let lit = directly(segment.clone(), &kit.direct, rng);
                for k in 1..=c.len().min(max.saturating_sub(2)) {
                    for t in 0..=l.len().max(1).min(max - k - 2) {
                        let middle = if t == 1 { &lit } else { &segment };
                        let tail = light.slice(0..if t == 1 { 0 } else { t }).reversed();
                        let path = cam.slice(0..k).concat(middle).concat(&tail);
                        let joins: &[usize] = if t == 0 { &[k - 1] } else { &[k - 1, k + 1] };
                        radiance +=
                            self.contribute(&kit, &path, Split::Portal(k), joins, pixel, splats);
                    }
                }
            }
        }
        radiance.as_vec3()
    }
}

impl<'s> Bdpt<'s> {
    /// The weighted estimate of `path`, sampled by `own`, with its
    /// visibility tested on the edges after the vertices in `joins`: returned
    /// for `pixel` if the camera subpath chose the pixel, splatted otherwise.
    fn contribute(
        &self,
        kit: &Kit<'_, 's>,
        path: &Path<'_>,
        own: Split,
        joins: &[usize],
        pixel: [u32; 2],
        splats: &mut Splats,
    ) -> DVec3 {
        let v = path.vertices();
        let first = v.get(1).filter(|_| path.is_complete());
        let (Some(f), Some(d)) = (self.integrand(), first.and_then(|b| v[0].direction_to(b)))
        else {
            return DVec3::ZERO;
        };
        let through = f.throughput(v, joins);
        let estimate = |j: [u32; 2], look: &CameraDirection<'_>| {
            // Occluded or black paths need no weight.
            let open = through != DVec3::ZERO;
            let (w, p) = open.then(|| self.weight(kit, look, own, path))?;
            if p.is_nan() || p <= 0.0 {
                return None;
            }
            let unweighted = through * self.camera.importance(j, &v[0], d) / p;
            if let (Some(images), Split::Bdpt(s)) = (&self.images, own) {
                images.add(s, v.len() - s, j, unweighted * w, unweighted, s == 1);
            }
            Some(unweighted * w).filter(|e| e.is_finite())
        };
        if !matches!(own, Split::Bdpt(1) | Split::Portal(1)) {
            return estimate(pixel, &kit.look).unwrap_or(DVec3::ZERO);
        }
        for j in self.camera.pixels_toward(&v[0], d) {
            if let Some(e) = estimate(j, &self.camera.direction(self.scene, j)) {
                splats.push((j, e.as_vec3()));
            }
        }
        DVec3::ZERO
    }

    fn integrand(&self) -> Option<Integrand<'_>> {
        let lights = self.lights.as_ref()?;
        Some(Integrand::new(self.scene, &self.camera, lights))
    }

    /// The MIS weight of `path` (for the pixel `look` samples) against
    /// every split of it, and its density under its own.
    fn weight(
        &self,
        kit: &Kit<'_, 's>,
        look: &CameraDirection<'_>,
        own: Split,
        path: &Path<'_>,
    ) -> (f64, f64) {
        let n = path.len();
        let direct = |t: usize| (t == 1).then_some((one(&kit.direct), false));
        let portal = self.portal.as_ref().map(|p| (StrategyRef::Two(p), false));
        let splits = (1..=n)
            .map(|s| aether_core::Split {
                camera: s,
                middle: direct(n - s).into_iter().collect(),
            })
            .chain((1..n.saturating_sub(1)).filter_map(|k| {
                Some(aether_core::Split {
                    camera: k,
                    middle: [portal?].into_iter().chain(direct(n - k - 2)).collect(),
                })
            }));
        let splits: SmallVec<[_; 24]> = splits.collect();
        let index = match own {
            Split::Bdpt(s) => s - 1,
            Split::Portal(k) => n + k - 1,
        };
        let camera = [one(&kit.lens), one(look), one(&kit.scatter)];
        let light = [one(&kit.emit), one(&kit.leave), one(&kit.gather)];
        let (w, p) = weight_of_split(path, &camera, &light, &splits, index, self.heuristic);
        (w, if p.is_zero() { 0.0 } else { p.value() })
    }
}
