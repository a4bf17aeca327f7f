//! Structural combinators: change of frame and a choice between two kinds
//! of block.

use glam::Vec3;

use crate::density::Density;
use crate::distribution::{Distribution, Sample, Uniforms};
use crate::frame::Frame;

/// Maps directions of `inner` from a local frame to the world.
///
/// Density: unchanged (a rotation has unit Jacobian).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InFrame<D> {
    frame: Frame,
    inner: D,
}

impl<D: Distribution<Value = Vec3>> InFrame<D> {
    /// Directions of `inner` expressed in `frame`.
    #[inline(always)]
    pub fn new(frame: Frame, inner: D) -> Self {
        InFrame { frame, inner }
    }
}

impl<D: Distribution<Value = Vec3>> Distribution for InFrame<D> {
    type Value = Vec3;
    fn dims(&self) -> usize {
        self.inner.dims()
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<Vec3>> {
        self.inner
            .sample(u)
            .map(|s| s.map(|w| self.frame.to_world(w)))
    }
    fn density(&self, w: &Vec3) -> Density {
        self.inner.density(&self.frame.to_local(*w))
    }
    fn invert(&self, w: &Vec3) -> Option<Uniforms> {
        self.inner.invert(&self.frame.to_local(*w))
    }
    fn has_overlapping_branches(&self) -> bool {
        self.inner.has_overlapping_branches()
    }
}

/// One of two blocks with the same value type, chosen by the strategy from
/// its deterministic inputs (for instance a Dirac or a rough lobe depending
/// on the material).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Either<A, B> {
    /// The first kind.
    Left(A),
    /// The second kind.
    Right(B),
}

impl<A: Distribution, B: Distribution<Value = A::Value>> Distribution for Either<A, B> {
    type Value = A::Value;
    fn dims(&self) -> usize {
        match self {
            Either::Left(a) => a.dims(),
            Either::Right(b) => b.dims(),
        }
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<A::Value>> {
        match self {
            Either::Left(a) => a.sample(u),
            Either::Right(b) => b.sample(u),
        }
    }
    fn density(&self, v: &A::Value) -> Density {
        match self {
            Either::Left(a) => a.density(v),
            Either::Right(b) => b.density(v),
        }
    }
    fn invert(&self, v: &A::Value) -> Option<Uniforms> {
        match self {
            Either::Left(a) => a.invert(v),
            Either::Right(b) => b.invert(v),
        }
    }
    fn has_overlapping_branches(&self) -> bool {
        match self {
            Either::Left(a) => a.has_overlapping_branches(),
            Either::Right(b) => b.has_overlapping_branches(),
        }
    }
}

/// A block that may be absent: a strategy with nothing to sample at this
/// vertex (no BSDF at a point light) samples nothing (a void sample), and
/// every value has density zero under it.
impl<D: Distribution> Distribution for Option<D> {
    type Value = D::Value;
    fn dims(&self) -> usize {
        self.as_ref().map_or(0, Distribution::dims)
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<D::Value>> {
        self.as_ref()?.sample(u)
    }
    fn density(&self, v: &D::Value) -> Density {
        match self {
            Some(d) => d.density(v),
            None => Density::zero(crate::density::Measure::Discrete),
        }
    }
    fn invert(&self, v: &D::Value) -> Option<Uniforms> {
        self.as_ref()?.invert(v)
    }
    fn has_overlapping_branches(&self) -> bool {
        self.as_ref()
            .is_some_and(Distribution::has_overlapping_branches)
    }
}
