//! The multi-chain perturbation proposes what its transition density says,
//! as `proposals.rs` checks the other mutations, on a four-dimensional
//! chart: it moves two vertices freely, the film point and a turn into the
//! specular chain.
//!
//! From a path camera → floor → mirror → wall → light of the caustic room
//! ([`tests::caustic_room`]), 10⁶ proposals of Veach's whole mixture are
//! binned by the proposals that move the floor, mirror and wall vertices,
//! the wall vertex being where the mirror reflects the turned direction: by
//! the film offset toward the new floor vertex (log-spaced radius, as the
//! lens perturbation's offsets) and the direction from there to the mirror
//! (log-spaced angle, as the multi-chain turn's cone about the old
//! direction), so that the chart's edges are the perturbations' and its
//! fixed quadrature meets no jump. The multi-chain perturbation and the bidirectional mutation
//! (film direction, BSDF sampling, reflection) both land there; T(y | x) is
//! their sum. The chi-square test compares the histogram with T integrated
//! over each cell, the reflection's Dirac factor carrying the wall
//! vertex's r² / |cos θ| divided out (as in `proposals.rs`).

use aether_core::harness::{Check, Grid4, Parameterization, Parameterization4, check_histogram};
use aether_core::{ChainPath, Distribution, Prefix, RayCaster, Step, Strategy};
use aether_strategies::bsdf::Transport;
use aether_strategies::camera::Camera;
use aether_strategies::mutations::{Kind, MutationSettings};
use aether_strategies::scattering::{BsdfSampling, Roulette};
use aether_strategies::scene::Scene;
use aether_strategies::vertex::SceneVertex;
use glam::Vec2;
use integrators::mlt::MltSettings;
use integrators::mlt::veach::VeachMlt;
use tests::caustic_room;
use tests::cone::{Angles, Cone};
use tests::proposal::{On, Proposal, Proposals, path_over};

/// Proposals that move vertices 1, 2 and 3 of x: 1 seen from the camera
/// through a film point offset from x's, 2 seen from 1 about x's edge
/// 1 → 2, 3 the reflection of 2.
struct Chain<'a> {
    scene: &'a Scene,
    camera: &'a Camera,
    x: &'a ChainPath<SceneVertex>,
    /// x's film point and the offsets' radii, in pixels.
    center: Vec2,
    radii: (f64, f64),
    turns: Angles,
    reflect: BsdfSampling<'a>,
}

impl Chain<'_> {
    /// The first hit through the film point offset from x's by radius
    /// r_min (r_max / r_min)^s₀ at angle 2π s₁, and its area per unit of
    /// (s₀, s₁): the offset's area element, the film plane's solid angle
    /// (cos³ of the angle to the optical axis per unit plane area, a pixel
    /// being `pixel_angle` wide at unit distance), and r² / |cos θ|.
    fn first(&self, s: [f64; 2]) -> Option<(SceneVertex, f64)> {
        let lens = self.x.vertices()[0];
        let (r_min, r_max) = self.radii;
        let r = r_min * (r_max / r_min).powf(s[0]);
        let phi = 2.0 * std::f64::consts::PI * s[1];
        let raster = self.center + Vec2::new((r * phi.cos()) as f32, (r * phi.sin()) as f32);
        let [w, h] = self.camera.size().map(|n| n as f32);
        let film = self.camera.film_directions(&lens);
        let toward = |p: Vec2| film.sample(&[p.x / w, p.y / h]).map(|d| d.value);
        let (dir, axis) = (toward(raster)?, toward(Vec2::new(w, h) / 2.0)?);
        let hit = self.scene.cast(&lens, dir)?;
        let d = hit.position - lens.position;
        let area = 2.0 * std::f64::consts::PI * r * r * (r_max / r_min).ln();
        let solid = f64::from(self.camera.pixel_angle()).powi(2) * f64::from(dir.dot(axis)).powi(3);
        let cos = d.normalize().dot(hit.geometric_normal).abs();
        Some((hit, area * solid * f64::from(d.length_squared() / cos)))
    }

    /// The chart coordinates of a first hit `v`.
    fn first_coords(&self, v: &SceneVertex) -> Option<[f64; 2]> {
        let lens = self.x.vertices()[0];
        let offset = self
            .camera
            .raster(&lens, (v.position - lens.position).normalize())?
            - self.center;
        let (r_min, r_max) = self.radii;
        let r = f64::from(offset.length());
        let phi = f64::from(offset.y).atan2(f64::from(offset.x));
        Some([
            (r / r_min).ln() / (r_max / r_min).ln(),
            phi.rem_euclid(2.0 * std::f64::consts::PI) / (2.0 * std::f64::consts::PI),
        ])
    }

    /// The turn's cone from a new first hit.
    fn turn(&self, from: SceneVertex) -> Cone<'_> {
        let v = self.x.vertices();
        Cone::new(self.scene, from, v[2].position - v[1].position, self.turns)
    }
}

impl Parameterization4<Proposal> for Chain<'_> {
    fn value(&self, s: [f64; 4]) -> Option<(Proposal, f64)> {
        let (first, film_jacobian) = self.first([s[0], s[1]])?;
        let turn = self.turn(first);
        let mirror = turn.hit([s[2], s[3]])?;
        if !On::Mirror.holds(self.scene, &mirror) {
            return None;
        }
        let prefix = [first, mirror];
        let d = self.reflect.distribution(Prefix::forward(&prefix));
        let u = vec![0.5; d.dims()];
        let Step::Vertex(wall) = d.sample(&u)?.value else {
            return None;
        };
        let y = self
            .x
            .with_vertex(1, first)?
            .with_vertex(2, mirror)?
            .with_vertex(3, wall)?;
        let r = wall.position - mirror.position;
        let cos = r.normalize().dot(wall.geometric_normal).abs();
        let jacobian =
            film_jacobian * turn.jacobian([s[2], s[3]]) * f64::from(r.length_squared() / cos);
        Some((Proposal(y), jacobian))
    }

    fn coords(&self, y: &Proposal) -> Option<[f64; 4]> {
        let (y, x) = (&y.0, self.x);
        let moved = [1, 2, 3];
        let same =
            y.len() == x.len() && (0..x.len()).all(|i| moved.contains(&i) != y.shares(i, x, i));
        if !same {
            return None;
        }
        let v = y.vertices();
        let [a, b] = self.first_coords(&v[1])?;
        let [c, d] = self.turn(v[1]).coords(&Step::Vertex(v[2]))?;
        let s = [a, b, c, d];
        // On the chart's manifold: what the chart puts at s is y (the wall
        // vertex the reflection, every vertex the first hit it is binned as).
        let (Proposal(on), _) = self.value(s.map(|c| c.clamp(0.0, 1.0)))?;
        let close = moved.iter().all(|&i| {
            let (p, q) = (on.vertices()[i].position, v[i].position);
            p.distance(q) <= 1e-3 * p.length().max(1.0)
        });
        close.then_some(s)
    }
}

#[test]
fn multi_chain_proposals_follow_the_transition_density() {
    let scene = caustic_room(16, 12, 6);
    let mlt = VeachMlt::new(&scene, &MltSettings::default()).unwrap();
    let mutations = mlt.mutations();
    let camera = Camera::new(&scene).unwrap();
    let x = path_over(
        &scene,
        &[On::Diffuse, On::Mirror, On::Diffuse],
        Kind::MultiChain,
    );
    let v = x.vertices();
    let settings = MutationSettings::new(scene.film.width, scene.film.height, 8);
    let (r_min, r_max) = settings.lens_offsets;
    let center = camera
        .raster(&v[0], (v[1].position - v[0].position).normalize())
        .unwrap();
    let (min, max) = settings.chain_angles;
    let chain = Chain {
        scene: &scene,
        camera: &camera,
        x: &x,
        center,
        radii: (f64::from(r_min), f64::from(r_max)),
        turns: Angles::Log(min, max),
        reflect: BsdfSampling::new(&scene, Transport::Radiance, Roulette::NEVER),
    };
    let proposals = Proposals {
        mutation: &mutations,
        x: &x,
    };
    let config = Check {
        samples: 1_000_000,
        ..Check::default()
    };
    let report = check_histogram(&proposals, &Grid4::new(chain, 4), &config)
        .unwrap_or_else(|f| panic!("multi-chain: {f}"));
    println!("multi-chain proposals: {report}");
    assert!(report.p_value > 0.01, "{report}");
    assert!(report.integral > 0.05, "the chart holds little: {report}");
}
