//! Six-axis kinematics against forward kinematics written here from the published definitions,
//! never the crate's own:
//! - OPW arms: a product of rotations about the six joint axes placed as the parameter figure of
//!   Brandstötter, Angerer, Hofbaur (2014) places them with every model angle zero (axis 1 the
//!   base `z`; axis 2 along `y` through `(a1, 0, c1)`; axis 3 `c2` above it; axis 4 vertical
//!   through `(a1 + a2, b)`; axes 5 (`y`) and 6 (`z`) through the wrist centre
//!   `(a1 + a2, b, c1 + c2 + c3)`; the flange `c4` above it, base axes), with the model angle
//!   `sign · joint − offset` (ROS-Industrial `opw_kinematics`).
//! - UR arms: the standard Denavit–Hartenberg chain of 4×4 matrices from UR's published table
//!   (values typed here in metres as UR lists them).
//!
//! FK → IK → FK over 10 000 random joint vectors per preset: every branch the inverse returns
//! reproduces the pose (< 1e-9 mm, < 1e-9 rad), the drawn joints' own branch is among them, and
//! for OPW arms the number of branches equals the number the reach admits.

// Per-axis arrays (joints, limits, speeds) are indexed together by axis.
#![allow(clippy::needless_range_loop)]

use std::f64::consts::{PI, TAU};

use nalgebra::{Isometry3, Matrix3, Matrix4, Point3, Translation3, Unit, Vector3};
use paths::arm::opw::{OPW_PRESETS, Opw};
use paths::arm::ur::{UR_PRESETS, Ur};
use paths::arm::{
    Config, Elbow, EyeTarget, Joints6, Pose6, Shoulder, SixAxisArm, SixAxisKind, Tool, Wrist,
};

/// SplitMix64: a small deterministic generator for the random poses.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }

    fn between(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next()
    }
}

/// A rotation by `angle` about the line through `p` along `axis`.
fn about_line(p: Vector3<f64>, axis: Vector3<f64>, angle: f64) -> Isometry3<f64> {
    Isometry3::from_parts(Translation3::from(p), Default::default())
        * Isometry3::rotation(Unit::new_normalize(axis).into_inner() * angle)
        * Isometry3::from_parts(Translation3::from(-p), Default::default())
}

fn opw_model_angles(o: &Opw, q: &Joints6) -> Joints6 {
    std::array::from_fn(|i| f64::from(o.signs[i]) * q[i] - o.offsets_rad[i])
}

/// The OPW arm's flange as the product of its six joint rotations (module documentation).
fn opw_fk(o: &Opw, q: &Joints6) -> Pose6 {
    let m = opw_model_angles(o, q);
    let wrist = Vector3::new(o.a1_mm + o.a2_mm, o.b_mm, o.c1_mm + o.c2_mm + o.c3_mm);
    let axes = [
        (Vector3::zeros(), Vector3::z()),
        (Vector3::new(o.a1_mm, 0.0, o.c1_mm), Vector3::y()),
        (Vector3::new(o.a1_mm, 0.0, o.c1_mm + o.c2_mm), Vector3::y()),
        (Vector3::new(o.a1_mm + o.a2_mm, o.b_mm, 0.0), Vector3::z()),
        (wrist, Vector3::y()),
        (wrist, Vector3::z()),
    ];
    let mut t = Isometry3::identity();
    for (i, (p, a)) in axes.iter().enumerate() {
        t *= about_line(*p, *a, m[i]);
    }
    t *= Isometry3::translation(wrist.x, wrist.y, wrist.z + o.c4_mm);
    Pose6 {
        rotation: *t.rotation.to_rotation_matrix().matrix(),
        translation_mm: t.translation.vector,
    }
}

/// The independent OPW configuration of joints: wrist centre in front of or behind axis 1 along
/// the arm's heading, the sign of the forearm's turn from the upper arm's line, the sign of the
/// wrist bend.
fn opw_config(o: &Opw, q: &Joints6) -> (Config, f64) {
    let m = opw_model_angles(o, q);
    let f = opw_fk(o, q);
    let centre = f.translation_mm - f.rotation.column(2) * o.c4_mm;
    let heading = Vector3::new(m[0].cos(), m[0].sin(), 0.0);
    let ahead = centre.dot(&heading);
    let bend = m[2] + o.a2_mm.atan2(o.c3_mm);
    let config = Config {
        shoulder: if ahead >= 0.0 {
            Shoulder::Front
        } else {
            Shoulder::Back
        },
        elbow: if bend.sin() >= 0.0 {
            Elbow::Up
        } else {
            Elbow::Down
        },
        wrist: if m[4].sin() >= 0.0 {
            Wrist::NoFlip
        } else {
            Wrist::Flip
        },
    };
    // How far from a branch boundary: the smallest of the three deciding quantities (mm and
    // sines scaled to mm by 1000).
    let clearance = ahead
        .abs()
        .min(1000.0 * bend.sin().abs())
        .min(1000.0 * m[4].sin().abs());
    (config, clearance)
}

/// UR's DH table, metres as published (d1, a2, a3, d4, d5, d6).
const UR_TABLE_M: [(&str, [f64; 6]); 3] = [
    ("ur5e", [0.1625, -0.425, -0.3922, 0.1333, 0.0997, 0.0996]),
    (
        "ur10e",
        [0.1807, -0.6127, -0.57155, 0.17415, 0.11985, 0.11655],
    ),
    ("ur16e", [0.1807, -0.4784, -0.36, 0.17415, 0.11985, 0.11655]),
];

fn dh(theta: f64, d: f64, a: f64, alpha: f64) -> Matrix4<f64> {
    let (st, ct) = theta.sin_cos();
    let (sa, ca) = alpha.sin_cos();
    Matrix4::new(
        ct,
        -st * ca,
        st * sa,
        a * ct,
        st,
        ct * ca,
        -ct * sa,
        a * st,
        0.0,
        sa,
        ca,
        d,
        0.0,
        0.0,
        0.0,
        1.0,
    )
}

/// UR's flange from the DH table (standard DH), mm.
fn ur_fk(table_m: &[f64; 6], q: &Joints6) -> Pose6 {
    let [d1, a2, a3, d4, d5, d6] = table_m.map(|v| v * 1000.0);
    let rows = [
        (d1, 0.0, PI / 2.0),
        (0.0, a2, 0.0),
        (0.0, a3, 0.0),
        (d4, 0.0, PI / 2.0),
        (d5, 0.0, -PI / 2.0),
        (d6, 0.0, 0.0),
    ];
    let mut t = Matrix4::identity();
    for (i, (d, a, alpha)) in rows.iter().enumerate() {
        t *= dh(q[i], *d, *a, *alpha);
    }
    Pose6 {
        rotation: t.fixed_view::<3, 3>(0, 0).into_owned(),
        translation_mm: t.fixed_view::<3, 1>(0, 3).into_owned(),
    }
}

/// The difference of two rotations: the Frobenius norm of `A − B`, which is `2√2·sin(θ/2)`
/// for a relative turn θ (an arccosine of the trace would lose half the digits near 0).
fn rotation_error(a: &Matrix3<f64>, b: &Matrix3<f64>) -> f64 {
    (a - b).norm() / 2f64.sqrt()
}

fn same_angles(a: &Joints6, b: &Joints6, tol: f64) -> bool {
    a.iter().zip(b).all(|(x, y)| {
        let d = (x - y).rem_euclid(TAU);
        d.min(TAU - d) < tol
    })
}

const SAMPLES: usize = 10_000;

#[test]
fn opw_presets_round_trip_through_all_branches() {
    for p in &OPW_PRESETS {
        let o = p.opw;
        let kind = SixAxisKind::Opw(o);
        let lim = p.limits();
        let (k, _) = (o.a2_mm.hypot(o.c3_mm), ());
        let mut rng = Rng(0x5EED ^ p.model.len() as u64);
        let (mut worst_mm, mut worst_rad, mut counted) = (0.0f64, 0.0f64, 0usize);
        for _ in 0..SAMPLES {
            let q: Joints6 = std::array::from_fn(|i| rng.between(lim.min_rad[i], lim.max_rad[i]));
            let pose = opw_fk(&o, &q);
            let sols = kind.inverse(&pose);
            for b in 0..8 {
                if !sols.valid[b] {
                    continue;
                }
                let back = opw_fk(&o, &sols.joints[b]);
                worst_mm = worst_mm.max((back.translation_mm - pose.translation_mm).norm());
                worst_rad = worst_rad.max(rotation_error(&back.rotation, &pose.rotation));
            }
            let (config, clearance) = opw_config(&o, &q);
            if clearance < 1e-3 {
                continue;
            }
            counted += 1;
            assert!(
                sols.valid[config.index()],
                "{}: {q:?} branch {config}",
                p.model
            );
            assert!(
                same_angles(&sols.joints[config.index()], &q, 1e-6),
                "{}: {q:?} → {:?}",
                p.model,
                sols.joints[config.index()]
            );
            // Branches the reach admits: four per shoulder side whose elbow triangle closes.
            let f = opw_fk(&o, &q);
            let c = f.translation_mm - f.rotation.column(2) * o.c4_mm;
            let rho = (c.x * c.x + c.y * c.y - o.b_mm * o.b_mm).max(0.0).sqrt();
            let mut expected = 0;
            for x in [rho - o.a1_mm, -rho - o.a1_mm] {
                let s = x.hypot(c.z - o.c1_mm);
                let (lo, hi) = ((o.c2_mm - k).abs(), o.c2_mm + k);
                if (s - lo).abs() < 1e-6 || (s - hi).abs() < 1e-6 {
                    expected = usize::MAX;
                    break;
                }
                if s > lo && s < hi {
                    expected += 4;
                }
            }
            if expected != usize::MAX {
                assert_eq!(
                    sols.valid.iter().filter(|v| **v).count(),
                    expected,
                    "{}: {q:?}",
                    p.model
                );
            }
        }
        assert!(worst_mm < 1e-9, "{}: {worst_mm} mm", p.model);
        assert!(worst_rad < 1e-9, "{}: {worst_rad} rad", p.model);
        assert!(counted > SAMPLES * 9 / 10, "{}: {counted}", p.model);
    }
}

/// Offsets the presets do not exercise: a lateral wrist offset `b`, no shoulder offset, a
/// positive `a2`, mixed signs and offsets.
#[test]
fn opw_general_parameters_round_trip() {
    let o = Opw {
        a1_mm: 0.0,
        a2_mm: 40.0,
        b_mm: 35.0,
        c1_mm: 320.0,
        c2_mm: 225.0,
        c3_mm: 260.0,
        c4_mm: 65.0,
        offsets_rad: [0.1, -0.3, -PI / 2.0, 0.2, 0.0, PI],
        signs: [-1, 1, -1, 1, -1, 1],
    };
    o.validate().unwrap();
    let kind = SixAxisKind::Opw(o);
    let mut rng = Rng(7);
    for _ in 0..SAMPLES {
        let q: Joints6 = std::array::from_fn(|_| rng.between(-PI, PI));
        let pose = opw_fk(&o, &q);
        let sols = kind.inverse(&pose);
        for b in 0..8 {
            if sols.valid[b] {
                let back = opw_fk(&o, &sols.joints[b]);
                assert!((back.translation_mm - pose.translation_mm).norm() < 1e-9);
                assert!(rotation_error(&back.rotation, &pose.rotation) < 1e-9);
            }
        }
        let (config, clearance) = opw_config(&o, &q);
        if clearance > 1e-3 {
            assert!(same_angles(&sols.joints[config.index()], &q, 1e-6), "{q:?}");
        }
    }
}

#[test]
fn ur_presets_match_the_published_table_and_round_trip() {
    for (p, (name, table)) in UR_PRESETS.iter().zip(UR_TABLE_M) {
        assert_eq!(p.model, name);
        let u: Ur = p.ur;
        let from_table = table.map(|v| v * 1000.0);
        let preset = [u.d1_mm, u.a2_mm, u.a3_mm, u.d4_mm, u.d5_mm, u.d6_mm];
        for (a, b) in preset.iter().zip(from_table) {
            assert!((a - b).abs() < 1e-9, "{name}: {preset:?} vs {from_table:?}");
        }
        let kind = SixAxisKind::Ur(u);
        let mut rng = Rng(0xC0B07 + name.len() as u64);
        let (mut worst_mm, mut worst_rad, mut eights) = (0.0f64, 0.0f64, 0usize);
        for _ in 0..SAMPLES {
            let q: Joints6 = std::array::from_fn(|_| rng.between(-TAU, TAU));
            let pose = ur_fk(&table, &q);
            let sols = kind.inverse(&pose);
            for b in 0..8 {
                if sols.valid[b] {
                    let back = ur_fk(&table, &sols.joints[b]);
                    worst_mm = worst_mm.max((back.translation_mm - pose.translation_mm).norm());
                    worst_rad = worst_rad.max(rotation_error(&back.rotation, &pose.rotation));
                }
            }
            // The elbow's two bends exist together (one two-link triangle per shoulder and wrist).
            for b in [0, 1, 4, 5] {
                assert_eq!(sols.valid[b], sols.valid[b + 2]);
            }
            if sols.valid.iter().all(|v| *v) {
                eights += 1;
            }
            // The drawn joints' own branch, away from the branch boundaries.
            let f = ur_fk(&table, &q);
            let p5 = f.translation_mm - f.rotation.column(2) * (table[5] * 1000.0);
            let ahead = p5.x * q[0].cos() + p5.y * q[0].sin();
            if ahead.abs() < 1.0 || q[2].sin().abs() < 1e-3 || q[4].sin().abs() < 1e-3 {
                continue;
            }
            let config = Config {
                shoulder: if ahead >= 0.0 {
                    Shoulder::Front
                } else {
                    Shoulder::Back
                },
                elbow: if q[2].sin() >= 0.0 {
                    Elbow::Up
                } else {
                    Elbow::Down
                },
                wrist: if q[4].sin() >= 0.0 {
                    Wrist::NoFlip
                } else {
                    Wrist::Flip
                },
            };
            assert!(sols.valid[config.index()], "{name}: {q:?}");
            assert!(
                same_angles(&sols.joints[config.index()], &q, 1e-6),
                "{name}: {q:?} → {:?}",
                sols.joints[config.index()]
            );
        }
        assert!(worst_mm < 1e-9, "{name}: {worst_mm} mm");
        assert!(worst_rad < 1e-9, "{name}: {worst_rad} rad");
        // Most random poses of a UR arm are reachable in all eight ways.
        assert!(eights > SAMPLES / 4, "{name}: {eights}");
    }
}

/// Eye poses as a winding cell sees them: the mandrel (radius 60 mm, vertical axis at `centre`)
/// turns, so the tangent point stays on the side facing the robot, swinging ±35° about it
/// `swings` times while it climbs `height_mm`; the wind angle grows from 30° to 60°; the eye is
/// 80 mm back along the free fibre, the tow from the eye to the tangent point.
fn winding(centre: Point3<f64>, swings: f64, height_mm: f64, n: usize) -> Vec<EyeTarget> {
    let facing = (-centre.y).atan2(-centre.x);
    (0..n)
        .map(|i| {
            let s = i as f64 / (n - 1) as f64;
            let phi = facing + 35f64.to_radians() * (TAU * swings * s).sin();
            let wind = (30.0 + 30.0 * s).to_radians();
            let (sp, cp) = phi.sin_cos();
            let tangent_point = Point3::new(centre.x, centre.y, centre.z + height_mm * s)
                + Vector3::new(cp, sp, 0.0) * 60.0;
            let along = Vector3::new(-sp, cp, 0.0) * wind.sin() + Vector3::z() * wind.cos();
            let eye = tangent_point - along * 80.0;
            EyeTarget {
                eye_mm: eye,
                tow: Unit::new_normalize(tangent_point - eye),
            }
        })
        .collect()
}

fn check_path(arm: &SixAxisArm, targets: &[EyeTarget], fk: &dyn Fn(&Joints6) -> Pose6) {
    let solved = arm.solve_path(targets, None).unwrap();
    let tool = arm.tool.frame();
    for (k, (q, t)) in solved.joints.iter().zip(targets).enumerate() {
        let f = fk(q);
        let eye = f.rotation * tool.translation_mm + f.translation_mm;
        let z = f.rotation * tool.rotation.column(2);
        assert!(
            (eye - t.eye_mm.coords).norm() < 0.01,
            "pose {k}: eye off by {}",
            (eye - t.eye_mm.coords).norm()
        );
        let angle = z.angle(&t.tow).to_degrees();
        assert!(angle < 0.01, "pose {k}: tool axis {angle}° off the tow");
        for i in 0..6 {
            assert!(q[i] >= arm.limits.min_rad[i] && q[i] <= arm.limits.max_rad[i]);
        }
        if k > 0 {
            for i in 0..6 {
                let step = (q[i] - solved.joints[k - 1][i]).abs().to_degrees();
                assert!(step <= 10.0, "pose {k} axis {}: {step}°", i + 1);
            }
        }
    }
    // The report's least margins, recomputed from the joints.
    let least = solved
        .joints
        .iter()
        .flat_map(|q| {
            (0..6).map(move |i| (q[i] - arm.limits.min_rad[i]).min(arm.limits.max_rad[i] - q[i]))
        })
        .fold(f64::INFINITY, f64::min)
        .to_degrees();
    assert!((least - solved.report.least_limit_margin_deg).abs() < 1e-9);
    assert!(least >= 2.0 - 1e-9);
    assert!(solved.report.least_wrist_margin_deg >= 5.0 - 1e-9);
    assert!(solved.report.largest_step_deg <= 10.0);
}

/// The IRB 2600 with the eye 150 mm out of the flange, its axis across the flange's (along the
/// flange's x), so that the flange can face the mandrel while the eye looks along the fibre.
fn irb2600_eye_across() -> SixAxisArm {
    let tool = Tool {
        tcp_mm: [0.0, 0.0, 150.0],
        rpy_deg: [0.0, 90.0, 0.0],
    };
    SixAxisArm::opw_preset("irb2600-12/1.65", tool).unwrap()
}

/// The UR10e with the eye off the flange's axis and tilted.
fn ur10e_eye_offset() -> SixAxisArm {
    let tool = Tool {
        tcp_mm: [0.0, 50.0, 120.0],
        rpy_deg: [20.0, 0.0, 0.0],
    };
    SixAxisArm::ur_preset("ur10e", tool).unwrap()
}

#[test]
fn a_winding_path_keeps_one_configuration_on_an_irb2600() {
    let arm = irb2600_eye_across();
    let o = match arm.kind {
        SixAxisKind::Opw(o) => o,
        SixAxisKind::Ur(_) => unreachable!(),
    };
    let targets = winding(Point3::new(1000.0, 0.0, 500.0), 2.0, 400.0, 201);
    check_path(&arm, &targets, &|q| opw_fk(&o, q));
    let solved = arm.solve_path(&targets, None).unwrap();
    let first = opw_config(&o, &solved.joints[0]).0;
    assert_eq!(first, solved.report.config);
    for q in &solved.joints {
        assert_eq!(opw_config(&o, q).0, first);
    }
}

#[test]
fn a_winding_path_keeps_one_configuration_on_a_ur10e() {
    let arm = ur10e_eye_offset();
    let table = UR_TABLE_M[1].1;
    let targets = winding(Point3::new(700.0, 200.0, 100.0), 1.5, 300.0, 151);
    check_path(&arm, &targets, &|q| ur_fk(&table, q));
}

#[test]
fn a_path_out_of_reach_is_refused_with_its_pose() {
    let arm = SixAxisArm::ur_preset("ur5e", Tool::default()).unwrap();
    let mut targets = winding(Point3::new(600.0, 0.0, 100.0), 1.0, 100.0, 21);
    targets[12].eye_mm = Point3::new(3000.0, 0.0, 100.0);
    let e = arm.solve_path(&targets, None).unwrap_err().to_string();
    assert!(e.starts_with("segment 12: "), "{e}");
    assert!(e.contains("out of reach"), "{e}");
}

/// The least joint time from `prev` to an admissible pose at `target` in `config` over the
/// whole turn about the tow line, found by brute force: a 0.25° scan of the whole turn, then a
/// 0.0025° scan of the half degree about the scan's best (same limits, margins and continuity
/// limit as the solver's, written out here from their definitions).
fn least_joint_time_by_scan(
    arm: &SixAxisArm,
    target: &EyeTarget,
    prev: &Joints6,
    config: paths::arm::Config,
) -> f64 {
    let speeds = arm.limits.speed_rad_s.unwrap();
    let m = arm.margins;
    let t_tool = arm.tool.frame();
    let d = target.tow.into_inner();
    let e1 = d.cross(&Vector3::z()).normalize();
    let e2 = d.cross(&e1);
    let time_at = |g: f64| -> Option<f64> {
        let x = e1 * g.cos() + e2 * g.sin();
        let r_tool = Matrix3::from_columns(&[x, d.cross(&x), d]);
        let rotation = r_tool * t_tool.rotation.transpose();
        let flange = Pose6 {
            translation_mm: target.eye_mm.coords - rotation * t_tool.translation_mm,
            rotation,
        };
        let raw = arm.kind.inverse_branch(&flange, config).ok()?;
        let mut q = raw;
        for i in 0..6 {
            let (lo, hi) = (
                arm.limits.min_rad[i] + m.limit_rad,
                arm.limits.max_rad[i] - m.limit_rad,
            );
            q[i] = (-3..=3)
                .map(|n| raw[i] + n as f64 * TAU)
                .filter(|v| *v >= lo && *v <= hi)
                .min_by(|a, b| (a - prev[i]).abs().total_cmp(&(b - prev[i]).abs()))
                .filter(|v| (v - prev[i]).abs() <= m.step_max_rad)?;
        }
        (arm.kind.wrist_distance_rad(&q) >= m.wrist_rad).then(|| {
            (0..6)
                .map(|i| (q[i] - prev[i]).abs() / speeds[i])
                .fold(0.0, f64::max)
        })
    };
    let coarse = TAU / 1440.0;
    let (best_g, mut least) = (0..1440)
        .filter_map(|s| time_at(s as f64 * coarse).map(|t| (s as f64 * coarse, t)))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .expect("the scan found no admissible turn");
    for s in -100..=100 {
        if let Some(t) = time_at(best_g + s as f64 * coarse / 100.0) {
            least = least.min(t);
        }
    }
    least
}

/// The turn about the tow line is chosen so that the joints move no more than needed: at every
/// pose of a winding path, the joint time from the previous pose (the largest `|Δq_i| / speed_i`)
/// is compared with the least a brute-force scan of the whole turn finds
/// ([`least_joint_time_by_scan`]), from the same previous pose. Two arms, a short path and a
/// long one with 500 poses a swing (the density of the pose benchmark).
#[test]
fn the_chosen_turn_needs_no_more_joint_time_than_a_fine_scan() {
    let cases = [
        (
            irb2600_eye_across(),
            winding(Point3::new(1000.0, 0.0, 500.0), 2.0, 400.0, 201),
        ),
        (
            irb2600_eye_across(),
            winding(Point3::new(1000.0, 0.0, 500.0), 2.0, 400.0, 1000),
        ),
        (
            ur10e_eye_offset(),
            winding(Point3::new(700.0, 200.0, 100.0), 2.0, 300.0, 1000),
        ),
    ];
    for (arm, targets) in &cases {
        let solved = arm.solve_path(targets, None).unwrap();
        let speeds = arm.limits.speed_rad_s.unwrap();
        let mut worst: f64 = 0.0;
        let mut total = (0.0, 0.0);
        for k in 1..targets.len() {
            let prev = solved.joints[k - 1];
            let chosen = (0..6)
                .map(|i| (solved.joints[k][i] - prev[i]).abs() / speeds[i])
                .fold(0.0, f64::max);
            let least = least_joint_time_by_scan(arm, &targets[k], &prev, solved.report.config);
            total = (total.0 + chosen, total.1 + least);
            worst = worst.max(chosen / least);
        }
        eprintln!(
            "{} poses: largest ratio of chosen to scanned joint time {worst:.4}, over the path {:.4}",
            targets.len(),
            total.0 / total.1
        );
        // Over the path within 1 % of the brute-force least; no pose more than 30 % above it
        // (where the least joint switches, a pose or two may lag).
        assert!(total.0 <= total.1 * 1.01, "{} {}", total.0, total.1);
        assert!(worst <= 1.3, "{worst}");
    }
}

/// The link capsules join the arm's joint origins: the wrist capsule ends at the flange and the
/// tool capsule at the eye, both as the independent forward kinematics puts them; the upper arm
/// is `c2` long (OPW) or `|a2|` (UR).
#[test]
fn link_capsules_follow_the_arm() {
    let tool = Tool {
        tcp_mm: [10.0, -20.0, 150.0],
        rpy_deg: [0.0, 90.0, 0.0],
    };
    let arm = SixAxisArm::opw_preset("kr16-2", tool).unwrap();
    let o = match arm.kind {
        SixAxisKind::Opw(o) => o,
        SixAxisKind::Ur(_) => unreachable!(),
    };
    let mut rng = Rng(99);
    for _ in 0..200 {
        let q: Joints6 =
            std::array::from_fn(|i| rng.between(arm.limits.min_rad[i], arm.limits.max_rad[i]));
        let links = arm.links(&q);
        let f = opw_fk(&o, &q);
        let eye = f.rotation * Vector3::from(tool.tcp_mm) + f.translation_mm;
        let centre = f.translation_mm - f.rotation.column(2) * o.c4_mm;
        assert!((links[5].a.coords - centre).norm() < 1e-9);
        assert!((links[5].b.coords - f.translation_mm).norm() < 1e-9);
        assert!((links[6].b.coords - eye).norm() < 1e-9);
        assert!(((links[2].b - links[2].a).norm() - o.c2_mm).abs() < 1e-9);
        assert_eq!(links[0].a, Point3::origin());
        for (l, r) in links.iter().zip(arm.link_radii_mm) {
            assert_eq!(l.radius_mm, r);
        }
    }
    let ur = SixAxisArm::ur_preset("ur16e", tool).unwrap();
    let table = UR_TABLE_M[2].1;
    for _ in 0..200 {
        let q: Joints6 = std::array::from_fn(|_| rng.between(-PI, PI));
        let links = ur.links(&q);
        let f = ur_fk(&table, &q);
        assert!((links[5].b.coords - f.translation_mm).norm() < 1e-9);
        assert!(((links[1].b - links[1].a).norm() - 478.4).abs() < 1e-9);
    }
}

#[test]
fn bad_arm_parameters_are_refused() {
    use paths::arm::JointLimits6;
    let e = SixAxisArm::opw_preset("kr1000", Tool::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("unknown opw model \"kr1000\""), "{e}");
    let e = SixAxisArm::ur_preset("ur3", Tool::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("unknown ur model \"ur3\" (known: \"ur5e\", \"ur10e\", \"ur16e\")"),
        "{e}"
    );
    let mut min = [-1.0; 6];
    let max = [1.0; 6];
    min[3] = 1.0;
    assert!(JointLimits6::degrees(min, max, None).validate().is_err());
    assert!(
        JointLimits6::degrees([f64::NAN; 6], max, None)
            .validate()
            .is_err()
    );
    assert!(
        JointLimits6::degrees([-1.0; 6], max, Some([0.0; 6]))
            .validate()
            .is_err()
    );
    let mut arm = SixAxisArm::ur_preset("ur5e", Tool::default()).unwrap();
    arm.validate().unwrap();
    arm.link_radii_mm[2] = -1.0;
    assert!(arm.validate().is_err());
    let mut arm = SixAxisArm::ur_preset("ur5e", Tool::default()).unwrap();
    arm.margins.wrist_rad = f64::NAN;
    assert!(arm.validate().is_err());
    let arm = SixAxisArm::ur_preset("ur5e", Tool::default()).unwrap();
    assert!(arm.solve_path(&[], None).is_err());
    let bad = EyeTarget {
        eye_mm: Point3::new(f64::NAN, 0.0, 0.0),
        tow: Vector3::z_axis(),
    };
    assert!(arm.solve_path(&[bad], None).is_err());
}
