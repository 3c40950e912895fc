//! `windcell lathe stream` against `windcell sim-grbl` over a real pseudo-terminal: the planned
//! seed 002 vessel arrives line for line, in order, and the 128-byte receive buffer never
//! overflows; a host that ignores the buffer is caught; Ctrl-C holds and resets; a pause waits at
//! the layer boundary.

use crate::common;

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use common::{example, serve_on_pty, stderr, stop_cleanly, windcell};

fn log_records(p: &Path) -> Vec<serde_json::Value> {
    std::fs::read_to_string(p)
        .unwrap_or_default()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

/// The lines a controller should receive: the file's lines without comments, blank lines and
/// the `%` marks, trimmed (worked out here independently of the streamer).
fn expected_lines(gcode: &str) -> Vec<String> {
    gcode
        .lines()
        .map(|l| {
            let mut out = String::new();
            let mut depth = 0;
            for c in l.chars() {
                match c {
                    '(' => depth += 1,
                    ')' => depth -= 1,
                    ';' if depth == 0 => break,
                    c if depth == 0 => out.push(c),
                    _ => {}
                }
            }
            out.trim().to_string()
        })
        .filter(|l| !l.is_empty() && l != "%")
        .collect()
}

fn received(log: &[serde_json::Value]) -> Vec<String> {
    log.iter()
        .filter(|r| r.get("line").is_some())
        .map(|r| r["text"].as_str().unwrap().to_string())
        .collect()
}

fn overflow_bytes(log: &[serde_json::Value]) -> u64 {
    log.iter()
        .filter_map(|r| r["overflow_bytes"].as_u64())
        .sum()
}

fn sim(d: &Path, time_scale: &str) -> (Child, String, PathBuf) {
    let log = d.join("grbl.log");
    let (child, pty) = serve_on_pty(&[
        "sim-grbl",
        "--pty",
        "--log",
        log.to_str().unwrap(),
        "--time-scale",
        time_scale,
    ]);
    (child, pty, log)
}

fn plan_vessel(d: &Path) -> PathBuf {
    let out = windcell(&[
        "lathe",
        "plan",
        example("seed002-vessel.toml").to_str().unwrap(),
        "--dialect",
        "grbl",
        "--out",
        d.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    d.join("seed002.nc")
}

/// Waits until the log holds `n` received lines.
fn wait_for_lines(log: &Path, n: usize) {
    let t0 = Instant::now();
    while received(&log_records(log)).len() < n {
        assert!(
            t0.elapsed() < Duration::from_secs(30),
            "fewer than {n} lines"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn planned_vessel_streams_every_line_once_in_order_without_overflow() {
    let d = tempfile::tempdir().unwrap();
    let gcode = plan_vessel(d.path());
    let want = expected_lines(&std::fs::read_to_string(&gcode).unwrap());
    assert!(want.len() > 7000, "{}", want.len());
    for flow in ["counting", "ok-per-line"] {
        // Motion 2000 times faster than commanded: the 17-minute program runs in about 0.5 s of
        // motion, still slower than the link, so the receive buffer fills.
        let (server, pty, log) = sim(d.path(), "2000");
        let out = windcell(&[
            "lathe",
            "stream",
            gcode.to_str().unwrap(),
            "--port",
            &pty,
            "--flow",
            flow,
        ]);
        stop_cleanly(server);
        assert_eq!(out.status.code(), Some(0), "{flow}: {}", stderr(&out));
        let records = log_records(&log);
        assert_eq!(received(&records), want, "{flow}");
        assert_eq!(overflow_bytes(&records), 0, "{flow}");
        let max_rx = records
            .iter()
            .filter_map(|r| r["rx_bytes"].as_u64())
            .max()
            .unwrap();
        assert!(max_rx <= 128, "{flow}: {max_rx}");
        if flow == "counting" {
            // Character counting keeps several lines in the buffer, not one.
            assert!(max_rx > 100, "{max_rx}");
        } else {
            let longest = want.iter().map(|l| l.len() as u64 + 1).max().unwrap();
            assert!(max_rx <= longest, "{max_rx} > {longest}");
        }
    }
}

#[test]
fn a_host_ignoring_the_receive_buffer_is_caught_as_overflow() {
    let d = tempfile::tempdir().unwrap();
    let gcode = plan_vessel(d.path());
    let (server, pty, log) = sim(d.path(), "1");
    let text = std::fs::read_to_string(&gcode).unwrap();
    let mut port = serialport::new(&pty, 115_200)
        .timeout(Duration::from_millis(100))
        .open()
        .unwrap();
    // The first 4000 bytes at once, as a naive sender would.
    port.write_all(&text.as_bytes()[..4000]).unwrap();
    port.flush().unwrap();
    let t0 = Instant::now();
    while overflow_bytes(&log_records(&log)) == 0 {
        assert!(t0.elapsed() < Duration::from_secs(10), "no overflow logged");
        std::thread::sleep(Duration::from_millis(20));
    }
    drop(port);
    stop_cleanly(server);
}

#[test]
fn ctrl_c_sends_feed_hold_and_reset_and_exits_130() {
    let d = tempfile::tempdir().unwrap();
    let gcode = plan_vessel(d.path());
    let (server, pty, log) = sim(d.path(), "1");
    let child = Command::new(env!("CARGO_BIN_EXE_windcell"))
        .args(["lathe", "stream", gcode.to_str().unwrap(), "--port", &pty])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    wait_for_lines(&log, 10);
    nix::sys::signal::kill(
        nix::unistd::Pid::from_raw(child.id() as i32),
        nix::sys::signal::Signal::SIGINT,
    )
    .unwrap();
    let out = child.wait_with_output().unwrap();
    assert_eq!(out.status.code(), Some(130), "{}", stderr(&out));
    assert_eq!(stderr(&out).lines().count(), 1, "{}", stderr(&out));
    let t0 = Instant::now();
    loop {
        let rt: Vec<String> = log_records(&log)
            .iter()
            .filter_map(|r| r["realtime"].as_str().map(str::to_string))
            .collect();
        if rt == ["feed_hold", "reset"] {
            break;
        }
        assert!(t0.elapsed() < Duration::from_secs(10), "{rt:?}");
        std::thread::sleep(Duration::from_millis(20));
    }
    stop_cleanly(server);
}

#[test]
fn pause_waits_at_the_layer_boundary_and_resume_completes() {
    let d = tempfile::tempdir().unwrap();
    let prog = d.path().join("two.nc");
    // Layer 1: 60 lines of 0.05 s each. The controller takes about 25 short lines at once (15
    // planner blocks and a full 128-byte receive buffer), then one per block finished, so layer
    // 1 is still being sent for about 1.7 s after the pause request (20 lines, as this test had,
    // all fit at once: the pause then raced the first milliseconds of the stream).
    let mut text = String::from("(layer 1)\nG21 G90 G94\n");
    for i in 1..=60 {
        text.push_str(&format!("G1 X{i} F1200\n"));
    }
    text.push_str("(layer 2)\nG1 X61\nG1 X62\nM30\n");
    std::fs::write(&prog, text).unwrap();
    let (server, pty, log) = sim(d.path(), "1");
    let mut child = Command::new(env!("CARGO_BIN_EXE_windcell"))
        .args(["lathe", "stream", prog.to_str().unwrap(), "--port", &pty])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    stdin.write_all(b"p\n").unwrap();
    // Nothing of layer 2 may follow while paused, though layer 1's motion has finished.
    wait_for_lines(&log, 61);
    std::thread::sleep(Duration::from_millis(2500));
    assert_eq!(received(&log_records(&log)).len(), 61);
    stdin.write_all(b"r\n").unwrap();
    let out = child.wait_with_output().unwrap();
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("paused before layer 2"),
        "{}",
        stderr(&out)
    );
    assert_eq!(received(&log_records(&log)).len(), 64);
    stop_cleanly(server);
}

#[test]
fn bad_input_and_a_missing_port_exit_2_with_one_line() {
    let d = tempfile::tempdir().unwrap();
    let long = d.path().join("long.nc");
    std::fs::write(&long, format!("G1 X1 F1\nG1 X{}\n", "1".repeat(130))).unwrap();
    let out = windcell(&[
        "lathe",
        "stream",
        long.to_str().unwrap(),
        "--port",
        "/dev/null",
    ]);
    assert_eq!(out.status.code(), Some(2));
    let e = stderr(&out);
    assert_eq!(e.lines().count(), 1, "{e}");
    // At the word that takes the line past GRBL's 80-character line buffer.
    assert!(
        e.contains("long.nc:2:4: line longer than the controller's 80-character line buffer"),
        "{e}"
    );
    let ok = d.path().join("ok.nc");
    std::fs::write(&ok, "G1 X1 F1\n").unwrap();
    let missing = d.path().join("no-such-port");
    let out = windcell(&[
        "lathe",
        "stream",
        ok.to_str().unwrap(),
        "--port",
        missing.to_str().unwrap(),
    ]);
    // A port that does not exist is bad input, found before anything is sent
    // (docs/file-formats.md, "Cell file").
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert_eq!(stderr(&out).lines().count(), 1);
}
