//! The TOOL step (seed 001 §5.6) for a six-axis arm: from equal-length surface points to eye
//! targets, joints, mandrel angles, step counts and segment times.
//!
//! # What stays as in the thesis cell
//! The eye in the mandrel frame (eqs 3.8–3.14, [`crate::eye`]), the mandrel angle of eq 3.7 and
//! its unwrapping, the steps with the remainder carried and the segment times of
//! [`crate::plan`] are the same. Eq 3.7 turns the mandrel so that the tangent point's horizontal
//! tangent passes through the robot's pedestal axis at distance `b`; for an axis anywhere in the
//! base frame ([`MandrelAxis`]) the robot's place is its **shoulder** (axis 2's origin at zero
//! joints) seen in the mandrel frame: its distance from the rotation axis is `b`, and the angle
//! at which it stands about the axis turns every mandrel angle by the same amount. In the thesis
//! geometry (vertical axis at `(b, 0)`) that turn is 0.
//!
//! # What six axes change
//! The eye takes the tow line exactly (entry angle 0): the tool's `z` axis points from the eye
//! along the free fibre to the tangent point at the commanded mandrel angle, and the rotation
//! about it is chosen per pose with the configuration by [`SixAxisArm::solve_path`] (one
//! configuration per path, joint-limit and wrist-singularity margins, joint continuity). A pose
//! the arm cannot take is [`Error::SixAxis`] naming the segment.
//!
//! # The robot's least time for a segment
//! The eye's straight-line travel at the controller's maximum speed ([`Speeds::max_speed_mm_s`])
//! and the largest joint turn at that joint's speed limit (`joint_speed_deg_s`; none given: no
//! joint bound), the longer of the two. Accelerations are `predict`'s concern.

use std::f64::consts::{FRAC_PI_2, PI};

use nalgebra::{Point3, Unit, UnitQuaternion, Vector3};

use super::{EyeTarget, Joints6, MandrelDrive, SixAxisArm};
use crate::Error;
use crate::plan::Setup;
use crate::plan::{
    ArmJoints, PathArm, PathPlan, Pose, SixAxisCell, Speeds, eyes_and_angles, timed_segments,
};
use crate::segment::SurfacePoint;
use crate::step::RemainderCarrier;

/// The turn that takes a tool frame (`z` along the fibre) to the wrist frame of [`Pose::wrist_q`]
/// (`x` along the fibre): a quarter turn about `y`, `R_y(−90°)`, which takes `x` onto `z`.
pub fn tool_to_wrist() -> UnitQuaternion<f64> {
    UnitQuaternion::from_axis_angle(&Vector3::y_axis(), -FRAC_PI_2)
}

/// The robot's place for eq 3.7, mandrel frame at angle 0: the distance `b` of the arm's
/// shoulder from the rotation axis and the turn of every mandrel angle (module documentation).
pub fn facing(six: &SixAxisCell) -> (f64, f64) {
    let shoulder = six.arm.kind.link_points(&[0.0; 6])[2];
    let m = six.axis.frame(0.0).inverse_transform_point(&shoulder);
    (m.x.hypot(m.y), m.y.atan2(m.x) - PI)
}

/// The robot's least time from `from` to `to`, s (module documentation).
pub fn robot_time_s(arm: &SixAxisArm, speeds: &Speeds, from: &Pose, to: &Pose) -> f64 {
    let linear_s = (to.eye_mm - from.eye_mm).norm() / speeds.max_speed_mm_s;
    let joint_s = match (
        six_joints(&from.joints),
        six_joints(&to.joints),
        arm.limits.speed_rad_s,
    ) {
        (Some(a), Some(b), Some(speed)) => (0..6)
            .map(|i| (b[i] - a[i]).abs() / speed[i])
            .fold(0.0, f64::max),
        _ => 0.0,
    };
    linear_s.max(joint_s)
}

fn six_joints(joints: &ArmJoints) -> Option<Joints6> {
    match joints {
        ArmJoints::SixAxis { joints, .. } => Some(*joints),
        ArmJoints::Irb62(_) => None,
    }
}

/// Plans one path for a six-axis arm (called by [`crate::plan::plan`], which has checked the
/// setup, the speeds and the point count).
pub(crate) fn plan(
    points: &[SurfacePoint],
    clearance_mm: impl Fn(&Point3<f64>) -> f64,
    setup: &Setup,
    six: &SixAxisCell,
    speeds: &Speeds,
) -> Result<PathPlan, Error> {
    let (b, turn) = facing(six);
    let prepared = eyes_and_angles(points, setup, b, turn)?;

    // The steps with the remainder carried and the commanded angle at every point.
    let step_angle = setup.gearing.step_angle_rad();
    let phi0 = prepared[0].ideal;
    let mut carrier = RemainderCarrier::default();
    let mut commanded = Vec::with_capacity(points.len());
    let mut steps = Vec::with_capacity(points.len());
    commanded.push(phi0);
    steps.push(0);
    let mut max_drift_rad = 0.0f64;
    for prep in prepared.iter().skip(1) {
        steps.push(carrier.next(setup.gearing.steps(prep.ideal - phi0)));
        let phi = phi0 + carrier.commanded as f64 * step_angle;
        max_drift_rad = max_drift_rad.max((phi - prep.ideal).abs());
        commanded.push(phi);
    }

    // The eye targets in the base frame, and the eye's clearance from the mandrel.
    let axis = &six.axis;
    let mut min_clearance = f64::INFINITY;
    let mut targets = Vec::with_capacity(points.len());
    for (k, (prep, phi)) in prepared.iter().zip(&commanded).enumerate() {
        let clearance = clearance_mm(&prep.eye);
        if clearance <= 0.0 || clearance.is_nan() {
            return Err(Error::EyeInsideMandrel {
                segment: k,
                clearance_mm: clearance,
            });
        }
        min_clearance = min_clearance.min(clearance);
        let eye_mm = axis.to_base(*phi, &prep.eye);
        let tow = Unit::try_new(axis.to_base(*phi, &points[k].point) - eye_mm, 1e-9)
            .ok_or(Error::DegenerateSegment { segment: k.max(1) })?;
        targets.push(EyeTarget { eye_mm, tow });
    }
    let solved = six.arm.solve_path(&targets, None)?;

    // The poses, as the arm takes them.
    let to_wrist = tool_to_wrist();
    let coupled = axis.drive == MandrelDrive::Robot;
    let mut max_entry = 0.0f64;
    let poses: Vec<(Pose, i64)> = solved
        .joints
        .iter()
        .enumerate()
        .map(|(k, q)| {
            let frame = six.arm.tool_frame(q);
            let tool_q = frame.quaternion();
            let entry = (tool_q * Vector3::z()).angle(&targets[k].tow);
            max_entry = max_entry.max(entry);
            let pose = Pose {
                tangent_point_mm: points[k].point,
                normal: points[k].normal,
                eye_mandrel_mm: prepared[k].eye,
                eye_mm: targets[k].eye_mm,
                joints: ArmJoints::SixAxis {
                    joints: *q,
                    tool_q,
                    external_rad: coupled.then_some(commanded[k]),
                },
                entry_angle_rad: entry,
                wrist_q: tool_q * to_wrist,
                ideal_mandrel_rad: prepared[k].ideal,
                mandrel_rad: commanded[k],
            };
            (pose, steps[k])
        })
        .collect();
    let start = poses[0].0;
    let segments = timed_segments(&start, &poses[1..], setup, speeds, |_, from, to| {
        robot_time_s(&six.arm, speeds, from, to)
    })?;
    Ok(PathPlan {
        sync_drive_rad: setup.calibration.drive_angle_rad(start.mandrel_rad),
        start,
        segments,
        arm: PathArm::SixAxis(solved.report),
        max_drift_rad,
        min_eye_clearance_mm: min_clearance,
        max_entry_angle_rad: max_entry,
    })
}

/// The joints on `config` that put the tool frame at `eye_mm` with orientation `tool_q` (base
/// frame): the flange is the tool pose followed by the tool's inverse, `T · F⁻¹`.
pub fn joints_for_tool(
    arm: &SixAxisArm,
    eye_mm: &Point3<f64>,
    tool_q: &UnitQuaternion<f64>,
    config: super::Config,
) -> Result<Joints6, super::SixAxisFault> {
    let tool = arm.tool.frame();
    let rotation = tool_q.to_rotation_matrix().into_inner() * tool.rotation.transpose();
    let flange = super::Pose6 {
        rotation,
        translation_mm: eye_mm.coords - rotation * tool.translation_mm,
    };
    arm.kind.inverse_branch(&flange, config)
}

/// For each joint, a bound on how far a point of the arm's links or tool (up to `extra_mm` beyond
/// the eye) can lie from that joint's axis: the chain's length from the joint's link point on
/// (link lengths do not change with the joints). A point's speed is at most `Σ |q̇ⱼ| · bound[j]`.
pub fn lever_arms_mm(arm: &SixAxisArm, extra_mm: f64) -> [f64; 6] {
    // The tool, the last link, ends at the eye: its levers are the chain's length from each
    // joint's link point to the eye. Joint j's axis passes through link point j − 1 or a later
    // one (the UR's DH origins lie on the axes; an OPW arm's shoulder, elbow and wrist centre
    // come one point later), and the chain from an earlier point is the longer.
    let to_eye = link_lever_arms_mm(arm)[super::LINKS - 1];
    to_eye.map(|lever| lever + extra_mm)
}

/// Per link, [`lever_arms_mm`] without the eye mechanism: `[k][j]` bounds how far a point of link
/// `k` ([`SixAxisArm::links`]) can lie from joint `j`'s axis, the chain's length from joint `j`'s
/// link point to the link's far end (0 for the joints after the link, which do not move it).
pub fn link_lever_arms_mm(arm: &SixAxisArm) -> [[f64; 6]; super::LINKS] {
    let q = [0.0; 6];
    let p = arm.kind.link_points(&q);
    let eye = arm.tool_frame(&q).origin();
    // along[i]: the chain's length from the base to point i (point 7: the eye).
    let mut along = [0.0; 8];
    for i in 1..8 {
        let here = if i < 7 { p[i] } else { eye };
        along[i] = along[i - 1] + (here - p[i - 1]).norm();
    }
    std::array::from_fn(|k| {
        std::array::from_fn(|j| if j <= k { along[k + 1] - along[j] } else { 0.0 })
    })
}

/// For the links that move with the tool frame, the farthest of their points from the eye, mm:
/// the wrist link (wrist centre to flange, on axis 6, which turning axis 6 leaves in place) and
/// the tool (flange to eye). The other links: `None`.
pub fn tool_reach_mm(arm: &SixAxisArm) -> [Option<f64>; super::LINKS] {
    let q = [0.0; 6];
    let p = arm.kind.link_points(&q);
    let eye = arm.tool_frame(&q).origin();
    let from_eye = |i: usize| (p[i] - eye).norm();
    let mut reach = [None; super::LINKS];
    reach[5] = Some(from_eye(5).max(from_eye(6)));
    reach[6] = Some(from_eye(6));
    reach
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::arm::{MandrelAxis, MandrelDrive, Tool};
    use crate::geodesic::{self, Direction, PathStart};
    use crate::plan::{ENTRY_ANGLE_MAX_DEG, plan as plan_path};
    use crate::segment::equal_length;
    use crate::{Arm, Calibration, Gearing, MandrelProfile, Movement, Tube};

    /// The IRB 2600 with the eye 200 mm out and its axis across the flange (`docs/arms.md`).
    fn irb2600() -> SixAxisArm {
        SixAxisArm::opw_preset(
            "irb2600-12/1.65",
            Tool {
                tcp_mm: [0.0, 0.0, 200.0],
                rpy_deg: [0.0, 90.0, 0.0],
            },
        )
        .unwrap()
    }

    fn setup(robot_distance_mm: f64, six_axis: Option<SixAxisCell>) -> Setup {
        Setup {
            robot_distance_mm,
            mandrel_height_mm: 300.0,
            offset_mm: 100.0,
            arm: Arm::default(),
            entry_angle_max_rad: ENTRY_ANGLE_MAX_DEG.to_radians(),
            calibration: Calibration::default(),
            gearing: Gearing::default(),
            six_axis,
        }
    }

    fn speeds(movement: Movement) -> Speeds {
        Speeds {
            mandrel: MandrelProfile {
                accel_rps2: 1.0,
                start_stop_rps: 0.05,
                max_rps: 0.1,
            },
            base_speed_mm_s: 1000.0,
            max_speed_mm_s: 1500.0,
            movement,
        }
    }

    fn cylinder_points() -> (Tube, Vec<SurfacePoint>) {
        let tube = Tube::cylinder(63.5, 178.0, 0.0, 0.0).unwrap();
        let start = PathStart {
            angle_rad: 0.0,
            wind_angle_rad: 48.3f64.to_radians(),
            direction: Direction::Up,
        };
        let path = geodesic::helix(&tube, &start, 1.0).unwrap();
        let points = equal_length(&tube, &path, 50).unwrap();
        (tube, points)
    }

    /// The shoulder of the IRB 2600 stands at (a1, 0, c1) = (150, 0, 445) mm with its joints at
    /// 0: a vertical axis through (800, 0) sees it 650 mm off on its −x side (no turn); an axis
    /// through (150, 650) sees it on its −y side, a quarter turn clockwise of −x.
    #[test]
    fn the_robot_faces_the_mandrel_from_its_shoulder() {
        let arm = irb2600();
        let cell = |origin: [f64; 3], direction: [f64; 3]| SixAxisCell {
            arm,
            axis: MandrelAxis::new(origin, direction, MandrelDrive::Indexer).unwrap(),
        };
        let (b, turn) = facing(&cell([800.0, 0.0, 300.0], [0.0, 0.0, 1.0]));
        assert!((b - 650.0).abs() < 1e-9 && turn.abs() < 1e-12, "{b} {turn}");
        let (b, turn) = facing(&cell([150.0, 650.0, 0.0], [0.0, 0.0, 1.0]));
        assert!((b - 650.0).abs() < 1e-9, "{b}");
        // atan2(−650, 0) − π = −3π/2, a quarter turn counter-clockwise (the same angle).
        assert!(
            (turn.rem_euclid(std::f64::consts::TAU) - FRAC_PI_2).abs() < 1e-12,
            "{turn}"
        );
    }

    /// In the thesis geometry (vertical axis) the six-axis plan's mandrel angles and steps are
    /// eq 3.7's for a robot at the shoulder's distance: those of the IRB 6/2 plan with `b`
    /// = 650 mm. The eye (mandrel frame) is the same; only the arm differs.
    #[test]
    fn a_vertical_axis_gives_the_thesis_mandrel_angles_and_steps() {
        let (tube, points) = cylinder_points();
        let clearance = |p: &Point3<f64>| tube.distance_to_surface_mm(p);
        let six = SixAxisCell {
            arm: irb2600(),
            axis: MandrelAxis::new([800.0, 0.0, 300.0], [0.0, 0.0, 1.0], MandrelDrive::Robot)
                .unwrap(),
        };
        let s = speeds(Movement::Fine);
        let six_plan = plan_path(&points, clearance, &setup(800.0, Some(six)), &s).unwrap();
        let irb_plan = plan_path(&points, clearance, &setup(650.0, None), &s).unwrap();
        assert_eq!(six_plan.segments.len(), irb_plan.segments.len());
        for (a, b) in six_plan.segments.iter().zip(&irb_plan.segments) {
            assert_eq!(a.steps, b.steps);
            assert!((a.pose.ideal_mandrel_rad - b.pose.ideal_mandrel_rad).abs() < 1e-12);
            assert!((a.pose.eye_mandrel_mm - b.pose.eye_mandrel_mm).norm() < 1e-9);
            // Coupled: the external axis is the commanded mandrel angle.
            let ArmJoints::SixAxis {
                joints,
                tool_q,
                external_rad,
            } = a.pose.joints
            else {
                panic!("a six-axis pose");
            };
            assert_eq!(external_rad, Some(a.pose.mandrel_rad));
            // The joints put the eye at the pose's eye, the tool's z along the tow line.
            let frame = six.arm.tool_frame(&joints);
            assert!((frame.origin() - a.pose.eye_mm).norm() < 1e-6);
            let tangent = six
                .axis
                .to_base(a.pose.mandrel_rad, &a.pose.tangent_point_mm);
            let tow = (tangent - a.pose.eye_mm).normalize();
            assert!((tool_q * Vector3::z()).angle(&tow) < 1e-6);
            assert!((a.pose.wrist_q * Vector3::x()).angle(&tow) < 1e-6);
            assert!(a.pose.entry_angle_rad < 1e-6);
        }
        assert!(matches!(six_plan.arm, PathArm::SixAxis(_)));
        // The same steps, so the same drift from the ideal angles (at most half a step).
        assert!((six_plan.max_drift_rad - irb_plan.max_drift_rad).abs() < 1e-12);
        assert!(six_plan.max_drift_rad > 0.0);
        assert!(six_plan.max_drift_rad <= 0.5 * Gearing::default().step_angle_rad() + 1e-12);
        // An eye inside the mandrel (or a clearance that is not a number) is refused.
        for inside in [-1.0, 0.0, f64::NAN] {
            let e = plan_path(&points, |_| inside, &setup(800.0, Some(six)), &s);
            assert!(
                matches!(e, Err(crate::Error::EyeInsideMandrel { segment: 0, .. })),
                "{inside}: {e:?}"
            );
        }
        // Decoupled: no external axis.
        let decoupled = SixAxisCell {
            axis: MandrelAxis {
                drive: MandrelDrive::Indexer,
                ..six.axis
            },
            ..six
        };
        let p = plan_path(&points, clearance, &setup(800.0, Some(decoupled)), &s).unwrap();
        assert!(p.segments.iter().all(|seg| matches!(
            seg.pose.joints,
            ArmJoints::SixAxis {
                external_rad: None,
                ..
            }
        )));
    }

    /// The robot's least time is the longer of the straight travel at the controller's speed and
    /// the largest joint turn at its speed (by hand: 150 mm at 1500 mm/s = 0.1 s; 35° of axis 1
    /// at 175°/s = 0.2 s).
    #[test]
    fn robot_time_is_the_longer_of_travel_and_joint_turn() {
        let arm = irb2600();
        let s = speeds(Movement::Discrete);
        let pose = |x: f64, q1_deg: f64| Pose {
            tangent_point_mm: Point3::origin(),
            normal: Vector3::z(),
            eye_mandrel_mm: Point3::origin(),
            eye_mm: Point3::new(x, 0.0, 0.0),
            joints: ArmJoints::SixAxis {
                joints: [q1_deg.to_radians(), 0.0, 0.0, 0.0, 0.0, 0.0],
                tool_q: UnitQuaternion::identity(),
                external_rad: None,
            },
            entry_angle_rad: 0.0,
            wrist_q: UnitQuaternion::identity(),
            ideal_mandrel_rad: 0.0,
            mandrel_rad: 0.0,
        };
        let t = robot_time_s(&arm, &s, &pose(0.0, 0.0), &pose(150.0, 0.0));
        assert!((t - 0.1).abs() < 1e-12, "{t}");
        let t = robot_time_s(&arm, &s, &pose(0.0, 0.0), &pose(150.0, 35.0));
        assert!((t - 0.2).abs() < 1e-12, "{t}");
        let t = robot_time_s(&arm, &s, &pose(0.0, 10.0), &pose(3.0, -25.0));
        assert!((t - 0.2).abs() < 1e-12, "{t}");
    }

    /// The joints that put the tool where a pose has it are the pose's own, on its
    /// configuration.
    #[test]
    fn joints_for_a_tool_pose_return_the_joints_that_made_it() {
        let arm = SixAxisArm::ur_preset(
            "ur10e",
            Tool {
                tcp_mm: [10.0, 20.0, 150.0],
                rpy_deg: [5.0, 10.0, 15.0],
            },
        )
        .unwrap();
        for q in [
            [0.3, -1.2, 1.4, -0.5, 1.1, 0.7],
            [-2.0, -0.6, -1.9, 2.2, -0.8, -1.5],
        ] {
            let frame = arm.tool_frame(&q);
            let config = arm.kind.config_of(&q);
            let back = joints_for_tool(&arm, &frame.origin(), &frame.quaternion(), config).unwrap();
            let again = arm.tool_frame(&back);
            assert!((again.origin() - frame.origin()).norm() < 1e-9);
            assert!(again.quaternion().angle_to(&frame.quaternion()) < 1e-9);
            assert_eq!(arm.kind.config_of(&back), config);
        }
    }

    /// No point of the links moves further than `Σ |Δqⱼ| · lever[j]` for a small joint move (the
    /// bound the check's Lipschitz constant rests on), over random moves.
    #[test]
    fn lever_arms_bound_how_far_the_links_move() {
        for arm in [
            irb2600(),
            SixAxisArm::ur_preset("ur10e", Tool::default()).unwrap(),
        ] {
            let levers = lever_arms_mm(&arm, 150.0);
            let mut seed = 0x2545_f491_4f6c_dd1du64;
            let mut next = || {
                seed ^= seed << 13;
                seed ^= seed >> 7;
                seed ^= seed << 17;
                (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
            };
            for _ in 0..500 {
                let q: Joints6 = std::array::from_fn(|_| 3.0 * next());
                let dq: Joints6 = std::array::from_fn(|_| 1e-4 * next());
                let q2: Joints6 = std::array::from_fn(|j| q[j] + dq[j]);
                let bound: f64 = (0..6).map(|j| dq[j].abs() * levers[j]).sum();
                let (a, b) = (arm.kind.link_points(&q), arm.kind.link_points(&q2));
                for i in 0..7 {
                    assert!((b[i] - a[i]).norm() <= bound * (1.0 + 1e-6) + 1e-12);
                }
                let moved = (arm.tool_frame(&q2).origin() - arm.tool_frame(&q).origin()).norm();
                assert!(moved <= bound * (1.0 + 1e-6) + 1e-12);
            }
        }
    }
    /// Per link: a small joint move moves link `k`'s ends no further than `Σ_{j≤k} |Δqⱼ| ·
    /// lever[k][j]`, and the joints after it do not move it at all; the wrist link and the tool
    /// sit still in the tool frame whatever the joints (so on a straight move they move as the
    /// frame does), within their reach of the eye.
    #[test]
    fn link_levers_and_tool_reach_bound_each_link() {
        for arm in [
            irb2600(),
            SixAxisArm::ur_preset("ur10e", Tool::default()).unwrap(),
        ] {
            let levers = link_lever_arms_mm(&arm);
            let reach = tool_reach_mm(&arm);
            assert!(reach[..5].iter().all(Option::is_none));
            let ends = |q: &Joints6| {
                let p = arm.kind.link_points(q);
                let eye = arm.tool_frame(q).origin();
                let at = |i: usize| if i < 7 { p[i] } else { eye };
                std::array::from_fn::<_, 7, _>(|k| [at(k), at(k + 1)])
            };
            let mut uniform = crate::clearance::test_support::uniform(0x9e37_79b9_7f4a_7c15);
            let mut next = || uniform() * 2.0 - 1.0;
            let in_tool = |q: &Joints6, p: &Point3<f64>| {
                let f = arm.tool_frame(q);
                f.rotation.transpose() * (p.coords - f.translation_mm)
            };
            let home = [0.0; 6];
            for _ in 0..500 {
                let q: Joints6 = std::array::from_fn(|_| 3.0 * next());
                let dq: Joints6 = std::array::from_fn(|_| 1e-4 * next());
                let q2: Joints6 = std::array::from_fn(|j| q[j] + dq[j]);
                let (a, b) = (ends(&q), ends(&q2));
                for k in 0..7 {
                    let bound: f64 = (0..6).map(|j| dq[j].abs() * levers[k][j]).sum();
                    for e in 0..2 {
                        let moved = (b[k][e] - a[k][e]).norm();
                        assert!(
                            moved <= bound * (1.0 + 1e-6) + 1e-12,
                            "link {k}: {moved} > {bound}"
                        );
                    }
                    // Only the joints up to the link's own move it.
                    let later: Joints6 = std::array::from_fn(|j| if j > k { q2[j] } else { q[j] });
                    let c = ends(&later);
                    for e in 0..2 {
                        assert!(
                            (c[k][e] - a[k][e]).norm() < 1e-9,
                            "link {k} moved by a later joint"
                        );
                    }
                }
                for k in 5..7 {
                    let r = reach[k].unwrap();
                    for (e, end) in a[k].iter().enumerate() {
                        let here = in_tool(&q, end);
                        let there = in_tool(&home, &ends(&home)[k][e]);
                        assert!(
                            (here - there).norm() < 1e-6,
                            "link {k} moves in the tool frame"
                        );
                        assert!(here.norm() <= r + 1e-9, "link {k} beyond its reach {r}");
                    }
                }
            }
        }
    }

    /// The lever arms by hand from the makers' figures. The IRB 2600's chain from the base
    /// through its link points (OPW `c1`, `a1`, `c2`, `|a2|`, `c3`, `c4`) to the eye 200 mm out
    /// on the flange is 445, 150, 700, 115, 795, 85 and 200 mm long; the UR10e's DH origins
    /// (`d1`, `|a2|`, `|a3|`, `d4`, `d5`, `d6` of UR's table) with the eye at the flange 180.7,
    /// 612.7, 571.55, 174.15, 119.85, 116.55 and 0 mm. Link `k`'s lever for joint `j ≤ k` is the
    /// chain from link point `j` to the link's far end, 0 for the joints after it; the whole
    /// arm's is the chain to the eye plus the eye mechanism (150 mm here); the wrist link and the
    /// tool reach as far from the eye as the wrist centre and the flange are.
    #[test]
    fn lever_arms_are_the_chain_lengths_by_hand() {
        let ur10e = SixAxisArm::ur_preset("ur10e", Tool::default()).unwrap();
        for (arm, chain, wrist_reach, tool_reach) in [
            (
                irb2600(),
                [445.0, 150.0, 700.0, 115.0, 795.0, 85.0, 200.0],
                285.0,
                200.0,
            ),
            (
                ur10e,
                [180.7, 612.7, 571.55, 174.15, 119.85, 116.55, 0.0],
                116.55,
                0.0,
            ),
        ] {
            let mut along = [0.0f64; 8];
            for i in 1..8 {
                along[i] = along[i - 1] + chain[i - 1];
            }
            let levers = link_lever_arms_mm(&arm);
            for (k, row) in levers.iter().enumerate() {
                for (j, lever) in row.iter().enumerate() {
                    let want = if j <= k { along[k + 1] - along[j] } else { 0.0 };
                    assert!(
                        (lever - want).abs() < 1e-9,
                        "link {k} joint {j}: {lever} vs {want}"
                    );
                }
            }
            let whole = lever_arms_mm(&arm, 150.0);
            for (j, lever) in whole.iter().enumerate() {
                let want = along[7] - along[j] + 150.0;
                assert!((lever - want).abs() < 1e-9, "joint {j}: {lever} vs {want}");
            }
            let reach = tool_reach_mm(&arm);
            assert!(reach[..5].iter().all(Option::is_none));
            assert!((reach[5].unwrap() - wrist_reach).abs() < 1e-9, "{reach:?}");
            assert!((reach[6].unwrap() - tool_reach).abs() < 1e-9, "{reach:?}");
        }
    }
}
