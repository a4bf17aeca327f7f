//! The strategies of Veach's perturbations through the full harness
//! (agreement, inversion, numerical Jacobian, chi-square at 10⁶ samples,
//! p > 0.01), conditioned on vertices of real paths: BDPT paths of
//! cbox-sphere, whose metal and glass spheres make the specular chains the
//! perturbations follow.
//!
//! * `FilmDirection` (the camera edge of a bidirectional mutation) and
//!   `PerturbedFilm` (the lens and multi-chain perturbations' first edge)
//!   from the camera vertex of a path, toward the film point of its first
//!   hit;
//! * `PerturbedDirection` (the caustic and multi-chain perturbations) from
//!   a diffuse vertex, from a vertex on a sphere (near-specular) and along
//!   the most grazing edge found, about the path's own next edge, with the
//!   scene's cone and with a wider one.
//!
//! The chart ([`tests::cone::Cone`]) is written from geometry alone: cells
//! of angle about the axis (log-spaced for the perturbations, which are
//! log-uniform in angle) and of azimuth, each cell's points being the
//! first hits of its directions.

use aether_core::harness::{Check, Grid, check_strategy};
use aether_core::primitives::{ExponentialCone, ExponentialDisk};
use aether_core::{ChainPath, Pcg32};
use aether_strategies::camera::{Camera, FilmDirection, PerturbedFilm};
use aether_strategies::mutations::{MutationSettings, PerturbedDirection, Specular};
use aether_strategies::scene::Scene;
use aether_strategies::vertex::SceneVertex;
use glam::Vec3;
use integrators::mlt::MltSettings;
use integrators::mlt::veach::VeachMlt;
use tests::cbox_sphere_small;
use tests::cone::{Angles, Cone};

/// The primitives' tolerances (agreement 1e-4, Jacobian 1e-3) and 10⁶
/// samples for the chi-square test.
fn config() -> Check {
    Check {
        samples: 1_000_000,
        ..Check::default()
    }
}

/// For the scene's own perturbation sizes, turns of 1e-4 rad and film
/// offsets of 0.1 pixel: such a move shifts a hit point by ~1e-4 of the
/// scene's size, a few hundred f32 ulps, and density mode measures the
/// move from the hit point, so single-precision vertices resolve its
/// density to ~1e-3 and its finite differences to a few 1e-3. The
/// chi-square test, which bins, is as strict as ever; wider perturbations
/// are checked at the primitives' tolerances.
fn fine_config() -> Check {
    Check {
        agreement_tolerance: 5e-3,
        jacobian_tolerance: 1e-2,
        ..config()
    }
}

/// For the scene's cone of turns (1e-4 to 1.7e-3 rad): as
/// [`fine_config`], but the finite differences of the harness's steps move
/// such hit points by less than the rounding of an f32 position, so most
/// cases cannot be differenced and the Jacobian is compared wherever they
/// can. The cone's own Jacobian is checked as a primitive
/// (`aether-core/tests/primitives.rs`), and the same strategy's Jacobian
/// through the ray cast on a wide cone below.
fn turn_config() -> Check {
    Check {
        min_checked: 0.0,
        ..fine_config()
    }
}

/// For cones of 1e-2 to 0.3 rad: the primitives' agreement, and their
/// Jacobian tolerance tripled, since the harness's finite-difference steps
/// in the narrowest part of the cone move a hit point by a few thousand
/// f32 ulps of its position, which resolves the difference to ~1e-3.
fn wide_config() -> Check {
    Check {
        jacobian_tolerance: 3e-3,
        ..config()
    }
}

/// Paths of cbox-sphere that BDPT finds, with at least three vertices.
fn paths(scene: &Scene) -> Vec<ChainPath<SceneVertex>> {
    let mlt = VeachMlt::new(scene, &MltSettings::default()).unwrap();
    let mut found = Vec::new();
    for i in 0..2_000 {
        found.extend(
            mlt.seed_paths(&mut Pcg32::new(91, i))
                .into_iter()
                .filter(|p| p.len() >= 3),
        );
    }
    assert!(found.len() > 100, "only {} paths", found.len());
    found
}

fn passes(
    name: &str,
    report: Result<aether_core::harness::Report, impl std::fmt::Display>,
) -> aether_core::harness::Report {
    match report {
        Ok(r) => {
            println!("{name}: {r}");
            assert!(r.p_value > 0.01, "{name}: {r}");
            r
        }
        Err(f) => panic!("{name}: {f}"),
    }
}

#[test]
fn film_strategies_pass_the_harness_from_real_camera_vertices() {
    let scene = cbox_sphere_small();
    let camera = Camera::new(&scene).unwrap();
    let (width, height) = (scene.film.width, scene.film.height);
    let settings = MutationSettings::new(width, height, 8);
    let (r_min, r_max) = settings.lens_offsets;
    let offsets = ExponentialDisk::new(r_min, r_max);
    let pixel = f64::from(camera.pixel_angle());
    let all = paths(&scene);
    // Paths toward the middle, a side and a corner of the film.
    let mut picked: Vec<&ChainPath<SceneVertex>> = Vec::new();
    for target in [[32.0, 24.0], [4.0, 24.0], [60.0, 44.0]] {
        let near = all.iter().min_by(|a, b| {
            let d = |p: &ChainPath<SceneVertex>| {
                let v = p.vertices();
                camera
                    .raster(&v[0], (v[1].position - v[0].position).normalize())
                    .map_or(f32::INFINITY, |r| r.distance(target.into()))
            };
            d(a).total_cmp(&d(b))
        });
        picked.push(near.expect("a path"));
    }
    for path in picked {
        let (lens, first) = (path.vertices()[0], path.vertices()[1]);
        let axis = first.position - lens.position;
        let center = camera.raster(&lens, axis.normalize()).expect("on the film");
        let name = format!("PerturbedFilm toward raster {center}");
        // Film offsets of 0.1 to r_max pixels subtend at least ~0.05 pixel
        // angles (at the film's corners) and at most r_max of them.
        let angles = Angles::Log(0.02 * pixel, 1.5 * f64::from(r_max) * pixel);
        // Noisy at ~1e-3 through f32 hits, as the narrow cones below.
        let chart = Grid::new(Cone::new(&scene, lens, axis, angles), 16).with_tolerance(1e-3);
        let strategy = PerturbedFilm::new(&camera, &scene, center, offsets);
        let report = passes(
            &name,
            check_strategy(&strategy, &[lens], &chart, &fine_config()),
        );
        // Where the disk lies on the film, the chart holds all of it; at
        // the film's edge the part off the film is void.
        let on_film = center.x - r_max >= 0.0
            && center.y - r_max >= 0.0
            && center.x + r_max <= width as f32
            && center.y + r_max <= height as f32;
        if on_film {
            assert!(
                report.integral > 0.99,
                "{name}: the chart holds the disk: {report}"
            );
        }
        // Offsets of 1 to 20 pixels, at the primitives' tolerances.
        let angles = Angles::Log(0.5 * pixel, 30.0 * pixel);
        let chart = Grid::new(Cone::new(&scene, lens, axis, angles), 16);
        let wide = PerturbedFilm::new(&camera, &scene, center, ExponentialDisk::new(1.0, 20.0));
        // Part of the disk may fall off the film (void samples): the
        // chi-square test counts them in a cell of their own.
        passes(
            &format!("{name}, 1..20 px"),
            check_strategy(&wide, &[lens], &chart, &config()),
        );
    }
    // The whole film, seen about the direction to its middle.
    let lens = all[0].vertices()[0];
    let film = FilmDirection::new(&camera, &scene);
    let middle = all
        .iter()
        .map(|p| (p.vertices()[1].position - lens.position).normalize())
        .fold(Vec3::ZERO, |a, w| a + w);
    let chart = Grid::new(Cone::new(&scene, lens, middle, Angles::Linear(0.8)), 16);
    passes(
        "FilmDirection",
        check_strategy(&film, &[lens], &chart, &config()),
    );
}

/// A vertex of `paths` and the direction of the edge after it, for each of
/// the cases the caustic and multi-chain perturbations meet.
fn conditioning(
    scene: &Scene,
    paths: &[ChainPath<SceneVertex>],
) -> Vec<(&'static str, SceneVertex, Vec3)> {
    // Specular as the mutations classify it (the spheres' metal and glass).
    let specular = Specular::of(scene, MutationSettings::new(1, 1, 8).roughness_threshold);
    let on_sphere = |v: &SceneVertex| specular.at(v);
    let edges = paths.iter().flat_map(|p| {
        let v = p.vertices();
        (1..v.len() - 1).map(move |i| (v[i], v[i + 1]))
    });
    let cosine = |(x, y): &(SceneVertex, SceneVertex)| {
        (y.position - x.position)
            .normalize()
            .dot(y.geometric_normal)
            .abs()
    };
    let mut cases = Vec::new();
    let diffuse = edges
        .clone()
        .find(|(x, y)| !on_sphere(x) && !on_sphere(y) && cosine(&(*x, *y)) > 0.3);
    let near_specular = edges.clone().find(|(x, _)| on_sphere(x));
    let grazing = edges
        .filter(|(x, y)| !on_sphere(y) && x.position.distance(y.position) > 0.2)
        .min_by(|a, b| cosine(a).total_cmp(&cosine(b)));
    for (name, edge) in [
        ("diffuse", diffuse),
        ("near-specular", near_specular),
        ("grazing", grazing),
    ] {
        let (x, y) = edge.unwrap_or_else(|| panic!("no {name} edge in {} paths", paths.len()));
        cases.push((name, x, y.position - x.position));
    }
    cases
}

#[test]
fn perturbed_directions_pass_the_harness_from_real_path_vertices() {
    let scene = cbox_sphere_small();
    let settings = MutationSettings::new(scene.film.width, scene.film.height, 8);
    let all = paths(&scene);
    let (narrow_min, narrow_max) = settings.chain_angles;
    for (case, x, axis) in conditioning(&scene, &all) {
        // The scene's cone and a wide one.
        // The density through f32 hits of turns of 1e-4 rad is noisy at
        // ~1e-3 (see `fine_config`): the chart integrates to that.
        let cones = [
            (narrow_min, narrow_max, turn_config(), 1e-3),
            (1e-2, 0.3, wide_config(), 1e-5),
        ];
        for (min, max, config, tolerance) in cones {
            let cone = ExponentialCone::new(min, max);
            let strategy = PerturbedDirection::new(&scene, axis.normalize(), cone);
            let chart = Grid::new(Cone::new(&scene, x, axis, Angles::Log(min, max)), 16)
                .with_tolerance(tolerance);
            let name = format!("PerturbedDirection, {case} edge, cone {min:.0e}..{max:.0e} rad");
            let report = passes(&name, check_strategy(&strategy, &[x], &chart, &config));
            // The scene's cone stays on the surface it hits; part of a wide
            // one leaves the box or meets the light, which the chi-square
            // test counts as void.
            if max < 0.01 {
                assert!(
                    report.integral > 0.99,
                    "{name}: the chart holds the cone: {report}"
                );
            }
        }
    }
}
