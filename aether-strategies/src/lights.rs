//! The lights as strategies: where a light path starts (a light chosen by
//! power, then a point on it), the direction it leaves in, and direct
//! sampling of a light from a shading point; and what the lights emit.

use aether_core::primitives::{
    CosineHemisphere, DiracDirection, DiscreteDistribution, Equirect, PiecewiseConstant2D,
    SpherePoint, UniformCone, UniformDisk, UniformSphere, UniformTriangle,
};
use aether_core::{
    AtInfinity, DiracPoint, Distribution, Either, Frame, InFrame, Intersect, OnSurface, OnTriangle,
    ParallelRays, Prefix, RayCaster, Select, Step, Strategy,
};
use glam::Vec3;

use crate::camera::frame_of;
use crate::geometry::Primitive;
use crate::mesh::{TriangleMesh, triangle_normal};
use crate::scene::{Emitter, Scene};
use crate::spectrum::luminance;
use crate::vertex::{SceneVertex, Site};

/// Mesh `mesh` of the geometry, its triangles chosen by area; the
/// triangles built once, not at every light sample.
#[derive(Debug)]
struct MeshLight {
    mesh: u32,
    triangles: DiscreteDistribution,
    pieces: Vec<UniformTriangle>,
    normals: Vec<Vec3>,
}

impl MeshLight {
    /// The light of mesh `index` of the geometry, and its total area: one
    /// pass over its triangles.
    fn new(index: u32, mesh: &TriangleMesh) -> (Self, f64) {
        let count = mesh.triangles.len();
        let (mut areas, mut pieces, mut normals) = (Vec::new(), Vec::new(), Vec::new());
        for t in 0..count {
            let corners = mesh.corners(t);
            let [a, b, c] = corners;
            areas.push(mesh.triangle_area(t));
            pieces.push(UniformTriangle::new(a, b, c));
            normals.push(triangle_normal(corners));
        }
        // A mesh without area emits nothing: power zero, never chosen.
        let triangles = DiscreteDistribution::new(&areas)
            .unwrap_or_else(|_| DiscreteDistribution::new(&[1.0]).expect("one weight"));
        let light = MeshLight {
            mesh: index,
            triangles,
            pieces,
            normals,
        };
        (light, areas.iter().sum())
    }

    /// The light vertex of barycentrics `b`, sampled on triangle `t`.
    fn vertex(&self, scene: &Scene, t: usize, b: [f32; 3]) -> SceneVertex {
        let shape = (self.pieces[t].corners(), self.normals[t]);
        SceneVertex::at_barycentrics(scene, (self.mesh, t as u32), shape, b)
    }
}

/// What an emitter is made of, for sampling.
#[derive(Debug)]
enum Source {
    /// A mesh of the geometry.
    Mesh(MeshLight),
    /// Sphere `sphere` of the geometry.
    Sphere { sphere: u32 },
    /// A point or spot light at `position`, emitting in `frame`.
    Point {
        position: Vec3,
        frame: Frame,
        cos_cutoff: f64,
    },
    /// A directional light towards `direction` (from the scene).
    Distant { direction: Vec3 },
    /// Uniform radiance from every direction.
    Constant,
    /// An environment map, importance-sampled by luminance × sin θ.
    Map {
        frame: Frame,
        table: PiecewiseConstant2D,
    },
}

/// The scene's emitters prepared for sampling: the choice of a light by
/// power, triangle tables by area, environment-map tables, and the
/// bounding sphere that distant lights shine through.
#[derive(Debug)]
pub struct Lights<'s> {
    scene: &'s Scene,
    choice: DiscreteDistribution,
    sources: Vec<Source>,
    environment: Option<usize>,
    center: Vec3,
    radius: f32,
}

impl<'s> Lights<'s> {
    /// The lights of `scene`, or `None` if it has no emitter that emits.
    #[must_use]
    pub fn new(scene: &'s Scene) -> Option<Lights<'s>> {
        let (center, radius) = bounding_sphere(scene);
        let disk = std::f64::consts::PI * f64::from(radius).powi(2);
        let mut power = Vec::new();
        let mut sources = Vec::new();
        let mut environment = None;
        let meshes = scene.geometry.meshes();
        for (i, e) in scene.emitters.iter().enumerate() {
            let (p, source) = match e {
                Emitter::Area { radiance, shape } if *shape < meshes.len() => {
                    let (light, area) = MeshLight::new(*shape as u32, &meshes[*shape]);
                    let power = luminance(*radiance) * std::f64::consts::PI * area;
                    (power, Source::Mesh(light))
                }
                Emitter::Area { radiance, shape } => {
                    let sphere = (*shape - meshes.len()) as u32;
                    let r = f64::from(scene.geometry.spheres()[sphere as usize].radius);
                    let area = 4.0 * std::f64::consts::PI * r * r;
                    (
                        luminance(*radiance) * std::f64::consts::PI * area,
                        Source::Sphere { sphere },
                    )
                }
                Emitter::Point {
                    position,
                    intensity,
                } => (
                    luminance(*intensity) * 4.0 * std::f64::consts::PI,
                    Source::Point {
                        position: *position,
                        frame: Frame::WORLD,
                        cos_cutoff: -1.0,
                    },
                ),
                Emitter::Spot {
                    to_world,
                    intensity,
                    cutoff_angle,
                    ..
                } => {
                    let cos_cutoff = f64::from(cutoff_angle.to_radians().cos());
                    let frame = frame_of(*to_world);
                    let position = to_world.transform_point3(Vec3::ZERO);
                    let solid_angle = 2.0 * std::f64::consts::PI * (1.0 - cos_cutoff);
                    (
                        luminance(*intensity) * solid_angle,
                        Source::Point {
                            position,
                            frame,
                            cos_cutoff,
                        },
                    )
                }
                Emitter::Directional {
                    direction,
                    irradiance,
                } => (
                    luminance(*irradiance) * disk,
                    Source::Distant {
                        direction: -direction.normalize(),
                    },
                ),
                Emitter::Constant { radiance } => {
                    environment = Some(i);
                    let power = luminance(*radiance) * 4.0 * std::f64::consts::PI * disk;
                    (power, Source::Constant)
                }
                Emitter::EnvMap {
                    image,
                    scale,
                    to_world,
                    ..
                } => {
                    environment = Some(i);
                    let (w, h) = (image.width as usize, image.height as usize);
                    let weights: Vec<f64> = (0..w * h)
                        .map(|k| {
                            let theta = std::f64::consts::PI * ((k / w) as f64 + 0.5) / h as f64;
                            luminance(image.texels[k]).max(0.0) * theta.sin()
                        })
                        .collect();
                    let mean = weights.iter().sum::<f64>() / (w * h) as f64;
                    // A black map emits nothing: power zero, never chosen.
                    let Ok(table) = PiecewiseConstant2D::new(&weights, w, h) else {
                        power.push(0.0);
                        sources.push(Source::Constant);
                        continue;
                    };
                    let power =
                        mean * f64::from(*scale) * 2.0 * std::f64::consts::PI.powi(2) * disk;
                    (
                        power,
                        Source::Map {
                            frame: frame_of(*to_world),
                            table,
                        },
                    )
                }
            };
            power.push(if p.is_finite() { p.max(0.0) } else { 0.0 });
            sources.push(source);
        }
        let choice = DiscreteDistribution::new(&power).ok()?;
        Some(Lights {
            scene,
            choice,
            sources,
            environment,
            center,
            radius,
        })
    }

    /// The probability with which light `emitter` is chosen.
    #[must_use]
    pub fn probability(&self, emitter: usize) -> f64 {
        self.choice.probability(emitter)
    }

    /// The strategy that starts light paths.
    #[must_use]
    pub fn position(&self) -> EmitterPosition<'_, 's> {
        EmitterPosition(self)
    }

    /// The strategy that continues a light path from its light vertex.
    #[must_use]
    pub fn direction(&self) -> EmitterDirection<'_, 's> {
        EmitterDirection(self)
    }

    /// The strategy that samples a light from a shading point.
    #[must_use]
    pub fn direct(&self) -> DirectEmitter<'_, 's> {
        DirectEmitter(self)
    }

    /// The emitter a vertex lies on, if any.
    #[must_use]
    pub fn emitter_of(&self, v: &SceneVertex) -> Option<usize> {
        match v.site {
            Site::Surface { shape, .. } => self.scene.shapes[shape as usize].emitter,
            Site::Point { emitter } => emitter.map(|e| e as usize),
            Site::Distant { emitter, .. } => Some(emitter as usize),
            Site::Environment { .. } => self.environment,
            Site::Lens => None,
        }
    }

    fn emitter_of_step(&self, v: &Step<SceneVertex>) -> Option<usize> {
        match v {
            Step::Vertex(v) => self.emitter_of(v),
            _ => None,
        }
    }

    /// The radiance (intensity for point lights, irradiance for directional
    /// lights: their Dirac coefficients) that light vertex `light` sends
    /// along unit direction `toward`.
    #[must_use]
    pub fn emitted(&self, light: &SceneVertex, toward: Vec3) -> Vec3 {
        let Some(e) = self.emitter_of(light) else {
            return Vec3::ZERO;
        };
        let rgb = Vec3::from_array;
        match (&self.scene.emitters[e], &self.sources[e]) {
            (Emitter::Area { radiance, .. }, _) if toward.dot(light.geometric_normal) > 0.0 => {
                rgb(*radiance)
            }
            (Emitter::Point { intensity, .. }, _) => rgb(*intensity),
            (
                Emitter::Spot {
                    intensity,
                    cutoff_angle,
                    beam_width,
                    ..
                },
                Source::Point { frame, .. },
            ) => {
                let cos = frame.to_local(toward).z.clamp(-1.0, 1.0);
                let (cutoff, beam) = (cutoff_angle.to_radians(), beam_width.to_radians());
                let angle = cos.acos();
                // Mitsuba 3's falloff: full inside the beam, linear in angle to the cut-off.
                let falloff = if angle >= cutoff {
                    0.0
                } else if angle <= beam {
                    1.0
                } else {
                    (cutoff - angle) / (cutoff - beam)
                };
                rgb(*intensity) * falloff
            }
            (Emitter::Directional { irradiance, .. }, _) => rgb(*irradiance),
            (Emitter::Constant { radiance }, _) => rgb(*radiance),
            (Emitter::EnvMap { image, scale, .. }, Source::Map { frame, .. }) => {
                // The map's rows run from the top (v = 0 is up, as in the
                // Equirect block), while texture lookups put v = 0 at the bottom.
                let d = frame.to_local(-toward).as_dvec3().normalize();
                let u = (d.x.atan2(-d.z) / std::f64::consts::TAU).rem_euclid(1.0);
                let v = d.y.clamp(-1.0, 1.0).acos() / std::f64::consts::PI;
                rgb(image.lookup(u as f32, 1.0 - v as f32)) * *scale
            }
            _ => Vec3::ZERO,
        }
    }

    /// The distribution of the light vertex of emitter `e`, when a point on
    /// it is sampled by area (or in direction, for distant lights).
    fn points(&self, e: usize) -> impl Distribution<Value = Step<SceneVertex>> + '_ {
        let scene = self.scene;
        match &self.sources[e] {
            Source::Mesh(light) => {
                // The triangle is chosen by area and named by the vertex's site.
                let m = light.mesh;
                let on = move |t: usize| {
                    let at = move |_, b| Some(light.vertex(scene, t, b));
                    OnTriangle::new(light.pieces[t], at)
                };
                let area = Select::new(&light.triangles, 2, on, move |v| triangle_of(v, m));
                Either::Left(Either::Left(area))
            }
            Source::Sphere { sphere: i } => {
                let s = scene.geometry.spheres()[*i as usize];
                let at = move |p| Some(SceneVertex::on_sphere(scene, *i, p));
                let area = SpherePoint::new(UniformSphere, s.center, s.radius);
                Either::Left(Either::Right(OnSurface::new(area, at)))
            }
            Source::Point { position, .. } => {
                let light = SceneVertex::point(*position, Some(e as u32));
                Either::Right(Either::Left(DiracPoint::new(light, 1.0)))
            }
            Source::Distant { .. } | Source::Constant | Source::Map { .. } => {
                let directions = match &self.sources[e] {
                    Source::Distant { direction } => {
                        Either::Left(Either::Left(DiracDirection::new(*direction, 1.0)))
                    }
                    Source::Map { frame, table } => {
                        Either::Right(InFrame::new(*frame, Equirect::new(table)))
                    }
                    _ => Either::Left(Either::Right(UniformSphere)),
                };
                let distant = matches!(self.sources[e], Source::Distant { .. });
                let at = move |d| match distant {
                    true => SceneVertex::distant(e as u32, d),
                    false => SceneVertex::environment(d),
                };
                Either::Right(Either::Right(AtInfinity::new(directions, at)))
            }
        }
    }
}

/// The triangle of mesh `mesh` a light vertex lies on, if any.
fn triangle_of(v: &Step<SceneVertex>, mesh: u32) -> Option<usize> {
    match v {
        Step::Vertex(SceneVertex {
            site:
                Site::Surface {
                    primitive: Primitive::Triangle { mesh: m, triangle },
                    ..
                },
            ..
        }) if *m == mesh => Some(*triangle as usize),
        _ => None,
    }
}

fn bounding_sphere(scene: &Scene) -> (Vec3, f32) {
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for m in scene.geometry.meshes() {
        for p in &m.positions {
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
    }
    for s in scene.geometry.spheres() {
        lo = lo.min(s.center - s.radius);
        hi = hi.max(s.center + s.radius);
    }
    if lo.x > hi.x {
        return (Vec3::ZERO, 1.0);
    }
    let center = 0.5 * (lo + hi);
    (center, (0.5 * (hi - lo).length() * 1.01).max(1e-3))
}

/// The start of a light path: a light chosen by power, then a point on it
/// by area (meshes, spheres), its position (point and spot lights), or a
/// direction (distant lights: directional ones exactly, environments by
/// their luminance).
///
/// ```
/// # fn f(scene: &aether_strategies::scene::Scene) {
/// use aether_core::RandomSequence;
/// use aether_strategies::lights::Lights;
/// let lights = Lights::new(scene).expect("a lit scene");
/// let (start, leave) = (lights.position(), lights.direction());
/// let mut light_path = RandomSequence::new();
/// light_path.append(&start).append(&leave);
/// # }
/// ```
#[derive(Clone, Copy, Debug)]
pub struct EmitterPosition<'l, 's>(&'l Lights<'s>);

impl Strategy<SceneVertex> for EmitterPosition<'_, '_> {
    fn distribution<'a>(
        &'a self,
        _prefix: Prefix<'a, SceneVertex>,
    ) -> impl Distribution<Value = Step<SceneVertex>> + 'a {
        let l = self.0;
        Select::new(
            &l.choice,
            2,
            move |e| l.points(e),
            move |v| l.emitter_of_step(v),
        )
    }
    fn memory(&self) -> usize {
        0
    }
    fn depth_class(&self, _prefix_len: usize) -> usize {
        0
    }
}

/// The first bounce of a light path: cosine-distributed about an area
/// light's normal, uniform from a point light, uniform in a spot light's
/// cone, and parallel rays through a disk covering the scene from a
/// distant light.
///
/// ```
/// # fn f(scene: &aether_strategies::scene::Scene) {
/// use aether_core::{Pcg32, RandomSequence};
/// use aether_strategies::lights::Lights;
/// let lights = Lights::new(scene).expect("a lit scene");
/// let (start, leave) = (lights.position(), lights.direction());
/// let mut rng = Pcg32::new(1, 0);
/// let mut light_path = RandomSequence::new();
/// let lit = light_path.append_sample(&start, &mut rng) && light_path.append_sample(&leave, &mut rng);
/// # }
/// ```
#[derive(Clone, Copy, Debug)]
pub struct EmitterDirection<'l, 's>(&'l Lights<'s>);

impl Strategy<SceneVertex> for EmitterDirection<'_, '_> {
    fn distribution<'a>(
        &'a self,
        prefix: Prefix<'a, SceneVertex>,
    ) -> impl Distribution<Value = Step<SceneVertex>> + 'a {
        let (l, scene) = (self.0, self.0.scene);
        let x = prefix.last().expect("a light vertex to leave from");
        let disk = |toward: Vec3| {
            ParallelRays::new(
                toward,
                l.center,
                l.radius,
                UniformDisk::new(l.radius),
                |o| SceneVertex::point(o, None),
                scene,
            )
        };
        match (x.site, l.emitter_of(x).map(|e| &l.sources[e])) {
            (
                Site::Point { .. },
                Some(Source::Point {
                    frame, cos_cutoff, ..
                }),
            ) => {
                let cone = InFrame::new(*frame, UniformCone::new(*cos_cutoff));
                Either::Left(Either::Left(Intersect::new(x, cone, scene)))
            }
            (Site::Environment { direction } | Site::Distant { direction, .. }, _) => {
                Either::Right(disk(direction))
            }
            _ => {
                let cosine = InFrame::new(Frame::from_normal(x.geometric_normal), CosineHemisphere);
                Either::Left(Either::Right(Intersect::new(x, cosine, scene)))
            }
        }
    }
    fn memory(&self) -> usize {
        1
    }
    fn depth_class(&self, _prefix_len: usize) -> usize {
        0
    }
}

/// Rays that only see sphere `sphere`: direct sampling of a sphere light
/// by its cone lands on the light itself, and the connection is tested for
/// visibility like any other.
#[derive(Clone, Copy, Debug)]
struct OnlySphere<'s> {
    scene: &'s Scene,
    sphere: u32,
}

impl RayCaster<SceneVertex> for OnlySphere<'_> {
    fn cast(&self, from: &SceneVertex, direction: Vec3) -> Option<SceneVertex> {
        let s = self.scene.geometry.spheres()[self.sphere as usize];
        let (o, d) = ((from.position - s.center).as_dvec3(), direction.as_dvec3());
        let (b, c) = (o.dot(d), o.length_squared() - f64::from(s.radius).powi(2));
        let disc = b * b - c;
        if disc < 0.0 {
            return None;
        }
        let t = -b - disc.sqrt();
        (t > 0.0).then(|| {
            let p = (from.position.as_dvec3() + t * d).as_vec3();
            SceneVertex::on_sphere(self.scene, self.sphere, p)
        })
    }
}

/// Direct sampling of a light from shading point x: a light chosen by
/// power, then a point by area on meshes, a direction in the cone a sphere
/// subtends, the position of point and spot lights, and the direction of
/// distant lights (environment maps by luminance). No ray is cast: the
/// edge to the light is a connection, whose visibility the integrand tests.
///
/// ```
/// # fn f(scene: &aether_strategies::scene::Scene) {
/// use aether_core::{Pcg32, RandomSequence};
/// use aether_strategies::camera::Camera;
/// use aether_strategies::lights::Lights;
/// let (camera, lights) = (Camera::new(scene).unwrap(), Lights::new(scene).expect("lit"));
/// let (lens, pixel, direct) = (camera.position(), camera.direction(scene, [0, 0]), lights.direct());
/// let mut rng = Pcg32::new(3, 0);
/// let mut path = RandomSequence::new();
/// path.append(&lens).append(&pixel);
/// let mut to_light = path.clone();
/// to_light.append(&direct);
/// let ok = path.sample(&mut rng);
/// # }
/// ```
#[derive(Clone, Copy, Debug)]
pub struct DirectEmitter<'l, 's>(&'l Lights<'s>);

impl Strategy<SceneVertex> for DirectEmitter<'_, '_> {
    fn distribution<'a>(
        &'a self,
        prefix: Prefix<'a, SceneVertex>,
    ) -> impl Distribution<Value = Step<SceneVertex>> + 'a {
        let (l, scene) = (self.0, self.0.scene);
        let x = prefix.last().expect("a shading point");
        let light = move |e: usize| match &l.sources[e] {
            Source::Sphere { sphere } => {
                let s = scene.geometry.spheres()[*sphere as usize];
                let to = s.center - x.position;
                let (d2, r2) = (f64::from(to.length_squared()), f64::from(s.radius).powi(2));
                if d2 > r2 * (1.0 + 1e-4) {
                    let cone = InFrame::new(
                        Frame::from_normal(to.normalize()),
                        UniformCone::subtended(r2, d2),
                    );
                    Either::Left(Intersect::new(
                        x,
                        cone,
                        OnlySphere {
                            scene,
                            sphere: *sphere,
                        },
                    ))
                } else {
                    Either::Right(l.points(e))
                }
            }
            _ => Either::Right(l.points(e)),
        };
        Select::new(&l.choice, 2, light, move |v| l.emitter_of_step(v))
    }
    fn memory(&self) -> usize {
        1
    }
    fn depth_class(&self, _prefix_len: usize) -> usize {
        0
    }
}
