//! `windcell run` driving a GRBL indexer (`[indexer] dialect = "grbl"` in the cell file) over a
//! pseudo-terminal in real time: `windcell sim-robot --pty` and `windcell sim-indexer --dialect
//! grbl --pty`, discrete mode (a GRBL controller has no trigger input), the cylinder batch cut to
//! three instructions per path as in `run_pty.rs`. Before the dialect key, the X-language client
//! spoke to the GRBL simulator and the run failed on its `error:20`.

use crate::common;

use std::io::{Read, Write};
use std::path::Path;
use std::time::{Duration, Instant};

use common::{serve_on_pty, stderr, stop_cleanly, windcell};
use foxglove::Decode;
use foxglove::schemas::FrameTransform;

use super::run_pty::{completed_targets, short_cylinder};

/// The `pos_mm` of every instruction of the `.ROB` files of `d`, and where the mandrel ends: the
/// last path's `sync_mandrel_deg` (the angle the coordinator turns it to before the path, in
/// whole steps) plus that path's instruction `steps`.
fn planned(d: &Path, steps_per_deg: f64) -> (Vec<Vec<f64>>, i64) {
    let mut targets = Vec::new();
    let mut end = 0;
    for k in 1..=2 {
        let text = std::fs::read_to_string(d.join(format!("CYL_{k}.ROB"))).unwrap();
        for l in text.lines() {
            if let Some(deg) = l.strip_prefix("sync_mandrel_deg ") {
                end = (deg.trim().parse::<f64>().unwrap() * steps_per_deg).round() as i64;
            }
            if !l.starts_with("instr ") {
                continue;
            }
            for w in l.split(' ') {
                if let Some(v) = w.strip_prefix("pos_mm=") {
                    targets.push(v.split(',').map(|x| x.parse().unwrap()).collect());
                }
                if let Some(v) = w.strip_prefix("steps=") {
                    end += v.parse::<i64>().unwrap();
                }
            }
        }
    }
    (targets, end)
}

/// Asks a GRBL controller on `pty` for its status (`?`) and returns the A position, degrees,
/// from `<Idle|MPos:x,y,z,a|…>` (GRBL 1.1 status report, grblHAL's fourth axis).
fn grbl_a_deg(pty: &str) -> f64 {
    let mut port = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .open(pty)
        .unwrap();
    // Raw mode is the simulator's; the test's end only writes one byte and reads a line.
    port.write_all(b"?").unwrap();
    let t0 = Instant::now();
    let mut text = String::new();
    let mut buf = [0u8; 256];
    while !text.contains('>') {
        assert!(t0.elapsed() < Duration::from_secs(5), "no status: {text:?}");
        let n = port.read(&mut buf).unwrap();
        text.push_str(&String::from_utf8_lossy(&buf[..n]));
    }
    let mpos = text.split("MPos:").nth(1).unwrap();
    let mpos = mpos.split(['|', '>']).next().unwrap();
    mpos.split(',').nth(3).unwrap().parse().unwrap()
}

/// Six discrete segments to the robot and a GRBL indexer on pseudo-terminals: the run succeeds,
/// the journal confirms each segment once, the robot simulator's log has every planned target in
/// order, and the GRBL controller stands where the plan's last path ends (its A position read
/// back over its own port and turned into steps with the thesis drive's 400 steps per motor
/// revolution and 13:60 belt, seed 001 §4.1; the plan's from its `.ROB` files). A program mode is refused before anything moves,
/// naming the cell file's dialect line and column.
#[test]
fn a_discrete_batch_drives_a_grbl_indexer_over_ptys() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    short_cylinder(d, 3);
    let robot_log = d.join("robot.log");
    let (robot, robot_pty) = serve_on_pty(&[
        "sim-robot",
        "--pty",
        "--home-s",
        "0.2",
        "--log",
        robot_log.to_str().unwrap(),
    ]);
    let (indexer, indexer_pty) = serve_on_pty(&["sim-indexer", "--pty", "--dialect", "grbl"]);
    let cell = d.join("cell.toml");
    std::fs::write(
        &cell,
        format!(
            "[ports]\nrobot = \"{robot_pty}\"\nindexer = \"{indexer_pty}\"\n\n[indexer]\ndialect = \"grbl\"\n"
        ),
    )
    .unwrap();
    let seq = d.join("CYL.SEQ");
    // Program mode cannot arm a GRBL move on the start line: refused at the key, nothing sent.
    let o = windcell(&[
        "run",
        seq.to_str().unwrap(),
        "--mode",
        "fine",
        "--cell",
        cell.to_str().unwrap(),
        "--force",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let line = stderr(&o);
    assert_eq!(line.trim().lines().count(), 1, "{line}");
    assert!(line.contains("cell.toml:6:11:"), "{line}");
    assert!(!d.join("CYL.journal").exists());
    let o = windcell(&[
        "run",
        seq.to_str().unwrap(),
        "--mode",
        "discrete",
        "--cell",
        cell.to_str().unwrap(),
        "--force",
        "--json",
        "--record",
        d.join("grbl.mcap").to_str().unwrap(),
    ]);
    let a_deg = grbl_a_deg(&indexer_pty);
    stop_cleanly(robot);
    stop_cleanly(indexer);
    assert!(o.status.success(), "{}", stderr(&o));
    let journal = std::fs::read_to_string(d.join("CYL.journal")).unwrap();
    let confirmed = journal
        .lines()
        .filter(|l| l.contains("\"rec\":\"segment\""))
        .count();
    assert_eq!(confirmed, 6);
    assert!(journal.lines().last().unwrap().contains("\"rec\":\"done\""));
    // The thesis drive: 400 steps per motor revolution, 13:60 belt (seed 001 §4.1).
    let steps_per_deg = 400.0 * 60.0 / 13.0 / 360.0;
    let (targets, end_steps) = planned(d, steps_per_deg);
    let done = completed_targets(&robot_log);
    assert_eq!(done.len(), targets.len(), "{done:?}");
    for (got, want) in done.iter().zip(&targets) {
        assert!(
            got.iter().zip(want).all(|(a, b)| (a - b).abs() <= 0.05),
            "{got:?} against {want:?}"
        );
    }
    let turned = a_deg * steps_per_deg;
    assert!(
        (turned - end_steps as f64).abs() < 0.5,
        "GRBL at {a_deg} deg = {turned} steps, the plan ends at {end_steps}"
    );
    // On serial ports `/tf` comes from what the devices report: the robot's position replies as
    // `world → eye` (metres), the GRBL status reports' A position as `world → mandrel` (a
    // rotation about the axis, z). The last of each is where the batch ended.
    let bytes = std::fs::read(d.join("grbl.mcap")).unwrap();
    let mut eye = Vec::new();
    let mut mandrel = Vec::new();
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        if m.channel.topic == "/tf" {
            let f = FrameTransform::decode(&m.data[..]).unwrap();
            match f.child_frame_id.as_str() {
                "eye" => eye.push(f),
                "mandrel" => mandrel.push(f),
                other => panic!("frame {other}"),
            }
        }
    }
    assert!(eye.len() >= 6, "{} eye reports", eye.len());
    let last = eye.last().unwrap().translation.unwrap();
    let want = targets.last().unwrap();
    for (got_m, want_mm) in [last.x, last.y, last.z].iter().zip(want) {
        assert!(
            (got_m * 1000.0 - want_mm).abs() <= 0.05,
            "{last:?} against {want:?}"
        );
    }
    let q = mandrel.last().expect("no mandrel report").rotation.unwrap();
    let angle_deg = 2.0 * q.z.atan2(q.w).to_degrees();
    assert!(
        (angle_deg - end_steps as f64 / steps_per_deg).abs() < 0.01,
        "mandrel frame at {angle_deg} deg, the plan ends at {end_steps} steps"
    );
}
