//! Every operator-file reader of `sequences`, fed mutations of a valid file: each mutated text is
//! read or refused, never a panic, and each read takes well under a second whatever the text
//! (no panic and bounded time for the `.wind`, vessel, part-program, machine-parameter, G-code
//! and control-file readers; the job file and DXF have their own in `cell`'s
//! `example_mutations`, the cell file in `cell`'s `cell_file_mutations`).
//!
//! The mutations are the shapes bad input takes in the corpus: a value replaced by an extreme
//! or malformed token, a line deleted or doubled, the text cut short, bytes inserted.

use std::path::Path;
use std::time::{Duration, Instant};

use proptest::prelude::*;
use sequences::gcode::Dialect;
use sequences::{MachineParameters, MandrelFile, PartProgram, RobotFile, RunFile, SequenceFile};

fn example(name: &str) -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../examples")
        .join(name);
    std::fs::read_to_string(path).expect("the example reads")
}

/// Tokens a careless or hostile file holds in place of a value.
const TOKENS: [&str; 18] = [
    "1e308",
    "-1e308",
    "1e-308",
    "NaN",
    "inf",
    "-0",
    "0",
    "99999999999999999999",
    "",
    "\n",
    "=",
    "[",
    "]",
    "\"",
    ",",
    "é",
    "\u{0}",
    "-",
];

#[derive(Debug, Clone)]
enum Edit {
    /// Replace `len` bytes at `at` (both taken modulo the text) with a token.
    Replace { at: usize, len: usize, token: usize },
    /// Delete the line at `line` (modulo the line count).
    DeleteLine { line: usize },
    /// Write the line at `line` twice.
    DoubleLine { line: usize },
    /// Keep only the first `keep` bytes (modulo the length).
    Cut { keep: usize },
}

fn edit() -> impl Strategy<Value = Edit> {
    prop_oneof![
        (any::<usize>(), 0usize..12, 0..TOKENS.len()).prop_map(|(at, len, token)| Edit::Replace {
            at,
            len,
            token
        }),
        any::<usize>().prop_map(|line| Edit::DeleteLine { line }),
        any::<usize>().prop_map(|line| Edit::DoubleLine { line }),
        any::<usize>().prop_map(|keep| Edit::Cut { keep }),
    ]
}

/// The text with the edits made, in order, at character boundaries.
fn mutate(text: &str, edits: &[Edit]) -> String {
    let mut t = text.to_string();
    for e in edits {
        let boundary = |t: &str, at: usize| -> usize {
            let mut at = if t.is_empty() { 0 } else { at % (t.len() + 1) };
            while !t.is_char_boundary(at) {
                at -= 1;
            }
            at
        };
        match *e {
            Edit::Replace { at, len, token } => {
                let a = boundary(&t, at);
                let b = boundary(&t, a.saturating_add(len).min(t.len()));
                t.replace_range(a..b.max(a), TOKENS[token]);
            }
            Edit::DeleteLine { line } | Edit::DoubleLine { line } => {
                let mut lines: Vec<&str> = t.lines().collect();
                if lines.is_empty() {
                    continue;
                }
                let k = line % lines.len();
                if matches!(e, Edit::DeleteLine { .. }) {
                    lines.remove(k);
                } else {
                    lines.insert(k, lines[k]);
                }
                t = lines.join("\n") + "\n";
            }
            Edit::Cut { keep } => {
                let k = boundary(&t, keep);
                t.truncate(k);
            }
        }
    }
    t
}

/// Reads `text` with `read`, which must return (never panic) within a second.
fn bounded(name: &str, text: &str, read: impl FnOnce(&str) -> bool) {
    let started = Instant::now();
    let _ = read(text);
    let took = started.elapsed();
    assert!(
        took < Duration::from_secs(1),
        "{name}: {took:?} for {text:?}"
    );
}

/// A robot control file as `windcell plan` writes one (seed 001 §5.6.1), three instructions.
const ROB: &str = "# windcell robot control file (seed 001 §5.6.1)\nrob 1\nprogram 1\n\
base_speed_mm_s 1000\nmax_speed_mm_s 2000\nmovement fine\nsync_mandrel_deg 2.041594\n\
instr 1 speed_pct=10 pos_mm=715.1518,25.4935,595.664 q=0.674464605,0.68160186,-0.18819911,0.212361712 move=rect ref=abs accel_rps2=1 start_rps=0.05 max_rps=0.1 steps=0\n\
instr 2 speed_pct=10 pos_mm=715.1,25.5,590.0 q=0.674464605,0.68160186,-0.18819911,0.212361712 move=rect ref=abs accel_rps2=1 start_rps=0.05 max_rps=0.1 steps=37\n\
instr 3 speed_pct=10 pos_mm=715.0,25.6,585.0 q=0.674464605,0.68160186,-0.18819911,0.212361712 move=rect ref=abs accel_rps2=1 start_rps=0.05 max_rps=0.1 steps=37\nend\n";

/// A mandrel control file (init, one move, reset), a sequence and a run file as `windcell plan`
/// writes them (seed 001 §5.6.2–5.6.3).
const IND: &str = "# windcell mandrel control file (seed 001 §5.6.2)\nind 1\ninit\n\
move accel_rps2=1 start_rps=0.05 max_rps=0.1 steps=74\nreset\n";
const SEQ: &str = "SBEND_1\nSBEND_2\n";
const RUN: &str = "1\n2\n";

/// A GRBL program of the kind `windcell lathe plan --dialect grbl` writes.
const GCODE: &str = "G21 G90 G94\nG0 X0 A0 B0\nG1 X100 A360 B45 F6000\nG1 X0 A720 B-45\nM2\n";

proptest! {
    #![proptest_config(ProptestConfig::with_cases(96))]

    #[test]
    fn mutated_operator_files_read_or_are_refused_in_bounded_time(
        edits in prop::collection::vec(edit(), 1..4)
    ) {
        let wind = example("helical-tube.wind");
        bounded("wind", &mutate(&wind, &edits), |t| {
            sequences::wind::WindFile::parse(t, "helical-tube").is_ok()
        });
        let vessel = example("seed002-vessel.toml");
        bounded("vessel", &mutate(&vessel, &edits), |t| {
            sequences::vessel::VesselFile::parse(t).is_ok()
        });
        let prg = example("cone-dome-cylinder.prg");
        bounded("part program", &mutate(&prg, &edits), |t| PartProgram::parse(t).is_ok());
        let par = example("FW-CNC.PAR");
        bounded("machine parameters", &mutate(&par, &edits), |t| {
            MachineParameters::parse(t).is_ok()
        });
        for dialect in [Dialect::Grbl, Dialect::LinuxCnc] {
            bounded("g-code", &mutate(GCODE, &edits), |t| {
                sequences::gcode::read(t, dialect).is_ok()
            });
        }
        bounded("rob", &mutate(ROB, &edits), |t| RobotFile::parse(t).is_ok());
        bounded("ind", &mutate(IND, &edits), |t| MandrelFile::parse(t).is_ok());
        bounded("seq", &mutate(SEQ, &edits), |t| SequenceFile::parse(t).is_ok());
        bounded("run", &mutate(RUN, &edits), |t| RunFile::parse(t).is_ok());
    }
}

/// The seeds are valid: the readers accept every unmutated file (so a mutation's refusal is the
/// mutation's).
#[test]
fn the_unmutated_files_read() {
    assert!(
        sequences::wind::WindFile::parse(&example("helical-tube.wind"), "helical-tube").is_ok()
    );
    assert!(sequences::vessel::VesselFile::parse(&example("seed002-vessel.toml")).is_ok());
    assert!(PartProgram::parse(&example("cone-dome-cylinder.prg")).is_ok());
    assert!(MachineParameters::parse(&example("FW-CNC.PAR")).is_ok());
    for dialect in [Dialect::Grbl, Dialect::LinuxCnc] {
        assert!(
            sequences::gcode::read(GCODE, dialect).is_ok(),
            "{dialect:?}"
        );
    }
    assert!(
        RobotFile::parse(ROB).is_ok(),
        "{:?}",
        RobotFile::parse(ROB).err()
    );
    assert!(
        MandrelFile::parse(IND).is_ok(),
        "{:?}",
        MandrelFile::parse(IND).err()
    );
    assert!(SequenceFile::parse(SEQ).is_ok());
    assert!(RunFile::parse(RUN).is_ok());
}
