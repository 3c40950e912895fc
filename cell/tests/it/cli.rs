//! The `windcell` command line, run as a user runs it.

use crate::common;

use common::{example, windcell, windcell_json};

const EXAMPLES: [&str; 7] = [
    "cylinder.toml",
    "offset-1r.toml",
    "offset-2r.toml",
    "offset-3r.toml",
    "tilted-1r.toml",
    "tilted-2r.toml",
    "sbend.toml",
];

#[test]
fn plans_every_example_into_control_files() {
    let dir = tempfile::tempdir().unwrap();
    for name in EXAMPLES {
        let out = dir.path().join(name);
        let result = windcell(&[
            "plan",
            example(name).to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ]);
        assert!(
            result.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&result.stderr)
        );
        let files: Vec<String> = std::fs::read_dir(&out)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        assert_eq!(files.len(), 6, "{files:?}");
        for f in &files {
            let text = std::fs::read_to_string(out.join(f)).unwrap();
            match f.rsplit('.').next().unwrap() {
                "ROB" => drop(sequences::RobotFile::parse(&text).unwrap()),
                "IND" => drop(sequences::MandrelFile::parse(&text).unwrap()),
                "SEQ" => assert_eq!(
                    sequences::SequenceFile::parse(&text).unwrap().names.len(),
                    2
                ),
                "RUN" => assert_eq!(
                    sequences::RunFile::parse(&text).unwrap().programs,
                    vec![1, 2]
                ),
                other => panic!("unexpected file type {other}"),
            }
        }
    }
}

#[test]
fn json_report_has_every_documented_field() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("cyl");
    let report = windcell_json(&[
        "plan",
        example("cylinder.toml").to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--json",
    ]);
    let paths = report["paths"].as_array().unwrap();
    assert_eq!(paths.len(), 2);
    for path in paths {
        assert!(path["name"].as_str().unwrap().starts_with("CYL_"));
        assert!(path["program"].as_u64().is_some());
        let segments = path["segments"].as_array().unwrap();
        assert_eq!(segments.len(), 50);
        for s in segments {
            for key in ["tangent_point_mm", "eye_mandrel_mm", "eye_mm"] {
                assert_eq!(s[key].as_array().unwrap().len(), 3, "{key}");
            }
            assert_eq!(s["wrist_q"].as_array().unwrap().len(), 4);
            for key in [
                "mandrel_deg",
                "ideal_mandrel_deg",
                "speed_pct",
                "entry_angle_deg",
                "duration_s",
                "robot_time_s",
                "mandrel_max_rps",
            ] {
                assert!(s[key].as_f64().is_some(), "{key}");
            }
            assert_eq!(s["joints_deg"].as_array().unwrap().len(), 5);
            assert_eq!(s["robot_paced"].as_bool(), Some(false));
            assert!(s["steps"].as_i64().is_some());
        }
        // One revolution of the mandrel per 178 mm pass at 48.3° (seed 001 §6.4), within 1 %.
        let first = path["start"]["mandrel_deg"].as_f64().unwrap();
        let last = segments[49]["mandrel_deg"].as_f64().unwrap();
        assert!(
            ((first - last).abs() / 360.0 - 1.0).abs() < 0.01,
            "{first} → {last}"
        );
        let drift = path["max_drift_deg"].as_f64().unwrap();
        assert!(
            drift <= 0.5 * 360.0 * 13.0 / (400.0 * 60.0) + 1e-9,
            "{drift}"
        );
        assert!(path["min_eye_clearance_mm"].as_f64().unwrap() > 0.0);
        // The worst entry angle and the joints' extremes over the path.
        let worst = segments
            .iter()
            .chain([&path["start"]])
            .map(|s| s["entry_angle_deg"].as_f64().unwrap())
            .fold(0.0, f64::max);
        assert_eq!(path["max_entry_angle_deg"].as_f64(), Some(worst));
        assert!(worst > 0.0 && worst < 30.0, "{worst}");
        assert_eq!(path["elbow"].as_str(), Some("up"));
        assert_eq!(path["joints_min_deg"].as_array().unwrap().len(), 5);
        assert_eq!(path["joints_max_deg"].as_array().unwrap().len(), 5);
        assert!(path["min_joint_margin_deg"].as_f64().unwrap() > 0.0);
        assert!(path["robot_paced_segments"].as_array().unwrap().is_empty());
    }
}

/// Each bad job gives exit code 2, one line naming file:line:col, and writes nothing.
#[test]
fn bad_jobs_fail_cleanly_and_write_nothing() {
    let good = std::fs::read_to_string(example("offset-3r.toml")).unwrap();
    let cases = [
        ("offset_mm = 100.0", "", "missing field `offset_mm`"),
        (
            "offset_mm = 100.0",
            "offset_mm = 100.0\nspeed = 1",
            "unknown field `speed`",
        ),
        ("diameter_mm = 63.5", "diameter_mm = -63.5", ":22:15:"),
        ("diameter_mm = 63.5", "diameter_mm = 0.0", "must be > 0"),
        (
            "wind_angle_deg = 48.3",
            "wind_angle_deg = 90.0",
            "(0°, 90°)",
        ),
        ("wind_angle_deg = 48.3", "wind_angle_deg = 0.0", "(0°, 90°)"),
        ("offset_mm = 100.0", "offset_mm = -5.0", ":9:13:"),
        (
            "segments = 50",
            "segments = 0",
            "a path has 2 to 10000 segments",
        ),
        (
            "robot_distance_mm = 800.0",
            "robot_distance_mm = 60.0",
            "eq 3.7 undefined",
        ),
        (
            "robot_distance_mm = 800.0",
            "robot_distance_mm = \"far\"",
            ":5:21:",
        ),
        // The arm and the plan's guards.
        (
            "segments = 50",
            "segments = 2",
            "more than half a revolution",
        ),
        (
            "segments = 50",
            "segments = 1",
            "segments = 1 is out of range",
        ),
        (
            "wind_angle_deg = 48.3",
            "wind_angle_deg = 89.0",
            "more than half a revolution",
        ),
        (
            "eye_mechanism_length_mm = 150.0",
            "eye_mechanism_length_mm = 900.0",
            "longest eye mechanism",
        ),
        (
            "mandrel_speed_rps = 0.1",
            "mandrel_speed_rps = 3.0",
            "rev/s would fit",
        ),
        (
            "[mandrel]",
            "[cell.robot]\nentry_angle_max_deg = 1.0\n\n[mandrel]",
            "more than the 1.00° limit",
        ),
        (
            "[mandrel]",
            "[cell.robot]\npitch_deg = [-10.0, 10.0]\n\n[mandrel]",
            "joint pitch",
        ),
        (
            "robot_distance_mm = 800.0",
            "robot_distance_mm = 1700.0",
            "outside the arm's reach",
        ),
    ];
    let dir = tempfile::tempdir().unwrap();
    for (i, (from, to, expected)) in cases.iter().enumerate() {
        let text = good.replacen(from, to, 1);
        assert_ne!(text, good);
        let job = dir.path().join(format!("bad{i}.toml"));
        std::fs::write(&job, text).unwrap();
        let out = dir.path().join(format!("out{i}"));
        let result = windcell(&["plan", job.to_str().unwrap(), "-o", out.to_str().unwrap()]);
        let stderr = String::from_utf8_lossy(&result.stderr);
        assert_eq!(result.status.code(), Some(2), "{to}: {stderr}");
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
        assert!(stderr.contains(job.to_str().unwrap()), "{stderr}");
        assert!(
            stderr.contains(expected),
            "{stderr} should contain {expected}"
        );
        assert!(!stderr.contains("panicked"));
        assert!(!out.exists(), "{to}: output written");
    }
    let leftovers = std::fs::read_dir(dir.path())
        .unwrap()
        .filter(|e| {
            e.as_ref()
                .unwrap()
                .file_name()
                .to_string_lossy()
                .starts_with(".windcell")
        })
        .count();
    assert_eq!(leftovers, 0);
}

#[test]
fn a_missing_job_file_is_reported() {
    let result = windcell(&["plan", "/nonexistent/job.toml", "-o", "/tmp/never"]);
    assert_eq!(result.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&result.stderr).contains("/nonexistent/job.toml"));
}
