//! `windcell check` on the shipped robot-cell examples: each analytic-mandrel job checks clear
//! (exit 0, one summary line), and `--json` lists every segment of every path.

use crate::common;

use common::{example, stderr, windcell};

#[test]
fn the_analytic_examples_check_clear() {
    for job in [
        "cylinder.toml",
        "offset-1r.toml",
        "offset-3r.toml",
        "tilted-2r.toml",
        "sbend.toml",
    ] {
        let out = windcell(&["check", example(job).to_str().unwrap()]);
        let stdout = String::from_utf8_lossy(&out.stdout);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(0), "{job}: {stdout}{stderr}");
        assert!(
            stdout.contains("check: clear over 2 paths, 100 segments"),
            "{job}: {stdout}"
        );
    }
}

#[test]
fn json_lists_every_segment_with_its_clearances() {
    let out = windcell(&["check", example("sbend.toml").to_str().unwrap(), "--json"]);
    assert_eq!(out.status.code(), Some(0));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let text = v.to_string();
    // 2 paths × 50 segments, each with an eye, a free-fibre and an arm clearance in mm.
    for key in ["eye", "fibre", "arm"] {
        assert!(text.contains(key), "{key} missing");
    }
    let segments = text.matches("\"segment\":").count();
    assert!(segments >= 100, "{segments} segment records");
}

/// The gate: a job whose eye mechanism (made 60 mm thick here) touches the mandrel is refused by
/// `windcell run` with exit code 3 before anything is sent, and `--force` winds it anyway.
#[test]
fn run_refuses_a_job_the_check_fails_unless_forced() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(example("cylinder.toml")).unwrap();
    let fat_eye = text.replacen("[mandrel]", "[cell.eye]\nradius_mm = 60.0\n\n[mandrel]", 1);
    assert_ne!(fat_eye, text);
    let job = dir.path().join("fat-eye.toml");
    std::fs::write(&job, fat_eye).unwrap();
    let job = job.to_str().unwrap();

    let check = windcell(&["check", job]);
    assert_eq!(check.status.code(), Some(3));

    let journal = dir.path().join("a.journal");
    let refused = windcell(&["run", job, "--journal", journal.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert_eq!(refused.status.code(), Some(3), "{stderr}");
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.contains("--force"), "{stderr}");
    assert!(!journal.exists(), "a refused run must not start a journal");

    let forced = windcell(&[
        "run",
        job,
        "--force",
        "--mode",
        "medium",
        "--journal",
        journal.to_str().unwrap(),
    ]);
    let stdout = String::from_utf8_lossy(&forced.stdout);
    assert_eq!(forced.status.code(), Some(0), "{stdout}");
    assert!(stdout.contains("batch done"), "{stdout}");
}

/// The gate of a sequence: the files must be the plan of `--job` line for line (exit 2 naming
/// the file and line otherwise, `--force` or not), then the job's check gates (exit 3 unless
/// `--force`, which the journal records); without the job there is nothing to check the
/// clearance against (exit 3 unless `--force`). Nothing is sent and no journal started on a
/// refusal.
#[test]
fn run_of_a_sequence_is_gated_by_the_plan_and_the_check_of_its_job() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let text = std::fs::read_to_string(example("cylinder.toml")).unwrap();
    let fat_eye = text.replacen("[mandrel]", "[cell.eye]\nradius_mm = 60.0\n\n[mandrel]", 1);
    let job = d.join("fat-eye.toml");
    std::fs::write(&job, fat_eye).unwrap();
    let out = d.join("out");
    let o = windcell(&["plan", job.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let seq = out.join("CYL.SEQ");
    let seq = seq.to_str().unwrap();
    let journal = d.join("j.journal");
    let jp = journal.to_str().unwrap();
    let refused = |args: &[&str], code: i32, expect: &str| {
        let mut all = vec!["run", seq, "--mode", "discrete", "--journal", jp];
        all.extend_from_slice(args);
        let o = windcell(&all);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(code), "{args:?}: {stderr}");
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
        assert!(stderr.contains(expect), "{args:?}: {stderr}");
        assert!(o.stdout.is_empty(), "{args:?}: something was run");
        assert!(!journal.exists(), "{args:?}: a journal was started");
    };
    // No job: no clearance check.
    refused(&[], 3, "no collision check without the job");
    // The job's check finds the eye in the mandrel.
    let job_arg = job.to_str().unwrap();
    refused(&["--job", job_arg], 3, "--force winds anyway");
    // Another job's plan: the sequence is not its plan (bad input, not overridable).
    let cylinder = example("cylinder.toml");
    let cylinder = cylinder.to_str().unwrap();
    let sbend = example("sbend.toml");
    refused(
        &["--job", sbend.to_str().unwrap(), "--force"],
        2,
        "CYL.SEQ:1:1: differs from the plan",
    );
    // A file edited by hand: its first differing line is named.
    let rob = out.join("CYL_1.ROB");
    let original = std::fs::read_to_string(&rob).unwrap();
    let lines: Vec<&str> = original.lines().collect();
    let k = lines
        .iter()
        .position(|l| l.starts_with("instr 7 "))
        .unwrap();
    let edited: String = lines
        .iter()
        .enumerate()
        .map(|(i, l)| {
            if i == k {
                l.replacen("speed_pct=", "speed_pct=1", 1) + "\n"
            } else {
                format!("{l}\n")
            }
        })
        .collect();
    std::fs::write(&rob, edited).unwrap();
    refused(
        &["--job", cylinder, "--force"],
        2,
        &format!("CYL_1.ROB:{}:1: differs from the plan", k + 1),
    );
    std::fs::write(&rob, original).unwrap();
    // Forced past the check: wound, and the journal says so.
    let o = windcell(&[
        "run",
        seq,
        "--mode",
        "discrete",
        "--journal",
        jp,
        "--job",
        job_arg,
        "--force",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let first = std::fs::read_to_string(&journal).unwrap();
    let begin: serde_json::Value = serde_json::from_str(first.lines().next().unwrap()).unwrap();
    assert_eq!(begin["force"], true);
}

/// `check --svg` draws Figure 5.9 as a document another reader accepts: Python's XML parser
/// reads it, and finds the two views with their mm axes (a tick at 0 mm), the rotation axis,
/// a legend entry per path, and the findings in red only where the check found some.
#[test]
fn check_svg_is_a_figure_with_axes_legend_and_findings() {
    let dir = tempfile::tempdir().unwrap();
    let reader = r##"
import sys, xml.etree.ElementTree as ET
ns = {"s": "http://www.w3.org/2000/svg"}
root = ET.parse(sys.argv[1]).getroot()
texts = [t.text or "" for t in root.iter("{http://www.w3.org/2000/svg}text")]
red = [e for e in root.iter() if e.get("stroke") == "#d62728"]
clips = root.findall(".//s:clipPath", ns)
axis = [e for e in root.iter() if e.get("stroke-dasharray") == "10 3 2 3"]
print(len(clips), len(red), len(axis), "0" in texts,
      sum("side view" in t for t in texts), "|".join(t for t in texts if t.startswith("eye path")))
"##;
    let read = |svg: &std::path::Path| -> String {
        let o = std::process::Command::new("python3")
            .args(["-c", reader, svg.to_str().unwrap()])
            .output()
            .expect("python3 runs");
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stdout).trim().to_string()
    };
    let hit = dir.path().join("hit.svg");
    let o = windcell(&[
        "check",
        example("arm-hits-frame.toml").to_str().unwrap(),
        "--svg",
        hit.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(3), "{}", stderr(&o));
    let seen = read(&hit);
    let fields: Vec<&str> = seen.splitn(6, ' ').collect();
    assert_eq!(fields[0], "2", "two clipped views: {seen}");
    assert!(
        fields[1].parse::<usize>().unwrap() > 2,
        "findings in red: {seen}"
    );
    // The rotation axis in the side view and the legend's sample of it.
    assert_eq!(fields[2], "2", "{seen}");
    assert_eq!(fields[3], "True", "a tick at 0 mm: {seen}");
    assert_eq!(fields[4], "1", "{seen}");
    assert_eq!(
        fields[5], "eye path, CYLFRAME_1|eye path, CYLFRAME_2",
        "{seen}"
    );
    // The drive frame (a box 40 × 600 × 334.7 mm in the cell frame, `examples/arm-hits-frame.toml`)
    // in both views: twelve edges each. The mandrel turns about the cell's vertical, so from
    // above the box keeps its shape: its four vertical edges are points and the rest are its
    // 40 mm and 600 mm sides, in the ratio 15 whatever the angle.
    let obstacle_reader = r##"
import sys, math, xml.etree.ElementTree as ET
S = "{http://www.w3.org/2000/svg}"
root = ET.parse(sys.argv[1]).getroot()
groups = [g for g in root.iter(S + "g") if (g.findtext(S + "title") or "") == "drive frame"]
print(len(groups), [len(g.findall(S + "line")) for g in groups])
top = groups[1].findall(S + "line")
lengths = sorted(math.hypot(float(l.get("x2")) - float(l.get("x1")), float(l.get("y2")) - float(l.get("y1"))) for l in top)
print(lengths[3] < 0.05, lengths[4] > 1, round(lengths[-1] / lengths[4], 2))
"##;
    let o = std::process::Command::new("python3")
        .args(["-c", obstacle_reader, hit.to_str().unwrap()])
        .output()
        .expect("python3 runs");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let seen = String::from_utf8_lossy(&o.stdout);
    let lines: Vec<&str> = seen.lines().collect();
    assert_eq!(lines[0], "2 [12, 12]", "{seen}");
    assert_eq!(lines[1], "True True 15.0", "{seen}");
    let clean = dir.path().join("clean.svg");
    let o = windcell(&[
        "check",
        example("sbend.toml").to_str().unwrap(),
        "--svg",
        clean.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let seen = read(&clean);
    let fields: Vec<&str> = seen.splitn(6, ' ').collect();
    // Only the legend's sample is red where nothing was found.
    assert_eq!(fields[1], "1", "{seen}");
    assert_eq!(fields[5], "eye path, SBEND_1|eye path, SBEND_2", "{seen}");
}

/// An output that is one of the command's inputs (the job, its mesh) is refused before anything
/// is read further or written: one line, exit 2, the input byte for byte as it was.
#[test]
fn an_output_that_is_an_input_is_refused_and_left_alone() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["sbend-mesh.toml", "sbend.stl"] {
        std::fs::copy(example(name), dir.path().join(name)).unwrap();
    }
    let job = dir.path().join("sbend-mesh.toml");
    let mesh = dir.path().join("sbend.stl");
    let before = [std::fs::read(&job).unwrap(), std::fs::read(&mesh).unwrap()];
    let job_s = job.to_str().unwrap();
    // The same files under other spellings.
    let mesh_alias = format!("{}/./sbend.stl", dir.path().display());
    let job_alias = format!(
        "{}/../{}/sbend-mesh.toml",
        dir.path().display(),
        dir.path().file_name().unwrap().to_str().unwrap()
    );
    for args in [
        vec!["check", job_s, "--svg", mesh_alias.as_str()],
        vec!["check", job_s, "--record", job_alias.as_str()],
        vec!["predict", job_s, "--svg", job_s],
        vec!["triasym", job_s, "-o", mesh_alias.as_str()],
    ] {
        let out = windcell(&args);
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert_eq!(err.lines().count(), 1, "{args:?}: {err}");
        assert!(err.contains("an input of this command"), "{args:?}: {err}");
    }
    assert_eq!(std::fs::read(&job).unwrap(), before[0]);
    assert_eq!(std::fs::read(&mesh).unwrap(), before[1]);
}
