//! The watertight ray-triangle test (Woop, Benthin and Wald 2013): the
//! per-ray shear, set up once and applied to every candidate triangle of
//! the ray, and the edge functions of a hit, divided into barycentrics only
//! for the hit a ray keeps.

use glam::{Vec3, Vec3A};

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

impl Shear {
    pub(crate) fn new(origin: Vec3, dir: Vec3) -> Self {
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
        let mut columns = [Vec3A::ZERO; 3];
        columns[kx] = Vec3A::X;
        columns[ky] = Vec3A::Y;
        columns[kz] = Vec3A::new(-s.x, -s.y, s.z);
        Shear {
            origin: origin.into(),
            columns,
        }
    }

    /// Distance and edge functions of the hit, if any, in (t_min, t_max).
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
        (t > t_min && t < t_max).then_some((t, Edges([u, w2, w], det)))
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
