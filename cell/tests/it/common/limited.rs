//! Running `windcell` within the bad-input budget of docs/ARCHITECTURE.md ("Limits"): a child
//! process under an address-space and CPU-time limit (`ulimit` in `sh`, so no unsafe code), its
//! wall time measured and its peak resident memory read with `getrusage` afterwards.

use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

/// Wall-clock budget of one run.
pub const BUDGET: Duration = Duration::from_secs(5);
/// Memory budget of one run, bytes.
pub const BUDGET_BYTES: u64 = 500 << 20;

/// Runs `windcell args` in `cwd` under the memory and CPU limits; returns its output, wall time
/// and the largest peak resident set of any child so far, bytes.
pub fn run_limited(args: &[String], cwd: &Path) -> (Output, Duration, u64) {
    let limit_kib = 2 * BUDGET_BYTES / 1024;
    let script = format!("ulimit -v {limit_kib} && ulimit -t 10 && exec \"$0\" \"$@\"");
    let started = Instant::now();
    let mut child = Command::new("sh")
        .arg("-c")
        .arg(script)
        .arg(env!("CARGO_BIN_EXE_windcell"))
        .args(args)
        .current_dir(cwd)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("sh runs");
    // A hard stop well past the budget, so that a runaway case fails instead of hanging.
    loop {
        if child.try_wait().unwrap().is_some() || started.elapsed() > 4 * BUDGET {
            break;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    let _ = child.kill();
    let output = child.wait_with_output().unwrap();
    let elapsed = started.elapsed();
    let usage = nix::sys::resource::getrusage(nix::sys::resource::UsageWho::RUSAGE_CHILDREN)
        .expect("getrusage");
    // Linux reports ru_maxrss in KiB.
    let peak = u64::try_from(usage.max_rss()).unwrap_or(0) * 1024;
    (output, elapsed, peak)
}

/// Checks one finished run against the rules; `None` when it keeps them.
pub fn broken_rule(output: &Output, elapsed: Duration, peak: u64, expect: &str) -> Option<String> {
    let stderr = String::from_utf8_lossy(&output.stderr);
    let lines: Vec<&str> = stderr.lines().collect();
    if output.status.code() != Some(2) {
        Some(format!("exit {:?}, not 2", output.status.code()))
    } else if lines.len() != 1 {
        Some(format!("{} lines on standard error", lines.len()))
    } else if !lines[0].starts_with("windcell: ") {
        Some("the line does not start with `windcell: `".into())
    } else if !lines[0].contains(expect) {
        Some(format!("the line lacks `{expect}`"))
    } else if lines[0].contains(".windcell-") || lines[0].contains("panicked") {
        Some("the line names a staging path or a panic".into())
    } else if !output.stdout.is_empty() {
        Some("something was printed on standard output".into())
    } else if elapsed > BUDGET {
        Some(format!("took {elapsed:?}"))
    } else if peak > BUDGET_BYTES {
        Some(format!("peak memory {} MB", peak >> 20))
    } else {
        None
    }
}
