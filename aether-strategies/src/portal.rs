//! The portal (keyhole) segment of tridirectional path tracing: a line
//! through an opening declared in the scene, and the two vertices it meets
//! on either side.

use aether_core::primitives::{CosineHemisphere, DiscreteDistribution, UniformTriangle};
use aether_core::{
    Distribution, Either, Frame, InFrame, PairStrategy, Prefix, Segment, Select, Step,
};
use glam::Vec3;

use crate::scene::Scene;
use crate::vertex::SceneVertex;

/// A segment through portal `index` of the scene: a point on the opening
/// by area, a cosine-distributed direction to either side of it, and the
/// first surfaces the line meets both ways. Its density is in the product
/// of the two vertices' areas.
///
/// ```
/// # fn f(scene: &aether_strategies::scene::Scene) {
/// use aether_core::RandomSequence;
/// use aether_strategies::portal::PortalSegment;
/// let keyhole = PortalSegment::new(scene, 0).expect("a planar portal");
/// let mut middle = RandomSequence::new();
/// middle.append_pair(&keyhole);
/// # }
/// ```
#[derive(Debug)]
pub struct PortalSegment<'s> {
    scene: &'s Scene,
    corners: Vec<[Vec3; 3]>,
    by_area: DiscreteDistribution,
    sides: DiscreteDistribution,
    origin: Vec3,
    normal: Vec3,
}

impl<'s> PortalSegment<'s> {
    /// The segment strategy of `scene.portals[index]`.
    ///
    /// # Errors
    /// If there is no such portal, or it is not planar.
    pub fn new(scene: &'s Scene, index: usize) -> Result<Self, String> {
        let mesh = scene
            .portals
            .get(index)
            .ok_or_else(|| format!("the scene has no portal {index}"))?;
        let corners: Vec<[Vec3; 3]> = (0..mesh.triangles.len()).map(|t| mesh.corners(t)).collect();
        let areas: Vec<f64> = (0..corners.len()).map(|t| mesh.triangle_area(t)).collect();
        let by_area =
            DiscreteDistribution::new(&areas).map_err(|_| format!("portal {index} has no area"))?;
        let largest = (0..areas.len())
            .max_by(|&a, &b| areas[a].total_cmp(&areas[b]))
            .expect("a triangle");
        let [a, b, c] = corners[largest];
        let normal = (b - a).cross(c - a).normalize();
        let size = mesh.area().sqrt() as f32;
        for p in &mesh.positions {
            if (*p - a).dot(normal).abs() > 1e-4 * size.max(1e-6) {
                return Err(format!(
                    "portal {index} ('{}') is not planar: the segment strategy needs one plane",
                    mesh.name
                ));
            }
        }
        Ok(PortalSegment {
            scene,
            corners,
            by_area,
            sides: DiscreteDistribution::new(&[0.5, 0.5]).expect("positive"),
            origin: a,
            normal,
        })
    }
}

impl PortalSegment<'_> {
    /// Which side of the portal's plane `v` is on: 1 in front (along the
    /// normal), 0 behind. After a vertex, segments start on its side.
    #[must_use]
    pub fn side(&self, v: &SceneVertex) -> usize {
        usize::from((v.position - self.origin).dot(self.normal) > 0.0)
    }
}

impl PairStrategy<SceneVertex> for PortalSegment<'_> {
    fn distribution<'a>(
        &'a self,
        prefix: Prefix<'a, SceneVertex>,
    ) -> impl Distribution<Value = Step<(SceneVertex, SceneVertex)>> + 'a {
        let points = Select::new(
            &self.by_area,
            2,
            |t| {
                let [a, b, c] = self.corners[t];
                UniformTriangle::new(a, b, c)
            },
            |y: &Vec3| {
                self.corners
                    .iter()
                    .position(|&[a, b, c]| UniformTriangle::new(a, b, c).barycentrics(*y).is_some())
            },
        );
        // Lines cross the opening either way, so the direction is cosine
        // distributed about either side of it; its side names the choice.
        // After a vertex, the line leaves the vertex's side, so that the
        // segment's first vertex (behind the line) is on that side and the
        // path can join it.
        let side = [
            Frame::from_normal(self.normal),
            Frame::from_normal(-self.normal),
        ];
        let n = self.normal;
        let after = prefix.last().filter(|v| !v.is_at_infinity());
        let directions = match after.map(|v| self.side(v)) {
            Some(i) => Either::Left(InFrame::new(side[i], CosineHemisphere)),
            None => Either::Right(Select::new(
                &self.sides,
                2,
                move |i| InFrame::new(side[i], CosineHemisphere),
                move |w: &Vec3| Some(usize::from(w.dot(n) < 0.0)),
            )),
        };
        let at = |y| SceneVertex::point(y, None);
        Segment::new(points, directions, self.origin, self.normal, at, self.scene)
    }
    fn memory(&self) -> usize {
        1
    }
    fn depth_class(&self, _prefix_len: usize) -> usize {
        0
    }
}
