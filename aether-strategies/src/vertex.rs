//! The path vertex of a loaded scene, and ray casting that produces it.

use aether_core::{Geometry as Place, RayCaster, Recycle, Vertex};
use glam::{Vec2, Vec3};

use crate::geometry::{Hit, Primitive, offset_origin, unit};
use crate::scene::Scene;

/// What a vertex lies on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Site {
    /// Shape `shape` of [`Scene::shapes`], at `primitive`.
    Surface {
        /// Index into `Scene::shapes`.
        shape: u32,
        /// The triangle or sphere hit.
        primitive: Primitive,
    },
    /// An isolated point: a pinhole or a point light (index into `Scene::emitters`).
    Point {
        /// The emitter, if it is a light.
        emitter: Option<u32>,
    },
    /// A point on a thin lens's aperture (a surface whose normal is the
    /// camera's viewing direction).
    Lens,
    /// The environment (a constant or environment-map emitter), at
    /// infinity in `direction`.
    Environment {
        /// Unit direction from the scene towards the environment.
        direction: Vec3,
    },
    /// A directional light, at infinity in `direction`.
    Distant {
        /// Index into `Scene::emitters`.
        emitter: u32,
        /// Unit direction from the scene towards the light.
        direction: Vec3,
    },
}

/// A path vertex of a loaded scene: position, normals, texture
/// coordinates, the rounding-error bound of the position, and its site.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SceneVertex {
    /// Position.
    pub position: Vec3,
    /// Geometric normal (zero for points and environments).
    pub geometric_normal: Vec3,
    /// Shading normal.
    pub shading_normal: Vec3,
    /// Texture coordinates ((0, 0) on a sphere whose material reads none:
    /// [`Geometry::set_sphere_uvs_used`](crate::geometry::Geometry::set_sphere_uvs_used)).
    pub uv: Vec2,
    /// Absolute rounding-error bound per coordinate of `position`.
    pub error: Vec3,
    /// What it lies on.
    pub site: Site,
}

impl SceneVertex {
    /// The vertex of a ray hit on shape `shape`.
    #[must_use]
    pub fn from_hit(hit: &Hit, shape: u32) -> Self {
        SceneVertex {
            position: hit.position,
            geometric_normal: hit.geometric_normal,
            shading_normal: hit.shading_normal,
            uv: hit.uv,
            error: hit.error,
            site: Site::Surface {
                shape,
                primitive: hit.primitive,
            },
        }
    }

    /// An isolated point (a pinhole, a point light).
    #[must_use]
    pub fn point(position: Vec3, emitter: Option<u32>) -> Self {
        SceneVertex {
            position,
            geometric_normal: Vec3::ZERO,
            shading_normal: Vec3::ZERO,
            uv: Vec2::ZERO,
            error: Vec3::ZERO,
            site: Site::Point { emitter },
        }
    }

    /// The vertex at infinity in `direction` (unit, from the scene), on the
    /// environment.
    #[must_use]
    pub fn environment(direction: Vec3) -> Self {
        SceneVertex {
            site: Site::Environment { direction },
            ..SceneVertex::point(Vec3::ZERO, None)
        }
    }

    /// The vertex at infinity of directional light `emitter`.
    #[must_use]
    pub fn distant(emitter: u32, direction: Vec3) -> Self {
        SceneVertex {
            site: Site::Distant { emitter, direction },
            ..SceneVertex::point(Vec3::ZERO, None)
        }
    }

    /// A point on a thin lens whose optical axis is `axis`.
    #[must_use]
    pub fn lens(position: Vec3, axis: Vec3) -> Self {
        SceneVertex {
            geometric_normal: axis,
            shading_normal: axis,
            site: Site::Lens,
            ..SceneVertex::point(position, None)
        }
    }

    /// The vertex at `position` sampled on triangle `triangle` of mesh `mesh`.
    #[must_use]
    pub fn on_triangle(scene: &Scene, mesh: u32, triangle: u32, position: Vec3) -> Self {
        let hit = scene.geometry.point_on_triangle(mesh, triangle, position);
        SceneVertex::from_hit(&hit, scene.shape_of(hit.primitive))
    }

    /// As [`on_triangle`](Self::on_triangle), for the point of barycentrics
    /// `b` (as it was sampled), given the triangle's corners and unit normal.
    #[must_use]
    pub fn at_barycentrics(
        scene: &Scene,
        (mesh, triangle): (u32, u32),
        shape: ([Vec3; 3], Vec3),
        b: [f32; 3],
    ) -> Self {
        let hit = scene.geometry.point_at(mesh, triangle, shape, b);
        SceneVertex::from_hit(&hit, scene.shape_of(hit.primitive))
    }

    /// The vertex at `position` sampled on sphere `sphere` of the geometry.
    #[must_use]
    pub fn on_sphere(scene: &Scene, sphere: u32, position: Vec3) -> Self {
        let center = scene.geometry.spheres()[sphere as usize].center;
        let hit = scene.geometry.point_on_sphere(sphere, position - center);
        SceneVertex::from_hit(&hit, scene.shape_of(hit.primitive))
    }

    /// The unit direction from this vertex towards `other` (for a vertex at
    /// infinity, its direction), or `None` if they coincide.
    #[must_use]
    pub fn direction_to(&self, other: &SceneVertex) -> Option<Vec3> {
        // By reference, one site at a time: matching the pair of sites by
        // value copied both at every call (1.4 % of a path tracer's
        // instructions), and most calls join two surface points.
        if let Site::Environment { direction } | Site::Distant { direction, .. } = &other.site {
            return Some(*direction);
        }
        if let Site::Environment { direction } | Site::Distant { direction, .. } = &self.site {
            return Some(-*direction);
        }
        unit(other.position - self.position)
    }

    /// The unit directions from this vertex to `other` and back: what
    /// `self.direction_to(other)` and `other.direction_to(self)` give, with
    /// one square root and division where both are points (the way back
    /// is then the negated way there, to the bit: a − b is −(b − a)
    /// exactly, and so is every step of the normalization).
    #[must_use]
    #[inline(always)]
    pub fn directions_between(&self, other: &SceneVertex) -> Option<(Vec3, Vec3)> {
        if self.is_at_infinity() || other.is_at_infinity() {
            return self.direction_to(other).zip(other.direction_to(self));
        }
        let d = unit(other.position - self.position)?;
        Some((d, -d))
    }

    /// True if the vertex lies at infinity.
    #[must_use]
    pub fn is_at_infinity(&self) -> bool {
        matches!(self.site, Site::Environment { .. } | Site::Distant { .. })
    }

    /// The index of the shape the vertex lies on.
    #[must_use]
    pub fn shape(&self) -> Option<usize> {
        match self.site {
            Site::Surface { shape, .. } => Some(shape as usize),
            _ => None,
        }
    }
}

impl Recycle for SceneVertex {
    type Static = Self;
}

impl Vertex for SceneVertex {
    fn position(&self) -> Vec3 {
        self.position
    }
    fn geometry(&self) -> Place {
        match self.site {
            Site::Surface { .. } => Place::Surface {
                normal: self.geometric_normal,
            },
            Site::Lens => Place::Surface {
                normal: self.geometric_normal,
            },
            Site::Point { .. } => Place::Point,
            Site::Environment { direction } | Site::Distant { direction, .. } => {
                Place::AtInfinity { direction }
            }
        }
    }
}

impl Scene {
    /// The index in [`Scene::shapes`] of the shape a hit lies on.
    #[must_use]
    pub fn shape_of(&self, primitive: Primitive) -> u32 {
        match primitive {
            Primitive::Triangle { mesh, .. } => mesh,
            Primitive::Sphere(s) => self.geometry.meshes().len() as u32 + s,
        }
    }
}

/// Rays leave surface vertices offset past their rounding error, and
/// isolated points from the point itself. A ray that escapes meets the
/// environment if the scene has one.
impl RayCaster<SceneVertex> for Scene {
    fn origin(&self, from: &SceneVertex, toward: Vec3) -> Vec3 {
        match from.site {
            Site::Surface { .. } => {
                offset_origin(from.position, from.error, from.geometric_normal, toward)
            }
            _ => from.position,
        }
    }

    fn cast(&self, from: &SceneVertex, direction: Vec3) -> Option<SceneVertex> {
        self.cast_from(from, direction).1
    }

    #[inline(always)]
    fn cast_from(&self, from: &SceneVertex, direction: Vec3) -> (Vec3, Option<SceneVertex>) {
        let origin = self.origin(from, direction);
        (origin, self.cast_at(origin, from, direction))
    }

    /// The default's fixed point, found from the side of the surface each
    /// candidate origin sees the target on: [`offset_origin`] reads the
    /// direction only through that side, so an origin on the side it was
    /// offset to is the fixed point, without computing it again and
    /// comparing (every density of BSDF sampling asks this). The same
    /// vectors, the same `None`s (a test compares the two).
    fn origin_reaching(&self, from: &SceneVertex, target: &SceneVertex) -> Option<Vec3> {
        let Site::Surface { .. } = from.site else {
            let p = from.position;
            return (!p.is_nan()).then_some(p);
        };
        let (p, n, error) = (from.position, from.geometric_normal, from.error);
        let toward = |o: Vec3| match target.site {
            Site::Environment { direction } | Site::Distant { direction, .. } => direction,
            _ => target.position - o,
        };
        let below = |dir: Vec3| n.dot(dir) < 0.0;
        let to_first = toward(p);
        let first = offset_origin(p, error, n, to_first);
        let to_second = toward(first);
        // The target on the side the origin was offset to: the second
        // origin would be the first again, bit for bit.
        if below(to_second) == below(to_first) {
            return (!first.is_nan()).then_some(first);
        }
        // The sides differ, so the offset moved the origin: the second
        // origin differs from the first (the default's test that they are
        // equal cannot pass here). A third is the second if it sees the
        // target on the same side, else the first again: no fixed point.
        let second = offset_origin(p, error, n, to_second);
        (below(toward(second)) == below(to_second) && !second.is_nan()).then_some(second)
    }
}

/// The aperture of a thin-lens camera: a disk facing along the view.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aperture {
    /// Centre.
    pub center: Vec3,
    /// Unit viewing direction, the disk's normal.
    pub axis: Vec3,
    /// Radius.
    pub radius: f32,
}

impl Aperture {
    /// Where the ray from `origin` along `direction` crosses the disk
    /// strictly between 0 and `far`, if it does.
    #[must_use]
    pub fn crossing(&self, origin: Vec3, direction: Vec3, far: f32) -> Option<Vec3> {
        let along = direction.dot(self.axis);
        let t = (self.center - origin).dot(self.axis) / along;
        let p = origin + t * direction;
        let inside = (p - self.center).length_squared() <= self.radius * self.radius;
        (along != 0.0 && t > 0.0 && t < far && inside).then_some(p)
    }
}

impl Scene {
    /// The first vertex a ray from `origin` (the offset position of
    /// `from`) meets along `direction`.
    #[inline(always)]
    fn cast_at(&self, origin: Vec3, from: &SceneVertex, direction: Vec3) -> Option<SceneVertex> {
        let hit = self.geometry.intersect(origin, direction, f32::INFINITY);
        // A thin lens's aperture is a surface: light paths reach the camera
        // on it, and it stops what crosses it (rays leaving it cannot).
        if let Some(a) = self.aperture().filter(|_| from.site != Site::Lens) {
            let far = hit
                .as_ref()
                .map_or(f32::INFINITY, |h| (h.position - origin).length());
            if let Some(p) = a.crossing(origin, direction, far) {
                return Some(SceneVertex::lens(p, a.axis));
            }
        }
        match hit {
            Some(hit) => Some(SceneVertex::from_hit(&hit, self.shape_of(hit.primitive))),
            None => self
                .has_environment()
                .then(|| SceneVertex::environment(direction)),
        }
    }

    /// The camera's aperture, if it is a thin lens.
    #[must_use]
    pub fn aperture(&self) -> Option<Aperture> {
        let c = &self.camera;
        (c.aperture_radius > 0.0).then(|| Aperture {
            center: c.to_world.transform_point3(Vec3::ZERO),
            axis: crate::camera::frame_of(c.to_world).n,
            radius: c.aperture_radius,
        })
    }

    /// True if the scene has a constant or environment-map emitter.
    #[must_use]
    pub fn has_environment(&self) -> bool {
        self.emitters.iter().any(|e| {
            matches!(
                e,
                crate::scene::Emitter::Constant { .. } | crate::scene::Emitter::EnvMap { .. }
            )
        })
    }
}
