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
