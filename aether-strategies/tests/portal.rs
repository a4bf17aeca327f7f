//! The portal segment through the chi-square test: its values are pairs of
//! vertices (the two ends of a line through the opening), a
//! four-dimensional space, so the chart is written here: a line by the
//! point where it crosses the opening (two coordinates on the rectangle)
//! and its direction (two coordinates that are uniform for a cosine
//! distribution, on either side), its ends the first hits both ways.
//! From (point, direction) to the ends' areas the Jacobian is
//! ‖a − b‖² |cos θ_y| / (|cos θ_a| |cos θ_b|) dA(y) dω: the line measure,
//! derived from geometry alone, not from the strategy. The harness's
//! [`Grid4`] bins and integrates.

mod support;

use std::f64::consts::PI;

use aether_core::harness::{Check, Grid4, Misreported, Parameterization4, check_histogram};
use aether_core::{Frame, PairStrategy, Prefix, RayCaster, Step};
use aether_strategies::portal::PortalSegment;
use aether_strategies::scene::Scene;
use aether_strategies::vertex::{SceneVertex, Site};
use glam::Vec3;
use support::portal_room;

type Pair = Step<(SceneVertex, SceneVertex)>;

/// Lines through a rectangular opening: coordinates u, v of the point on
/// it, then the direction, whose side is the half of the third coordinate
/// (below ½: along the opening's normal), sin²θ its position in that half,
/// and φ / 2π the fourth.
struct Lines<'s> {
    scene: &'s Scene,
    corner: Vec3,
    edges: [Vec3; 2],
    normal: Vec3,
}

impl<'s> Lines<'s> {
    /// The lines through the scene's portal `index`, a rectangle.
    fn new(scene: &'s Scene, index: usize) -> Self {
        let p = &scene.portals[index].positions;
        assert_eq!(p.len(), 4, "a rectangle");
        // Its corner p[0] and the two corners nearest it.
        let mut others: Vec<Vec3> = p[1..].to_vec();
        others.sort_by(|a, b| a.distance(p[0]).total_cmp(&b.distance(p[0])));
        let edges = [others[0] - p[0], others[1] - p[0]];
        Lines {
            scene,
            corner: p[0],
            edges,
            normal: edges[0].cross(edges[1]).normalize(),
        }
    }

    /// The side's normal and the direction's frame about it.
    fn frame(&self, side: usize) -> Frame {
        Frame::from_normal(if side == 0 { self.normal } else { -self.normal })
    }
}

impl Parameterization4<Pair> for Lines<'_> {
    fn value(&self, s: [f64; 4]) -> Option<(Pair, f64)> {
        let y = self.corner + self.edges[0] * s[0] as f32 + self.edges[1] * s[1] as f32;
        let side = usize::from(s[2] >= 0.5);
        let (sin2, phi) = (2.0 * s[2] - side as f64, 2.0 * PI * s[3]);
        let local = Vec3::new(
            (sin2.sqrt() * phi.cos()) as f32,
            (sin2.sqrt() * phi.sin()) as f32,
            (1.0 - sin2).max(0.0).sqrt() as f32,
        );
        let w = self.frame(side).to_world(local).normalize();
        let at = SceneVertex::point(y, None);
        let surface = |v: SceneVertex| matches!(v.site, Site::Surface { .. }).then_some(v);
        let b = surface(self.scene.cast(&at, w)?)?;
        let a = surface(self.scene.cast(&at, -w)?)?;
        // dω = π d(sin²θ) d(φ / 2π) / |cos θ_y|, and sin²θ runs twice as
        // fast as s₂: the line measure |cos θ_y| dA(y) dω is 2π · area · ds,
        // and dA(a) dA(b) = ‖a − b‖² / (|cos θ_a| |cos θ_b|) of it.
        let cos = |v: &SceneVertex| f64::from(w.dot(v.geometric_normal).abs());
        let area = f64::from(self.edges[0].cross(self.edges[1]).length());
        let ends = f64::from(a.position.distance_squared(b.position)) / (cos(&a) * cos(&b));
        Some((Step::Vertex((a, b)), 2.0 * PI * area * ends))
    }

    fn coords(&self, value: &Pair) -> Option<[f64; 4]> {
        let Step::Vertex((a, b)) = value else {
            return None;
        };
        let w = (b.position - a.position).normalize();
        let side = usize::from(w.dot(self.normal) < 0.0);
        // Where the line crosses the opening's plane.
        let t = (self.corner - a.position).dot(self.normal) / w.dot(self.normal);
        let y = a.position + w * t - self.corner;
        let [e0, e1] = self.edges;
        let (u, v) = (
            y.dot(e0) / e0.length_squared(),
            y.dot(e1) / e1.length_squared(),
        );
        let local = self.frame(side).to_local(w);
        let sin2 = f64::from(local.x)
            .hypot(f64::from(local.y))
            .powi(2)
            .min(1.0);
        let phi = f64::from(local.y)
            .atan2(f64::from(local.x))
            .rem_euclid(2.0 * PI);
        let s = [
            f64::from(u),
            f64::from(v),
            (sin2 + side as f64) / 2.0,
            phi / (2.0 * PI),
        ];
        // The ends must be the line's first hits (a pair the strategy could
        // not see through occluders is elsewhere).
        let (Step::Vertex((a2, b2)), _) = self.value(s)? else {
            return None;
        };
        let close = |p: Vec3, q: Vec3| p.distance(q) <= 1e-3;
        (close(a.position, a2.position) && close(b.position, b2.position)).then_some(s)
    }
}

#[test]
fn the_portal_segment_passes_the_chi_square_test() {
    let scene = portal_room();
    let segment = PortalSegment::new(&scene, 0).unwrap();
    let chart = Grid4::new(Lines::new(&scene, 0), 6);
    let config = Check {
        samples: 1_000_000,
        ..Check::default()
    };
    // Both sides (no vertex before), then from a vertex on each side.
    let before: [&[SceneVertex]; 3] = [
        &[],
        &[SceneVertex::point(Vec3::new(0.0, -0.5, 0.1), None)],
        &[SceneVertex::point(Vec3::new(0.0, 0.5, 0.1), None)],
    ];
    for prefix in before {
        let d = segment.distribution(Prefix::forward(prefix));
        let report = check_histogram(&d, &chart, &config)
            .unwrap_or_else(|f| panic!("portal segment after {prefix:?}: {f}"));
        println!("portal segment after {} vertices: {report}", prefix.len());
        assert!(report.p_value > 0.01, "{report}");
        // The room is closed: every line ends on its walls.
        assert!(report.integral > 0.99, "{report}");
    }
}

#[test]
fn a_segment_without_the_cosine_at_the_opening_fails_the_chi_square_test() {
    let scene = portal_room();
    let segment = PortalSegment::new(&scene, 0).unwrap();
    let chart = Grid4::new(Lines::new(&scene, 0), 6);
    let config = Check {
        samples: 200_000,
        ..Check::default()
    };
    let normal = Lines::new(&scene, 0).normal;
    // |cos θ_y| left out of the line measure.
    let wrong = Misreported {
        distribution: segment.distribution(Prefix::forward(&[])),
        factor: |value: &Pair| match value {
            Step::Vertex((a, b)) => {
                1.0 / f64::from((b.position - a.position).normalize().dot(normal).abs())
            }
            _ => 1.0,
        },
    };
    let failure = check_histogram(&wrong, &chart, &config).expect_err("a wrong density");
    println!("planted: {failure}");
}
