//! `windcell run` from the command line on the built-in simulated cell: the three modes, the
//! console's stop and `--resume`, `--json` events, and each kind of bad input (one line, exit 2,
//! nothing sent).

use crate::common;

use std::io::Write;
use std::path::Path;
use std::process::{Command, Stdio};

use common::{example, example_variant, stderr, windcell};

fn plan_sbend(dir: &Path) {
    let o = windcell(&[
        "plan",
        example("sbend.toml").to_str().unwrap(),
        "-o",
        dir.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
}

fn run(args: &[&str]) -> std::process::Output {
    let mut all = vec!["run"];
    all.extend_from_slice(args);
    windcell(&all)
}

#[test]
fn json_events_of_a_fine_run_from_a_sequence() {
    let dir = tempfile::tempdir().unwrap();
    plan_sbend(dir.path());
    let seq = dir.path().join("SBEND.SEQ");
    let log = dir.path().join("cell.log");
    let job = example("sbend.toml");
    let o = run(&[
        seq.to_str().unwrap(),
        "--json",
        "--log",
        log.to_str().unwrap(),
        "--job",
        job.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let events: Vec<serde_json::Value> = String::from_utf8_lossy(&o.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let mut kinds: Vec<&str> = events
        .iter()
        .map(|e| e["event"].as_str().unwrap())
        .collect();
    kinds.dedup();
    // Homing, the upload's phase and its exchanges; per path its approach, its winding, the
    // program's start, its segments, its end.
    assert_eq!(
        kinds,
        [
            "started", "phase", "upload", "phase", "program", "segment", "program", "phase",
            "program", "segment", "program", "done"
        ]
    );
    let phases: Vec<&str> = events
        .iter()
        .filter(|e| e["event"] == "phase")
        .map(|e| e["phase"].as_str().unwrap())
        .collect();
    assert_eq!(
        phases,
        [
            "homing", "upload", "approach", "winding", "approach", "winding"
        ]
    );
    let upload = events.iter().rfind(|e| e["event"] == "upload").unwrap();
    assert_eq!(upload["done"], upload["total"]);
    // Segments 1..50 of each path, as `plan` numbers them.
    for item in 1..=2 {
        let numbers: Vec<u64> = events
            .iter()
            .filter(|e| e["event"] == "segment" && e["item"] == item)
            .map(|e| e["segment"].as_u64().unwrap())
            .collect();
        assert_eq!(numbers, (1..=50).collect::<Vec<u64>>());
    }
    assert_eq!(events[0]["mode"], "fine");
    assert!(
        events[0]["journal"]
            .as_str()
            .unwrap()
            .ends_with("SBEND.journal")
    );
    let paths = events.last().unwrap()["paths"].as_array().unwrap();
    assert_eq!(paths.len(), 2);
    assert_eq!(paths[1]["name"], "SBEND_2");
    // The simulators' log: 51 + 51 robot instructions of the two programs, completed.
    let text = std::fs::read_to_string(&log).unwrap();
    let program_instructions = text
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap())
        .filter(|r| r["device"] == "robot" && r["program"] != 0 && r["completed"] == true)
        .count();
    assert_eq!(program_instructions, 102);
}

#[test]
fn the_console_stop_then_resume_finishes_the_batch() {
    let dir = tempfile::tempdir().unwrap();
    plan_sbend(dir.path());
    let seq = dir.path().join("SBEND.SEQ");
    let journal = dir.path().join("SBEND.journal");
    let mut child = Command::new(env!("CARGO_BIN_EXE_windcell"))
        .args([
            "run",
            seq.to_str().unwrap(),
            "--mode",
            "discrete",
            "--force",
        ])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    child.stdin.take().unwrap().write_all(b"s\n").unwrap();
    let o = child.wait_with_output().unwrap();
    assert_eq!(o.status.code(), Some(130), "{}", stderr(&o));
    let err = stderr(&o);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains("stopped at path 1 (SBEND_1)"), "{err}");
    assert!(err.contains("the console's stop"), "{err}");
    assert!(err.contains("--resume"), "{err}");
    assert!(!String::from_utf8_lossy(&o.stdout).contains("resuming"));
    let o = run(&[
        seq.to_str().unwrap(),
        "--mode",
        "discrete",
        "--force",
        "--resume",
        journal.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains("batch done: 2 paths"));
    assert!(out.contains("resuming path "), "{out}");
    // Without a terminal the progress is a line every tenth segment and at the last.
    let mut shown: Vec<(usize, usize)> = Vec::new();
    for l in out.lines().filter(|l| l.contains("path 2/2")) {
        let Some((_, rest)) = l.split_once(": segment ") else {
            continue;
        };
        let (k, n) = rest.split_once(',').unwrap().0.split_once('/').unwrap();
        shown.push((k.parse().unwrap(), n.parse().unwrap()));
    }
    let n = shown.last().expect("segment lines").1;
    let want: Vec<(usize, usize)> = (1..=n)
        .filter(|k| k % 10 == 0 || *k == n)
        .map(|k| (k, n))
        .collect();
    assert_eq!(shown, want, "{out}");
    // Done is done.
    let o = run(&[
        seq.to_str().unwrap(),
        "--mode",
        "discrete",
        "--resume",
        journal.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
}

fn bad(args: &[&str], expect: &str) {
    let o = run(args);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains(expect), "{args:?}: {err}");
    assert!(o.stdout.is_empty(), "{args:?}: something was run");
}

#[test]
fn bad_input_is_one_line_and_exit_code_2_before_anything_is_sent() {
    let dir = tempfile::tempdir().unwrap();
    plan_sbend(dir.path());
    let d = dir.path();
    let p = |n: &str| d.join(n).to_str().unwrap().to_string();
    // A control file named in the sequence that is missing.
    std::fs::write(d.join("MISS.SEQ"), "SBEND_1\nSBEND_9\n").unwrap();
    bad(&[&p("MISS.SEQ"), "--mode", "discrete"], "SBEND_9.ROB");
    // A program in the run file that the sequence does not load.
    std::fs::write(d.join("R.RUN"), "1\n7\n").unwrap();
    bad(
        &[&p("SBEND.SEQ"), "--run", &p("R.RUN")],
        "R.RUN:2:1: program 7 is not loaded by the sequence",
    );
    // A batch over the robot's memory: nine 51-point programs.
    let rob = std::fs::read_to_string(d.join("SBEND_1.ROB")).unwrap();
    let ind = std::fs::read_to_string(d.join("SBEND_1.IND")).unwrap();
    let mut seq = String::new();
    let mut runf = String::new();
    for k in 1..=9 {
        std::fs::write(
            d.join(format!("BIG_{k}.ROB")),
            rob.replace("program 1\n", &format!("program {k}\n")),
        )
        .unwrap();
        std::fs::write(d.join(format!("BIG_{k}.IND")), &ind).unwrap();
        seq += &format!("BIG_{k}\n");
        runf += &format!("{k}\n");
    }
    std::fs::write(d.join("BIG.SEQ"), seq).unwrap();
    std::fs::write(d.join("BIG.RUN"), runf).unwrap();
    bad(&[&p("BIG.SEQ")], "memory units of the robot's 9400");
    // An instruction the arm cannot reach.
    let far: String = rob
        .lines()
        .map(|l| {
            let words: Vec<&str> = l
                .split(' ')
                .map(|w| {
                    if l.starts_with("instr 1 ") && w.starts_with("pos_mm=") {
                        "pos_mm=1700,0,500"
                    } else {
                        w
                    }
                })
                .collect();
            words.join(" ") + "\n"
        })
        .collect();
    std::fs::create_dir(d.join("far")).unwrap();
    std::fs::write(d.join("far/FAR_1.ROB"), far).unwrap();
    std::fs::write(d.join("far/FAR.SEQ"), "FAR_1\n").unwrap();
    bad(
        &[&p("far/FAR.SEQ"), "--mode", "discrete"],
        "out of the arm's reach",
    );
    // A port that does not exist.
    std::fs::write(
        d.join("cell.toml"),
        "[ports]\nrobot = \"/dev/windcell-none-r\"\nindexer = \"/dev/windcell-none-i\"\nsync = \"/dev/windcell-none-s\"\n",
    )
    .unwrap();
    bad(
        &[&p("SBEND.SEQ"), "--cell", &p("cell.toml")],
        "/dev/windcell-none-r",
    );
    // A cell whose drive is not the one the job's steps were planned for (quarter steps for the
    // job's half steps), for the job and for its sequence checked against it.
    let cell800 = example_variant(
        d,
        "cell-sim.toml",
        "cell800.toml",
        &[("steps_per_rev = 400", "steps_per_rev = 800")],
    );
    let sbend = example("sbend.toml");
    for input in [
        vec![sbend.to_str().unwrap()],
        vec![&p("SBEND.SEQ"), "--job", sbend.to_str().unwrap()],
    ] {
        let mut args = input.clone();
        args.extend(["--cell", cell800.to_str().unwrap(), "--force"]);
        bad(&args, "800 steps/rev, 13:60 belt) is not the one");
    }
    // --resume with no journal.
    bad(
        &[&p("SBEND.SEQ"), "--resume", &p("none.journal")],
        "no such journal",
    );
    // A journal from another job, and one edited by hand.
    let j = d.join("other.journal");
    let mut w = cell::run::journal::Journal::create(&j).unwrap();
    w.append(serde_json::json!({"rec": "begin", "job": "0123456789abcdef", "mode": "fine"}))
        .unwrap();
    drop(w);
    bad(
        &[&p("SBEND.SEQ"), "--resume", j.to_str().unwrap()],
        "belongs to another job",
    );
    let text = std::fs::read_to_string(&j).unwrap();
    std::fs::write(&j, text.replace("fine", "fast")).unwrap();
    bad(
        &[&p("SBEND.SEQ"), "--resume", j.to_str().unwrap()],
        "other.journal:1:1: the record's chain does not match",
    );
}

#[test]
fn jog_moves_robot_and_mandrel_together_with_the_limit_checks() {
    let o = windcell(&["jog", "--pos", "900,0,800", "--steps", "200"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        String::from_utf8_lossy(&o.stdout),
        "robot at (900.00, 0.00, 800.00) mm; indexer counter 200 steps\n"
    );
    // Relative to the powered-up robot's home pose (900, 0, 800) mm.
    let o = windcell(&["jog", "--pos", "0,-50,-100", "--rel", "--pitch-deg", "30"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        String::from_utf8_lossy(&o.stdout).starts_with("robot at (900.00, -50.00, 700.00) mm"),
        "{}",
        String::from_utf8_lossy(&o.stdout)
    );
    for (args, expect) in [
        (vec!["jog", "--pos", "1700,0,500"], "out of the arm's reach"),
        (vec!["jog", "--pos", "900,0"], "--pos needs X,Y,Z"),
        (
            vec![
                "jog",
                "--pos",
                "900,0,800",
                "--steps",
                "10",
                "--max-rps",
                "20",
            ],
            "exceeds the translator limit",
        ),
    ] {
        let o = windcell(&args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(expect), "{args:?}: {}", stderr(&o));
    }
}

#[test]
fn a_port_another_windcell_holds_is_busy_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    plan_sbend(dir.path());
    let d = dir.path();
    let (robot, robot_pty) = common::serve_on_pty(&["sim-robot", "--pty"]);
    let (indexer, indexer_pty) = common::serve_on_pty(&["sim-indexer", "--pty"]);
    std::fs::write(
        d.join("cell.toml"),
        format!("[ports]\nrobot = \"{robot_pty}\"\nindexer = \"{indexer_pty}\"\n"),
    )
    .unwrap();
    // What a running `windcell run` holds on its ports (an exclusive advisory lock, flock).
    let held = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .open(&indexer_pty)
        .unwrap();
    held.try_lock().unwrap();
    let seq = d.join("SBEND.SEQ");
    let cell = d.join("cell.toml");
    let journal = d.join("SBEND.journal");
    bad(
        &[
            seq.to_str().unwrap(),
            "--mode",
            "discrete",
            "--force",
            "--cell",
            cell.to_str().unwrap(),
        ],
        &format!("{indexer_pty}: in use: another program"),
    );
    assert!(!journal.exists());
    drop(held);
    common::stop_cleanly(robot);
    common::stop_cleanly(indexer);
}

/// Simulated cell time of a finished batch, s (the summary line).
fn cell_time_s(o: &std::process::Output) -> f64 {
    let out = String::from_utf8_lossy(&o.stdout);
    let line = out
        .lines()
        .find(|l| l.starts_with("batch done:"))
        .unwrap_or_else(|| panic!("no summary: {out}\n{}", stderr(o)));
    let (_, rest) = line.split_once(", ").unwrap();
    rest.split_once(" s of").unwrap().0.parse().unwrap()
}

/// The sync lines reach the PC through the cell file's opto delay (App. D). With a slow chain
/// (0.5 s, the cell file allows up to 1 s) the in-position level the previous move left high is
/// still seen after the next move's telegram: the coordinator waits it out instead of taking it
/// for the move's end, and the fine run winds both paths. Each program then waits at least twice
/// for the delay (its lowered line, and its raised line at the end), so the run takes at least
/// 2 × 2 × 0.5 s longer than on the 20 µs cell.
#[test]
fn a_slow_opto_chain_is_waited_out() {
    let dir = tempfile::tempdir().unwrap();
    let slow = example_variant(
        dir.path(),
        "cell-sim.toml",
        "slow-opto.toml",
        &[("opto_delay_s = 20e-6", "opto_delay_s = 0.5")],
    );
    let times: Vec<f64> = [example("cell-sim.toml"), slow]
        .iter()
        .map(|cell| {
            let o = run(&[
                example("cylinder.toml").to_str().unwrap(),
                "--mode",
                "fine",
                "--cell",
                cell.to_str().unwrap(),
                "--journal",
                dir.path().join("run.journal").to_str().unwrap(),
            ]);
            assert!(o.status.success(), "{}", stderr(&o));
            cell_time_s(&o)
        })
        .collect();
    assert!(times[1] - times[0] >= 2.0, "{times:?}");
}

/// The simulated cell is built from the job's own arm: with the robot 1300 mm from the mandrel
/// and a forearm of 1000 mm the job plans and winds, where the IRB 6/2's own arm would need its
/// shoulder at 82°, beyond its 60° (`windcell plan` of the same job without the `[cell.robot]`
/// section says so).
#[test]
fn the_simulated_cell_runs_the_jobs_own_arm() {
    let dir = tempfile::tempdir().unwrap();
    let far = ("robot_distance_mm = 800.0", "robot_distance_mm = 1300.0");
    let short = example_variant(dir.path(), "cylinder.toml", "short.toml", &[far]);
    let o = windcell(&[
        "plan",
        short.to_str().unwrap(),
        "-o",
        dir.path().join("s").to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("shoulder"), "{}", stderr(&o));
    let long = example_variant(
        dir.path(),
        "cylinder.toml",
        "long.toml",
        &[
            far,
            (
                "[mandrel]",
                "[cell.robot]\nforearm_mm = 1000.0\n\n[mandrel]",
            ),
        ],
    );
    let o = windcell(&[
        "run",
        long.to_str().unwrap(),
        "--mode",
        "fine",
        "--journal",
        dir.path().join("run.journal").to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(String::from_utf8_lossy(&o.stdout).contains("batch done: 2 paths"));
}

/// A re-run never loses the batch's resume record: over a journal of an unfinished batch the
/// same command is refused before anything is sent (exit 2, one line naming the `--resume`
/// command), the journal byte for byte as it was; `--restart` keeps the old journal as
/// `NAME.journal.1` and winds the batch over; a finished journal may be replaced.
#[test]
fn a_rerun_over_an_unfinished_journal_changes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let journal = dir.path().join("SBEND.journal");
    let job = example("sbend.toml");
    // An unfinished batch: its begin record, the mandrel zeroed, path 1 under way.
    {
        let mut j = cell::run::journal::Journal::create(&journal).unwrap();
        j.append(serde_json::json!({"rec": "begin", "job": "x", "mode": "fine"}))
            .unwrap();
        j.append(serde_json::json!({"rec": "mandrel_zero", "counter_before": 0}))
            .unwrap();
        j.append(serde_json::json!({"rec": "item", "item": 0, "name": "SBEND_1"}))
            .unwrap();
    }
    let before = std::fs::read(&journal).unwrap();
    let args = [
        "run",
        job.to_str().unwrap(),
        "--journal",
        journal.to_str().unwrap(),
    ];
    let o = windcell(&args);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let err = stderr(&o);
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(err.contains("unfinished batch, 0 paths done"), "{err}");
    assert!(
        err.contains(&format!("--resume {}", journal.display())),
        "{err}"
    );
    assert!(
        o.stdout.is_empty(),
        "nothing wound: {}",
        String::from_utf8_lossy(&o.stdout)
    );
    assert_eq!(std::fs::read(&journal).unwrap(), before);
    // Starting over keeps the old record under a new name.
    let mut restart = args.to_vec();
    restart.push("--restart");
    let o = windcell(&restart);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        std::fs::read(dir.path().join("SBEND.journal.1")).unwrap(),
        before
    );
    let done = std::fs::read_to_string(&journal).unwrap();
    assert!(done.trim_end().ends_with('}') && done.contains("\"rec\":\"done\""));
    // A finished batch's journal is replaced by the next run.
    let o = windcell(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!dir.path().join("SBEND.journal.2").exists());
}

/// Program mode on serial ports without a sync port is refused before the journal is written
/// or a port opened (the ports named here do not exist: a refusal after opening them would say
/// so instead).
#[test]
fn program_mode_without_sync_lines_is_refused_before_anything() {
    let dir = tempfile::tempdir().unwrap();
    let cell_file = dir.path().join("cell.toml");
    std::fs::write(
        &cell_file,
        "[ports]\nrobot = \"/dev/windcell-no-robot\"\nindexer = \"/dev/windcell-no-indexer\"\n",
    )
    .unwrap();
    let journal = dir.path().join("run.journal");
    let o = windcell(&[
        "run",
        example("sbend.toml").to_str().unwrap(),
        "--mode",
        "fine",
        "--cell",
        cell_file.to_str().unwrap(),
        "--journal",
        journal.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(err.contains("fine mode needs the sync lines"), "{err}");
    assert!(!err.contains("windcell-no-robot"), "{err}");
    assert!(!journal.exists());
}

/// A sweep is planned, checked and wound as planned: `sweep` prints its collision check, and
/// `run --job` holds the sweep's files to the job's sweep of as many paths (four copies of the
/// cylinder's path at 0°, 90°, 180°, 270°), then winds every one; a sweep's file changed by
/// hand, or the sweep's sequence given another job, is refused before anything is sent.
#[test]
fn a_sweep_is_checked_and_wound_as_planned() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("cover");
    let job = example("cylinder.toml");
    let o = windcell(&[
        "sweep",
        job.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--paths",
        "4",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("check: clear over 4 paths, 200 segments"),
        "{text}"
    );
    // The four programs start a quarter turn apart (the .ROB header's sync angle).
    let sync_deg: Vec<f64> = (1..=4)
        .map(|k| {
            let rob = std::fs::read_to_string(out.join(format!("CYL_{k}.ROB"))).unwrap();
            rob.lines()
                .find_map(|l| l.strip_prefix("sync_mandrel_deg "))
                .unwrap()
                .parse()
                .unwrap()
        })
        .collect();
    // (The mandrel turns the path's start to the robot: its angle steps by minus a quarter.)
    for k in 1..4 {
        let step = (sync_deg[k] - sync_deg[k - 1]).rem_euclid(360.0);
        assert!((step - 270.0).abs() < 1e-3, "{sync_deg:?}");
    }
    let seq = out.join("CYL.SEQ");
    let journal = dir.path().join("cover.journal");
    let o = run(&[
        seq.to_str().unwrap(),
        "--job",
        job.to_str().unwrap(),
        "--json",
        "--journal",
        journal.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let done = String::from_utf8_lossy(&o.stdout)
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap())
        .rfind(|e| e["event"] == "done")
        .unwrap();
    assert_eq!(done["paths"].as_array().unwrap().len(), 4);
    // Another job's sweep: refused at the first file that is not its plan, nothing sent.
    let o = run(&[
        seq.to_str().unwrap(),
        "--job",
        example("sbend.toml").to_str().unwrap(),
        "--journal",
        dir.path().join("other.journal").to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(!dir.path().join("other.journal").exists());
    // A sweep file edited by hand: refused at its line.
    let rob = out.join("CYL_3.ROB");
    let edited = std::fs::read_to_string(&rob)
        .unwrap()
        .replacen("speed_pct=", "speed_pct=1", 1);
    std::fs::write(&rob, edited).unwrap();
    let o = run(&[
        seq.to_str().unwrap(),
        "--job",
        job.to_str().unwrap(),
        "--journal",
        dir.path().join("edited.journal").to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("CYL_3.ROB:"), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("differs from the plan"),
        "{}",
        stderr(&o)
    );
}
