//! The fuzzer ([`tests::fuzz`]) over every scene of `../shared/scenes/aether`
//! and `scenes/`: no mutant panics, hangs or renders a NaN, and every
//! rejection names a file. The in-process run takes a few thousand
//! mutants; `fuzz_long` (ignored) runs 10⁶ in child processes, so that an
//! abort or a stack overflow, which no process survives, is caught too:
//!
//! ```sh
//! AETHER_FUZZ=1000000 cargo test --release -p tests --test fuzz -- --ignored fuzz_long --nocapture
//! ```

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use tests::fuzz::{Outcome, Tally, run, scene_files};

fn scenes() -> Vec<PathBuf> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let found = scene_files(&[root.join("../shared/scenes/aether"), root.join("scenes")]);
    assert!(found.len() >= 5, "the scenes are missing: {found:?}");
    found
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("aether-fuzz-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("a temporary folder");
    dir
}

fn env_u64(name: &str, default: u64) -> u64 {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

fn assert_clean(tally: &Tally) {
    eprintln!("{}", tally.line());
    for f in &tally.failures {
        eprintln!("  {f}");
    }
    for bad in [
        Outcome::Unnamed,
        Outcome::NonFinite,
        Outcome::Panic,
        Outcome::Hang,
    ] {
        assert_eq!(tally.count(bad), 0, "{bad:?}: {:#?}", tally.failures);
    }
    // The mutants reach both sides: many are refused, many still render.
    assert!(
        tally.count(Outcome::Error) > tally.mutants / 10,
        "{}",
        tally.line()
    );
    assert!(
        tally.count(Outcome::Rendered) > tally.mutants / 20,
        "{}",
        tally.line()
    );
}

#[test]
fn mutated_scenes_never_crash_and_every_rejection_names_a_file() {
    let scenes = scenes();
    let total = env_u64("AETHER_FUZZ_MUTANTS", 6000);
    let dir = scratch("in-process");
    // Two halves on the two cores.
    let halves = std::thread::scope(|s| {
        let handles: Vec<_> = [0..total / 2, total / 2..total]
            .into_iter()
            .enumerate()
            .map(|(k, range)| {
                let (scenes, dir) = (&scenes, dir.join(k.to_string()));
                std::fs::create_dir_all(&dir).expect("a temporary folder");
                s.spawn(move || run(scenes, range, &dir))
            })
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().expect("the fuzzer catches every panic"))
            .collect::<Vec<Tally>>()
    });
    let mut tally = Tally::default();
    for h in &halves {
        tally.merge(h);
    }
    assert_eq!(tally.mutants, total);
    assert_clean(&tally);
}

/// One batch of the long run, in a child process (see `fuzz_long`).
#[test]
#[ignore = "run by fuzz_long in a child process"]
fn fuzz_batch() {
    let Ok(batch) = std::env::var("AETHER_FUZZ_BATCH") else {
        return;
    };
    let (start, end) = batch
        .split_once("..")
        .and_then(|(a, b)| Some((a.parse().ok()?, b.parse().ok()?)))
        .expect("AETHER_FUZZ_BATCH is start..end");
    let tally = run(&scenes(), start..end, &scratch(&format!("batch-{start}")));
    println!("{}", tally.line());
    for f in &tally.failures {
        println!("failure: {f}");
    }
}

#[test]
#[ignore = "the long mode: 10⁶ mutants by default, an hour or more"]
fn fuzz_long() {
    let total = env_u64("AETHER_FUZZ", 1_000_000);
    let batch = 5_000;
    let exe = std::env::current_exe().expect("the test binary");
    let mut tally = Tally::default();
    let mut aborted = Vec::new();
    let workers = std::thread::available_parallelism().map_or(2, usize::from);
    let mut queue = (0..total)
        .step_by(batch as usize)
        .map(|s| s..(s + batch).min(total));
    let mut running = Vec::new();
    let begin = Instant::now();
    // A batch is one child process; as soon as one ends the next starts,
    // so that one slow batch does not idle the other cores.
    loop {
        while running.len() < workers {
            let Some(range) = queue.next() else { break };
            let child = Command::new(&exe)
                .args(["--exact", "fuzz_batch", "--ignored", "--nocapture"])
                .env(
                    "AETHER_FUZZ_BATCH",
                    format!("{}..{}", range.start, range.end),
                )
                .stdout(Stdio::piped())
                .stderr(Stdio::null())
                .spawn()
                .expect("the test binary starts");
            running.push((range, child, Instant::now() + Duration::from_secs(600)));
        }
        if running.is_empty() {
            break;
        }
        std::thread::sleep(Duration::from_millis(100));
        let mut k = 0;
        while k < running.len() {
            let (_, child, deadline) = &mut running[k];
            let status = match child.try_wait().expect("the child can be waited for") {
                Some(status) => Some(status),
                None if Instant::now() > *deadline => {
                    let _ = child.kill();
                    None
                }
                None => {
                    k += 1;
                    continue;
                }
            };
            let (range, child, _) = running.swap_remove(k);
            let output = child.wait_with_output().expect("the child's output");
            let text = String::from_utf8_lossy(&output.stdout);
            match (status, text.lines().find_map(Tally::parse)) {
                (Some(s), Some(t)) if s.success() => {
                    tally.merge(&t);
                    for f in text.lines().filter(|l| l.starts_with("failure: ")) {
                        eprintln!("{f}");
                        tally.failures.push(f.to_string());
                    }
                }
                (status, _) => {
                    let batch = format!("mutants {range:?}: {status:?}");
                    eprintln!("aborted or hung: {batch}");
                    aborted.push(batch);
                }
            }
            eprintln!("{} ({:.0} s)", tally.line(), begin.elapsed().as_secs_f64());
        }
    }
    assert!(
        aborted.is_empty(),
        "batches that aborted or hung: {aborted:#?}"
    );
    assert_clean(&tally);
}

/// Writes one mutant to standard output, to reproduce a failure the
/// fuzzer reported: `AETHER_FUZZ_SHOW=SCENE.xml:INDEX`.
#[test]
#[ignore = "a tool: prints the mutant AETHER_FUZZ_SHOW names"]
fn fuzz_show() {
    let Ok(what) = std::env::var("AETHER_FUZZ_SHOW") else {
        return;
    };
    let (scene, index) = what.rsplit_once(':').expect("SCENE.xml:INDEX");
    let text = std::fs::read_to_string(scene).expect("the scene");
    let index = index.parse().expect("a mutant index");
    let mutant = tests::fuzz::mutate(&text, Path::new(scene), index);
    use std::io::Write;
    std::io::stdout()
        .write_all(&mutant)
        .expect("standard output");
}
