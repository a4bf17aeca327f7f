//! What each family of integrators puts in a part of a render
//! ([`Partial`]), and how the sum of the parts becomes its images: the
//! same functions make a single process's image, so that a merge of parts
//! and the whole render differ only in the order of their additions.
//!
//! - the estimators (path, direct, light, BDPT, tridirectional): camera
//!   sums and counts per pixel, splatted sums and the light-path count;
//! - gradient-domain tracing: each pixel's pair sums and count; the
//!   Poisson reconstruction runs on the merge;
//! - Metropolis: the chains' unscaled splat sums and their mutations, the
//!   normalisation that every part computes from the seed, and for Veach's
//!   MLT with a direct pass that pass's camera sums.

use aether_strategies::scene::Scene;
use glam::DVec3;

use crate::film::{Film, camera_image, saturate};
use crate::gradient::{PairSums, pair_images};
use crate::poisson::{Norm, reconstruct};
use crate::shard::Partial;

/// Puts `film`'s camera sums (`{prefix}sum`), counts (`{prefix}samples`),
/// splatted sums (`{prefix}splat`, zero where none) and light paths
/// (`{prefix}light_paths`) in `p`.
pub fn put_camera(film: &Film, prefix: &str, p: &mut Partial) {
    p.put_rgb(&format!("{prefix}sum"), film.sums());
    let counts = film.counts().iter().map(|&n| f64::from(n)).collect();
    p.planes.insert(format!("{prefix}samples"), counts);
    let (splats, paths) = film.splat_sums().map_or_else(
        || (vec![[0.0; 3]; film.sums().len()], 0),
        |(s, n)| (s.to_vec(), n),
    );
    p.put_rgb(&format!("{prefix}splat"), &splats);
    p.totals
        .insert(format!("{prefix}light_paths"), paths as f64);
    p.totals
        .insert(format!("{prefix}dropped"), film.dropped() as f64);
}

/// Copies `from`'s planes and totals into `to`, their names prefixed.
pub fn put_prefixed(from: &Partial, prefix: &str, to: &mut Partial) {
    for (name, plane) in &from.planes {
        to.planes.insert(format!("{prefix}{name}"), plane.clone());
    }
    for (name, total) in &from.totals {
        to.totals.insert(format!("{prefix}{name}"), *total);
    }
}

/// The image of the camera planes `{prefix}…` of `p`.
fn camera_from(p: &Partial, prefix: &str) -> Option<Vec<[f32; 3]>> {
    let sums = p.rgb(&format!("{prefix}sum"))?;
    let counts: Vec<u32> = p
        .plane(&format!("{prefix}samples"))?
        .iter()
        .map(|&n| n as u32)
        .collect();
    let splats = p.rgb(&format!("{prefix}splat"))?;
    let paths = p.total(&format!("{prefix}light_paths")) as u64;
    Some(camera_image(&sums, &counts, Some((&splats, paths))))
}

/// Metropolis' image: the chains' splat sums times the normalisation over
/// the mutations.
#[must_use]
pub fn chain_image(sums: &[[f64; 3]], normalisation: f64, mutations: f64) -> Vec<[f64; 3]> {
    let scale = normalisation / mutations.max(1.0);
    sums.iter().map(|a| a.map(|v| v * scale)).collect()
}

/// Veach's MLT image with its direct pass added.
#[must_use]
pub fn with_direct(chains: &[[f32; 3]], direct: &[[f32; 3]]) -> Vec<[f64; 3]> {
    chains
        .iter()
        .zip(direct)
        .map(|(a, b)| [0, 1, 2].map(|k| f64::from(a[k]) + f64::from(b[k])))
        .collect()
}

/// The images a merge writes: the image, and images to write beside it
/// (the primal and gradients of gradient-domain tracing) with the suffix
/// of their names.
#[derive(Debug)]
pub struct Finished {
    /// The image.
    pub image: Vec<[f32; 3]>,
    /// Images beside it.
    pub beside: Vec<(&'static str, Vec<[f32; 3]>)>,
}

/// The images of the sum of a render's parts, by the integrator they name.
///
/// # Errors
/// If the parts lack what their integrator's images need.
pub fn finish(p: &Partial) -> Result<Finished, String> {
    let integrator = p.same.get("integrator").map_or("", String::as_str);
    let missing = |what: &str| format!("the parts lack {what} for the integrator '{integrator}'");
    let image = match integrator {
        "path" | "direct" | "light" | "bdpt" | "tridir" => {
            camera_from(p, "").ok_or_else(|| missing("camera sums"))?
        }
        "mlt" | "pssmlt" | "mmlt" => {
            let sums = p.rgb("chain").ok_or_else(|| missing("chain sums"))?;
            let b: f64 = p
                .same
                .get("normalisation")
                .and_then(|b| b.parse().ok())
                .ok_or_else(|| missing("the normalisation"))?;
            let chains = chain_image(&sums, b, p.total("mutations"));
            let chains: Vec<[f32; 3]> = chains.iter().map(|c| c.map(saturate)).collect();
            match camera_from(p, "direct.") {
                Some(direct) => with_direct(&chains, &direct)
                    .iter()
                    .map(|c| c.map(saturate))
                    .collect(),
                None => chains,
            }
        }
        "gpt" => return finish_gradients(p).ok_or_else(|| missing("pair sums")),
        other => {
            return Err(format!(
                "the parts name no integrator that can be merged ('{other}')"
            ));
        }
    };
    Ok(Finished {
        image,
        beside: Vec::new(),
    })
}

fn finish_gradients(p: &Partial) -> Option<Finished> {
    let counts = p.plane("samples")?;
    let planes: Vec<Vec<[f64; 3]>> = (0..4)
        .flat_map(|d| [format!("base{d}"), format!("offset{d}")])
        .map(|name| p.rgb(&name))
        .collect::<Option<_>>()?;
    let sums: Vec<Option<PairSums>> = (0..counts.len())
        .map(|i| {
            (counts[i] > 0.0).then(|| PairSums {
                base: std::array::from_fn(|d| DVec3::from_array(planes[2 * d][i])),
                offset: std::array::from_fn(|d| DVec3::from_array(planes[2 * d + 1][i])),
            })
        })
        .collect();
    let done = counts.iter().copied().fold(0.0, f64::max) as u32;
    let [primal, dx, dy] = pair_images(p.width, p.height, &sums, done);
    let l1 = p.same.get("gpt.l1")?.parse::<bool>().ok()?;
    let alpha = p.same.get("gpt.alpha")?.parse::<f32>().ok()?;
    let norm = if l1 { Norm::L1 } else { Norm::L2 };
    let image = reconstruct(p.width, p.height, &primal, &dx, &dy, alpha, norm);
    Some(Finished {
        image,
        beside: vec![("primal", primal), ("dx", dx), ("dy", dy)],
    })
}

/// What every part of a render of `scene` must share: a hash of the
/// scene's content (geometry, materials, emitters, camera and film), its
/// integrator and settings (`settings`: what the command line set), and the seed.
pub fn put_render(p: &mut Partial, scene: &Scene, settings: &str, seed: u64) {
    p.same.insert("scene".into(), content_hash(scene));
    p.same
        .insert("integrator".into(), scene.integrator.name.clone());
    p.same.insert("settings".into(), settings.to_string());
    p.same.insert("seed".into(), seed.to_string());
}

/// A 64-bit FNV-1a hash of everything in `scene` that changes its image.
#[must_use]
pub fn content_hash(scene: &Scene) -> String {
    struct Fnv(u64);
    impl Fnv {
        fn bytes(&mut self, b: &[u8]) {
            for &x in b {
                self.0 = (self.0 ^ u64::from(x)).wrapping_mul(0x100_0000_01b3);
            }
        }
    }
    impl std::fmt::Write for Fnv {
        fn write_str(&mut self, s: &str) -> std::fmt::Result {
            self.bytes(s.as_bytes());
            Ok(())
        }
    }
    let mut h = Fnv(0xcbf2_9ce4_8422_2325);
    let f = &scene.film;
    // Not where shapes were declared: the same scene at another path is
    // the same scene.
    let shapes: Vec<_> = scene
        .shapes
        .iter()
        .map(|s| (s.material, s.emitter))
        .collect();
    let described = (
        shapes,
        scene.geometry.spheres(),
        &scene.materials,
        &scene.emitters,
        &scene.camera,
        (f.width, f.height, f.crop, &f.filter),
        &scene.integrator,
        &scene.portals,
    );
    let _ = std::fmt::Write::write_fmt(&mut h, format_args!("{described:?}"));
    for mesh in scene.geometry.meshes() {
        for p in &mesh.positions {
            p.to_array().iter().for_each(|v| h.bytes(&v.to_le_bytes()));
        }
        for t in &mesh.triangles {
            t.iter().for_each(|v| h.bytes(&v.to_le_bytes()));
        }
    }
    format!("{:016x}", h.0)
}
