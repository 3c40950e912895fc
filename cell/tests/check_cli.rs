//! `windcell check` on the shipped robot-cell examples: each analytic-mandrel job checks clear
//! (exit 0, one summary line), and `--json` lists every segment of every path.

mod common;

use common::{example, windcell};

#[test]
fn the_analytic_examples_check_clear() {
    for job in [
        "cylinder.toml",
        "offset-1r.toml",
        "offset-3r.toml",
        "tilted-2r.toml",
        "sbend.toml",
    ] {
        let out = windcell(&["check", example(job).to_str().unwrap()]);
        let stdout = String::from_utf8_lossy(&out.stdout);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(0), "{job}: {stdout}{stderr}");
        assert!(
            stdout.contains("check: clear over 2 paths, 100 segments"),
            "{job}: {stdout}"
        );
    }
}

#[test]
fn json_lists_every_segment_with_its_clearances() {
    let out = windcell(&["check", example("sbend.toml").to_str().unwrap(), "--json"]);
    assert_eq!(out.status.code(), Some(0));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let text = v.to_string();
    // 2 paths × 50 segments, each with an eye, a free-fibre and an arm clearance in mm.
    for key in ["eye", "fibre", "arm"] {
        assert!(text.contains(key), "{key} missing");
    }
    let segments = text.matches("\"segment\":").count();
    assert!(segments >= 100, "{segments} segment records");
}

/// The gate: a job whose eye mechanism (made 60 mm thick here) touches the mandrel is refused by
/// `windcell run` with exit code 3 before anything is sent, and `--force` winds it anyway.
#[test]
fn run_refuses_a_job_the_check_fails_unless_forced() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(example("cylinder.toml")).unwrap();
    let fat_eye = text.replacen("[mandrel]", "[cell.eye]\nradius_mm = 60.0\n\n[mandrel]", 1);
    assert_ne!(fat_eye, text);
    let job = dir.path().join("fat-eye.toml");
    std::fs::write(&job, fat_eye).unwrap();
    let job = job.to_str().unwrap();

    let check = windcell(&["check", job]);
    assert_eq!(check.status.code(), Some(3));

    let journal = dir.path().join("a.journal");
    let refused = windcell(&["run", job, "--journal", journal.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert_eq!(refused.status.code(), Some(3), "{stderr}");
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.contains("--force"), "{stderr}");
    assert!(!journal.exists(), "a refused run must not start a journal");

    let forced = windcell(&[
        "run",
        job,
        "--force",
        "--mode",
        "medium",
        "--journal",
        journal.to_str().unwrap(),
    ]);
    let stdout = String::from_utf8_lossy(&forced.stdout);
    assert_eq!(forced.status.code(), Some(0), "{stdout}");
    assert!(stdout.contains("batch done"), "{stdout}");
}
