//! Light-transport algorithms written as short combinators over
//! [`aether_core::RandomSequence`] and [`aether_core::combine`], plus the
//! film, the render loop and the command-line program.
//!
//! This crate is being built (issue "integrators as short combinators").
#![deny(unsafe_code)]

pub use aether_strategies as strategies;
