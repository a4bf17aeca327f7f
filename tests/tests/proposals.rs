//! Veach's mutations propose what their transition density says: from a
//! fixed path x of the caustic room ([`tests::caustic_room`]), 10⁶
//! proposals y ~ T(· | x) of the whole mixture are binned on a chart of the
//! vertices they move, and the histogram is compared (chi-square, p > 0.01)
//! with T(y | x) integrated over each cell, T as the language derives it
//! ([`transition_density`]).
//!
//! * From a path whose first hit is diffuse, the proposals that move that
//!   vertex alone: the lens perturbation's and the bidirectional mutation's
//!   (which deletes it and samples a new one from the camera), binned by
//!   the direction from the camera. T is the sum of the two branches.
//! * From a path lit through the mirror sphere (camera, floor, mirror,
//!   light), the proposals that move the mirror vertex and the floor vertex
//!   its reflection leads to: the caustic perturbation's (a turn at the
//!   light) and the bidirectional mutation's (a new emitted direction, then
//!   the reflection), binned by the direction from the light; the floor
//!   vertex is a function of the mirror vertex (a Dirac reflection), so the
//!   chart is two-dimensional and T, a density times a Dirac mass there, is
//!   a density on it.
//!
//! Proposals that move other vertices are counted as "elsewhere", against
//! one minus the chart's integral. The multi-chain perturbation moves two
//! vertices freely (the film point and a turn): `multi_chain.rs` checks it
//! on a four-dimensional chart.
//!
//! Planted faults, as `harness_fails.rs` plants them for primitives: a
//! mutation whose lens branch doubles its density, and one whose film
//! strategy forgets the solid angle → area Jacobian, each fail the test;
//! both still satisfy the detailed-balance equality f(x) T(y|x) a(x→y) =
//! f(y) T(x|y) a(y→x) exactly, which is why that equality proves nothing
//! about T.

use aether_core::harness::{Chart, Check, Grid, Misreported, Parameterization, check_histogram};
use aether_core::primitives::ExponentialDisk;
use aether_core::{
    ChainPath, Distribution, Mutation, Mutator, Pcg32, Prefix, Step, Strategy, acceptance, propose,
    transition_density,
};
use aether_strategies::bsdf::Transport;
use aether_strategies::camera::{Camera, PerturbedFilm};
use aether_strategies::mutations::{Kind, MutationSettings};
use aether_strategies::scattering::{BsdfSampling, Roulette};
use aether_strategies::scene::Scene;
use aether_strategies::vertex::SceneVertex;
use integrators::mlt::MltSettings;
use integrators::mlt::veach::VeachMlt;
use tests::caustic_room;
use tests::cone::{Angles, Cone};
use tests::proposal::{On, Proposal, Proposals, path_over};

/// Proposals that share every vertex of x but those `build` makes from the
/// hit of a cone: the chart's points are `build(hit)`.
struct Moved<'a, B> {
    cone: Cone<'a>,
    x: &'a ChainPath<SceneVertex>,
    /// The vertex the cone's hit becomes.
    index: usize,
    /// The vertices that move.
    moved: &'a [usize],
    build: B,
}

impl<B: Fn(SceneVertex) -> Option<ChainPath<SceneVertex>>> Parameterization<Proposal>
    for Moved<'_, B>
{
    fn dims(&self) -> usize {
        2
    }
    fn value(&self, s: [f64; 2]) -> Option<Proposal> {
        self.cone.hit(s).and_then(&self.build).map(Proposal)
    }
    fn coords(&self, y: &Proposal) -> Option<[f64; 2]> {
        let (y, x) = (&y.0, self.x);
        let same = y.len() == x.len()
            && (0..x.len()).all(|i| self.moved.contains(&i) != y.shares(i, x, i));
        if !same {
            return None;
        }
        // On the chart's manifold: the other moved vertices are where the
        // hit leads (a proposal that moves them freely is elsewhere).
        let v = y.vertices()[self.index];
        let on = (self.build)(v)?;
        let close = self.moved.iter().all(|&i| {
            let (a, b) = (on.vertices()[i].position, y.vertices()[i].position);
            a.distance(b) <= 1e-3 * a.length().max(1.0)
        });
        if !close {
            return None;
        }
        // Seen from the cone's apex (a vertex hidden from it, which another
        // branch may propose, is not the hit at its coordinates).
        let s = self.cone.coords(&Step::Vertex(v))?;
        let seen = self.cone.hit(s.map(|c| c.clamp(0.0, 1.0)))?;
        (seen.position.distance(v.position) <= 1e-3 * v.position.length().max(1.0)).then_some(s)
    }
    /// The cone's area element, and for each vertex the hit leads to by a
    /// Dirac reflection, the r² / |cos θ| that T's Dirac factor carries
    /// there (its mass is expressed in that vertex's area measure, which
    /// the chart's points do not spread over).
    fn jacobian(&self, s: [f64; 2]) -> f64 {
        let Some(Proposal(y)) = self.value(s) else {
            return 0.0;
        };
        let v = y.vertices();
        let followed = self.moved.iter().filter(|&&i| i != self.index);
        followed.fold(self.cone.jacobian(s), |j, &i| {
            let from = if i < self.index { i + 1 } else { i - 1 };
            let d = v[i].position - v[from].position;
            let cos = d.normalize().dot(v[i].geometric_normal).abs();
            j * f64::from(d.length_squared() / cos)
        })
    }
}

fn config(samples: usize) -> Check {
    Check {
        samples,
        ..Check::default()
    }
}

/// The chi-square test of `mutation`'s proposals from `x` on `chart`.
fn histogram<M: Mutation<SceneVertex>>(
    mutation: &M,
    x: &ChainPath<SceneVertex>,
    chart: &impl aether_core::harness::Chart<Proposal>,
    samples: usize,
) -> Result<aether_core::harness::Report, aether_core::harness::Failure> {
    check_histogram(&Proposals { mutation, x }, chart, &config(samples))
}

/// A path camera → diffuse → … whose first hit is diffuse, and the chart
/// of the proposals that move that hit alone.
fn first_hit_chart<'a>(
    scene: &'a Scene,
    camera: &Camera,
    x: &'a ChainPath<SceneVertex>,
) -> Grid<Moved<'a, impl Fn(SceneVertex) -> Option<ChainPath<SceneVertex>> + 'a>> {
    let v = x.vertices();
    let pixel = f64::from(camera.pixel_angle());
    // The lens perturbation's disk (0.1 px and up) and most of the film.
    let angles = Angles::Log(0.02 * pixel, 0.8);
    let cone = Cone::new(scene, v[0], v[1].position - v[0].position, angles);
    let moved = Moved {
        cone,
        x,
        index: 1,
        moved: &[1],
        build: move |hit| x.with_vertex(1, hit),
    };
    // Noisy at ~1e-3 through f32 hits of 0.1-pixel moves (see
    // `mutation_strategies.rs`): the chart integrates to that.
    Grid::new(moved, 16).with_tolerance(1e-3)
}

fn report(name: &str, r: Result<aether_core::harness::Report, impl std::fmt::Display>) {
    match r {
        Ok(r) => {
            println!("{name}: {r}");
            assert!(r.p_value > 0.01, "{name}: {r}");
            assert!(r.integral > 0.05, "{name}: the chart holds little: {r}");
        }
        Err(f) => panic!("{name}: {f}"),
    }
}

#[test]
fn proposals_that_move_the_first_hit_follow_the_transition_density() {
    let scene = caustic_room(16, 12, 6);
    let mlt = VeachMlt::new(&scene, &MltSettings::default()).unwrap();
    let mutations = mlt.mutations();
    let camera = Camera::new(&scene).unwrap();
    let x = path_over(&scene, &[On::Diffuse], Kind::Lens);
    let chart = first_hit_chart(&scene, &camera, &x);
    report(
        "first hit moved",
        histogram(&mutations, &x, &chart, 1_000_000),
    );
}

#[test]
fn proposals_through_the_mirror_follow_the_transition_density() {
    let scene = caustic_room(16, 12, 6);
    let mlt = VeachMlt::new(&scene, &MltSettings::default()).unwrap();
    let mutations = mlt.mutations();
    let x = path_over(&scene, &[On::Diffuse, On::Mirror], Kind::Caustic);
    let v = x.vertices();
    // The mirror's reflection from the light, followed by the mutations'
    // own light-side BSDF sampling (a Dirac lobe: any uniforms).
    let reflect = BsdfSampling::new(&scene, Transport::Importance, Roulette::NEVER);
    let light = v[3];
    let build = |hit: SceneVertex| {
        if !On::Mirror.holds(&scene, &hit) {
            return None;
        }
        let prefix = [light, hit];
        let d = reflect.distribution(Prefix::forward(&prefix));
        let u = vec![0.5; d.dims()];
        let Step::Vertex(floor) = d.sample(&u)?.value else {
            return None;
        };
        x.with_vertex(2, hit)?.with_vertex(1, floor)
    };
    let cone = Cone::new(
        &scene,
        light,
        v[2].position - light.position,
        Angles::Log(MutationSettings::MIN_ANGLE, 0.5),
    );
    let moved = Moved {
        cone,
        x: &x,
        index: 2,
        moved: &[1, 2],
        build,
    };
    let chart = Grid::new(moved, 16).with_tolerance(1e-3);
    report(
        "through the mirror",
        histogram(&mutations, &x, &chart, 1_000_000),
    );
}

/// A strategy whose density is `factor(prefix's last, value)` times what it
/// says: a planted fault.
struct Misreporting<S, F> {
    strategy: S,
    factor: F,
}

impl<S: Strategy<SceneVertex>, F: Fn(&SceneVertex, &SceneVertex) -> f64 + Copy>
    Strategy<SceneVertex> for Misreporting<S, F>
{
    fn distribution<'a>(
        &'a self,
        prefix: Prefix<'a, SceneVertex>,
    ) -> impl Distribution<Value = Step<SceneVertex>> + 'a {
        let from = *prefix.last().expect("a vertex to leave from");
        let factor = self.factor;
        Misreported {
            distribution: self.strategy.distribution(prefix),
            factor: move |step: &Step<SceneVertex>| match step {
                Step::Vertex(v) => factor(&from, v),
                _ => 1.0,
            },
        }
    }
}

/// A lens perturbation of paths with a diffuse first hit, alongside a
/// resampling of that hit over the whole film (two branches, chosen
/// evenly), with the lens branch's film strategy misreporting its density
/// by `factor`.
struct PlantedLens<'a, F> {
    scene: &'a Scene,
    camera: &'a Camera,
    factor: F,
}

impl<F: Fn(&SceneVertex, &SceneVertex) -> f64 + Copy> Mutation<SceneVertex> for PlantedLens<'_, F> {
    fn propose(&self, x: &ChainPath<SceneVertex>, m: &mut Mutator<'_, SceneVertex>) -> Option<()> {
        let v = x.vertices();
        m.copy_eye(x, 0..1)?;
        if m.choose(&[1.0, 1.0])? == 0 {
            let center = self.camera.raster(&v[0], v[0].direction_to(&v[1])?)?;
            let film = PerturbedFilm::new(
                self.camera,
                self.scene,
                center,
                ExponentialDisk::new(0.1, 1.75),
            );
            let planted = Misreporting {
                strategy: film,
                factor: self.factor,
            };
            m.eye(&planted)?;
        } else {
            m.eye(&aether_strategies::camera::FilmDirection::new(
                self.camera,
                self.scene,
            ))?;
        }
        m.copy_light(x, 2..x.len())
    }
}

#[test]
fn planted_faults_in_a_transition_density_fail_the_test_but_not_detailed_balance() {
    let scene = caustic_room(16, 12, 6);
    let mlt = VeachMlt::new(&scene, &MltSettings::default()).unwrap();
    let camera = Camera::new(&scene).unwrap();
    let x = path_over(&scene, &[On::Diffuse], Kind::Lens);
    let chart = first_hit_chart(&scene, &camera, &x);
    let doubled = |_: &SceneVertex, _: &SceneVertex| 2.0;
    // Area → solid angle: what a density loses without r² / |cos θ|.
    let no_jacobian = |from: &SceneVertex, to: &SceneVertex| {
        let d = to.position - from.position;
        let cos = d.normalize().dot(to.geometric_normal).abs();
        f64::from(d.length_squared() / cos)
    };
    // The mutation without a fault passes.
    let honest = PlantedLens {
        scene: &scene,
        camera: &camera,
        factor: |_: &SceneVertex, _: &SceneVertex| 1.0,
    };
    report(
        "planted lens, no fault",
        histogram(&honest, &x, &chart, 200_000),
    );
    let doubled = PlantedLens {
        scene: &scene,
        camera: &camera,
        factor: doubled,
    };
    caught(
        "the lens branch's density doubled",
        &doubled,
        &mlt,
        &x,
        &chart,
    );
    let no_jacobian = PlantedLens {
        scene: &scene,
        camera: &camera,
        factor: no_jacobian,
    };
    caught(
        "the film strategy's Jacobian dropped",
        &no_jacobian,
        &mlt,
        &x,
        &chart,
    );
}

/// The chi-square test fails `mutation`, whose T is wrong, while detailed
/// balance holds for it.
fn caught<M: Mutation<SceneVertex>>(
    name: &str,
    mutation: &M,
    mlt: &VeachMlt<'_>,
    x: &ChainPath<SceneVertex>,
    chart: &impl Chart<Proposal>,
) {
    let caught = histogram(mutation, x, chart, 200_000).is_err();
    let worst = balance(mlt, mutation, x);
    println!("{name}: caught {caught}; detailed balance holds to {worst:.1e}");
    assert!(caught, "{name}: the chi-square test passed a wrong T");
    assert!(worst < 1e-9, "{name}: detailed balance {worst}");
}

/// The largest relative error of f(x) T(y|x) a(x→y) = f(y) T(x|y) a(y→x)
/// over proposals of `mutation` from `x`.
fn balance<M: Mutation<SceneVertex>>(
    mlt: &VeachMlt<'_>,
    mutation: &M,
    x: &ChainPath<SceneVertex>,
) -> f64 {
    let f_x = mlt.target(x, None);
    let mut worst: f64 = 0.0;
    let mut pairs = 0;
    for k in 0..2_000 {
        let Some((y, _)) = propose(mutation, x, &mut Pcg32::new(8, k)) else {
            continue;
        };
        let f_y = mlt.target(&y, Some(x));
        let (forward, backward) = (
            transition_density(mutation, x, &y),
            transition_density(mutation, &y, x),
        );
        if f_y == 0.0 || forward.value() == 0.0 || backward.value() == 0.0 {
            continue;
        }
        pairs += 1;
        let flow = f_x * forward.value() * acceptance(f_x, f_y, forward, backward);
        let back = f_y * backward.value() * acceptance(f_y, f_x, backward, forward);
        worst = worst.max((flow / back - 1.0).abs());
    }
    assert!(pairs > 100, "{pairs} reversible pairs");
    worst
}
