//! `windcell run` in discrete mode over pseudo-terminals to `windcell sim-robot --pty` and
//! `windcell sim-indexer --pty`, separate processes in real time (a real cell's set-up without
//! sync lines). The cylinder batch is cut to its first three instructions per path so that the
//! test takes seconds.

mod common;

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
    let (robot, robot_pty) = serve_on_pty(&["sim-robot", "--pty", "--home-s", "0.2"]);
    let (indexer, indexer_pty) = serve_on_pty(&["sim-indexer", "--pty"]);
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
}
