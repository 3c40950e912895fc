//! `windcell plan` refuses what would be planned wrong: DXF paths with a coordinate that makes the
//! path absurdly long, non-finite coordinates, drawings in another unit than they say, paths off
//! the mandrel, and segment counts the robot cannot number or hold. Each refusal is one line
//! `FILE:LINE:COL: message` at the offending value, exit code 2, the output folder as it was,
//! within a second.

use crate::common;

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use common::{example, example_variant, stderr, windcell, windcell_json};

/// The S-bend DXF job and its drawing, copied into a scratch folder so that they can be edited.
struct Scratch {
    dir: tempfile::TempDir,
    job: String,
    drawing: String,
}

impl Scratch {
    fn new() -> Self {
        Scratch {
            dir: tempfile::tempdir().unwrap(),
            job: std::fs::read_to_string(example("sbend-dxf.toml")).unwrap(),
            drawing: std::fs::read_to_string(example("sbend-path.dxf")).unwrap(),
        }
    }

    /// Writes `drawing` as `NAME.dxf` and the job (naming it, with `job_edit` applied) as
    /// `NAME.toml`; returns the job's path.
    fn case(&self, name: &str, drawing: &str, job_edit: (&str, &str)) -> PathBuf {
        std::fs::write(self.dir.path().join(format!("{name}.dxf")), drawing).unwrap();
        let job = self
            .job
            .replace("sbend-path.dxf", &format!("{name}.dxf"))
            .replacen(job_edit.0, job_edit.1, 1);
        let path = self.dir.path().join(format!("{name}.toml"));
        std::fs::write(&path, job).unwrap();
        path
    }

    /// The drawing with every value of group codes `codes` mapped by `f`.
    fn drawing_with(&self, codes: &[&str], f: impl Fn(f64) -> f64) -> String {
        let lines: Vec<&str> = self.drawing.lines().collect();
        let mut out = Vec::with_capacity(lines.len());
        for (k, line) in lines.iter().enumerate() {
            if k % 2 == 1 && codes.contains(&lines[k - 1].trim()) {
                out.push(format!("{:?}", f(line.trim().parse::<f64>().unwrap())));
            } else {
                out.push(line.to_string());
            }
        }
        out.join("\n") + "\n"
    }

    /// The drawing with the first point's y value (line 14) replaced by `text`.
    fn first_y(&self, text: &str) -> String {
        let mut lines: Vec<String> = self.drawing.lines().map(String::from).collect();
        assert_eq!(
            lines[12].trim(),
            "20",
            "line 13 is the first POINT's y code"
        );
        lines[13] = text.to_string();
        lines.join("\n") + "\n"
    }
}

/// Runs `plan JOB -o OUT` into an output folder that already holds one file, and checks the
/// refusal: exit 2, one line starting with `expected_place`, containing `expected`, no panic,
/// the folder as it was, under a second.
fn refused(job: &Path, expected_place: &str, expected: &str) {
    let out = job.with_extension("out");
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(out.join("KEEP.txt"), "earlier work\n").unwrap();
    let started = Instant::now();
    let result = windcell(&["plan", job.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    let took = started.elapsed();
    let stderr = String::from_utf8_lossy(&result.stderr).into_owned();
    assert_eq!(result.status.code(), Some(2), "{stderr}");
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(
        stderr.starts_with(&format!("windcell: {expected_place}")),
        "{stderr} should start with {expected_place}"
    );
    assert!(
        stderr.contains(expected),
        "{stderr} should contain {expected}"
    );
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(result.stdout.is_empty());
    let left: Vec<_> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(left, vec!["KEEP.txt"], "{stderr}");
    assert_eq!(
        std::fs::read_to_string(out.join("KEEP.txt")).unwrap(),
        "earlier work\n"
    );
    assert!(took < Duration::from_secs(1), "{stderr}: took {took:?}");
}

/// Where the value of a job's `segments = …` stands, `LINE:COLUMN` (column 12, after
/// `segments = `).
fn segments_value_at(job_text: &str) -> String {
    let line = job_text
        .lines()
        .position(|l| l.starts_with("segments = "))
        .unwrap();
    format!("{}:12", line + 1)
}

fn place(dir: &Path, file: &str, line_column: &str) -> String {
    format!("{}:{line_column}:", dir.join(file).display())
}

/// `windcell plan JOB -o OUT --json`, which must succeed: the report.
fn plan_json(job: &Path, out: &Path) -> serde_json::Value {
    windcell_json(&[
        "plan",
        job.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--json",
    ])
}

#[test]
fn absurd_dxf_coordinates_are_refused_at_their_value() {
    let s = Scratch::new();
    let d = s.dir.path();
    for (name, value) in [("big", "1e9"), ("huge", "1e308")] {
        let job = s.case(name, &s.first_y(value), ("", ""));
        refused(
            &job,
            &place(d, &format!("{name}.dxf"), "14:1"),
            &format!(
                "path point 1 at {value} mm makes the path longer than the limit of 100000 mm"
            ),
        );
    }
    for (name, value) in [("nan", "NaN"), ("inf", "-inf")] {
        let job = s.case(name, &s.first_y(value), ("", ""));
        refused(
            &job,
            &place(d, &format!("{name}.dxf"), "14:1"),
            "which is not a finite number",
        );
    }
}

#[test]
fn a_drawing_in_metres_is_refused_unless_it_says_so() {
    let s = Scratch::new();
    let d = s.dir.path();
    let metres = s.drawing_with(&["10", "20", "30"], |v| v / 1000.0);
    let job = s.case("metres", &metres, ("", ""));
    // The first point's x value is on line 12.
    refused(
        &job,
        &place(d, "metres.dxf", "12:1"),
        "path point 1 lies -28.324 mm from the mandrel surface",
    );
    // Saying so: `$INSUNITS` 6 (metres) in a HEADER section, and the same drawing plans.
    let header = "  0\nSECTION\n  2\nHEADER\n  9\n$INSUNITS\n 70\n6\n  0\nENDSEC\n";
    let (comment, rest) = metres.split_at(metres.find("  0\nSECTION").unwrap());
    let job = s.case("metres-said", &format!("{comment}{header}{rest}"), ("", ""));
    let out = d.join("metres-said-out");
    let report = plan_json(&job, &out);
    // Scaled by 1000 after a round trip through 16 significant digits: on the surface to 1 nm.
    let worst = report["paths"][0]["dxf_max_surface_distance_mm"]
        .as_f64()
        .unwrap();
    assert!(worst < 1e-6, "{worst}");
}

#[test]
fn paths_off_the_mandrel_are_refused_at_the_first_point_off_it() {
    let s = Scratch::new();
    let d = s.dir.path();
    let shifted = s.drawing_with(&["10"], |x| x + 100.0);
    let job = s.case("shifted", &shifted, ("", ""));
    refused(
        &job,
        &place(d, "shifted.dxf", "12:1"),
        "from the mandrel surface, more than surface_tolerance_mm = 0.5 mm",
    );
    // 0.3 mm out passes the default 0.5 mm, not a tolerance of 0.2 mm; the report gives every
    // point's distance.
    let out_by = |p: [f64; 3]| -> [f64; 3] {
        let r = p[0].hypot(p[1]);
        [p[0] * (r + 0.3) / r, p[1] * (r + 0.3) / r, p[2]]
    };
    let drawing = sequences::Drawing::parse(&s.drawing).unwrap();
    let mut moved = drawing.clone();
    for e in &mut moved.entities {
        for p in &mut e.points {
            *p = out_by(*p);
        }
    }
    let text = moved.write().unwrap();
    let job = s.case("out-by-0.3", &text, ("", ""));
    let out = d.join("out-by-0.3-out");
    let report = plan_json(&job, &out);
    let distances = report["paths"][0]["dxf_surface_distance_mm"]
        .as_array()
        .unwrap();
    assert_eq!(distances.len(), 51);
    // Pushed radially out from the rotation axis by 0.3 mm: at most 0.3 mm from the tube, and
    // where the spine lies on the axis, exactly that.
    for d in distances {
        let d = d.as_f64().unwrap();
        assert!((0.0..=0.3 + 1e-9).contains(&d), "{d}");
    }
    assert!((distances[0].as_f64().unwrap() - 0.3).abs() < 1e-3);
    let job = s.case(
        "tight",
        &text,
        ("segments = 50", "segments = 50\nsurface_tolerance_mm = 0.2"),
    );
    // The written drawing has no comment: its first x value is on line 10.
    refused(
        &job,
        &place(d, "tight.dxf", "10:1"),
        "surface_tolerance_mm = 0.2 mm",
    );
}

#[test]
fn segment_counts_the_robot_cannot_number_or_hold_are_refused_at_segments() {
    let s = Scratch::new();
    let d = s.dir.path();
    for (name, value, expected) in [
        (
            "many",
            "70000",
            "segments = 70000 is out of range: a path has 2 to 10000",
        ),
        ("one", "1", "segments = 1 is out of range"),
        (
            "memory",
            "466",
            "program 1 needs 467 positioning and 4 control instructions, more than the robot's \
             memory holds",
        ),
    ] {
        let job = s.case(
            name,
            &s.drawing,
            ("segments = 50", &format!("segments = {value}")),
        );
        let at = segments_value_at(&std::fs::read_to_string(&job).unwrap());
        refused(&job, &place(d, &format!("{name}.toml"), &at), expected);
    }
}

/// A cylinder job (`examples/cylinder.toml`'s cell and mandrel) wound along `helix.dxf`: a helix
/// drawn every 2° on the 63.5 mm × 178 mm cylinder from the top at 0° down to the bottom, turning
/// `turns` revolutions counter-clockwise seen from above, cut into `segments` segments.
fn helix_job(dir: &Path, name: &str, turns: f64, segments: u32) -> PathBuf {
    let (r, length) = (31.75, 178.0);
    let samples = (turns * 180.0).ceil() as usize;
    let mut dxf = String::from("  0\nSECTION\n  2\nENTITIES\n");
    for k in 0..=samples {
        let f = k as f64 / samples as f64;
        let a = std::f64::consts::TAU * turns * f;
        dxf += &format!(
            "  0\nPOINT\n  8\nFIBRE\n 10\n{:.9}\n 20\n{:.9}\n 30\n{:.9}\n",
            r * a.cos(),
            r * a.sin(),
            length * (1.0 - f)
        );
    }
    dxf += "  0\nENDSEC\n  0\nEOF\n";
    std::fs::write(dir.join(format!("{name}.dxf")), dxf).unwrap();
    let cylinder = std::fs::read_to_string(example("cylinder.toml")).unwrap();
    let head = &cylinder[..cylinder.find("[[path]]").unwrap()];
    // A steep helix's chord leaves the arm plane by about 16–30°: the entry-angle limit is
    // raised so that only the turn per segment decides.
    let job = head.replace(
        "[cell.drive]",
        "[cell.robot]\nentry_angle_max_deg = 60.0\n\n[cell.drive]",
    ) + &format!(
        "[[path]]\nprogram = 1\ndxf = \"{name}.dxf\"\nlayer = \"FIBRE\"\nsegments = {segments}\n"
    );
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, job).unwrap();
    path
}

#[test]
fn an_imported_segment_turning_more_than_half_a_revolution_is_refused_at_segments() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // 1.2 revolutions in 2 segments: 0.6 revolution (216°) each. Unwrapped to the nearest
    // multiple of a revolution, each would turn −144° the wrong way and plan.
    let job = helix_job(d, "wide", 1.2, 2);
    let at = segments_value_at(&std::fs::read_to_string(&job).unwrap());
    refused(&job, &place(d, "wide.toml", &at), "turns the mandrel");
}

#[test]
fn an_imported_segment_turning_four_tenths_of_a_revolution_plans_the_right_way() {
    let dir = tempfile::tempdir().unwrap();
    let job_path = helix_job(dir.path(), "turning", 0.8, 2);
    let (job, text) = sequences::Job::load(&job_path).unwrap();
    let plan = cell::plan::tool::plan(&job, &text, &job_path).unwrap();
    let segments = &plan.paths[0].plan.segments;
    // Independently: the cylinder stands on the rotation axis, so the tangent point stays at the
    // same angle in the cell and the mandrel turns back by the path's own turn about its axis:
    // −0.4 revolution per segment, at 400 × 60/13 steps per mandrel revolution (indexer sense =
    // counter-clockwise, rotation_sign 1), remainders carried: −738.46 → −738, −1476.92 → −1477.
    let per_rev: f64 = 400.0 * 60.0 / 13.0;
    let expected: Vec<i64> = {
        let c1 = (-0.4 * per_rev).round() as i64;
        let c2 = (-0.8 * per_rev).round() as i64;
        vec![c1, c2 - c1]
    };
    assert_eq!(expected, vec![-738, -739]);
    let steps: Vec<i64> = segments.iter().map(|s| s.steps).collect();
    assert_eq!(steps, expected);
}

/// Continuous movement needs every segment to last the robot's time per flying instruction
/// (0.13 s in the medium zone, with a 10 % margin: 0.143 s). The cylinder at 0.1 rev/s runs at
/// `V0.46` motor rev/s, 184 steps/s at 400 steps per motor turn: 26.3 steps per 0.143 s, so a
/// segment needs 27 whole steps and its 1849 steps make at most ⌊1849 / 27⌋ = 68 segments; 80
/// are refused at `segments`, 68 plan.
#[test]
fn continuous_movement_refuses_more_segments_than_the_robot_can_take() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(example("cylinder.toml"))
        .unwrap()
        .replacen("movement = \"fine\"", "movement = \"continuous\"", 1);
    assert!(text.contains("movement = \"continuous\""));
    let job = dir.path().join("cont.toml");
    std::fs::write(&job, text.replacen("segments = 50", "segments = 80", 1)).unwrap();
    refused(
        &job,
        &place(dir.path(), "cont.toml", &segments_value_at(&text)),
        "the robot needs 0.1430 s per instruction in continuous movement (at most 68 segments",
    );
    std::fs::write(&job, text.replacen("segments = 50", "segments = 68", 1)).unwrap();
    let out = dir.path().join("out");
    let r = windcell(&["plan", job.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    assert_eq!(
        r.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&r.stderr)
    );
    let rob = std::fs::read_to_string(out.join("CYL_1.ROB")).unwrap();
    assert!(rob.contains("movement continuous"), "{rob}");
}

/// A continuous S-bend too fast for the robot's time per instruction is refused with a mandrel
/// speed to use instead, and that speed plans: the advice counts the ramps and the indexer's
/// 0.01 motor rev/s (the S-bend's second segment, in the ramp, takes as long at 1 rev/s as at
/// 0.5, so scaling one segment's time would advise a speed that still fails).
#[test]
fn the_continuous_speed_advice_plans() {
    let dir = tempfile::tempdir().unwrap();
    let job = |rps: &str| {
        example_variant(
            dir.path(),
            "sbend.toml",
            &format!("sbend-{rps}.toml"),
            &[
                (
                    "mandrel_speed_rps = 0.1 ",
                    &format!("mandrel_speed_rps = {rps} "),
                ),
                ("movement = \"fine\"", "movement = \"continuous\""),
            ],
        )
    };
    let plan = |p: &Path| {
        windcell(&[
            "plan",
            p.to_str().unwrap(),
            "-o",
            dir.path().join("out").to_str().unwrap(),
        ])
    };
    for rps in ["1.0", "0.3"] {
        let o = plan(&job(rps));
        assert_eq!(o.status.code(), Some(2));
        let err = stderr(&o);
        let advice = err
            .split("a mandrel speed of at most ")
            .nth(1)
            .and_then(|r| r.split(' ').next())
            .unwrap_or_else(|| panic!("{err}"));
        let o = plan(&job(advice));
        assert!(o.status.success(), "{rps} → {advice}: {}", stderr(&o));
    }
}

/// `plan`, `sweep` and `check` refuse what `run` would refuse on the job's own cell (its pre-run
/// check, `cell::run::batch::admit`), before anything is written: a drive whose pulse rate the
/// translator cannot make (51 200 steps per motor rev at 0.1 mandrel rev/s through 60:13 is
/// 0.1 × 60/13 × 51 200 ≈ 23 631 pulses/s, over its 10 000), an acceleration beyond the
/// indexer's 999 motor rev/s² (500 mandrel rev/s² × 60/13 ≈ 2308), a robot speed beyond the
/// header's 7.99988 m/s; and a sweep whose eight programs with room to resume the longest need
/// more of the robot's 9400 memory units than it has (seed 001 §4.1.2: 470 positionings fill it,
/// or 300 positionings and 200 controls: 20 units a positioning, 17 a control; a 50-segment
/// program is 51 positions and 4 handshake controls, 1088 units). The same job as planned is
/// accepted.
#[test]
fn a_plan_that_run_would_refuse_is_refused_when_planned() {
    let dir = tempfile::tempdir().unwrap();
    // Each refusal is placed at the one job value behind it: the pulse rate at the mandrel
    // speed (the figure the rate is of), the acceleration and the header speed at their own.
    for (name, edit, key, expected) in [
        (
            "pulses.toml",
            ("steps_per_rev = 400", "steps_per_rev = 51200"),
            "mandrel_speed_rps = ",
            "23631 pulses/s exceeds the translator limit of 10000 pulses/s",
        ),
        (
            "accel.toml",
            ("accel_rps2 = 1.0", "accel_rps2 = 500.0"),
            "accel_rps2 = ",
            "accel (motor rev/s²) = 2307.69231 out of range",
        ),
        (
            "speed.toml",
            ("max_speed_mm_s = 2000.0", "max_speed_mm_s = 9000.0"),
            "max_speed_mm_s = ",
            "max_speed = 9 out of range",
        ),
    ] {
        let job = example_variant(dir.path(), "cylinder.toml", name, &[edit]);
        let text = std::fs::read_to_string(&job).unwrap();
        let (line, column) = text
            .lines()
            .enumerate()
            .find_map(|(k, l)| l.starts_with(key).then_some((k + 1, key.len() + 1)))
            .unwrap();
        let place = format!(
            "{}:{line}:{column}: the plan cannot be wound as it stands",
            job.display()
        );
        refused(&job, &place, expected);
        let o = windcell(&["check", job.to_str().unwrap()]);
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        assert!(stderr(&o).contains(expected), "{}", stderr(&o));
    }
    let out = dir.path().join("eight");
    let o = windcell(&[
        "sweep",
        example("cylinder.toml").to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--paths",
        "8",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert_eq!(stderr(&o).lines().count(), 1, "{}", stderr(&o));
    assert!(
        stderr(&o).contains("the batch needs 9792 memory units of the robot's 9400"),
        "{}",
        stderr(&o)
    );
    assert!(!out.exists());
    // Four fit (4 × 1088 + 1088 = 5440 units).
    let o = windcell(&[
        "sweep",
        example("cylinder.toml").to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--paths",
        "4",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
}
