//! Points sampled uniformly on a triangle turned into vertices, with the
//! barycentrics the sample was made of: a mesh light's vertex interpolates
//! its normal and texture coordinates by them, and solving them again from
//! the sampled point (a 2×2 system in double precision per light sample)
//! cost a path tracer about 1 % of its instructions.

use glam::Vec3;

use crate::density::{Density, Measure};
use crate::distribution::{Distribution, Sample, Step, Uniforms};
use crate::primitives::UniformTriangle;
use crate::surface::on_a_surface;
use crate::vertex::Vertex;

/// [`OnSurface`](crate::OnSurface) for a [`UniformTriangle`], with
/// `at(point, barycentrics)` building the vertex at a sampled point; the
/// barycentrics (b₀, b₁, b₂) weigh the triangle's corners in the order it
/// was built with.
///
/// Density: the triangle's, 1 / A in area measure, for target vertices on
/// a surface in its plane and inside it; zero otherwise.
///
/// ```
/// use aether_core::primitives::UniformTriangle;
/// use aether_core::testing::TestVertex;
/// use aether_core::{Distribution, OnTriangle, Step};
/// use glam::Vec3;
///
/// let triangle = UniformTriangle::new(Vec3::ZERO, Vec3::X, Vec3::Y);
/// let on = OnTriangle::new(triangle, |p, b: [f32; 3]| {
///     assert!((b[1] * Vec3::X + b[2] * Vec3::Y - p).length() < 1e-6);
///     Some(TestVertex::on_surface(p, Vec3::Z))
/// });
/// let s = on.sample(&[0.3, 0.6]).unwrap();
/// assert!((s.density.value() - 2.0).abs() < 1e-9);
/// assert_eq!(on.density(&s.value).value(), s.density.value());
/// ```
pub struct OnTriangle<F> {
    triangle: UniformTriangle,
    at: F,
}

impl<F> std::fmt::Debug for OnTriangle<F> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("OnTriangle")
            .field("triangle", &self.triangle)
            .finish_non_exhaustive()
    }
}

impl<V: Vertex, F: Fn(Vec3, [f32; 3]) -> Option<V>> OnTriangle<F> {
    /// Vertices at the points of `triangle`.
    pub fn new(triangle: UniformTriangle, at: F) -> Self {
        OnTriangle { triangle, at }
    }
}

impl<V: Vertex, F: Fn(Vec3, [f32; 3]) -> Option<V>> Distribution for OnTriangle<F> {
    type Value = Step<V>;
    fn dims(&self) -> usize {
        2
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<Step<V>>> {
        let s = self.triangle.sample_point(u);
        let (p, b) = s.value;
        let v = (self.at)(p, b.map(|b| b as f32))?;
        Some(Sample::new(Step::Vertex(v), s.density))
    }
    fn density(&self, v: &Step<V>) -> Density {
        on_a_surface(v).map_or(Density::zero(Measure::Area), |p| self.triangle.density(&p))
    }
    fn invert(&self, v: &Step<V>) -> Option<Uniforms> {
        on_a_surface(v).and_then(|p| self.triangle.invert(&p))
    }
}
