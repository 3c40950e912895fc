//! The robot arm: a five-axis revolute arm of the ASEA IRB 6/2 class (seed 001 §4.1.1: "a five
//! degrees of freedom industrial robot … a revolute robot with a stationary base pedestal and two
//! rigid rectangular box links … the wrist joint has pitch and roll but not yaw motion"), carrying
//! the payout eye on the roll axis (§4.1.3).
//!
//! # Model and frames
//! The **cell frame** has its origin on the pedestal axis at the robot base, `z` up. The joints,
//! in order ([`Joints`]):
//! 1. `base_yaw_rad` turns the **arm plane** (the vertical plane through the pedestal axis and the
//!    wrist) about `z`; its horizontal unit vector is `r̂ = (cos q1, sin q1, 0)`.
//! 2. `shoulder_rad`: the upper arm's angle from the vertical, positive leaning toward `r̂`. The
//!    shoulder axis lies on the pedestal axis at `shoulder_height_mm`.
//! 3. `elbow_rad`: the forearm's elevation above the horizontal.
//! 4. `pitch_rad`: the roll axis's angle below the horizontal, in the arm plane (App. A's pitch θ).
//!
//! Axes 3 and 4 are measured against the horizontal, not against the previous link: the IRB 6/2
//! drives its arms "using harmonic drives and linkages" (§4.1.1), parallel linkages from motors on
//! the base, so each of these joints sets its link's angle to the ground (assumption: the seed
//! names the linkages but not their geometry).
//! 5. `roll_rad`: the turn about the roll axis, which sets the plane of the eye's rocker arm.
//!
//! In the arm plane, with angles measured from `r̂` toward `z`, the upper arm points at
//! `π/2 − q2`, the forearm at `a_f = q3` and the roll axis at `a_r = −q4`. The wrist
//! (pitch axis) is at the forearm's end; the eye sits on the roll axis `eye_mechanism_mm` beyond
//! it. With no wrist yaw, **the roll axis always lies in the arm plane**: the only orientations a
//! 5-axis arm can take are those whose roll axis lies in the vertical plane through the pedestal
//! axis and the eye.
//!
//! The orientation is App. A's pitch-then-roll in the arm frame, turned by the base yaw:
//! `q = R_z(q1) · R_y(θ) · R_x(Φ)` with `θ = q4` the roll axis's pitch (positive nose down) and
//! `Φ = q5`; the tool `x` axis is the roll axis ([`ArmPose::orientation`]).
//!
//! # API
//! - [`Arm`]: geometry, joint limits and speeds; `Arm::default()` is the IRB 6/2 (see its
//!   documentation for where each figure comes from).
//! - [`Arm::forward`]: [`Joints`] → [`ArmPose`] (eye, wrist, roll axis, orientation).
//! - [`Arm::inverse`]: eye, roll axis, roll and [`ElbowBranch`] → [`Joints`], or an error when the
//!   roll axis leaves the arm plane or the wrist is out of reach; [`Arm::check_joints`] for the
//!   limits (inverse does not check them, so that a caller can report which limit a pose breaks).
//! - [`Arm::links`]: one [`Capsule`] per link (pedestal, upper arm, forearm, wrist, eye
//!   mechanism) for collision checks.
//! - [`Arm::max_tool_speed_mm_s`]: the fastest the eye can move in a direction at a pose with
//!   the wrist held fixed in the arm frame, from the joint speed limits (630 mm/s retracted to
//!   2300 mm/s extended for the IRB 6/2, §4.1.1), and [`Arm::joint_time_s`] for a joint move.

use std::f64::consts::{FRAC_PI_2, PI, TAU};
use std::fmt;

use nalgebra::{Point3, Unit, UnitQuaternion, Vector3};

use crate::{Error, wrist};

/// One of the five joints.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Joint {
    /// Axis 1: base yaw about the pedestal axis.
    BaseYaw,
    /// Axis 2: shoulder (upper arm).
    Shoulder,
    /// Axis 3: elbow (forearm).
    Elbow,
    /// Axis 4: wrist pitch.
    Pitch,
    /// Axis 5: wrist roll.
    Roll,
}

impl Joint {
    /// The five joints in axis order.
    pub const ALL: [Joint; 5] = [
        Joint::BaseYaw,
        Joint::Shoulder,
        Joint::Elbow,
        Joint::Pitch,
        Joint::Roll,
    ];

    /// The joint's name in the cell file and in messages.
    pub fn name(self) -> &'static str {
        match self {
            Joint::BaseYaw => "base_yaw",
            Joint::Shoulder => "shoulder",
            Joint::Elbow => "elbow",
            Joint::Pitch => "pitch",
            Joint::Roll => "roll",
        }
    }
}

impl fmt::Display for Joint {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Joint angles, radians (conventions in the module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Joints {
    /// Axis 1, base yaw.
    pub base_yaw_rad: f64,
    /// Axis 2, upper arm from the vertical.
    pub shoulder_rad: f64,
    /// Axis 3, forearm elevation above the horizontal.
    pub elbow_rad: f64,
    /// Axis 4, roll axis below the horizontal (App. A's pitch θ).
    pub pitch_rad: f64,
    /// Axis 5, turn about the roll axis.
    pub roll_rad: f64,
}

impl Joints {
    /// The angles in axis order.
    pub fn to_array(&self) -> [f64; 5] {
        [
            self.base_yaw_rad,
            self.shoulder_rad,
            self.elbow_rad,
            self.pitch_rad,
            self.roll_rad,
        ]
    }

    /// The angles in axis order, degrees.
    pub fn to_degrees(&self) -> [f64; 5] {
        self.to_array().map(f64::to_degrees)
    }

    /// App. A's pitch θ (about the arm frame's `y`, positive nose down): the roll axis's angle
    /// below the horizontal, which axis 4's linkage sets directly.
    pub fn app_a_pitch_rad(&self) -> f64 {
        self.pitch_rad
    }
}

/// Which of the two arm configurations reaches a wrist position.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ElbowBranch {
    /// The elbow above the line from the shoulder to the wrist: the forearm bends down from the
    /// upper arm's direction (`π/2 − shoulder − elbow` in (0, π) after wrapping).
    Up,
    /// The elbow below it (the bend in (−π, 0)).
    Down,
}

/// The range and speed of one joint.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointLimit {
    /// Least angle, rad.
    pub min_rad: f64,
    /// Greatest angle, rad.
    pub max_rad: f64,
    /// Fastest turn, rad/s.
    pub max_speed_rad_s: f64,
}

impl JointLimit {
    fn degrees(min_deg: f64, max_deg: f64, speed_deg_s: f64) -> Self {
        JointLimit {
            min_rad: min_deg.to_radians(),
            max_rad: max_deg.to_radians(),
            max_speed_rad_s: speed_deg_s.to_radians(),
        }
    }
}

/// A segment with a radius: the volume a link sweeps, cell frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Capsule {
    /// One end of the axis.
    pub a: Point3<f64>,
    /// The other end.
    pub b: Point3<f64>,
    /// Radius about the axis, mm.
    pub radius_mm: f64,
}

/// Where the arm puts the eye, cell frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArmPose {
    /// The payout eye.
    pub eye_mm: Point3<f64>,
    /// The wrist (pitch axis, on the roll axis).
    pub wrist_mm: Point3<f64>,
    /// The roll axis, from the wrist toward the eye.
    pub roll_axis: Unit<Vector3<f64>>,
    /// `R_z(q1) · R_y(θ) · R_x(Φ)` (App. A's quaternion composed with the base yaw); its `x` axis
    /// is the roll axis, its `x–z` plane the rocker arm's plane.
    pub orientation: UnitQuaternion<f64>,
}

/// Why the arm cannot take a pose (inside [`Error::Arm`]).
#[derive(Debug, Clone, PartialEq)]
pub enum ArmFault {
    /// The wrist is farther from, or nearer to, the shoulder than the two links reach.
    OutOfReach {
        /// Shoulder-to-wrist distance asked for.
        distance_mm: f64,
        /// Least reachable (|upper arm − forearm|).
        min_mm: f64,
        /// Greatest reachable (upper arm + forearm).
        max_mm: f64,
    },
    /// The wrist lies on the pedestal axis: the base yaw is undefined.
    WristOnPedestalAxis,
    /// The roll axis leaves the vertical plane through the pedestal axis and the wrist (no wrist
    /// yaw).
    OffArmPlane {
        /// Angle between the roll axis and the arm plane.
        angle_deg: f64,
    },
    /// A joint outside its range.
    JointLimit {
        /// Which joint.
        joint: Joint,
        /// The angle asked for.
        value_deg: f64,
        /// Its range.
        min_deg: f64,
        /// Its range.
        max_deg: f64,
    },
    /// A joint would jump between consecutive poses (a branch or wrap change).
    JointJump {
        /// Which joint.
        joint: Joint,
        /// The change.
        change_deg: f64,
        /// The largest accepted change.
        limit_deg: f64,
    },
}

impl fmt::Display for ArmFault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ArmFault::OutOfReach {
                distance_mm,
                min_mm,
                max_mm,
            } => write!(
                f,
                "the wrist is {distance_mm:.1} mm from the shoulder, outside the arm's reach \
                 {min_mm:.1}–{max_mm:.1} mm"
            ),
            ArmFault::WristOnPedestalAxis => f.write_str("the wrist lies on the pedestal axis"),
            ArmFault::OffArmPlane { angle_deg } => write!(
                f,
                "the roll axis leaves the arm plane by {angle_deg:.3}° (the wrist has no yaw)"
            ),
            ArmFault::JointLimit {
                joint,
                value_deg,
                min_deg,
                max_deg,
            } => write!(
                f,
                "joint {joint} at {value_deg:.2}° is outside its range {min_deg:.1}°..{max_deg:.1}°"
            ),
            ArmFault::JointJump {
                joint,
                change_deg,
                limit_deg,
            } => write!(
                f,
                "joint {joint} jumps {change_deg:.2}° from the previous pose (more than {limit_deg}°)"
            ),
        }
    }
}

/// The arm: link lengths, joint ranges and speeds, and the payout-eye mechanism.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Arm {
    /// Height of the shoulder axis above the base, on the pedestal axis.
    pub shoulder_height_mm: f64,
    /// Shoulder axis to elbow axis.
    pub upper_arm_mm: f64,
    /// Elbow axis to wrist (pitch) axis.
    pub forearm_mm: f64,
    /// Wrist to payout eye along the roll axis (seed 001 §5.6 f).
    pub eye_mechanism_mm: f64,
    /// The longest eye mechanism the wrist can carry.
    pub eye_mechanism_max_mm: f64,
    /// Ranges and speeds in axis order ([`Joint::ALL`]).
    pub joints: [JointLimit; 5],
    /// Radii of the link capsules in [`Arm::links`] order: pedestal, upper arm, forearm, wrist,
    /// eye mechanism.
    pub link_radii_mm: [f64; 5],
    /// The largest change of any joint between consecutive poses of a path; a larger one is a
    /// branch or wrap switch, not a motion.
    pub joint_jump_max_rad: f64,
}

/// The IRB 6/2's extended wrist radius for §4.1.1's 2300 mm/s: `upper_arm + forearm`.
const IRB6_REACH_MM: f64 = 450.0 + 670.0;

impl Default for Arm {
    /// An IRB 6/2. Seed 001 §4.1.1 gives five axes (base yaw, two links, wrist pitch and roll, no
    /// yaw) and the tool speeds, 2300 mm/s with the arm extended and 630 mm/s retracted; nothing
    /// else. Every other figure here is an **assumption** for an arm of this class, to be replaced
    /// by the real robot's in `[cell.robot]`:
    /// - shoulder 300 mm above the base, upper arm 450 mm, forearm 670 mm (assumption; reach
    ///   about 1.1 m from the shoulder);
    /// - ranges: base yaw ±170°, shoulder −40°..+60° from the vertical (leaning toward the
    ///   mandrel positive), forearm elevation −60°..+30°,
    ///   pitch ±90°, roll ±180° (assumption);
    /// - base yaw speed `2300 mm/s ÷ 1120 mm = 117.7°/s`, so that the base yaw carries the wrist
    ///   stretched out horizontally at §4.1.1's 2300 mm/s; the same joint speed gives 630 mm/s at
    ///   307 mm from the pedestal axis, the arm retracted (derived from §4.1.1);
    /// - shoulder 60°/s, elbow 70°/s, pitch 195°/s, roll 240°/s (assumption);
    /// - eye mechanism at most 400 mm long (assumption: the rated 6 kg load, §4.1.1, at a lever
    ///   no longer than the wrist housing allows);
    /// - capsule radii 250 (pedestal), 100, 80, 70 and 25 mm (assumption);
    /// - a joint jump between consecutive poses above 45° is a branch switch (assumption).
    fn default() -> Self {
        Arm {
            shoulder_height_mm: 300.0,
            upper_arm_mm: 450.0,
            forearm_mm: 670.0,
            eye_mechanism_mm: 150.0,
            eye_mechanism_max_mm: 400.0,
            joints: [
                JointLimit {
                    min_rad: (-170f64).to_radians(),
                    max_rad: 170f64.to_radians(),
                    max_speed_rad_s: 2300.0 / IRB6_REACH_MM,
                },
                JointLimit::degrees(-40.0, 60.0, 60.0),
                JointLimit::degrees(-60.0, 30.0, 70.0),
                JointLimit::degrees(-90.0, 90.0, 195.0),
                JointLimit::degrees(-180.0, 180.0, 240.0),
            ],
            link_radii_mm: [250.0, 100.0, 80.0, 70.0, 25.0],
            joint_jump_max_rad: 45f64.to_radians(),
        }
    }
}

fn fault(fault: ArmFault) -> Error {
    Error::Arm {
        segment: None,
        fault,
    }
}

/// Wraps an angle into (−π, π] (one add for the sums of arctangents inverse kinematics makes,
/// a floating remainder otherwise).
fn wrap(a: f64) -> f64 {
    if a > -PI && a <= PI {
        a
    } else if a > PI && a <= PI + TAU {
        let w = a - TAU;
        if w > -PI { w } else { PI }
    } else if a <= -PI && a > -PI - TAU {
        a + TAU
    } else {
        let w = a.rem_euclid(TAU);
        if w > PI { w - TAU } else { w }
    }
}

/// The sines and cosines of a pose's yaw, shoulder, elbow and pitch, from which the arm's speed
/// limits at the pose follow ([`Arm::max_tool_speed_at`]). Inverse kinematics finds them on the
/// way to the angles ([`Arm::inverse_with_trig`]); [`JointTrig::of`] computes them from joints.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointTrig {
    /// sin, cos of the base yaw.
    pub yaw: (f64, f64),
    /// sin, cos of the shoulder angle.
    pub shoulder: (f64, f64),
    /// sin, cos of the elbow angle.
    pub elbow: (f64, f64),
    /// cos of the pitch.
    pub cos_pitch: f64,
}

impl JointTrig {
    /// From the joint angles.
    pub fn of(j: &Joints) -> Self {
        JointTrig {
            yaw: j.base_yaw_rad.sin_cos(),
            shoulder: j.shoulder_rad.sin_cos(),
            elbow: j.elbow_rad.sin_cos(),
            cos_pitch: j.pitch_rad.cos(),
        }
    }
}

/// Largest angle between the eye's roll axis and the arm's vertical plane that the controller
/// takes as in the plane, rad ([`Arm::takes_pose`]): the resolution of the pose on the wire, not a
/// wrist yaw. A Q1.14 quaternion component (1/16384 = 6.1 × 10⁻⁵) turns the axis by up to about
/// 2.5 × 10⁻⁴ rad, and a 0.0625 mm coordinate tilts the plane through an eye 300 mm from the base
/// axis by up to 3 × 10⁻⁴ rad; 1 × 10⁻³ rad (0.057°) is above both, and far below any yaw a path
/// asks for (ours).
pub const WIRE_YAW_TOLERANCE_RAD: f64 = 1.0e-3;

/// The roll axis turned into the vertical plane through the base axis and the eye (the plane the
/// five axes can point it in: base yaw, then pitches), if it is out of that plane by no more than
/// [`WIRE_YAW_TOLERANCE_RAD`]; `None` if it needs a wrist yaw.
pub fn in_arm_plane(eye_mm: [f64; 3], axis: Unit<Vector3<f64>>) -> Option<Unit<Vector3<f64>>> {
    let rho = eye_mm[0].hypot(eye_mm[1]);
    if rho < 1e-9 {
        return Some(axis);
    }
    let n = Vector3::new(-eye_mm[1] / rho, eye_mm[0] / rho, 0.0);
    let off = n.dot(axis.as_ref());
    if off.abs() > WIRE_YAW_TOLERANCE_RAD.sin() {
        return None;
    }
    Unit::try_new(axis.into_inner() - n * off, 1e-12)
}

impl Arm {
    /// Checks every length, range and speed.
    pub fn validate(&self) -> Result<(), Error> {
        for (name, value) in [
            ("shoulder_height_mm", self.shoulder_height_mm),
            ("upper_arm_mm", self.upper_arm_mm),
            ("forearm_mm", self.forearm_mm),
            ("eye_mechanism_max_mm", self.eye_mechanism_max_mm),
            ("joint_jump_max_deg", self.joint_jump_max_rad.to_degrees()),
        ] {
            if !(value > 0.0 && value.is_finite()) {
                return Err(Error::OutOfRange {
                    name,
                    value,
                    expected: "must be > 0",
                });
            }
        }
        if !(self.eye_mechanism_mm >= 0.0 && self.eye_mechanism_mm <= self.eye_mechanism_max_mm) {
            return Err(Error::OutOfRange {
                name: "eye_mechanism_length_mm",
                value: self.eye_mechanism_mm,
                expected: "must lie between 0 and the longest eye mechanism the arm can carry \
                           (eye_mechanism_max_mm)",
            });
        }
        for (joint, limit) in Joint::ALL.iter().zip(&self.joints) {
            if !(limit.min_rad.is_finite()
                && limit.max_rad.is_finite()
                && limit.min_rad < limit.max_rad)
            {
                return Err(Error::OutOfRange {
                    name: joint_range_name(*joint),
                    value: limit.max_rad.to_degrees(),
                    expected: "must be finite and above the least angle",
                });
            }
            if !(limit.max_speed_rad_s > 0.0 && limit.max_speed_rad_s.is_finite()) {
                return Err(Error::OutOfRange {
                    name: "joint_speed_deg_s",
                    value: limit.max_speed_rad_s.to_degrees(),
                    expected: "must be > 0",
                });
            }
        }
        for r in self.link_radii_mm {
            if !(r >= 0.0 && r.is_finite()) {
                return Err(Error::OutOfRange {
                    name: "link_radii_mm",
                    value: r,
                    expected: "must be ≥ 0",
                });
            }
        }
        Ok(())
    }

    /// Where the joints put the eye, wrist and roll axis (cell frame).
    pub fn forward(&self, j: &Joints) -> ArmPose {
        let (s1, c1) = j.base_yaw_rad.sin_cos();
        let (s2, c2) = j.shoulder_rad.sin_cos();
        let (sf, cf) = j.elbow_rad.sin_cos();
        let a_r = -j.pitch_rad;
        let (sr, cr) = a_r.sin_cos();
        let wrist_rho = self.upper_arm_mm * s2 + self.forearm_mm * cf;
        let wrist_z = self.shoulder_height_mm + self.upper_arm_mm * c2 + self.forearm_mm * sf;
        let roll_axis = Vector3::new(cr * c1, cr * s1, sr);
        let wrist_mm = Point3::new(wrist_rho * c1, wrist_rho * s1, wrist_z);
        ArmPose {
            eye_mm: wrist_mm + roll_axis * self.eye_mechanism_mm,
            wrist_mm,
            roll_axis: Unit::new_unchecked(roll_axis),
            orientation: UnitQuaternion::from_axis_angle(&Vector3::z_axis(), j.base_yaw_rad)
                * wrist::from_pitch_roll(-a_r, j.roll_rad),
        }
    }

    /// The joints that put the eye at `eye_mm` with the roll axis along `roll_axis` (from the
    /// wrist toward the eye) and the roll at `roll_rad`, on the given elbow branch. Refuses a roll
    /// axis more than 1e-9 rad out of the arm plane and a wrist out of reach; does not check the
    /// joint ranges ([`Arm::check_joints`]). Angles are wrapped into (−π, π] except the roll.
    pub fn inverse(
        &self,
        eye_mm: &Point3<f64>,
        roll_axis: &Unit<Vector3<f64>>,
        roll_rad: f64,
        branch: ElbowBranch,
    ) -> Result<Joints, Error> {
        self.inverse_with_trig(eye_mm, roll_axis, roll_rad, branch)
            .map(|(j, _)| j)
    }

    /// [`Arm::inverse`], with the sines and cosines of the angles found (for
    /// [`Arm::max_tool_speed_at`]). The shoulder and forearm directions come from rotating the
    /// shoulder-to-wrist vector by the triangle's angles as complex products, one arctangent each.
    pub fn inverse_with_trig(
        &self,
        eye_mm: &Point3<f64>,
        roll_axis: &Unit<Vector3<f64>>,
        roll_rad: f64,
        branch: ElbowBranch,
    ) -> Result<(Joints, JointTrig), Error> {
        let u = roll_axis.as_ref();
        let w = eye_mm - u * self.eye_mechanism_mm;
        let rho = (w.x * w.x + w.y * w.y).sqrt();
        if rho < 1e-9 {
            return Err(fault(ArmFault::WristOnPedestalAxis));
        }
        let (c1, s1) = (w.x / rho, w.y / rho);
        let out_of_plane = -s1 * u.x + c1 * u.y;
        if out_of_plane.abs() > 1e-9 {
            return Err(fault(ArmFault::OffArmPlane {
                angle_deg: out_of_plane.clamp(-1.0, 1.0).asin().to_degrees(),
            }));
        }
        let u_r = c1 * u.x + s1 * u.y;
        let a_r = u.z.atan2(u_r);
        let (l1, l2) = (self.upper_arm_mm, self.forearm_mm);
        let z = w.z - self.shoulder_height_mm;
        let d2 = rho * rho + z * z;
        let cos_g = (d2 - l1 * l1 - l2 * l2) / (2.0 * l1 * l2);
        if !(-1.0..=1.0).contains(&cos_g) {
            return Err(fault(ArmFault::OutOfReach {
                distance_mm: d2.sqrt(),
                min_mm: (l1 - l2).abs(),
                max_mm: l1 + l2,
            }));
        }
        let sin_g = ((1.0 - cos_g) * (1.0 + cos_g)).sqrt();
        let sign = match branch {
            ElbowBranch::Up => 1.0,
            ElbowBranch::Down => -1.0,
        };
        // Upper arm: (ρ, z) turned by atan2(±l2 sin γ, l1 + l2 cos γ); forearm: that turned
        // back by ∓γ. Both are (ρ, z)-scaled directions; their arctangents are the angles.
        let (tr, tz) = (l1 + l2 * cos_g, sign * l2 * sin_g);
        let (ur, uz) = (rho * tr - z * tz, rho * tz + z * tr);
        let (fr, fz) = (
            ur * cos_g + uz * sign * sin_g,
            uz * cos_g - ur * sign * sin_g,
        );
        let a_u = uz.atan2(ur);
        let a_f = fz.atan2(fr);
        let (nu, nf) = (
            (ur * ur + uz * uz).sqrt().max(f64::MIN_POSITIVE),
            (fr * fr + fz * fz).sqrt().max(f64::MIN_POSITIVE),
        );
        Ok((
            Joints {
                base_yaw_rad: s1.atan2(c1),
                shoulder_rad: wrap(FRAC_PI_2 - a_u),
                elbow_rad: a_f,
                pitch_rad: wrap(-a_r),
                roll_rad,
            },
            JointTrig {
                yaw: (s1, c1),
                // shoulder = π/2 − a_u: sin = cos a_u, cos = sin a_u.
                shoulder: (ur / nu, uz / nu),
                elbow: (fz / nf, fr / nf),
                cos_pitch: u_r,
            },
        ))
    }

    /// True when the arm can take the eye pose `eye_mm` (cell frame) with the wrist quaternion
    /// `q_wxyz` (scalar first), as the robot controller decides it (seed 001 §4.1.1, App. A):
    /// the eye's roll axis is the quaternion's X axis; five axes can point it only in the
    /// vertical plane through the base axis and the eye, so an axis out of that plane by more
    /// than [`WIRE_YAW_TOLERANCE_RAD`] (a wrist yaw) is refused; the rest must have an inverse
    /// solution, elbow up or down, inside every joint range. A quaternion that is not finite or
    /// has no direction is refused.
    pub fn takes_pose(&self, eye_mm: [f64; 3], q_wxyz: [f64; 4]) -> bool {
        let q = nalgebra::Quaternion::new(q_wxyz[0], q_wxyz[1], q_wxyz[2], q_wxyz[3]);
        if !(q.norm().is_finite() && q.norm() > 0.0) {
            return false;
        }
        let roll_axis = UnitQuaternion::from_quaternion(q) * Vector3::x_axis();
        let Some(axis) = in_arm_plane(eye_mm, roll_axis) else {
            return false;
        };
        let eye = Point3::new(eye_mm[0], eye_mm[1], eye_mm[2]);
        [ElbowBranch::Up, ElbowBranch::Down]
            .into_iter()
            .any(|branch| {
                self.inverse(&eye, &axis, 0.0, branch)
                    .is_ok_and(|j| self.check_joints(&j).is_ok())
            })
    }

    /// The first joint outside its range, as an error.
    pub fn check_joints(&self, j: &Joints) -> Result<(), Error> {
        for ((joint, limit), value) in Joint::ALL.iter().zip(&self.joints).zip(j.to_array()) {
            if !(value >= limit.min_rad && value <= limit.max_rad) {
                return Err(fault(ArmFault::JointLimit {
                    joint: *joint,
                    value_deg: value.to_degrees(),
                    min_deg: limit.min_rad.to_degrees(),
                    max_deg: limit.max_rad.to_degrees(),
                }));
            }
        }
        Ok(())
    }

    /// The first joint that changes by more than [`Arm::joint_jump_max_rad`] from `previous` to
    /// `next`, as an error (joint-space continuity between consecutive poses).
    pub fn check_continuity(&self, previous: &Joints, next: &Joints) -> Result<(), Error> {
        for ((joint, a), b) in Joint::ALL
            .iter()
            .zip(previous.to_array())
            .zip(next.to_array())
        {
            let change = (b - a).abs();
            if change > self.joint_jump_max_rad || change.is_nan() {
                return Err(fault(ArmFault::JointJump {
                    joint: *joint,
                    change_deg: change.to_degrees(),
                    limit_deg: self.joint_jump_max_rad.to_degrees(),
                }));
            }
        }
        Ok(())
    }

    /// The least time for a joint move from `from` to `to` with every joint at most at its speed
    /// limit, s.
    pub fn joint_time_s(&self, from: &Joints, to: &Joints) -> f64 {
        from.to_array()
            .iter()
            .zip(to.to_array())
            .zip(&self.joints)
            .map(|((a, b), limit)| (b - a).abs() / limit.max_speed_rad_s)
            .fold(0.0, f64::max)
    }

    /// The link capsules, cell frame: pedestal (base to shoulder), upper arm (shoulder to elbow),
    /// forearm (elbow to wrist), wrist (a sphere at the wrist) and eye mechanism (wrist to eye).
    pub fn links(&self, j: &Joints) -> [Capsule; 5] {
        let pose = self.forward(j);
        let (s1, c1) = j.base_yaw_rad.sin_cos();
        let (s2, c2) = j.shoulder_rad.sin_cos();
        let shoulder = Point3::new(0.0, 0.0, self.shoulder_height_mm);
        let elbow = Point3::new(
            self.upper_arm_mm * s2 * c1,
            self.upper_arm_mm * s2 * s1,
            self.shoulder_height_mm + self.upper_arm_mm * c2,
        );
        let r = self.link_radii_mm;
        [
            Capsule {
                a: Point3::origin(),
                b: shoulder,
                radius_mm: r[0],
            },
            Capsule {
                a: shoulder,
                b: elbow,
                radius_mm: r[1],
            },
            Capsule {
                a: elbow,
                b: pose.wrist_mm,
                radius_mm: r[2],
            },
            Capsule {
                a: pose.wrist_mm,
                b: pose.wrist_mm,
                radius_mm: r[3],
            },
            Capsule {
                a: pose.wrist_mm,
                b: pose.eye_mm,
                radius_mm: r[4],
            },
        ]
    }

    /// The fastest the eye can move along `direction` at the pose `j`, mm/s, with the wrist held
    /// fixed in the arm frame (the roll axis keeps its pitch and roll): the joint
    /// rates for a unit eye velocity come from the arm's Jacobian, and the speed is the least
    /// `max_speed / |rate|` over the joints. 0 at a singular pose (arm stretched or folded) when
    /// the direction needs the singular one.
    pub fn max_tool_speed_mm_s(&self, j: &Joints, direction: &Unit<Vector3<f64>>) -> f64 {
        self.max_tool_speed_at(&JointTrig::of(j), direction)
    }

    /// [`Arm::max_tool_speed_mm_s`] from the pose's sines and cosines.
    pub fn max_tool_speed_at(&self, t: &JointTrig, direction: &Unit<Vector3<f64>>) -> f64 {
        let rates = self.joint_rates_at(t, direction.as_ref());
        rates
            .iter()
            .zip(&self.joints)
            .map(|(rate, limit)| {
                if *rate == 0.0 {
                    f64::INFINITY
                } else {
                    limit.max_speed_rad_s / rate.abs()
                }
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// Joint rates (rad/s) for the eye velocity `v` (mm/s) with the wrist fixed in the arm frame;
    /// infinite where the pose is singular for `v`.
    pub fn joint_rates(&self, j: &Joints, v: &Vector3<f64>) -> [f64; 5] {
        self.joint_rates_at(&JointTrig::of(j), v)
    }

    /// [`Arm::joint_rates`] from the pose's sines and cosines.
    pub fn joint_rates_at(&self, t: &JointTrig, v: &Vector3<f64>) -> [f64; 5] {
        let (s1, c1) = t.yaw;
        let (s2, c2) = t.shoulder;
        let (sf, cf) = t.elbow;
        let (l1, l2) = (self.upper_arm_mm, self.forearm_mm);
        let eye_rho = l1 * s2 + l2 * cf + self.eye_mechanism_mm * t.cos_pitch;
        let v_t = -s1 * v.x + c1 * v.y;
        let v_r = c1 * v.x + s1 * v.y;
        let v_z = v.z;
        let yaw_rate = if v_t == 0.0 { 0.0 } else { v_t / eye_rho.abs() };
        // In the arm plane: ∂(ρ, z)/∂q2 = (l1 c2, −l1 s2), ∂/∂q3 = (−l2 sf, l2 cf); the
        // determinant is l1 l2 cos(q2 + q3), 0 with the arm stretched or folded.
        let (j2r, j2z) = (l1 * c2, -l1 * s2);
        let (j3r, j3z) = (-l2 * sf, l2 * cf);
        let det = j2r * j3z - j3r * j2z;
        let (q2, q3) = if v_r == 0.0 && v_z == 0.0 {
            (0.0, 0.0)
        } else if det.abs() < 1e-9 * l1 * l2 {
            (f64::INFINITY, f64::INFINITY)
        } else {
            ((v_r * j3z - j3r * v_z) / det, (j2r * v_z - v_r * j2z) / det)
        };
        // The wrist keeps its pitch (axis 4 is referred to the horizontal) and roll.
        [yaw_rate, q2, q3, 0.0, 0.0]
    }
}

fn joint_range_name(joint: Joint) -> &'static str {
    match joint {
        Joint::BaseYaw => "base_yaw_deg",
        Joint::Shoulder => "shoulder_deg",
        Joint::Elbow => "elbow_deg",
        Joint::Pitch => "pitch_deg",
        Joint::Roll => "roll_deg",
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;

    /// The controller's decision, by cases worked from the arm's own geometry: a pose the
    /// forward model makes from joints inside the ranges is taken; the same eye with its roll
    /// axis yawed 20° out of the arm's plane (a wrist yaw the five axes lack) is not, nor 0.5°
    /// out (above the wire's 0.057° allowance) while 0.02° is; a quaternion of no direction and
    /// an eye beyond both links are not; joints outside a range make a pose that is refused.
    #[test]
    fn takes_pose_accepts_the_arms_own_poses_and_nothing_a_five_axis_wrist_cannot_reach() {
        let arm = Arm::default();
        let j = Joints {
            base_yaw_rad: 0.3,
            shoulder_rad: 0.2,
            elbow_rad: 0.1,
            pitch_rad: -0.4,
            roll_rad: 0.0,
        };
        let pose = arm.forward(&j);
        let eye = [pose.eye_mm.x, pose.eye_mm.y, pose.eye_mm.z];
        let wxyz = |q: UnitQuaternion<f64>| [q.w, q.i, q.j, q.k];
        assert!(arm.takes_pose(eye, wxyz(pose.orientation)));
        // A yaw about the vertical through the eye turns the roll axis out of the arm's plane.
        let yawed = |deg: f64| {
            wxyz(
                UnitQuaternion::from_axis_angle(&Vector3::z_axis(), deg.to_radians())
                    * pose.orientation,
            )
        };
        assert!(!arm.takes_pose(eye, yawed(20.0)));
        assert!(!arm.takes_pose(eye, yawed(0.5)));
        assert!(arm.takes_pose(eye, yawed(0.02)));
        assert!(!arm.takes_pose(eye, [0.0; 4]));
        assert!(!arm.takes_pose(eye, [f64::NAN, 0.0, 0.0, 1.0]));
        // Beyond reach: the eye pushed out along its radius by both links' length.
        let far = arm.upper_arm_mm + arm.forearm_mm;
        let out = [
            eye[0] + far * 0.3f64.cos(),
            eye[1] + far * 0.3f64.sin(),
            eye[2],
        ];
        assert!(!arm.takes_pose(out, wxyz(pose.orientation)));
        // A pose whose only solutions put a joint outside its range: the pitch far past its
        // limit on a roll axis pointing back at the base.
        let limit = arm.joints[3].max_rad;
        let past = Joints {
            pitch_rad: limit + 0.3,
            ..j
        };
        let p = arm.forward(&past);
        let e = [p.eye_mm.x, p.eye_mm.y, p.eye_mm.z];
        assert!(arm.check_joints(&past).is_err());
        assert!([ElbowBranch::Up, ElbowBranch::Down].iter().all(|&b| {
            arm.inverse(&p.eye_mm, &p.roll_axis, 0.0, b)
                .map_or(true, |k| arm.check_joints(&k).is_err())
        }));
        assert!(!arm.takes_pose(e, wxyz(p.orientation)));
    }

    /// Every figure of the arm is checked, and the one that is wrong is named: each length and
    /// the jump limit at 0, below 0, infinite and NaN; the eye mechanism below 0, above the
    /// longest the arm carries (and exactly that longest, which is taken); each joint's range
    /// empty, reversed or infinite at either end and its speed at 0 or infinite; a link radius
    /// below 0 or infinite (0 is taken).
    #[test]
    fn every_figure_of_the_arm_is_checked_by_name() {
        let ok = Arm::default();
        assert!(ok.validate().is_ok());
        let named = |arm: Arm| match arm.validate() {
            Err(Error::OutOfRange { name, .. }) => name,
            other => panic!("{other:?}"),
        };
        for bad in [0.0, -1.0, f64::INFINITY, f64::NAN] {
            let cases: [(Arm, &str); 5] = [
                (
                    Arm {
                        shoulder_height_mm: bad,
                        ..ok
                    },
                    "shoulder_height_mm",
                ),
                (
                    Arm {
                        upper_arm_mm: bad,
                        ..ok
                    },
                    "upper_arm_mm",
                ),
                (
                    Arm {
                        forearm_mm: bad,
                        ..ok
                    },
                    "forearm_mm",
                ),
                (
                    Arm {
                        eye_mechanism_max_mm: bad,
                        eye_mechanism_mm: 0.0,
                        ..ok
                    },
                    "eye_mechanism_max_mm",
                ),
                (
                    Arm {
                        joint_jump_max_rad: bad,
                        ..ok
                    },
                    "joint_jump_max_deg",
                ),
            ];
            for (arm, name) in cases {
                assert_eq!(named(arm), name, "{bad}");
            }
        }
        let longest = ok.eye_mechanism_max_mm;
        assert!(
            Arm {
                eye_mechanism_mm: longest,
                ..ok
            }
            .validate()
            .is_ok()
        );
        assert!(
            Arm {
                eye_mechanism_mm: 0.0,
                ..ok
            }
            .validate()
            .is_ok()
        );
        for bad in [-0.1, longest + 0.1, f64::NAN] {
            assert_eq!(
                named(Arm {
                    eye_mechanism_mm: bad,
                    ..ok
                }),
                "eye_mechanism_length_mm"
            );
        }
        let names = [
            "base_yaw_deg",
            "shoulder_deg",
            "elbow_deg",
            "pitch_deg",
            "roll_deg",
        ];
        for (k, want) in names.iter().enumerate() {
            let with = |limit: JointLimit| {
                let mut arm = ok;
                arm.joints[k] = limit;
                arm
            };
            let j = ok.joints[k];
            for (min, max) in [
                (j.min_rad, j.min_rad),
                (j.max_rad, j.min_rad),
                (f64::NEG_INFINITY, j.max_rad),
                (j.min_rad, f64::INFINITY),
                (f64::NAN, j.max_rad),
            ] {
                let limit = JointLimit {
                    min_rad: min,
                    max_rad: max,
                    ..j
                };
                assert_eq!(named(with(limit)), *want, "{min} {max}");
            }
            for speed in [0.0, -1.0, f64::INFINITY] {
                let limit = JointLimit {
                    max_speed_rad_s: speed,
                    ..j
                };
                assert_eq!(named(with(limit)), "joint_speed_deg_s");
            }
        }
        for k in 0..5 {
            let mut arm = ok;
            arm.link_radii_mm[k] = 0.0;
            assert!(arm.validate().is_ok());
            for bad in [-0.5, f64::INFINITY] {
                arm.link_radii_mm[k] = bad;
                assert_eq!(named(arm), "link_radii_mm");
            }
        }
    }

    /// The names messages and cell files use, and the faults' messages with their figures.
    #[test]
    fn joints_and_faults_are_named_in_words() {
        let names: Vec<String> = Joint::ALL.iter().map(|j| j.to_string()).collect();
        assert_eq!(names, ["base_yaw", "shoulder", "elbow", "pitch", "roll"]);
        let j = Joints {
            base_yaw_rad: std::f64::consts::FRAC_PI_2,
            shoulder_rad: -std::f64::consts::FRAC_PI_4,
            elbow_rad: 0.0,
            pitch_rad: std::f64::consts::PI,
            roll_rad: -std::f64::consts::PI / 6.0,
        };
        let deg = j.to_degrees();
        for (got, want) in deg.iter().zip([90.0, -45.0, 0.0, 180.0, -30.0]) {
            assert!((got - want).abs() < 1e-12, "{deg:?}");
        }
        let faults = [
            (
                ArmFault::OutOfReach {
                    distance_mm: 1234.56,
                    min_mm: 100.0,
                    max_mm: 1100.0,
                },
                "the wrist is 1234.6 mm from the shoulder, outside the arm's reach 100.0–1100.0 mm",
            ),
            (
                ArmFault::WristOnPedestalAxis,
                "the wrist lies on the pedestal axis",
            ),
            (
                ArmFault::OffArmPlane { angle_deg: 1.5 },
                "the roll axis leaves the arm plane by 1.500° (the wrist has no yaw)",
            ),
            (
                ArmFault::JointLimit {
                    joint: Joint::Elbow,
                    value_deg: -61.0,
                    min_deg: -60.0,
                    max_deg: 60.0,
                },
                "joint elbow at -61.00° is outside its range -60.0°..60.0°",
            ),
            (
                ArmFault::JointJump {
                    joint: Joint::Roll,
                    change_deg: 200.0,
                    limit_deg: 90.0,
                },
                "joint roll jumps 200.00° from the previous pose (more than 90°)",
            ),
        ];
        for (fault, text) in faults {
            assert_eq!(fault.to_string(), text);
        }
    }

    /// A small seeded generator (xorshift64*), so the random poses are the same on every run.
    struct Seeded(u64);

    impl Seeded {
        fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            let bits = self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11;
            lo + (hi - lo) * (bits as f64 / (1u64 << 53) as f64)
        }
    }

    fn stretched() -> Joints {
        // Upper arm and forearm horizontal, roll axis horizontal along the arm.
        Joints {
            base_yaw_rad: 0.0,
            shoulder_rad: FRAC_PI_2,
            elbow_rad: 0.0,
            pitch_rad: 0.0,
            roll_rad: 0.0,
        }
    }

    #[test]
    fn forward_places_the_links_by_hand() {
        let arm = Arm::default();
        // All joints at 0: upper arm vertical, forearm and roll axis horizontal along +x.
        let p = arm.forward(&Joints::default());
        assert_abs_diff_eq!(p.wrist_mm, Point3::new(670.0, 0.0, 750.0), epsilon = 1e-12);
        assert_abs_diff_eq!(p.eye_mm, Point3::new(820.0, 0.0, 750.0), epsilon = 1e-12);
        // Stretched out and turned 90°: along +y at shoulder height.
        let j = Joints {
            base_yaw_rad: FRAC_PI_2,
            ..stretched()
        };
        let p = arm.forward(&j);
        assert_abs_diff_eq!(p.wrist_mm, Point3::new(0.0, 1120.0, 300.0), epsilon = 1e-9);
        assert_abs_diff_eq!(p.eye_mm, Point3::new(0.0, 1270.0, 300.0), epsilon = 1e-9);
        // Pitch 90° points the roll axis straight down; the orientation's x axis follows it.
        let j = Joints {
            pitch_rad: FRAC_PI_2,
            ..Joints::default()
        };
        let p = arm.forward(&j);
        assert_abs_diff_eq!(p.roll_axis.into_inner(), -Vector3::z(), epsilon = 1e-12);
        assert_abs_diff_eq!(p.eye_mm, Point3::new(670.0, 0.0, 600.0), epsilon = 1e-9);
        assert_abs_diff_eq!(p.orientation * Vector3::x(), -Vector3::z(), epsilon = 1e-12);
        // The orientation is App. A's quaternion (θ = 90°, Φ) turned by the base yaw.
        let j = Joints {
            base_yaw_rad: 0.3,
            roll_rad: 0.7,
            ..j
        };
        let q = arm.forward(&j).orientation;
        let expected = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 0.3)
            * wrist::from_pitch_roll(FRAC_PI_2, 0.7);
        assert_abs_diff_eq!(q.coords, expected.coords, epsilon = 1e-12);
    }

    #[test]
    fn inverse_round_trips_10000_random_reachable_poses_on_both_branches() {
        let arm = Arm::default();
        let mut rng = Seeded(0x5EED_0001);
        let mut tested = [0usize; 2];
        while tested[0] + tested[1] < 10_000 {
            let j = Joints {
                base_yaw_rad: rng.uniform(-3.0, 3.0),
                shoulder_rad: rng.uniform(-1.0, 1.2),
                elbow_rad: rng.uniform(-1.5, 2.5),
                pitch_rad: rng.uniform(-2.5, 2.5),
                roll_rad: rng.uniform(-3.0, 3.0),
            };
            let pose = arm.forward(&j);
            // Away from the singular stretched/folded arm, and the wrist in front of the pedestal
            // axis (behind it the same pose is reached with the base turned half a revolution).
            let (s1, c1) = j.base_yaw_rad.sin_cos();
            let ahead_mm = c1 * pose.wrist_mm.x + s1 * pose.wrist_mm.y;
            // The elbow's bend from the upper arm's direction to the forearm's.
            let bend = wrap(FRAC_PI_2 - j.shoulder_rad - j.elbow_rad);
            if bend.abs() < 0.02 || bend.abs() > PI - 0.02 || ahead_mm < 50.0 {
                continue;
            }
            let branch = if bend > 0.0 {
                ElbowBranch::Up
            } else {
                ElbowBranch::Down
            };
            tested[usize::from(branch == ElbowBranch::Down)] += 1;
            let back = arm
                .inverse(&pose.eye_mm, &pose.roll_axis, j.roll_rad, branch)
                .unwrap();
            let again = arm.forward(&back);
            assert!((again.eye_mm - pose.eye_mm).norm() < 1e-9, "{j:?}");
            assert!((again.wrist_mm - pose.wrist_mm).norm() < 1e-9, "{j:?}");
            // Angles from chord lengths (an arccos of a dot product cannot resolve 1e-9 rad).
            assert!((again.roll_axis.into_inner() - pose.roll_axis.into_inner()).norm() < 1e-9);
            let gap = (again.orientation.coords - pose.orientation.coords)
                .norm()
                .min((again.orientation.coords + pose.orientation.coords).norm());
            assert!(2.0 * gap < 1e-9, "{j:?}");
            for (a, b) in back.to_array().iter().zip(j.to_array()) {
                assert!(wrap(a - b).abs() < 1e-9, "{j:?} vs {back:?}");
            }
            // The sines and cosines found on the way are those of the angles found.
            let (_, trig) = arm
                .inverse_with_trig(&pose.eye_mm, &pose.roll_axis, j.roll_rad, branch)
                .unwrap();
            let of = JointTrig::of(&back);
            for (x, y) in [
                (trig.yaw, of.yaw),
                (trig.shoulder, of.shoulder),
                (trig.elbow, of.elbow),
                ((trig.cos_pitch, 0.0), (of.cos_pitch, 0.0)),
            ] {
                assert!(
                    (x.0 - y.0).abs() < 1e-12 && (x.1 - y.1).abs() < 1e-12,
                    "{j:?}"
                );
            }
        }
        assert!(tested.iter().all(|&n| n > 1000), "{tested:?}");
    }

    #[test]
    fn joint_time_is_the_slowest_joints_travel_over_its_speed() {
        let arm = Arm::default();
        // By hand: 30° of shoulder at 60°/s is 0.5 s; 14° of elbow at 70°/s is 0.2 s; 120° of
        // roll at 240°/s is 0.5 s; 58.85° of base yaw at 2300/1120 rad/s is 0.5002 s.
        let from = Joints::default();
        let to = Joints {
            shoulder_rad: 30f64.to_radians(),
            elbow_rad: -14f64.to_radians(),
            roll_rad: 120f64.to_radians(),
            ..from
        };
        assert_abs_diff_eq!(arm.joint_time_s(&from, &to), 0.5, epsilon = 1e-12);
        assert_abs_diff_eq!(arm.joint_time_s(&to, &from), 0.5, epsilon = 1e-12);
        let yaw = Joints {
            base_yaw_rad: 58.85f64.to_radians(),
            ..to
        };
        let expected = 58.85f64.to_radians() / (2300.0 / 1120.0);
        assert_abs_diff_eq!(arm.joint_time_s(&to, &yaw), expected, epsilon = 1e-12);
        assert_eq!(arm.joint_time_s(&to, &to), 0.0);
    }

    #[test]
    fn a_joint_change_of_exactly_the_jump_limit_is_a_motion() {
        let arm = Arm::default();
        let from = Joints::default();
        let at_limit = Joints {
            pitch_rad: arm.joint_jump_max_rad,
            ..from
        };
        assert!(arm.check_continuity(&from, &at_limit).is_ok());
        let beyond = Joints {
            pitch_rad: arm.joint_jump_max_rad * (1.0 + 1e-12),
            ..from
        };
        assert!(arm.check_continuity(&from, &beyond).is_err());
    }

    #[test]
    fn wrap_lands_in_the_half_open_turn_for_any_angle() {
        for k in -2000..=2000 {
            let a = k as f64 * 0.0173 + if k % 7 == 0 { PI } else { 0.0 };
            let w = wrap(a);
            assert!(w > -PI && w <= PI, "{a} -> {w}");
            // The same angle: a whole number of turns apart.
            let turns = (a - w) / TAU;
            assert!((turns - turns.round()).abs() < 1e-9, "{a} -> {w}");
        }
        assert_eq!(wrap(PI), PI);
        assert_eq!(wrap(-PI), PI);
        assert_eq!(wrap(3.0 * PI), PI);
        assert_eq!(wrap(0.5), 0.5);
        // −9π (as rounded) is beyond one turn, so it takes the general branch, whose remainder
        // is then exactly π: it must stay π, not become −π.
        assert_eq!((-9.0 * PI).rem_euclid(TAU), PI);
        assert_eq!(wrap(-9.0 * PI), PI);
    }

    #[test]
    fn unreachable_poses_are_refused() {
        let arm = Arm::default();
        let x = Unit::new_normalize(Vector3::x());
        let err = arm
            .inverse(&Point3::new(2000.0, 0.0, 500.0), &x, 0.0, ElbowBranch::Up)
            .unwrap_err();
        assert!(matches!(
            err,
            Error::Arm {
                fault: ArmFault::OutOfReach { max_mm, .. },
                ..
            } if max_mm == 1120.0
        ));
        // Too close to the shoulder for the two links (|450 − 670| = 220 mm).
        let err = arm
            .inverse(&Point3::new(250.0, 0.0, 400.0), &x, 0.0, ElbowBranch::Up)
            .unwrap_err();
        assert!(matches!(
            err,
            Error::Arm {
                fault: ArmFault::OutOfReach { min_mm, max_mm, .. },
                ..
            } if min_mm == 220.0 && max_mm == 1120.0
        ));
        // A roll axis 1° out of the arm plane: the wrist has no yaw.
        let off = Unit::new_normalize(Vector3::new(
            1f64.to_radians().cos(),
            1f64.to_radians().sin(),
            0.0,
        ));
        let err = arm
            .inverse(&Point3::new(800.0, 0.0, 600.0), &off, 0.0, ElbowBranch::Up)
            .unwrap_err();
        match err {
            Error::Arm {
                fault: ArmFault::OffArmPlane { angle_deg },
                ..
            } => {
                // The arm plane runs through the wrist, 150 mm back along the tilted axis.
                let (s, c) = 1f64.to_radians().sin_cos();
                let plane_deg = (150.0 * s).atan2(800.0 - 150.0 * c).to_degrees();
                assert_abs_diff_eq!(angle_deg, 1.0 + plane_deg, epsilon = 1e-9)
            }
            other => panic!("{other}"),
        }
        // The wrist on the pedestal axis.
        let err = arm
            .inverse(&Point3::new(150.0, 0.0, 900.0), &x, 0.0, ElbowBranch::Up)
            .unwrap_err();
        assert!(matches!(
            err,
            Error::Arm {
                fault: ArmFault::WristOnPedestalAxis,
                ..
            }
        ));
    }

    #[test]
    fn joint_limits_and_jumps_name_the_joint() {
        let arm = Arm::default();
        assert!(arm.check_joints(&Joints::default()).is_ok());
        let j = Joints {
            elbow_rad: 35f64.to_radians(),
            ..Joints::default()
        };
        match arm.check_joints(&j).unwrap_err() {
            Error::Arm {
                fault: ArmFault::JointLimit { joint, max_deg, .. },
                ..
            } => {
                assert_eq!(joint, Joint::Elbow);
                assert_abs_diff_eq!(max_deg, 30.0, epsilon = 1e-9);
            }
            other => panic!("{other}"),
        }
        let next = Joints {
            roll_rad: 50f64.to_radians(),
            ..Joints::default()
        };
        assert!(matches!(
            arm.check_continuity(&Joints::default(), &next).unwrap_err(),
            Error::Arm {
                fault: ArmFault::JointJump {
                    joint: Joint::Roll,
                    ..
                },
                ..
            }
        ));
        let small = Joints {
            roll_rad: 40f64.to_radians(),
            ..Joints::default()
        };
        assert!(arm.check_continuity(&Joints::default(), &small).is_ok());
        assert!(
            arm.check_joints(&Joints {
                base_yaw_rad: f64::NAN,
                ..Joints::default()
            })
            .is_err()
        );
    }

    #[test]
    fn tool_speed_spans_630_retracted_to_2300_extended() {
        // §4.1.1: 2300 mm/s with the arm extended, 630 mm/s retracted; the eye on the wrist.
        let arm = Arm {
            eye_mechanism_mm: 0.0,
            ..Arm::default()
        };
        let sideways = Unit::new_normalize(Vector3::y());
        assert_abs_diff_eq!(
            arm.max_tool_speed_mm_s(&stretched(), &sideways),
            2300.0,
            epsilon = 1e-9
        );
        let x = Unit::new_normalize(Vector3::x());
        let retracted_mm = 630.0 / 2300.0 * 1120.0;
        let j = arm
            .inverse(
                &Point3::new(retracted_mm, 0.0, 700.0),
                &x,
                0.0,
                ElbowBranch::Up,
            )
            .unwrap();
        assert_abs_diff_eq!(
            arm.max_tool_speed_mm_s(&j, &sideways),
            630.0,
            epsilon = 1e-9
        );
        // Stretched out, the arm cannot move along itself (singular).
        assert_eq!(arm.max_tool_speed_mm_s(&stretched(), &x), 0.0);
    }

    #[test]
    fn joint_rates_call_the_arm_singular_within_a_billionth_of_stretched() {
        // With the shoulder upright (q2 = 0) the forearm's angle from the horizontal is π/2 − δ;
        // the in-plane determinant is l1·l2·sin δ, and the arm is called singular (infinite
        // rates) when sin δ < 1e-9, a scale-free threshold on cos(q2 + q3).
        let arm = Arm::default();
        // Straight up, along the nearly stretched arm.
        let along = Vector3::new(0.0, 0.0, 1.0);
        let at = |delta: f64| JointTrig {
            yaw: (0.0, 1.0),
            shoulder: (0.0, 1.0),
            elbow: (delta.cos(), delta.sin()),
            cos_pitch: 1.0,
        };
        for delta in [1e-10, 5e-10] {
            let rates = arm.joint_rates_at(&at(delta), &along);
            assert!(
                rates[1].is_infinite() && rates[2].is_infinite(),
                "δ = {delta}: {rates:?}"
            );
        }
        for delta in [2e-9, 1e-8, 1e-6] {
            let rates = arm.joint_rates_at(&at(delta), &along);
            // Cramer's rule on [[l1, −l2 cos δ], [0, l2 sin δ]]·(q̇2, q̇3) = (0, 1): the elbow
            // turns at 1 / (l2 sin δ), finite however large.
            assert!(
                rates[1].is_finite() && rates[2].is_finite(),
                "δ = {delta}: {rates:?}"
            );
            let expect = 1.0 / (arm.forearm_mm * delta.sin());
            assert!(
                (rates[2].abs() / expect - 1.0).abs() < 1e-6,
                "δ = {delta}: {rates:?}"
            );
        }
    }

    #[test]
    fn joint_rates_move_the_eye_with_the_wrist_fixed_in_the_arm_frame() {
        // Independent check of the Jacobian: step the joints by the rates and difference the
        // forward kinematics.
        let arm = Arm::default();
        let mut rng = Seeded(42);
        for _ in 0..200 {
            let j = Joints {
                base_yaw_rad: rng.uniform(-2.0, 2.0),
                shoulder_rad: rng.uniform(-0.5, 0.9),
                elbow_rad: rng.uniform(-0.8, 0.4),
                pitch_rad: rng.uniform(-1.5, 1.5),
                roll_rad: rng.uniform(-1.0, 1.0),
            };
            let v = Vector3::new(
                rng.uniform(-1.0, 1.0),
                rng.uniform(-1.0, 1.0),
                rng.uniform(-1.0, 1.0),
            );
            let rates = arm.joint_rates(&j, &v);
            let h = 1e-6;
            let step = |s: f64| {
                let q = j.to_array();
                let q: Vec<f64> = q.iter().zip(rates).map(|(a, r)| a + s * h * r).collect();
                arm.forward(&Joints {
                    base_yaw_rad: q[0],
                    shoulder_rad: q[1],
                    elbow_rad: q[2],
                    pitch_rad: q[3],
                    roll_rad: q[4],
                })
            };
            let (plus, minus) = (step(1.0), step(-1.0));
            let velocity = (plus.eye_mm - minus.eye_mm) / (2.0 * h);
            assert_abs_diff_eq!(velocity, v, epsilon = 1e-6);
            // The roll axis keeps its elevation (it turns only with the base yaw).
            assert_abs_diff_eq!(plus.roll_axis.z, minus.roll_axis.z, epsilon = 1e-9);
            let speed = arm.max_tool_speed_mm_s(&j, &Unit::new_normalize(v));
            let worst = rates
                .iter()
                .zip(&arm.joints)
                .map(|(r, l)| r.abs() * speed / v.norm() / l.max_speed_rad_s)
                .fold(0.0, f64::max);
            assert_abs_diff_eq!(worst, 1.0, epsilon = 1e-9);
        }
    }

    #[test]
    fn capsules_chain_from_the_base_to_the_eye() {
        let arm = Arm::default();
        let j = Joints {
            base_yaw_rad: 0.4,
            shoulder_rad: 0.3,
            elbow_rad: -0.2,
            pitch_rad: 0.5,
            roll_rad: 1.0,
        };
        let links = arm.links(&j);
        let pose = arm.forward(&j);
        assert_eq!(links[0].a, Point3::origin());
        for pair in links.windows(2) {
            assert_abs_diff_eq!(pair[0].b, pair[1].a, epsilon = 1e-12);
        }
        assert_abs_diff_eq!(links[4].b, pose.eye_mm, epsilon = 1e-12);
        for (link, length) in links.iter().zip([300.0, 450.0, 670.0, 0.0, 150.0]) {
            assert_abs_diff_eq!((link.b - link.a).norm(), length, epsilon = 1e-9);
        }
        assert_eq!(links.map(|l| l.radius_mm), arm.link_radii_mm);
    }

    #[test]
    fn validation_refuses_an_eye_mechanism_too_long_to_carry() {
        assert!(Arm::default().validate().is_ok());
        let arm = Arm {
            eye_mechanism_mm: 600.0,
            ..Arm::default()
        };
        assert!(matches!(
            arm.validate(),
            Err(Error::OutOfRange {
                name: "eye_mechanism_length_mm",
                ..
            })
        ));
    }
}
