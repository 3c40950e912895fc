//! `windcell run` over pseudo-terminals in real time: discrete mode to separate `windcell
//! sim-robot --pty` and `windcell sim-indexer --pty` processes (a cell without sync lines), fine
//! mode to `windcell sim-cell --pty` (sync lines on its socket). The cylinder batch is cut to its
//! first three instructions per path so that the tests take seconds, not minutes (a verified
//! upload at 9600 baud costs about 0.9 s per instruction).

mod common;

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Command, Stdio};

use common::{example, serve_on_pty, stderr, stop_cleanly, windcell};

/// The header and the first `n` instructions of a .ROB, the first at full speed (the approach).
fn first_instructions(rob: &str, n: usize) -> String {
    let mut out = String::new();
    let mut k = 0;
    for line in rob.lines() {
        if line.starts_with("instr ") {
            k += 1;
            if k > n {
                continue;
            }
            if k == 1 {
                let l: Vec<String> = line
                    .split(' ')
                    .map(|w| {
                        if w.starts_with("speed_pct=") {
                            "speed_pct=100".to_string()
                        } else {
                            w.to_string()
                        }
                    })
                    .collect();
                out += &(l.join(" ") + "\n");
                continue;
            }
        }
        out += line;
        out.push('\n');
    }
    out
}

#[test]
fn discrete_batch_over_ptys_to_separate_simulators() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let o = windcell(&[
        "plan",
        example("cylinder.toml").to_str().unwrap(),
        "-o",
        d.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    for name in ["CYL_1.ROB", "CYL_2.ROB"] {
        let text = std::fs::read_to_string(d.join(name)).unwrap();
        std::fs::write(d.join(name), first_instructions(&text, 3)).unwrap();
    }
    let robot_log = d.join("robot.log");
    let indexer_log = d.join("indexer.log");
    let (robot, robot_pty) = serve_on_pty(&[
        "sim-robot",
        "--pty",
        "--home-s",
        "0.2",
        "--log",
        robot_log.to_str().unwrap(),
    ]);
    let (indexer, indexer_pty) = serve_on_pty(&[
        "sim-indexer",
        "--pty",
        "--log",
        indexer_log.to_str().unwrap(),
    ]);
    std::fs::write(
        d.join("cell.toml"),
        format!("[ports]\nrobot = \"{robot_pty}\"\nindexer = \"{indexer_pty}\"\n"),
    )
    .unwrap();
    let seq = d.join("CYL.SEQ");
    let cell = d.join("cell.toml");
    let o = windcell(&[
        "run",
        seq.to_str().unwrap(),
        "--mode",
        "discrete",
        "--cell",
        cell.to_str().unwrap(),
        "--json",
    ]);
    stop_cleanly(robot);
    stop_cleanly(indexer);
    assert!(o.status.success(), "{}", stderr(&o));
    let segments: Vec<(u64, u64)> = String::from_utf8_lossy(&o.stdout)
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap())
        .filter(|e| e["event"] == "segment")
        .map(|e| (e["item"].as_u64().unwrap(), e["segment"].as_u64().unwrap()))
        .collect();
    let want: Vec<(u64, u64)> = (1..=2).flat_map(|i| (1..=3).map(move |s| (i, s))).collect();
    assert_eq!(segments, want);
    // The journal confirms each segment once, with the robot at its target and the counter at
    // its destination.
    let journal = std::fs::read_to_string(d.join("CYL.journal")).unwrap();
    let confirmed = journal
        .lines()
        .filter(|l| l.contains("\"rec\":\"segment\""))
        .count();
    assert_eq!(confirmed, 6);
    assert!(journal.lines().last().unwrap().contains("\"rec\":\"done\""));
    // The simulators' own logs: every robot target once, in order; every segment's mandrel move
    // once, in order (the syncs at each path's start between them).
    let records = |p: &std::path::Path| -> Vec<serde_json::Value> {
        std::fs::read_to_string(p)
            .unwrap()
            .lines()
            .map(|l| serde_json::from_str(l).unwrap())
            .collect()
    };
    let mut targets = Vec::new();
    let mut steps = Vec::new();
    for k in 1..=2 {
        for l in std::fs::read_to_string(d.join(format!("CYL_{k}.ROB")))
            .unwrap()
            .lines()
        {
            if l.starts_with("instr ") {
                for w in l.split(' ') {
                    if let Some(v) = w.strip_prefix("pos_mm=") {
                        let v: Vec<f64> = v.split(',').map(|x| x.parse().unwrap()).collect();
                        targets.push(v);
                    }
                    if let Some(v) = w.strip_prefix("steps=") {
                        let v: i64 = v.parse().unwrap();
                        if v != 0 {
                            steps.push(v);
                        }
                    }
                }
            }
        }
    }
    let done: Vec<Vec<f64>> = records(&robot_log)
        .iter()
        .filter(|r| r["completed"] == true)
        .map(|r| {
            r["target_mm"]
                .as_array()
                .unwrap()
                .iter()
                .map(|x| x.as_f64().unwrap())
                .collect()
        })
        .collect();
    assert_eq!(done.len(), targets.len(), "{done:?}");
    for (got, want) in done.iter().zip(&targets) {
        assert!(
            got.iter().zip(want).all(|(a, b)| (a - b).abs() <= 0.05),
            "{got:?} against {want:?}"
        );
    }
    let turned: Vec<i64> = records(&indexer_log)
        .iter()
        .map(|r| r["steps"].as_i64().unwrap())
        .collect();
    let mut k = 0;
    for t in &turned {
        if k < steps.len() && *t == steps[k] {
            k += 1;
        }
    }
    assert_eq!(
        k,
        steps.len(),
        "segment moves {steps:?} not all in {turned:?}"
    );
    assert!(turned.len() <= steps.len() + 2, "extra moves: {turned:?}");
}

/// The cylinder plan in `d`, cut to `n` instructions per path, the .IND moves made to match.
fn short_cylinder(d: &Path, n: usize) {
    let o = windcell(&[
        "plan",
        example("cylinder.toml").to_str().unwrap(),
        "-o",
        d.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    for k in 1..=2 {
        let rob = d.join(format!("CYL_{k}.ROB"));
        let text = first_instructions(&std::fs::read_to_string(&rob).unwrap(), n);
        let steps: i64 = text
            .lines()
            .filter(|l| l.starts_with("instr "))
            .filter_map(|l| l.split(' ').find_map(|w| w.strip_prefix("steps=")))
            .map(|s| s.parse::<i64>().unwrap())
            .sum();
        std::fs::write(&rob, text).unwrap();
        let ind = d.join(format!("CYL_{k}.IND"));
        let text: String = std::fs::read_to_string(&ind)
            .unwrap()
            .lines()
            .map(|l| {
                if l.starts_with("move ") {
                    let w: Vec<String> = l
                        .split(' ')
                        .map(|w| {
                            if w.starts_with("steps=") {
                                format!("steps={steps}")
                            } else {
                                w.to_string()
                            }
                        })
                        .collect();
                    w.join(" ") + "\n"
                } else {
                    l.to_string() + "\n"
                }
            })
            .collect();
        std::fs::write(&ind, text).unwrap();
    }
}

#[test]
fn fine_batch_over_ptys_to_sim_cell() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    short_cylinder(d, 3);
    let log = d.join("cell.log");
    let socket = d.join("sync.sock");
    let mut server = Command::new(env!("CARGO_BIN_EXE_windcell"))
        .args([
            "sim-cell",
            "--pty",
            "--home-s",
            "0.2",
            "--log",
            log.to_str().unwrap(),
            "--socket",
            socket.to_str().unwrap(),
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut lines = BufReader::new(server.stdout.take().unwrap()).lines();
    let robot = lines.next().unwrap().unwrap();
    let indexer = lines.next().unwrap().unwrap();
    let sock = lines.next().unwrap().unwrap();
    std::fs::write(
        d.join("cell.toml"),
        format!("[ports]\nrobot = \"{robot}\"\nindexer = \"{indexer}\"\nsync = \"unix:{sock}\"\n"),
    )
    .unwrap();
    let seq = d.join("CYL.SEQ");
    let cell = d.join("cell.toml");
    // Medium mode takes the same code path (covered on the fast clock in tests/coordinator.rs).
    let o = windcell(&[
        "run",
        seq.to_str().unwrap(),
        "--mode",
        "fine",
        "--cell",
        cell.to_str().unwrap(),
    ]);
    stop_cleanly(server);
    assert!(o.status.success(), "{}", stderr(&o));
    // The cell's log: each program's three instructions once, in order.
    let done: Vec<(u64, u64)> = std::fs::read_to_string(&log)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap())
        .filter(|r| r["device"] == "robot" && r["program"] != 0 && r["completed"] == true)
        .map(|r| {
            (
                r["program"].as_u64().unwrap(),
                r["instruction"].as_u64().unwrap(),
            )
        })
        .collect();
    let one: Vec<(u64, u64)> = (1..=2).flat_map(|p| (3..=5).map(move |i| (p, i))).collect();
    assert_eq!(done, one);
}
