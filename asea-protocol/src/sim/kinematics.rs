//! Which poses the simulated arm can take (seed 001 §4.1.1: a five-axis revolute arm, base yaw,
//! two links, wrist pitch and roll, no wrist yaw). A pose it cannot take is refused with
//! [`RobotError::Kinematics`] (code 9), as the real controller refuses it: at once for an
//! immediate move, at the instruction for a program (standby check or operate run).
//!
//! Two models behind one trait:
//! - [`ArmModel`], the default of `sim::Machine`: the arm of [`paths::robot::Arm`]. The eye's
//!   roll axis is the quaternion's X axis (App. A: pitch about Y, then roll about the new X; the
//!   eye mechanism sits on the roll axis, §4.1.3), and the pose must have an inverse solution
//!   (elbow up or down) inside every joint range. A roll axis out of the arm's vertical plane
//!   needs a wrist yaw and is refused (beyond [`WIRE_YAW_TOLERANCE_RAD`]). The planner's poses
//!   carry the roll axis in that plane (tool x of `paths::robot`), so they are taken.
//! - [`Reach`]: the eye within a radius of the base axis and inside the wire's z range, any
//!   wrist orientation (opt-in with `Machine::with_kinematics`).

use nalgebra::{Quaternion, Unit, UnitQuaternion, Vector3};
use paths::robot::Arm;

use crate::command::RobotError;

/// A check of one target pose: eye position (mm, robot base frame) and wrist quaternion
/// (w, x, y, z).
pub trait Kinematics: std::fmt::Debug + Send + Sync {
    /// `Ok` if the arm can take the pose, else the robot's error.
    fn check(&self, eye_mm: [f64; 3], q_wxyz: [f64; 4]) -> Result<(), RobotError>;
}

/// Largest distance of the eye from the base axis in the [`Reach`] model, mm (the IRB 6/2's
/// links, 450 + 670 mm, with the eye mechanism and wrist: ours).
pub const REACH_MM: f64 = 1600.0;

/// The radius model: the eye within `reach_mm` of the base axis, |z| within the wire range.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reach {
    /// Largest distance from the base axis, mm.
    pub reach_mm: f64,
}

impl Default for Reach {
    fn default() -> Self {
        Reach { reach_mm: REACH_MM }
    }
}

impl Kinematics for Reach {
    fn check(&self, eye_mm: [f64; 3], _q: [f64; 4]) -> Result<(), RobotError> {
        let radial = eye_mm[0].hypot(eye_mm[1]);
        if radial <= self.reach_mm && eye_mm[2].abs() <= 2047.9375 {
            Ok(())
        } else {
            Err(RobotError::Kinematics)
        }
    }
}

/// The five-axis arm of [`paths::robot::Arm`].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ArmModel {
    /// Link lengths and joint ranges.
    pub arm: Arm,
}

impl ArmModel {
    /// The eye's roll axis for the wrist quaternion: its X axis.
    pub fn roll_axis(q_wxyz: [f64; 4]) -> Unit<Vector3<f64>> {
        let q = UnitQuaternion::from_quaternion(Quaternion::new(
            q_wxyz[0], q_wxyz[1], q_wxyz[2], q_wxyz[3],
        ));
        Unit::new_normalize(q * Vector3::x())
    }
}

/// [`paths::robot::WIRE_YAW_TOLERANCE_RAD`], re-exported where the simulator's model is read.
pub use paths::robot::WIRE_YAW_TOLERANCE_RAD;

impl ArmModel {
    /// [`paths::robot::in_arm_plane`].
    pub fn in_arm_plane(eye_mm: [f64; 3], axis: Unit<Vector3<f64>>) -> Option<Unit<Vector3<f64>>> {
        paths::robot::in_arm_plane(eye_mm, axis)
    }
}

impl Kinematics for ArmModel {
    /// [`Arm::takes_pose`]: the one decision the pre-run check makes too.
    fn check(&self, eye_mm: [f64; 3], q_wxyz: [f64; 4]) -> Result<(), RobotError> {
        if self.arm.takes_pose(eye_mm, q_wxyz) {
            Ok(())
        } else {
            Err(RobotError::Kinematics)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use paths::robot::{Arm, Joints};

    /// The forward pose of a joint set inside the ranges is accepted; the same eye with its roll
    /// axis turned out of the arm plane (a wrist yaw) is refused, and so is a pose beyond reach.
    #[test]
    fn the_arm_takes_its_own_poses_and_refuses_a_wrist_yaw() {
        let model = ArmModel::default();
        let j = Joints {
            base_yaw_rad: 0.3,
            shoulder_rad: 0.2,
            elbow_rad: 0.1,
            pitch_rad: -0.4,
            roll_rad: 0.0,
        };
        let pose = model.arm.forward(&j);
        let q = pose.orientation;
        let wxyz = [q.w, q.i, q.j, q.k];
        // The quaternion's X axis is the roll axis the forward model reports.
        let axis = ArmModel::roll_axis(wxyz);
        assert!((axis.as_ref() - pose.roll_axis.as_ref()).norm() < 1e-9);
        let eye = [pose.eye_mm.x, pose.eye_mm.y, pose.eye_mm.z];
        assert_eq!(model.check(eye, wxyz), Ok(()));
        // Yaw the wrist 20° about the vertical at the eye: out of the arm plane.
        let yaw = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 20f64.to_radians()) * q;
        let yawed = [yaw.w, yaw.i, yaw.j, yaw.k];
        assert_eq!(model.check(eye, yawed), Err(RobotError::Kinematics));
        // Twice the links' reach away.
        assert_eq!(
            model.check([3000.0, 0.0, 500.0], [1.0, 0.0, 0.0, 0.0]),
            Err(RobotError::Kinematics)
        );
        // The radius model takes the yawed pose but not the far one.
        assert_eq!(Reach::default().check(eye, yawed), Ok(()));
        assert_eq!(
            Reach::default().check([1700.0, 0.0, 0.0], wxyz),
            Err(RobotError::Kinematics)
        );
    }

    /// An eye on the base axis lies in every vertical plane through it, so no roll axis there
    /// needs a wrist yaw. The eye mechanism then points back over the pedestal (roll axis at more
    /// than 90° from the arm's outward direction), which the default arm's pitch (±90°) cannot
    /// take; an arm whose pitch turns to ±170° can: base yaw 0, forearm −60°, pitch 150° (roll
    /// axis 30° below the horizontal, pointing at −x), the wrist 150 mm · cos 30° out, so that
    /// the 150 mm eye mechanism ends on the axis.
    #[test]
    fn an_eye_on_the_base_axis_is_in_every_arm_plane() {
        let mut arm = Arm::default();
        arm.joints[3].min_rad = (-170f64).to_radians();
        arm.joints[3].max_rad = 170f64.to_radians();
        let model = ArmModel { arm };
        let elbow = (-60f64).to_radians();
        let wrist_rho = 150.0 * 30f64.to_radians().cos();
        // 450 sin(shoulder) + 670 cos(forearm) = the wrist's distance from the axis.
        let shoulder = ((wrist_rho - 670.0 * elbow.cos()) / 450.0).asin();
        let j = Joints {
            base_yaw_rad: 0.0,
            shoulder_rad: shoulder,
            elbow_rad: elbow,
            pitch_rad: 150f64.to_radians(),
            roll_rad: 0.0,
        };
        let pose = model.arm.forward(&j);
        assert!(pose.eye_mm.x.hypot(pose.eye_mm.y) < 1e-9);
        let q = pose.orientation;
        let wxyz = [q.w, q.i, q.j, q.k];
        let eye = [0.0, 0.0, pose.eye_mm.z];
        assert_eq!(model.check(eye, wxyz), Ok(()));
        let axis = ArmModel::roll_axis(wxyz);
        let kept = ArmModel::in_arm_plane(eye, axis).expect("on the axis every plane holds it");
        assert!((kept.as_ref() - axis.as_ref()).norm() < 1e-12);
        // The default arm refuses the same pose: its pitch stops at 90°.
        assert_eq!(
            ArmModel::default().check(eye, wxyz),
            Err(RobotError::Kinematics)
        );
    }

    /// Within the wire's resolution a roll axis off the arm plane is turned into it; a yaw
    /// beyond it is refused. Measured at a point 30° round the base axis, so that the plane is
    /// not the xz plane.
    #[test]
    fn the_wire_resolution_is_not_a_wrist_yaw() {
        let model = ArmModel::default();
        let az = 30f64.to_radians();
        let eye = [900.0 * az.cos(), 900.0 * az.sin(), 700.0];
        let at = |off_rad: f64| {
            let q = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), az + off_rad);
            model.check(eye, [q.w, q.i, q.j, q.k])
        };
        assert_eq!(at(0.0), Ok(()));
        assert_eq!(at(0.5 * WIRE_YAW_TOLERANCE_RAD), Ok(()));
        assert_eq!(at(-0.9 * WIRE_YAW_TOLERANCE_RAD), Ok(()));
        assert_eq!(
            at(1.5 * WIRE_YAW_TOLERANCE_RAD),
            Err(RobotError::Kinematics)
        );
        assert_eq!(
            at(-1.5 * WIRE_YAW_TOLERANCE_RAD),
            Err(RobotError::Kinematics)
        );
        // The turned axis lies in the plane through the eye and the base axis.
        let q = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), az + 5e-4);
        let u = ArmModel::in_arm_plane(eye, ArmModel::roll_axis([q.w, q.i, q.j, q.k])).unwrap();
        assert!((u.y * az.cos() - u.x * az.sin()).abs() < 1e-12);
    }
}
