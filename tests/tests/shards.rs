//! A render split into N parts (`--shard K/N`), each written to a file and
//! read back, merges to the single-process render of the same samples and
//! seed: every pixel within 1e-5 relative (the parts' sums are the same
//! samples, added in another order and kept to 2⁻⁴⁸ in the files), for
//! N = 1, 2, 3 and 7 and every family of integrators.

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;

use integrators::cornell::cornell_box;
use integrators::parts::{finish, put_render};
use integrators::render::{Settings, render};
use integrators::shard::{Shard, merge};
use integrators::shard_file::{read_part, write_part};

fn folder(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("aether-shards-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Renders part `shard` of the box with `integrator` and returns its
/// partial result, and the image the renderer itself made.
fn part(integrator: &str, shard: Shard) -> (integrators::shard::Partial, Vec<[f32; 3]>) {
    let mut scene = cornell_box(12, 10, 7);
    scene.integrator.name = integrator.to_string();
    let m = &mut scene.integrator.metropolis;
    (m.chains, m.luminance_samples, m.direct_samples) = (7, 400, 0);
    if integrator == "mlt" {
        m.direct_samples = 3;
    }
    let settings = Settings {
        shard,
        threads: Some(2),
        ..Settings::new(7, 11)
    };
    let r = render(&scene, &settings, &AtomicBool::new(false)).unwrap();
    let mut p = r.partial;
    put_render(&mut p, &scene, "spp=7", 11);
    (p, r.film.image())
}

fn close(a: &[[f32; 3]], b: &[[f32; 3]], what: &str) {
    assert_eq!(a.len(), b.len());
    for (i, (x, y)) in a.iter().zip(b).enumerate() {
        for k in 0..3 {
            let (x, y) = (f64::from(x[k]), f64::from(y[k]));
            let bound = 1e-5 * y.abs().max(1e-4);
            assert!((x - y).abs() <= bound, "{what}: pixel {i}: {x} against {y}");
        }
    }
}

#[test]
fn merged_parts_are_the_single_process_render() {
    let dir = folder("merge");
    for integrator in [
        "path", "direct", "light", "bdpt", "tridir", "gpt", "pssmlt", "mmlt", "mlt",
    ] {
        let (whole, image) = part(integrator, Shard::WHOLE);
        let finished = finish(&whole).unwrap();
        if integrator != "gpt" {
            // The render's own image is the finish of its sums.
            close(&finished.image, &image, &format!("{integrator} itself"));
        }
        for n in [1u32, 2, 3, 7] {
            let parts: Vec<_> = (0..n)
                .map(|k| {
                    let shard = Shard { index: k, count: n };
                    let (p, own) = part(integrator, shard);
                    let file = dir.join(format!("{integrator}-{k}-{n}.exr"));
                    write_part(&file, shard, &p, &own).unwrap();
                    let (s, q) = read_part(&file).unwrap();
                    (file, s, q)
                })
                .collect();
            let merged = merge(&parts, false).unwrap();
            assert_eq!(merged.fraction, 1.0);
            let what = format!("{integrator}, {n} parts");
            close(
                &finish(&merged.partial).unwrap().image,
                &finished.image,
                &what,
            );
            for (suffix, beside) in &finish(&merged.partial).unwrap().beside {
                let own = &finished.beside.iter().find(|(s, _)| s == suffix).unwrap().1;
                close(beside, own, &format!("{what}, {suffix}"));
            }
            let samples: f64 = merged
                .partial
                .plane("samples")
                .map_or(0.0, |s| s.iter().sum());
            if integrator.contains("mlt") {
                let all = whole.total("mutations");
                assert_eq!(
                    merged.partial.total("mutations"),
                    all,
                    "{what}: every chain once"
                );
            } else {
                assert_eq!(samples, 7.0 * 120.0, "{what}: every sample once");
            }
        }
    }
}

#[test]
fn parts_of_different_renders_or_missing_parts_are_refused() {
    let dir = folder("refused");
    let file = |name: &str,
                integrator: &str,
                shard: Shard,
                tweak: &dyn Fn(&mut integrators::shard::Partial)| {
        let (mut p, own) = part(integrator, shard);
        tweak(&mut p);
        let path = dir.join(name);
        write_part(&path, shard, &p, &own).unwrap();
        let (s, q) = read_part(&path).unwrap();
        (path, s, q)
    };
    let same = |_: &mut integrators::shard::Partial| {};
    let a = file("a.exr", "path", Shard { index: 0, count: 3 }, &same);
    let b = file("b.exr", "path", Shard { index: 1, count: 3 }, &same);
    let c = file("c.exr", "path", Shard { index: 2, count: 3 }, &same);
    let text = |parts: &[_], partial| merge(parts, partial).unwrap_err().to_string();
    let e = text(&[a.clone(), b.clone()], false);
    assert!(e.contains("parts 2 of 3 are missing"), "{e}");
    let partial = merge(&[a.clone(), b.clone()], true).unwrap();
    assert!((partial.fraction - 2.0 / 3.0).abs() < 1e-12);
    let e = text(&[a.clone(), b.clone(), b.clone()], false);
    assert!(
        e.contains("b.exr and") && e.contains("the same part 1/3"),
        "{e}"
    );
    let seed = file("seed.exr", "path", Shard { index: 2, count: 3 }, &|p| {
        p.same.insert("seed".into(), "12".into());
    });
    let e = text(&[a.clone(), b.clone(), seed], false);
    assert!(
        e.contains("seed.exr: its seed is 12, but") && e.contains("a.exr has 11"),
        "{e}"
    );
    let other = file("bdpt.exr", "bdpt", Shard { index: 2, count: 3 }, &same);
    let e = text(&[a.clone(), b.clone(), other], false);
    assert!(
        e.contains("bdpt.exr: its") && e.contains("integrator"),
        "{e}"
    );
    let scene = file("scene.exr", "path", Shard { index: 2, count: 3 }, &|p| {
        p.same.insert("scene".into(), "0123".into());
    });
    let e = text(&[a.clone(), b.clone(), scene], false);
    assert!(e.contains("its scene is 0123"), "{e}");
    let four = file("four.exr", "path", Shard { index: 3, count: 4 }, &same);
    let e = text(&[a.clone(), four], false);
    assert!(e.contains("four.exr: its number of parts is 4"), "{e}");
    merge(&[c, a, b], false).unwrap();
}
