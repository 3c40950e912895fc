//! `windcell sim-indexer --pty`: the binary prints its pty path, a client drives a preset move
//! over it, and SIGTERM ends it with exit code 0.

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::time::Duration;

use mandrel_drive::{GrblClient, Indexer, IndexerConfig, PosMode, Profile, XClient};

fn run_dialect(dialect: &str) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_windcell"))
        .args(["sim-indexer", "--pty", "--dialect", dialect])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn windcell");
    let stdout = child.stdout.take().expect("stdout");
    let mut path = String::new();
    BufReader::new(stdout)
        .read_line(&mut path)
        .expect("path line");
    let path = path.trim().to_string();
    assert!(path.starts_with("/dev/"), "{path:?}");

    let port = serialport::new(&path, 115_200)
        .timeout(Duration::from_millis(100))
        .open_native()
        .expect("open pty");
    let profile = Profile {
        accel_rps2: 4.0,
        start_rps: 0.0,
        max_rps: 2.0,
    };
    let cfg = IndexerConfig::default();
    if dialect == "x" {
        let mut c = XClient::new(port, cfg);
        c.init().unwrap();
        c.set_profile(profile).unwrap();
        c.move_to(1846, PosMode::Incremental).unwrap();
        c.wait_complete(Duration::from_secs(5)).unwrap();
        assert_eq!(c.status().unwrap().position_steps, Some(1846));
    } else {
        let mut c = GrblClient::new(port, cfg);
        c.init().unwrap();
        c.set_profile(profile).unwrap();
        c.move_to(1846, PosMode::Absolute).unwrap();
        let s = c.wait_idle(Duration::from_secs(5)).unwrap();
        assert_eq!(s.position_steps, Some(1846));
    }

    let killed = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .expect("kill");
    assert!(killed.success());
    let out = child.wait_with_output().expect("wait");
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn serves_both_dialects_and_stops_on_sigterm() {
    run_dialect("x");
    run_dialect("grbl");
}

#[test]
fn without_pty_is_bad_input() {
    let out = Command::new(env!("CARGO_BIN_EXE_windcell"))
        .args(["sim-indexer"])
        .output()
        .expect("run");
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--pty"));
}
