//! The harness must be able to fail: deliberately wrong primitives.

use aether_core::harness::{Categories, Check, Failure, Grid, SphereDirections, check};
use aether_core::primitives::{
    CosineHemisphere, DiscreteDistribution, SmoothRefraction, UniformCells, UniformHemisphere,
};
use aether_core::{Density, Distribution, Either, Mixture, Sample, Uniforms};
use glam::Vec3;

/// Cosine-weighted directions whose Jacobian is wrong by 5 % in a way
/// sampling and density mode agree on: only the Jacobian check sees it.
struct WrongJacobian;

impl Distribution for WrongJacobian {
    type Value = Vec3;
    fn dims(&self) -> usize {
        2
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<Vec3>> {
        let s = CosineHemisphere.sample(u)?;
        Some(Sample::new(s.value, self.density(&s.value)))
    }
    fn density(&self, w: &Vec3) -> Density {
        CosineHemisphere
            .density(w)
            .scale(1.0 + 0.05 * f64::from(w.x).abs())
    }
    fn invert(&self, w: &Vec3) -> Option<Uniforms> {
        CosineHemisphere.invert(w)
    }
}

/// Smooth refraction into glass with η² left out of Snell's Jacobian (the
/// factor a light path through glass once carried by hand), consistently
/// in both modes.
struct RefractionWithoutEta;

const GLASS: f32 = 1.5;

impl Distribution for RefractionWithoutEta {
    type Value = Vec3;
    fn dims(&self) -> usize {
        2
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<Vec3>> {
        let s = SmoothRefraction::new(CosineHemisphere, GLASS).sample(u)?;
        Some(Sample::new(s.value, self.density(&s.value)))
    }
    fn density(&self, w: &Vec3) -> Density {
        let eta = f64::from(GLASS);
        SmoothRefraction::new(CosineHemisphere, GLASS)
            .density(w)
            .scale(1.0 / (eta * eta))
    }
    fn invert(&self, w: &Vec3) -> Option<Uniforms> {
        SmoothRefraction::new(CosineHemisphere, GLASS).invert(w)
    }
}

/// Records the right density while sampling, but evaluates another.
struct DisagreeingModes;

impl Distribution for DisagreeingModes {
    type Value = Vec3;
    fn dims(&self) -> usize {
        2
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<Vec3>> {
        CosineHemisphere.sample(u)
    }
    fn density(&self, w: &Vec3) -> Density {
        UniformHemisphere.density(w)
    }
    fn invert(&self, w: &Vec3) -> Option<Uniforms> {
        CosineHemisphere.invert(w)
    }
}

/// An inverse that returns the wrong uniforms.
struct WrongInverse;

impl Distribution for WrongInverse {
    type Value = Vec3;
    fn dims(&self) -> usize {
        2
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<Vec3>> {
        CosineHemisphere.sample(u)
    }
    fn density(&self, w: &Vec3) -> Density {
        CosineHemisphere.density(w)
    }
    fn invert(&self, w: &Vec3) -> Option<Uniforms> {
        CosineHemisphere.invert(&Vec3::new(w.y, w.x, w.z))
    }
}

/// A mixture whose density forgets one lobe. Its modes agree and the
/// Jacobian check does not apply to overlapping lobes: only the histogram
/// can see it.
struct ForgetfulMixture(DiscreteDistribution);

impl Distribution for ForgetfulMixture {
    type Value = Vec3;
    fn dims(&self) -> usize {
        2
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<Vec3>> {
        let s = self.mixture().sample(u)?;
        Some(Sample::new(s.value, self.density(&s.value)))
    }
    fn density(&self, w: &Vec3) -> Density {
        CosineHemisphere.density(w).scale(self.0.probability(0))
    }
    fn invert(&self, w: &Vec3) -> Option<Uniforms> {
        self.mixture().invert(w)
    }
    fn has_overlapping_branches(&self) -> bool {
        true
    }
}

impl ForgetfulMixture {
    fn mixture(&self) -> impl Distribution<Value = Vec3> + '_ {
        Mixture::new(&self.0, 2, |i| {
            if i == 0 {
                Either::Left(CosineHemisphere)
            } else {
                Either::Right(UniformHemisphere)
            }
        })
    }
}

fn run(d: &impl Distribution<Value = Vec3>) -> Failure {
    let failure = check(d, &Grid::new(SphereDirections, 16), &Check::default())
        .expect_err("the harness must reject this distribution");
    println!("{failure}");
    failure
}

#[test]
fn wrong_jacobian_fails_the_jacobian_check() {
    assert!(matches!(run(&WrongJacobian), Failure::Jacobian { .. }));
}

#[test]
fn refraction_without_eta_squared_fails_the_jacobian_check() {
    assert!(matches!(
        run(&RefractionWithoutEta),
        Failure::Jacobian { .. }
    ));
}

#[test]
fn disagreeing_modes_fail_the_agreement_check() {
    assert!(matches!(run(&DisagreeingModes), Failure::Agreement { .. }));
}

#[test]
fn wrong_inverse_fails_the_inversion_check() {
    assert!(matches!(run(&WrongInverse), Failure::Inversion { .. }));
}

#[test]
fn forgotten_lobe_fails_the_chi_square_test() {
    let d = ForgetfulMixture(DiscreteDistribution::new(&[0.7, 0.3]).unwrap());
    assert!(matches!(run(&d), Failure::ChiSquare { .. }));
}

/// A pixel choice on a 7 × 5 film whose probability counts the columns
/// only, in both modes: the estimate of the pixel it picks would be
/// weighted by 7, not 35.
struct ColumnsOnly(UniformCells);

impl Distribution for ColumnsOnly {
    type Value = usize;
    fn dims(&self) -> usize {
        2
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<usize>> {
        let s = self.0.sample(u)?;
        Some(Sample::new(s.value, self.density(&s.value)))
    }
    fn density(&self, i: &usize) -> Density {
        self.0.density(i).scale(5.0)
    }
    fn invert(&self, i: &usize) -> Option<Uniforms> {
        self.0.invert(i)
    }
}

#[test]
fn a_pixel_choice_that_forgets_the_rows_fails_the_chi_square_test() {
    let d = ColumnsOnly(UniformCells::new(7, 5));
    let failure = check(&d, &Categories(35), &Check::default()).expect_err("must fail");
    assert!(
        matches!(
            failure,
            Failure::ChiSquare { .. } | Failure::IntegralAboveOne { .. }
        ),
        "{failure}"
    );
}

/// Cosine directions that record density zero: produced, yet "impossible".
struct ZeroDensity;

impl Distribution for ZeroDensity {
    type Value = Vec3;
    fn dims(&self) -> usize {
        2
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<Vec3>> {
        CosineHemisphere
            .sample(u)
            .map(|s| Sample::new(s.value, Density::zero(aether_core::Measure::SolidAngle)))
    }
    fn density(&self, _w: &Vec3) -> Density {
        Density::zero(aether_core::Measure::SolidAngle)
    }
    fn invert(&self, w: &Vec3) -> Option<Uniforms> {
        CosineHemisphere.invert(w)
    }
}

#[test]
fn zero_density_samples_fail_the_agreement_check() {
    assert!(matches!(
        run(&ZeroDensity),
        Failure::ZeroDensitySample { .. }
    ));
}

/// A bounce that states a memory (the number it holds) shorter than the
/// two conditioning vertices it reads: with none, its densities are cached
/// under keys that collide; with one, it turns to the side its path came
/// from by a vertex it says it does not read.
struct Forgetful<'s>(aether_core::testing::Bounce<'s>, usize);

impl aether_core::Strategy<aether_core::testing::TestVertex> for Forgetful<'_> {
    fn distribution<'a>(
        &'a self,
        prefix: aether_core::Prefix<'a, aether_core::testing::TestVertex>,
    ) -> impl Distribution<Value = aether_core::Step<aether_core::testing::TestVertex>> + 'a {
        self.0.distribution(prefix)
    }
    fn memory(&self) -> usize {
        self.1
    }
}

#[test]
fn misstated_memory_fails_the_mis_check() {
    use aether_core::harness::{Technique, check_mis};
    use aether_core::testing::{BidirectionalFixture, TestScene};
    let scene = TestScene::open_box();
    let f = BidirectionalFixture::new(&scene);
    let forgetful = Forgetful(f.bounce, 0);
    // Five vertices: the middle one has the same depth from either end, so
    // its forward and reversed densities share a key when the conditioning
    // vertices are left out of it.
    fn make<'s>(
        f: &'s BidirectionalFixture<'_>,
        b: &'s dyn aether_core::DynStrategy<aether_core::testing::TestVertex>,
    ) -> [Technique<'s, aether_core::testing::TestVertex>; 3] {
        [
            Technique::new()
                .forward(&f.camera)
                .forward(&f.look)
                .forward(b)
                .forward(b)
                .reversed(&f.light),
            Technique::new()
                .forward(&f.camera)
                .forward(&f.look)
                .forward(b)
                .reversed(b)
                .reversed(&f.light),
            Technique::new()
                .forward(&f.camera)
                .forward(&f.look)
                .reversed(b)
                .reversed(b)
                .reversed(&f.light),
        ]
    }
    let e = check_mis(
        &make(&f, &forgetful),
        aether_core::Heuristic::POWER,
        300,
        &mut aether_core::Pcg32::new(1, 2),
    )
    .expect_err("collisions must show");
    println!("{e}");
    // The honest bounce passes the same check.
    let honest = make(&f, &f.bounce);
    check_mis(
        &honest,
        aether_core::Heuristic::POWER,
        200,
        &mut aether_core::Pcg32::new(1, 2),
    )
    .unwrap();
}

#[test]
fn misstated_memory_fails_the_strategy_check() {
    use aether_core::harness::check_strategy;
    use aether_core::testing::{Bounce, SphereChart, TestScene, TestVertex};
    let scene = TestScene::open_box();
    // A point on the sphere seen from its centre: the bounce turns inward,
    // which the stated memory (the point alone) cannot see.
    let (center, radius, sphere) = (Vec3::new(0.4, 0.3, 0.35), 0.35, 6);
    let on = scene.vertex_on(sphere, center + Vec3::new(0.0, 0.0, radius));
    let prefix = [TestVertex::point(center), on];
    let chart = Grid::new(SphereChart::new(&scene, sphere), 8);
    let shortsighted = Forgetful(Bounce::new(&scene), 1);
    let failure = check_strategy(&shortsighted, &prefix, &chart, &Check::default())
        .expect_err("the misstated memory must show");
    assert!(
        matches!(failure, Failure::Memory { memory: 1, .. }),
        "{failure}"
    );
    println!("{failure}");
}
