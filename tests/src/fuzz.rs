//! A seeded fuzzer for the scene reader and the renderer: mutants of real
//! scene files (truncated, lines deleted and duplicated, numbers and
//! attribute values replaced by extreme or hostile ones, deep nesting,
//! include cycles, invalid UTF-8), each loaded and, where it loads,
//! rendered at a tiny size, with panics caught and counted.

use std::collections::HashMap;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use aether_core::Pcg32;
use aether_strategies::scene::Scene;
use integrators::render::{Settings, render};

/// Numbers that have broken renderers: NaN, infinities, overflowing and
/// denormal values, huge and negative sizes.
const NUMBERS: &[&str] = &[
    "nan",
    "NaN",
    "inf",
    "-inf",
    "1e30",
    "-1e30",
    "1e20",
    "1e17",
    "3.4e38",
    "-3.4e38",
    "1e-40",
    "-1",
    "0",
    "-0",
    "2147483647",
    "4294967295",
    "-2147483648",
    "99999999999999999999",
    "1e308",
    "0.0000001",
];

/// Attribute values that name nothing, devices, folders or garbage.
const VALUES: &[&str] = &[
    "",
    "/dev/zero",
    "/dev/urandom",
    ".",
    "..",
    "missing.obj",
    "$undefined",
    "<",
    "&amp;",
    "∞",
    "obj",
    "serialized",
    "twosided",
    "area",
    "path",
    "mlt",
    "tridir",
    "gpt",
    "1e20",
    "-1",
];

/// What one mutant did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Outcome {
    /// Refused with an error naming a file.
    Error,
    /// Refused with an error that names no file.
    Unnamed,
    /// Loaded and rendered, every pixel finite.
    Rendered,
    /// Loaded, and the renderer refused it with an error.
    RenderError,
    /// Rendered, with a NaN or infinite pixel.
    NonFinite,
    /// A panic, with its message.
    Panic,
    /// Took longer than the hang bound.
    Hang,
}

/// Counts of outcomes over a run of mutants.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Tally {
    /// Mutants run.
    pub mutants: u64,
    /// Counts by outcome, in the order of [`Outcome`]'s variants.
    pub counts: [u64; 7],
    /// The first few failures: seed scene, mutant index and what happened.
    pub failures: Vec<String>,
}

impl Tally {
    /// Adds one outcome.
    pub fn add(&mut self, outcome: Outcome, what: impl FnOnce() -> String) {
        self.mutants += 1;
        self.counts[outcome as usize] += 1;
        let bad = !matches!(
            outcome,
            Outcome::Error | Outcome::Rendered | Outcome::RenderError
        );
        if bad && self.failures.len() < 20 {
            self.failures.push(what());
        }
    }

    /// Adds another tally's counts.
    pub fn merge(&mut self, other: &Tally) {
        self.mutants += other.mutants;
        for (a, b) in self.counts.iter_mut().zip(other.counts) {
            *a += b;
        }
        self.failures.extend(other.failures.iter().cloned());
    }

    /// The count of one outcome.
    #[must_use]
    pub fn count(&self, outcome: Outcome) -> u64 {
        self.counts[outcome as usize]
    }

    /// One line: the figures a report quotes, and how a parent parses them.
    #[must_use]
    pub fn line(&self) -> String {
        let c = &self.counts;
        format!(
            "fuzz: mutants={} errors={} unnamed={} rendered={} render_errors={} nonfinite={} panics={} hangs={}",
            self.mutants, c[0], c[1], c[2], c[3], c[4], c[5], c[6]
        )
    }

    /// Parses [`Tally::line`].
    #[must_use]
    pub fn parse(line: &str) -> Option<Tally> {
        let rest = line.strip_prefix("fuzz: ")?;
        let values: Vec<u64> = rest
            .split(' ')
            .map(|kv| kv.split_once('=').and_then(|(_, v)| v.parse().ok()))
            .collect::<Option<_>>()?;
        let (&mutants, counts) = values.split_first()?;
        Some(Tally {
            mutants,
            counts: counts.try_into().ok()?,
            failures: Vec::new(),
        })
    }
}

/// Every scene file under the folders given (absent ones skipped), sorted.
#[must_use]
pub fn scene_files(folders: &[PathBuf]) -> Vec<PathBuf> {
    let mut out: Vec<PathBuf> = folders
        .iter()
        .filter_map(|f| examples::reproduce::scene_files(f).ok())
        .flatten()
        .collect();
    out.sort();
    out
}

/// Mutant `index` of the scene text `original`, whose file is `path`.
#[must_use]
pub fn mutate(original: &str, path: &Path, index: u64) -> Vec<u8> {
    let mut rng = Pcg32::new(0xf022, index);
    let mut text = original.to_string();
    let edits = 1 + rng.next_u32() % 3;
    for _ in 0..edits {
        text = edit(&text, path, &mut rng);
    }
    let mut bytes = text.into_bytes();
    if rng.next_u32() % 24 == 0 {
        // Invalid UTF-8 somewhere.
        let at = below(&mut rng, bytes.len() + 1);
        bytes.splice(at..at, [0xff, 0xfe, 0xc3]);
    }
    bytes
}

fn below(rng: &mut Pcg32, n: usize) -> usize {
    (rng.next_u32() as usize) % n.max(1)
}

fn edit(text: &str, path: &Path, rng: &mut Pcg32) -> String {
    let lines: Vec<&str> = text.lines().collect();
    let line = below(rng, lines.len());
    let join = |ls: Vec<&str>| ls.join("\n");
    match rng.next_u32() % 9 {
        0 => {
            let mut cut = below(rng, text.len());
            while !text.is_char_boundary(cut) {
                cut -= 1;
            }
            text[..cut].to_string()
        }
        1 => {
            let mut ls = lines.clone();
            if !ls.is_empty() {
                ls.remove(line);
            }
            join(ls)
        }
        2 => {
            let mut ls = lines.clone();
            if let Some(&l) = ls.get(line) {
                ls.insert(line, l);
            }
            join(ls)
        }
        3 | 4 => replace_token(text, rng, is_number_start, NUMBERS),
        5 | 6 => replace_attribute(text, rng),
        7 => {
            // Deep nesting, past the reader's bound and to where recursion
            // would overflow the stack.
            let depth = [150, 2_000, 8_000][below(rng, 3)];
            let tag = [
                "shape type=\"obj\"",
                "bsdf type=\"twosided\"",
                "transform name=\"toWorld\"",
            ][below(rng, 3)];
            let name = tag.split(' ').next().unwrap_or("shape");
            let open = format!("<{tag}>").repeat(depth);
            let close = format!("</{name}>").repeat(depth);
            let mut ls = lines.clone();
            let nested = format!("{open}{close}");
            ls.insert(line.max(1).min(ls.len()), &nested);
            join(ls)
        }
        _ => {
            // The scene includes itself (a cycle) or a device.
            let target = match rng.next_u32() % 3 {
                0 => "/dev/zero".to_string(),
                1 => ".".to_string(),
                _ => path
                    .file_name()
                    .map_or("x".into(), |n| n.to_string_lossy().into_owned()),
            };
            let include = format!("<include filename=\"{target}\"/>");
            let mut ls = lines.clone();
            ls.insert(line.max(1).min(ls.len()), &include);
            join(ls)
        }
    }
}

fn is_number_start(b: u8) -> bool {
    b.is_ascii_digit() || b == b'-' || b == b'.'
}

/// Replaces a random run of number characters by one of `with`.
fn replace_token(text: &str, rng: &mut Pcg32, starts: fn(u8) -> bool, with: &[&str]) -> String {
    let bytes = text.as_bytes();
    let starts_at: Vec<usize> = (0..bytes.len())
        .filter(|&i| starts(bytes[i]) && (i == 0 || !starts(bytes[i - 1])))
        .collect();
    if starts_at.is_empty() {
        return text.to_string();
    }
    let s = starts_at[below(rng, starts_at.len())];
    let e = (s..bytes.len())
        .find(|&i| !(starts(bytes[i]) || bytes[i] == b'e'))
        .unwrap_or(bytes.len());
    format!(
        "{}{}{}",
        &text[..s],
        with[below(rng, with.len())],
        &text[e..]
    )
}

/// Replaces a random attribute value by a hostile one.
fn replace_attribute(text: &str, rng: &mut Pcg32) -> String {
    let quotes: Vec<usize> = text.match_indices("=\"").map(|(i, _)| i + 2).collect();
    if quotes.is_empty() {
        return text.to_string();
    }
    let s = quotes[below(rng, quotes.len())];
    let Some(len) = text[s..].find('"') else {
        return text.to_string();
    };
    let value = VALUES[below(rng, VALUES.len())];
    format!("{}{value}{}", &text[..s], &text[s + len..])
}

/// Loads `bytes` as the scene file `path` (invalid UTF-8 through a file in
/// `scratch`) and renders what loads at 8 pixels wide (at most 8 tall),
/// one sample per pixel, on one thread.
pub fn run_one(bytes: &[u8], path: &Path, scratch: &Path, hang: Duration) -> (Outcome, String) {
    let start = Instant::now();
    let result = catch_unwind(AssertUnwindSafe(|| load_and_render(bytes, path, scratch)));
    let outcome = match result {
        Ok(outcome) => outcome,
        Err(panic) => {
            let message = panic
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| panic.downcast_ref::<&str>().map(|s| (*s).to_string()))
                .unwrap_or_default();
            (Outcome::Panic, message)
        }
    };
    if start.elapsed() > hang {
        return (Outcome::Hang, format!("{:?}", start.elapsed()));
    }
    outcome
}

fn load_and_render(bytes: &[u8], path: &Path, scratch: &Path) -> (Outcome, String) {
    let params = HashMap::new();
    let loaded = match std::str::from_utf8(bytes) {
        Ok(text) => Scene::load_str(text, path, &params),
        Err(_) => {
            let file = scratch.join("mutant.xml");
            if std::fs::write(&file, bytes).is_err() {
                return (Outcome::Error, "scratch file".into());
            }
            Scene::load(&file, &params)
        }
    };
    let mut scene = match loaded {
        Err(e) if e.location.file.as_os_str().is_empty() => {
            return (Outcome::Unnamed, e.to_string());
        }
        Err(e) => return (Outcome::Error, e.to_string()),
        Ok(scene) => scene,
    };
    if scene.film.scale_to_width(8).is_err() {
        return (Outcome::Error, "film".into());
    }
    // A mutated aspect ratio would make an 8-pixel-wide film millions of
    // pixels tall: minutes of rendering that the hang check would flag.
    let f = &mut scene.film;
    f.height = f.height.min(8);
    f.crop = [0, 0, f.width, f.height];
    scene.film.spp = 1;
    if scene.integrator.max_depth < 0 || scene.integrator.max_depth > 8 {
        scene.integrator.max_depth = 8;
    }
    // The work the scene asks for is bounded like the film's, so that a
    // mutated count (2³¹ direct samples per pixel, say) is not a hang.
    let m = &mut scene.integrator.metropolis;
    (m.luminance_samples, m.chains) = (m.luminance_samples.min(64), m.chains.min(2));
    m.direct_samples = m.direct_samples.min(1);
    let settings = Settings {
        threads: Some(1),
        ..Settings::new(1, 0)
    };
    match render(&scene, &settings, &AtomicBool::new(false)) {
        Err(e) => (Outcome::RenderError, e),
        Ok(r) if r.film.image().iter().flatten().all(|v| v.is_finite()) => {
            (Outcome::Rendered, String::new())
        }
        Ok(_) => (Outcome::NonFinite, String::new()),
    }
}

/// Runs mutants `range` of every scene in `scenes` (mutant `i` of the run
/// is mutant `i / scenes` of scene `i % scenes`).
#[must_use]
pub fn run(scenes: &[PathBuf], range: std::ops::Range<u64>, scratch: &Path) -> Tally {
    let texts: Vec<String> = scenes
        .iter()
        .map(|p| std::fs::read_to_string(p).unwrap_or_default())
        .collect();
    let mut tally = Tally::default();
    let n = scenes.len() as u64;
    // To find a mutant that never returns: each is named before it runs.
    let trace = std::env::var_os("AETHER_FUZZ_TRACE").is_some();
    for i in range {
        let k = (i % n) as usize;
        let mutant = mutate(&texts[k], &scenes[k], i / n);
        if trace {
            eprintln!("mutant {} of {}", i / n, scenes[k].display());
        }
        let (outcome, message) = run_one(&mutant, &scenes[k], scratch, Duration::from_secs(20));
        tally.add(outcome, || {
            format!(
                "{} mutant {}: {outcome:?}: {message}",
                scenes[k].display(),
                i / n
            )
        });
    }
    tally
}
