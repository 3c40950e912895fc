//! `windcell sim-marlin`: a `.wind` plan written for FiberPath's XAB machine streams to the end,
//! by `windcell lathe stream --flow ok-per-line` over a pseudo-terminal and by FiberPath's own
//! `fiberpath stream` (the marlin-host library, line numbers and checksums) over a socket; the
//! log shows every line of the file executed once, in order (the lines worked out here from the
//! file: every line that is not a comment or blank).

use crate::common;

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};

use common::lathe::lathe_plan;
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

/// Runs `windcell lathe stream PROGRAM --port PORT --flow ok-per-line EXTRA…` (Marlin's flow).
fn stream_ok_per_line(program: &Path, port: &str, extra: &[&str]) -> std::process::Output {
    let mut args = vec![
        "lathe",
        "stream",
        program.to_str().unwrap(),
        "--port",
        port,
        "--flow",
        "ok-per-line",
    ];
    args.extend_from_slice(extra);
    windcell(&args)
}

/// `windcell sim-marlin --log LOG --time-scale SCALE` on a pseudo-terminal: the server and its
/// device.
fn serve_marlin(log: &Path, time_scale: &str) -> (Child, String) {
    serve_on_pty(&[
        "sim-marlin",
        "--log",
        log.to_str().unwrap(),
        "--time-scale",
        time_scale,
    ])
}

/// Plans the tube for Marlin (the default machine, fiberpath-xab) into `dir`.
fn program(dir: &Path) -> PathBuf {
    let wind = dir.join("tube.wind");
    std::fs::write(&wind, TUBE).unwrap();
    let out = lathe_plan(&wind, dir, "marlin", &[]);
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
    // `--pty` given (it is also the default).
    let (child, pty) = serve_on_pty(&[
        "sim-marlin",
        "--pty",
        "--log",
        log.to_str().unwrap(),
        "--time-scale",
        "1000",
    ]);
    let out = stream_ok_per_line(&program, &pty, &[]);
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

#[test]
fn progress_is_shown_as_plain_lines_and_json_events() {
    let d = tempfile::tempdir().unwrap();
    let program = program(d.path());
    let layers = std::fs::read_to_string(&program)
        .unwrap()
        .lines()
        .filter(|l| l.starts_with("; layer "))
        .count();
    assert_eq!(layers, 3);
    let log = d.path().join("marlin.log");
    let (child, pty) = serve_marlin(&log, "300");
    // Not a terminal: plain lines every 0.2 s, the last at 100 %.
    let out = stream_ok_per_line(&program, &pty, &["--progress-every-s", "0.2"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let err = stderr(&out);
    let total = commands(&program).len();
    let progress: Vec<&str> = err.lines().filter(|l| l.contains("lines sent,")).collect();
    assert!(progress.len() >= 3, "{err}");
    assert!(
        progress.last().unwrap().contains(&format!(
            "{total}/{total} lines sent, {total} acknowledged (100 %), layer 3/3"
        )),
        "{err}"
    );
    assert!(progress.iter().any(|l| l.contains("left ")), "{err}");
    // JSON: start, one event per layer in order, progress, done.
    let out = stream_ok_per_line(&program, &pty, &["--json"]);
    stop_cleanly(child);
    assert!(out.status.success(), "{}", stderr(&out));
    let events: Vec<serde_json::Value> = String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(events[0]["event"], "start");
    assert_eq!(events[0]["lines"].as_u64(), Some(total as u64));
    let layer_events: Vec<u64> = events
        .iter()
        .filter(|e| e["event"] == "layer")
        .map(|e| e["layer"].as_u64().unwrap())
        .collect();
    assert_eq!(layer_events, [1, 2, 3]);
    assert_eq!(events.last().unwrap()["event"], "done");
    assert!(
        events
            .iter()
            .any(|e| e["event"] == "progress" && e["acknowledged"].as_u64() == Some(total as u64))
    );
}

#[test]
fn a_bad_line_anywhere_is_refused_before_the_first_line_is_sent() {
    let d = tempfile::tempdir().unwrap();
    let program = program(d.path());
    let text = std::fs::read_to_string(&program).unwrap();
    let n = text.lines().count();
    // A bad number near the end.
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let at = n - 3;
    lines[at] = "G1 X12.5.1 A3".to_string();
    let bad = d.path().join("bad.gcode");
    std::fs::write(&bad, lines.join("\n")).unwrap();
    let log = d.path().join("marlin.log");
    let (child, pty) = serve_on_pty(&["sim-marlin", "--log", log.to_str().unwrap()]);
    let out = windcell(&["lathe", "stream", bad.to_str().unwrap(), "--port", &pty]);
    std::thread::sleep(std::time::Duration::from_millis(300));
    stop_cleanly(child);
    assert_eq!(out.status.code(), Some(2));
    let err = stderr(&out);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(
        err.contains(&format!("bad.gcode:{}:5: word X has no number", at + 1)),
        "{err}"
    );
    assert!(std::fs::read_to_string(&log).unwrap().is_empty());
}

#[test]
fn a_stop_names_the_line_to_restart_from() {
    let d = tempfile::tempdir().unwrap();
    let program = program(d.path());
    let log = d.path().join("marlin.log");
    // Real time: the program takes minutes, the stop comes after a second.
    let (child, pty) = serve_on_pty(&["sim-marlin", "--log", log.to_str().unwrap()]);
    let stream = Command::new(env!("CARGO_BIN_EXE_windcell"))
        .args([
            "lathe",
            "stream",
            program.to_str().unwrap(),
            "--port",
            &pty,
            "--flow",
            "ok-per-line",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .stdin(Stdio::null())
        .spawn()
        .unwrap();
    std::thread::sleep(std::time::Duration::from_millis(1500));
    Command::new("kill")
        .args(["-INT", &stream.id().to_string()])
        .status()
        .unwrap();
    let out = stream.wait_with_output().unwrap();
    stop_cleanly(child);
    assert_eq!(out.status.code(), Some(130), "{}", stderr(&out));
    let err = stderr(&out);
    let last = err.lines().last().unwrap();
    let restart: usize = last
        .split("restart from ")
        .nth(1)
        .and_then(|r| r.split(' ').next())
        .and_then(|r| r.rsplit(':').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("{err}"));
    // The restart line is a line to send, and every line before it was executed.
    let text = std::fs::read_to_string(&program).unwrap();
    let file_lines: Vec<&str> = text.lines().collect();
    let line = file_lines[restart - 1];
    assert!(!line.is_empty() && !line.starts_with(';'), "{line}");
    let before = file_lines[..restart - 1]
        .iter()
        .filter(|l| !l.is_empty() && !l.starts_with(';'))
        .count();
    let (ran, _) = executed(&log);
    assert!(ran.len() >= before && before > 0, "{} {before}", ran.len());
    assert!(last.contains("layer "), "{last}");
}
