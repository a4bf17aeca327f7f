//! Light-transport algorithms written as short combinators over
//! [`aether_core::RandomSequence`] and [`aether_core::combine`], plus the
//! film, the render loop and the command-line program `aether`.
//!
//! Built so far: the [`film`] (filters, accumulation, splats, dropped
//! samples), [`output`] (EXR and PNG), the parallel [`render`] loop, the
//! built-in [`cornell`] box, [`camera`] rays, and a stand-in
//! direct-lighting estimator ([`preview`]) that the integrators of the
//! sampling language will replace.
#![deny(unsafe_code)]

pub mod camera;
pub mod cornell;
pub mod film;
pub mod output;
pub mod path;
pub mod preview;
pub mod render;

pub use aether_strategies as strategies;
