//! Ray casting: a compressed wide BVH (obvhs, built in `bvh`, its nodes
//! decoded for traversal in `wide`) over every triangle, analytic spheres
//! beside it (a few) or in it (more), the watertight triangle test, and
//! ray origins offset by the rounding error of the hit point (no fixed
//! epsilon).

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use glam::{DVec3, Vec2, Vec3};
use obvhs::ray::{Ray, RayHit};

use crate::mesh::{TriangleMesh, TrianglePlane, triangle_normal};
use crate::watertight::{Edges, Shear, Shear4};
use crate::wide::{Tree, with_tree};

/// An analytic sphere.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere {
    /// Centre.
    pub center: Vec3,
    /// Radius (positive).
    pub radius: f32,
}

/// What a ray hit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Primitive {
    /// Triangle `triangle` of mesh `mesh`.
    Triangle {
        /// Index of the mesh.
        mesh: u32,
        /// Index of the triangle in the mesh.
        triangle: u32,
    },
    /// Sphere `0`.
    Sphere(u32),
}

/// A ray's closest hit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Distance along the (unit) ray direction.
    pub t: f32,
    /// The hit point, reconstructed on the surface.
    pub position: Vec3,
    /// A bound on the absolute rounding error of each coordinate of `position`.
    pub error: Vec3,
    /// The unit geometric normal (by the triangle's winding, or outwards).
    pub geometric_normal: Vec3,
    /// The unit shading normal (interpolated, or the geometric normal).
    pub shading_normal: Vec3,
    /// Texture coordinates (barycentric if the mesh has none; (0, 0) on a
    /// sphere whose material reads none: [`Geometry::set_sphere_uvs_used`]).
    pub uv: Vec2,
    /// What was hit.
    pub primitive: Primitive,
}

/// γ(n) of floating-point error analysis (Higham), for f32.
fn gamma(n: f32) -> f32 {
    let e = f32::EPSILON * 0.5;
    n * e / (1.0 - n * e)
}

thread_local! {
    static RAYS: std::cell::Cell<u64> = const { std::cell::Cell::new(0) };
    static RAY_NANOS: std::cell::Cell<u64> = const { std::cell::Cell::new(0) };
}

/// Whether rays are timed ([`time_rays`]).
static TIMING: AtomicBool = AtomicBool::new(false);

fn count_ray() {
    RAYS.with(|r| r.set(r.get() + 1));
}

/// Times one ray while it lives, if timing is on.
struct RayTimer(Option<Instant>);

impl RayTimer {
    fn start() -> Self {
        count_ray();
        RayTimer(TIMING.load(Ordering::Relaxed).then(Instant::now))
    }
}

impl Drop for RayTimer {
    fn drop(&mut self) {
        if let Some(start) = self.0 {
            let nanos = start.elapsed().as_nanos() as u64;
            RAY_NANOS.with(|t| t.set(t.get() + nanos));
        }
    }
}

/// Turns the timing of every ray cast on or off (off by default: reading
/// the clock twice per ray costs a few percent). Benchmarks turn it on to
/// measure the share of time spent in ray casting.
pub fn time_rays(on: bool) {
    TIMING.store(on, Ordering::Relaxed);
}

/// Nanoseconds this thread has spent casting rays while timing was on.
#[must_use]
pub fn ray_nanos() -> u64 {
    RAY_NANOS.with(std::cell::Cell::get)
}

/// The number of rays (closest-hit and shadow) this thread has cast so far:
/// the render loop reads it before and after a tile to report rays per second.
#[must_use]
pub fn rays_cast() -> u64 {
    RAYS.with(std::cell::Cell::get)
}

/// True if `x` is finite: `x − x` is zero exactly for finite `x`. Two
/// float instructions, where `x.is_finite()` followed by a comparison
/// compiled to tests of the bits with branches.
#[must_use]
#[inline(always)]
#[allow(clippy::eq_op)]
pub fn is_finite(x: f32) -> bool {
    x - x == 0.0
}

/// `v` scaled to unit length, or `None` if its length is zero, infinite
/// or NaN: glam's `try_normalize`, with its test of the reciprocal length
/// made of two float comparisons (every edge of every path is normalized).
#[inline(always)]
pub(crate) fn unit(v: Vec3) -> Option<Vec3> {
    let rcp = v.length_recip();
    (is_finite(rcp) && rcp > 0.0).then(|| v * rcp)
}

/// The origin of a ray leaving a surface point `p` (with error bound
/// `error` and normal `n`) in direction `dir`: `p` pushed along the normal,
/// to the side of `dir`, past its rounding error.
#[must_use]
pub fn offset_origin(p: Vec3, error: Vec3, n: Vec3, dir: Vec3) -> Vec3 {
    let d = n.abs().dot(error) * 2.0;
    let offset = if n.dot(dir) < 0.0 { -d * n } else { d * n };
    p + offset
}

/// The scene's geometry, ready for ray casting.
#[derive(Debug)]
pub struct Geometry {
    meshes: Vec<TriangleMesh>,
    spheres: Vec<Sphere>,
    /// The BVH's primitives in its order: triangles (a large one split by
    /// the build appears once per piece) with their unit normals (found
    /// once, not at every hit), and spheres, whose corners are NaN (a test
    /// the triangle test never passes) and normals zero; and where each
    /// came from: (mesh, triangle), or ([`SPHERE`], sphere).
    triangles: Vec<[Vec3; 3]>,
    normals: Vec<Vec3>,
    origins: Vec<(u32, u32)>,
    bvh: Option<Tree>,
    /// True if the spheres are few enough to be tested one by one beside
    /// the tree rather than in it.
    spheres_listed: bool,
    /// Per sphere, whether its hits need texture coordinates (an angle
    /// and an arc cosine in double precision per hit: 2 % of a path
    /// tracer's time on SmallVCM's box, whose spheres are untextured).
    sphere_uvs: Vec<bool>,
}

/// The mesh index of a sphere in [`Geometry`]'s BVH order.
const SPHERE: u32 = u32::MAX;

/// Up to this many spheres are tested one by one beside the tree: a
/// handful of sphere tests costs less than the check that tells a sphere
/// from a triangle at every candidate of every ray (on SmallVCM's box, with
/// two spheres, the tree with them took 0.7 % more instructions for BDPT,
/// and a scene without spheres 0.8 % more for path tracing, when every
/// tree carried the check).
const LISTED_SPHERES: usize = 8;

/// An obvhs ray. Negative zeros in the direction become positive: obvhs
/// takes the sign of a slab from `direction < 0` but its inverse from the
/// sign bit, and the two disagree on −0, which misses every box.
fn bvh_ray(origin: Vec3, dir: Vec3, t_max: f32) -> Ray {
    Ray::new(origin.into(), (dir + Vec3::ZERO).into(), 0.0, t_max)
}

impl Geometry {
    /// Builds the BVH over the triangles of `meshes` (already in world
    /// space) and the spheres.
    #[must_use]
    pub fn new(meshes: Vec<TriangleMesh>, spheres: Vec<Sphere>) -> Self {
        let mut flat = Vec::new();
        let mut from = Vec::new();
        for (m, mesh) in meshes.iter().enumerate() {
            for t in 0..mesh.triangles.len() {
                flat.push(mesh.corners(t));
                from.push((m as u32, t as u32));
            }
        }
        let spheres_listed = spheres.len() <= LISTED_SPHERES;
        let in_tree = if spheres_listed {
            &[][..]
        } else {
            &spheres[..]
        };
        let (bvh, order) = crate::bvh::build_binary(&flat, in_tree)
            .map(|b| Tree::build(&b, &flat, in_tree.len()))
            .unzip();
        let order = order.unwrap_or_default();
        let primitive = |i: u32| match flat.get(i as usize) {
            Some(&corners) => (corners, triangle_normal(corners), from[i as usize]),
            None => ([Vec3::NAN; 3], Vec3::ZERO, (SPHERE, i - flat.len() as u32)),
        };
        let (mut triangles, mut normals, mut origins) = (Vec::new(), Vec::new(), Vec::new());
        for &i in &order {
            let (corners, normal, origin) = primitive(i);
            triangles.push(corners);
            normals.push(normal);
            origins.push(origin);
        }
        Geometry {
            sphere_uvs: vec![true; spheres.len()],
            meshes,
            spheres,
            triangles,
            normals,
            origins,
            bvh,
            spheres_listed,
        }
    }

    /// Says which spheres' hits need texture coordinates (`used(i)` for
    /// sphere `i`): the others' hits carry (0, 0). All do until this is
    /// called. The caller promises that nothing reads the others' (the
    /// scene loader: their materials read none,
    /// [`Material::reads_uv`](crate::scene::Material::reads_uv)); whoever
    /// changes a loaded scene's materials or shapes calls it again.
    pub fn set_sphere_uvs_used(&mut self, used: impl Fn(usize) -> bool) {
        for (i, u) in self.sphere_uvs.iter_mut().enumerate() {
            *u = used(i);
        }
    }

    /// The meshes, in world space.
    #[must_use]
    pub fn meshes(&self) -> &[TriangleMesh] {
        &self.meshes
    }

    /// The spheres.
    #[must_use]
    pub fn spheres(&self) -> &[Sphere] {
        &self.spheres
    }

    /// Number of triangles (of the meshes: the BVH may hold a large
    /// triangle more than once, split into pieces).
    #[must_use]
    pub fn triangle_count(&self) -> usize {
        self.meshes.iter().map(|m| m.triangles.len()).sum()
    }

    /// The closest hit of the ray from `origin` along unit `dir` with
    /// t ∈ (0, `t_max`).
    #[must_use]
    pub fn intersect(&self, origin: Vec3, dir: Vec3, t_max: f32) -> Option<Hit> {
        let _timer = RayTimer::start();
        if !self.spheres_listed {
            return self.intersect_tree_with_spheres(origin, dir, t_max);
        }
        let best = self.bvh.as_ref().and_then(|bvh| {
            let exact = |shear: &Shear, id: usize, t_max: f32| {
                shear.intersect(&self.triangles[id], 0.0, t_max)
            };
            with_tree!(bvh, tree => {
                let shear = Shear::new(origin, dir);
                let mut hit = RayHit::none();
                let mut edges = Edges([0.0; 3], 1.0);
                tree.ray_traverse(bvh_ray(origin, dir, t_max), &mut hit, |r, id| {
                    match exact(&shear, id, r.tmax) {
                        Some((t, e)) => {
                            edges = e;
                            t
                        }
                        None => f32::INFINITY,
                    }
                });
                (hit.t < t_max).then_some((hit.t, hit.primitive_id as usize, edges))
            }, quad => {
                // The scalar setup only for the rare leaf that needs it.
                let exact = |id, t_max| exact(&Shear::new(origin, dir), id, t_max);
                quad.closest(&Shear4::new(origin, dir), (origin, dir), t_max, exact)
            })
            .map(|(t, id, edges)| (t, id, edges.barycentrics()))
        });
        let mut sphere_hit = None;
        let limit = best.map_or(t_max, |b| b.0);
        for (i, s) in self.spheres.iter().enumerate() {
            if let Some(t) =
                intersect_sphere(s, origin, dir, 0.0, sphere_hit.map_or(limit, |(t, _)| t))
            {
                sphere_hit = Some((t, i));
            }
        }
        if let Some((t, i)) = sphere_hit {
            return Some(self.sphere_hit(i, origin, dir, t));
        }
        best.map(|(t, id, bary)| self.triangle_hit(id, t, bary))
    }

    /// As [`intersect`](Self::intersect) when the spheres are in the tree
    /// (NaN corners mark them among the triangles). Kept apart so that the
    /// usual case, few or no spheres, runs the triangle test without the
    /// check at every candidate (and out of line, so that it does not
    /// change how that case compiles).
    #[inline(never)]
    fn intersect_tree_with_spheres(&self, origin: Vec3, dir: Vec3, t_max: f32) -> Option<Hit> {
        let bvh = self.bvh.as_ref()?;
        let shear = Shear::new(origin, dir);
        let mut hit = RayHit::none();
        let mut edges = Edges([0.0; 3], 1.0);
        let ray = bvh_ray(origin, dir, t_max);
        // (Trees with spheres are never four-wide.)
        with_tree!(bvh, tree => tree.ray_traverse(ray, &mut hit, |r, id| {
            match self.tree_candidate(&shear, id, (origin, dir), r.tmax) {
                Some((t, e)) => {
                    edges = e.unwrap_or(edges);
                    t
                }
                None => f32::INFINITY,
            }
        }), _quad => {
            debug_assert!(false, "a tree with spheres is never four-wide");
            false
        });
        if hit.t >= t_max {
            return None;
        }
        let id = hit.primitive_id as usize;
        Some(match self.origins[id] {
            (SPHERE, k) => self.sphere_hit(k as usize, origin, dir, hit.t),
            _ => self.triangle_hit(id, hit.t, edges.barycentrics()),
        })
    }

    /// Where the ray (`shear` set up for it) meets the primitive at BVH
    /// position `id` of a tree that holds spheres, if before `t_max`: the
    /// distance, and a triangle's edge functions.
    #[inline(always)]
    fn tree_candidate(
        &self,
        shear: &Shear,
        id: usize,
        (origin, dir): (Vec3, Vec3),
        t_max: f32,
    ) -> Option<(f32, Option<Edges>)> {
        let corners = &self.triangles[id];
        if !corners[0].x.is_nan() {
            return shear
                .intersect(corners, 0.0, t_max)
                .map(|(t, e)| (t, Some(e)));
        }
        match self.origins[id] {
            (SPHERE, k) => intersect_sphere(&self.spheres[k as usize], origin, dir, 0.0, t_max)
                .map(|t| (t, None)),
            _ => None,
        }
    }

    /// True if anything lies on the ray from `origin` along unit `dir` with
    /// t ∈ (0, `t_max`). Stops at the first hit found.
    #[must_use]
    pub fn occluded(&self, origin: Vec3, dir: Vec3, t_max: f32) -> bool {
        let _timer = RayTimer::start();
        if !self.spheres_listed {
            return self.tree_with_spheres_blocks(origin, dir, t_max);
        }
        if self
            .spheres
            .iter()
            .any(|s| intersect_sphere(s, origin, dir, 0.0, t_max).is_some())
        {
            return true;
        }
        let Some(bvh) = &self.bvh else { return false };
        let exact = |shear: &Shear, id: usize, t_max: f32| {
            shear
                .intersect(&self.triangles[id], 0.0, t_max)
                .map_or(f32::INFINITY, |h| h.0)
        };
        with_tree!(bvh, tree => {
            let shear = Shear::new(origin, dir);
            !tree.ray_traverse_miss(bvh_ray(origin, dir, t_max), |r, id| exact(&shear, id, r.tmax))
        }, quad => {
            let exact = |id, t_max| exact(&Shear::new(origin, dir), id, t_max) < t_max;
            quad.blocked(&Shear4::new(origin, dir), (origin, dir), t_max, exact)
        })
    }

    /// As [`occluded`](Self::occluded) when the spheres are in the tree.
    #[inline(never)]
    fn tree_with_spheres_blocks(&self, origin: Vec3, dir: Vec3, t_max: f32) -> bool {
        let Some(bvh) = &self.bvh else { return false };
        let shear = Shear::new(origin, dir);
        let ray = bvh_ray(origin, dir, t_max);
        // (Trees with spheres are never four-wide.)
        !with_tree!(bvh, tree => tree.ray_traverse_miss(ray, |r, id| {
            self.tree_candidate(&shear, id, (origin, dir), r.tmax)
                .map_or(f32::INFINITY, |h| h.0)
        }), _quad => {
            debug_assert!(false, "a tree with spheres is never four-wide");
            true
        })
    }

    /// True if the segment between two surface points is unobstructed;
    /// both ends are offset past their rounding error.
    #[must_use]
    pub fn visible(&self, a: (Vec3, Vec3, Vec3), b: (Vec3, Vec3, Vec3)) -> bool {
        let (pa, ea, na) = a;
        let (pb, eb, nb) = b;
        let oa = offset_origin(pa, ea, na, pb - pa);
        let ob = offset_origin(pb, eb, nb, pa - pb);
        let d = ob - oa;
        let dist = d.length();
        if dist == 0.0 || !is_finite(dist) {
            return true;
        }
        !self.occluded(oa, d / dist, dist * (1.0 - 1e-4))
    }

    // Inline, so that the closest hit is written where the caller wants
    // it: returned from a call, it was copied out of the callee's record in
    // wide loads over narrow stores, which the processor cannot forward
    // (4 % of the ray cast's time sat on that copy).
    #[inline(always)]
    fn triangle_hit(&self, id: usize, t: f32, b: [f32; 3]) -> Hit {
        let (m, tri) = self.origins[id];
        self.on_triangle(m, tri, (self.triangles[id], self.normals[id]), t, b)
    }

    /// The surface point of triangle `triangle` of mesh `mesh` nearest to
    /// `position` (a point sampled on it), with its normals, uv and error.
    #[must_use]
    pub fn point_on_triangle(&self, mesh: u32, triangle: u32, position: Vec3) -> Hit {
        let plane = TrianglePlane::new(self.meshes[mesh as usize].corners(triangle as usize));
        let shape = (plane.corners(), plane.normal());
        self.point_at(mesh, triangle, shape, plane.barycentrics(position))
    }

    /// As [`point_on_triangle`](Self::point_on_triangle), for the point
    /// of barycentrics `b` (sampled with them: a light's triangles, at
    /// every vertex of every path), given the triangle's corners and unit
    /// normal (found once per light).
    #[must_use]
    pub fn point_at(&self, mesh: u32, triangle: u32, shape: ([Vec3; 3], Vec3), b: [f32; 3]) -> Hit {
        self.on_triangle(mesh, triangle, shape, 0.0, b)
    }

    /// The surface point of sphere `sphere` in `direction` from its centre.
    #[must_use]
    pub fn point_on_sphere(&self, sphere: u32, direction: Vec3) -> Hit {
        let s = self.spheres[sphere as usize];
        self.sphere_hit(sphere as usize, s.center, direction.normalize(), s.radius)
    }

    /// The surface point of barycentrics `b` on triangle `tri` of mesh `m`,
    /// given its corners and unit normal.
    fn on_triangle(&self, m: u32, tri: u32, shape: ([Vec3; 3], Vec3), t: f32, b: [f32; 3]) -> Hit {
        let mesh = &self.meshes[m as usize];
        let idx = mesh.triangles[tri as usize];
        let ([p0, p1, p2], geometric_normal) = shape;
        let position = b[0] * p0 + b[1] * p1 + b[2] * p2;
        let error = gamma(7.0) * ((b[0] * p0).abs() + (b[1] * p1).abs() + (b[2] * p2).abs());
        let shading_normal = if mesh.normals.is_empty() {
            geometric_normal
        } else {
            let n = idx.map(|k| mesh.normals[k as usize]);
            unit(b[0] * n[0] + b[1] * n[1] + b[2] * n[2]).unwrap_or(geometric_normal)
        };
        let uv = if mesh.uvs.is_empty() {
            Vec2::new(b[1], b[2])
        } else {
            let uv = idx.map(|k| mesh.uvs[k as usize]);
            b[0] * uv[0] + b[1] * uv[1] + b[2] * uv[2]
        };
        Hit {
            t,
            position,
            error,
            geometric_normal,
            shading_normal,
            uv,
            primitive: Primitive::Triangle {
                mesh: m,
                triangle: tri,
            },
        }
    }

    fn sphere_hit(&self, i: usize, origin: Vec3, dir: Vec3, t: f32) -> Hit {
        let s = self.spheres[i];
        // Reproject onto the sphere so that the error bound is small and known.
        let raw =
            (origin.as_dvec3() + f64::from(t) * dir.as_dvec3() - s.center.as_dvec3()).normalize();
        let position = (s.center.as_dvec3() + f64::from(s.radius) * raw).as_vec3();
        let error = gamma(5.0) * position.abs();
        let n = raw.as_vec3();
        let uv = if self.sphere_uvs[i] {
            let phi = raw.y.atan2(raw.x).rem_euclid(std::f64::consts::TAU);
            Vec2::new(
                (phi / std::f64::consts::TAU) as f32,
                (raw.z.clamp(-1.0, 1.0).acos() / std::f64::consts::PI) as f32,
            )
        } else {
            Vec2::ZERO
        };
        Hit {
            t,
            position,
            error,
            geometric_normal: n,
            shading_normal: n,
            uv,
            primitive: Primitive::Sphere(i as u32),
        }
    }
}

/// The nearest t ∈ (t_min, t_max) at which the ray meets the sphere, in
/// double precision, with the discriminant taken from the perpendicular
/// distance (no cancellation for distant spheres).
fn intersect_sphere(s: &Sphere, origin: Vec3, dir: Vec3, t_min: f32, t_max: f32) -> Option<f32> {
    let oc: DVec3 = origin.as_dvec3() - s.center.as_dvec3();
    let d = dir.as_dvec3();
    let b = oc.dot(d);
    let r = f64::from(s.radius);
    let perp = oc - b * d;
    let disc = r * r - perp.length_squared();
    if disc < 0.0 {
        return None;
    }
    let q = disc.sqrt();
    [-b - q, -b + q]
        .into_iter()
        .map(|t| t as f32)
        .find(|&t| t > t_min && t < t_max)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quad() -> TriangleMesh {
        TriangleMesh::rectangle()
    }

    #[test]
    fn hits_and_misses() {
        let g = Geometry::new(
            vec![quad()],
            vec![Sphere {
                center: Vec3::new(0.0, 0.0, 3.0),
                radius: 0.5,
            }],
        );
        let h = g
            .intersect(Vec3::new(0.2, 0.3, 1.0), -Vec3::Z, f32::INFINITY)
            .unwrap();
        assert!((h.t - 1.0).abs() < 1e-6 && h.geometric_normal == Vec3::Z);
        assert!(
            g.intersect(Vec3::new(2.0, 0.0, 1.0), -Vec3::Z, f32::INFINITY)
                .is_none()
        );
        let s = g
            .intersect(Vec3::new(0.0, 0.0, 1.0), Vec3::Z, f32::INFINITY)
            .unwrap();
        assert_eq!(s.primitive, Primitive::Sphere(0));
        assert!((s.t - 1.5).abs() < 1e-5);
        assert!(g.occluded(Vec3::new(0.0, 0.0, 1.0), -Vec3::Z, 2.0));
        assert!(!g.occluded(Vec3::new(0.0, 0.0, 1.0), -Vec3::Z, 0.5));
    }

    #[test]
    fn spheres_in_the_tree_are_found_as_by_testing_them_all() {
        // A grid of spheres above a quad: every ray's closest hit and its
        // occlusion agree with a test of every primitive, sphere by sphere.
        let spheres: Vec<Sphere> = (0..64)
            .map(|i| Sphere {
                center: Vec3::new((i % 8) as f32 * 0.3 - 1.0, (i / 8) as f32 * 0.3 - 1.0, 0.5),
                radius: 0.05 + 0.01 * (i % 5) as f32,
            })
            .collect();
        let g = Geometry::new(vec![quad()], spheres.clone());
        let mut rng = aether_core::Pcg32::new(7, 1);
        let mut sphere_hits = 0;
        for _ in 0..4000 {
            let mut u = || aether_core::UniformSource::next_f32(&mut rng);
            let origin = Vec3::new(2.0 * u() - 1.0, 2.0 * u() - 1.0, 2.0);
            let dir = Vec3::new(0.6 * u() - 0.3, 0.6 * u() - 0.3, -1.0).normalize();
            let nearest_sphere = spheres
                .iter()
                .enumerate()
                .filter_map(|(k, s)| {
                    intersect_sphere(s, origin, dir, 0.0, f32::INFINITY).map(|t| (t, k))
                })
                .min_by(|a, b| a.0.total_cmp(&b.0));
            let hit = g.intersect(origin, dir, f32::INFINITY);
            match (nearest_sphere, hit) {
                (Some((t, k)), Some(h)) if h.t >= t => {
                    assert_eq!(h.primitive, Primitive::Sphere(k as u32));
                    assert_eq!(h.t, t);
                    sphere_hits += 1;
                }
                (_, Some(h)) => assert!(matches!(h.primitive, Primitive::Triangle { .. })),
                (None, None) => {}
                (Some(_), None) => panic!("a sphere the tree missed from {origin} along {dir}"),
            }
            let limit = hit.map_or(10.0, |h| h.t);
            assert!(g.occluded(origin, dir, limit * 1.001) == hit.is_some());
            assert!(!g.occluded(origin, dir, limit * 0.999));
        }
        assert!(sphere_hits > 200, "{sphere_hits} rays met a sphere");
    }

    #[test]
    fn watertight_on_the_shared_edge() {
        // Rays through the diagonal shared by both triangles never slip through.
        let g = Geometry::new(vec![quad()], vec![]);
        for i in 0..1000 {
            let x = -0.9 + 1.8 * i as f32 / 999.0;
            assert!(
                g.intersect(Vec3::new(x, x, 1.0), -Vec3::Z, f32::INFINITY)
                    .is_some(),
                "gap at {x}"
            );
        }
    }

    #[test]
    fn offset_origins_do_not_self_intersect_far_from_the_origin() {
        let mut far = quad();
        far.transform(
            glam::Mat4::from_translation(Vec3::splat(1.0e4))
                * glam::Mat4::from_scale(Vec3::splat(100.0)),
        );
        let g = Geometry::new(vec![far], vec![]);
        let mut rng = aether_core::Pcg32::new(1, 0);
        use aether_core::UniformSource;
        for _ in 0..10_000 {
            let (u, v) = (rng.next_f32() * 180.0 - 90.0, rng.next_f32() * 180.0 - 90.0);
            let h = g
                .intersect(
                    Vec3::new(1.0e4 + u, 1.0e4 + v, 1.0e4 + 50.0),
                    Vec3::new(0.01, 0.02, -1.0).normalize(),
                    f32::INFINITY,
                )
                .unwrap();
            let dir = Vec3::new(0.3 * rng.next_f32(), 0.2, 1.0).normalize();
            let o = offset_origin(h.position, h.error, h.geometric_normal, dir);
            assert!(
                g.intersect(o, dir, f32::INFINITY).is_none(),
                "self-intersection at {:?}",
                h.position
            );
        }
    }
}
