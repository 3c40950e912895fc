//! `windcell post` and `windcell verify` on the S-bend mesh job wound by six-axis arms: every
//! format posts and verifies clean, the simulated run of the posted program lays the fibre where
//! `predict` says (within 0.05 mm), and a program edited as an operator might slip (a target moved
//! by 1 mm, a quaternion's sign, a wrong configuration, a missing move) is a finding naming the
//! file and the line of the move (exit 3). The lines are found here by reading the text, not by
//! windcell's reader.

use std::path::{Path, PathBuf};

use crate::common;

use common::{example, example_variant, stderr, windcell};

/// The S-bend mesh job on a UR10e beside the indexer (discrete movement: one sync point per
/// segment), the mandrel's axis horizontal at the UR's reach.
fn ur_sbend(dir: &Path) -> PathBuf {
    let mesh = format!("mesh = {:?}", example("sbend.stl").to_str().unwrap());
    example_variant(
        dir,
        "irb2600-positioner.toml",
        "ursbend.toml",
        &[
            ("mesh = \"sbend.stl\"", mesh.as_str()),
            ("name = \"IRB2600\"", "name = \"URSB\""),
            ("kind = \"opw\"", "kind = \"ur\""),
            ("model = \"irb2600-12/1.65\"", "model = \"ur10e\""),
            ("drive = \"robot\"", "drive = \"indexer\""),
            ("movement = \"fine\"", "movement = \"discrete\""),
            (
                "axis_origin_mm = [1000.0, -175.0, 700.0]",
                "axis_origin_mm = [750.0, -175.0, 500.0]",
            ),
        ],
    )
}

fn post(job: &Path, format: &str, out: &Path) {
    let o = windcell(&[
        "post",
        job.to_str().unwrap(),
        "--format",
        format,
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(0), "{format}: {}", stderr(&o));
}

fn verify(dir: &Path, job: &Path) -> (Option<i32>, String) {
    let o = windcell(&[
        "verify",
        dir.to_str().unwrap(),
        "--job",
        job.to_str().unwrap(),
    ]);
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stdout).into_owned() + &stderr(&o),
    )
}

/// `(simulated run, predict)` placement errors per path, from verify's report.
fn errors(report: &str) -> Vec<(f64, f64)> {
    report
        .lines()
        .filter(|l| l.contains("the simulated run: error"))
        .map(|l| {
            let number_after = |key: &str| -> f64 {
                let rest = &l[l.find(key).unwrap() + key.len()..];
                rest.split_whitespace().next().unwrap().parse().unwrap()
            };
            (
                number_after("the simulated run: error"),
                number_after("predict of the plan: error"),
            )
        })
        .collect()
}

/// The 1-based line of the first line of `text` containing `needle`.
fn line_of(text: &str, needle: &str) -> usize {
    text.lines()
        .position(|l| l.contains(needle))
        .unwrap_or_else(|| panic!("no line with {needle}"))
        + 1
}

#[test]
fn every_format_posts_and_verifies_clean_and_runs_as_predicted() {
    let dir = tempfile::tempdir().unwrap();
    let ur = ur_sbend(dir.path());
    let irb = example("irb2600-positioner.toml");
    for (format, job) in [
        ("rapid", &irb),
        ("krl", &irb),
        ("fanuc", &irb),
        ("urscript", &ur),
    ] {
        let out = dir.path().join(format);
        post(job, format, &out);
        let (code, report) = verify(&out, job);
        assert_eq!(code, Some(0), "{format}: {report}");
        assert!(report.contains("verify: clean"), "{format}: {report}");
        let e = errors(&report);
        assert_eq!(e.len(), 2, "{format}: {report}");
        for (run, predicted) in e {
            assert!((run - predicted).abs() <= 0.05, "{format}: {report}");
        }
    }
}

/// Each slip in its own copy of the posted RAPID programs; the finding names the file and the
/// line of the edited target's move.
#[test]
fn a_slipped_rapid_program_is_a_finding_at_its_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let job = example("irb2600-positioner.toml");
    let posted = dir.path().join("posted");
    post(&job, "rapid", &posted);
    let text = std::fs::read_to_string(posted.join("IRB2600_1.mod")).unwrap();
    let decl = text
        .lines()
        .find(|l| l.contains("robtarget pW10 :="))
        .unwrap()
        .to_string();
    let move_line = line_of(&text, "MoveL pW10,");
    // The declaration's fields: [[x,y,z],[q1,q2,q3,q4],[cf1,cf4,cf6,cfx],[eax…]].
    let inner = &decl[decl.find("[[").unwrap() + 2..];
    let xyz: Vec<&str> = inner[..inner.find(']').unwrap()].split(',').collect();
    let after_xyz = &inner[inner.find("],[").unwrap() + 3..];
    let quat: Vec<&str> = after_xyz[..after_xyz.find(']').unwrap()]
        .split(',')
        .collect();
    let after_quat = &after_xyz[after_xyz.find("],[").unwrap() + 3..];
    let conf: Vec<&str> = after_quat[..after_quat.find(']').unwrap()]
        .split(',')
        .collect();
    let x: f64 = xyz[0].parse().unwrap();
    let q2: f64 = quat[1].parse().unwrap();
    let cf1: i32 = conf[0].parse().unwrap();
    let slips: [(&str, String, &str); 4] = [
        (
            "moved 1 mm",
            decl.replacen(&format!("[[{}", xyz[0]), &format!("[[{:.3}", x + 1.0), 1),
            "mm and",
        ),
        (
            "quaternion sign",
            decl.replacen(
                &format!("{},{}", quat[0], quat[1]),
                &format!("{},{:.6}", quat[0], -q2),
                1,
            ),
            "mm and",
        ),
        (
            "configuration",
            decl.replacen(
                &format!("[{},{}", conf[0], conf[1]),
                &format!("[{},{}", cf1 + 1, conf[1]),
                1,
            ),
            "configuration",
        ),
        ("missing move", String::new(), "missing"),
    ];
    for (what, edited_decl, expect) in slips {
        let copy = dir.path().join(what.replace(' ', "-"));
        std::fs::create_dir_all(&copy).unwrap();
        for name in ["IRB2600_1.mod", "IRB2600_2.mod"] {
            std::fs::copy(posted.join(name), copy.join(name)).unwrap();
        }
        let edited = if what == "missing move" {
            let lines: Vec<&str> = text.lines().collect();
            lines
                .iter()
                .enumerate()
                .filter(|(i, _)| i + 1 != move_line)
                .map(|(_, l)| *l)
                .collect::<Vec<_>>()
                .join("\n")
                + "\n"
        } else {
            assert_ne!(edited_decl, decl, "{what}: the edit changed nothing");
            text.replace(&decl, &edited_decl)
        };
        std::fs::write(copy.join("IRB2600_1.mod"), &edited).unwrap();
        let (code, report) = verify(&copy, &job);
        assert_eq!(code, Some(3), "{what}: {report}");
        // The move to the next target moved up one line when a move was deleted.
        let at = format!("IRB2600_1.mod:{move_line}:");
        assert!(report.contains(&at), "{what}: no {at} in {report}");
        assert!(report.contains(expect), "{what}: {report}");
    }
}

#[test]
fn verify_refuses_what_it_cannot_read_in_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let job = example("irb2600-positioner.toml");
    // No folder.
    let (code, report) = verify(&dir.path().join("none"), &job);
    assert_eq!(code, Some(2), "{report}");
    // A syntax error: file, line and column.
    let posted = dir.path().join("krl");
    post(&job, "krl", &posted);
    let src = std::fs::read_to_string(posted.join("IRB2600_1.src")).unwrap();
    let line = line_of(&src, "LIN XP5");
    std::fs::write(
        posted.join("IRB2600_1.src"),
        src.replacen("LIN XP5", "LIN XP5 )(", 1),
    )
    .unwrap();
    let (code, report) = verify(&posted, &job);
    assert_eq!(code, Some(2), "{report}");
    assert_eq!(report.lines().count(), 1, "{report}");
    assert!(
        report.contains(&format!("IRB2600_1.src:{line}:")),
        "{report}"
    );
    // Programs of another job.
    let ur = dir.path().join("ur");
    post(&example("ur10e-cylinder.toml"), "urscript", &ur);
    let (code, report) = verify(&ur, &job);
    assert_eq!(code, Some(2), "{report}");
    assert!(report.contains("another job"), "{report}");
}
