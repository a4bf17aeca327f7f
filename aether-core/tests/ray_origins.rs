//! Densities of rays that start off their vertex: a caster that moves each
//! origin past its rounding error (to the side the ray leaves by) casts a
//! ray from there, and the `intersect` primitive's density mode must
//! describe that ray, not the one from the vertex, or sampled and
//! evaluated densities part on short edges.

use aether_core::primitives::CosineHemisphere;
use aether_core::testing::TestVertex;
use aether_core::{Distribution, Frame, InFrame, Intersect, Pcg32, RayCaster, Step, UniformSource};
use glam::Vec3;

/// The floor z = 0 and a ceiling z = `height` over it; origins move
/// `offset` along the floor's normal, to the side of the ray.
struct Slab {
    height: f32,
    offset: f32,
}

impl RayCaster<TestVertex> for Slab {
    fn origin(&self, from: &TestVertex, toward: Vec3) -> Vec3 {
        let side = if toward.z < 0.0 { -1.0 } else { 1.0 };
        from.position + side * self.offset * Vec3::Z
    }

    fn cast(&self, from: &TestVertex, direction: Vec3) -> Option<TestVertex> {
        let o = self.origin(from, direction);
        let t = (self.height - o.z) / direction.z;
        (t > 0.0).then(|| TestVertex::on_surface(o + t * direction, -Vec3::Z))
    }
}

/// Edges of ten offsets: measured from the vertex, densities would be off
/// by about 20 %.
const SLAB: Slab = Slab {
    height: 0.01,
    offset: 0.001,
};

/// A cosine bounce off the floor at the origin.
fn bounce(from: &TestVertex) -> impl Distribution<Value = Step<TestVertex>> + '_ {
    Intersect::new(
        from,
        InFrame::new(Frame::from_normal(Vec3::Z), CosineHemisphere),
        &SLAB,
    )
}

#[test]
fn densities_of_short_edges_describe_the_rays_cast() {
    let from = TestVertex::on_surface(Vec3::ZERO, Vec3::Z);
    let bounce = bounce(&from);
    let mut rng = Pcg32::new(3, 0);
    let mut worst = 0.0f64;
    for _ in 0..1000 {
        let u = [rng.next_f32(), rng.next_f32()];
        let Some(hit) = bounce.sample(&u) else {
            continue;
        };
        assert!(matches!(hit.value, Step::Vertex(_)));
        let evaluated = bounce.density(&hit.value).value();
        worst = worst.max((evaluated / hit.density.value() - 1.0).abs());
    }
    assert!(
        worst < 1e-3,
        "sampled and evaluated densities differ by {worst}"
    );
}

#[test]
fn targets_no_offset_ray_reaches_have_no_density() {
    let from = TestVertex::on_surface(Vec3::ZERO, Vec3::Z);
    let bounce = bounce(&from);
    // In the tangent plane: from the upper origin it lies below, from the
    // lower one above; neither ray leaves by the side it would need.
    let flat = TestVertex::on_surface(Vec3::new(1.0, 0.0, 0.0), Vec3::Z);
    assert_eq!(bounce.density(&Step::Vertex(flat)).value(), 0.0);
    // Just above the upper origin, it is reached.
    let above = TestVertex::on_surface(Vec3::new(1.0, 0.0, 0.002), -Vec3::Z);
    assert!(bounce.density(&Step::Vertex(above)).value() > 0.0);
}
