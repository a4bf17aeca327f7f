//! The watertight ray-triangle test (Woop, Benthin and Wald 2013): the
//! per-ray shear, set up once and applied to every candidate triangle of
//! the ray, and the edge functions of a hit, divided into barycentrics only
//! for the hit a ray keeps.

use glam::{Vec3, Vec3Swizzles};

/// The per-ray setup of the watertight test (Woop, Benthin and Wald 2013).
pub(crate) struct Shear {
    origin: Vec3,
    /// Which of the six axis orders (kx, ky, kz) the ray uses: kz the
    /// dominant axis of the direction, kx and ky swapped where it is negative.
    order: u8,
    s: Vec3,
}

impl Shear {
    pub(crate) fn new(origin: Vec3, dir: Vec3) -> Self {
        let a = dir.abs();
        // The dominant axis and the direction's component along it.
        let (kz, dz) = if a.x > a.y {
            if a.x > a.z { (0, dir.x) } else { (2, dir.z) }
        } else if a.y > a.z {
            (1, dir.y)
        } else {
            (2, dir.z)
        };
        let mut shear = Shear {
            origin,
            order: 2 * kz + u8::from(dz < 0.0),
            s: Vec3::ZERO,
        };
        // (dir[kx], dir[ky], dir[kz]) by the swizzle the test uses:
        // indexing by the axes costs a branch per index.
        let d = shear.permute(dir);
        shear.s = Vec3::new(d.x / d.z, d.y / d.z, 1.0 / d.z);
        shear
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
    /// Always inlined: out of line (once four traversals called it), the
    /// call cost path tracing 1.2 % more instructions.
    #[inline(always)]
    pub(crate) fn intersect(&self, v: &[Vec3; 3], t_min: f32, t_max: f32) -> Option<(f32, Edges)> {
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
pub(crate) struct Edges(pub(crate) [f32; 3], pub(crate) f32);

impl Edges {
    pub(crate) fn barycentrics(self) -> [f32; 3] {
        let Edges([u, w2, w], det) = self;
        [u / det, w2 / det, w / det]
    }
}
