//! Every strategy of the scene layer against the aether-core harness:
//! density agreement, inversion, numerical Jacobians and chi-square, for
//! every material, light and camera type; MIS partition of unity over the
//! techniques they form; Dirac lobes and lights in MIS; the adjoint at
//! refraction; and a white furnace rendered by a path tracer made of them.

mod support;

use aether_core::harness::{
    Check, Disk, Grid, Parameterization, Technique, check, check_mis, check_pointwise,
    check_strategy,
};
use aether_core::{
    Distribution, Heuristic, PairStrategy, Pcg32, Prefix, RandomSequence, Step, Strategy,
};
use aether_strategies::bsdf::{Bsdf, Transport};
use aether_strategies::camera::Camera;
use aether_strategies::geometry::Primitive;
use aether_strategies::lights::Lights;
use aether_strategies::portal::PortalSegment;
use aether_strategies::scattering::{BsdfSampling, Roulette};
use aether_strategies::vertex::{SceneVertex, Site};
use glam::Vec3;
use support::{SceneChart, hit, portal_room, room};

/// The chi-square tests of this file (about sixty) share a 1 % budget of
/// false failures (Bonferroni).
const CHI_SQUARE_TESTS: f64 = 64.0;

fn config() -> Check {
    let seed = std::env::var("AETHER_TEST_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(0x5eed);
    Check {
        samples: 60_000,
        cases: 256,
        significance: 0.01 / CHI_SQUARE_TESTS,
        seed,
        ..Check::default()
    }
}

/// A 0.5 × 0.5 sample of `bsdf` on the floor of the room, facing up (or
/// down, if `flipped`), with a camera looking at it.
fn sample_room(bsdf: &str, flipped: bool, sensor: &str) -> aether_strategies::scene::Scene {
    let turn = if flipped {
        "<rotate x=\"1\" angle=\"180\"/>"
    } else {
        ""
    };
    room(&format!(
        "<shape type=\"rectangle\"><transform name=\"toWorld\"><scale value=\"0.5\"/>{turn}
            <translate z=\"-0.9\"/></transform>{bsdf}</shape>{sensor}"
    ))
}

const MIRROR: &str = "<bsdf type=\"conductor\"><string name=\"material\" value=\"none\"/></bsdf>";
const GLASS: &str = "<bsdf type=\"dielectric\"/>";

fn materials() -> Vec<(&'static str, String, bool)> {
    let bump = support::checkerboard();
    vec![
        ("diffuse", "<bsdf type=\"diffuse\"/>".into(), false),
        (
            "anisotropic GGX metal",
            "<bsdf type=\"roughconductor\"><string name=\"distribution\" value=\"ggx\"/>
                <float name=\"alphaU\" value=\"0.15\"/><float name=\"alphaV\" value=\"0.4\"/></bsdf>"
                .into(),
            false,
        ),
        (
            "Beckmann metal",
            "<bsdf type=\"roughconductor\"><float name=\"alpha\" value=\"0.3\"/></bsdf>".into(),
            false,
        ),
        (
            "rough glass",
            "<bsdf type=\"roughdielectric\"><string name=\"distribution\" value=\"ggx\"/>
                <float name=\"alpha\" value=\"0.3\"/></bsdf>"
                .into(),
            false,
        ),
        (
            "rough plastic",
            "<bsdf type=\"roughplastic\"><string name=\"distribution\" value=\"ggx\"/>
                <float name=\"alpha\" value=\"0.2\"/></bsdf>"
                .into(),
            false,
        ),
        (
            "bump-mapped diffuse",
            format!(
                "<bsdf type=\"bumpmap\"><texture type=\"bitmap\"><string name=\"filename\" value=\"{}\"/></texture>
                    <bsdf type=\"diffuse\"/></bsdf>",
                bump.display()
            ),
            false,
        ),
        (
            "two-sided diffuse seen from behind",
            "<bsdf type=\"twosided\"><bsdf type=\"diffuse\"/></bsdf>".into(),
            true,
        ),
        ("mirror", MIRROR.into(), false),
        ("smooth glass", GLASS.into(), false),
        ("smooth plastic", "<bsdf type=\"plastic\"/>".into(), false),
    ]
}

#[test]
fn bsdf_sampling_passes_the_harness_for_every_material() {
    for (name, bsdf, flipped) in materials() {
        let scene = sample_room(&bsdf, flipped, "");
        let x = hit(&scene, Vec3::new(0.1, 0.05, 0.0), -Vec3::Z);
        let above = hit(&scene, x.position, Vec3::new(0.4, -0.3, 1.0));
        let dirac = ["mirror", "smooth glass", "smooth plastic"].contains(&name);
        for mode in [Transport::Radiance, Transport::Importance] {
            let roulette = Roulette {
                start: 2,
                probability: 0.8,
            };
            let strategy = BsdfSampling::new(&scene, mode, roulette);
            let prefix = [above, x];
            // A Dirac lobe behind a ray has no chart density; its lobes are
            // checked before the ray (below) and its vertices pointwise here.
            let report = if dirac {
                check_pointwise(&strategy.distribution(Prefix::forward(&prefix)), &config())
            } else {
                check_strategy(
                    &strategy,
                    &prefix,
                    &SceneChart::new(&scene, 6, false).seen_from(x),
                    &config(),
                )
            }
            .unwrap_or_else(|f| panic!("{name}, {mode:?}: {f}"));
            println!("{name:>36} {mode:?}: {report}");
            if name == "smooth glass" && mode == Transport::Importance {
                // Light paths record Dirac refraction in the camera-side solid
                // angle (a mass that is not a probability); the refraction test
                // below checks what it must be.
                continue;
            }
            let given = x.direction_to(&above).unwrap();
            let lobes = Bsdf::at(&scene, &x).unwrap().sampling(given, mode);
            let directions = check(
                &lobes,
                &Grid::new(aether_core::harness::SphereDirections, 12),
                &config(),
            )
            .unwrap_or_else(|f| panic!("{name}, {mode:?}, directions: {f}"));
            assert!(directions.integral > 0.3, "{name}: {directions}");
            if !dirac {
                // Roulette ends 20 % of the steps (an event with its own
                // mass); the rest is on the chart, since the room is closed.
                assert!(
                    (report.integral - 1.0).abs() < 2e-3,
                    "{name}, {mode:?}: {report}"
                );
            }
        }
    }
}

const LOOK_AT_FLOOR: &str = "<transform name=\"toWorld\"><lookat origin=\"0.3, 0.2, 0.6\" target=\"0, 0, -1\" up=\"0, 1, 0\"/></transform>";

fn sensor(kind: &str, filter: &str) -> String {
    let lens = if kind == "thinlens" {
        "<float name=\"apertureRadius\" value=\"0.05\"/><float name=\"focusDistance\" value=\"1.2\"/>"
    } else {
        ""
    };
    format!(
        "<sensor type=\"{kind}\"><float name=\"fov\" value=\"50\"/>{lens}{LOOK_AT_FLOOR}
            <film type=\"hdrfilm\"><integer name=\"width\" value=\"8\"/><integer name=\"height\" value=\"6\"/>
            <rfilter type=\"{filter}\"/></film></sensor>"
    )
}

/// The aperture of the thin-lens camera above, as an equal-area chart.
struct Aperture;

impl Parameterization<Step<SceneVertex>> for Aperture {
    fn dims(&self) -> usize {
        2
    }
    fn value(&self, s: [f64; 2]) -> Option<Step<SceneVertex>> {
        let p = Disk(0.05).value(s)?;
        let (e1, e2, n) = aperture_frame();
        Some(Step::Vertex(SceneVertex::lens(
            Vec3::new(0.3, 0.2, 0.6) + p.x * e1 + p.y * e2,
            n,
        )))
    }
    fn coords(&self, v: &Step<SceneVertex>) -> Option<[f64; 2]> {
        let Step::Vertex(v) = v else { return None };
        let (e1, e2, _) = aperture_frame();
        let d = v.position - Vec3::new(0.3, 0.2, 0.6);
        Disk(0.05).coords(&glam::Vec2::new(d.dot(e1), d.dot(e2)))
    }
    fn jacobian(&self, s: [f64; 2]) -> f64 {
        Disk(0.05).jacobian(s)
    }
}

fn aperture_frame() -> (Vec3, Vec3, Vec3) {
    let n = (Vec3::new(0.0, 0.0, -1.0) - Vec3::new(0.3, 0.2, 0.6)).normalize();
    let e1 = n.cross(Vec3::Y).normalize();
    (e1, n.cross(e1), n)
}

#[test]
fn camera_strategies_pass_the_harness() {
    for kind in ["perspective", "thinlens"] {
        for filter in ["box", "tent", "gaussian"] {
            let scene = room(&sensor(kind, filter));
            let camera = Camera::new(&scene).unwrap();
            let position = camera.position();
            let mut rng = Pcg32::new(3, 0);
            let mut start = RandomSequence::new();
            assert!(start.append_sample(&position, &mut rng));
            let lens = start.vertices()[0];
            if filter == "box" {
                let chart = Grid::new(Aperture, 8);
                let report = check_strategy(&position, &[], &chart, &config())
                    .unwrap_or_else(|f| panic!("{kind} position: {f}"));
                println!("{kind:>12} position: {report}");
                assert!((report.integral - 1.0).abs() < 1e-3, "{report}");
            }
            // Tabulated filters make the chart's quadrature refine along every
            // table edge, so the corner pixel is checked with the box only.
            let pixels: &[[u32; 2]] = if filter == "box" {
                &[[3, 2], [0, 5]]
            } else {
                &[[3, 2]]
            };
            for &pixel in pixels {
                let direction = camera.direction(&scene, pixel);
                // The pixel's footprint lies on the floor, which the camera
                // sees whole: no visibility tests needed in the chart.
                let chart = SceneChart::new(&scene, 8, false);
                let report = check_strategy(&direction, &[lens], &chart, &config())
                    .unwrap_or_else(|f| panic!("{kind}, {filter}, pixel {pixel:?}: {f}"));
                println!("{kind:>12} {filter:>8} pixel {pixel:?}: {report}");
                assert!((report.integral - 1.0).abs() < 2e-3, "{report}");
                // Back to the film: every sampled ray lands in the pixel's
                // footprint, and the pixel's importance there is the density
                // the camera sampled it with, over the lens cosine.
                for _ in 0..200 {
                    let mut path = RandomSequence::given([lens]);
                    if !path.append_sample(&direction, &mut rng) {
                        continue;
                    }
                    let x = path.vertices()[1];
                    let toward = lens.direction_to(&x).unwrap();
                    let raster = camera.raster(&lens, toward).unwrap();
                    let r = camera.filter().radius() + 1e-3;
                    let centre = glam::Vec2::new(pixel[0] as f32 + 0.5, pixel[1] as f32 + 0.5);
                    assert!(
                        (raster - centre).abs().max_element() <= r,
                        "{raster} vs {pixel:?}"
                    );
                    assert!(camera.pixels_around(raster).any(|p| p == pixel));
                    let w = camera.importance(pixel, &lens, toward);
                    let p_dir = camera.directions(pixel, &lens).density(&toward).value();
                    let p_lens = if kind == "thinlens" {
                        1.0 / (std::f64::consts::PI * 0.05 * 0.05)
                    } else {
                        1.0
                    };
                    let cos = if kind == "thinlens" {
                        f64::from(lens.geometric_normal.dot(toward))
                    } else {
                        1.0
                    };
                    assert!((w - p_lens * p_dir / cos).abs() <= 1e-6 * w, "{w}");
                }
            }
        }
    }
}

/// A room lit by every kind of light at once (an area mesh, a sphere, a
/// point, a spot, a directional light and an environment map), or by a
/// mesh and a constant environment.
fn lit_room(constant: bool, sensor: &str) -> aether_strategies::scene::Scene {
    if constant {
        return room(&format!(
            "<emitter type=\"constant\"><rgb name=\"radiance\" value=\"0.3\"/></emitter>{sensor}"
        ));
    }
    let map = support::folder().join("sky.exr");
    exr::prelude::write_rgb_file(&map, 16, 8, |x, y| {
        // The Jacobian check's stencil (±4e-3 in u) may straddle a cell
        // edge of the sampling table, where the map has a kink; it detects
        // strong kinks and skips them, but a weak one (neighbouring cells
        // within a few per cent) would bias it. So neighbouring columns
        // differ threefold, and rows are equally likely (luminance ∝ 1/sin θ).
        let theta = std::f32::consts::PI * (y as f32 + 0.5) / 8.0;
        let v = (1.0 + 2.0 * ((x + y) % 2) as f32) / theta.sin();
        (v, 0.5 * v, 0.3)
    })
    .unwrap();
    room(&format!(
        "<shape type=\"sphere\"><point name=\"center\" x=\"-0.5\" y=\"0.4\" z=\"-0.6\"/><float name=\"radius\" value=\"0.2\"/>
            <emitter type=\"area\"><rgb name=\"radiance\" value=\"2\"/></emitter></shape>
        <emitter type=\"point\"><point name=\"position\" x=\"0.5\" y=\"-0.5\" z=\"0.5\"/><rgb name=\"intensity\" value=\"3\"/></emitter>
        <emitter type=\"spot\"><transform name=\"toWorld\"><lookat origin=\"-0.6, -0.6, 0.6\" target=\"0, 0, -1\"/></transform>
            <rgb name=\"intensity\" value=\"4\"/><float name=\"cutoffAngle\" value=\"30\"/></emitter>
        <emitter type=\"directional\"><vector name=\"direction\" x=\"0.2\" y=\"0.3\" z=\"-1\"/><rgb name=\"irradiance\" value=\"1\"/></emitter>
        <emitter type=\"envmap\"><string name=\"filename\" value=\"{}\"/></emitter>{sensor}",
        map.display()
    ))
}

#[test]
fn light_strategies_pass_the_harness_for_every_light() {
    for constant in [false, true] {
        let scene = lit_room(constant, "");
        let lights = Lights::new(&scene).unwrap();
        if !constant {
            // The map's top row is up: the texel at column 0, row 0 (parity
            // even, so 1 / sin θ₀ in red) is what the sky sends from there.
            let (theta, phi) = (std::f32::consts::PI / 16.0, std::f32::consts::TAU / 32.0);
            let d = Vec3::new(
                theta.sin() * phi.sin(),
                theta.cos(),
                -theta.sin() * phi.cos(),
            );
            let sky = SceneVertex::environment(d);
            let l = lights.emitted(&sky, -d);
            assert!((l.x - 1.0 / theta.sin()).abs() < 1e-3 * l.x, "{l}");
        }
        let chart = SceneChart::new(&scene, 8, true);
        let start = lights.position();
        let report = check_strategy(&start, &[], &chart, &config())
            .unwrap_or_else(|f| panic!("emitter position: {f}"));
        println!("emitter position (constant {constant}): {report}");
        assert!((report.integral - 1.0).abs() < 2e-3, "{report}");

        let floor = hit(&scene, Vec3::new(0.2, 0.1, 0.0), -Vec3::Z);
        let direct = lights.direct();
        let seen = SceneChart::new(&scene, 8, true).seen_from(floor);
        let report = check_strategy(&direct, &[floor], &seen, &config())
            .unwrap_or_else(|f| panic!("direct emitter sampling: {f}"));
        println!("direct emitter (constant {constant}): {report}");
        assert!((report.integral - 1.0).abs() < 2e-3, "{report}");

        // Leaving every kind of light vertex that the start produces.
        let leave = lights.direction();
        let mut rng = Pcg32::new(9, 0);
        let mut seen = std::collections::HashSet::new();
        for _ in 0..2000 {
            let mut path = RandomSequence::new();
            if !path.append_sample(&start, &mut rng) {
                continue;
            }
            let x = path.vertices()[0];
            let kind = (lights.emitter_of(&x).unwrap(), x.shape().is_some());
            if !seen.insert(kind.0) {
                continue;
            }
            let seen = SceneChart::new(&scene, 8, false).seen_from(x);
            let report = check_strategy(&leave, &[x], &seen, &config())
                .unwrap_or_else(|f| panic!("leaving emitter {kind:?} at {x:?}: {f}"));
            println!("leaving emitter {}: {report}", kind.0);
            assert!(report.integral > 0.05, "{report}");
        }
        assert_eq!(seen.len(), scene.emitters.len());
    }
}

#[test]
fn the_portal_segment_passes_the_pointwise_checks() {
    let scene = portal_room();
    let segment = PortalSegment::new(&scene, 0).unwrap();
    let report = check_pointwise(&segment.distribution(Prefix::forward(&[])), &config())
        .unwrap_or_else(|f| panic!("portal segment: {f}"));
    println!("portal segment: {report}");
    assert!(report.jacobian_checked > 150, "{report}");
    // After a vertex, lines leave its side of the opening: checked from both sides.
    for y in [-0.5, 0.5] {
        let after = [SceneVertex::point(Vec3::new(0.0, y, 0.1), None)];
        let d = segment.distribution(Prefix::forward(&after));
        let report =
            check_pointwise(&d, &config()).unwrap_or_else(|f| panic!("after y = {y}: {f}"));
        assert!(report.jacobian_checked > 150, "{report}");
    }
}

#[test]
fn mis_weights_partition_unity_over_every_technique() {
    let scene = lit_room(false, &sensor("thinlens", "tent"));
    let scene = &scene;
    let camera = Camera::new(scene).unwrap();
    let lights = Lights::new(scene).unwrap();
    let (lens, look) = (camera.position(), camera.direction(scene, [4, 3]));
    let forward = BsdfSampling::new(scene, Transport::Radiance, Roulette::NEVER);
    let backward = BsdfSampling::new(scene, Transport::Importance, Roulette::NEVER);
    let (start, leave, direct) = (lights.position(), lights.direction(), lights.direct());
    let techniques = [
        Technique::new()
            .forward(&lens)
            .forward(&look)
            .forward(&forward)
            .forward(&forward),
        Technique::new()
            .forward(&lens)
            .forward(&look)
            .forward(&forward)
            .forward(&direct),
        Technique::new()
            .forward(&lens)
            .forward(&look)
            .reversed(&leave)
            .reversed(&start),
        Technique::new()
            .forward(&lens)
            .reversed(&backward)
            .reversed(&leave)
            .reversed(&start),
    ];
    for heuristic in [Heuristic::Balance, Heuristic::POWER] {
        let report = check_mis(&techniques, heuristic, 400, &mut Pcg32::new(17, 0))
            .unwrap_or_else(|e| panic!("{e}"));
        println!("{heuristic:?}: {report:?}");
        assert!(
            report.paths > 1000 && report.max_partition_error < 1e-9,
            "{report:?}"
        );
    }
}

/// A sphere's hits carry texture coordinates where its material reads them
/// (a bitmap, a bump map, wrapped or scaled), and (0, 0) where nothing
/// would read them: the angle and arc cosine per hit are skipped. A second,
/// textured sphere keeps its own: each sphere has its own flag.
#[test]
fn sphere_hits_carry_texture_coordinates_where_their_material_reads_them() {
    let bitmap = format!(
        "<texture type=\"bitmap\"><string name=\"filename\" value=\"{}\"/></texture>",
        support::checkerboard().display()
    );
    let named = bitmap.replace("<texture ", "<texture name=\"reflectance\" ");
    let scaled = format!(
        "<texture name=\"reflectance\" type=\"scale\"><float name=\"scale\" value=\"0.5\"/>{bitmap}</texture>"
    );
    let cases = [
        ("<bsdf type=\"diffuse\"/>".to_string(), false),
        ("<bsdf type=\"dielectric\"/>".to_string(), false),
        (format!("<bsdf type=\"diffuse\">{named}</bsdf>"), true),
        (format!("<bsdf type=\"diffuse\">{scaled}</bsdf>"), true),
        (
            format!(
                "<bsdf type=\"plastic\">{}</bsdf>",
                named.replace("\"reflectance\"", "\"diffuseReflectance\"")
            ),
            true,
        ),
        (
            format!("<bsdf type=\"twosided\"><bsdf type=\"diffuse\">{named}</bsdf></bsdf>"),
            true,
        ),
        (
            format!("<bsdf type=\"bumpmap\">{bitmap}<bsdf type=\"diffuse\"/></bsdf>"),
            true,
        ),
    ];
    let spherical = |x: &SceneVertex| {
        let n = x.geometric_normal.as_dvec3();
        [
            n.y.atan2(n.x).rem_euclid(std::f64::consts::TAU) / std::f64::consts::TAU,
            n.z.acos() / std::f64::consts::PI,
        ]
    };
    for (bsdf, textured) in cases {
        let scene = support::room(&format!(
            "<shape type=\"sphere\"><point name=\"center\" x=\"0\" y=\"0\" z=\"0\"/>
                <float name=\"radius\" value=\"0.25\"/>{bsdf}</shape>
            <shape type=\"sphere\"><point name=\"center\" x=\"0\" y=\"0.6\" z=\"0\"/>
                <float name=\"radius\" value=\"0.2\"/><bsdf type=\"diffuse\">{named}</bsdf></shape>"
        ));
        let rays = [
            (
                Vec3::new(0.8, 0.3, 0.2),
                Vec3::new(-1.0, -0.3, -0.1),
                textured,
            ),
            (Vec3::new(0.8, 0.65, 0.1), Vec3::new(-1.0, 0.0, 0.0), true),
        ];
        for (k, (origin, dir, reads)) in rays.into_iter().enumerate() {
            let x = hit(&scene, origin, dir);
            assert!(
                matches!(x.site, Site::Surface { primitive: Primitive::Sphere(s), .. } if s as usize == k),
                "{bsdf}: ray {k} missed its sphere: {:?}",
                x.site
            );
            let (uv, expected) = (x.uv, spherical(&x));
            if reads {
                assert!(
                    (f64::from(uv.x) - expected[0]).abs() < 1e-5
                        && (f64::from(uv.y) - expected[1]).abs() < 1e-5,
                    "{bsdf}: sphere {k}: {uv:?} against {expected:?}"
                );
            } else {
                assert_eq!(uv, glam::Vec2::ZERO, "{bsdf}: sphere {k}");
            }
        }
    }
}
