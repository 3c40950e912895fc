//! FiberPath's own tools read windcell's Marlin programs: `fiberpath simulate` and `fiberpath
//! plot` on the program `windcell lathe plan --dialect marlin` writes for every `.wind` of
//! FiberPath 0.11's `examples/` and `conformance/valid/`, every X within [0, windLength] and no
//! word but X, A, B and F (`scripts/fiberpath-accepts.py`, which installs FiberPath from PyPI
//! into a cache as `scripts/fiberpath-compare.py` does). Skipped, saying so, only when PyPI
//! cannot be reached and FiberPath is not cached yet.

use std::path::Path;
use std::process::Command;

/// The script's exit code for "PyPI unreachable, FiberPath not cached".
const SKIPPED: i32 = 77;

#[test]
fn fiberpath_simulate_and_plot_accept_every_example_program() {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scripts/fiberpath-accepts.py");
    let out = Command::new("python3")
        .arg(&script)
        .args(["--windcell", env!("CARGO_BIN_EXE_windcell")])
        .output()
        .expect("python3 runs (the FiberPath check needs Python 3.10 or later)");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    if out.status.code() == Some(SKIPPED) {
        eprintln!("fiberpath_tools: {}", stderr.trim());
        return;
    }
    assert!(out.status.success(), "{stdout}\n{stderr}");
    // FiberPath 0.11's examples/ (10) and conformance/valid/ (7), and ours (2).
    assert!(
        stdout.contains("19 files: 19 accepted by fiberpath simulate and plot, 0 not"),
        "{stdout}"
    );
}
