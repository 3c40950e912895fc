//! `windcell lathe plan`: seed 002's appendix program from the example, every dialect read back,
//! `.wind` jobs, and bad input refused before anything is written.

use crate::common;

use common::lathe::{lathe_plan, lathe_plan_summary, refused_in_one_line, tube};
use common::{example, stderr, variant, wind_job, windcell};
use paths::motion::MoveKind;
use sequences::gcode::{Dialect, Frame, read_in_frame};
use sequences::machine::MachineProfile;

/// The frame a summary says its program was written in (the machine and its carriage zero).
fn frame_of(summary: &serde_json::Value) -> Frame {
    let machine = &summary["machine"];
    let profile = MachineProfile::builtin(machine["name"].as_str().unwrap()).unwrap();
    Frame::of_machine(&profile, machine["carriage_offset_mm"].as_f64().unwrap())
}

/// A written program read back into the planner's frame.
fn read(text: &str, dialect: Dialect, summary: &serde_json::Value) -> paths::motion::Recording {
    read_in_frame(text, dialect, &frame_of(summary)).unwrap()
}

include!("../../../paths/tests/data/seed002_o0004.rs");

fn words(line: &str) -> [f64; 4] {
    let mut v = [0.0; 4];
    for w in line.split_whitespace() {
        let (letter, num) = w.split_at(1);
        let i = match letter {
            "X" => 0,
            "Y" => 1,
            "Z" => 2,
            "A" => 3,
            _ => continue,
        };
        v[i] = num.parse().unwrap();
    }
    v
}

#[test]
fn seed002_mach3_is_the_appendix_program() {
    let dir = tempfile::tempdir().unwrap();
    let out = lathe_plan(&example("seed002-vessel.toml"), dir.path(), "mach3", &[]);
    assert!(out.status.success(), "{}", stderr(&out));
    let text = std::fs::read_to_string(dir.path().join("seed002.tap")).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    let g91 = lines.iter().position(|l| *l == "G91").unwrap();
    // Forward stroke (O0004) then backward stroke (O0005: Y and A mirrored).
    for (stroke, sign) in [(0, 1.0), (1, -1.0)] {
        for (i, want) in APPENDIX_FORWARD.iter().enumerate() {
            if stroke == 1 && i == 40 {
                continue; // the last move carries the cycle's turnaround extras (O0006/O0007)
            }
            let got = words(lines[g91 + 1 + 41 * stroke + i]);
            let want = [want[0], sign * want[1], want[2], sign * want[3]];
            for k in 0..4 {
                assert!(
                    (got[k] - want[k]).abs() <= 0.005,
                    "stroke {stroke} move {}: {got:?} vs {want:?}",
                    i + 1
                );
            }
        }
    }
    let summary = String::from_utf8_lossy(&out.stdout);
    assert!(
        summary.contains("pitch 60° (6 cycles × 15 patterns)"),
        "{summary}"
    );
}

#[test]
fn every_dialect_file_reads_back_to_the_plan() {
    let dir = tempfile::tempdir().unwrap();
    let job = dir.path().join("v3.toml");
    let text = std::fs::read_to_string(example("seed002-vessel.toml"))
        .unwrap()
        .replace("axes = 4", "axes = 3")
        .replace("name = \"seed002\"", "name = \"v3\"");
    std::fs::write(&job, text).unwrap();
    for dialect in Dialect::ALL {
        let source = if dialect == Dialect::FwCnc {
            job.clone()
        } else {
            example("seed002-vessel.toml")
        };
        let summary = lathe_plan_summary(&source, dir.path(), dialect.name(), &["--force"]);
        let file = summary["file"].as_str().unwrap();
        let written = std::fs::read_to_string(file).unwrap();
        assert_eq!(
            written.lines().count() as u64,
            summary["lines"].as_u64().unwrap()
        );
        let back = read(&written, dialect, &summary);
        // One rapid (a feed in fw-cnc) and 90 cycles of 82 moves; the time the feeds encode is
        // the plan's nominal time.
        assert_eq!(
            back.moves.len() as u64,
            summary["moves"].as_u64().unwrap(),
            "{dialect}"
        );
        assert_eq!(back.moves.len(), 1 + 90 * 82);
        assert_eq!(back.layers.len(), 1);
        if dialect != Dialect::FwCnc {
            assert_eq!(back.moves[0].kind, MoveKind::Rapid);
            let t: f64 = back.moves.iter().map(|m| m.duration_s).sum();
            let nominal = summary["nominal_time_s"].as_f64().unwrap();
            assert!(
                (t - nominal).abs() < 1e-3 * nominal,
                "{dialect}: {t} vs {nominal}"
            );
        }
        let end = back.moves.last().unwrap().to;
        // 90 cycles of Φ1 = 420.0125° and 15 advances of 4°.
        assert!(
            (end.mandrel_deg - (90.0 * 420.0125 + 60.0)).abs() < 0.01,
            "{dialect}: {end:?}"
        );
        assert!((end.carriage_mm + 98.255).abs() < 0.001, "{dialect}");
    }
}

/// `windcell lathe plan JOB -o OUT --dialect grbl` refused as bad input: exit 2, one line that
/// contains `expect`, and nothing written (`OUT` not even created). Returns the line.
fn refused_in_grbl(job: &std::path::Path, out_dir: &std::path::Path, expect: &str) -> String {
    refused_in_one_line(&lathe_plan(job, out_dir, "grbl", &[]), expect, out_dir)
}

#[test]
fn bad_input_exits_2_with_file_line_column_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let job = dir.path().join("bad.toml");
    let text = std::fs::read_to_string(example("seed002-vessel.toml"))
        .unwrap()
        .replace(
            "kind = \"helical\"",
            "kind = \"helical\"\ncycles_per_pattern = 4\ndwell_deg = 0",
        );
    std::fs::write(&job, text).unwrap();
    let out_dir = dir.path().join("out");
    let err = refused_in_grbl(
        &job,
        &out_dir,
        "bad.toml:30:8: layer 1: the winding pattern does not close",
    );
    assert!(err.contains("nearest valid"), "{err}");
    // fw-cnc on a 4-axis machine: refused, nothing written.
    let out = lathe_plan(&example("seed002-vessel.toml"), &out_dir, "fw-cnc", &[]);
    assert_eq!(out.status.code(), Some(2));
    assert!(!out_dir.exists());
    let out = windcell(&["lathe", "plan", "x.toml", "-o", "y", "--dialect", "haas"]);
    assert_eq!(out.status.code(), Some(2));
}

#[test]
fn wind_files_plan_and_their_rules_are_located() {
    let dir = tempfile::tempdir().unwrap();
    let summary = lathe_plan_summary(&tube(), dir.path(), "grbl", &[]);
    assert_eq!(summary["circuits"].as_u64(), Some(24));
    assert!(dir.path().join("tube.nc").exists());
    let wind = variant(
        &tube(),
        dir.path(),
        "tube.wind",
        &[("\"skipIndex\": 1", "\"skipIndex\": 3")],
    );
    let out = lathe_plan(&wind, &dir.path().join("o2"), "grbl", &[]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        stderr(&out).contains("tube.wind:8:5: layer 2: skip index 3"),
        "{}",
        stderr(&out)
    );
}

/// Plans `job` with every dialect that carries its axes and checks each file reads back to the
/// plan's own moves, layer marks and kinds.
fn reads_back_in_every_dialect(job: &std::path::Path, plan: &paths::vessel::Plan, axes: u8) {
    let mut planned = paths::motion::Recording::default();
    plan.emit(&mut planned).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let mut written = 0;
    for dialect in Dialect::ALL {
        let out = lathe_plan(job, dir.path(), dialect.name(), &["--json", "--force"]);
        if axes == 4 && dialect == Dialect::FwCnc {
            // FW-CNC has no fourth axis: refused before anything is written.
            assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
            continue;
        }
        assert!(out.status.success(), "{dialect}: {}", stderr(&out));
        written += 1;
        let summary: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        let text = std::fs::read_to_string(summary["file"].as_str().unwrap()).unwrap();
        let back = read(&text, dialect, &summary);
        let frame = frame_of(&summary);
        assert_eq!(back.moves.len(), planned.moves.len(), "{dialect}");
        assert_eq!(back.layers.len(), planned.layers.len(), "{dialect}");
        for (b, p) in back.layers.iter().zip(&planned.layers) {
            assert_eq!(b.kind, p.kind, "{dialect}");
            assert_eq!(b.circuits, p.circuits, "{dialect}");
        }
        for (i, (b, p)) in back.moves.iter().zip(&planned.moves).enumerate() {
            let (b, p) = (b.to.to_array(), p.to.to_array());
            for k in (0..4).filter(|&k| frame.letters[k].is_some()) {
                // Three decimals printed; incremental dialects may carry the rounding.
                assert!(
                    (b[k] - p[k]).abs() < 0.01,
                    "{dialect}: move {i} axis {k}: {} vs {}",
                    b[k],
                    p[k]
                );
            }
        }
    }
    assert!(written >= 5);
}

#[test]
fn polar_layers_read_back_in_every_dialect() {
    let job = example("polar-vessel.toml");
    let (loaded, text) = sequences::vessel::VesselFile::load(&job).unwrap();
    let plan = loaded.check(&text).unwrap();
    assert_eq!(plan.layers[0].mark.kind, paths::motion::LayerKind::Polar);
    // ⌈2π·60·cos 12.0643° / 4⌉ = ⌈92.17⌉ = 93 circuits (α by hand in `paths::vessel::polar`).
    assert_eq!(plan.layers[0].mark.circuits, 93);
    reads_back_in_every_dialect(&job, &plan, 4);
}

#[test]
fn cone_layers_read_back_in_every_dialect() {
    let dir = tempfile::tempdir().unwrap();
    let wind = wind_job("reducer.wind");
    let job = sequences::wind::WindFile::load(&wind).unwrap().0;
    let plan = job.check().unwrap();
    // ⌈π·98·cos 30° / 6⌉ = ⌈44.44⌉ = 45 circuits, counted at the large end.
    assert_eq!(plan.layers[0].mark.circuits, 45);
    reads_back_in_every_dialect(&wind, &plan, 4);
    // Too steep for the taper: refused at the layer, nothing written.
    let wind = variant(
        &wind_job("reducer.wind"),
        dir.path(),
        "reducer.wind",
        &[("\"windAngle\": 30", "\"windAngle\": 40")],
    );
    refused_in_grbl(
        &wind,
        &dir.path().join("refused"),
        "reducer.wind:4:5: layer 1: wind angle 40° is too steep for the cone",
    );
}

#[test]
fn nose_layers_read_back_in_every_dialect() {
    let dir = tempfile::tempdir().unwrap();
    let wind = dir.path().join("ogive.wind");
    let text = r#"{
  "schemaVersion": "1.3",
  "layers": [
    { "windType": "helical", "windAngle": 30, "patternNumber": 3, "skipIndex": 1,
      "lockDegrees": 180, "leadInMM": 5, "leadOutDegrees": 15 },
    { "windType": "skip", "mandrelRotation": 45 },
    { "windType": "helical", "windAngle": 30, "patternNumber": 3, "skipIndex": 1,
      "lockDegrees": 180, "leadInMM": 5, "leadOutDegrees": 15, "frictionLambda": 0.15 }
  ],
  "mandrelParameters": { "diameter": 98.0, "windLength": 300.0, "profile": { "type": "vonKarman" } },
  "towParameters": { "width": 7.0, "thickness": 0.5 },
  "defaultFeedRate": 9000.0
}"#;
    std::fs::write(&wind, text).unwrap();
    let job = sequences::wind::WindFile::load(&wind).unwrap().0;
    let plan = job.check().unwrap();
    // ⌈π·98·cos 30° / 7⌉ = ⌈38.09⌉ = 39 circuits, counted on the base.
    assert_eq!(plan.layers[0].mark.circuits, 39);
    assert_eq!(plan.layers[2].mark.circuits, 39);
    reads_back_in_every_dialect(&wind, &plan, 4);
    // The geodesic's passes reach the turnaround where the Haack radius is 49·sin 30° = 24.5 mm
    // (210.596 mm from the base), the friction passes deeper; never the tip.
    let summary = lathe_plan_summary(&wind, dir.path(), "linuxcnc", &[]);
    assert_eq!(summary["circuits"].as_u64(), Some(78));
    let gcode = std::fs::read_to_string(summary["file"].as_str().unwrap()).unwrap();
    let mut far = [f64::MIN; 3];
    let mut layer = 0;
    for line in gcode.lines() {
        if line.contains("layer ") && (line.starts_with(';') || line.starts_with('(')) {
            layer += 1;
        }
        if let Some(x) = line
            .split_whitespace()
            .find_map(|w| w.strip_prefix('X').and_then(|v| v.parse::<f64>().ok()))
        {
            // X from 0 at the base (the mandrel's start).
            far[layer.min(3) - 1] = far[layer.min(3) - 1].max(x);
        }
    }
    assert!((far[0] - 210.596).abs() < 2e-3, "{far:?}");
    assert!(far[2] > 260.0 && far[2] < 300.0, "{far:?}");
    // Friction above the slip limit: refused at the layer, one line, nothing written.
    std::fs::write(
        &wind,
        text.replace("\"frictionLambda\": 0.15", "\"frictionLambda\": 0.5"),
    )
    .unwrap();
    refused_in_grbl(
        &wind,
        &dir.path().join("refused"),
        "ogive.wind:7:5: layer 3: frictionLambda 0.5 exceeds the machine slip limit",
    );
}
