//! What the render loop asks of an integrator: one sample of a pixel, with
//! the contributions its light paths make to other pixels.

use aether_core::Pcg32;
use glam::Vec3;

/// Contributions of light paths to pixels of the film, in the units of a
/// pixel's camera-path estimate: the render loop divides their sum by the
/// total number of samples taken.
pub type Splats = Vec<([u32; 2], Vec3)>;

/// An integrator as the render loop sees it.
pub trait Estimator: Sync {
    /// One sample of pixel `pixel`: the estimate carried by its camera path,
    /// with light-path contributions to any pixel pushed onto `splats`.
    fn sample(&self, pixel: [u32; 2], rng: &mut Pcg32, splats: &mut Splats) -> Vec3;
}
