//! The harness on every primitive: agreement, inversion, finite-difference
//! Jacobian and chi-square (p > 0.01 at a fixed seed).

use aether_core::harness::{
    Categories, Check, Disk, Grid, Interval, SphereDirections, Square, Triangle, check,
};
use aether_core::primitives::*;
use aether_core::{Distribution, Embed, Frame, InFrame, Mixture, Select};
use glam::Vec3;
use proptest::prelude::*;

fn run<D>(d: &D, chart: &impl aether_core::harness::Chart<D::Value>) -> aether_core::harness::Report
where
    D: Distribution,
    D::Value: Embed + std::fmt::Debug,
{
    let report = check(d, chart, &Check::default()).unwrap_or_else(|f| panic!("{f}"));
    println!("{report}");
    report
}

#[test]
fn uniform_interval() {
    run(
        &UniformInterval::new(-1.0, 3.0),
        &Grid::new(Interval(-1.0, 3.0), 64),
    );
}

#[test]
fn uniform_square() {
    run(&UniformSquare, &Grid::new(Square, 16));
}

#[test]
fn discrete_distribution() {
    let d = DiscreteDistribution::new(&[0.5, 0.0, 2.0, 1.0, 0.25, 3.0]).unwrap();
    run(&d, &Categories(6));
}

#[test]
fn uniform_cells() {
    // A film of 7 × 5 pixels, and a choice among 4 techniques.
    for (columns, rows) in [(7, 5), (4, 1)] {
        let d = UniformCells::new(columns, rows);
        let r = run(&d, &Categories(d.len()));
        assert!((r.integral - 1.0).abs() < 1e-12, "{r}");
    }
}

#[test]
fn uniform_disk() {
    run(&UniformDisk::new(2.5), &Grid::new(Disk(2.5), 16));
}

#[test]
fn exponential_disk() {
    run(&ExponentialDisk::new(0.05, 2.0), &Grid::new(Disk(2.0), 16));
}

#[test]
fn exponential_cone() {
    let r = run(
        &ExponentialCone::new(0.15, 1.2),
        &Grid::new(SphereDirections, 16),
    );
    assert!(r.jacobian_checked > 400, "{r}");
}

#[test]
fn cosine_hemisphere() {
    let r = run(&CosineHemisphere, &Grid::new(SphereDirections, 16));
    assert!(r.jacobian_checked > 400, "{r}");
}

#[test]
fn uniform_hemisphere() {
    run(&UniformHemisphere, &Grid::new(SphereDirections, 16));
}

#[test]
fn uniform_sphere() {
    run(&UniformSphere, &Grid::new(SphereDirections, 16));
}

#[test]
fn uniform_cones_wide_and_tiny() {
    run(&UniformCone::new(0.3), &Grid::new(SphereDirections, 16));
    // A distant sphere light: sin² θ_max = 1e-6. The chart is the cone's own.
    let tiny = UniformCone::subtended(1e-6, 1.0);
    check(
        &tiny,
        &Grid::new(ConeChart(tiny.cos_max()), 16),
        &Check::default(),
    )
    .unwrap_or_else(|f| panic!("{f}"));
}

/// Directions of a cone by ((1 − cos θ)/(1 − cos θ_max), φ/2π).
struct ConeChart(f64);

impl aether_core::harness::Parameterization<Vec3> for ConeChart {
    fn dims(&self) -> usize {
        2
    }
    fn value(&self, s: [f64; 2]) -> Option<Vec3> {
        let omc = s[0] * (1.0 - self.0);
        let sin = (omc * (2.0 - omc)).sqrt();
        let phi = 2.0 * std::f64::consts::PI * s[1];
        Some(Vec3::new(
            (sin * phi.cos()) as f32,
            (sin * phi.sin()) as f32,
            (1.0 - omc) as f32,
        ))
    }
    fn coords(&self, w: &Vec3) -> Option<[f64; 2]> {
        let w = w.as_dvec3();
        let omc = (w.x * w.x + w.y * w.y) / (1.0 + w.z);
        let phi = w.y.atan2(w.x);
        Some([
            omc / (1.0 - self.0),
            if phi < 0.0 {
                phi / std::f64::consts::TAU + 1.0
            } else {
                phi / std::f64::consts::TAU
            },
        ])
    }
    fn jacobian(&self, _s: [f64; 2]) -> f64 {
        std::f64::consts::TAU * (1.0 - self.0)
    }
}

#[test]
fn uniform_triangle() {
    let (a, b, c) = (
        Vec3::new(0.0, 0.0, 1.0),
        Vec3::new(2.0, 0.5, 1.0),
        Vec3::new(0.5, 1.5, 1.5),
    );
    run(
        &UniformTriangle::new(a, b, c),
        &Grid::new(Triangle(a, b, c), 16),
    );
}

#[test]
fn piecewise_constant_1d() {
    let d = PiecewiseConstant1D::new(&[1.0, 0.0, 4.0, 2.0, 0.5, 3.0, 0.0, 1.0]).unwrap();
    run(&d, &Grid::new(Interval(0.0, 1.0), 32));
}

#[test]
fn piecewise_constant_with_one_cell_is_uniform() {
    // A box filter's table takes the one-cell shortcut; it is still a
    // primitive like the others, and returns its uniform unchanged.
    let d = PiecewiseConstant1D::new(&[2.5]).unwrap();
    run(&d, &Grid::new(Interval(0.0, 1.0), 32));
    for u in [0.0, 0.3, 0.999_999_9] {
        let s = d.sample(&[u]).unwrap();
        assert_eq!((s.value, s.density.value()), (u, 1.0));
    }
    run(
        &PiecewiseConstant2D::new(&[0.7], 1, 1).unwrap(),
        &Grid::new(Square, 24),
    );
}

#[test]
fn piecewise_constant_2d() {
    let values: Vec<f64> = (0..12 * 8)
        .map(|i| ((i * 7919) % 13) as f64 + if i % 5 == 0 { 0.0 } else { 0.5 })
        .collect();
    let d = PiecewiseConstant2D::new(&values, 12, 8).unwrap();
    run(&d, &Grid::new(Square, 24));
}

#[test]
fn frame_change_keeps_density() {
    let frame = Frame::from_normal(Vec3::new(0.3, -0.4, 0.866).normalize());
    run(
        &InFrame::new(frame, CosineHemisphere),
        &Grid::new(SphereDirections, 16),
    );
}

#[test]
fn ggx_visible_normals_isotropic_and_anisotropic() {
    for (ax, ay, wi) in [
        (0.3, 0.3, Vec3::new(0.5, 0.1, 0.86)),
        (0.08, 0.5, Vec3::new(-0.7, 0.3, 0.3)),
        (0.9, 0.9, Vec3::Z),
    ] {
        run(
            &GgxVisibleNormals::new(ax, ay, wi.normalize()),
            &Grid::new(SphereDirections, 16),
        );
    }
}

#[test]
fn beckmann_normals() {
    for alpha in [0.1, 0.4, 1.0] {
        run(
            &BeckmannNormals::new(alpha),
            &Grid::new(SphereDirections, 16),
        );
    }
}

#[test]
fn microfacet_reflection_has_half_vector_jacobian() {
    let wi = Vec3::new(0.4, -0.2, 0.89).normalize();
    run(
        &Reflect::new(wi, GgxVisibleNormals::new(0.25, 0.4, wi)),
        &Grid::new(SphereDirections, 16),
    );
    run(
        &Reflect::new(wi, BeckmannNormals::new(0.3)),
        &Grid::new(SphereDirections, 16),
    );
}

#[test]
fn microfacet_refraction_has_half_vector_jacobian() {
    let wi = Vec3::new(0.5, 0.2, 0.84).normalize();
    // Entering glass, and leaving it (where total internal reflection voids samples).
    run(
        &Refract::new(wi, 1.5, GgxVisibleNormals::new(0.3, 0.3, wi)),
        &Grid::new(SphereDirections, 16),
    );
    run(
        &Refract::new(wi, 1.0 / 1.5, BeckmannNormals::new(0.2)),
        &Grid::new(SphereDirections, 16),
    );
}

#[test]
fn smooth_refraction_carries_snells_jacobian() {
    // Into glass, out of it (total internal reflection voids samples), into water.
    for eta in [1.5, 1.0 / 1.5, 1.33] {
        let r = run(
            &SmoothRefraction::new(CosineHemisphere, eta),
            &Grid::new(SphereDirections, 16),
        );
        // Leaving glass, more than half the hemisphere reflects totally.
        assert!(r.jacobian_checked > 150, "{r}");
    }
    // A Dirac direction refracts into an atom whose mass is the Jacobian
    // the continuous case was just checked for: the lobe of a light path
    // through glass, measured as a camera path measures it.
    for (w, eta) in [
        (Vec3::new(0.5, 0.2, 0.84), 1.5),
        (Vec3::new(0.9, 0.1, 0.1), 1.5),
        (Vec3::new(0.3, -0.4, 0.87), 1.0 / 1.5),
    ] {
        let w = w.normalize();
        let dirac = SmoothRefraction::new(DiracDirection::new(w, 1.0), eta);
        let atom = dirac.sample(&[]).expect("no total internal reflection");
        assert_eq!(atom.density.dirac_order(), 1);
        let smooth = SmoothRefraction::new(CosineHemisphere, eta).density(&atom.value);
        let jacobian = smooth.value() / CosineHemisphere.density(&w).value();
        let mass = dirac.density(&atom.value).value();
        assert!(
            (mass / jacobian - 1.0).abs() < 1e-4,
            "{mass} against {jacobian}"
        );
        assert!((atom.density.value() / mass - 1.0).abs() < 1e-5);
    }
}

#[test]
fn dirac_direction_is_an_atom() {
    let w = Vec3::new(0.0, 0.6, 0.8);
    let r = run(
        &DiracDirection::new(w, 1.0),
        &Grid::new(SphereDirections, 8),
    );
    assert_eq!(r.jacobian_checked, 0);
    assert!(
        DiracDirection::new(w, 1.0)
            .density(&Vec3::new(0.0, 0.61, 0.79).normalize())
            .is_zero()
    );
}

#[test]
fn lobe_mixture_with_a_dirac_lobe() {
    // A glossy lobe and a mirror lobe: the mixture's density sums the
    // continuous lobe, and the mirror direction is an atom of mass 0.3.
    let wi = Vec3::new(0.3, 0.0, 0.95).normalize();
    let choice = DiscreteDistribution::new(&[0.7, 0.3]).unwrap();
    let lobes = |i: usize| match i {
        0 => aether_core::Either::Left(Reflect::new(wi, GgxVisibleNormals::new(0.3, 0.3, wi))),
        _ => {
            aether_core::Either::Right(DiracDirection::new(aether_core::reflect(wi, Vec3::Z), 1.0))
        }
    };
    let r = run(
        &Mixture::new(&choice, 2, lobes),
        &Grid::new(SphereDirections, 16),
    );
    assert!((r.integral - 1.0).abs() < 0.01, "{r}");
}

#[test]
fn select_by_lookup_over_triangles() {
    let tris = [
        UniformTriangle::new(Vec3::ZERO, Vec3::X, Vec3::Y),
        UniformTriangle::new(Vec3::X, Vec3::new(3.0, 0.0, 0.0), Vec3::new(1.0, 1.0, 0.0)),
    ];
    let by_area = DiscreteDistribution::new(&[tris[0].area(), tris[1].area()]).unwrap();
    let which = |p: &Vec3| (0..2).find(|&i| tris[i].barycentrics(*p).is_some());
    let d = Select::new(&by_area, 2, |i| tris[i], which);
    // Uniform over the union: density 1 / total area everywhere.
    let total = tris[0].area() + tris[1].area();
    assert!((d.density(&Vec3::new(0.2, 0.2, 0.0)).value() - 1.0 / total).abs() < 1e-9);
    run(&d, &Grid::new(Square3(3.0), 24));
}

/// The rectangle [0, w] × [0, 1] in the z = 0 plane.
struct Square3(f32);

impl aether_core::harness::Parameterization<Vec3> for Square3 {
    fn dims(&self) -> usize {
        2
    }
    fn value(&self, s: [f64; 2]) -> Option<Vec3> {
        Some(Vec3::new(s[0] as f32 * self.0, s[1] as f32, 0.0))
    }
    fn coords(&self, p: &Vec3) -> Option<[f64; 2]> {
        Some([f64::from(p.x / self.0), f64::from(p.y)])
    }
    fn jacobian(&self, _s: [f64; 2]) -> f64 {
        f64::from(self.0)
    }
}

/// Parameter sets in the GGX sweep.
const SWEEP: u32 = 64;

proptest! {
    #![proptest_config(ProptestConfig {
        cases: SWEEP,
        failure_persistence: None,
        rng_seed: proptest::test_runner::RngSeed::Fixed(0xa37e),
        ..ProptestConfig::default()
    })]

    /// The harness over random parameters: GGX roughness and view direction.
    /// With 64 chi-square tests, each is held to 0.01 / 64 (Bonferroni), so
    /// that the sweep as a whole fails a correct density with probability 0.01.
    #[test]
    fn ggx_over_parameters(ax in 0.05f32..1.0, ay in 0.05f32..1.0, x in -0.9f32..0.9, y in -0.9f32..0.9) {
        let wi = Vec3::new(x, y, 0.2 + (1.0 - x * x - y * y).max(0.0).sqrt()).normalize();
        let config = Check { cases: 64, samples: 20_000, significance: 0.01 / f64::from(SWEEP), ..Check::default() };
        let d = Reflect::new(wi, GgxVisibleNormals::new(ax, ay, wi));
        check(&d, &Grid::new(SphereDirections, 12), &config).map_err(|f| TestCaseError::fail(f.to_string()))?;
    }

    /// Round trips of the concentric map and cone over the whole square.
    #[test]
    fn disk_and_cone_round_trip(u0 in 0.0f32..1.0, u1 in 0.0f32..1.0, c in -0.99f64..0.99) {
        let p = UniformDisk::concentric([u0, u1]);
        let v = UniformDisk::concentric_inverse(p).unwrap();
        prop_assert!((v[0] - u0).abs() < 1e-4 && (v[1] - u1).abs() < 1e-4);
        let cone = UniformCone::new(c);
        let w = cone.sample(&[u0, u1]).unwrap().value;
        let back = cone.invert(&w).unwrap();
        prop_assert!((back[0] - u0).abs() < 1e-3);
    }
}
