//! What the language needs to know about a path vertex and about the scene.

use glam::Vec3;

use crate::recycle::Recycle;

/// Where a vertex lies, which fixes the measure its density is expressed in.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Geometry {
    /// On a surface with this unit geometric normal: area measure.
    Surface {
        /// Geometric normal (either orientation).
        normal: Vec3,
    },
    /// An isolated point (a point light, a pinhole): only a Dirac
    /// component can produce it.
    Point,
    /// At infinity in this unit direction (an environment): solid angle.
    AtInfinity {
        /// Direction from the scene towards the vertex.
        direction: Vec3,
    },
}

/// A path vertex. Scene layers define their own (with material, emitter and
/// shading frame); the language only reads position and geometry. Its
/// [`Recycle`] twin is itself (`type Static = Self;`) unless it borrows.
pub trait Vertex: Clone + Recycle {
    /// Position in world space (unused for vertices at infinity).
    fn position(&self) -> Vec3;
    /// The kind of place the vertex lies on.
    fn geometry(&self) -> Geometry;
}

/// Casts rays: the only way sampling code touches the scene's geometry.
///
/// Density evaluation never calls it (the target vertex is given).
pub trait RayCaster<V> {
    /// The first vertex hit by the ray leaving `from` in unit `direction`,
    /// a vertex at infinity if the ray escapes into an environment emitter,
    /// or `None` if it escapes into nothing. Offsetting the origin to avoid
    /// self-intersection is the caster's job.
    fn cast(&self, from: &V, direction: Vec3) -> Option<V>;

    /// Where a ray leaving `from` toward the side of `toward` (a direction,
    /// not necessarily unit) starts: `from`'s position, or that position
    /// moved past its rounding error by a caster that offsets origins.
    /// Densities measure edges from here, so that they describe the rays
    /// the caster actually casts (on edges a few offsets long, the
    /// difference matters).
    fn origin(&self, from: &V, toward: Vec3) -> Vec3
    where
        V: Vertex,
    {
        let _ = toward;
        from.position()
    }

    /// [`cast`](Self::cast), with the [`origin`](Self::origin) the ray
    /// left from: a sampled edge's density is measured from it, and a
    /// caster that offsets origins finds it once for both.
    fn cast_from(&self, from: &V, direction: Vec3) -> (Vec3, Option<V>)
    where
        V: Vertex,
    {
        (self.origin(from, direction), self.cast(from, direction))
    }

    /// The [`origin`](Self::origin) of the ray from `from` that reaches
    /// `target`: the origin may depend on the ray's direction (the side of
    /// the surface it leaves by), and this is the one consistent with the
    /// direction from it to `target`. `None` if no origin the caster uses
    /// reaches `target` that way (a target in the tangent plane, between
    /// the offsets) or the origin is not a number (a NaN position or
    /// error bound). Densities of edges are measured from it. The default
    /// looks for the fixed point of at most three origins; a caster that
    /// knows how its origin depends on the direction may find the same
    /// point with less arithmetic.
    fn origin_reaching(&self, from: &V, target: &V) -> Option<Vec3>
    where
        V: Vertex,
    {
        let toward = |o: Vec3| match target.geometry() {
            Geometry::AtInfinity { direction } => direction,
            _ => target.position() - o,
        };
        let first = self.origin(from, toward(from.position()));
        let second = self.origin(from, toward(first));
        if second == first {
            return Some(first);
        }
        (self.origin(from, toward(second)) == second).then_some(second)
    }
}

impl<V, R: RayCaster<V> + ?Sized> RayCaster<V> for &R {
    fn cast(&self, from: &V, direction: Vec3) -> Option<V> {
        (**self).cast(from, direction)
    }
    fn origin(&self, from: &V, toward: Vec3) -> Vec3
    where
        V: Vertex,
    {
        (**self).origin(from, toward)
    }
    fn cast_from(&self, from: &V, direction: Vec3) -> (Vec3, Option<V>)
    where
        V: Vertex,
    {
        (**self).cast_from(from, direction)
    }
    fn origin_reaching(&self, from: &V, target: &V) -> Option<Vec3>
    where
        V: Vertex,
    {
        (**self).origin_reaching(from, target)
    }
}
