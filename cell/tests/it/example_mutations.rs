//! Property tests: the shipped examples with one value mutated (scaled by 1e6 or 1e-6, set to 0,
//! negated, NaN) or one line dropped, in the job or in the DXF drawing it names. Whatever the
//! mutation, `windcell plan` either succeeds or fails cleanly: exit 2, one line naming the job or
//! drawing with line and column, nothing written, within 5 s and 500 MB.

use crate::common;

use std::path::Path;

use common::limited::{broken_rule, run_limited};
use proptest::prelude::*;

const JOBS: [&str; 8] = [
    "cylinder.toml",
    "irb2600-positioner.toml",
    "ur10e-cylinder.toml",
    "offset-2r.toml",
    "tilted-1r.toml",
    "sbend.toml",
    "sbend-mesh.toml",
    "sbend-dxf.toml",
];

#[derive(Debug, Clone, Copy)]
enum Mutation {
    Scale(f64),
    Zero,
    Negate,
    NaN,
    Drop,
}

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        Just(Mutation::Scale(1e6)),
        Just(Mutation::Scale(1e-6)),
        Just(Mutation::Zero),
        Just(Mutation::Negate),
        Just(Mutation::NaN),
        Just(Mutation::Drop),
    ]
}

/// The numbers of `line` as byte ranges (a TOML value, a spine knot, a DXF value line).
fn numbers(line: &str) -> Vec<std::ops::Range<usize>> {
    let bytes = line.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < bytes.len() {
        let starts = bytes[i].is_ascii_digit()
            || (bytes[i] == b'-' && bytes.get(i + 1).is_some_and(u8::is_ascii_digit));
        let inside_word = i > 0 && (bytes[i - 1].is_ascii_alphanumeric() || bytes[i - 1] == b'_');
        if starts && !inside_word {
            let start = i;
            i += 1;
            while i < bytes.len() && (bytes[i].is_ascii_digit() || b".eE+-".contains(&bytes[i])) {
                i += 1;
            }
            if line[start..i].parse::<f64>().is_ok() {
                out.push(start..i);
            }
        } else {
            i += 1;
        }
    }
    out
}

/// `text` with the `pick`-th number (over the lines outside comments) mutated, or the line that
/// holds it dropped.
fn mutate(text: &str, pick: usize, m: Mutation) -> String {
    let lines: Vec<&str> = text.lines().collect();
    let places: Vec<(usize, std::ops::Range<usize>)> = lines
        .iter()
        .enumerate()
        .flat_map(|(k, l)| {
            let code = l.split('#').next().unwrap_or_default();
            numbers(code).into_iter().map(move |r| (k, r))
        })
        .collect();
    let (k, range) = places[pick % places.len()].clone();
    let mut out: Vec<String> = lines.iter().map(ToString::to_string).collect();
    let value: f64 = lines[k][range.clone()].parse().unwrap_or(0.0);
    let new = match m {
        Mutation::Scale(f) => format!("{:e}", value * f),
        Mutation::Zero => "0".to_string(),
        Mutation::Negate => format!("{}", -value),
        Mutation::NaN => "nan".to_string(),
        Mutation::Drop => String::new(),
    };
    if matches!(m, Mutation::Drop) {
        out.remove(k);
    } else {
        // An integer field (segments, program, steps) given a float is a type error: also fine.
        out[k].replace_range(range, &new);
    }
    out.join("\n") + "\n"
}

fn check(job: &str, pick: usize, m: Mutation, in_drawing: bool) -> Result<(), TestCaseError> {
    let examples = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples");
    let tmp = tempfile::tempdir().unwrap();
    std::os::unix::fs::symlink(examples.join("sbend.stl"), tmp.path().join("sbend.stl")).unwrap();
    let text = std::fs::read_to_string(examples.join(job)).unwrap();
    let drawing = std::fs::read_to_string(examples.join("sbend-path.dxf")).unwrap();
    let (text, drawing) = if in_drawing {
        (text, mutate(&drawing, pick, m))
    } else {
        (mutate(&text, pick, m), drawing)
    };
    std::fs::write(tmp.path().join("sbend-path.dxf"), drawing).unwrap();
    std::fs::write(tmp.path().join("job.toml"), &text).unwrap();
    let args: Vec<String> = ["plan", "job.toml", "-o", "out"]
        .iter()
        .map(ToString::to_string)
        .collect();
    let (output, elapsed, peak) = run_limited(&args, tmp.path());
    if output.status.code() == Some(0) {
        prop_assert!(tmp.path().join("out").is_dir());
        return Ok(());
    }
    let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
    let located = stderr.contains("job.toml:") || stderr.contains("sbend-path.dxf:");
    prop_assert!(
        broken_rule(&output, elapsed, peak, "").is_none() && located,
        "{job} number {pick} {m:?} (drawing: {in_drawing}): {:?} {elapsed:?} {stderr}",
        output.status.code()
    );
    let (line, column) = stderr
        .split(".toml:")
        .nth(1)
        .or_else(|| stderr.split(".dxf:").nth(1))
        .map(|rest| {
            let mut parts = rest.split(':');
            (parts.next(), parts.next())
        })
        .unwrap_or((None, None));
    prop_assert!(
        line.is_some_and(|l| l.parse::<usize>().is_ok())
            && column.is_some_and(|c| c.parse::<usize>().is_ok()),
        "no line and column: {stderr}"
    );
    prop_assert!(!tmp.path().join("out").exists(), "output written: {stderr}");
    Ok(())
}

/// The cell file `name` with its `pick`-th number mutated by `m`: read, or refused in one line
/// naming the file; never a panic; within a second.
fn check_cell_file(name: &str, pick: usize, m: Mutation) -> Result<(), TestCaseError> {
    let text = mutate(
        &std::fs::read_to_string(common::example(name)).unwrap(),
        pick,
        m,
    );
    let path = Path::new(name);
    let started = std::time::Instant::now();
    let read = std::panic::catch_unwind(|| cell::run::cellfile::Cell::parse(&text, path));
    prop_assert!(started.elapsed() < std::time::Duration::from_secs(1));
    match read {
        Ok(Ok(_)) => {}
        Ok(Err(e)) => {
            let line = e.to_string();
            prop_assert!(line.contains(name), "{line}");
            prop_assert_eq!(line.lines().count(), 1, "{}", line);
        }
        Err(_) => prop_assert!(false, "{name} panicked on {text:?}"),
    }
    Ok(())
}

/// Every mutation the property tests draw from.
const MUTATIONS: [Mutation; 6] = [
    Mutation::Scale(1e6),
    Mutation::Scale(1e-6),
    Mutation::Zero,
    Mutation::Negate,
    Mutation::NaN,
    Mutation::Drop,
];

/// The numbers outside comments in `text`.
fn count_numbers(text: &str) -> usize {
    text.lines()
        .map(|l| numbers(l.split('#').next().unwrap_or_default()).len())
        .sum()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn a_mutated_example_plans_or_fails_cleanly(
        job in 0..JOBS.len(),
        pick in 0usize..10_000,
        m in mutation(),
    ) {
        check(JOBS[job], pick, m, false)?;
    }

    #[test]
    fn a_mutated_drawing_plans_or_fails_cleanly(pick in 0usize..10_000, m in mutation()) {
        check("sbend-dxf.toml", pick, m, true)?;
    }

    /// The cell file's reader (`Cell::parse`) on the shipped cell files with one value mutated
    /// or one line dropped: read or refused in one line naming the file, never a panic, within
    /// a second.
    #[test]
    fn a_mutated_cell_file_reads_or_is_refused_cleanly(
        file in 0usize..2,
        pick in 0usize..10_000,
        m in mutation(),
    ) {
        check_cell_file(["cell-serial.toml", "cell-sim.toml"][file], pick, m)?;
    }
}

#[test]
fn mutations_change_what_they_say() {
    let text = "a = 2.5 # 7\nspine = [[1.0, -2e1]]\nname_2 = 3\n";
    assert_eq!(
        mutate(text, 0, Mutation::Scale(1e6)),
        "a = 2.5e6 # 7\nspine = [[1.0, -2e1]]\nname_2 = 3\n"
    );
    assert_eq!(
        mutate(text, 2, Mutation::Negate),
        "a = 2.5 # 7\nspine = [[1.0, 20]]\nname_2 = 3\n"
    );
    assert_eq!(
        mutate(text, 3, Mutation::NaN),
        "a = 2.5 # 7\nspine = [[1.0, -2e1]]\nname_2 = nan\n"
    );
    assert_eq!(mutate(text, 1, Mutation::Drop), "a = 2.5 # 7\nname_2 = 3\n");
    assert_eq!(
        mutate(text, 4, Mutation::Zero),
        "a = 0 # 7\nspine = [[1.0, -2e1]]\nname_2 = 3\n"
    );
}

/// Every number of the UR10e job (the arm's placement, tool, mandrel axis, drive and paths)
/// mutated every way, one at a time: each plans or fails cleanly (about 200 cases, no
/// sampling).
#[test]
fn every_number_of_the_six_axis_job_mutated_every_way_plans_or_fails_cleanly() {
    let text = std::fs::read_to_string(common::example("ur10e-cylinder.toml")).unwrap();
    let count = count_numbers(&text);
    assert!(count >= 30, "{count} numbers");
    let mut cases = 0;
    for pick in 0..count {
        for m in MUTATIONS {
            check("ur10e-cylinder.toml", pick, m, false)
                .unwrap_or_else(|e| panic!("number {pick}, {m:?}: {e}"));
            cases += 1;
        }
    }
    assert!(cases >= 180, "{cases} cases");
}

/// The cell files' whole mutation space, not a sample: each number of both shipped cell files
/// mutated each way (the reader is in-process and fast, so every case runs every time).
#[test]
fn every_number_of_the_shipped_cell_files_mutated_every_way_reads_or_is_refused_cleanly() {
    let mut cases = 0;
    for name in ["cell-serial.toml", "cell-sim.toml"] {
        let count = count_numbers(&std::fs::read_to_string(common::example(name)).unwrap());
        assert!(count >= 4, "{name}: {count} numbers");
        for pick in 0..count {
            for m in MUTATIONS {
                check_cell_file(name, pick, m)
                    .unwrap_or_else(|e| panic!("{name} number {pick}, {m:?}: {e}"));
                cases += 1;
            }
        }
    }
    assert!(cases >= 48, "{cases} cases");
}
