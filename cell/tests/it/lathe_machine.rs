//! `windcell lathe plan --machine`: a program in the coordinates of the machine it is for. The
//! expected values come from the `.wind` file (X from 0 at the mandrel's start to `windLength`,
//! FiberPath's convention) and from the plan itself read through `paths` (the same moves, moved by
//! the origin and scaled by the units, nothing else).

use crate::common;

use std::path::Path;

use common::lathe::{lathe_plan, refused_in_one_line, tube};
use common::{example, stderr};
use paths::motion::Recording;

fn planned(job: &std::path::Path) -> Recording {
    let (job, _) = sequences::wind::WindFile::load(job).unwrap();
    let plan = job.check().unwrap();
    let mut rec = Recording::default();
    plan.emit(&mut rec).unwrap();
    rec
}

/// `windcell lathe plan JOB -o OUT --dialect DIALECT EXTRA… --json`: the run and, when it
/// succeeds, its summary.
fn plan(
    job: &Path,
    out: &Path,
    dialect: &str,
    extra: &[&str],
) -> (std::process::Output, serde_json::Value) {
    let mut extra = extra.to_vec();
    extra.push("--json");
    let out = lathe_plan(job, out, dialect, &extra);
    let summary = if out.status.success() {
        serde_json::from_slice(&out.stdout).unwrap()
    } else {
        serde_json::Value::Null
    };
    (out, summary)
}

/// Every word of every motion line: (letter, value).
fn motion_words(text: &str) -> Vec<Vec<(char, f64)>> {
    text.lines()
        .filter(|l| l.starts_with("G0") || l.starts_with("G1 ") || l.starts_with("G92"))
        .map(|l| {
            l.split_whitespace()
                .skip(1)
                .map(|w| (w.chars().next().unwrap(), w[1..].parse().unwrap()))
                .collect()
        })
        .collect()
}

#[test]
fn a_wind_job_in_marlin_is_written_for_fiberpaths_xab_machine() {
    let dir = tempfile::tempdir().unwrap();
    let job = tube();
    let out_dir = dir.path().join("out");
    let (out, summary) = plan(&job, &out_dir, "marlin", &[]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert_eq!(summary["machine"]["name"], "fiberpath-xab");
    let text = std::fs::read_to_string(out_dir.join("tube.gcode")).unwrap();
    // FiberPath's header, with the file's mandrel and tow.
    let header = text
        .lines()
        .find_map(|l| l.strip_prefix("; Parameters "))
        .expect("a Parameters header");
    let h: serde_json::Value = serde_json::from_str(header).unwrap();
    assert_eq!(h["mandrel"]["diameter"], 70.0);
    assert_eq!(h["mandrel"]["windLength"], 500.0);
    assert_eq!(h["tow"]["width"], 6.5);
    assert_eq!(h["tow"]["thickness"], 0.25);
    // Only the codes FiberPath's reader takes, and only X, A, B (and F) as words.
    for line in text.lines().filter(|l| !l.starts_with(';')) {
        let code = line.split_whitespace().next().unwrap();
        assert!(
            ["G0", "G1", "G21", "G90", "G92", "G94"].contains(&code),
            "{line}"
        );
    }
    let mut x_seen = (f64::INFINITY, f64::NEG_INFINITY);
    for words in motion_words(&text) {
        for (letter, v) in words {
            assert!("XABF".contains(letter), "word {letter}{v}");
            if letter == 'X' {
                x_seen = (x_seen.0.min(v), x_seen.1.max(v));
            }
        }
    }
    // X from 0 at the mandrel's start to windLength, both reached (passes end to end).
    assert_eq!(x_seen, (0.0, 500.0));
    // The same moves as the plan, the carriage moved by half the wound length.
    let planned = planned(&job);
    let mut x = f64::NAN;
    for words in motion_words(&text) {
        if let Some((_, v)) = words.iter().find(|(l, _)| *l == 'X') {
            x = *v;
        }
    }
    let last = planned.moves.last().unwrap().to;
    assert!(
        (x - (last.carriage_mm + 250.0)).abs() < 0.001,
        "{x} vs {last:?}"
    );
}

#[test]
fn the_written_frame_is_the_plan_moved_by_the_origin_and_scaled_by_the_units() {
    let dir = tempfile::tempdir().unwrap();
    let job = tube();
    let planned = planned(&job);
    let profile = dir.path().join("inch.toml");
    std::fs::write(
        &profile,
        "name = \"inch-winder\"\nunits = \"inch\"\norigin = \"mandrel-start\"\n\
         feed = \"inverse-time\"\n[axes.mandrel]\nletter = \"C\"\n[axes.carriage]\n\
         letter = \"U\"\n[axes.eye]\nletter = \"W\"\n",
    )
    .unwrap();
    let out_dir = dir.path().join("out");
    let (out, summary) = plan(
        &job,
        &out_dir,
        "linuxcnc",
        &["--machine", profile.to_str().unwrap()],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    assert_eq!(summary["machine"]["name"], "inch-winder");
    let text = std::fs::read_to_string(out_dir.join("tube.ngc")).unwrap();
    assert!(text.contains("G20 G90 G93"), "{}", &text[..200]);
    // Every written U is (carriage + 250 mm) / 25.4 of the planned move, to the written 0.001.
    let mut us = Vec::new();
    for line in text
        .lines()
        .filter(|l| l.starts_with("G1") || l.starts_with("G0"))
    {
        for w in line.split_whitespace() {
            assert!(!w.starts_with('X') && !w.starts_with('Y'), "{line}");
            if let Some(v) = w.strip_prefix('U') {
                us.push(v.parse::<f64>().unwrap());
            }
        }
    }
    let mut expected = Vec::new();
    let mut last = f64::NAN;
    for m in &planned.moves {
        let u = ((m.to.carriage_mm + 250.0) / 25.4 * 1000.0).round() / 1000.0;
        if u != last {
            expected.push(u);
            last = u;
        }
    }
    assert_eq!(us.len(), expected.len());
    for (a, b) in us.iter().zip(&expected) {
        assert!((a - b).abs() < 1e-9, "{a} vs {b}");
    }
    assert!(us.iter().all(|&u| (0.0..=500.0 / 25.4 + 1e-9).contains(&u)));
}

#[test]
fn bad_machines_are_refused_in_one_located_line_and_nothing_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let job = tube();
    let out_dir = dir.path().join("out");
    let refused = |machine: &str, expect: &str| {
        let (out, _) = plan(&job, &out_dir, "marlin", &["--machine", machine]);
        refused_in_one_line(&out, expect, &out_dir);
    };
    refused("haas", "--machine `haas`: neither a built-in");
    // Profiles `NAME.toml` holding the text (none: no such file).
    let cases = [
        // A travel shorter than the mandrel: refused at the profile's `max`.
        (
            "short",
            Some(
                "name = \"short\"\nfeed = \"linear-words\"\n[axes.mandrel]\nletter = \"A\"\n\
                 [axes.carriage]\nletter = \"X\"\nmin = 0\nmax = 400.0\n[axes.eye]\nletter = \"B\"\n",
            ),
            "short.toml:8:7: the plan moves X to 500 mm, beyond max = 400 mm",
        ),
        // A machine without the eye a .wind plan turns.
        (
            "noeye",
            Some(
                "name = \"noeye\"\nfeed = \"linear-words\"\n[axes.mandrel]\nletter = \"A\"\n\
                 [axes.carriage]\nletter = \"X\"\n",
            ),
            "machine `noeye` has no eye-rotation axis, and the plan moves it",
        ),
        // A malformed profile.
        ("bad", Some("name = \"bad\"\nfeed = 3\n"), "bad.toml:2:8:"),
        ("missing", None, "missing.toml"),
    ];
    for (name, text, expect) in cases {
        let path = dir.path().join(format!("{name}.toml"));
        if let Some(text) = text {
            std::fs::write(&path, text).unwrap();
        }
        refused(path.to_str().unwrap(), expect);
    }
}

#[test]
fn seed_000s_machine_keeps_part_zero_and_its_travel() {
    let dir = tempfile::tempdir().unwrap();
    let job = common::example_variant(
        dir.path(),
        "seed002-vessel.toml",
        "v3.toml",
        &[("axes = 4", "axes = 3")],
    );
    let out_dir = dir.path().join("out");
    let (out, summary) = plan(&job, &out_dir, "fw-cnc", &[]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert_eq!(summary["machine"]["name"], "fw-cnc");
    assert_eq!(summary["machine"]["carriage_offset_mm"], 0.0);
    // The vessel with cross-feed on FiberPath's machine: the cross-feed moves, refused.
    let (out, _) = plan(
        &example("seed002-vessel.toml"),
        &dir.path().join("o2"),
        "marlin",
        &["--machine", "fiberpath-xab"],
    );
    assert_eq!(out.status.code(), Some(2));
    assert!(
        stderr(&out).contains("has no cross-feed axis"),
        "{}",
        stderr(&out)
    );
}
