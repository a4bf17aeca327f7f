//! Light-transport algorithms written as short combinators over
//! [`aether_core::RandomSequence`] and MIS weights derived by the language
//! ([`aether_core::weight_of_split`]), plus the film, the render loop and
//! the command-line program `aether`.
//!
//! - [`path`]: path tracing with next-event estimation (and direct lighting,
//!   the same tracer stopped after one bounce);
//! - [`light`]: light tracing, splatted;
//! - [`bdpt`]: bidirectional path tracing over every (s, t), and
//!   tridirectional path tracing with a portal segment; [`techniques`] holds
//!   its optional (s, t) images;
//! - [`mlt`]: Metropolis light transport: Veach's path-space MLT with
//!   mutations whose transition densities the language derives, and
//!   primary-sample-space and multiplexed MLT on BDPT;
//! - [`gradient`]: gradient-domain path tracing, its images reconstructed
//!   by [`poisson`];
//! - [`estimator`]: what the [`render`] loop asks of each; [`film`],
//!   [`output`] (EXR and PNG), the built-in [`cornell`] box.
#![deny(unsafe_code)]

pub mod bdpt;
pub mod cornell;
pub mod direct;
pub mod estimator;
pub mod film;
pub mod gradient;
pub mod light;
pub mod mlt;
pub mod output;
pub mod parts;
pub mod path;
pub mod poisson;
pub mod render;
pub mod rounds;
pub mod shard;
pub mod shard_file;
mod shift;
pub mod techniques;

pub use aether_strategies as strategies;
