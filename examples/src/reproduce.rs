//! The reproduction report: every Aether scene file rendered with the
//! integrator it names, and each distinct scene with every integrator at
//! equal time, all compared with a long BDPT reference that the report
//! renders itself (cached, and reused when present), written as an HTML
//! page with PNG images. With the output of `tools/mitsuba_compare.py`, the
//! named renders are also compared with Mitsuba 3's, with false-colour
//! difference images.

use std::collections::HashMap;
use std::collections::hash_map::DefaultHasher;
use std::fmt::Write as _;
use std::hash::{Hash, Hasher};
use std::path::{Path, PathBuf};

use aether_strategies::scene::Scene;
use aether_strategies::spectrum::luminance;
use indicatif::{ProgressBar, ProgressStyle};
use integrators::output::{Comparison, read_exr, write_exr, write_png};

use crate::{render_for, workspace};

/// What to render and where to write it.
#[derive(Clone, Debug)]
pub struct Options {
    /// The folder of Aether scene files (searched recursively).
    pub scenes: PathBuf,
    /// Where the report (`index.html`) and its images go.
    pub out: PathBuf,
    /// Where references are cached.
    pub cache: PathBuf,
    /// Film width of every render (the height keeps the aspect ratio).
    pub width: u32,
    /// Seconds of each render.
    pub seconds: f64,
    /// Seconds of each reference.
    pub reference_seconds: f64,
    /// Mitsuba 3 renders (`<scene stem>.exr`, same resolution), if any.
    pub mitsuba: Option<PathBuf>,
    /// Show a progress bar.
    pub progress: bool,
}

impl Options {
    /// The full report: 192 pixels wide, 10 s per render, 240 s references,
    /// in `target/reproduce`.
    #[must_use]
    pub fn full() -> Self {
        let target = workspace().join("target/reproduce");
        Options {
            scenes: workspace().join("../shared/scenes/aether"),
            cache: target.join("references"),
            out: target,
            width: 192,
            seconds: 10.0,
            reference_seconds: 240.0,
            mitsuba: None,
            progress: true,
        }
    }

    /// The quick report for CI: 32 pixels wide, 0.2 s per render, 1.5 s
    /// references (a couple of minutes in all on two cores).
    #[must_use]
    pub fn quick() -> Self {
        let target = workspace().join("target/reproduce-quick");
        Options {
            cache: target.join("references"),
            out: target,
            width: 32,
            seconds: 0.2,
            reference_seconds: 1.5,
            ..Options::full()
        }
    }
}

/// Which part of the report a row belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Section {
    /// A scene file with the integrator it names.
    Named,
    /// A scene with one of every integrator, at equal time.
    EqualTime,
    /// The reference of a scene.
    Reference,
}

/// One render of the report.
#[derive(Clone, Debug)]
pub struct Row {
    /// Its part of the report.
    pub section: Section,
    /// The scene file, relative to the scene folder.
    pub scene: String,
    /// The integrator.
    pub integrator: String,
    /// What came of it: the render, or why there is none.
    pub outcome: Result<Render, String>,
}

/// A finished render.
#[derive(Clone, Debug)]
pub struct Render {
    /// Its PNG preview, relative to the report.
    pub png: String,
    /// Film size.
    pub size: [u32; 2],
    /// Passes of one sample per pixel.
    pub passes: u32,
    /// Wall-clock seconds.
    pub seconds: f64,
    /// Camera samples per second.
    pub samples_per_second: f64,
    /// Mean luminance.
    pub mean: f64,
    /// True if every pixel is finite.
    pub finite: bool,
    /// True if some pixel is not black.
    pub lit: bool,
    /// RMSE and relMSE against the reference.
    pub error: Option<(f64, f64)>,
    /// Against Mitsuba 3: relative difference of means, RMSE, and the
    /// false-colour difference image.
    pub mitsuba: Option<(f64, f64, String, String)>,
}

/// The report: its rows and the HTML page.
#[derive(Debug)]
pub struct Report {
    /// Every render, in the order of the page.
    pub rows: Vec<Row>,
    /// The page.
    pub html: PathBuf,
}

/// The integrators of the equal-time part (direct lighting is left out: it
/// estimates another image).
const EQUAL_TIME: [&str; 8] = [
    "path", "light", "bdpt", "tridir", "gpt", "mlt", "pssmlt", "mmlt",
];

/// Scene files replaced by the project's own version: Aether hard-coded the
/// keyhole of `cbox_tridir.xml`, which `scenes/` declares as a portal.
const REPLACED: [(&str, &str); 1] = [("cbox/cbox_tridir.xml", "scenes/cbox_tridir_keyhole.xml")];

/// Renders the report.
///
/// # Errors
/// If the scene folder cannot be read or the report cannot be written;
/// a scene or integrator that fails gets a row saying why.
pub fn run(o: &Options) -> Result<Report, String> {
    let files = scene_files(&o.scenes)?;
    let images = o.out.join("images");
    for dir in [&o.out, &images, &o.cache] {
        std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    }
    let mut scenes = Vec::new();
    let mut rows = Vec::new();
    for file in &files {
        let name = file
            .strip_prefix(&o.scenes)
            .unwrap_or(file)
            .display()
            .to_string();
        match load_scaled(o, &name, file) {
            Ok(scene) => scenes.push((name, scene)),
            Err(e) => rows.push(Row {
                section: Section::Named,
                scene: name,
                integrator: "-".into(),
                outcome: Err(e),
            }),
        }
    }
    // Each distinct scene once in the equal-time part: files that differ
    // only in their integrator share a signature.
    let mut distinct: Vec<usize> = Vec::new();
    for (i, (_, scene)) in scenes.iter().enumerate() {
        if !distinct
            .iter()
            .any(|&j| signature(&scenes[j].1) == signature(scene))
        {
            distinct.push(i);
        }
    }
    let equal_time: Vec<(usize, &str)> = distinct
        .iter()
        .flat_map(|&i| EQUAL_TIME.iter().map(move |&n| (i, n)))
        .filter(|&(i, n)| n != "tridir" || !scenes[i].1.portals.is_empty())
        .collect();
    let bar = if o.progress {
        ProgressBar::new((scenes.len() + equal_time.len()) as u64)
    } else {
        ProgressBar::hidden()
    };
    bar.set_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} {elapsed_precise} {msg}")
            .expect("valid template"),
    );
    let mut references: HashMap<u64, Option<Vec<[f32; 3]>>> = HashMap::new();
    let mut reference = |name: &str, scene: &mut Scene, bar: &ProgressBar, rows: &mut Vec<Row>| {
        let key = reference_key(scene);
        references
            .entry(key)
            .or_insert_with(|| {
                bar.set_message(format!("{name}: reference"));
                let row = render_reference(o, name, key, scene);
                let image = row.1;
                rows.push(row.0);
                image
            })
            .clone()
    };
    for (name, scene) in &mut scenes {
        bar.set_message(format!("{name}: {}", scene.integrator.name));
        let integrator = scene.integrator.name.clone();
        let r = reference(name, scene, &bar, &mut rows);
        let outcome = render_row(o, name, &integrator, scene, r.as_deref(), "named");
        rows.push(Row {
            section: Section::Named,
            scene: name.clone(),
            integrator,
            outcome,
        });
        bar.inc(1);
    }
    for (i, integrator) in equal_time {
        let (name, scene) = &mut scenes[i];
        bar.set_message(format!("{name}: {integrator}, equal time"));
        let r = reference(name, scene, &bar, &mut rows);
        let outcome = render_row(o, name, integrator, scene, r.as_deref(), "equal");
        rows.push(Row {
            section: Section::EqualTime,
            scene: name.clone(),
            integrator: integrator.into(),
            outcome,
        });
        bar.inc(1);
    }
    bar.finish_and_clear();
    let html = o.out.join("index.html");
    std::fs::write(&html, page(o, &rows)).map_err(|e| format!("{}: {e}", html.display()))?;
    Ok(Report { rows, html })
}

/// The scene files under `dir` and its folders, sorted.
///
/// # Errors
/// If a folder cannot be listed.
pub fn scene_files(dir: &Path) -> Result<Vec<PathBuf>, String> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        let entries = std::fs::read_dir(&d).map_err(|e| format!("{}: {e}", d.display()))?;
        for entry in entries.flatten() {
            let path = entry.path();
            if path.is_dir() {
                stack.push(path);
            } else if path.extension().is_some_and(|e| e == "xml") {
                out.push(path);
            }
        }
    }
    out.sort();
    Ok(out)
}

/// Loads a scene at the report's width, with Aether's depth limit of 6
/// where the file sets none.
fn load_scaled(o: &Options, name: &str, file: &Path) -> Result<Scene, String> {
    let replaced = REPLACED.iter().find(|(from, _)| *from == name);
    let file = replaced.map_or(file.to_path_buf(), |(_, to)| workspace().join(to));
    let mut scene = Scene::load(&file, &HashMap::new()).map_err(|e| e.to_string())?;
    scene
        .film
        .scale_to_width(o.width)
        .map_err(|e| e.to_string())?;
    if scene.integrator.max_depth < 0 {
        scene.integrator.max_depth = 6;
    }
    Ok(scene)
}

/// What makes two scene files the same scene: everything but the integrator.
fn signature(scene: &Scene) -> String {
    let film = &scene.film;
    format!(
        "{} {} {} {} {:?} {}x{} {:?} {} {}",
        scene.geometry.triangle_count(),
        scene.geometry.spheres().len(),
        scene.emitters.len(),
        scene.materials.len(),
        scene.camera,
        film.width,
        film.height,
        film.crop,
        film.filter,
        scene.portals.len()
    )
}

/// The cache key of a scene's reference: the scene and the depth limits.
fn reference_key(scene: &Scene) -> u64 {
    let mut h = DefaultHasher::new();
    signature(scene).hash(&mut h);
    (scene.integrator.max_depth, scene.integrator.rr_depth).hash(&mut h);
    h.finish()
}

/// The reference of a scene: BDPT for the reference time on its own
/// random streams, read from the cache when present.
fn render_reference(
    o: &Options,
    name: &str,
    key: u64,
    scene: &mut Scene,
) -> (Row, Option<Vec<[f32; 3]>>) {
    let (w, h) = (scene.film.width, scene.film.height);
    let file = o
        .cache
        .join(format!("{key:016x}-{w}x{h}-{}s.exr", o.reference_seconds));
    let named = scene.integrator.name.clone();
    let outcome = match read_exr(&file) {
        Ok((rw, rh, image)) if (rw, rh) == (w, h) => Ok((image, 0, 0.0, 0.0)),
        _ => render_for(scene, "bdpt", o.reference_seconds, 1_000_003).and_then(|r| {
            write_exr(&file, w, h, &r.image, r.passes, r.seconds)?;
            Ok((r.image, r.passes, r.seconds, r.samples as f64 / r.seconds))
        }),
    };
    scene.integrator.name = named;
    let row = |outcome| Row {
        section: Section::Reference,
        scene: name.to_string(),
        integrator: "bdpt".into(),
        outcome,
    };
    match outcome {
        Ok((image, passes, seconds, rate)) => {
            let png = format!("images/reference-{key:016x}.png");
            let written = write_png(&o.out.join(&png), w, h, &image, 0.0);
            let render = written.map(|()| Render {
                png,
                size: [w, h],
                passes,
                seconds,
                samples_per_second: rate,
                mean: mean(&image),
                finite: image.iter().flatten().all(|v| v.is_finite()),
                lit: image.iter().flatten().any(|&v| v > 0.0),
                error: None,
                mitsuba: None,
            });
            (row(render), Some(image))
        }
        Err(e) => (row(Err(e)), None),
    }
}

/// Renders one row's image and compares it.
fn render_row(
    o: &Options,
    name: &str,
    integrator: &str,
    scene: &mut Scene,
    reference: Option<&[[f32; 3]]>,
    part: &str,
) -> Result<Render, String> {
    let named = scene.integrator.name.clone();
    let r = render_for(scene, integrator, o.seconds, 17);
    scene.integrator.name = named;
    let r = r?;
    let (w, h) = (scene.film.width, scene.film.height);
    let stem = name.replace(['/', '.'], "-");
    let png = format!("images/{part}-{stem}-{integrator}.png");
    write_png(&o.out.join(&png), w, h, &r.image, 0.0)?;
    let error = reference
        .and_then(|rf| Comparison::of(&r.image, rf))
        .map(|c| (c.rmse, c.rel_mse));
    let mitsuba = match (&o.mitsuba, part) {
        (Some(dir), "named") => against_mitsuba(o, dir, name, &r.image, [w, h])?,
        _ => None,
    };
    Ok(Render {
        png,
        size: [w, h],
        passes: r.passes,
        seconds: r.seconds,
        samples_per_second: r.samples as f64 / r.seconds,
        mean: mean(&r.image),
        finite: r.image.iter().flatten().all(|v| v.is_finite()),
        lit: r.image.iter().flatten().any(|&v| v > 0.0),
        error,
        mitsuba,
    })
}

/// Compares `image` with Mitsuba 3's render of the scene, if there is one
/// of the same size: the relative difference of means, the RMSE, Mitsuba's
/// image and a false-colour difference image (red where ours is brighter,
/// blue where darker; full colour at three times the RMSE).
fn against_mitsuba(
    o: &Options,
    dir: &Path,
    name: &str,
    image: &[[f32; 3]],
    [w, h]: [u32; 2],
) -> Result<Option<(f64, f64, String, String)>, String> {
    let stem = name.replace(['/', '.'], "-");
    let Ok((mw, mh, theirs)) = read_exr(&dir.join(format!("{stem}.exr"))) else {
        return Ok(None);
    };
    let Some(c) = Comparison::of(image, &theirs).filter(|_| (mw, mh) == (w, h)) else {
        return Ok(None);
    };
    let (png, diff) = (
        format!("images/mitsuba-{stem}.png"),
        format!("images/difference-{stem}.png"),
    );
    write_png(&o.out.join(&png), w, h, &theirs, 0.0)?;
    let scale = 3.0 * c.rmse.max(1e-12);
    let colours: Vec<u8> = image
        .iter()
        .zip(&theirs)
        .flat_map(|(a, b)| {
            let d = ((luminance(*a) - luminance(*b)) / scale).clamp(-1.0, 1.0);
            let fade = |x: f64| (255.0 * (1.0 - x.abs())) as u8;
            if d >= 0.0 {
                [255, fade(d), fade(d)]
            } else {
                [fade(d), fade(d), 255]
            }
        })
        .collect();
    image::save_buffer(o.out.join(&diff), &colours, w, h, image::ColorType::Rgb8)
        .map_err(|e| format!("{diff}: {e}"))?;
    Ok(Some((c.relative_difference(), c.rmse, png, diff)))
}

fn mean(image: &[[f32; 3]]) -> f64 {
    image.iter().map(|c| luminance(*c)).sum::<f64>() / image.len().max(1) as f64
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// The HTML page.
fn page(o: &Options, rows: &[Row]) -> String {
    let mut s = String::new();
    let _ = write!(
        s,
        "<!doctype html>\n<html><head><meta charset=\"utf-8\"><title>Reproducing the Aether examples</title>\n\
         <style>body{{font-family:sans-serif;margin:2em}}table{{border-collapse:collapse}}\
         td,th{{border:1px solid #ccc;padding:4px 8px;text-align:right;vertical-align:top}}\
         td.l,th.l{{text-align:left}}img{{width:192px;image-rendering:pixelated}}.err{{color:#a00}}</style>\n\
         </head><body>\n<h1>Reproducing the Aether examples</h1>\n\
         <p>Every scene file of <code>{}</code> rendered {} pixels wide for {} s with the integrator it names; \
         each distinct scene with every integrator for the same time; RMSE and relMSE against BDPT rendered for {} s \
         on its own random streams (cached in <code>{}</code>).</p>\n",
        escape(&o.scenes.display().to_string()),
        o.width,
        o.seconds,
        o.reference_seconds,
        escape(&o.cache.display().to_string())
    );
    let sections = [
        (Section::Named, "Each scene with the integrator it names"),
        (Section::EqualTime, "Every integrator at equal time"),
        (Section::Reference, "References"),
    ];
    for (section, title) in sections {
        let _ = write!(
            s,
            "<h2>{title}</h2>\n<table><tr><th class=l>scene</th><th class=l>integrator</th><th>image</th>\
             <th>passes</th><th>seconds</th><th>samples/s</th><th>mean</th><th>RMSE</th><th>relMSE</th>\
             <th>Mitsuba 3</th><th>difference</th><th>Δ mean</th><th>RMSE vs Mitsuba</th></tr>\n"
        );
        for row in rows.iter().filter(|r| r.section == section) {
            let _ = write!(
                s,
                "<tr><td class=l>{}</td><td class=l>{}</td>",
                escape(&row.scene),
                escape(&row.integrator)
            );
            match &row.outcome {
                Ok(r) => {
                    let (rmse, rel) = r.error.map_or(("-".into(), "-".into()), |(a, b)| {
                        (format!("{a:.5}"), format!("{b:.5}"))
                    });
                    let _ = write!(
                        s,
                        "<td><img src=\"{}\"></td><td>{}</td><td>{:.2}</td><td>{:.0}</td><td>{:.5}</td><td>{rmse}</td><td>{rel}</td>",
                        r.png, r.passes, r.seconds, r.samples_per_second, r.mean
                    );
                    match &r.mitsuba {
                        Some((d, e, png, diff)) => {
                            let _ = write!(
                                s,
                                "<td><img src=\"{png}\"></td><td><img src=\"{diff}\"></td><td>{:+.2} %</td><td>{e:.5}</td>",
                                100.0 * d
                            );
                        }
                        None => s.push_str("<td>-</td><td>-</td><td>-</td><td>-</td>"),
                    }
                }
                Err(e) => {
                    let _ = write!(s, "<td class=\"l err\" colspan=11>{}</td>", escape(e));
                }
            }
            s.push_str("</tr>\n");
        }
        s.push_str("</table>\n");
    }
    s.push_str("</body></html>\n");
    s
}
