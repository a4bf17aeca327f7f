//! Scene-facing strategies written in the [`aether_core`] sampling language:
//! camera position and direction, BSDF sampling with Russian roulette,
//! emitter position and direction, direct emitter sampling and the portal
//! segment, with the scene, geometry and materials they sample.
//!
//! This crate is being built (issues "scenes" and "reusable strategies");
//! until then it only re-exports the language it builds on.
#![deny(unsafe_code)]

pub use aether_core as core;
