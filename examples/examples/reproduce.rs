//! Reproduces the Aether examples as an HTML report: every scene file under
//! `../shared/scenes/aether` with the integrator it names, each distinct
//! scene with every integrator at equal time, RMSE against long BDPT
//! references that the command renders and caches, and, given Mitsuba 3's
//! renders (`tools/mitsuba_compare.py`), their differences.
//!
//! ```text
//! cargo run --release -p examples --example reproduce -- [--quick] [--seconds 10]
//!     [--reference-seconds 240] [--width 192] [--out DIR] [--mitsuba DIR]
//! ```
//!
//! `--quick` (32 pixels wide, 0.2 s per render) finishes in a couple of
//! minutes; the report is `target/reproduce/index.html`
//! (`target/reproduce-quick` for `--quick`).

use std::path::PathBuf;

use examples::reproduce::{Options, run};

fn options() -> Result<Options, String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut o = if args.iter().any(|a| a == "--quick") {
        Options::quick()
    } else {
        Options::full()
    };
    let mut rest = args.iter().filter(|a| *a != "--quick");
    while let Some(flag) = rest.next() {
        let value = rest.next().ok_or_else(|| format!("{flag} needs a value"))?;
        let number = || examples::positive(flag, value);
        match flag.as_str() {
            "--seconds" => o.seconds = number()?,
            "--reference-seconds" => o.reference_seconds = number()?,
            "--width" => o.width = number()?.round().max(2.0) as u32,
            "--out" => {
                o.out = PathBuf::from(value);
                o.cache = o.out.join("references");
            }
            "--mitsuba" => o.mitsuba = Some(PathBuf::from(value)),
            _ => return Err(format!("unknown option {flag}")),
        }
    }
    Ok(o)
}

fn main() {
    let result = options().and_then(|o| run(&o));
    match result {
        Ok(report) => {
            let failed = report.rows.iter().filter(|r| r.outcome.is_err()).count();
            println!(
                "{} renders ({failed} without an image): {}",
                report.rows.len(),
                report.html.display()
            );
        }
        Err(e) => {
            eprintln!("reproduce: {e}");
            std::process::exit(1);
        }
    }
}
