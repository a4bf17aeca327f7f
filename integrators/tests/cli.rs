//! The `aether` program as a user meets it: bad command lines are refused
//! before any rendering, the output format follows the file name, and
//! Ctrl-C or SIGTERM stop a render between samples with the whole image
//! written at the counts each pixel got.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use integrators::output::{read_counts, read_exr};

fn aether() -> Command {
    Command::new(env!("CARGO_BIN_EXE_aether"))
}

fn folder(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("aether-cli-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn run(args: &[&str]) -> Output {
    aether().args(args).output().expect("aether runs")
}

fn refused(args: &[&str], says: &str) {
    let out = run(args);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{args:?} is refused");
    assert!(err.contains(says), "{args:?}: {err}");
}

#[test]
fn bad_command_lines_are_refused_before_rendering() {
    // Each would otherwise render for hours: the check comes first.
    let dir = folder("refused");
    let out = dir.join("o.exr");
    let o = out.to_str().unwrap();
    let long = ["render", "--spp", "100000000", "--size", "64"];
    fn with<'a>(long: &[&'a str], extra: &[&'a str]) -> Vec<&'a str> {
        [long, extra].concat()
    }
    refused(
        &with(&long, &["-o", "a.jpg"]),
        "a.jpg: the output is written as EXR",
    );
    refused(
        &with(&long, &["-o", "/nonexistent-folder/x.exr"]),
        "/nonexistent-folder/x.exr: cannot be written",
    );
    refused(&with(&long, &["-o", dir.to_str().unwrap()]), "");
    refused(
        &with(&long, &["-o", o, "--threads", "0"]),
        "--threads must be at least 1",
    );
    refused(&["render", "-o", o, "--size", "100000"], "over the limit");
    refused(&["render", "-o", o, "--width", "100000"], "over the limit");
    refused(
        &["render", "-o", o, "--width", "4294967295"],
        "over the limit",
    );
    let missing = dir.join("missing.xml");
    let m = missing.to_str().unwrap();
    refused(
        &["render", m, "-o", o],
        &format!("{m}: cannot read the scene file: {m} does not exist"),
    );
    assert!(!out.exists(), "nothing was written");
}

#[test]
fn a_png_name_writes_the_preview_and_keeps_the_hdr_image_beside_it() {
    let dir = folder("png");
    let png = dir.join("p.png");
    let out = run(&[
        "render",
        "--size",
        "8",
        "--spp",
        "2",
        "-o",
        png.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let bytes = std::fs::read(&png).unwrap();
    assert_eq!(&bytes[1..4], b"PNG", "the .png is a PNG");
    let (w, h, image) = read_exr(&dir.join("p.exr")).unwrap();
    assert_eq!((w, h), (8, 8));
    assert!(image.iter().flatten().all(|v| v.is_finite()));
    let counts = read_counts(&dir.join("p.exr")).unwrap().unwrap();
    assert!(counts.iter().all(|&n| n == 2), "{counts:?}");
}

/// Starts a render that would take hours, stops it with `signals` (one
/// after another, 100 ms apart) once it is under way, and returns how long
/// it took to exit after the first and how it ended.
fn stop_with(signals: &[&str], exr: &Path) -> (Duration, Output) {
    let child = aether()
        .args([
            "render",
            "--spp",
            "100000000",
            "--size",
            "32",
            "-o",
            exr.to_str().unwrap(),
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Long enough that every pixel has its first samples.
    std::thread::sleep(Duration::from_millis(1500));
    let sent = Instant::now();
    for s in signals {
        Command::new("kill")
            .args([&format!("-{s}"), &child.id().to_string()])
            .status()
            .unwrap();
        std::thread::sleep(Duration::from_millis(100));
    }
    let out = child.wait_with_output().unwrap();
    (sent.elapsed(), out)
}

#[test]
fn sigterm_and_ctrl_c_stop_at_once_and_write_the_whole_image() {
    let dir = folder("signals");
    for signal in ["TERM", "INT"] {
        let exr = dir.join(format!("{signal}.exr"));
        let (took, out) = stop_with(&[signal], &exr);
        let err = String::from_utf8_lossy(&out.stderr);
        eprintln!(
            "SIG{signal}: exited {:.2} s after the signal",
            took.as_secs_f64()
        );
        assert_eq!(out.status.code(), Some(130), "{err}");
        // A hang guard, not a speed claim: the stop is between samples.
        assert!(took < Duration::from_secs(10), "{took:?}");
        let counts = read_counts(&exr).unwrap().expect("the true counts");
        assert!(
            counts.iter().all(|&n| n >= 1),
            "every pixel has its first samples"
        );
        let (_, _, image) = read_exr(&exr).unwrap();
        assert!(image.iter().flatten().all(|v| v.is_finite()));
        assert!(image.iter().any(|c| c[0] > 0.0), "the image is not black");
    }
    // A second Ctrl-C quits without writing.
    let exr = dir.join("twice.exr");
    let (_, out) = stop_with(&["INT", "INT"], &exr);
    assert_eq!(out.status.code(), Some(130));
}

#[test]
fn parts_render_and_merge_and_bad_parts_are_refused() {
    let dir = folder("parts");
    let d = |name: &str| dir.join(name).to_str().unwrap().to_string();
    refused(
        &["render", "--shard", "4/4", "-o", &d("x.exr")],
        "'4/4' is not a part K/N",
    );
    refused(
        &["render", "--shard", "0/0", "-o", &d("x.exr")],
        "'0/0' is not a part K/N",
    );
    for k in 0..3 {
        let part = d(&format!("p{k}.exr"));
        let shard = format!("{k}/3");
        let out = run(&[
            "render", "--size", "8", "--spp", "3", "-i", "bdpt", "--shard", &shard, "-o", &part,
        ]);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let (p0, p1, p2) = (d("p0.exr"), d("p1.exr"), d("p2.exr"));
    let out = run(&["merge", &d("m.exr"), &p2, &p0, &p1]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let counts = read_counts(&dir.join("m.exr")).unwrap().unwrap();
    assert!(counts.iter().all(|&n| n == 3), "{counts:?}");
    refused(
        &["merge", &d("m.exr"), &p0, &p1, &p2],
        "m.exr: exists (--force overwrites it)",
    );
    refused(
        &["merge", &d("n.exr"), &p0, &p1],
        "parts 2 of 3 are missing",
    );
    let out = run(&["merge", "--partial", &d("n.exr"), &p0, &p1]);
    assert!(String::from_utf8_lossy(&out.stdout).contains("66.7 % of the render's parts"));
    // An image that is not a part, and a truncated part.
    std::fs::copy(dir.join("m.exr"), dir.join("image.exr")).unwrap();
    refused(
        &["merge", &d("o.exr"), &d("image.exr")],
        "image.exr: no aether.shard in its header",
    );
    let bytes = std::fs::read(&p1).unwrap();
    std::fs::write(dir.join("cut.exr"), &bytes[..bytes.len() / 3]).unwrap();
    refused(
        &["merge", &d("o.exr"), &p0, &d("cut.exr"), &p2],
        "cut.exr: not a readable EXR image",
    );
}
