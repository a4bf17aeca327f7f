//! The Aether sampling language: write a sampling strategy once and get
//! its density for any vertex, so that multiple importance sampling is
//! automatic.
//!
//! # The model
//! A strategy is sampling code: it draws uniforms, warps them, changes
//! frames, casts a ray and returns a vertex. Here it is written as a
//! composition of invertible blocks ([`Distribution`]s) built from the
//! conditioning vertices alone. The framework runs the composition forward
//! to sample and backward, through each block's analytic inverse and
//! Jacobian, to evaluate the density of any given vertex, without casting
//! rays. No strategy writes a pdf.
//!
//! * [`primitives`]: the closed set of warps with inverses and Jacobians,
//!   and the changes of variables between their spaces (film plane →
//!   directions, environment map → directions, plane → aperture,
//!   directions → sphere).
//! * Combinators: [`InFrame`] (frame change), [`Select`] (a discrete choice
//!   looked up from the value), [`Mixture`] (overlapping lobes, summed),
//!   [`RussianRoulette`] (termination as an event with probability),
//!   [`Sometimes`] (a strategy taken for a share of the samples),
//!   [`Either`], [`Intersect`] (solid angle → area at the hit point),
//!   [`OnSurface`], [`OnTriangle`] (with the sampled barycentrics),
//!   [`DiracPoint`], [`AtInfinity`] (environment and
//!   directional emitters), [`ParallelRays`] (the far disk of a distant
//!   light: disk area → area at the hit point) and [`Segment`] (two
//!   vertices through a portal).
//! * Measures: [`Density`] carries its [`Measure`] and Dirac order; a path's
//!   [`PathDensity`] compares by Dirac order first.
//! * Paths: [`Strategy`], [`RandomSequence`] (append, sample, slice, concat,
//!   reverse, pdf) and [`combine`] with a [`Heuristic`].
//! * Shifts between paths (gradient-domain rendering): [`replay_jacobian`]
//!   and [`weight_of_shift`], from the same conditional densities.
//! * Metropolis mutations ([`Mutation`]): proposals written as sampling
//!   code over a [`Mutator`]; [`transition_density`] runs the same code in
//!   density mode to give T(y | x), copied vertices counting as Dirac.
//! * Verification: [`harness`] checks any distribution or strategy against
//!   finite differences, chi-square histograms and MIS partition of unity.
//! * [`testing`]: a tiny analytic scene and strategies for examples and tests.
//!
//! Floating point: geometry is f32; densities, their products and MIS
//! ratios are f64.
#![deny(unsafe_code)]
#![warn(missing_docs, missing_debug_implementations)]

mod blocks;
mod choice;
mod density;
mod distribution;
mod frame;
pub mod harness;
mod join;
mod joins;
mod kept;
mod last_step;
mod mis;
mod mutation;
mod on_triangle;
mod primary;
pub mod primitives;
mod recycle;
mod rng;
mod sequence;
mod shift;
mod sometimes;
mod split;
mod strategy;
mod surface;
pub mod testing;
mod vertex;

pub use blocks::{Either, InFrame};
pub use choice::{Mixture, RussianRoulette, Select};
pub use density::{Density, Measure, PathDensity};
pub use distribution::{Coords, Distribution, Embed, Sample, Step, Uniforms};
pub use frame::{Frame, reflect, refract};
pub use join::Join;
pub use joins::Joins;
pub use last_step::{Aside, weight_of_last_step, weight_of_step};
pub use mis::{DensityCache, Heuristic, Weights, combine};
pub use mutation::{ChainPath, Mutation, Mutator, acceptance, propose, transition_density};
pub use on_triangle::OnTriangle;
pub use primary::{PrimarySamples, Replay};
pub use recycle::{Pooled, Recycle};
pub use rng::{Pcg32, UniformSource};
pub use sequence::{INLINE_VERTICES, RandomSequence};
pub use shift::{replay_jacobian, weight_of_shift};
pub use sometimes::Sometimes;
pub use split::{Split, Splits, densities_of_split, weight_of_split, weights_of_split_variants};
pub use strategy::{
    DynPairStrategy, DynStrategy, PairStrategy, Prefix, Produced, Sampled, StepKind, Strategy,
    StrategyRef,
};
pub use surface::{AtInfinity, DiracPoint, Intersect, OnSurface, ParallelRays, Segment};
pub use vertex::{Geometry, RayCaster, Vertex};

#[doc = include_str!("../../README.md")]
#[cfg(doctest)]
pub struct ReadmeDoctests;
