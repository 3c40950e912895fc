//! `windcell sim-indexer --pty`: the binary prints its pty path, a client drives a preset move
//! over it, and SIGTERM ends it with exit code 0.

use crate::common;

use std::time::Duration;

use mandrel_drive::link::SerialLink;
use mandrel_drive::{GrblClient, Indexer, IndexerConfig, PosMode, Profile, XClient};

fn run_dialect(dialect: &str) {
    let (child, path) = common::serve_on_pty(&["sim-indexer", "--pty", "--dialect", dialect]);

    let port = SerialLink(Box::new(
        serialport::new(&path, 115_200)
            .timeout(Duration::from_millis(100))
            .open_native()
            .expect("open pty"),
    ));
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

    common::stop_cleanly(child);
}

#[test]
fn serves_both_dialects_and_stops_on_sigterm() {
    run_dialect("x");
    run_dialect("grbl");
}

#[test]
fn serves_on_a_pty_without_the_flag_too() {
    // The pseudo-terminal is the only transport, so it is the default.
    let (child, path) = common::serve_on_pty(&["sim-indexer"]);
    assert!(std::path::Path::new(&path).exists(), "{path}");
    common::stop_cleanly(child);
}
