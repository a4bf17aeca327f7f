//! Veach's mutations in density mode give the densities they sampled with,
//! and their moves can be undone.
//!
//! For paths x that BDPT finds (F(x) > 0) on the built-in Cornell box and on
//! cbox-sphere (whose metal and glass spheres make specular chains, so that
//! the caustic and multi-chain perturbations apply), each mutation proposes
//! y. For every pair with F(y) > 0 the test checks that
//! * T(y | x) of the mutation alone, run in density mode, is at least the
//!   density of the branch that was sampled, and equals it for the
//!   perturbations (one branch), to the precision of single-precision
//!   vertices (see `SLACK`);
//! * the move can be undone: T(x | y) > 0 for nearly every pair (a
//!   perturbation's reverse cone, built from y, may miss x in rare cases).
//!
//! Detailed balance itself, f(x) T(y|x) a(x→y) = f(y) T(x|y) a(y→x), holds
//! for any positive T under Metropolis–Hastings acceptance and so says
//! nothing about T: `proposals.rs` checks T against the proposals' own
//! histogram, and shows a wrong T passing that equality.

use aether_core::{ChainPath, Pcg32, propose, transition_density};
use aether_strategies::mutations::{Kind, Only};
use aether_strategies::scene::Scene;
use aether_strategies::vertex::SceneVertex;
use integrators::cornell::cornell_box;
use integrators::mlt::MltSettings;
use integrators::mlt::veach::VeachMlt;
use tests::cbox_sphere_small;

/// Pairs checked per mutation and scene (at most).
const PAIRS: usize = 150;

/// Largest relative difference expected between T(y | x) in density mode
/// and the density recorded while sampling y. Density mode measures an
/// edge from the origin the ray caster starts it at; what it cannot undo
/// is the rounding of the vertex the ray found: on a short edge through
/// the nearly specular glass sphere of cbox-sphere (GGX α = 0.001, a
/// sphere's error bound of ~1e-4 of its size) that turns the measured
/// direction enough to change the density by up to a factor of a few.
/// The multi-chain perturbation's turns of 1e-4 rad resolve to about
/// 0.2 % ([`MutationSettings::MIN_ANGLE`]). At most one pair in twenty may
/// differ by more than `SLACK`, and the median by more than 1 %.
///
/// [`MutationSettings::MIN_ANGLE`]: aether_strategies::mutations::MutationSettings::MIN_ANGLE
const SLACK: f64 = 0.05;

/// Seed paths from BDPT samples, up to `count`, that `kind` applies to.
fn paths(mlt: &VeachMlt<'_>, kind: Kind, count: usize) -> Vec<ChainPath<SceneVertex>> {
    let mutations = mlt.mutations();
    let index = Kind::ALL.iter().position(|&k| k == kind).unwrap();
    let mut found = Vec::new();
    for i in 0..20_000 {
        for p in mlt.seed_paths(&mut Pcg32::new(77, i)) {
            if mutations.weights(p.vertices())[index] > 0.0 {
                found.push(p);
            }
        }
        if found.len() >= count {
            break;
        }
    }
    found
}

fn check(name: &str, scene: &Scene, kind: Kind) {
    let mlt = VeachMlt::new(scene, &MltSettings::default()).unwrap();
    let mutations = mlt.mutations();
    let only = Only {
        mutations: &mutations,
        kind,
    };
    let (mut pairs, mut irreversible, mut tries) = (0, 0, 0);
    let mut gaps = Vec::new();
    let starts = paths(&mlt, kind, PAIRS);
    assert!(
        !starts.is_empty(),
        "{name}: no path that {kind:?} applies to"
    );
    for (k, x) in starts.iter().cycle().take(20 * PAIRS).enumerate() {
        if pairs >= PAIRS {
            break;
        }
        tries += 1;
        let Some((y, sampled)) = propose(&only, x, &mut Pcg32::new(5, k as u64)) else {
            continue;
        };
        let f_y = mlt.target(&y, Some(x));
        if f_y == 0.0 {
            continue;
        }
        pairs += 1;
        let forward = transition_density(&mutations, x, &y);
        let backward = transition_density(&mutations, &y, x);
        // The density of the sampled branch is one term of T(y | x): the
        // perturbations have one branch, so it is all of it.
        let own = transition_density(&only, x, &y);
        let gap = own.value() / sampled.value() - 1.0;
        if kind == Kind::Bidirectional {
            gaps.push(gap.min(0.0).abs());
        } else {
            gaps.push(gap.abs());
        }
        assert!(
            forward.value() > 0.0,
            "{name} {kind:?}: the mixture cannot propose y"
        );
        if backward.value() == 0.0 {
            irreversible += 1;
        }
    }
    gaps.sort_by(f64::total_cmp);
    let median = gaps.get(gaps.len() / 2).copied().unwrap_or(0.0);
    let far = gaps.iter().filter(|&&g| g > SLACK).count();
    println!(
        "{name} {kind:?}: {pairs} pairs of {tries} proposals, {irreversible} without a way back; density mode vs sampled density: median gap {median:.1e}, {far} beyond {SLACK}, worst {:.1e}",
        gaps.last().copied().unwrap_or(0.0)
    );
    assert!(median < 1e-2, "{name} {kind:?}: median gap {median}");
    assert!(
        far * 20 <= pairs,
        "{name} {kind:?}: {far} gaps beyond {SLACK}"
    );
    assert!(pairs >= PAIRS / 3, "{name} {kind:?}: only {pairs} pairs");
    assert!(
        irreversible * 20 <= pairs,
        "{name} {kind:?}: {irreversible} of {pairs} moves cannot be undone"
    );
}

#[test]
fn bidirectional_mutation_densities_agree_and_moves_undo() {
    let mut scene = cornell_box(32, 32, 1);
    scene.integrator.max_depth = 5;
    check("Cornell box", &scene, Kind::Bidirectional);
    check("cbox-sphere", &cbox_sphere_small(), Kind::Bidirectional);
}

#[test]
fn lens_perturbation_densities_agree_and_moves_undo() {
    let mut scene = cornell_box(32, 32, 1);
    scene.integrator.max_depth = 5;
    check("Cornell box", &scene, Kind::Lens);
    check("cbox-sphere", &cbox_sphere_small(), Kind::Lens);
}

#[test]
fn caustic_perturbation_densities_agree_and_moves_undo() {
    check("cbox-sphere", &cbox_sphere_small(), Kind::Caustic);
}

#[test]
fn multi_chain_perturbation_densities_agree_and_moves_undo() {
    check("cbox-sphere", &cbox_sphere_small(), Kind::MultiChain);
}
