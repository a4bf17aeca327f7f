//! Orthonormal frames and the deterministic scattering geometry (reflection
//! and refraction about a normal) that strategies compute from their prefix.

use glam::Vec3;

/// An orthonormal frame: `n` is the local +z axis.
///
/// A change of frame is a rotation: its Jacobian determinant is one, so it
/// leaves solid-angle densities unchanged (see [`InFrame`](crate::InFrame)).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// Local x axis.
    pub s: Vec3,
    /// Local y axis.
    pub t: Vec3,
    /// Local z axis (the normal).
    pub n: Vec3,
}

impl Frame {
    /// The frame of the world axes.
    pub const WORLD: Frame = Frame {
        s: Vec3::X,
        t: Vec3::Y,
        n: Vec3::Z,
    };

    /// A frame around a unit normal (Duff et al. 2017, branchless).
    #[must_use]
    pub fn from_normal(n: Vec3) -> Frame {
        debug_assert!(
            (n.length_squared() - 1.0).abs() < 1e-3,
            "normal {n} is not unit length"
        );
        let sign = 1.0f32.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        let s = Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
        let t = Vec3::new(b, sign + n.y * n.y * a, -n.y);
        Frame { s, t, n }
    }

    /// World → local.
    #[must_use]
    pub fn to_local(&self, v: Vec3) -> Vec3 {
        Vec3::new(v.dot(self.s), v.dot(self.t), v.dot(self.n))
    }

    /// Local → world.
    #[must_use]
    pub fn to_world(&self, v: Vec3) -> Vec3 {
        self.s * v.x + self.t * v.y + self.n * v.z
    }
}

/// Mirror reflection of `wi` (pointing away from the surface) about `n`.
#[must_use]
pub fn reflect(wi: Vec3, n: Vec3) -> Vec3 {
    2.0 * wi.dot(n) * n - wi
}

/// The refraction of `wi` (pointing away from the surface, on the side `n`
/// points to) through an interface with relative index `eta` = η_other /
/// η_wi-side. `None` on total internal reflection.
#[must_use]
pub fn refract(wi: Vec3, n: Vec3, eta: f32) -> Option<Vec3> {
    let cos_i = wi.dot(n);
    let sin2_t = (1.0 - cos_i * cos_i).max(0.0) / (eta * eta);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some(-wi / eta + (cos_i / eta - cos_t) * n)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_is_orthonormal() {
        for n in [
            Vec3::Z,
            -Vec3::Z,
            Vec3::new(0.3, -0.5, 0.81).normalize(),
            Vec3::X,
        ] {
            let f = Frame::from_normal(n);
            assert!(f.s.dot(f.t).abs() < 1e-6 && f.s.dot(f.n).abs() < 1e-6);
            assert!((f.s.cross(f.t) - f.n).length() < 1e-5);
            let v = Vec3::new(0.1, 0.7, -0.2);
            assert!((f.to_world(f.to_local(v)) - v).length() < 1e-6);
        }
    }

    #[test]
    fn snell_holds() {
        let wi = Vec3::new(0.6, 0.0, 0.8);
        let wo = refract(wi, Vec3::Z, 1.5).unwrap();
        assert!((wi.x - -1.5 * wo.x).abs() < 1e-6);
        assert!(refract(Vec3::new(0.9, 0.0, 0.435_889_9), Vec3::Z, 1.0 / 1.5).is_none());
    }
}
