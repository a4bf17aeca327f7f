//! The scene layer speaks the sampling language: vertices of a loaded
//! scene, rays cast through it, and a strategy over it that passes the
//! harness.

use std::collections::HashMap;
use std::path::PathBuf;

use aether_core::harness::{Check, Grid, Parameterization, check_strategy};
use aether_core::primitives::CosineHemisphere;
use aether_core::{Distribution, Frame, InFrame, Intersect, Prefix, RayCaster, Step, Strategy};
use aether_strategies::geometry::Primitive;
use aether_strategies::scene::Scene;
use aether_strategies::vertex::{SceneVertex, Site};
use glam::Vec3;

/// A closed room (a cube turned inside out) with a lamp under its ceiling.
fn room(extra: &str) -> Scene {
    let xml = format!(
        "<scene><sensor type=\"perspective\"/>
        <shape type=\"cube\"><boolean name=\"flipNormals\" value=\"true\"/><bsdf type=\"diffuse\"/></shape>
        <shape type=\"rectangle\"><transform name=\"toWorld\"><scale value=\"0.3\"/><rotate x=\"1\" angle=\"180\"/><translate y=\"0\" z=\"0.95\"/></transform>
            <emitter type=\"area\"><rgb name=\"radiance\" value=\"5\"/></emitter></shape>
        {extra}</scene>"
    );
    let dir = std::env::temp_dir().join(format!("aether-room-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    static NEXT: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let path: PathBuf = dir.join(format!(
        "room{}.xml",
        NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed)
    ));
    std::fs::write(&path, xml).unwrap();
    Scene::load(&path, &HashMap::new()).unwrap_or_else(|e| panic!("{e}"))
}

/// A diffuse bounce written against the scene's vertices.
struct Bounce<'s>(&'s Scene);

impl Strategy<SceneVertex> for Bounce<'_> {
    fn distribution<'a>(
        &'a self,
        prefix: Prefix<'a, SceneVertex>,
    ) -> impl Distribution<Value = Step<SceneVertex>> + 'a {
        let x = prefix.last().expect("a vertex to leave from");
        let mut n = x.geometric_normal;
        if let Some(from) = prefix.back(1) {
            if (from.position - x.position).dot(n) < 0.0 {
                n = -n;
            }
        }
        Intersect::new(
            x,
            InFrame::new(Frame::from_normal(n), CosineHemisphere),
            self.0,
        )
    }
    fn memory(&self) -> usize {
        2
    }
}

/// The wall x = 1 of the room (the cube's +x face), as vertices.
struct WallChart;

impl Parameterization<Step<SceneVertex>> for WallChart {
    fn dims(&self) -> usize {
        2
    }
    fn value(&self, s: [f64; 2]) -> Option<Step<SceneVertex>> {
        let p = Vec3::new(1.0, (2.0 * s[0] - 1.0) as f32, (2.0 * s[1] - 1.0) as f32);
        let site = Site::Surface {
            shape: 0,
            primitive: Primitive::Triangle {
                mesh: 0,
                triangle: 0,
            },
        };
        Some(Step::Vertex(SceneVertex {
            position: p,
            geometric_normal: -Vec3::X,
            shading_normal: -Vec3::X,
            uv: glam::Vec2::ZERO,
            error: Vec3::ZERO,
            site,
        }))
    }
    fn coords(&self, v: &Step<SceneVertex>) -> Option<[f64; 2]> {
        let Step::Vertex(v) = v else { return None };
        let on_wall =
            matches!(v.site, Site::Surface { shape: 0, .. }) && (v.position.x - 1.0).abs() < 1e-4;
        on_wall.then(|| {
            [
                f64::from(v.position.y + 1.0) / 2.0,
                f64::from(v.position.z + 1.0) / 2.0,
            ]
        })
    }
    fn jacobian(&self, _s: [f64; 2]) -> f64 {
        4.0
    }
}

#[test]
fn a_bounce_in_a_loaded_scene_passes_the_harness() {
    let scene = room("");
    let hit = scene
        .geometry
        .intersect(Vec3::new(-0.2, 0.1, 0.0), -Vec3::Z, f32::INFINITY)
        .unwrap();
    let floor = SceneVertex::from_hit(&hit, scene.shape_of(hit.primitive));
    assert!(
        floor.geometric_normal.z > 0.99,
        "the flipped cube faces inwards: {floor:?}"
    );
    let report = check_strategy(
        &Bounce(&scene),
        &[floor],
        &Grid::new(WallChart, 16),
        &Check::default(),
    )
    .unwrap_or_else(|f| panic!("{f}"));
    println!("{report}");
    assert!(
        report.jacobian_checked > 200 && report.integral > 0.05,
        "{report}"
    );
}

#[test]
fn rays_leave_surfaces_cleanly_and_escape_into_environments() {
    let scene = room("");
    let hit = scene
        .geometry
        .intersect(Vec3::ZERO, -Vec3::Z, f32::INFINITY)
        .unwrap();
    let v = SceneVertex::from_hit(&hit, scene.shape_of(hit.primitive));
    // Grazing rays along the floor never re-hit it.
    for i in 0..100 {
        let a = i as f32 / 100.0 * std::f32::consts::TAU;
        let d = Vec3::new(a.cos(), a.sin(), 1e-3).normalize();
        let next = scene.cast(&v, d).unwrap();
        assert!(next.position.z > -0.999, "{next:?}");
    }
    // The lamp faces down, into the room.
    let lamp = scene
        .cast(&SceneVertex::point(Vec3::ZERO, None), Vec3::Z)
        .unwrap();
    assert_eq!(
        lamp.site,
        Site::Surface {
            shape: 1,
            primitive: Primitive::Triangle {
                mesh: 1,
                triangle: lamp_triangle(&lamp)
            }
        }
    );
    assert!(lamp.geometric_normal.z < -0.99);
    // Without walls and with a constant emitter, a ray escapes to the environment.
    let open = room("<emitter type=\"constant\"/>");
    assert!(open.has_environment());
    let out = open
        .cast(&SceneVertex::point(Vec3::new(5.0, 5.0, 5.0), None), Vec3::X)
        .unwrap();
    assert_eq!(out.site, Site::Environment { direction: Vec3::X });
}

fn lamp_triangle(v: &SceneVertex) -> u32 {
    match v.site {
        Site::Surface {
            primitive: Primitive::Triangle { triangle, .. },
            ..
        } => triangle,
        _ => u32::MAX,
    }
}

/// The scene's ray casting without its own `origin_reaching`: the
/// language's default, which the scene's shortcut must agree with.
struct Plain<'s>(&'s Scene);

impl RayCaster<SceneVertex> for Plain<'_> {
    fn cast(&self, from: &SceneVertex, direction: Vec3) -> Option<SceneVertex> {
        self.0.cast(from, direction)
    }
    fn origin(&self, from: &SceneVertex, toward: Vec3) -> Vec3 {
        self.0.origin(from, toward)
    }
}

#[test]
fn the_scenes_origin_reaching_a_target_is_the_default_fixed_point() {
    let scene = room("");
    let bits = |o: Option<Vec3>| o.map(|v| v.to_array().map(f32::to_bits));
    let mut rng = aether_core::Pcg32::new(11, 0);
    let mut u = || aether_core::UniformSource::next_f32(&mut rng);
    // Outcomes: no origin, the point itself, an offset origin.
    let mut seen = [0usize; 3];
    for _ in 0..4000 {
        let d = Vec3::new(u() - 0.5, u() - 0.5, u() - 0.5).normalize();
        let Some(hit) = scene.geometry.intersect(Vec3::ZERO, d, f32::INFINITY) else {
            continue;
        };
        let from = SceneVertex::from_hit(&hit, scene.shape_of(hit.primitive));
        let n = from.geometric_normal;
        // Targets anywhere, at infinity, and in or a hair off the tangent
        // plane, where the offset origins see them on different sides.
        let tangent = n.cross(Vec3::new(0.3, 0.5, 0.7)).normalize();
        let grazing = |along: f32, k: f32| {
            let mut v = from;
            v.position = from.position + tangent * along + n * k * 1e-7;
            v
        };
        let elsewhere = scene.cast(
            &from,
            Vec3::new(u() - 0.5, u() - 0.5, u() - 0.5).normalize(),
        );
        let (a, b, c, k) = (u(), u(), u(), 30.0 * (u() - 0.5));
        let mut distant = SceneVertex::environment(d);
        distant.site = Site::Distant {
            direction: -d,
            emitter: 0,
        };
        let targets = [
            elsewhere,
            Some(grazing(a, 0.0)),
            Some(grazing(b, 1.0)),
            Some(grazing(c, -1.0)),
            Some(grazing(a, k)),
            Some(SceneVertex::environment(-d)),
            Some(distant),
            Some(SceneVertex::point(Vec3::ZERO, None)),
        ];
        // Surface sources with their error bound, none and a NaN one, and
        // sources off any surface (a point, a lens, a NaN point).
        let mut zero_error = from;
        zero_error.error = Vec3::ZERO;
        let mut nan_error = from;
        nan_error.error = Vec3::NAN;
        let point = SceneVertex::point(from.position, None);
        let lens = SceneVertex::lens(from.position, n);
        let nan = SceneVertex::point(Vec3::NAN, None);
        for target in targets.iter().flatten() {
            for source in [&from, &zero_error, &nan_error, &point, &lens, &nan] {
                let ours = scene.origin_reaching(source, target);
                let default = Plain(&scene).origin_reaching(source, target);
                assert_eq!(bits(ours), bits(default), "{source:?} toward {target:?}");
                seen[match ours {
                    None => 0,
                    Some(o) if o == source.position => 1,
                    Some(_) => 2,
                }] += 1;
            }
        }
    }
    // Every outcome occurs. (An origin that is the second of the default's
    // three does not: on this room's axis-aligned walls, an origin offset
    // away from a grazing target makes the next one return to the first.)
    assert!(seen.iter().all(|&k| k > 0), "{seen:?}");
}
