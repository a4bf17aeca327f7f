//! Cross-crate tests (convergence, agreement between integrators, scenes)
//! live in `tests/`; this library holds their shared helpers: scenes
//! written to temporary files, repeated renders with per-pixel variances,
//! and the statistical comparison of two integrators' images.
#![deny(unsafe_code)]

pub mod cone;
pub mod fuzz;
pub mod proposal;

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use aether_core::{Pcg32, RandomSequence};
use aether_strategies::camera::Camera;
use aether_strategies::scene::Scene;
use aether_strategies::spectrum::luminance;
use aether_strategies::vertex::SceneVertex;
use integrators::render::{Settings, render};

/// Aether's cbox-sphere (a metal and a glass sphere in the Cornell box: the
/// specular chains Veach's perturbations follow) at 64×48 pixels.
///
/// # Panics
/// If the scene does not load.
#[must_use]
pub fn cbox_sphere_small() -> Scene {
    let file = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../shared/scenes/aether/cbox-sphere/cbox-sphere-mlt-aether.xml");
    let mut scene = Scene::load(&file, &HashMap::new()).unwrap_or_else(|e| panic!("{e}"));
    let film = &mut scene.film;
    (film.width, film.height, film.crop) = (64, 48, [0, 0, 64, 48]);
    scene
}

/// Loads a scene from Mitsuba XML text, written to a fresh temporary file
/// (with `files`, name and contents, beside it).
///
/// # Panics
/// If the files cannot be written or the scene does not load.
#[must_use]
pub fn scene_from(xml: &str, files: &[(&str, &str)]) -> Scene {
    static NEXT: AtomicUsize = AtomicUsize::new(0);
    let n = NEXT.fetch_add(1, Ordering::Relaxed);
    let dir = std::env::temp_dir().join(format!("aether-tests-{}-{n}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("a temporary folder");
    for (name, text) in files {
        std::fs::write(dir.join(name), text).expect("a temporary file");
    }
    let path = dir.join("scene.xml");
    std::fs::write(&path, xml).expect("a temporary file");
    Scene::load(&path, &HashMap::new()).unwrap_or_else(|e| panic!("{e}"))
}

/// Per-pixel luminance estimates of an integrator from independent renders.
#[derive(Clone, Debug)]
pub struct Estimate {
    /// The integrator.
    pub integrator: String,
    /// Independent renders.
    pub renders: u32,
    /// Mean luminance of each pixel over the renders.
    pub mean: Vec<f64>,
    /// Variance of that mean (the sample variance over renders, over their number).
    pub variance: Vec<f64>,
    /// Each render's luminance per pixel.
    pub renders_luminance: Vec<Vec<f64>>,
    /// True if the pixels' errors are correlated, as a Metropolis image's
    /// are (its total is its normalisation, so they cancel): the error of
    /// a mean over pixels then comes from how the renders' means vary
    /// rather than from the pixels' variances.
    pub correlated_pixels: bool,
}

impl Estimate {
    /// Renders `scene` with `integrator` `renders` times, with seeds
    /// 1, 2, …, at `spp` samples per pixel each.
    ///
    /// # Panics
    /// If a render fails or drops a sample.
    #[must_use]
    pub fn of(scene: &mut Scene, integrator: &str, renders: u32, spp: u32) -> Estimate {
        scene.integrator.name = integrator.to_string();
        let images: Vec<Vec<[f32; 3]>> = (1..=u64::from(renders))
            .map(|seed| {
                let settings = Settings::new(spp, seed);
                let r = render(scene, &settings, &AtomicBool::new(false))
                    .unwrap_or_else(|e| panic!("{integrator}: {e}"));
                assert_eq!(r.film.dropped(), 0, "{integrator} dropped samples");
                r.film.image()
            })
            .collect();
        Estimate::from_images(integrator, &images)
    }

    /// The per-pixel luminance estimate from independent `images` (signed
    /// values, such as gradients, are fine).
    ///
    /// # Panics
    /// If there are fewer than two images or their sizes differ.
    #[must_use]
    pub fn from_images(name: &str, images: &[Vec<[f32; 3]>]) -> Estimate {
        assert!(images.len() >= 2, "a variance needs two images");
        let n = images[0].len();
        let (mut sum, mut sum2) = (vec![0.0; n], vec![0.0; n]);
        let mut renders_luminance = Vec::with_capacity(images.len());
        for image in images {
            assert_eq!(image.len(), n, "images of one size");
            let y: Vec<f64> = image.iter().map(|c| luminance(*c)).collect();
            for (i, y) in y.iter().enumerate() {
                sum[i] += y;
                sum2[i] += y * y;
            }
            renders_luminance.push(y);
        }
        let renders = images.len() as u32;
        let k = f64::from(renders);
        let mean: Vec<f64> = sum.iter().map(|s| s / k).collect();
        let variance = sum2
            .iter()
            .zip(&mean)
            .map(|(s2, m)| ((s2 - k * m * m) / (k - 1.0)).max(0.0) / k)
            .collect();
        Estimate {
            integrator: name.to_string(),
            renders,
            mean,
            variance,
            renders_luminance,
            correlated_pixels: false,
        }
    }

    /// The variance of the sum over the pixels `keep` holds: the sum of
    /// their variances, or for correlated pixels the sample variance of the
    /// renders' sums there, over their number.
    #[must_use]
    pub fn mean_variance(&self, keep: impl Fn(usize) -> bool) -> f64 {
        if !self.correlated_pixels {
            return (0..self.variance.len())
                .filter(|&i| keep(i))
                .map(|i| self.variance[i])
                .sum();
        }
        let means: Vec<f64> = self
            .renders_luminance
            .iter()
            .map(|y| (0..y.len()).filter(|&i| keep(i)).map(|i| y[i]).sum())
            .collect();
        let k = means.len() as f64;
        let m = means.iter().sum::<f64>() / k;
        means.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (k - 1.0) / k
    }

    /// The mean over the image.
    #[must_use]
    pub fn image_mean(&self) -> f64 {
        self.mean.iter().sum::<f64>() / self.mean.len() as f64
    }

    /// The standard error of [`image_mean`](Self::image_mean).
    #[must_use]
    pub fn image_mean_error(&self) -> f64 {
        self.mean_variance(|_| true).sqrt() / self.mean.len() as f64
    }
}

/// Pixels whose camera rays (16 per pixel) first hit a vertex for which
/// `what` holds.
///
/// # Panics
/// If the scene's camera cannot be built.
#[must_use]
pub fn seeing(scene: &Scene, what: impl Fn(&SceneVertex) -> bool) -> Vec<bool> {
    let camera = Camera::new(scene).unwrap();
    let [w, h] = camera.size();
    let lens = camera.position();
    let mut rng = Pcg32::new(0, 0);
    (0..w * h)
        .map(|i| {
            let look = camera.direction(scene, [i % w, i / w]);
            (0..16).any(|_| {
                let mut p = RandomSequence::new();
                p.append(&lens).append(&look).sample(&mut rng);
                p.vertices().get(1).is_some_and(&what)
            })
        })
        .collect()
}

/// How two estimates of one image compare.
#[derive(Clone, Debug)]
pub struct Agreement {
    /// (mean of a − mean of b) / mean of b.
    pub relative_difference: f64,
    /// Its standard error.
    pub relative_error: f64,
    /// Pixels whose difference exceeds the critical value of the test.
    pub failures: usize,
    /// Pixels tested (with a positive variance and not masked out).
    pub tested: usize,
    /// Largest failure rate consistent with the level: the level plus three
    /// binomial standard deviations.
    pub allowed: f64,
}

/// Two-sided 1 % critical values of Student's t for 1 to 15 degrees of freedom.
const T_CRITICAL_1_PERCENT: [f64; 15] = [
    63.657, 9.925, 5.841, 4.604, 4.032, 3.707, 3.499, 3.355, 3.250, 3.169, 3.106, 3.055, 3.012,
    2.977, 2.947,
];

/// Compares `a` with `b`, over the pixels where `skip` is not true: each
/// pixel at level 1 % (the difference over its standard error follows
/// Student's t with at least renders − 1 degrees of freedom if both converge
/// to the same image, so at most 1 % of pixels, plus binomial noise, may
/// exceed the critical value), and the image means, from which the pixels
/// in `edges` are left out too: pixels that see a light, whose noise at
/// the light's edge would take far more samples than a test can afford to
/// pin a mean down to 0.5 % (the per-pixel test still covers them).
///
/// # Panics
/// If the estimates differ in size or have fewer than 2 or more than 16 renders.
#[must_use]
pub fn agreement(
    a: &Estimate,
    b: &Estimate,
    skip: Option<&[bool]>,
    edges: Option<&[bool]>,
) -> Agreement {
    assert_eq!(a.mean.len(), b.mean.len());
    let df = a.renders.min(b.renders) as usize - 1;
    let critical = T_CRITICAL_1_PERCENT[df - 1];
    let (mut failures, mut tested) = (0, 0);
    let (mut ma, mut mb) = (0.0, 0.0);
    let in_means = |i: usize| !skip.is_some_and(|s| s[i]) && !edges.is_some_and(|e| e[i]);
    for i in 0..a.mean.len() {
        if skip.is_some_and(|s| s[i]) {
            continue;
        }
        let v = a.variance[i] + b.variance[i];
        if in_means(i) {
            ma += a.mean[i];
            mb += b.mean[i];
        }
        if v <= 0.0 {
            continue;
        }
        tested += 1;
        if (a.mean[i] - b.mean[i]).abs() / v.sqrt() > critical {
            failures += 1;
        }
    }
    let error = (a.mean_variance(in_means) + b.mean_variance(in_means)).sqrt() / mb;
    let level = 0.01;
    Agreement {
        relative_difference: (ma - mb) / mb,
        relative_error: error,
        failures,
        tested,
        allowed: level + 3.0 * (level * (1.0 - level) / tested.max(1) as f64).sqrt(),
    }
}

/// Asserts that `a` and `b` agree ([`agreement`]): image means within
/// `tolerance` (relative), with a standard error small enough to tell
/// (below a third of it), and a per-pixel failure rate within
/// [`Agreement::allowed`].
///
/// # Panics
/// If they do not.
pub fn assert_agree(
    scene: &str,
    (a, b): (&Estimate, &Estimate),
    skip: Option<&[bool]>,
    edges: Option<&[bool]>,
    tolerance: f64,
) {
    let r = agreement(a, b, skip, edges);
    let rate = r.failures as f64 / r.tested.max(1) as f64;
    println!(
        "{scene}: {} {:.5} ± {:.5}, {} {:.5} ± {:.5} (whole images)",
        a.integrator,
        a.image_mean(),
        a.image_mean_error(),
        b.integrator,
        b.image_mean(),
        b.image_mean_error()
    );
    println!(
        "{scene}: {} vs {}: means differ by {:+.3} % ± {:.3} %, {} of {} pixels fail the 1 % test ({:.2} %, allowed {:.2} %)",
        a.integrator,
        b.integrator,
        100.0 * r.relative_difference,
        100.0 * r.relative_error,
        r.failures,
        r.tested,
        100.0 * rate,
        100.0 * r.allowed
    );
    assert!(r.tested > 0, "{scene}: no pixel to test");
    assert!(
        r.relative_error < tolerance / 3.0,
        "{scene}: {} and {}: a standard error of {:.3} % cannot resolve {:.2} %",
        a.integrator,
        b.integrator,
        100.0 * r.relative_error,
        100.0 * tolerance
    );
    assert!(
        r.relative_difference.abs() < tolerance,
        "{scene}: {} and {} means differ by {:.3} % ± {:.3} %",
        a.integrator,
        b.integrator,
        100.0 * r.relative_difference,
        100.0 * r.relative_error
    );
    assert!(
        rate <= r.allowed,
        "{scene}: {} and {} differ in {} of {} pixels",
        a.integrator,
        b.integrator,
        r.failures,
        r.tested
    );
}

/// The lines of the function `name` (its signature through its closing
/// brace) in `source`, after the first occurrence of `after`: the
/// non-blank, non-comment lines of its body.
///
/// # Panics
/// If `after` or the function is not found.
#[must_use]
pub fn function_lines(source: &str, after: &str, name: &str) -> usize {
    let start = source
        .find(after)
        .unwrap_or_else(|| panic!("{after} not found"));
    let rest = &source[start..];
    let at = rest
        .find(&format!("fn {name}"))
        .unwrap_or_else(|| panic!("fn {name} not found after {after}"));
    // The body: the lines after the one that opens it, up to its closing
    // brace (the signature is boilerplate, not sampling code).
    let mut depth = 0i32;
    let mut opened = false;
    let mut count = 0;
    for line in rest[at..].lines() {
        let code = line.trim();
        let counted = opened && !code.is_empty() && !code.starts_with("//");
        for c in code.chars() {
            match c {
                '{' => {
                    depth += 1;
                    opened = true;
                }
                '}' => depth -= 1,
                _ => {}
            }
        }
        if opened && depth == 0 {
            break;
        }
        if counted {
            count += 1;
        }
    }
    count
}

/// Non-blank, non-comment lines of `source` from the line holding `start`
/// up to (not including) the line holding `end`, the first `end` after it.
///
/// # Panics
/// If either marker is missing.
#[must_use]
pub fn lines_between(source: &str, start: &str, end: &str) -> usize {
    let from = source
        .find(start)
        .unwrap_or_else(|| panic!("{start} not found"));
    let from = source[..from].rfind('\n').map_or(0, |i| i + 1);
    let to = from
        + source[from..]
            .find(end)
            .unwrap_or_else(|| panic!("{end} not found after {start}"));
    source[from..to]
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with("//"))
        .count()
}

/// A caustic room: a smooth glass sphere over the diffuse floor of a closed
/// room under a point light, and a smooth mirror sphere beside it
/// that the camera sees the floor in. Light reaches the floor through the
/// glass (L S S D E paths: the caustic perturbation's) and the camera sees
/// that caustic in the mirror (E S D S S L: the multi-chain
/// perturbation's), at `width` × `height` pixels with a box filter.
///
/// # Panics
/// If the scene does not load.
#[must_use]
pub fn caustic_room(width: u32, height: u32, max_depth: i32) -> Scene {
    let xml = format!(
        r#"<scene version="0.5.0">
            <integrator type="bdpt"><integer name="maxDepth" value="{max_depth}"/></integrator>
            <shape type="cube"><boolean name="flipNormals" value="true"/>
                <bsdf type="diffuse"><rgb name="reflectance" value="0.6, 0.55, 0.5"/></bsdf></shape>
            <shape type="sphere"><point name="center" x="-0.2" y="-0.55" z="-0.1"/><float name="radius" value="0.3"/>
                <bsdf type="dielectric"><float name="intIOR" value="1.5"/><float name="extIOR" value="1"/></bsdf></shape>
            <shape type="sphere"><point name="center" x="0.55" y="-0.7" z="-0.45"/><float name="radius" value="0.3"/>
                <bsdf type="conductor"><string name="material" value="none"/></bsdf></shape>
            <emitter type="point"><point name="position" x="-0.25" y="0.75" z="-0.15"/><rgb name="intensity" value="1"/></emitter>
            <sensor type="perspective"><float name="fov" value="60"/>
                <transform name="toWorld"><lookat origin="0.1, 0.1, 0.95" target="-0.05, -0.6, -0.1" up="0, 1, 0"/></transform>
                <film type="hdrfilm"><integer name="width" value="{width}"/><integer name="height" value="{height}"/>
                <rfilter type="box"/></film></sensor>
        </scene>"#
    );
    scene_from(&xml, &[])
}
