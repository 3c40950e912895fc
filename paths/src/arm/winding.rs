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
    let q = [0.0; 6];
    let p = arm.kind.link_points(&q);
    let eye = arm.tool_frame(&q).origin();
    let mut chain = [0.0; 8];
    // chain[i]: length from point i to the eye along the links.
    for i in (0..7).rev() {
        let next = if i + 1 < 7 { p[i + 1] } else { eye };
        chain[i] = (next - p[i]).norm() + chain[i + 1];
    }
    // Joint j's axis passes through link point j − 1 or a later one (the UR's DH origins lie on
    // the axes; an OPW arm's shoulder, elbow and wrist centre come one point later), and the
    // chain from an earlier point is the longer.
    std::array::from_fn(|j| chain[j] + extra_mm)
}
