//! Ray casting: a compressed wide BVH (obvhs) over every triangle, analytic
//! spheres beside it, a watertight triangle test, and ray origins offset by
//! the rounding error of the hit point (no fixed epsilon).

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use glam::{DVec3, Vec2, Vec3, Vec3A, Vec3Swizzles};
use obvhs::BvhBuildParams;
use obvhs::cwbvh::CwBvh;
use obvhs::cwbvh::builder::build_cwbvh_from_tris;
use obvhs::ray::{Ray, RayHit};
use obvhs::triangle::Triangle;

use crate::mesh::{TriangleMesh, TrianglePlane, triangle_normal};

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
    /// Texture coordinates (barycentric if the mesh has none).
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
    /// Triangles in BVH order (a large one split by the build appears once
    /// per piece), their unit normals (found once, not at every hit), and
    /// where each came from.
    triangles: Vec<[Vec3; 3]>,
    normals: Vec<Vec3>,
    origins: Vec<(u32, u32)>,
    bvh: Option<CwBvh>,
}

/// Scenes up to this many triangles get obvhs's slowest, best BVH build.
const BEST_BUILD_LIMIT: usize = 1 << 20;

/// How the BVH of `triangles` triangles is built. The slowest build
/// (large triangles split into several boxes, every node considered for
/// reinsertion) casts the Cornell box's rays with 4.5 % fewer instructions
/// per path-traced sample than obvhs's medium build, whose trees overlap
/// more, but takes about three times as long: 3 s instead of 1 s for a
/// million triangles on two cores. Larger scenes keep the medium build, so
/// that a big scene starts rendering in seconds.
fn build_params(triangles: usize) -> BvhBuildParams {
    if triangles <= BEST_BUILD_LIMIT {
        BvhBuildParams::very_slow_build()
    } else {
        BvhBuildParams::medium_build()
    }
}

/// An obvhs ray. Negative zeros in the direction become positive: obvhs
/// takes the sign of a slab from `direction < 0` but its inverse from the
/// sign bit, and the two disagree on −0, which misses every box.
fn bvh_ray(origin: Vec3, dir: Vec3, t_max: f32) -> Ray {
    Ray::new(origin.into(), (dir + Vec3::ZERO).into(), 0.0, t_max)
}

/// The per-ray setup of the watertight test (Woop, Benthin and Wald 2013).
struct Shear {
    origin: Vec3,
    /// Which of the six axis orders (kx, ky, kz) the ray uses: kz the
    /// dominant axis of the direction, kx and ky swapped where it is negative.
    order: u8,
    s: Vec3,
}

impl Shear {
    fn new(origin: Vec3, dir: Vec3) -> Self {
        let a = dir.abs();
        let kz = if a.x > a.y {
            if a.x > a.z { 0 } else { 2 }
        } else if a.y > a.z {
            1
        } else {
            2
        };
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        let flip = dir[kz] < 0.0;
        if flip {
            std::mem::swap(&mut kx, &mut ky);
        }
        Shear {
            origin,
            order: 2 * kz as u8 + u8::from(flip),
            s: Vec3::new(dir[kx] / dir[kz], dir[ky] / dir[kz], 1.0 / dir[kz]),
        }
    }

    /// (p[kx], p[ky], p[kz]) by swizzles: indexing a vector by a variable
    /// costs more than the rest of the test.
    #[inline]
    fn permute(&self, p: Vec3) -> Vec3 {
        match self.order {
            0 => p.yzx(),
            1 => p.zyx(),
            2 => p.zxy(),
            3 => p.xzy(),
            4 => p,
            _ => p.yxz(),
        }
    }

    /// Distance and edge functions of the hit, if any, in (t_min, t_max).
    #[inline]
    fn intersect(&self, v: &[Vec3; 3], t_min: f32, t_max: f32) -> Option<(f32, Edges)> {
        let rel = v.map(|p| self.permute(p - self.origin));
        let xy = rel.map(|p| (p.x - self.s.x * p.z, p.y - self.s.y * p.z));
        let (a, b, c) = (xy[0], xy[1], xy[2]);
        let mut u = c.0 * b.1 - c.1 * b.0;
        let mut w2 = a.0 * c.1 - a.1 * c.0;
        let mut w = b.0 * a.1 - b.1 * a.0;
        if u == 0.0 || w2 == 0.0 || w == 0.0 {
            // Edges through the ray: decide in double precision.
            let d = xy.map(|(x, y)| (f64::from(x), f64::from(y)));
            u = (d[2].0 * d[1].1 - d[2].1 * d[1].0) as f32;
            w2 = (d[0].0 * d[2].1 - d[0].1 * d[2].0) as f32;
            w = (d[1].0 * d[0].1 - d[1].1 * d[0].0) as f32;
        }
        if (u < 0.0 || w2 < 0.0 || w < 0.0) && (u > 0.0 || w2 > 0.0 || w > 0.0) {
            return None;
        }
        let det = u + w2 + w;
        if det == 0.0 {
            return None;
        }
        let z = rel.map(|p| self.s.z * p.z);
        let t_scaled = u * z[0] + w2 * z[1] + w * z[2];
        let t = t_scaled / det;
        (t > t_min && t < t_max).then_some((t, Edges([u, w2, w], det)))
    }
}

/// The three edge functions of a hit and their sum: barycentrics once
/// divided, which only the closest hit of a ray needs (a closest-hit ray
/// meets several candidates; each still divides once for its distance,
/// and the three divisions here wait for the one kept).
#[derive(Clone, Copy)]
struct Edges([f32; 3], f32);

impl Edges {
    fn barycentrics(self) -> [f32; 3] {
        let Edges([u, w2, w], det) = self;
        [u / det, w2 / det, w / det]
    }
}

impl Geometry {
    /// Builds the BVH over the triangles of `meshes` (already in world space).
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
        let (triangles, origins, bvh) = if flat.is_empty() {
            (Vec::<[Vec3; 3]>::new(), Vec::new(), None)
        } else {
            let tris: Vec<Triangle> = flat
                .iter()
                .map(|[a, b, c]| Triangle {
                    v0: Vec3A::from(*a),
                    v1: Vec3A::from(*b),
                    v2: Vec3A::from(*c),
                })
                .collect();
            let bvh =
                build_cwbvh_from_tris(&tris, build_params(tris.len()), &mut Duration::default());
            let order = &bvh.primitive_indices;
            let triangles = order.iter().map(|&i| flat[i as usize]).collect();
            let origins = order.iter().map(|&i| from[i as usize]).collect();
            (triangles, origins, Some(bvh))
        };
        let normals = triangles.iter().map(|c| triangle_normal(*c)).collect();
        Geometry {
            meshes,
            spheres,
            triangles,
            normals,
            origins,
            bvh,
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
        let shear = Shear::new(origin, dir);
        let mut best: Option<(f32, usize, [f32; 3])> = None;
        if let Some(bvh) = &self.bvh {
            let ray = bvh_ray(origin, dir, t_max);
            let mut hit = RayHit::none();
            let mut edges = Edges([0.0; 3], 1.0);
            bvh.ray_traverse(ray, &mut hit, |r, id| {
                match shear.intersect(&self.triangles[id], 0.0, r.tmax) {
                    Some((t, e)) => {
                        edges = e;
                        t
                    }
                    None => f32::INFINITY,
                }
            });
            if hit.t < t_max {
                best = Some((hit.t, hit.primitive_id as usize, edges.barycentrics()));
            }
        }
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

    /// True if anything lies on the ray from `origin` along unit `dir` with
    /// t ∈ (0, `t_max`). Stops at the first hit found.
    #[must_use]
    pub fn occluded(&self, origin: Vec3, dir: Vec3, t_max: f32) -> bool {
        let _timer = RayTimer::start();
        if self
            .spheres
            .iter()
            .any(|s| intersect_sphere(s, origin, dir, 0.0, t_max).is_some())
        {
            return true;
        }
        let Some(bvh) = &self.bvh else { return false };
        let shear = Shear::new(origin, dir);
        let ray = bvh_ray(origin, dir, t_max);
        !bvh.ray_traverse_miss(ray, |r, id| {
            shear
                .intersect(&self.triangles[id], 0.0, r.tmax)
                .map_or(f32::INFINITY, |h| h.0)
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
        if dist == 0.0 || !dist.is_finite() {
            return true;
        }
        !self.occluded(oa, d / dist, dist * (1.0 - 1e-4))
    }

    fn triangle_hit(&self, id: usize, t: f32, b: [f32; 3]) -> Hit {
        let (m, tri) = self.origins[id];
        self.on_triangle(m, tri, (self.triangles[id], self.normals[id]), t, b)
    }

    /// The surface point of triangle `triangle` of mesh `mesh` nearest to
    /// `position` (a point sampled on it), with its normals, uv and error.
    #[must_use]
    pub fn point_on_triangle(&self, mesh: u32, triangle: u32, position: Vec3) -> Hit {
        let corners = self.meshes[mesh as usize].corners(triangle as usize);
        self.point_on_plane(mesh, triangle, &TrianglePlane::new(corners), position)
    }

    /// As [`point_on_triangle`](Self::point_on_triangle), with the
    /// triangle's plane solved beforehand (a light's triangles, sampled at
    /// every vertex of every path).
    #[must_use]
    pub fn point_on_plane(
        &self,
        mesh: u32,
        triangle: u32,
        plane: &TrianglePlane,
        position: Vec3,
    ) -> Hit {
        let shape = (plane.corners(), plane.normal());
        self.on_triangle(mesh, triangle, shape, 0.0, plane.barycentrics(position))
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
            (b[0] * n[0] + b[1] * n[1] + b[2] * n[2])
                .try_normalize()
                .unwrap_or(geometric_normal)
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
        let phi = raw.y.atan2(raw.x).rem_euclid(std::f64::consts::TAU);
        let uv = Vec2::new(
            (phi / std::f64::consts::TAU) as f32,
            (raw.z.clamp(-1.0, 1.0).acos() / std::f64::consts::PI) as f32,
        );
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
