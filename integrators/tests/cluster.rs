//! A real Slurm cluster on this machine (tools/slurm/test_cluster.sh): a
//! 4-task job array of the built-in box and its merge job, compared with a
//! single-process render. Skips, saying why, where Slurm and munge are not
//! installed (`.ci/run` installs them) or the test is not run as root.

use std::path::Path;
use std::process::Command;

fn found(program: &str) -> bool {
    Command::new("sh")
        .args(["-c", &format!("command -v {program}")])
        .output()
        .is_ok_and(|o| o.status.success())
}

#[test]
fn a_job_array_and_its_merge_equal_the_single_render() {
    let missing: Vec<&str> = [
        "sbatch",
        "squeue",
        "slurmctld",
        "slurmd",
        "munged",
        "runuser",
    ]
    .into_iter()
    .filter(|p| !found(p))
    .collect();
    if !missing.is_empty() {
        eprintln!(
            "skipped: {} not installed (apt-get install slurm-wlm munge)",
            missing.join(", ")
        );
        return;
    }
    let root = Command::new("id")
        .arg("-u")
        .output()
        .map(|o| o.stdout == b"0\n");
    if root.ok() != Some(true) {
        eprintln!("skipped: slurmd runs as root, and this test is not");
        return;
    }
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tools/slurm/test_cluster.sh");
    let out = Command::new(&script)
        .env("AETHER", env!("CARGO_BIN_EXE_aether"))
        .output()
        .expect("the cluster test starts");
    let text = String::from_utf8_lossy(&out.stdout);
    eprintln!("{text}{}", String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "the cluster test failed");
    assert!(text.contains("cluster test passed"), "{text}");
}
