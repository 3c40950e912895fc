//! The TOOL step end to end on the seven example jobs: plan, write, read back, and check the
//! control files against the plan and against the geometry.

use std::path::{Path, PathBuf};

use approx::assert_abs_diff_eq;
use nalgebra::{Rotation3, Vector3};
use sequences::{Job, MandrelFile, RobotFile};

fn examples() -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples");
    let mut jobs: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        // IRB 6/2 robot-cell jobs only: cell descriptions (`cell-*.toml`) and lathe vessels have
        // no paths; six-axis jobs (`[cell.robot] kind`) are tested in `cell/tests/it/six_axis.rs`.
        .filter(|p| std::fs::read_to_string(p).is_ok_and(|t| t.contains("[[path]]")))
        .filter(|p| Job::load(p).is_ok_and(|(job, _)| job.six_axis_arm().is_none()))
        .collect();
    jobs.sort();
    jobs
}

#[test]
fn the_seven_configurations_of_seed_001_are_shipped() {
    let names: Vec<String> = examples()
        .iter()
        .map(|p| p.file_stem().unwrap().to_string_lossy().into_owned())
        .collect();
    for expected in [
        "cylinder",
        "offset-1r",
        "offset-2r",
        "offset-3r",
        "tilted-1r",
        "tilted-2r",
        "sbend",
    ] {
        assert!(
            names.iter().any(|n| n == expected),
            "{expected} missing from {names:?}"
        );
    }
}

#[test]
fn control_files_round_trip_and_agree_with_the_plan() {
    for job_path in examples() {
        let (job, text) = Job::load(&job_path).unwrap();
        assert_eq!(
            Job::parse(&job.write().unwrap()).unwrap(),
            job,
            "{}",
            job_path.display()
        );
        let plan = cell::plan::tool::plan(&job, &text, &job_path).unwrap();
        assert_eq!(plan.paths.len(), job.paths.len());
        let b = *job.cell.robot_distance_mm.get_ref();
        let h = *job.cell.start_height_mm.get_ref();
        for path in &plan.paths {
            let rob_text = cell::plan::tool::robot_file(&job, path)
                .unwrap()
                .write()
                .unwrap();
            let rob = RobotFile::parse(&rob_text).unwrap();
            assert_eq!(rob.write().unwrap(), rob_text);
            let ind =
                MandrelFile::parse(&cell::plan::tool::mandrel_file(&job, path).write().unwrap())
                    .unwrap();
            // One robot instruction per segment end plus the start pose; the mandrel file's single
            // move is the sum of the per-segment moves.
            assert_eq!(rob.instructions.len(), path.plan.segments.len() + 1);
            let total: i64 = rob.instructions.iter().map(|i| i.mandrel.steps).sum();
            assert_eq!(total, ind.path_move.steps);
            // Drift stays within half a step (seed 001 §6.2.1 item 8, carried remainder).
            let half_step = 0.5 * 13.0 / 60.0 / 400.0 * std::f64::consts::TAU;
            assert!(path.plan.max_drift_rad <= half_step + 1e-12);
            for (instr, seg) in rob.instructions[1..].iter().zip(&path.plan.segments) {
                let e = seg.pose.eye_mm;
                for (a, b) in instr.position_mm.iter().zip([e.x, e.y, e.z]) {
                    assert!((a - b).abs() <= 0.5e-4 + 1e-9);
                }
                // The frames: eye_cell = (b, 0, h) + R_z(commanded mandrel angle) eye_mandrel.
                let expected = Rotation3::from_axis_angle(&Vector3::z_axis(), seg.pose.mandrel_rad)
                    * seg.pose.eye_mandrel_mm
                    + Vector3::new(b, 0.0, h);
                assert_abs_diff_eq!(seg.pose.eye_mm, expected, epsilon = 1e-9);
                // The eye's roll axis (the quaternion's x axis) lies in the vertical plane through
                // the pedestal axis and the eye (no wrist yaw) and meets the tow line at the
                // reported entry angle, within the default 30° limit.
                let tangent = Rotation3::from_axis_angle(&Vector3::z_axis(), seg.pose.mandrel_rad)
                    * seg.pose.tangent_point_mm
                    + Vector3::new(b, 0.0, h);
                let roll_axis = seg.pose.wrist_q * Vector3::x();
                let radial = Vector3::new(e.x, e.y, 0.0).normalize();
                assert!(roll_axis.dot(&Vector3::z().cross(&radial)).abs() < 1e-9);
                let tow = (tangent - seg.pose.eye_mm).normalize();
                let entry = tow.cross(&roll_axis).norm().atan2(tow.dot(&roll_axis));
                assert_abs_diff_eq!(entry, seg.pose.entry_angle_rad, epsilon = 1e-9);
                assert!(entry < 30f64.to_radians());
            }
        }
    }
}

/// The worst entry angle of each example as `docs/geometry.md` records it (first figure on the
/// example's row of the examples table), degrees.
fn recorded_worst_entry_deg(example: &str) -> Option<f64> {
    let doc = include_str!("../../../docs/geometry.md");
    let row = doc
        .lines()
        .find(|l| l.starts_with(&format!("| {example} |")))?;
    let cell = row.split('|').nth(2)?.trim();
    cell.split('°').next()?.trim().parse().ok()
}

#[test]
fn every_example_keeps_its_elbow_branch_its_joint_ranges_and_the_recorded_entry_angle() {
    let mut stale = Vec::new();
    for job_path in examples() {
        let name = job_path.file_stem().unwrap().to_string_lossy().into_owned();
        let (job, text) = Job::load(&job_path).unwrap();
        let plan = cell::plan::tool::plan(&job, &text, &job_path).unwrap();
        let arm = cell::plan::tool::arm(&job);
        let mut worst_deg = 0.0f64;
        let mut per_path = Vec::new();
        for path in &plan.paths {
            per_path.push(path.plan.max_entry_angle_rad.to_degrees());
            let poses =
                std::iter::once(&path.plan.start).chain(path.plan.segments.iter().map(|s| &s.pose));
            for pose in poses {
                // Every joint inside the arm's ranges.
                for (limit, value) in arm.joints.iter().zip(pose.joints.to_array()) {
                    assert!(
                        value >= limit.min_rad && value <= limit.max_rad,
                        "{name}: {:?}",
                        pose.joints
                    );
                }
                // The elbow bends to the same side at every pose (the bend from the upper arm's
                // direction to the forearm's: positive elbow up): no branch switch.
                let joints = pose.joints.irb62().expect("an IRB 6/2 pose");
                let bend = std::f64::consts::FRAC_PI_2 - joints.shoulder_rad - joints.elbow_rad;
                let up = bend.sin() > 0.0;
                assert_eq!(
                    up,
                    path.plan.arm.elbow() == Some(paths::ElbowBranch::Up),
                    "{name}"
                );
                worst_deg = worst_deg.max(pose.entry_angle_rad.to_degrees());
            }
            assert_abs_diff_eq!(
                path.plan.max_entry_angle_rad.to_degrees(),
                path.plan
                    .segments
                    .iter()
                    .map(|s| s.pose.entry_angle_rad)
                    .chain([path.plan.start.entry_angle_rad])
                    .fold(0.0, f64::max)
                    .to_degrees(),
                epsilon = 1e-12
            );
        }
        // docs/geometry.md records each example's worst entry angle to 0.01°.
        let recorded = recorded_worst_entry_deg(&name)
            .unwrap_or_else(|| panic!("docs/geometry.md has no row for {name}"));
        if (recorded - worst_deg).abs() > 0.005 + 1e-9 {
            stale.push(format!(
                "{name}: docs/geometry.md says {recorded}°, the plan {worst_deg:.3}° \
                 (per path {per_path:.3?})"
            ));
        }
    }
    assert!(stale.is_empty(), "{stale:#?}");
}
