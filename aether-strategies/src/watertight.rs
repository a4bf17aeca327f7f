//! The watertight ray-triangle test (Woop, Benthin and Wald 2013): the
//! per-ray shear, set up once and applied to every candidate triangle of
//! the ray, and the edge functions of a hit, divided into barycentrics only
//! for the hit a ray keeps.

use glam::{BVec4A, Vec3, Vec3A, Vec4};

/// The per-ray setup of the watertight test (Woop, Benthin and Wald 2013).
pub(crate) struct Shear {
    origin: Vec3A,
    /// The columns of the map from a corner's offset d from the origin to
    /// its sheared coordinates (d[kx] − Sx d[kz], d[ky] − Sy d[kz],
    /// Sz d[kz]), with kz the dominant axis of the direction, kx and ky
    /// swapped where it is negative. Applied as a matrix, not by permuting
    /// each corner: a permutation chosen per ray was a jump through a
    /// table at every corner, mispredicted on each new ray. For finite
    /// corners the terms the matrix adds are exact zeros and the others the
    /// test's own products, so every decision and every distance are as
    /// before, and the edge functions too but for the sign of a zero (a
    /// corner coordinate of −0 on an axis the ray does not move along).
    /// Non-finite corners give no hit, as before.
    columns: [Vec3A; 3],
}

/// The axes kx, ky and kz of the test for a ray along `dir` (kz the
/// dominant one, kx and ky swapped where it is negative), and the shear
/// Sx, Sy, Sz.
#[inline(always)]
fn axes(dir: Vec3) -> ([usize; 3], Vec3) {
    let a = dir.abs();
    let kz = if a.x > a.y {
        if a.x > a.z { 0 } else { 2 }
    } else if a.y > a.z {
        1
    } else {
        2
    };
    let d = dir.to_array();
    let (mut kx, mut ky) = ((kz + 1) % 3, (kz + 2) % 3);
    if d[kz] < 0.0 {
        std::mem::swap(&mut kx, &mut ky);
    }
    // Indexing arrays, not vectors (whose index is a branch per axis).
    let s = Vec3::new(d[kx] / d[kz], d[ky] / d[kz], 1.0 / d[kz]);
    ([kx, ky, kz], s)
}

impl Shear {
    pub(crate) fn new(origin: Vec3, dir: Vec3) -> Self {
        let ([kx, ky, kz], s) = axes(dir);
        let mut columns = [Vec3A::ZERO; 3];
        columns[kx] = Vec3A::X;
        columns[ky] = Vec3A::Y;
        columns[kz] = Vec3A::new(-s.x, -s.y, s.z);
        Shear {
            origin: origin.into(),
            columns,
        }
    }

    /// Distance and edge functions of the hit, if any, in (t_min, t_max)
    /// and farther than its rounding error ([`error_bound`]).
    /// Always inlined: out of line (once four traversals called it), the
    /// call cost path tracing 1.2 % more instructions.
    #[inline(always)]
    pub(crate) fn intersect(&self, v: &[Vec3; 3], t_min: f32, t_max: f32) -> Option<(f32, Edges)> {
        let [cx, cy, cz] = self.columns;
        let rel = v.map(|p| {
            let d = Vec3A::from(p) - self.origin;
            cx * d.x + cy * d.y + cz * d.z
        });
        let xy = rel.map(|p| (p.x, p.y));
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
        let z = rel.map(|p| p.z);
        let t_scaled = u * z[0] + w2 * z[1] + w * z[2];
        let t = t_scaled / det;
        if !(t > t_min && t < t_max) {
            return None;
        }
        let largest = |c: [f32; 3]| c[0].abs().max(c[1].abs()).max(c[2].abs());
        let bound = error_bound(
            [
                largest(xy.map(|p| p.0)),
                largest(xy.map(|p| p.1)),
                largest(z),
            ],
            largest([u, w2, w]),
        );
        (t * det.abs() > bound).then_some((t, Edges([u, w2, w], det)))
    }
}

/// The per-ray setup of the watertight test on four triangles at once: the
/// axes, and the origin's coordinates on them and the shear, each spread
/// over four lanes.
pub(crate) struct Shear4 {
    axes: [usize; 3],
    origin: [Vec4; 3],
    shear: [Vec4; 3],
}

impl Shear4 {
    #[inline(always)]
    pub(crate) fn new(origin: Vec3, dir: Vec3) -> Self {
        let (axes, s) = axes(dir);
        let o = origin.to_array();
        Shear4 {
            axes,
            origin: axes.map(|k| Vec4::splat(o[k])),
            shear: s.to_array().map(Vec4::splat),
        }
    }

    /// The test of [`Shear::intersect`] on four triangles at once,
    /// `corners[vertex][axis]` holding one triangle per lane: the lanes
    /// that hit in (0, `t_max`) farther than their rounding error, with
    /// their distances, edge functions and determinants, or None where an
    /// edge function of a lane is zero, for which the scalar test decides
    /// in double precision. For corners at finite offsets from the origin
    /// each lane's arithmetic is the scalar test's, operation for
    /// operation: the permutation picks whole vectors where the scalar
    /// test multiplies by a matrix of zeros and ones, which changes nothing
    /// but the sign of a zero.
    #[inline(always)]
    pub(crate) fn intersect(&self, corners: &[[Vec4; 3]; 3], t_max: f32) -> Option<Hits4> {
        let [kx, ky, kz] = self.axes;
        let [ox, oy, oz] = self.origin;
        let [sx, sy, sz] = self.shear;
        let sheared = |v: &[Vec4; 3]| {
            let dz = v[kz] - oz;
            ((v[kx] - ox) - sx * dz, (v[ky] - oy) - sy * dz, sz * dz)
        };
        let (a, b, c) = (
            sheared(&corners[0]),
            sheared(&corners[1]),
            sheared(&corners[2]),
        );
        let u = c.0 * b.1 - c.1 * b.0;
        let w2 = a.0 * c.1 - a.1 * c.0;
        let w = b.0 * a.1 - b.1 * a.0;
        let zero = Vec4::ZERO;
        if (u.cmpeq(zero) | w2.cmpeq(zero) | w.cmpeq(zero)).any() {
            return None;
        }
        let negative = u.cmplt(zero) | w2.cmplt(zero) | w.cmplt(zero);
        let positive = u.cmpgt(zero) | w2.cmpgt(zero) | w.cmpgt(zero);
        let det = u + w2 + w;
        let t = (u * a.2 + w2 * b.2 + w * c.2) / det;
        let inside: BVec4A = !(negative & positive) & det.cmpne(zero);
        let mut hit = inside & t.cmpgt(zero) & t.cmplt(Vec4::splat(t_max));
        if hit.any() {
            let largest = |p: Vec4, q: Vec4, r: Vec4| p.abs().max(q.abs()).max(r.abs());
            let bound = error_bound(
                [
                    largest(a.0, b.0, c.0),
                    largest(a.1, b.1, c.1),
                    largest(a.2, b.2, c.2),
                ],
                largest(u, w2, w),
            );
            hit &= (t * det.abs()).cmpgt(bound);
        }
        Some(Hits4 {
            hit,
            mask: hit.bitmask(),
            t,
            edges: [u, w2, w],
            det,
        })
    }
}

/// γₙ of floating-point error analysis (pbrt's `gamma`): a bound on the
/// relative error of n rounded operations.
const fn gamma(n: f32) -> f32 {
    let e = f32::EPSILON * 0.5;
    n * e / (1.0 - n * e)
}

/// A conservative bound on the rounding error of a hit's distance times
/// the determinant's magnitude, from the largest magnitudes of the sheared
/// corners' coordinates (x, y, z) and of the edge functions (pbrt-v4's
/// bound, section 6.8.5, kept multiplied so that the test of a hit needs
/// no second division): a hit no farther than this may lie behind the
/// origin. A ray leaving a surface point that no rounding moved off its
/// plane (the corner of an axis-aligned floor, say) would otherwise find
/// its own triangle a rounding error away and stop there.
#[inline(always)]
fn error_bound<T>([x, y, z]: [T; 3], edges: T) -> T
where
    T: Copy
        + std::ops::Add<Output = T>
        + std::ops::Mul<Output = T>
        + std::ops::Mul<f32, Output = T>,
{
    let dz = z * gamma(3.0);
    let dx = (x + z) * gamma(5.0);
    let dy = (y + z) * gamma(5.0);
    let de = (x * y * gamma(2.0) + dy * x + dx * y) * 2.0;
    (edges * z * gamma(3.0) + de * z + dz * edges) * 3.0
}

/// What [`Shear4::intersect`] finds: the lanes that hit (bits 0–3), with
/// every lane's distance, edge functions and determinant.
pub(crate) struct Hits4 {
    hit: BVec4A,
    pub(crate) mask: u32,
    pub(crate) t: Vec4,
    pub(crate) edges: [Vec4; 3],
    pub(crate) det: Vec4,
}

impl Hits4 {
    /// The lane of the nearest hit, if any (the first of equals).
    #[inline(always)]
    pub(crate) fn nearest(&self) -> Option<usize> {
        if self.mask == 0 {
            return None;
        }
        let t = Vec4::select(self.hit, self.t, Vec4::INFINITY);
        let least = t.min_element();
        Some((t.cmpeq(Vec4::splat(least)).bitmask() & self.mask).trailing_zeros() as usize)
    }

    /// The distance and edge functions of lane `k` (through arrays:
    /// a vector's lane by a variable index is a jump through a table).
    #[inline(always)]
    pub(crate) fn lane(&self, k: usize) -> (f32, Edges) {
        let k = k & 3;
        let [u, w2, w] = self.edges.map(|v| v.to_array());
        (
            self.t.to_array()[k],
            Edges([u[k], w2[k], w[k]], self.det.to_array()[k]),
        )
    }
}

/// The three edge functions of a hit and their sum: barycentrics once
/// divided, which only the closest hit of a ray needs (a closest-hit ray
/// meets several candidates; each still divides once for its distance,
/// and the three divisions here wait for the one kept).
#[derive(Clone, Copy)]
pub(crate) struct Edges(pub(crate) [f32; 3], pub(crate) f32);

impl Edges {
    pub(crate) fn barycentrics(self) -> [f32; 3] {
        let Edges([u, w2, w], det) = self;
        [u / det, w2 / det, w / det]
    }
}
