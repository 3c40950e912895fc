//! What an operator's day does to a run's records and ports: a file-size limit mid-batch (the
//! journal's writes are whole records or nothing), a second `windcell` on a port the first holds
//! (an advisory lock that dies with its process).

use crate::common;

use std::path::Path;
use std::process::Command;
use std::sync::{Mutex, MutexGuard};
use std::time::{Duration, Instant};

use cell::run::journal;
use common::{example, stderr, windcell};

use crate::run_pty::{
    PtyCell, completed_targets, log_records, pty_cell, start_run, wait_for_segments,
};

/// The pty tests of this file one at a time: each runs two simulators and up to two `windcell`
/// processes in real time, and on a loaded two-core machine several at once starve the
/// simulators past the indexer's 500 ms reply timeout.
static PTY_CELLS: Mutex<()> = Mutex::new(());

fn one_pty_cell_at_a_time() -> MutexGuard<'static, ()> {
    PTY_CELLS.lock().unwrap_or_else(|e| e.into_inner())
}

/// `windcell run ARGS` under a file-size limit of `kib` KiB (bash's `ulimit -f`, 1024-byte
/// blocks).
fn windcell_limited(kib: u64, args: &[&str]) -> std::process::Output {
    let mut line = format!("ulimit -f {kib}; exec \"$0\"");
    for (k, _) in args.iter().enumerate() {
        line += &format!(" \"${}\"", k + 1);
    }
    Command::new("bash")
        .arg("-c")
        .arg(line)
        .arg(env!("CARGO_BIN_EXE_windcell"))
        .args(args)
        .output()
        .expect("bash runs")
}

/// The (item, segment) of every segment record of a journal, in order.
fn segments(records: &[serde_json::Map<String, serde_json::Value>]) -> Vec<(u64, u64)> {
    records
        .iter()
        .filter(|r| journal::kind(r) == Some("segment"))
        .map(|r| (r["item"].as_u64().unwrap(), r["segment"].as_u64().unwrap()))
        .collect()
}

/// The S-bend in discrete mode journals a record per segment, 102 of them, about 200 bytes
/// each: with a file-size limit of 8 KiB the journal's write fails mid-batch. The process is not
/// killed by SIGXFSZ: the write comes back as EFBIG, the journal is cut back to its last whole
/// record, both devices are told to stop and one line says so with the resume command; the
/// resume (without the limit) finishes the batch, every segment journaled once.
#[test]
fn a_file_size_limit_ends_in_a_clean_stop_and_a_resumable_journal() {
    const LIMIT_KIB: u64 = 8;
    let dir = tempfile::tempdir().unwrap();
    let jp = dir.path().join("SBEND.journal");
    let job = example("sbend.toml");
    let args = [
        "run",
        job.to_str().unwrap(),
        "--mode",
        "discrete",
        "--journal",
        jp.to_str().unwrap(),
    ];
    let o = windcell_limited(LIMIT_KIB, &args);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(
        err.contains("File too large")
            && err.contains("both axes told to stop")
            && err.contains("--resume"),
        "{err}"
    );
    // Whole records only: every line a record whose chain holds, within the limit.
    let text = std::fs::read_to_string(&jp).unwrap();
    assert!(text.ends_with('\n'));
    assert!(text.len() as u64 <= LIMIT_KIB * 1024, "{}", text.len());
    let before = journal::read(&jp).unwrap();
    let first = segments(&before);
    assert!(!first.is_empty() && first.len() < 102, "{}", first.len());
    // The resume the line names, without the limit.
    let mut resume = args.to_vec();
    resume.truncate(4);
    let jp_s = jp.to_str().unwrap();
    resume.extend(["--resume", jp_s]);
    let o = windcell(&resume);
    assert!(o.status.success(), "{}", stderr(&o));
    let after = journal::read(&jp).unwrap();
    assert_eq!(journal::kind(after.last().unwrap()), Some("done"));
    let want: Vec<(u64, u64)> = (0..2).flat_map(|i| (1..=51).map(move |s| (i, s))).collect();
    assert_eq!(segments(&after), want);
}

/// The robot targets of the cut cylinder plan in `d` (both paths, in order), from its .ROB files.
fn plan_targets(d: &Path) -> Vec<Vec<f64>> {
    let mut targets = Vec::new();
    for k in 1..=2 {
        for l in std::fs::read_to_string(d.join(format!("CYL_{k}.ROB")))
            .unwrap()
            .lines()
            .filter(|l| l.starts_with("instr "))
        {
            let v = l
                .split(' ')
                .find_map(|w| w.strip_prefix("pos_mm="))
                .unwrap();
            targets.push(v.split(',').map(|x| x.parse::<f64>().unwrap()).collect());
        }
    }
    targets
}

/// Each path's mandrel steps per instruction, from its .ROB file.
fn plan_steps(d: &Path) -> Vec<Vec<i64>> {
    (1..=2)
        .map(|k| {
            std::fs::read_to_string(d.join(format!("CYL_{k}.ROB")))
                .unwrap()
                .lines()
                .filter(|l| l.starts_with("instr "))
                .map(|l| {
                    l.split(' ')
                        .find_map(|w| w.strip_prefix("steps="))
                        .unwrap()
                        .parse::<i64>()
                        .unwrap()
                })
                .collect()
        })
        .collect()
}

/// What one kill trial saw.
#[derive(Debug)]
struct Trial {
    /// How the interrupted run ended: its exit code (`None`: killed by a signal).
    interrupted_exit: Option<i32>,
    /// Both simulators received a stop command (a robot STOP telegram, an indexer `S`) after
    /// the signal was sent.
    both_stopped: bool,
    /// The resume completed the batch (exit 0, journal done).
    completed: bool,
    /// The mandrel's travel (steps without sign, every move the indexer simulator logged)
    /// against the plan's.
    travel: (i64, i64),
    /// A move against the winding direction of its path (after that path's sync).
    reversed: bool,
    /// Robot targets completed, against the plan's.
    targets_once_in_order: bool,
}

impl Trial {
    /// The batch finished on the resume, every target once and in order, the plan's travel, no
    /// reversal.
    fn resumed_cleanly(&self) -> bool {
        self.completed
            && self.travel.0 == self.travel.1
            && !self.reversed
            && self.targets_once_in_order
    }
}

/// The arguments of `windcell run` resuming the batch of `d` (or starting it over when the
/// journal holds no record: a kill before the first record leaves nothing to resume).
fn resume_args(d: &Path) -> Vec<String> {
    let jp = d.join("CYL.journal");
    let seq = d.join("CYL.SEQ");
    let cellfile = d.join("cell.toml");
    let mut args = vec![
        "run".to_string(),
        seq.display().to_string(),
        "--mode".into(),
        "discrete".into(),
        "--cell".into(),
        cellfile.display().to_string(),
        "--force".into(),
    ];
    let resumable = journal::read(&jp).is_ok_and(|r| !r.is_empty());
    if resumable {
        args.extend(["--resume".into(), jp.display().to_string()]);
    } else {
        args.push("--restart".into());
    }
    args
}

/// Sends `signal` to `child`.
fn signal(child: &std::process::Child, signal: nix::sys::signal::Signal) {
    nix::sys::signal::kill(nix::unistd::Pid::from_raw(child.id() as i32), signal).unwrap();
}

/// The first stop each simulator of `cell` received at or after `t0` (Unix s): a STOP telegram
/// at the robot, an `S` at the indexer (`cell::sim::wiretap`).
fn stops_after(robot_log: &Path, indexer_log: &Path, t0: f64) -> (Option<f64>, Option<f64>) {
    let first = |p: &Path| {
        log_records(p)
            .iter()
            .filter(|r| r["stop_received"] == true)
            .filter_map(|r| r["unix_s"].as_f64())
            .find(|t| *t >= t0)
    };
    (first(robot_log), first(indexer_log))
}

/// One trial: the cut cylinder's discrete batch over ptys, `sig` sent to `windcell run`
/// `kill_after` after it started, `--resume` `resume_after` after it exited. Expected values
/// come from the plan's control files: every robot target once and in order, the mandrel's
/// travel the two syncs (from the journal's sync records) plus every instruction's steps once.
fn interrupted_trial(
    sig: nix::sys::signal::Signal,
    kill_after: Duration,
    resume_after: Duration,
) -> Trial {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cell = pty_cell(d, 4);
    let child = start_run(d);
    std::thread::sleep(kill_after);
    let t0 = cell::sim::wiretap::unix_now_s();
    signal(&child, sig);
    let interrupted = child.wait_with_output().unwrap();
    if sig != nix::sys::signal::Signal::SIGKILL && interrupted.status.code() != Some(130) {
        eprintln!(
            "the interrupted run: {:?}: {}",
            interrupted.status,
            stderr(&interrupted)
        );
    }
    std::thread::sleep(resume_after);
    // The simulators' log threads have had at least 0.1 s to write the stops.
    let (r, i) = stops_after(&cell.robot_log, &cell.indexer_log, t0);
    let args = resume_args(d);
    let a: Vec<&str> = args.iter().map(String::as_str).collect();
    let o = windcell(&a);
    let PtyCell {
        robot,
        indexer,
        robot_log,
        indexer_log,
    } = cell;
    common::stop_cleanly(robot);
    common::stop_cleanly(indexer);
    if !o.status.success() {
        eprintln!("resume failed: {}", stderr(&o));
    }
    let mut t = judge(d, o.status.success(), &robot_log, &indexer_log);
    t.interrupted_exit = interrupted.status.code();
    t.both_stopped = r.is_some() && i.is_some();
    t
}

/// What the batch of `d` left once its last run ended (`succeeded`: exit 0): the journal, the
/// robot simulator's completed targets and the indexer simulator's moves, against the plan's
/// control files.
fn judge(d: &Path, succeeded: bool, robot_log: &Path, indexer_log: &Path) -> Trial {
    let jp = d.join("CYL.journal");
    let records = journal::read(&jp).unwrap_or_default();
    let completed = succeeded && records.last().and_then(journal::kind) == Some("done");
    let want = plan_targets(d);
    let done: Vec<Vec<f64>> = completed_targets(robot_log);
    let targets_once_in_order = done.len() == want.len()
        && done
            .iter()
            .zip(&want)
            .all(|(g, w)| g.iter().zip(w).all(|(a, b)| (a - b).abs() <= 0.05));
    // The syncs the journal aimed at (the last of each path: a sync journaled again by a
    // restart is the one wound).
    let mut syncs = [None, None];
    for r in &records {
        if journal::kind(r) == Some("sync") {
            let k = r["item"].as_u64().unwrap() as usize;
            syncs[k] = r["counter"].as_i64();
        }
    }
    let steps = plan_steps(d);
    let mut plan_travel = 0;
    let mut at = 0;
    for (k, s) in steps.iter().enumerate() {
        let sync = syncs[k].unwrap_or(at);
        plan_travel += (sync - at).abs() + s.iter().map(|x| x.abs()).sum::<i64>();
        at = sync + s.iter().sum::<i64>();
    }
    let moves: Vec<i64> = log_records(indexer_log)
        .iter()
        .filter_map(|r| r["steps"].as_i64())
        .collect();
    let travel: i64 = moves.iter().map(|s| s.abs()).sum();
    // Direction: each path is a sync (from where the mandrel stands to the journal's sync
    // counter) and then its winding (the sign of its segment steps). A stopped move and its
    // remainder are two moves of the same sign; a move of the other sign within either is a
    // reversal.
    let mut reversed = false;
    let mut pos = 0;
    let mut k = 0;
    let mut in_sync = true;
    let mut sync_at = syncs[0].unwrap_or(0);
    let mut sync_sign = sync_at.signum();
    for m in moves.iter().filter(|m| **m != 0) {
        if in_sync && pos == sync_at {
            in_sync = false;
        }
        let want = if in_sync {
            sync_sign
        } else {
            steps[k].iter().sum::<i64>().signum()
        };
        if m.signum() != want {
            reversed = true;
        }
        pos += m;
        if !in_sync && pos == sync_at + steps[k].iter().sum::<i64>() && k + 1 < steps.len() {
            k += 1;
            in_sync = true;
            sync_at = syncs[k].unwrap_or(pos);
            sync_sign = (sync_at - pos).signum();
        }
    }
    if reversed || travel != plan_travel {
        eprintln!("indexer moves {moves:?}; plan steps {steps:?}; syncs {syncs:?}");
    }
    Trial {
        interrupted_exit: None,
        both_stopped: false,
        completed,
        travel: (travel, plan_travel),
        reversed,
        targets_once_in_order,
    }
}

/// Kill moments spread over a run (seeded, reproducible): from the attach and homing to the
/// last segments, `n` of them.
fn kill_moments(n: usize, seed: u64) -> Vec<Duration> {
    seeded_moments(n, seed, 300, 4_000)
}

/// `n` moments between `from_ms` and `to_ms` from a linear congruential generator (Knuth's
/// MMIX constants) seeded with `seed`: the same seed gives the same moments.
fn seeded_moments(n: usize, seed: u64, from_ms: u64, to_ms: u64) -> Vec<Duration> {
    let mut x = seed;
    (0..n)
        .map(|_| {
            x = x
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            Duration::from_millis(from_ms + (x >> 33) % (to_ms - from_ms))
        })
        .collect()
}

/// `per_wait` trials for each resume delay (0.1 s, 0.5 s, 5 s) with `sig`, the moments from
/// `seed`. `WINDCELL_TRIAL=k` runs trial `k` alone (its moment and delay as in the full run),
/// to replay a failure.
fn interrupted_trials(sig: nix::sys::signal::Signal, per_wait: usize, seed: u64) {
    let _one = one_pty_cell_at_a_time();
    let waits = [
        Duration::from_millis(100),
        Duration::from_millis(500),
        Duration::from_secs(5),
    ];
    let only: Option<usize> = std::env::var("WINDCELL_TRIAL")
        .ok()
        .and_then(|v| v.parse().ok());
    let moments = kill_moments(per_wait * waits.len(), seed);
    let mut failed = Vec::new();
    let mut ran = 0;
    let t0 = Instant::now();
    for (i, kill_after) in moments.iter().enumerate() {
        if only.is_some_and(|k| k != i) {
            continue;
        }
        let wait = waits[i % waits.len()];
        let t = interrupted_trial(sig, *kill_after, wait);
        ran += 1;
        eprintln!("trial {i}: {sig} at {kill_after:?}, resume after {wait:?}: {t:?}");
        let stopped = sig == nix::sys::signal::Signal::SIGKILL
            || (t.interrupted_exit == Some(130) && t.both_stopped);
        if !(stopped && t.resumed_cleanly()) {
            failed.push((i, kill_after, wait, t));
        }
    }
    eprintln!(
        "{ran} {sig} trials (seed {seed}) in {:.0} s, {} failed",
        t0.elapsed().as_secs_f64(),
        failed.len()
    );
    assert!(failed.is_empty(), "{failed:#?}");
}

fn kill_trials(per_wait: usize, seed: u64) {
    interrupted_trials(nix::sys::signal::Signal::SIGKILL, per_wait, seed);
}

/// `kill -9` of `windcell run` at six moments of the batch over ptys, `--resume` 0.1 s, 0.5 s
/// and 5 s later (twice each): every resume completes the batch on its first try, every robot
/// target once and in order, the mandrel's travel the plan's and never against the winding
/// direction.
#[test]
fn kill_9_at_random_moments_then_resume_completes_without_turning_back() {
    kill_trials(2, 33);
}

/// The measurement: 20 kills for each resume delay (60 trials, several minutes).
/// `cargo test -p cell --test it -- --ignored --nocapture kill_9_sixty`
#[test]
#[ignore = "measurement: about 60 trials of real time"]
fn kill_9_sixty_trials_then_resume_completes_without_turning_back() {
    kill_trials(20, 2026);
}

/// The SIGINT measurement: 20 Ctrl-Cs for each resume delay (60 trials). Each
/// interrupted run stops both axes (each simulator logs its stop command after the signal) and
/// exits 130; each resume completes the batch as after `kill -9`.
/// `cargo test -p cell --test it -- --ignored --nocapture sigint_sixty`
#[test]
#[ignore = "measurement: about 60 trials of real time"]
fn sigint_sixty_trials_stop_both_axes_then_resume_completes_without_turning_back() {
    interrupted_trials(nix::sys::signal::Signal::SIGINT, 20, 2027);
}

/// The chain: `kill -9` of `windcell run` 0.3–3 s (seeded) after each start, the batch
/// resumed each time, `WINDCELL_KILLS` kills in a row (default 50), then the last resume runs
/// to its end. The batch is the cylinder cut to 50 instructions per path, long enough that it
/// is still under way at the last kill. It must finish, every robot target once and in order,
/// the mandrel's travel the plan's, no reversal.
/// `cargo test -p cell --test it -- --ignored --nocapture fifty_kills`
#[test]
#[ignore = "measurement: about 50 kills of real time"]
fn fifty_kills_in_a_row_still_end_in_a_finished_batch() {
    let _one = one_pty_cell_at_a_time();
    let kills: usize = std::env::var("WINDCELL_KILLS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(50);
    let seed: u64 = std::env::var("WINDCELL_SEED")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(5050);
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cell = pty_cell(d, 50);
    let t0 = Instant::now();
    let mut child = start_run(d);
    let mut killed = 0;
    let mut finished_early = None;
    for (k, after) in seeded_moments(kills, seed, 300, 3_000).iter().enumerate() {
        std::thread::sleep(*after);
        if let Some(status) = child.try_wait().unwrap() {
            // The run ended before its kill: the batch is done (or the run failed).
            let mut err = String::new();
            if let Some(mut e) = child.stderr.take() {
                let _ = std::io::Read::read_to_string(&mut e, &mut err);
            }
            eprintln!("start {k} ended by itself ({status:?}): {err}");
            finished_early = Some((k, status));
            break;
        }
        signal(&child, nix::sys::signal::Signal::SIGKILL);
        let _ = child.wait_with_output();
        killed += 1;
        let args = resume_args(d);
        child = Command::new(env!("CARGO_BIN_EXE_windcell"))
            .args(&args)
            .stdin(std::process::Stdio::null())
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
    }
    let succeeded = match finished_early {
        Some((_, status)) => status.success(),
        None => {
            let o = child.wait_with_output().unwrap();
            if !o.status.success() {
                eprintln!("the last resume failed: {}", stderr(&o));
            }
            o.status.success()
        }
    };
    let PtyCell {
        robot,
        indexer,
        robot_log,
        indexer_log,
    } = cell;
    common::stop_cleanly(robot);
    common::stop_cleanly(indexer);
    let t = judge(d, succeeded, &robot_log, &indexer_log);
    let resumes = journal::read(&d.join("CYL.journal"))
        .unwrap_or_default()
        .iter()
        .filter(|r| journal::kind(r) == Some("resume"))
        .count();
    eprintln!(
        "{killed} kills in a row (seed {seed}) in {:.0} s, {} targets: {t:?}, {resumes} resume records",
        t0.elapsed().as_secs_f64(),
        plan_targets(d).len()
    );
    assert!(t.resumed_cleanly(), "{t:?}");
    assert_eq!(killed, kills, "the batch ended before the last kill");
}

/// A simulated indexer killed mid-run (power loss) and started again on a new pty, its counter
/// at 0: the run that lost it stops; the resume on the new port stops before anything turns and
/// says in one line how to re-reference the mandrel.
#[test]
fn a_power_cycled_indexer_over_ptys_is_refused_with_the_rereference_line() {
    let _one = one_pty_cell_at_a_time();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cell = pty_cell(d, 4);
    let run = start_run(d);
    wait_for_segments(d, 2);
    let PtyCell {
        robot,
        mut indexer,
        robot_log,
        ..
    } = cell;
    indexer.kill().unwrap();
    let _ = indexer.wait();
    let o = run.wait_with_output().unwrap();
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    // Powered up again, on another pty.
    let log2 = d.join("indexer2.log");
    let (indexer, indexer_pty) =
        common::serve_on_pty(&["sim-indexer", "--pty", "--log", log2.to_str().unwrap()]);
    let robot_pty = std::fs::read_to_string(d.join("cell.toml"))
        .unwrap()
        .lines()
        .find_map(|l| {
            l.strip_prefix("robot = \"")
                .map(|r| r.trim_end_matches('"').to_string())
        })
        .unwrap();
    std::fs::write(
        d.join("cell.toml"),
        format!("[ports]\nrobot = \"{robot_pty}\"\nindexer = \"{indexer_pty}\"\n"),
    )
    .unwrap();
    let segments_before = journal::read(&d.join("CYL.journal"))
        .unwrap()
        .iter()
        .filter(|r| journal::kind(r) == Some("segment"))
        .count();
    let seq = d.join("CYL.SEQ");
    let cellfile = d.join("cell.toml");
    let jp = d.join("CYL.journal");
    let o = windcell(&[
        "run",
        seq.to_str().unwrap(),
        "--mode",
        "discrete",
        "--cell",
        cellfile.to_str().unwrap(),
        "--force",
        "--resume",
        jp.to_str().unwrap(),
    ]);
    common::stop_cleanly(robot);
    common::stop_cleanly(indexer);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(
        err.contains("re-reference the mandrel")
            && err.contains("the counter reads 0 steps")
            && err.contains("--rereference"),
        "{err}"
    );
    // Nothing turned on the indexer that came back, and no segment was journaled.
    assert!(
        log_records(&log2).iter().all(|r| r["steps"].is_null()),
        "{:?}",
        log_records(&log2)
    );
    let segments_after = journal::read(&jp)
        .unwrap()
        .iter()
        .filter(|r| journal::kind(r) == Some("segment"))
        .count();
    assert_eq!(segments_after, segments_before);
    let _ = robot_log;
}

/// A second `windcell run` on ports a running one holds gets one line naming the port and exit
/// code 2; once the first is killed with SIGKILL its advisory lock is gone with it (a flag left
/// on the device, TIOCEXCL, would refuse every later open but root's).
#[test]
fn a_port_lock_refuses_a_second_windcell_and_dies_with_the_first() {
    let _one = one_pty_cell_at_a_time();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cell = pty_cell(d, 4);
    let first = start_run(d);
    wait_for_segments(d, 1);
    let seq = d.join("CYL.SEQ");
    let cellfile = d.join("cell.toml");
    let other = d.join("other.journal");
    let o = windcell(&[
        "run",
        seq.to_str().unwrap(),
        "--mode",
        "discrete",
        "--cell",
        cellfile.to_str().unwrap(),
        "--force",
        "--journal",
        other.to_str().unwrap(),
    ]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(err.contains("in use: another program"), "{err}");
    assert!(!other.exists());
    nix::sys::signal::kill(
        nix::unistd::Pid::from_raw(first.id() as i32),
        nix::sys::signal::Signal::SIGKILL,
    )
    .unwrap();
    let _ = first.wait_with_output();
    // Both ports can be locked again at once.
    let text = std::fs::read_to_string(&cellfile).unwrap();
    for path in text.lines().filter_map(|l| l.split('"').nth(1)) {
        let f = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .open(path)
            .unwrap();
        f.try_lock().unwrap_or_else(|e| panic!("{path}: {e}"));
    }
    common::stop_cleanly(cell.robot);
    common::stop_cleanly(cell.indexer);
}
