//! What the `windcell` command-line tests share: running the binary, the examples, and a
//! simulator served on a pseudo-terminal.

// Each test file uses its own part of this module.
#![allow(dead_code)]

pub mod lathe;
pub mod limited;

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};

/// Runs `windcell` with `args` to the end.
pub fn windcell(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_windcell"))
        .args(args)
        .output()
        .expect("windcell runs")
}

/// A file of `examples/`.
pub fn example(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../examples")
        .join(name)
}

/// A copy of `examples/NAME` written into `dir` as `new_name`, each `(from, to)` replaced (every
/// `from` must be in the example: a replacement that matches nothing fails the test).
pub fn example_variant(dir: &Path, name: &str, new_name: &str, edits: &[(&str, &str)]) -> PathBuf {
    variant(&example(name), dir, new_name, edits)
}

/// A copy of the file `source` written into `dir` as `new_name`, each `(from, to)` replaced
/// (every `from` must be in the file).
pub fn variant(source: &Path, dir: &Path, new_name: &str, edits: &[(&str, &str)]) -> PathBuf {
    let mut text = std::fs::read_to_string(source).expect("the file reads");
    for (from, to) in edits {
        assert!(text.contains(from), "{} has no `{from}`", source.display());
        text = text.replace(from, to);
    }
    let path = dir.join(new_name);
    std::fs::write(&path, text).expect("the variant writes");
    path
}

/// A `.wind` job of the format tests, `sequences/tests/data/NAME` (not in `examples/`, whose
/// `.wind` files FiberPath's own tools are run on).
pub fn wind_job(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../sequences/tests/data")
        .join(name)
}

/// Runs `windcell ARGS`, which must succeed, and reads its standard output as JSON.
pub fn windcell_json(args: &[&str]) -> serde_json::Value {
    let out = windcell(args);
    assert!(out.status.success(), "{args:?}: {}", stderr(&out));
    serde_json::from_slice(&out.stdout).unwrap()
}

/// The process's standard error as text.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Starts `windcell ARGS` (a `sim-… --pty` server) and returns it with the device path it prints
/// on its first line.
pub fn serve_on_pty(args: &[&str]) -> (Child, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_windcell"))
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn windcell");
    let stdout = child.stdout.take().expect("stdout");
    let mut path = String::new();
    BufReader::new(stdout)
        .read_line(&mut path)
        .expect("path line");
    let path = path.trim().to_string();
    assert!(path.starts_with("/dev/"), "{path:?}");
    (child, path)
}

/// Sends SIGTERM to a server from [`serve_on_pty`] and asserts that it exits with code 0.
pub fn stop_cleanly(child: Child) {
    let killed = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .expect("kill");
    assert!(killed.success());
    let out = child.wait_with_output().expect("wait");
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
}
