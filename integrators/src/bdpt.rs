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
//! no more than a list of strategies ([`aether_core::weight_of_split`]); the
//! sample's [`aether_core::Joins`] find those weights from the two subpaths
//! as sampled, without building the joined paths.

use aether_core::{
    DynStrategy, Heuristic, INLINE_VERTICES, Join, Joins, RandomSequence, Sometimes, StrategyRef,
};
use aether_strategies::bsdf::Transport;
use aether_strategies::camera::{Camera, CameraDirection, CameraPosition};
use aether_strategies::integrand::Integrand;
use aether_strategies::lights::{DirectEmitter, EmitterDirection, EmitterPosition, Lights};
use aether_strategies::portal::PortalSegment;
use aether_strategies::scattering::{BsdfSampling, Roulette};
use aether_strategies::scene::Scene;
use aether_strategies::subpath::{End, Subpath};
use aether_strategies::vertex::{SceneVertex, Site};
use glam::{DVec3, Vec3};
use smallvec::SmallVec;

use crate::estimator::{Estimator, Rng, Splats, path_limits};
use crate::techniques::TechniqueImages;

type Path<'a> = RandomSequence<'a, SceneVertex>;

/// The share of samples that also sample portal segments: tridirectional
/// tracing's extra techniques cost more than BDPT's, and pay off on fewer
/// paths. The segment strategy is taken with this probability, so its
/// densities (and with them MIS) count it as that share of a sample.
const PORTAL_SHARE: f64 = 0.25;

/// Where a technique splits a path: `Bdpt(s)` samples the first s vertices
/// from the camera and the rest from the light; `Portal(k)` samples the
/// first k from the camera, the next two as a portal segment, the rest from
/// the light.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Split {
    Bdpt(usize),
    Portal(usize),
}

impl Split {
    /// The technique's index in `aether_core::Split::bidirectional`'s list
    /// for paths of `n` vertices.
    fn index(self, n: usize) -> usize {
        match self {
            Split::Bdpt(s) => s,
            Split::Portal(k) => n + k,
        }
    }
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
    portal: Option<Sometimes<PortalSegment<'s>>>,
    max_vertices: usize,
    roulette: Roulette,
    heuristic: Heuristic,
    images: Option<TechniqueImages>,
    /// Light paths per pixel sample that may splat to it: one per rendered
    /// pixel (of the crop window).
    splats: f64,
    /// True for a thin lens, which light paths can reach (s = 0).
    lens: bool,
}

/// The strategies of one sample, and the integrand they sample.
struct Kit<'a, 's> {
    f: Integrand<'a>,
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
            // Each rendered pixel's sample traces one light path.
            splats: f64::from(scene.film.crop[2]) * f64::from(scene.film.crop[3]),
            lens: scene.aperture().is_some(),
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
            portal: Some(Sometimes::new(PORTAL_SHARE, PortalSegment::new(scene, 0)?)),
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

    /// The strategies of a sample of `pixel`; none in a scene without lights.
    fn kit(&self, pixel: [u32; 2]) -> Option<Kit<'_, 's>> {
        let (scene, lights) = (self.scene, self.lights.as_ref()?);
        Some(Kit {
            f: Integrand::new(scene, &self.camera, lights),
            lens: self.camera.position(),
            look: self.camera.direction(scene, pixel),
            scatter: BsdfSampling::new(scene, Transport::Radiance, self.roulette),
            emit: lights.position(),
            leave: lights.direction(),
            gather: BsdfSampling::new(scene, Transport::Importance, self.roulette),
            direct: lights.direct(),
        })
    }
}

fn one<'a>(s: &'a dyn DynStrategy<SceneVertex>) -> StrategyRef<'a, SceneVertex> {
    StrategyRef::One(s)
}

/// Samples `first`, then `next` into `path` until a step fails or it has
/// `max` vertices. An out-parameter, against the house style, for speed: a
/// path returned by value (about 3 KB) was copied by `memcpy` twice per
/// sample, 1 % of BDPT's instructions.
fn walk<'a>(
    path: &mut Path<'a>,
    first: [&'a dyn DynStrategy<SceneVertex>; 2],
    next: &'a dyn DynStrategy<SceneVertex>,
    max: usize,
    rng: &mut Rng,
) {
    path.append(first[0]).append(first[1]);
    path.repeat(next, max, rng);
}

/// A path BDPT estimated, with its MIS-weighted contribution summed over
/// the pixels it reached: the seeds of Veach's Metropolis light transport.
#[derive(Clone, Debug)]
pub struct SeedPath {
    /// The vertices, camera first.
    pub vertices: SmallVec<[SceneVertex; INLINE_VERTICES]>,
    /// The weighted contribution, summed over pixels.
    pub weighted: DVec3,
    /// True if it was splatted (found by a light subpath that reached the
    /// camera), false if it belongs to the sample's pixel.
    pub splat: bool,
}

impl Estimator for Bdpt<'_> {
    fn sample(&self, pixel: [u32; 2], rng: &mut Rng, splats: &mut Splats) -> Vec3 {
        self.sample_into(pixel, rng, splats, None)
    }
}

impl Bdpt<'_> {
    /// As [`Estimator::sample`], also recording every path with a
    /// contribution in `seeds`.
    pub fn sample_seeds(
        &self,
        pixel: [u32; 2],
        rng: &mut Rng,
        splats: &mut Splats,
        seeds: &mut Vec<SeedPath>,
    ) -> Vec3 {
        self.sample_into(pixel, rng, splats, Some(seeds))
    }

    /// Samples only technique (s, n − s) for paths of `n` vertices: the
    /// camera subpath's first s vertices joined to the light subpath's
    /// first n − s, weighed by MIS against every technique of that length
    /// (multiplexed MLT). Returns the estimate for `pixel` (s ≥ 2) or
    /// pushes it to `splats` (s ≤ 1).
    pub fn sample_technique(
        &self,
        pixel: [u32; 2],
        (n, s): (usize, usize),
        rng: &mut Rng,
        splats: &mut Splats,
    ) -> Vec3 {
        let Some(kit) = self.kit(pixel) else {
            return Vec3::ZERO;
        };
        if n < 2 || n > self.max_vertices || s > n || (s == 0 && !self.lens) {
            return Vec3::ZERO;
        }
        let (kit, t) = (&kit, n - s);
        let (mut cam, mut light) = (RandomSequence::new(), RandomSequence::new());
        match s {
            0 => {}
            1 => {
                cam.append_sample(&kit.lens, rng);
            }
            _ => walk(&mut cam, [&kit.lens, &kit.look], &kit.scatter, s, rng),
        }
        if t >= 2 {
            walk(&mut light, [&kit.emit, &kit.leave], &kit.gather, t, rng);
        }
        if cam.len() != s || (t >= 2 && light.len() != t) {
            return Vec3::ZERO;
        }
        let eye = Subpath::of(kit.f, End::Camera, cam.vertices());
        let ends = (&light, &Subpath::of(kit.f, End::Light, light.vertices()));
        let joins = self.joins(kit, (&cam, &light));
        let mut run = Run::new(kit, pixel, rng, splats, None, joins);
        let radiance = if s == 0 {
            self.reach_lens(&mut run, ends)
        } else {
            run.only = Some(t);
            self.join(&mut run, &cam, (&eye, s), ends, Split::Bdpt(s))
        };
        radiance.as_vec3()
    }

    /// The number of techniques [`sample_technique`](Self::sample_technique)
    /// offers for paths of `n` vertices: s from 1 (0 with a thin lens) to n.
    #[must_use]
    pub fn techniques(&self, n: usize) -> usize {
        n + usize::from(self.lens)
    }

    /// The longest path, in vertices.
    #[must_use]
    pub fn max_vertices(&self) -> usize {
        self.max_vertices
    }

    fn sample_into(
        &self,
        pixel: [u32; 2],
        rng: &mut Rng,
        splats: &mut Splats,
        seeds: Option<&mut Vec<SeedPath>>,
    ) -> Vec3 {
        let Some(kit) = self.kit(pixel).filter(|_| self.max_vertices >= 2) else {
            return Vec3::ZERO;
        };
        let (kit, max, f) = (&kit, self.max_vertices, kit.f);
        let (mut cam, mut light) = (RandomSequence::new(), RandomSequence::new());
        walk(&mut cam, [&kit.lens, &kit.look], &kit.scatter, max, rng);
        // Light paths may reach a thin lens (s = 0) with the last vertex.
        let reach = max - usize::from(!self.lens);
        walk(&mut light, [&kit.emit, &kit.leave], &kit.gather, reach, rng);
        let (mut eye, mut lamp) = (Subpath::new(f, End::Camera), Subpath::new(f, End::Light));
        eye.extend(cam.vertices());
        lamp.extend(light.vertices());
        let ends = (&light, &lamp);
        let joins = self.joins(kit, (&cam, &light));
        let mut run = Run::new(kit, pixel, rng, splats, seeds, joins);
        let mut radiance = self.reach_lens(&mut run, ends);
        for s in 1..=cam.len() {
            radiance += self.join(&mut run, &cam, (&eye, s), ends, Split::Bdpt(s));
        }
        let Some(portal) = self.portal.as_ref() else {
            return radiance.as_vec3();
        };
        // One line through the portal for each side the camera vertices are
        // on, for a share of the samples (incomplete otherwise).
        let mut lines = [None, None];
        for k in 1..=cam.len().min(max.saturating_sub(2)) {
            let c = &cam.vertices()[k - 1];
            let line = lines[portal.inner().side(c)].get_or_insert_with(|| {
                let mut line = RandomSequence::given([*c]);
                line.append_pair(portal).sample(run.rng);
                line
            });
            if line.is_complete() && f.visible(c, &line.vertices()[1]) {
                let head = cam.slice(0..k).concat(&line.slice(1..3));
                let side = Subpath::of(f, End::Camera, head.vertices());
                radiance += self.join(&mut run, &head, (&side, k + 2), ends, Split::Portal(k));
            }
        }
        radiance.as_vec3()
    }
}

/// What the connections of one sample share (with the densities cached
/// for them, which a new run forgets).
struct Run<'r, 'j, 'a, 's> {
    kit: &'a Kit<'a, 's>,
    pixel: [u32; 2],
    rng: &'r mut Rng<'r>,
    splats: &'r mut Splats,
    seeds: Option<&'r mut Vec<SeedPath>>,
    /// The one light-prefix length to join, if not all.
    only: Option<usize>,
    /// The camera's importance for the pixel's own first ray (its two ends).
    importance: Option<(Vec3, Vec3, f64)>,
    /// The MIS weights of the joins of the sample's two subpaths.
    joins: Joins<'j, 'a, SceneVertex>,
}

impl<'r, 'j, 'a, 's> Run<'r, 'j, 'a, 's> {
    /// The camera's importance for pixel `pixel` and the first ray of
    /// `join`, leaving the lens in direction `d`; `own`, for the sample's
    /// own pixel, whose connections all share their first ray, is found
    /// once per sample.
    fn importance(
        &mut self,
        camera: &Camera,
        (pixel, join): ([u32; 2], &Join<'_, '_, SceneVertex>),
        d: Vec3,
        own: bool,
    ) -> f64 {
        let lens = join.vertex(0);
        let ray = (lens.position, join.vertex(1).position);
        match self.importance {
            Some((a, b, w)) if own && (a, b) == ray => w,
            _ => {
                let w = camera.importance(pixel, lens, d);
                if own {
                    self.importance = Some((ray.0, ray.1, w));
                }
                w
            }
        }
    }

    fn new(
        kit: &'a Kit<'a, 's>,
        pixel: [u32; 2],
        rng: &'r mut Rng<'r>,
        splats: &'r mut Splats,
        seeds: Option<&'r mut Vec<SeedPath>>,
        joins: Joins<'j, 'a, SceneVertex>,
    ) -> Self {
        Run {
            kit,
            pixel,
            rng,
            splats,
            seeds,
            only: None,
            importance: None,
            joins,
        }
    }
}

impl<'s> Bdpt<'s> {
    /// Joins the first `n` vertices of the camera side (`head`, whose
    /// integrand products are `side`) to every light prefix (or only the
    /// one of `run.only` vertices), to a light directly, or to nothing if
    /// they end on a light: the estimates of technique `own`.
    fn join<'a>(
        &'a self,
        run: &mut Run<'_, '_, 'a, 's>,
        head: &Path<'a>,
        (side, n): (&Subpath<'_>, usize),
        (light, lamp): (&Path<'a>, &Subpath<'_>),
        own: Split,
    ) -> DVec3 {
        let (mut radiance, open, only) = (DVec3::ZERO, side.connectible(n - 1), run.only);
        let all = 0..=lamp.len().max(1).min(self.max_vertices - n);
        for t in all.filter(|t| only.is_none_or(|o| o == *t)) {
            let aside = match t {
                1 if open => head.sample_after(n, &run.kit.direct, run.rng),
                _ => None,
            };
            let through = match (t, &aside) {
                (0, _) => side.emitted(n),
                (1, Some(l)) => side.connect_lamp(n, &l.vertex),
                (2.., _) if open && lamp.connectible(t - 1) => side.connect(n, lamp, t),
                _ => continue,
            };
            let join = Join::new((head, n), (light, t), aside.as_ref());
            radiance += self.contribute(run, own, through, &join);
        }
        radiance
    }

    /// The weighted estimate of `join`, sampled by `own`, whose integrand
    /// without the camera's importance is `through`: returned if the
    /// camera subpath chose the pixel, splatted otherwise.
    fn contribute<'a>(
        &'a self,
        run: &mut Run<'_, '_, 'a, 's>,
        own: Split,
        through: DVec3,
        join: &Join<'_, 'a, SceneVertex>,
    ) -> DVec3 {
        // Occluded or black paths need no weight.
        if through == DVec3::ZERO {
            return DVec3::ZERO;
        }
        let lens = join.vertex(0);
        let d = lens.direction_to(join.vertex(1)).unwrap_or(Vec3::Z);
        let splat = matches!(own, Split::Bdpt(0 | 1) | Split::Portal(1));
        let at = |j| (j, self.camera.direction(self.scene, j));
        // Lists filled in place: collected, each was returned by copy.
        let (mut pixels, mut looks) = (SmallVec::<[_; 16]>::new(), SmallVec::<[_; 16]>::new());
        match splat {
            true => pixels.extend(self.camera.pixels_toward(lens, d).map(at)),
            false => pixels.push((run.pixel, run.kit.look)),
        };
        // A splat varies the camera ray's strategy per pixel; the sample's
        // own pixel is weighed with its own strategies, no variant.
        let technique = own.index(join.len());
        looks.extend(pixels.iter().filter(|_| splat).map(|p| one(&p.1)));
        let weights = match splat {
            true => run.joins.join_weights(join, technique, 1, &looks),
            false => smallvec::smallvec![run.joins.join_weight(join, technique)],
        };
        let mut seen = DVec3::ZERO;
        for (&(j, _), &(w, p)) in pixels.iter().zip(&weights) {
            let p = p.value();
            let unweighted = through * run.importance(&self.camera, (j, join), d, !splat) / p;
            match unweighted * w {
                e if p <= 0.0 || !e.is_finite() => {}
                e if splat => run.splats.push((j, e.as_vec3())),
                e => seen = e,
            }
            self.observe(run, (own, j, splat), join, unweighted, w, p);
        }
        seen
    }

    /// The estimate of the light subpath as a whole if it ends on a thin
    /// lens (s = 0).
    fn reach_lens<'a>(
        &'a self,
        run: &mut Run<'_, '_, 'a, 's>,
        (light, lamp): (&Path<'a>, &Subpath<'_>),
    ) -> DVec3 {
        if light.vertices().last().is_none_or(|v| v.site != Site::Lens) {
            return DVec3::ZERO;
        }
        let join = Join::new((light, 0), (light, light.len()), None);
        self.contribute(run, Split::Bdpt(0), lamp.product(light.len() - 1), &join)
    }

    /// What the outputs beside the image see of each estimate: the (s, t)
    /// images, and the paths with their weighted contributions (the seeds
    /// of Veach's MLT).
    fn observe(
        &self,
        run: &mut Run<'_, '_, '_, 's>,
        (own, j, splat): (Split, [u32; 2], bool),
        join: &Join<'_, '_, SceneVertex>,
        unweighted: DVec3,
        w: f64,
        p: f64,
    ) {
        let weighted = unweighted * w;
        if p <= 0.0 || w == 0.0 || !weighted.is_finite() {
            return;
        }
        if let (Some(images), Split::Bdpt(s)) = (&self.images, own) {
            images.add(s, join.len() - s, j, weighted, unweighted, splat);
        }
        if let Some(seeds) = run.seeds.as_deref_mut().filter(|_| weighted != DVec3::ZERO) {
            // A splatted path reaches several pixels in turn: one seed.
            match seeds.last_mut() {
                Some(last) if splat && last.splat && last.vertices.iter().eq(join.vertices()) => {
                    last.weighted += weighted;
                }
                _ => seeds.push(SeedPath {
                    vertices: join.vertices().copied().collect(),
                    weighted,
                    splat,
                }),
            }
        }
    }

    /// The MIS weights of the joins of the subpaths `(eye, light)` that
    /// `kit`'s strategies sampled.
    fn joins<'p, 'x>(
        &'x self,
        kit: &'x Kit<'_, 's>,
        subpaths: (&'p Path<'x>, &'p Path<'x>),
    ) -> Joins<'p, 'x, SceneVertex> {
        let camera = [one(&kit.lens), one(&kit.look), one(&kit.scatter)];
        let light = [one(&kit.emit), one(&kit.leave), one(&kit.gather)];
        let portal = self.portal.as_ref().map(|p| StrategyRef::Two(p));
        let (steps, counts) = ((Some(one(&kit.direct)), portal), (self.splats, self.lens));
        Joins::new(subpaths, (&camera, &light), steps, counts, self.heuristic)
    }
}
