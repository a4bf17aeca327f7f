//! Scene-facing strategies written in the [`aether_core`] sampling language,
//! and the scene, geometry and materials they sample.
//!
//! Built so far: [`mesh`] (OBJ and Mitsuba `.serialized` loading) and
//! [`geometry`] (ray casting through a compressed wide BVH, analytic
//! spheres, watertight triangle tests and scale-aware ray offsets).
#![deny(unsafe_code)]

pub mod bitmap;
pub mod bsdf;
mod bvh;
pub mod camera;
pub mod files;
pub mod geometry;
pub mod integrand;
pub mod lights;
pub mod mesh;
pub mod mutations;
pub mod portal;
mod quad;
pub mod scattering;
pub mod scene;
pub mod spectrum;
pub mod subpath;
mod traversal;
pub mod vertex;
mod watertight;
mod wide;

pub use aether_core as core;
