//! The bad-input corpus (`tests/bad-input/cases.toml`): every case must exit 2 with one line on
//! standard error naming the place, print nothing, write nothing, and stay within the budget of
//! docs/ARCHITECTURE.md ("Limits"): 5 s and 500 MB. Each run is a child process under an
//! address-space and CPU-time limit (`ulimit` in `sh`), its peak resident memory read with
//! `getrusage` afterwards.

use crate::common;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

use common::limited::{BUDGET, BUDGET_BYTES, broken_rule, run_limited};

use serde::Deserialize;

#[derive(Debug, Deserialize)]
struct Corpus {
    case: Vec<Case>,
}

#[derive(Debug, Deserialize)]
struct Case {
    class: String,
    args: Vec<String>,
    expect: String,
    #[serde(default)]
    setup: Vec<String>,
    /// Text files written into `{tmp}` before the run (placeholders replaced in their text).
    #[serde(default)]
    files: BTreeMap<String, String>,
}

fn corpus_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/bad-input")
}

/// Every file and folder under `dir` with its contents (folders: `None`).
fn snapshot(dir: &Path) -> BTreeMap<PathBuf, Option<Vec<u8>>> {
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).unwrap() {
            let entry = entry.unwrap();
            let path = entry.path();
            let kind = entry.file_type().unwrap();
            if kind.is_dir() {
                stack.push(path.clone());
                out.insert(path, None);
            } else if kind.is_file() {
                out.insert(path.clone(), Some(std::fs::read(&path).unwrap()));
            } else {
                out.insert(path, Some(b"(special)".to_vec()));
            }
        }
    }
    out
}

fn set_up(tmp: &Path, steps: &[String]) {
    for step in steps {
        let (kind, path) = step.split_once(' ').expect("setup: KIND PATH");
        let path = tmp.join(path);
        match kind {
            "dir" => std::fs::create_dir_all(&path).unwrap(),
            "file" => std::fs::write(&path, "earlier\n").unwrap(),
            "fifo" => assert!(
                Command::new("mkfifo")
                    .arg(&path)
                    .status()
                    .unwrap()
                    .success()
            ),
            other => panic!("unknown setup step {other}"),
        }
    }
}

/// `{corpus}`, `{out}` and `{tmp}` replaced.
fn placed(text: &str, dir: &Path, tmp: &Path) -> String {
    text.replace("{corpus}", dir.to_str().unwrap())
        .replace("{out}", tmp.join("out").to_str().unwrap())
        .replace("{tmp}", tmp.to_str().unwrap())
}

/// Runs every case of `file` (under the corpus folder) by the rules; returns the broken ones
/// and the classes seen.
fn run_cases(file: &str) -> (Vec<String>, std::collections::BTreeSet<String>, usize) {
    let dir = corpus_dir();
    let corpus: Corpus = toml::from_str(&std::fs::read_to_string(dir.join(file)).unwrap()).unwrap();
    let mut failures = Vec::new();
    let mut classes = std::collections::BTreeSet::new();
    for case in &corpus.case {
        classes.insert(case.class.clone());
        let tmp = tempfile::tempdir().unwrap();
        set_up(tmp.path(), &case.setup);
        for (name, text) in &case.files {
            std::fs::write(tmp.path().join(name), placed(text, &dir, tmp.path())).unwrap();
        }
        let args: Vec<String> = case
            .args
            .iter()
            .map(|a| placed(a, &dir, tmp.path()))
            .collect();
        let before = snapshot(tmp.path());
        // The inputs: the group's own files and the shipped examples.
        let inputs = [
            dir.join(file).parent().unwrap().to_path_buf(),
            dir.join("../../examples"),
        ];
        let corpus_before: Vec<_> = inputs.iter().map(|d| snapshot(d)).collect();
        let (output, elapsed, peak) = run_limited(&args, &dir);
        let mut broken = broken_rule(
            &output,
            elapsed,
            peak,
            &placed(&case.expect, &dir, tmp.path()),
        );
        if broken.is_none() && snapshot(tmp.path()) != before {
            broken = Some("the output folder changed".into());
        }
        if broken.is_none()
            && inputs.iter().map(|d| snapshot(d)).collect::<Vec<_>>() != corpus_before
        {
            broken = Some("the corpus folder (the inputs) changed".into());
        }
        if let Some(rule) = broken {
            failures.push(format!(
                "[{}] windcell {}: {rule}\n    stderr: {}",
                case.class,
                case.args.join(" "),
                String::from_utf8_lossy(&output.stderr).trim_end()
            ));
        }
    }
    (failures, classes, corpus.case.len())
}

/// The corpus over every command (`tests/bad-input/<group>/cases.toml`, docs/testing.md, "Bad
/// input"): each group at least `least` cases, every case by the rules, and the group within
/// its share of the corpus's 20 s.
fn group_fails_cleanly(group: &str, least: usize) {
    let started = std::time::Instant::now();
    let (failures, classes, count) = run_cases(&format!("{group}/cases.toml"));
    assert!(count >= least, "{group}: {count} cases");
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    assert!(!classes.is_empty());
    let took = started.elapsed();
    assert!(
        took < std::time::Duration::from_secs(20),
        "{group}: {took:?}"
    );
}

#[test]
fn lathe_cases_fail_cleanly() {
    group_fails_cleanly("lathe", 200);
}

#[test]
fn run_cases_fail_cleanly() {
    group_fails_cleanly("run", 80);
}

#[test]
fn command_cases_fail_cleanly() {
    group_fails_cleanly("commands", 100);
}

#[test]
fn every_case_fails_cleanly_within_budget() {
    let dir = corpus_dir();
    let corpus: Corpus =
        toml::from_str(&std::fs::read_to_string(dir.join("cases.toml")).unwrap()).unwrap();
    assert!(corpus.case.len() >= 60, "{} cases", corpus.case.len());
    let mut failures = Vec::new();
    let mut classes = std::collections::BTreeSet::new();
    for case in &corpus.case {
        classes.insert(case.class.split(' ').next().unwrap_or_default().to_string());
        let tmp = tempfile::tempdir().unwrap();
        set_up(tmp.path(), &case.setup);
        let args: Vec<String> = case
            .args
            .iter()
            .map(|a| {
                a.replace("{corpus}", dir.to_str().unwrap())
                    .replace("{out}", tmp.path().join("out").to_str().unwrap())
                    .replace("{tmp}", tmp.path().to_str().unwrap())
            })
            .collect();
        let before = snapshot(tmp.path());
        let (output, elapsed, peak) = run_limited(&args, &dir);
        let mut broken = broken_rule(&output, elapsed, peak, &case.expect);
        if broken.is_none() && snapshot(tmp.path()) != before {
            broken = Some("the output folder changed".into());
        }
        if let Some(rule) = broken {
            failures.push(format!(
                "[{}] windcell {}: {rule}\n    stderr: {}",
                case.class,
                case.args.join(" "),
                String::from_utf8_lossy(&output.stderr).trim_end()
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    // One or more cases of each class 1–8 of docs/testing.md ("Bad input").
    let expected: std::collections::BTreeSet<String> = (1..=8).map(|k| k.to_string()).collect();
    assert_eq!(classes, expected);
    assert!(corpus_dir().join("cases.toml").exists());
}

#[test]
fn the_rules_catch_what_they_name() {
    // The checker itself: a good run passes, each kind of bad run is caught.
    let (ok, t, peak) = run_limited(
        &["plan".into(), "/dev/zero".into(), "-o".into(), "x".into()],
        Path::new("."),
    );
    assert_eq!(
        broken_rule(&ok, t, peak, "/dev/zero: is a character device"),
        None
    );
    assert!(broken_rule(&ok, t, peak, "another message").is_some());
    assert!(broken_rule(&ok, BUDGET * 2, peak, "/dev/zero").is_some());
    assert!(broken_rule(&ok, t, BUDGET_BYTES + 1, "/dev/zero").is_some());
    let (good, t, peak) = run_limited(&["--version".into()], Path::new("."));
    assert!(broken_rule(&good, t, peak, "").is_some());
}

#[test]
fn a_binary_stl_over_the_triangle_limit_is_refused_at_its_count() {
    // One triangle over the limit: the header's count is checked before the triangles are read.
    // The file is sparse (its records are zeros that are never read), so the test writes 84 bytes.
    let tmp = tempfile::tempdir().unwrap();
    let count = paths::limits::MAX_TRIANGLES as u32 + 1;
    let mut header = vec![b' '; 80];
    header.extend_from_slice(&count.to_le_bytes());
    let file = std::fs::File::create(tmp.path().join("big.stl")).unwrap();
    std::io::Write::write_all(&mut &file, &header).unwrap();
    file.set_len(84 + 50 * u64::from(count)).unwrap();
    let args: Vec<String> = ["geodesic", "big.stl", "--start", "0,0,0", "--heading", "0"]
        .iter()
        .map(ToString::to_string)
        .collect();
    let (output, elapsed, peak) = run_limited(&args, tmp.path());
    let expect = format!(
        "big.stl: byte 80: triangle count = {count} exceeds the limit of {}",
        paths::limits::MAX_TRIANGLES
    );
    assert_eq!(
        broken_rule(&output, elapsed, peak, &expect),
        None,
        "{output:?}"
    );
}
