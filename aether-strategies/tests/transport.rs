//! Light transport through the strategies: Dirac lobes and lights in MIS,
//! the adjoint at refraction, and a white furnace rendered by two path
//! tracers assembled from the strategies.

mod support;

use aether_core::harness::Technique;
use aether_core::{
    Distribution, Heuristic, Pcg32, Prefix, RandomSequence, Step, StepKind, Strategy,
    UniformSource, combine,
};
use aether_strategies::bsdf::{Bsdf, Transport, fresnel_dielectric};
use aether_strategies::camera::Camera;
use aether_strategies::integrand::Integrand;
use aether_strategies::lights::Lights;
use aether_strategies::scattering::{BsdfSampling, Roulette};
use aether_strategies::scene::{Emitter, Material, Scene, Texture};
use aether_strategies::vertex::{SceneVertex, Site};
use glam::Vec3;
use support::{hit, room};

const CAMERA: &str = "<sensor type=\"perspective\"><float name=\"fov\" value=\"60\"/>
    <transform name=\"toWorld\"><lookat origin=\"0.2, 0.1, 0.5\" target=\"0, 0, -1\" up=\"0, 1, 0\"/></transform>
    <film type=\"hdrfilm\"><integer name=\"width\" value=\"4\"/><integer name=\"height\" value=\"4\"/>
    <rfilter type=\"box\"/></film></sensor>";

fn on_emitter(scene: &Scene, v: &SceneVertex) -> bool {
    v.shape().is_some_and(|s| scene.shapes[s].emitter.is_some())
}

fn on_mirror(scene: &Scene, v: &SceneVertex) -> bool {
    v.shape().is_some_and(|s| {
        matches!(
            scene.materials[scene.shapes[s].material],
            Material::Conductor { .. }
        )
    })
}

#[test]
fn dirac_lights_and_lobes_weigh_correctly_in_mis() {
    let scene = room(&format!(
        "<shape type=\"rectangle\"><transform name=\"toWorld\"><scale value=\"0.6\"/><translate z=\"-0.9\"/></transform>
            <bsdf type=\"conductor\"><string name=\"material\" value=\"none\"/></bsdf></shape>
        <emitter type=\"point\"><point name=\"position\" x=\"-0.5\" y=\"0.5\" z=\"0.5\"/><rgb name=\"intensity\" value=\"2\"/></emitter>
        {CAMERA}"
    ));
    let (camera, lights) = (Camera::new(&scene).unwrap(), Lights::new(&scene).unwrap());
    let integrand = Integrand::new(&scene, &camera, &lights);
    let pixel = [1, 2];
    let (lens, look) = (camera.position(), camera.direction(&scene, pixel));
    let bsdf = BsdfSampling::new(&scene, Transport::Radiance, Roulette::NEVER);
    let (start, direct) = (lights.position(), lights.direct());
    let via_bsdf = |n: usize| {
        (0..n).fold(Technique::new().forward(&lens).forward(&look), |t, _| {
            t.forward(&bsdf)
        })
    };
    let connect = Technique::new()
        .forward(&lens)
        .forward(&look)
        .reversed(&start);
    let nee = Technique::new()
        .forward(&lens)
        .forward(&look)
        .forward(&bsdf)
        .forward(&direct);
    let mut rng = Pcg32::new(1, 7);
    let (mut point, mut mirror, mut cancelled) = (0, 0, 0);
    for _ in 0..20_000 {
        let mut path = RandomSequence::new();
        path.append(&lens).append(&look);
        if path.sample(&mut rng) != StepKind::Vertex {
            continue;
        }
        // A point light: BSDF sampling cannot hit it.
        let mut to_light = path.clone();
        if to_light.append_sample(&direct, &mut rng)
            && matches!(to_light.vertices()[2].site, Site::Point { .. })
        {
            let w = combine(
                &[to_light.clone(), via_bsdf(1).assign(&to_light).unwrap()],
                Heuristic::Balance,
            );
            assert_eq!(w.as_slice(), &[1.0, 0.0]);
            point += 1;
        }
        if !path.append_sample(&bsdf, &mut rng) || !on_mirror(&scene, &path.vertices()[1]) {
            continue;
        }
        let v = path.vertices();
        if on_emitter(&scene, &v[2]) {
            // Through the mirror to the lamp: a connection at the mirror has
            // one Dirac factor fewer, so weight zero; and f / p is the lamp's
            // radiance exactly (the Dirac coefficient and mass cancel).
            let w = combine(
                &[path.clone(), connect.assign(&path).unwrap()],
                Heuristic::Balance,
            );
            assert_eq!(w.as_slice(), &[1.0, 0.0]);
            let estimate = (integrand.evaluate(pixel, v, &[]) / path.pdf().value()).as_vec3();
            assert!(
                (estimate - Vec3::splat(5.0)).abs().max_element() < 5e-3,
                "{estimate}"
            );
            mirror += 1;
            continue;
        }
        // Mirror, then a diffuse wall, then the lamp by BSDF sampling or by
        // direct sampling: both carry the mirror's Dirac factor, which
        // cancels in the ratio, leaving the last steps' densities.
        if !path.append_sample(&bsdf, &mut rng) || !on_emitter(&scene, &path.vertices()[3]) {
            continue;
        }
        let as_nee = nee.assign(&path).unwrap();
        let w = combine(&[path.clone(), as_nee], Heuristic::Balance);
        let v = path.vertices();
        let last = Step::Vertex(v[3]);
        let p_bsdf = bsdf
            .distribution(Prefix::forward(&v[..3]))
            .density(&last)
            .value();
        let p_direct = direct
            .distribution(Prefix::forward(&v[..3]))
            .density(&last)
            .value();
        let expected = p_bsdf / (p_bsdf + p_direct);
        assert!(
            w[0] > 0.0 && w[0] < 1.0 && (w[0] - expected).abs() < 1e-4,
            "{w:?} vs {expected}"
        );
        cancelled += 1;
    }
    println!("point light {point}, mirror to lamp {mirror}, mirror–wall–lamp {cancelled}");
    assert!(point > 1000 && mirror > 20 && cancelled > 20);
}

#[test]
fn refraction_scales_radiance_and_not_importance() {
    let scene = room("<shape type=\"rectangle\"><transform name=\"toWorld\"><scale value=\"0.6\"/><translate z=\"-0.9\"/></transform>
        <bsdf type=\"dielectric\"><float name=\"intIOR\" value=\"1.5\"/><float name=\"extIOR\" value=\"1\"/></bsdf></shape>");
    let x = hit(&scene, Vec3::new(0.1, 0.05, 0.0), -Vec3::Z);
    let bsdf = Bsdf::at(&scene, &x).unwrap();
    let ng = x.geometric_normal;
    // The estimate f |cos| / p of one refraction, sampled from either end.
    let through = |given: Vec3, mode: Transport| {
        let lobes = bsdf.sampling(given, mode);
        (0..64)
            .filter_map(|i| lobes.sample(&[(i as f32 + 0.5) / 64.0, 0.5]))
            .find(|s| s.value.dot(ng) * given.dot(ng) < 0.0)
            .map(|s| {
                let (to_light, to_camera) = match mode {
                    Transport::Radiance => (s.value, given),
                    Transport::Importance => (given, s.value),
                };
                let f = bsdf.eval(to_light, to_camera);
                f.x * s.value.dot(ng).abs() / s.density.value() as f32
            })
            .unwrap()
    };
    for cos in [0.9f32, 0.6, 0.3] {
        let outside = Vec3::new((1.0 - cos * cos).sqrt(), 0.0, cos);
        let inside = Vec3::new((1.0 - cos * cos).sqrt(), 0.0, -cos);
        // A camera path entering the glass: radiance compresses by (1/1.5)²;
        // the weight (1 − F) cancels the lobe choice.
        let into = through(outside, Transport::Radiance);
        assert!((into - 1.0 / 2.25).abs() < 1e-4, "{cos}: {into}");
        // A camera path leaving it gains 1.5².
        if fresnel_dielectric(cos, 1.0 / 1.5) < 1.0 {
            let out = through(inside, Transport::Radiance);
            assert!((out - 2.25).abs() < 1e-3, "{cos}: {out}");
        }
        // A light path (importance) through the same interface carries no
        // η² either way.
        let light_in = through(outside, Transport::Importance);
        assert!((light_in - 1.0).abs() < 1e-4, "{cos}: {light_in}");
        if fresnel_dielectric(cos, 1.0 / 1.5) < 1.0 {
            let light_out = through(inside, Transport::Importance);
            assert!((light_out - 1.0).abs() < 1e-3, "{cos}: {light_out}");
        }
    }
}

/// A closed sphere of `rings` × 2 `rings` quads, its triangles wound to
/// face its centre, as an OBJ file.
fn inward_sphere(rings: usize) -> std::path::PathBuf {
    let mut obj = String::new();
    let point = |i: usize, j: usize| {
        let theta = std::f64::consts::PI * i as f64 / rings as f64;
        let phi = std::f64::consts::PI * j as f64 / rings as f64;
        Vec3::new(
            (theta.sin() * phi.cos()) as f32,
            (theta.sin() * phi.sin()) as f32,
            theta.cos() as f32,
        )
    };
    let mut positions = Vec::new();
    for i in 0..=rings {
        for j in 0..2 * rings {
            let p = point(i, j);
            positions.push(p);
            obj.push_str(&format!("v {} {} {}\n", p.x, p.y, p.z));
        }
    }
    let index = |i: usize, j: usize| i * 2 * rings + j % (2 * rings);
    for i in 0..rings {
        for j in 0..2 * rings {
            let quad = [
                index(i, j),
                index(i + 1, j),
                index(i + 1, j + 1),
                index(i, j + 1),
            ];
            for [a, b, c] in [[quad[0], quad[1], quad[2]], [quad[0], quad[2], quad[3]]] {
                let (pa, pb, pc) = (positions[a], positions[b], positions[c]);
                let n = (pb - pa).cross(pc - pa);
                if n.length() < 1e-9 {
                    continue; // degenerate at the poles
                }
                let (b, c) = if n.dot(pa + pb + pc) > 0.0 {
                    (c, b)
                } else {
                    (b, c)
                };
                obj.push_str(&format!("f {} {} {}\n", a + 1, b + 1, c + 1));
            }
        }
    }
    let path = support::folder().join("furnace.obj");
    std::fs::write(&path, obj).unwrap();
    path
}

fn furnace() -> Scene {
    let mesh = inward_sphere(24);
    support::scene(&format!(
        "<shape type=\"obj\"><string name=\"filename\" value=\"{}\"/>
            <bsdf type=\"diffuse\"><rgb name=\"reflectance\" value=\"0.5\"/></bsdf>
            <emitter type=\"area\"><rgb name=\"radiance\" value=\"1\"/></emitter></shape>
        <sensor type=\"perspective\"><transform name=\"toWorld\"><lookat origin=\"0.1, 0, 0\" target=\"1, 0.2, 0\" up=\"0, 0, 1\"/></transform>
            <film type=\"hdrfilm\"><integer name=\"width\" value=\"4\"/><integer name=\"height\" value=\"4\"/><rfilter type=\"box\"/></film></sensor>",
        mesh.display()
    ))
}

/// L / (1 − ρ) per channel, from what the scene loaded.
fn furnace_radiance(scene: &Scene) -> Vec3 {
    let Material::Diffuse {
        reflectance: Texture::Constant(rho),
    } = &scene.materials[0]
    else {
        panic!("a diffuse sphere");
    };
    let Emitter::Area { radiance, .. } = &scene.emitters[0] else {
        panic!("an area light")
    };
    Vec3::from_array(*radiance) / (Vec3::ONE - Vec3::from_array(*rho))
}

fn mean_and_error(samples: &[Vec3]) -> (Vec3, Vec3) {
    let n = samples.len() as f32;
    let mean = samples.iter().sum::<Vec3>() / n;
    let var = samples
        .iter()
        .map(|s| (*s - mean) * (*s - mean))
        .sum::<Vec3>()
        / (n - 1.0);
    (mean, (var / n).map(f32::sqrt))
}

#[test]
fn a_white_furnace_gives_l_over_one_minus_rho() {
    let scene = furnace();
    let expected = furnace_radiance(&scene);
    let (camera, lights) = (Camera::new(&scene).unwrap(), Lights::new(&scene).unwrap());
    let integrand = Integrand::new(&scene, &camera, &lights);
    let pixel = [2, 1];
    let (lens, look) = (camera.position(), camera.direction(&scene, pixel));
    let roulette = Roulette {
        start: 4,
        probability: 0.7,
    };
    let bsdf = BsdfSampling::new(&scene, Transport::Radiance, roulette);
    let direct = lights.direct();
    // The techniques that end at vertex k: by BSDF sampling or directly.
    let ending = |k: usize, last: &'static str| {
        let t = (2..k).fold(Technique::new().forward(&lens).forward(&look), |t, _| {
            t.forward(&bsdf)
        });
        if last == "bsdf" {
            t.forward(&bsdf)
        } else {
            t.forward(&direct)
        }
    };
    let mut rng = Pcg32::new(2024, 3);
    let (mut plain, mut mis) = (Vec::new(), Vec::new());
    for _ in 0..100_000 {
        let mut path = RandomSequence::new();
        path.append(&lens).append(&look);
        if path.sample(&mut rng) != StepKind::Vertex {
            continue;
        }
        let (mut sum_plain, mut sum_mis) = (Vec3::ZERO, Vec3::ZERO);
        loop {
            let k = path.len() - 1;
            let estimate =
                (integrand.evaluate(pixel, path.vertices(), &[]) / path.pdf().value()).as_vec3();
            sum_plain += estimate;
            // Unidirectional path tracing with MIS: the vertex hit by BSDF
            // sampling could have come from direct sampling too.
            sum_mis += if k == 1 {
                estimate
            } else {
                let alternative = ending(k, "direct").assign(&path).unwrap();
                estimate * combine(&[path.clone(), alternative], Heuristic::Balance)[0] as f32
            };
            // Direct sampling from the current vertex.
            let mut nee = path.clone();
            if nee.append_sample(&direct, &mut rng) {
                let alternative = ending(k + 1, "bsdf").assign(&nee).unwrap();
                let w = combine(&[nee.clone(), alternative], Heuristic::Balance)[0] as f32;
                let f = integrand.evaluate(pixel, nee.vertices(), &[k]);
                sum_mis += w * (f / nee.pdf().value()).as_vec3();
            }
            if path.len() > 200 || !path.append_sample(&bsdf, &mut rng) {
                break;
            }
        }
        plain.push(sum_plain);
        mis.push(sum_mis);
    }
    for (name, samples) in [
        ("BSDF sampling", &plain),
        ("MIS with direct sampling", &mis),
    ] {
        let (mean, error) = mean_and_error(samples);
        println!("{name}: {mean} ± {error} (expected {expected})");
        let relative = ((mean - expected) / expected).abs().max_element();
        assert!(relative < 5e-3, "{name}: {mean} vs {expected}");
        // The test is meaningful only if its noise is well below 0.5 %.
        assert!((error / expected).max_element() < 1.5e-3, "{error}");
    }
}

/// ∫ f(ω, ω_o) |cos ω| dω by the BSDF's own sampling and, independently, by
/// uniform directions plus the Dirac lobe's known reflectance: the two
/// estimates of the albedo agree only if sampling and evaluation describe the
/// same BSDF (a Dirac coefficient polluted by a continuous lobe, or a lobe
/// that eval forgets, shows here).
#[test]
fn bsdf_sampling_and_evaluation_give_the_same_albedo() {
    let materials = [
        ("smooth plastic", "<bsdf type=\"plastic\"/>", 1),
        (
            "rough plastic",
            "<bsdf type=\"roughplastic\"><float name=\"alpha\" value=\"0.3\"/></bsdf>",
            0,
        ),
        (
            "rough metal",
            "<bsdf type=\"roughconductor\"><float name=\"alpha\" value=\"0.4\"/></bsdf>",
            0,
        ),
        (
            "rough glass",
            "<bsdf type=\"roughdielectric\"><float name=\"alpha\" value=\"0.4\"/></bsdf>",
            0,
        ),
        (
            "rough GGX glass",
            "<bsdf type=\"roughdielectric\"><string name=\"distribution\" value=\"ggx\"/><float name=\"alpha\" value=\"0.4\"/></bsdf>",
            0,
        ),
        ("diffuse", "<bsdf type=\"diffuse\"/>", 0),
    ];
    for (name, bsdf, dirac) in materials {
        let scene = room(&format!(
            "<shape type=\"rectangle\"><transform name=\"toWorld\"><scale value=\"0.6\"/><translate z=\"-0.9\"/></transform>{bsdf}</shape>"
        ));
        let x = hit(&scene, Vec3::new(0.1, 0.05, 0.0), -Vec3::Z);
        let b = Bsdf::at(&scene, &x).unwrap();
        let ng = x.geometric_normal;
        let to_camera = Vec3::new(0.5, 0.1, 0.8).normalize();
        let mut rng = Pcg32::new(6, 1);
        let n = if name.contains("glass") {
            3_000_000
        } else {
            400_000
        };
        let lobes = b.sampling(to_camera, Transport::Radiance);
        let mut by_sampling = 0.0f64;
        let mut below = [0.0f64; 2];
        for _ in 0..n {
            let u = [rng.next_f32(), rng.next_f32()];
            if let Some(s) = lobes.sample(&u) {
                let f = b.eval(s.value, to_camera).x;
                let e = f64::from(f * s.value.dot(ng).abs()) / s.density.value();
                by_sampling += e;
                if s.value.dot(ng) < 0.0 {
                    below[0] += e;
                }
            }
        }
        by_sampling /= n as f64;
        // Uniform directions on the sphere, stratified (a jittered grid in
        // z and φ), see the continuous lobes only.
        let mut by_quadrature = 0.0f64;
        let (nz, nphi) = (n / 500, 500);
        for i in 0..nz {
            for j in 0..nphi {
                let z = 1.0 - 2.0 * (i as f32 + rng.next_f32()) / nz as f32;
                let phi = std::f32::consts::TAU * (j as f32 + rng.next_f32()) / nphi as f32;
                let r = (1.0 - z * z).max(0.0).sqrt();
                let w = Vec3::new(r * phi.cos(), r * phi.sin(), z);
                let e = f64::from(b.eval(w, to_camera).x * w.dot(ng).abs())
                    * 4.0
                    * std::f64::consts::PI;
                by_quadrature += e;
                if w.dot(ng) < 0.0 {
                    below[1] += e;
                }
            }
        }
        by_quadrature /= n as f64;
        if dirac == 1 {
            // The coat's mirror reflects F(cos θ) of the light.
            by_quadrature += f64::from(fresnel_dielectric(to_camera.dot(ng), 1.49 / 1.000_277));
        }
        println!(
            "{name}: sampling {by_sampling:.4}, quadrature {by_quadrature:.4}; transmitted {:.4} vs {:.4}",
            below[0] / n as f64,
            below[1] / n as f64
        );
        assert!(
            (by_sampling - by_quadrature).abs() < 5e-3 * by_quadrature.max(0.1),
            "{name}: sampling {by_sampling}, quadrature {by_quadrature}"
        );
    }
}
