//! Shifts: a path of one pixel mapped to a path of another, as gradient-domain
//! rendering needs them.
//!
//! A shift builds the offset path ȳ from the base path x̄. Vertices it
//! *replays* come from the same strategies, fed the same uniforms u,
//! conditioned on the offset's own earlier vertices; vertices it *copies*
//! (after a reconnection) are the base's. A replayed vertex maps as
//! u ↦ x (density p_x) and u ↦ y (density p_y), so ∂y/∂x = p_x(x) / p_y(y);
//! a copied vertex maps by the identity of the area measure. The Jacobian
//! of the whole shift is the product over replayed vertices: a ratio of
//! conditional densities of the same sampling code ([`replay_jacobian`]),
//! which the language already evaluates.

use std::ops::Range;

use smallvec::SmallVec;

use crate::density::{Density, Measure, PathDensity};
use crate::mis::Heuristic;
use crate::sequence::RandomSequence;
use crate::vertex::Vertex;

/// The Jacobian |∂ȳ/∂x̄| of the vertices at `replayed`, which `offset`
/// sampled with the same strategies and uniforms as `base` (each in its own
/// context): the product of `base`'s densities of those steps over
/// `offset`'s. Zero if `base` cannot have produced them, infinite if
/// `offset` cannot; Dirac factors must match in number.
///
/// ```
/// use aether_core::{Pcg32, RandomSequence, replay_jacobian};
/// use aether_core::testing::{CameraPoint, LookDown, TestScene};
/// use glam::Vec3;
///
/// let scene = TestScene::open_box();
/// let (high, low) = (CameraPoint { position: Vec3::new(0.0, 0.0, 1.5) }, CameraPoint::default());
/// let look = LookDown::new(&scene);
/// let (mut base, mut offset) = (RandomSequence::new(), RandomSequence::new());
/// base.append(&high).append_sample(&look, &mut Pcg32::new(5, 0));
/// offset.append(&low).append_sample(&look, &mut Pcg32::new(5, 0));
/// // The same direction from two heights: the offset's footprint is smaller.
/// let j = replay_jacobian(&base, &offset, 0..2);
/// assert!(j > 0.0 && j < 1.0);
/// ```
#[must_use]
pub fn replay_jacobian<V: Vertex>(
    base: &RandomSequence<'_, V>,
    offset: &RandomSequence<'_, V>,
    replayed: Range<usize>,
) -> f64 {
    offset
        .pdf_of_steps(replayed.clone())
        .ratio_to(base.pdf_of_steps(replayed))
}

/// The MIS weight of a base path, sampled by technique `own` of its pixel,
/// and of the offset path it shifts to, with the neighbour pixel's paths
/// shifted back as the competing techniques.
///
/// `base` and `offset` hold each path's density under every technique of
/// its own pixel ([`densities_of_split`](crate::densities_of_split)); the
/// offset comes with the shift's Jacobian J (`None` if the shift failed:
/// no path of the neighbour shifts back to this one). Shifted into the
/// base's pixel, the neighbour's technique k produces the base path with
/// density J·p_k(ȳ), so the weight is
/// h(p_own(x̄)) / (Σ_k h(p_k(x̄)) + Σ_k h(J·p_k(ȳ))) for the heuristic h.
/// The same weight applies to the offset's contribution f(ȳ)·J / p_own(x̄)
/// to the neighbour: both pixels' weights of a pair of paths add up to one.
///
/// ```
/// use aether_core::{Density, Heuristic, Measure, PathDensity, weight_of_shift};
/// let p = |v| PathDensity::ONE.times(Density::new(v, Measure::Area));
/// let (x, y) = ([p(1.0), p(3.0)], [p(2.0), p(2.0)]);
/// let from_x = weight_of_shift(&x, Some((&y, 0.5)), 0, Heuristic::Balance);
/// let from_y = weight_of_shift(&y, Some((&x, 2.0)), 0, Heuristic::Balance);
/// // Balance heuristic over {1, 3} and 0.5 · {2, 2}.
/// assert!((from_x - 1.0 / 6.0).abs() < 1e-12 && (from_y - 1.0 / 6.0).abs() < 1e-12);
/// ```
#[must_use]
pub fn weight_of_shift(
    base: &[PathDensity],
    offset: Option<(&[PathDensity], f64)>,
    own: usize,
    heuristic: Heuristic,
) -> f64 {
    let mut all: SmallVec<[PathDensity; 48]> = base.iter().copied().collect();
    if let Some((offset, jacobian)) = offset.filter(|(_, j)| j.is_finite() && *j > 0.0) {
        let scale = Density::new(jacobian, Measure::Discrete);
        all.extend(offset.iter().map(|p| p.times(scale)));
    }
    heuristic.weight(&all, own)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::UniformSource;
    use crate::testing::{Bounce, TestScene};
    use glam::Vec3;

    /// Uniforms from a list, for sampling the same step at nearby points.
    struct Fixed([f32; 2], usize);

    impl UniformSource for Fixed {
        fn next_f32(&mut self) -> f32 {
            self.1 += 1;
            self.0[(self.1 - 1) % 2]
        }
    }

    /// A bounce from `from` (seen from the camera) with uniforms `u`.
    fn bounce<'s>(
        scene: &'s TestScene,
        step: &'s Bounce<'s>,
        from: Vec3,
        u: [f32; 2],
    ) -> Option<RandomSequence<'s, crate::testing::TestVertex>> {
        let camera = scene.vertex_on(0, Vec3::new(0.0, 0.0, 1.0));
        let mut path = RandomSequence::given([camera, scene.vertex_on(0, from)]);
        path.append_sample(step, &mut Fixed(u, 0)).then_some(path)
    }

    /// The area of the parallelogram that the hit sweeps as u moves along
    /// each axis (central differences: hits at u ± h along u₁, then along
    /// u₂), if all four land on one shape.
    fn footprint(hits: [Option<RandomSequence<'_, crate::testing::TestVertex>>; 4]) -> Option<f32> {
        let mut v = SmallVec::<[crate::testing::TestVertex; 4]>::new();
        for hit in hits {
            v.push(hit?.vertices()[2]);
        }
        if v.iter().any(|h| h.shape != v[0].shape) {
            return None;
        }
        let (du, dv) = (v[0].position - v[1].position, v[2].position - v[3].position);
        Some(du.cross(dv).length())
    }

    #[test]
    fn replay_jacobian_matches_finite_differences() {
        let scene = TestScene::open_box();
        let step = Bounce::new(&scene);
        let (from_x, from_y) = (Vec3::new(-0.3, 0.2, 0.0), Vec3::new(0.2, -0.5, 0.0));
        let mut checked = 0;
        for i in 0..12 {
            for j in 0..12 {
                let u = [0.1 + 0.07 * i as f32, 0.1 + 0.07 * j as f32];
                let (Some(x), Some(y)) = (
                    bounce(&scene, &step, from_x, u),
                    bounce(&scene, &step, from_y, u),
                ) else {
                    continue;
                };
                // The ratio of footprints at step h, where both are on one shape.
                let numeric = |h: f32| {
                    let at = |from| {
                        let moved = [[h, 0.0], [-h, 0.0], [0.0, h], [0.0, -h]];
                        moved.map(|[a, b]| bounce(&scene, &step, from, [u[0] + a, u[1] + b]))
                    };
                    Some(f64::from(footprint(at(from_y))? / footprint(at(from_x))?))
                };
                let (Some(fine), Some(coarse)) = (numeric(1e-3), numeric(2e-3)) else {
                    continue;
                };
                // Near a silhouette the differences have not converged: skip.
                if (fine / coarse - 1.0).abs() > 1e-3 {
                    continue;
                }
                let replayed = replay_jacobian(&x, &y, 2..3);
                assert!(
                    (replayed / fine - 1.0).abs() < 2e-3,
                    "u = {u:?}: replay {replayed}, finite differences {fine}"
                );
                checked += 1;
            }
        }
        assert!(checked > 40, "only {checked} pairs hit one shape each");
    }

    #[test]
    fn weights_of_a_pair_add_up_to_one() {
        let p = |v: f64| PathDensity::ONE.times(Density::new(v, Measure::Area));
        let x = [p(0.7), p(2.5), p(0.0)];
        let y = [p(1.9), p(0.0), p(4.0)];
        for heuristic in [Heuristic::Balance, Heuristic::POWER, Heuristic::Power(3.0)] {
            for jacobian in [0.01, 0.8, 1.0, 37.0] {
                let sum: f64 = (0..3)
                    .map(|k| {
                        weight_of_shift(&x, Some((&y, jacobian)), k, heuristic)
                            + weight_of_shift(&y, Some((&x, 1.0 / jacobian)), k, heuristic)
                    })
                    .sum();
                assert!(
                    (sum - 1.0).abs() < 1e-12,
                    "{heuristic:?}, J = {jacobian}: {sum}"
                );
            }
        }
        // A failed shift leaves the base pixel's own weights.
        let alone: f64 = (0..3)
            .map(|k| weight_of_shift(&x, None, k, Heuristic::POWER))
            .sum();
        assert!((alone - 1.0).abs() < 1e-12);
    }
}
