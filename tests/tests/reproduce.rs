//! `reproduce --quick`: the report has a row for every Aether scene file
//! and one per integrator for every distinct scene at equal time, and each
//! of its images exists, is lit and free of NaN: every render succeeds,
//! Veach's MLT for the scene files that name it included.

use std::path::Path;

use examples::reproduce::{Options, Section, run};

#[test]
fn the_quick_report_holds_every_example() {
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/scenes/aether");
    if !scenes.is_dir() {
        println!("skipped: {} is absent", scenes.display());
        return;
    }
    let out = std::env::temp_dir().join(format!("aether-reproduce-{}", std::process::id()));
    let options = Options {
        out: out.clone(),
        cache: out.join("references"),
        progress: false,
        ..Options::quick()
    };
    let report = run(&options).unwrap();
    let html = std::fs::read_to_string(&report.html).unwrap();
    let named: Vec<_> = report
        .rows
        .iter()
        .filter(|r| r.section == Section::Named)
        .collect();
    assert!(named.len() >= 26, "{} scene files", named.len());
    let mlt = named.iter().filter(|r| r.integrator == "mlt").count();
    assert!(mlt >= 7, "{mlt} scene files ask for Veach's MLT");
    for row in &report.rows {
        match &row.outcome {
            Ok(r) => {
                let png = out.join(&r.png);
                let bytes = std::fs::metadata(&png).map_or(0, |m| m.len());
                assert!(
                    r.finite && r.lit && bytes > 0,
                    "{} with {}: finite {}, lit {}, {bytes} bytes",
                    row.scene,
                    row.integrator,
                    r.finite,
                    r.lit
                );
                assert!(html.contains(&r.png), "{} is not on the page", r.png);
            }
            Err(e) => panic!("{} with {}: {e}", row.scene, row.integrator),
        }
    }
    // Every distinct scene at equal time, with every integrator.
    let equal: Vec<_> = report
        .rows
        .iter()
        .filter(|r| r.section == Section::EqualTime)
        .collect();
    for integrator in ["path", "light", "bdpt", "gpt", "mlt", "pssmlt", "mmlt"] {
        let n = equal.iter().filter(|r| r.integrator == integrator).count();
        assert!(n >= 5, "{integrator} at equal time on {n} scenes");
    }
    assert!(equal.iter().any(|r| r.integrator == "tridir"));
    assert!(
        equal
            .iter()
            .all(|r| r.outcome.as_ref().is_ok_and(|r| r.error.is_some())),
        "every equal-time render has an RMSE"
    );
}
