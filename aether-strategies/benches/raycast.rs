//! Ray-casting throughput on the Aether scenes: closest-hit camera rays and
//! shadow rays towards the light, on one thread and on all threads.
//!
//! Run with `cargo bench -p aether-strategies --bench raycast`; the scenes
//! are read from ../shared/scenes/aether beside the project.

use std::collections::HashMap;
use std::path::Path;
use std::time::Instant;

use aether_core::{Pcg32, UniformSource};
use aether_strategies::geometry::Hit;
use aether_strategies::scene::{Emitter, Scene};
use glam::Vec3;
use rayon::prelude::*;

/// Camera rays through a `w` × `h` grid of jittered pixels (Mitsuba's
/// perspective camera: +z forward, x to the left, fov along x).
fn camera_rays(scene: &Scene, w: u32, h: u32) -> Vec<(Vec3, Vec3)> {
    let cam = &scene.camera;
    let tan_x = (cam.fov.to_radians() * 0.5).tan();
    let tan_y = tan_x * h as f32 / w as f32;
    let origin = cam.to_world.transform_point3(Vec3::ZERO);
    let mut rng = Pcg32::new(1, 0);
    (0..w * h)
        .map(|i| {
            let (px, py) = (
                ((i % w) as f32 + rng.next_f32()) / w as f32,
                ((i / w) as f32 + rng.next_f32()) / h as f32,
            );
            let d = Vec3::new((0.5 - px) * 2.0 * tan_x, (0.5 - py) * 2.0 * tan_y, 1.0);
            (origin, cam.to_world.transform_vector3(d).normalize())
        })
        .collect()
}

/// A point on the first area light, chosen by triangle and barycentrics.
fn light_point(scene: &Scene, rng: &mut Pcg32) -> Option<(Vec3, Vec3)> {
    let shape = scene.emitters.iter().find_map(|e| {
        if let Emitter::Area { shape, .. } = e {
            Some(*shape)
        } else {
            None
        }
    })?;
    let mesh = scene.geometry.meshes().get(shape)?;
    let t = (rng.next_f32() * mesh.triangles.len() as f32) as usize % mesh.triangles.len();
    let [a, b, c] = mesh.corners(t);
    let (u, v) = (rng.next_f32().sqrt(), rng.next_f32());
    Some((
        (1.0 - u) * a + u * (1.0 - v) * b + u * v * c,
        (b - a).cross(c - a).normalize(),
    ))
}

fn rate(rays: usize, seconds: f64) -> String {
    format!("{:.2} Mrays/s", rays as f64 / seconds / 1e6)
}

fn bench(path: &Path) {
    let Ok(scene) = Scene::load(path, &HashMap::new()) else {
        println!("{}: cannot load", path.display());
        return;
    };
    let rays = camera_rays(&scene, 512, 512);
    let closest = |(o, d): &(Vec3, Vec3)| scene.geometry.intersect(*o, *d, f32::INFINITY);
    let start = Instant::now();
    let hits: Vec<Option<Hit>> = rays.iter().map(closest).collect();
    let one = start.elapsed().as_secs_f64();
    let start = Instant::now();
    let hits_par: Vec<Option<Hit>> = rays.par_iter().map(closest).collect();
    let all = start.elapsed().as_secs_f64();
    assert_eq!(hits.len(), hits_par.len());

    let mut rng = Pcg32::new(2, 0);
    let shadow: Vec<_> = hits
        .iter()
        .flatten()
        .filter_map(|h| light_point(&scene, &mut rng).map(|l| (*h, l)))
        .collect();
    let test = |(h, (p, n)): &(Hit, (Vec3, Vec3))| {
        scene.geometry.visible(
            (h.position, h.error, h.geometric_normal),
            (*p, Vec3::splat(1e-4 * p.abs().max_element()), *n),
        )
    };
    let start = Instant::now();
    let visible = shadow.iter().filter(|s| test(s)).count();
    let shadow_one = start.elapsed().as_secs_f64();
    let start = Instant::now();
    let visible_par = shadow.par_iter().filter(|s| test(s)).count();
    let shadow_all = start.elapsed().as_secs_f64();
    assert_eq!(visible, visible_par);

    println!(
        "{}: {} triangles; closest hit {} (1 thread), {} ({} threads); shadow {} (1 thread), {} (all); {:.0} % of camera rays hit, {:.0} % of shadow rays unoccluded",
        path.file_name().unwrap().to_string_lossy(),
        scene.geometry.triangle_count(),
        rate(rays.len(), one),
        rate(rays.len(), all),
        rayon::current_num_threads(),
        rate(shadow.len(), shadow_one),
        rate(shadow.len(), shadow_all),
        100.0 * hits.iter().flatten().count() as f64 / rays.len() as f64,
        100.0 * visible as f64 / shadow.len().max(1) as f64,
    );
}

fn main() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/scenes/aether");
    if !dir.is_dir() {
        println!("{} is absent: nothing to measure", dir.display());
        return;
    }
    for scene in [
        "veach_door/door-bdpt-aether.xml",
        "cbox-sphere/cbox-sphere-path.xml",
        "cbox/cbox_path.xml",
    ] {
        bench(&dir.join(scene));
    }
}
