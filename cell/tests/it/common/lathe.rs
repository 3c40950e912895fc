//! What the `windcell lathe plan` tests share: the tube job, a plan run, and the refusal every
//! bad input must give.

use std::path::{Path, PathBuf};
use std::process::Output;

use super::{stderr, wind_job, windcell};

/// `sequences/tests/data/tube.wind`: a 70 mm tube wound over 500 mm with a 6.5 mm band, a hoop
/// layer and a 45° helical layer of pattern 3 (⌈π·70·cos 45° / 6.5⌉ = 24 circuits).
pub fn tube() -> PathBuf {
    wind_job("tube.wind")
}

/// Runs `windcell lathe plan JOB -o OUT --dialect DIALECT EXTRA…`.
pub fn lathe_plan(job: &Path, out: &Path, dialect: &str, extra: &[&str]) -> Output {
    let mut args = vec![
        "lathe",
        "plan",
        job.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--dialect",
        dialect,
    ];
    args.extend_from_slice(extra);
    windcell(&args)
}

/// [`lathe_plan`] with `--json`, which must succeed: its summary.
pub fn lathe_plan_summary(
    job: &Path,
    out: &Path,
    dialect: &str,
    extra: &[&str],
) -> serde_json::Value {
    let mut extra = extra.to_vec();
    extra.push("--json");
    let o = lathe_plan(job, out, dialect, &extra);
    assert!(o.status.success(), "{dialect}: {}", stderr(&o));
    serde_json::from_slice(&o.stdout).unwrap()
}

/// A refusal as bad input: exit code 2, one line on standard error that contains `expect`, and
/// `out` not created. Returns the line.
pub fn refused_in_one_line(o: &Output, expect: &str, out: &Path) -> String {
    let err = stderr(o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains(expect), "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(!out.exists(), "{}", out.display());
    err
}
