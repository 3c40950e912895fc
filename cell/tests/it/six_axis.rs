//! Six-axis arms through `windcell plan --json` and `windcell check`, on the two shipped
//! examples: every pose's joints are put through a forward kinematics written here from the
//! published equations (not windcell's), and must give the plan's eye, a tool axis along the
//! free fibre and the plan's tool orientation; each path keeps one configuration and no joint
//! turns more than 10° between poses.
//!
//! - OPW: Brandstötter, Angerer, Hofbaur, "An analytical solution of the inverse kinematics
//!   problem of industrial serial manipulators with an ortho-parallel basis and a spherical
//!   wrist", 2014, eqs for `c` and `u`; the joint convention of ROS-Industrial's
//!   `opw_kinematics` (`q = sign · joint − offset`). ABB IRB 2600-12/1.65: a1 150, a2 −115,
//!   b 0, c1 445, c2 700, c3 795, c4 85 mm, joint 3 offset −90°.
//! - UR: the standard Denavit–Hartenberg table Universal Robots publishes for the e-Series
//!   ("DH parameters for calculations of kinematics and dynamics"): UR10e d1 180.7, a2 −612.7,
//!   a3 −571.55, d4 174.15, d5 119.85, d6 116.55 mm, α = (90°, 0, 0, 90°, −90°, 0).

use crate::common;

use common::{example, windcell};
use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};

/// A frame: rotation (columns: its axes) and origin, base frame, mm.
type Frame = (Matrix3<f64>, Vector3<f64>);

fn rz(a: f64) -> Matrix3<f64> {
    *Rotation3::from_axis_angle(&Vector3::z_axis(), a).matrix()
}
fn ry(a: f64) -> Matrix3<f64> {
    *Rotation3::from_axis_angle(&Vector3::y_axis(), a).matrix()
}
fn rx(a: f64) -> Matrix3<f64> {
    *Rotation3::from_axis_angle(&Vector3::x_axis(), a).matrix()
}

/// The IRB 2600-12/1.65's flange from its controller joints, degrees (OPW, the paper's eqs).
fn irb2600_flange(joints_deg: &[f64]) -> Frame {
    let (a1, a2, b, c1, c2, c3, c4) = (150.0, -115.0, 0.0, 445.0, 700.0, 795.0, 85.0);
    let offsets = [0.0, 0.0, -90.0f64.to_radians(), 0.0, 0.0, 0.0];
    let q: Vec<f64> = (0..6)
        .map(|i| joints_deg[i].to_radians() - offsets[i])
        .collect();
    let psi3 = f64::atan2(a2, c3);
    let k = f64::hypot(a2, c3);
    let cx1 = c2 * q[1].sin() + k * (q[1] + q[2] + psi3).sin() + a1;
    let cy1 = b;
    let cz1 = c2 * q[1].cos() + k * (q[1] + q[2] + psi3).cos();
    let c = Vector3::new(
        cx1 * q[0].cos() - cy1 * q[0].sin(),
        cx1 * q[0].sin() + cy1 * q[0].cos(),
        cz1 + c1,
    );
    let r0c = rz(q[0]) * ry(q[1] + q[2]);
    let rce = rz(q[3]) * ry(q[4]) * rz(q[5]);
    let r = r0c * rce;
    (r, c + r * Vector3::new(0.0, 0.0, c4))
}

/// The UR10e's flange from its joints, degrees (the DH table).
fn ur10e_flange(joints_deg: &[f64]) -> Frame {
    let d = [180.7, 0.0, 0.0, 174.15, 119.85, 116.55];
    let a = [0.0, -612.7, -571.55, 0.0, 0.0, 0.0];
    let alpha = [
        90.0f64.to_radians(),
        0.0,
        0.0,
        90.0f64.to_radians(),
        -90.0f64.to_radians(),
        0.0,
    ];
    let mut r = Matrix3::identity();
    let mut p = Vector3::zeros();
    for i in 0..6 {
        let th = joints_deg[i].to_radians();
        // T_i = Rz(θ) · Tz(d) · Tx(a) · Rx(α).
        p += r * (rz(th) * Vector3::new(a[i], 0.0, 0.0) + Vector3::new(0.0, 0.0, d[i]));
        r = r * rz(th) * rx(alpha[i]);
    }
    (r, p)
}

fn v3(v: &serde_json::Value) -> Vector3<f64> {
    Vector3::new(
        v[0].as_f64().unwrap(),
        v[1].as_f64().unwrap(),
        v[2].as_f64().unwrap(),
    )
}

/// Plans `job` with `--json` and checks every pose against `flange` and the tool's `tcp_mm`.
fn check_poses(job: &str, flange: fn(&[f64]) -> Frame, tcp_mm: [f64; 3], coupled: bool) {
    let dir = tempfile::tempdir().unwrap();
    let out = windcell(&[
        "plan",
        example(job).to_str().unwrap(),
        "-o",
        dir.path().to_str().unwrap(),
        "--json",
    ]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{job}: {}",
        common::stderr(&out)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let paths = v["paths"].as_array().unwrap();
    assert_eq!(paths.len(), 2);
    for p in paths {
        let poses: Vec<&serde_json::Value> = std::iter::once(&p["start"])
            .chain(p["segments"].as_array().unwrap())
            .collect();
        assert_eq!(poses.len(), 51);
        let mut previous: Option<Vec<f64>> = None;
        let mut wrist_signs = Vec::new();
        for (k, pose) in poses.iter().enumerate() {
            let joints: Vec<f64> = pose["joints_deg"]
                .as_array()
                .unwrap()
                .iter()
                .map(|j| j.as_f64().unwrap())
                .collect();
            assert_eq!(joints.len(), 6, "{job} pose {k}");
            let (r, f) = flange(&joints);
            let eye = f + r * Vector3::from(tcp_mm);
            let planned_eye = v3(&pose["eye_mm"]);
            assert!(
                (eye - planned_eye).norm() < 0.01,
                "{job} pose {k}: FK eye {eye:?} against {planned_eye:?}"
            );
            // The tool's z axis along the free fibre, eye to tangent point.
            let fibre = (v3(&pose["tangent_point_cell_mm"]) - planned_eye).normalize();
            let axis = r.column(2).into_owned();
            assert!(
                axis.angle(&fibre).to_degrees() < 0.01,
                "{job} pose {k}: tool axis {:.4}° off the fibre",
                axis.angle(&fibre).to_degrees()
            );
            // The tool's distance: the plan's tow offset (100 mm).
            assert!(
                ((v3(&pose["tangent_point_cell_mm"]) - planned_eye).norm() - 100.0).abs() < 0.5,
                "{job} pose {k}"
            );
            let q = &pose["tool_q"];
            let planned_q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
                q[0].as_f64().unwrap(),
                q[1].as_f64().unwrap(),
                q[2].as_f64().unwrap(),
                q[3].as_f64().unwrap(),
            ));
            let fk_q = UnitQuaternion::from_matrix(&r);
            assert!(
                fk_q.angle_to(&planned_q).to_degrees() < 0.01,
                "{job} pose {k}: tool_q {:.4}° off",
                fk_q.angle_to(&planned_q).to_degrees()
            );
            assert_eq!(
                pose.get("external_deg").is_some(),
                coupled,
                "{job} pose {k}"
            );
            if coupled {
                let external = pose["external_deg"].as_f64().unwrap();
                assert!((external - pose["mandrel_deg"].as_f64().unwrap()).abs() < 1e-9);
            }
            wrist_signs.push(joints[4].to_radians().sin() >= 0.0);
            if let Some(prev) = &previous {
                for i in 0..6 {
                    assert!(
                        (joints[i] - prev[i]).abs() <= 10.0,
                        "{job} pose {k}: axis {} turns {:.2}°",
                        i + 1,
                        joints[i] - prev[i]
                    );
                }
            }
            previous = Some(joints);
        }
        // One configuration: the wrist never flips (the sign of sin q5), and the report says
        // which configuration was kept.
        assert!(
            wrist_signs.iter().all(|&s| s == wrist_signs[0]),
            "{job}: the wrist flips"
        );
        assert!(p["configuration"].as_str().unwrap().contains("elbow"));
        assert!(p["least_wrist_margin_deg"].as_f64().unwrap() >= 5.0);
    }
}

#[test]
fn irb2600_on_a_positioner_puts_every_pose_where_the_published_kinematics_do() {
    check_poses(
        "irb2600-positioner.toml",
        irb2600_flange,
        [0.0, 0.0, 200.0],
        true,
    );
}

#[test]
fn ur10e_beside_the_indexer_puts_every_pose_where_the_published_kinematics_do() {
    check_poses(
        "ur10e-cylinder.toml",
        ur10e_flange,
        [0.0, 0.0, 150.0],
        false,
    );
}

#[test]
fn six_axis_examples_check_clear_and_write_no_robot_files() {
    for (job, files) in [
        ("irb2600-positioner.toml", vec!["IRB2600.plan.json"]),
        (
            "ur10e-cylinder.toml",
            vec!["UR10E.plan.json", "UR10E_1.IND", "UR10E_2.IND"],
        ),
    ] {
        let out = windcell(&["check", example(job).to_str().unwrap()]);
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert_eq!(out.status.code(), Some(0), "{job}: {stdout}");
        assert!(
            stdout.contains("check: clear over 2 paths, 100 segments"),
            "{job}: {stdout}"
        );
        let dir = tempfile::tempdir().unwrap();
        let out = windcell(&[
            "plan",
            example(job).to_str().unwrap(),
            "-o",
            dir.path().to_str().unwrap(),
        ]);
        assert_eq!(out.status.code(), Some(0), "{job}");
        let mut written: Vec<String> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        written.sort();
        assert_eq!(written, files, "{job}");
    }
}

#[test]
fn an_obstacle_in_the_six_axis_arms_way_is_found() {
    // A post between the UR10e's base and the mandrel, at the height of its forearm.
    let dir = tempfile::tempdir().unwrap();
    let job = common::example_variant(
        dir.path(),
        "ur10e-cylinder.toml",
        "ur10e-post.toml",
        &[(
            "drive = \"indexer\"\n",
            "drive = \"indexer\"\n\n[[cell.obstacle]]\nname = \"post\"\nmin_mm = [300.0, -400.0, 0.0]\nmax_mm = [350.0, 400.0, 1500.0]\n",
        )],
    );
    let out = windcell(&["check", job.to_str().unwrap()]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert_eq!(
        out.status.code(),
        Some(3),
        "{stdout}{}",
        common::stderr(&out)
    );
    assert!(stdout.contains("hits post"), "{stdout}");
}

#[test]
fn run_refuses_a_six_axis_job_in_one_line_at_its_kind() {
    let job = example("ur10e-cylinder.toml");
    let out = windcell(&["run", job.to_str().unwrap()]);
    let err = common::stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");
    // `kind = "ur"` is line 26 of the example, its value at column 8.
    assert!(err.contains("ur10e-cylinder.toml:26:8:"), "{err}");
    assert!(err.contains("\"ur\""), "{err}");
}

/// `predict` of a six-axis job: each path's time is the plan's (the sum of its segment times in
/// `plan --json`), the coupled positioner's mandrel moves with the eye (no timing drift), and
/// the error stays within the chord model's sub-millimetre range.
#[test]
fn predict_of_a_six_axis_job_times_the_plan_and_lays_its_motion() {
    let job = example("irb2600-positioner.toml");
    let dir = tempfile::tempdir().unwrap();
    let plan = windcell(&[
        "plan",
        job.to_str().unwrap(),
        "-o",
        dir.path().to_str().unwrap(),
        "--json",
    ]);
    let plan: serde_json::Value = serde_json::from_slice(&plan.stdout).unwrap();
    let planned: Vec<f64> = plan["paths"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| {
            p["segments"]
                .as_array()
                .unwrap()
                .iter()
                .map(|s| s["duration_s"].as_f64().unwrap())
                .sum()
        })
        .collect();
    let out = windcell(&["predict", job.to_str().unwrap(), "--mode", "fine", "--json"]);
    assert_eq!(out.status.code(), Some(0), "{}", common::stderr(&out));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["model"], "six-axis plan");
    let paths = v["modes"][0]["paths"].as_array().unwrap();
    assert_eq!(paths.len(), 2);
    for (p, t) in paths.iter().zip(&planned) {
        assert!((p["time_s"].as_f64().unwrap() - t).abs() < 1e-6, "{p}");
        let e = p["max_error_mm"].as_f64().unwrap();
        assert!(e > 0.0 && e < 1.0, "{p}");
        let timing = p["sources_mm"]["timing_drift"].as_f64().unwrap();
        assert!(timing.abs() < 0.01, "coupled: {p}");
    }
}

/// A mandrel placed beyond the arm's reach: one line naming the segment and how far the arm
/// reaches (the UR10e's wrist centre reaches about 1.18 m from its shoulder: a2 + a3 = 612.7 +
/// 571.55 mm), exit 2, nothing written.
#[test]
fn a_mandrel_out_of_reach_is_refused_naming_the_segment_and_the_reach() {
    let dir = tempfile::tempdir().unwrap();
    let job = common::example_variant(
        dir.path(),
        "ur10e-cylinder.toml",
        "far.toml",
        &[(
            "axis_origin_mm = [700.0, 0.0, 100.0]",
            "axis_origin_mm = [3000.0, 0.0, 100.0]",
        )],
    );
    let out_dir = dir.path().join("out");
    let out = windcell(&[
        "plan",
        job.to_str().unwrap(),
        "-o",
        out_dir.to_str().unwrap(),
    ]);
    let err = common::stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(
        err.contains("far.toml:") && err.contains("segment 0"),
        "{err}"
    );
    assert!(
        err.contains("out of reach") && err.contains("1184.2 mm"),
        "{err}"
    );
    assert!(!out_dir.exists());
}
