//! `windcell sim-marlin`: a `.wind` plan written for FiberPath's XAB machine streams to the end,
//! by `windcell lathe stream --flow ok-per-line` over a pseudo-terminal and by FiberPath's own
//! `fiberpath stream` (the marlin-host library, line numbers and checksums) over a socket; the
//! log shows every line of the file executed once, in order (the lines worked out here from the
//! file: every line that is not a comment or blank).

mod common;

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};

use common::{serve_on_pty, stderr, stop_cleanly, windcell};

const TUBE: &str = r#"{
  "schemaVersion": "1.0",
  "mandrelParameters": { "diameter": 100, "windLength": 800 },
  "towParameters": { "width": 8, "thickness": 0.4 },
  "defaultFeedRate": 8000,
  "layers": [
    { "windType": "hoop" },
    { "windType": "helical", "windAngle": 45, "patternNumber": 4, "skipIndex": 1,
      "lockDegrees": 540, "leadInMM": 20, "leadOutDegrees": 20 },
    { "windType": "helical", "windAngle": 45, "patternNumber": 4, "skipIndex": 1,
      "lockDegrees": 540, "leadInMM": 20, "leadOutDegrees": 20 }
  ]
}"#;

/// Plans the tube for Marlin (the default machine, fiberpath-xab) into `dir`.
fn program(dir: &Path) -> PathBuf {
    let wind = dir.join("tube.wind");
    std::fs::write(&wind, TUBE).unwrap();
    let out = windcell(&[
        "lathe",
        "plan",
        wind.to_str().unwrap(),
        "-o",
        dir.to_str().unwrap(),
        "--dialect",
        "marlin",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    dir.join("tube.gcode")
}

/// The lines a host sends: not comments, not blank.
fn commands(program: &Path) -> Vec<String> {
    std::fs::read_to_string(program)
        .unwrap()
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with(';'))
        .map(str::to_string)
        .collect()
}

/// The executed lines of a sim-marlin log, in order, and every other record.
fn executed(log: &Path) -> (Vec<String>, Vec<serde_json::Value>) {
    let mut lines = Vec::new();
    let mut other = Vec::new();
    for l in std::fs::read_to_string(log).unwrap().lines() {
        let v: serde_json::Value = serde_json::from_str(l).unwrap();
        if v.get("executed").is_some() {
            lines.push(v["text"].as_str().unwrap().to_string());
        } else {
            other.push(v);
        }
    }
    (lines, other)
}

#[test]
fn lathe_stream_runs_a_fiberpath_machine_program_to_the_end() {
    let d = tempfile::tempdir().unwrap();
    let program = program(d.path());
    let log = d.path().join("marlin.log");
    let (child, pty) = serve_on_pty(&[
        "sim-marlin",
        "--pty",
        "--log",
        log.to_str().unwrap(),
        "--time-scale",
        "1000",
    ]);
    let out = windcell(&[
        "lathe",
        "stream",
        program.to_str().unwrap(),
        "--port",
        &pty,
        "--flow",
        "ok-per-line",
    ]);
    stop_cleanly(child);
    assert!(out.status.success(), "{}", stderr(&out));
    let (ran, other) = executed(&log);
    let sent = commands(&program);
    assert!(sent.len() > 500, "{}", sent.len());
    assert_eq!(ran, sent);
    assert!(other.is_empty(), "{other:?}");
}

/// `fiberpath` from the cache, installed from PyPI if needed; `None` (saying why) when PyPI
/// cannot be reached and it is not cached.
fn fiberpath() -> Option<String> {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scripts/fiberpath-accepts.py");
    let out = Command::new("python3")
        .arg(&script)
        .arg("--setup-only")
        .output()
        .expect("python3 runs");
    if out.status.code() == Some(77) {
        eprintln!("fiberpath stream skipped: {}", stderr(&out).trim());
        return None;
    }
    assert!(out.status.success(), "{}", stderr(&out));
    Some(String::from_utf8(out.stdout).unwrap().trim().to_string())
}

fn serve_on_tcp(log: &Path) -> (Child, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_windcell"))
        .args([
            "sim-marlin",
            "--tcp",
            "127.0.0.1:0",
            "--log",
            log.to_str().unwrap(),
            "--time-scale",
            "1000",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut url = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut url)
        .unwrap();
    let url = url.trim().to_string();
    assert!(url.starts_with("socket://127.0.0.1:"), "{url}");
    (child, url)
}

#[test]
fn fiberpath_stream_runs_a_windcell_program_to_the_end() {
    let Some(fiberpath) = fiberpath() else {
        return;
    };
    let d = tempfile::tempdir().unwrap();
    let program = program(d.path());
    let log = d.path().join("marlin.log");
    let (child, url) = serve_on_tcp(&log);
    let out = Command::new(&fiberpath)
        .args([
            "stream",
            program.to_str().unwrap(),
            "--port",
            &url,
            "--json",
        ])
        .output()
        .unwrap();
    stop_cleanly(child);
    assert!(
        out.status.success(),
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        stderr(&out)
    );
    let (ran, other) = executed(&log);
    let sent = commands(&program);
    // marlin-host's handshake first (M110 N0 to sync the line numbers, M115 for the firmware's
    // capabilities), then the file, every line once and in order.
    assert_eq!(ran[..2], ["M110 N0", "M115"]);
    assert_eq!(ran[2..], sent[..]);
    assert!(other.is_empty(), "{other:?}");
    let summary: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(summary["commands"].as_u64(), Some(sent.len() as u64));
}

#[test]
fn bad_arguments_exit_2_in_one_line() {
    for args in [
        &["sim-marlin", "--time-scale", "0"][..],
        &["sim-marlin", "--tcp", "nowhere:x"][..],
        &["sim-marlin", "--pty", "--tcp", "127.0.0.1:0"][..],
    ] {
        let out = windcell(args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        assert_eq!(stderr(&out).lines().count(), 1, "{}", stderr(&out));
    }
}
