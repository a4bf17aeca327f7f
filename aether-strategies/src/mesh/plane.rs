//! A triangle's plane, solved for the barycentrics of a point given by its
//! position (a point some strategy found on a mesh): what the point needs
//! to become a surface point (its barycentrics, for the normal, the
//! texture coordinates and the error bound), minus the point itself. A
//! light's own samples keep the barycentrics they were made of instead
//! (`aether_core::OnTriangle`).

use glam::{DVec3, Vec3};

/// The unit normal of a triangle by its winding (zero if degenerate), in
/// f32 as every hit on it computes it, so that a normal found once per
/// triangle is the normal each hit would have found.
#[must_use]
pub fn triangle_normal(corners: [Vec3; 3]) -> Vec3 {
    let [p0, p1, p2] = corners;
    (p1 - p0).cross(p2 - p0).normalize_or_zero()
}

/// The position-independent part of the least-squares barycentric solve
/// of a point of a triangle (the Gram matrix of its edges and its
/// determinant, in f64), with the corners and the unit normal.
///
/// ```
/// use aether_strategies::mesh::TrianglePlane;
/// use glam::Vec3;
/// let plane = TrianglePlane::new([Vec3::ZERO, Vec3::X, Vec3::Y]);
/// let [b0, b1, b2] = plane.barycentrics(Vec3::new(0.25, 0.5, 0.0));
/// assert_eq!([b0, b1, b2], [0.25, 0.25, 0.5]);
/// assert_eq!(plane.normal(), Vec3::Z);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrianglePlane {
    corners: [Vec3; 3],
    normal: Vec3,
    e1: DVec3,
    e2: DVec3,
    /// e1·e1, e1·e2, e2·e2 and the determinant of that Gram matrix.
    gram: [f64; 4],
}

impl TrianglePlane {
    /// The plane of the triangle with these corners.
    #[must_use]
    pub fn new(corners: [Vec3; 3]) -> Self {
        let [p0, p1, p2] = corners.map(Vec3::as_dvec3);
        let (e1, e2) = (p1 - p0, p2 - p0);
        let (a, b, c) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
        TrianglePlane {
            corners,
            normal: triangle_normal(corners),
            e1,
            e2,
            gram: [a, b, c, a * c - b * b],
        }
    }

    /// The corners.
    #[must_use]
    pub fn corners(&self) -> [Vec3; 3] {
        self.corners
    }

    /// The unit normal by the winding (zero if degenerate).
    #[must_use]
    pub fn normal(&self) -> Vec3 {
        self.normal
    }

    /// The barycentrics (b₀, b₁, b₂) of the point of the triangle's plane
    /// nearest to `position`; all weight on the first corner if the
    /// triangle is degenerate.
    #[must_use]
    pub fn barycentrics(&self, position: Vec3) -> [f32; 3] {
        let d = position.as_dvec3() - self.corners[0].as_dvec3();
        let [a, b, c, det] = self.gram;
        let (r1, r2) = (d.dot(self.e1), d.dot(self.e2));
        let (b1, b2) = if det > 0.0 {
            ((c * r1 - b * r2) / det, (a * r2 - b * r1) / det)
        } else {
            (0.0, 0.0)
        };
        [(1.0 - b1 - b2) as f32, b1 as f32, b2 as f32]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn corners_solve_to_unit_barycentrics() {
        let corners = [
            Vec3::new(1.0, 2.0, 3.0),
            Vec3::new(4.0, -1.0, 0.5),
            Vec3::new(-2.0, 0.0, 1.0),
        ];
        let plane = TrianglePlane::new(corners);
        for (k, p) in corners.iter().enumerate() {
            let b = plane.barycentrics(*p);
            for (j, bj) in b.iter().enumerate() {
                let expected = if j == k { 1.0 } else { 0.0 };
                assert!((bj - expected).abs() < 1e-6, "corner {k}: {b:?}");
            }
        }
        let n = plane.normal();
        assert!((n.length() - 1.0).abs() < 1e-6);
        assert!(n.dot(corners[1] - corners[0]).abs() < 1e-5);
    }

    #[test]
    fn a_degenerate_triangle_puts_its_point_on_the_first_corner() {
        let plane = TrianglePlane::new([Vec3::ZERO, Vec3::X, Vec3::X * 2.0]);
        assert_eq!(plane.barycentrics(Vec3::X), [1.0, 0.0, 0.0]);
        assert_eq!(plane.normal(), Vec3::ZERO);
    }
}
