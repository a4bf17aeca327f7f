//! A chart of the surface points seen from a vertex through a cone of
//! directions about an axis: cells of angle to the axis (linear, or
//! log-spaced for the perturbations, which are log-uniform in angle) and of
//! azimuth, each cell's points being the first hits of its directions, with
//! the solid angle → area Jacobian r² / |cos θ|. Written from geometry
//! alone, so that the harness checks densities against it.

use std::f64::consts::PI;

use aether_core::harness::Parameterization;
use aether_core::{Frame, RayCaster, Step};
use aether_strategies::scene::Scene;
use aether_strategies::vertex::{SceneVertex, Site};
use glam::{DVec3, Vec3};

/// How the angle to the axis runs over the chart's first coordinate.
#[derive(Clone, Copy, Debug)]
pub enum Angles {
    /// θ = θ_max · s.
    Linear(f64),
    /// θ = θ_min (θ_max / θ_min)^s.
    Log(f64, f64),
}

impl Angles {
    /// The angle at chart coordinate `s`.
    #[must_use]
    pub fn theta(self, s: f64) -> f64 {
        match self {
            Angles::Linear(max) => max * s,
            Angles::Log(min, max) => min * (max / min).powf(s),
        }
    }
    /// The chart coordinate of angle `theta`.
    #[must_use]
    pub fn coord(self, theta: f64) -> f64 {
        match self {
            Angles::Linear(max) => theta / max,
            Angles::Log(min, max) => (theta / min).ln() / (max / min).ln(),
        }
    }
    /// dθ / ds.
    #[must_use]
    pub fn rate(self, s: f64) -> f64 {
        match self {
            Angles::Linear(max) => max,
            Angles::Log(min, max) => self.theta(s) * (max / min).ln(),
        }
    }
}

/// The first hits of the directions about `axis` from `from`, by angle and
/// azimuth.
#[derive(Debug)]
pub struct Cone<'s> {
    scene: &'s Scene,
    from: SceneVertex,
    frame: Frame,
    angles: Angles,
}

impl<'s> Cone<'s> {
    /// The hits seen from `from` about `axis`, at `angles`.
    #[must_use]
    pub fn new(scene: &'s Scene, from: SceneVertex, axis: Vec3, angles: Angles) -> Self {
        Cone {
            scene,
            from,
            frame: Frame::from_normal(axis.normalize()),
            angles,
        }
    }

    /// The direction at chart coordinates `s`.
    #[must_use]
    pub fn direction(&self, s: [f64; 2]) -> DVec3 {
        let (theta, phi) = (self.angles.theta(s[0]), 2.0 * PI * s[1]);
        let local = DVec3::new(
            theta.sin() * phi.cos(),
            theta.sin() * phi.sin(),
            theta.cos(),
        );
        self.frame.to_world(local.as_vec3()).as_dvec3()
    }

    /// The surface point seen at chart coordinates `s`, if any.
    #[must_use]
    pub fn hit(&self, s: [f64; 2]) -> Option<SceneVertex> {
        let v = self.scene.cast(&self.from, self.direction(s).as_vec3())?;
        matches!(v.site, Site::Surface { .. }).then_some(v)
    }
}

impl Parameterization<Step<SceneVertex>> for Cone<'_> {
    fn dims(&self) -> usize {
        2
    }
    fn value(&self, s: [f64; 2]) -> Option<Step<SceneVertex>> {
        self.hit(s).map(Step::Vertex)
    }
    fn coords(&self, v: &Step<SceneVertex>) -> Option<[f64; 2]> {
        let Step::Vertex(v) = v else { return None };
        let w = (v.position.as_dvec3() - self.from.position.as_dvec3()).normalize();
        let local = self.frame.to_local(w.as_vec3()).as_dvec3();
        // θ from the sine and cosine: accurate at the cone's smallest angles.
        let theta = local.x.hypot(local.y).atan2(local.z);
        let phi = local.y.atan2(local.x).rem_euclid(2.0 * PI);
        // A hit's f32 position rounds its angle by ~1e-7 rad, which at a
        // cone's smallest angle (1e-4 rad) moves the coordinate by ~1e-3:
        // hits that rounding pushes just past the chart's rim belong to its
        // rim cells, not off the chart. Farther out they are off it.
        const ROUNDING: f64 = 1e-6;
        let (lo, hi) = (self.angles.theta(0.0), self.angles.theta(1.0));
        let s = if (lo - ROUNDING..=lo).contains(&theta) {
            0.0
        } else if (hi..=hi + ROUNDING).contains(&theta) {
            1.0
        } else {
            self.angles.coord(theta)
        };
        Some([s, phi / (2.0 * PI)])
    }
    fn jacobian(&self, s: [f64; 2]) -> f64 {
        let Some(hit) = self.hit(s) else { return 0.0 };
        let theta = self.angles.theta(s[0]);
        let solid_angle = theta.sin() * self.angles.rate(s[0]) * 2.0 * PI;
        let d = hit.position.as_dvec3() - self.from.position.as_dvec3();
        let cos = d.normalize().dot(hit.geometric_normal.as_dvec3()).abs();
        solid_angle * d.length_squared() / cos
    }
}
