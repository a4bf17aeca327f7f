//! The path integrand f(x̄): camera importance, geometry terms, BSDF values
//! and emitted radiance, with visibility tested on connection edges only
//! (edges that a ray traced while sampling are known to be clear).

use glam::{DVec3, Vec3};

use crate::camera::Camera;
use crate::lights::Lights;
use crate::scene::Scene;
use crate::subpath::{End, Subpath};
use crate::vertex::{SceneVertex, Site};

/// |cos| of the edge direction `d` at `v`: one for points and vertices at
/// infinity, whose measures carry no cosine.
fn cosine(v: &SceneVertex, d: Vec3) -> f32 {
    match v.site {
        Site::Surface { .. } | Site::Lens => v.geometric_normal.dot(d).abs(),
        _ => 1.0,
    }
}

/// The geometry term G(a, b) = |cos θ_a| |cos θ_b| / ‖a − b‖², with no
/// distance for an edge to infinity.
#[must_use]
pub fn geometry_term(a: &SceneVertex, b: &SceneVertex) -> f32 {
    a.direction_to(b)
        .map_or(0.0, |d| geometry_term_along(a, b, d))
}

/// [`geometry_term`] for the edge's unit direction `d` from `a` to `b`
/// (`a.direction_to(b)`), found once by a caller that also needs it.
pub(crate) fn geometry_term_along(a: &SceneVertex, b: &SceneVertex, d: Vec3) -> f32 {
    let c = cosine(a, d) * cosine(b, -d);
    if a.is_at_infinity() || b.is_at_infinity() {
        c
    } else {
        c / (b.position - a.position).length_squared()
    }
}

/// True if nothing in `scene` blocks the edge between `a` and `b` (either
/// may lie at infinity; two vertices at infinity never see each other).
#[must_use]
pub fn visible(scene: &Scene, a: &SceneVertex, b: &SceneVertex) -> bool {
    // A thin lens's aperture stops what crosses it, except edges from it.
    let on_lens = matches!(a.site, Site::Lens) || matches!(b.site, Site::Lens);
    if let Some(lens) = scene.aperture().filter(|_| !on_lens) {
        let (from, to) = if a.is_at_infinity() { (b, a) } else { (a, b) };
        let far = match to.is_at_infinity() {
            true => f32::INFINITY,
            false => (to.position - from.position).length(),
        };
        let crosses = |d| lens.crossing(from.position, d, far).is_some();
        if from.direction_to(to).is_some_and(crosses) {
            return false;
        }
    }
    let g = &scene.geometry;
    match (a.is_at_infinity(), b.is_at_infinity()) {
        (false, false) => g.visible(
            (a.position, a.error, a.geometric_normal),
            (b.position, b.error, b.geometric_normal),
        ),
        (true, true) => false,
        (false, true) | (true, false) => {
            let (x, far) = if b.is_at_infinity() { (a, b) } else { (b, a) };
            let d = x.direction_to(far).unwrap_or(Vec3::Z);
            let o = crate::geometry::offset_origin(x.position, x.error, x.geometric_normal, d);
            !g.occluded(o, d, f32::INFINITY)
        }
    }
}

/// The measurement contribution of paths of a scene.
#[derive(Clone, Copy, Debug)]
pub struct Integrand<'a> {
    scene: &'a Scene,
    camera: &'a Camera,
    lights: &'a Lights<'a>,
}

impl<'a> Integrand<'a> {
    /// The integrand of `scene` seen by `camera`, lit by `lights`.
    #[must_use]
    pub fn new(scene: &'a Scene, camera: &'a Camera, lights: &'a Lights<'a>) -> Self {
        Integrand {
            scene,
            camera,
            lights,
        }
    }

    /// True if nothing blocks the edge between `a` and `b`.
    #[must_use]
    pub fn visible(&self, a: &SceneVertex, b: &SceneVertex) -> bool {
        visible(self.scene, a, b)
    }

    /// f(x̄) without the camera's importance: the product of geometry
    /// terms, BSDF values and the radiance emitted by the last vertex (in
    /// double precision: geometry terms of long paths between close surfaces
    /// overflow single precision, as their densities would), for
    /// a path ordered from the camera (`path[0]`) to the light. Edges
    /// `path[i]`–`path[i + 1]` for `i` in `connections` are tested for
    /// visibility.
    #[must_use]
    pub fn throughput(&self, path: &[SceneVertex], connections: &[usize]) -> DVec3 {
        let f = Subpath::of(*self, End::Camera, path).emitted(path.len());
        if f == DVec3::ZERO
            || connections
                .iter()
                .any(|&i| !self.visible(&path[i], &path[i + 1]))
        {
            return DVec3::ZERO;
        }
        f
    }

    /// The scene.
    #[must_use]
    pub fn scene(&self) -> &'a Scene {
        self.scene
    }

    /// The radiance `light` emits toward the unit direction `toward` (zero
    /// if it is not on a light).
    #[must_use]
    pub fn emitted(&self, light: &SceneVertex, toward: Vec3) -> Vec3 {
        self.lights.emitted(light, toward)
    }

    /// True if `v` lies on a light (what [`emitted`](Self::emitted) can
    /// find nonzero).
    #[must_use]
    pub fn on_light(&self, v: &SceneVertex) -> bool {
        self.lights.emitter_of(v).is_some()
    }

    /// The camera's importance for pixel `pixel` along the first edge of
    /// `path` (zero for a path of fewer than two vertices).
    #[must_use]
    pub fn importance(&self, pixel: [u32; 2], path: &[SceneVertex]) -> f64 {
        let first = path.first().zip(path.get(1));
        first
            .and_then(|(a, b)| Some(self.camera.importance(pixel, a, a.direction_to(b)?)))
            .unwrap_or(0.0)
    }

    /// f(x̄) for pixel `pixel`: the camera's importance for the first edge
    /// times [`throughput`](Self::throughput).
    #[must_use]
    pub fn evaluate(&self, pixel: [u32; 2], path: &[SceneVertex], connections: &[usize]) -> DVec3 {
        match self.importance(pixel, path) {
            0.0 => DVec3::ZERO,
            importance => importance * self.throughput(path, connections),
        }
    }
}
