//! Primary rays of the scene's camera (Mitsuba's perspective and thin-lens
//! conventions: +z forward, x to the left, the field of view along an axis).

use aether_core::primitives::UniformDisk;
use aether_strategies::camera::film_tangents;
use aether_strategies::scene::Scene;
use glam::{Mat4, Vec3};

/// Generates primary rays for film positions.
#[derive(Clone, Debug)]
pub struct CameraRays {
    to_world: Mat4,
    tan: [f32; 2],
    width: f32,
    height: f32,
    aperture: f32,
    focus: f32,
}

impl CameraRays {
    /// The camera of `scene` for its film size.
    #[must_use]
    pub fn new(scene: &Scene) -> Self {
        let (w, h) = (scene.film.width as f32, scene.film.height as f32);
        let tan = film_tangents(scene).to_array();
        CameraRays {
            to_world: scene.camera.to_world,
            tan,
            width: w,
            height: h,
            aperture: scene.camera.aperture_radius,
            focus: scene.camera.focus_distance,
        }
    }

    /// The ray through film position (x, y) in pixels (y down), with lens
    /// uniforms `lens` for a thin-lens camera: origin and unit direction.
    #[must_use]
    pub fn ray(&self, x: f32, y: f32, lens: [f32; 2]) -> (Vec3, Vec3) {
        let d = Vec3::new(
            (0.5 - x / self.width) * 2.0 * self.tan[0],
            (0.5 - y / self.height) * 2.0 * self.tan[1],
            1.0,
        );
        let (origin, dir) = if self.aperture > 0.0 {
            let p = UniformDisk::concentric(lens) * self.aperture;
            let o = Vec3::new(p.x, p.y, 0.0);
            (o, d * self.focus - o)
        } else {
            (Vec3::ZERO, d)
        };
        (
            self.to_world.transform_point3(origin),
            self.to_world.transform_vector3(dir).normalize(),
        )
    }
}
