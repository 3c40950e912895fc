//! The TOOL step for one path (seed 001 §5.6): from equal-length surface points to robot poses,
//! arm joints, mandrel angles, step counts, segment times and robot speeds.
//!
//! # Frames
//! - **mandrel frame**: fixed to the mandrel (see [`crate::mandrel`]).
//! - **drive frame**: the mandrel frame turned by the mandrel angle `φ` about `z` (see
//!   [`crate::tangent`]); the robot pedestal stands at `(−b, 0)`.
//! - **cell frame**: the robot base at the origin, `z` up, the rotation axis through `(b, 0)` at
//!   the mandrel frame's origin height `h`, as measured ([`crate::calibration`]; nominally
//!   vertical: `p_cell = (b, 0, h) + R_z(φ) p_mandrel`).
//!
//! # The eye pose the arm can take
//! The eye is placed for the **commanded** (step-quantised) mandrel angle, so that robot and
//! mandrel agree on where the fibre is. The arm has no wrist yaw, so the eye's roll axis lies in
//! the vertical plane through the pedestal axis and the eye ([`crate::robot`]); the tow line (eye
//! to tangent point) generally does not. The roll axis is the tow line's projection onto that
//! plane, which makes the **fibre entry angle** (tow line to roll axis) the least the arm allows:
//! `asin |t·n|`, `n` the plane's normal. The tow line then lies in the plane of the roll axis and
//! `n`, so the roll that turns the eye's rocker arm (§4.1.3) into the fibre's plane is 90° (App. A's
//! `Φ`; any roll serves when the entry angle is 0). The elbow branch is chosen at the start point
//! (up if it reaches the pose within the joint ranges, else down) and kept; every pose is checked
//! against the joint ranges and against a joint jump from the previous one.
//!
//! # Mandrel angle
//! Eq 3.7 gives the mandrel angle modulo a revolution. It is unwrapped by the path's own angle
//! around the spine ([`SurfacePoint::around_rad`], continuous along the path): `φ = β − α` with
//! `α` that angle and `β` the tangency angle, which lies within a quarter revolution of `±90°`.
//! A segment that turns the mandrel more than half a revolution is refused (its robot move could
//! not follow the fibre).
//!
//! # Time and speed
//! Each mandrel move is the indexer's trapezoid ([`crate::timing`]). In **discrete** movement each
//! segment is its own move and both devices start and stop together at every point (§6.4.1): the
//! segment lasts the mandrel move's time, or the robot's least time when that is longer — then the
//! segment's mandrel move is slowed to the robot's time ([`MandrelProfile::slowed_to`]) and the
//! segment says so. In **fine** and **medium** movement the mandrel turns through the path in one
//! move and the robot must keep up: each segment lasts the time the one move takes between the
//! segment's end angles, and a segment the robot cannot cover in that time is an error naming the
//! mandrel speed that would fit. The robot's least time for a segment is the longest of: the eye's
//! travel at the arm's fastest speed at either end pose in that direction
//! ([`Arm::max_tool_speed_mm_s`], 630–2300 mm/s for the IRB 6/2), the travel at the controller's
//! maximum speed, and the joint move at the joint speed limits.

use std::f64::consts::{FRAC_PI_2, TAU};

use nalgebra::{Point3, Unit, UnitQuaternion, Vector2, Vector3};

use crate::arm::{Joints6, MandrelAxis, PathReport as SixAxisReport, SixAxisArm};
use crate::calibration::{Calibration, CellTransform};
use crate::robot::{Arm, ArmFault, ElbowBranch, JointTrig, Joints};
use crate::segment::SurfacePoint;
use crate::step::{Gearing, RemainderCarrier};
use crate::tangent::{self, Flank};
use crate::timing::MandrelProfile;
use crate::{Error, eye, wrist};

/// The default largest fibre entry angle (tow line to the eye's roll axis), degrees. Assumption:
/// the thesis gives no figure; the spring-loaded rocker arm (§4.1.3) is taken to guide the tow
/// up to 30° off its axis.
pub const ENTRY_ANGLE_MAX_DEG: f64 = 30.0;

/// Where the robot and mandrel stand and how the eye is carried.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Setup {
    /// `b`: robot pedestal to the mandrel drive's rotation axis (seed 001 §3.2, §5.6 c).
    pub robot_distance_mm: f64,
    /// Height of the mandrel frame's origin above the robot base (seed 001 §5.6 d, the start height).
    pub mandrel_height_mm: f64,
    /// Tow distance from the tangent point to the eye (100 mm in the experiments, §6.4).
    pub offset_mm: f64,
    /// The arm, with the eye-mechanism length (§5.6 f) in [`Arm::eye_mechanism_mm`].
    pub arm: Arm,
    /// Largest fibre entry angle, rad ([`ENTRY_ANGLE_MAX_DEG`] by default).
    pub entry_angle_max_rad: f64,
    /// The measured cell.
    pub calibration: Calibration,
    /// The mandrel drive train.
    pub gearing: Gearing,
    /// A six-axis arm and where the mandrel turns in its base frame (`[cell.robot] kind = "opw"`
    /// or `"ur"`); `None` plans for the IRB 6/2 of `arm`. With a six-axis arm, `arm`,
    /// `robot_distance_mm`, `mandrel_height_mm` and the calibration's cell placement are not
    /// used: the mandrel axis gives the mandrel frame's place (the calibration's sense of
    /// rotation and zero still turn commanded angles into indexer positions).
    pub six_axis: Option<SixAxisCell>,
}

/// A six-axis arm in a cell ([`crate::arm`]): the arm and the mandrel's rotation axis in its base
/// frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SixAxisCell {
    /// The arm, its tool (the payout eye), limits, link radii and margins.
    pub arm: SixAxisArm,
    /// The mandrel's rotation axis in the robot base frame and who turns it.
    pub axis: MandrelAxis,
}

/// How robot and mandrel move together (seed 001 §5.4).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Movement {
    /// Robot and mandrel start and stop together at every point (§5.4.1, §6.4.1).
    Discrete,
    /// The robot flies through a 1 mm zone of each point while the mandrel turns (§5.4.2).
    Fine,
    /// As fine, with a wider zone.
    Medium,
    /// As medium, kept in step with the mandrel (ours; docs/continuous.md): every segment lasts
    /// at least the robot computer's time per instruction, so the robot never falls behind.
    Continuous {
        /// The robot's least time per flying instruction, s (its interpretation time).
        instruction_s: f64,
    },
}

/// Winding speeds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Speeds {
    /// The mandrel moves' profile: maximum velocity (§5.6 e), acceleration, start/stop velocity.
    pub mandrel: MandrelProfile,
    /// The robot's base speed; instruction speeds are percentages of it (§5.4.1).
    pub base_speed_mm_s: f64,
    /// The robot controller's maximum speed; no instruction asks for more.
    pub max_speed_mm_s: f64,
    /// Discrete, fine or medium.
    pub movement: Movement,
}

impl Setup {
    /// A mandrel-frame point in the cell frame (the robot base frame) with the mandrel at
    /// `angle_rad`: through the calibrated cell transform for the IRB 6/2, through the mandrel
    /// axis for a six-axis arm.
    pub fn mandrel_to_cell(&self, angle_rad: f64, p: &Point3<f64>) -> Point3<f64> {
        match &self.six_axis {
            Some(six) => six.axis.to_base(angle_rad, p),
            None => {
                let cell = self
                    .calibration
                    .transform(self.robot_distance_mm, self.mandrel_height_mm);
                let (s, c) = angle_rad.sin_cos();
                cell.to_cell(&Point3::new(c * p.x - s * p.y, s * p.x + c * p.y, p.z))
            }
        }
    }

    /// Checks every length, the arm and the calibration.
    pub fn validate(&self) -> Result<(), Error> {
        positive("robot_distance_mm", self.robot_distance_mm)?;
        positive("offset_mm", self.offset_mm)?;
        finite("mandrel_height_mm", self.mandrel_height_mm)?;
        if !(self.entry_angle_max_rad > 0.0 && self.entry_angle_max_rad <= FRAC_PI_2) {
            return Err(Error::OutOfRange {
                name: "entry_angle_max_deg",
                value: self.entry_angle_max_rad.to_degrees(),
                expected: "must lie in (0°, 90°]",
            });
        }
        if let Some(six) = &self.six_axis {
            six.arm.validate()?;
        } else {
            self.arm.validate()?;
        }
        self.calibration.validate()?;
        self.gearing.validate()
    }
}

impl Speeds {
    /// Checks every speed.
    pub fn validate(&self) -> Result<(), Error> {
        self.mandrel.validate()?;
        positive("base_speed_mm_s", self.base_speed_mm_s)?;
        positive("max_speed_mm_s", self.max_speed_mm_s)
    }
}

fn finite(name: &'static str, value: f64) -> Result<(), Error> {
    if value.is_finite() {
        Ok(())
    } else {
        Err(Error::OutOfRange {
            name,
            value,
            expected: "must be finite",
        })
    }
}

fn positive(name: &'static str, value: f64) -> Result<(), Error> {
    if value > 0.0 && value.is_finite() {
        Ok(())
    } else {
        Err(Error::OutOfRange {
            name,
            value,
            expected: "must be > 0",
        })
    }
}

/// The robot and mandrel pose at one segment end.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    /// Tangent point, mandrel frame.
    pub tangent_point_mm: Point3<f64>,
    /// Outward unit surface normal at the tangent point, mandrel frame.
    pub normal: Vector3<f64>,
    /// The eye, mandrel frame.
    pub eye_mandrel_mm: Point3<f64>,
    /// The eye, cell frame (at the commanded mandrel angle).
    pub eye_mm: Point3<f64>,
    /// The arm's joints for this pose.
    pub joints: ArmJoints,
    /// Fibre entry angle: the tow line (eye to tangent point) against the eye's roll axis, rad.
    pub entry_angle_rad: f64,
    /// Wrist orientation, cell frame, its `x` axis the eye's axis (toward the mandrel). IRB 6/2:
    /// App. A's pitch-then-roll composed with the base yaw (`R_z(q1) R_y(θ) R_x(Φ)`, `x` the roll
    /// axis); six-axis arms: the tool frame turned so that its `x` is the tool's `z`
    /// ([`ArmJoints::SixAxis`] keeps the tool frame itself). A continuous function of the joints,
    /// so it never flips sign along a path.
    pub wrist_q: UnitQuaternion<f64>,
    /// Eq 3.7 mandrel angle, unwrapped along the path.
    pub ideal_mandrel_rad: f64,
    /// Commanded mandrel angle (counter-clockwise from above): the start angle plus the
    /// commanded steps.
    pub mandrel_rad: f64,
}

/// One segment: its end pose and what the robot and mandrel are told to do to get there.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Segment {
    /// The pose at the segment's end.
    pub pose: Pose,
    /// Indexer steps for this segment, in the indexer's sense of rotation
    /// ([`Calibration::rotation_sign`]).
    pub steps: i64,
    /// The segment's time, s: both devices' in discrete movement, the mandrel's in fine/medium.
    pub duration_s: f64,
    /// The robot's least time for the segment at the arm's and controller's speed limits, s.
    pub robot_time_s: f64,
    /// The eye's speed, mm/s.
    pub speed_mm_s: f64,
    /// Robot speed as a percentage of the base speed.
    pub speed_pct: f64,
    /// This segment's mandrel move (discrete: slowed below the job's profile when the robot sets
    /// the time).
    pub mandrel: MandrelProfile,
    /// Discrete movement: the robot's time set the segment's time and the mandrel move was slowed.
    pub robot_paced: bool,
}

/// The arm's joints at one pose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ArmJoints {
    /// The IRB 6/2's five joints (seed 001 §4.1).
    Irb62(Joints),
    /// A six-axis arm ([`crate::arm`]).
    SixAxis {
        /// The controller's joint angles, rad.
        joints: Joints6,
        /// The tool frame's orientation in the base frame (`z` along the free fibre).
        tool_q: UnitQuaternion<f64>,
        /// The mandrel axis angle when the robot controller turns it (`drive = "robot"`), rad:
        /// the commanded mandrel angle.
        external_rad: Option<f64>,
    },
}

impl ArmJoints {
    /// The IRB 6/2's joints, `None` for a six-axis arm.
    pub fn irb62(&self) -> Option<&Joints> {
        match self {
            ArmJoints::Irb62(j) => Some(j),
            ArmJoints::SixAxis { .. } => None,
        }
    }

    /// Every joint angle in axis order, rad (5 or 6 values).
    pub fn to_array(&self) -> Vec<f64> {
        match self {
            ArmJoints::Irb62(j) => j.to_array().to_vec(),
            ArmJoints::SixAxis { joints, .. } => joints.to_vec(),
        }
    }

    /// Every joint angle in axis order, degrees (5 or 6 values).
    pub fn to_degrees(&self) -> Vec<f64> {
        self.to_array().into_iter().map(f64::to_degrees).collect()
    }
}

/// What a path kept of the arm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PathArm {
    /// The IRB 6/2's elbow branch, used for the whole path.
    Irb62(ElbowBranch),
    /// A six-axis arm's configuration and margins ([`crate::arm::path`]).
    SixAxis(SixAxisReport),
}

impl PathArm {
    /// The IRB 6/2's elbow branch, `None` for a six-axis arm.
    pub fn elbow(&self) -> Option<ElbowBranch> {
        match self {
            PathArm::Irb62(e) => Some(*e),
            PathArm::SixAxis(_) => None,
        }
    }
}

/// The plan for one path.
#[derive(Debug, Clone, PartialEq)]
pub struct PathPlan {
    /// The pose at the path's first point (where the mandrel is synchronised to the robot).
    pub start: Pose,
    /// One entry per segment.
    pub segments: Vec<Segment>,
    /// The indexer position at the start pose, in its own sense of rotation from its zero, rad.
    pub sync_drive_rad: f64,
    /// The configuration kept for the whole path.
    pub arm: PathArm,
    /// Worst |commanded − ideal| mandrel angle over the segment ends.
    pub max_drift_rad: f64,
    /// Least distance from the eye to the mandrel surface.
    pub min_eye_clearance_mm: f64,
    /// Worst fibre entry angle over the path's poses, rad.
    pub max_entry_angle_rad: f64,
}

/// Per-point results of the first pass: the eye (mandrel frame), eq 3.7's angle's cosine and
/// sine, and that angle unwrapped along the path, rad.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Prepared {
    pub(crate) eye: Point3<f64>,
    cos: f64,
    sin: f64,
    pub(crate) ideal: f64,
}

/// An arm fault at pose `segment`.
fn arm_error(error: Error, segment: usize) -> Error {
    match error {
        Error::Arm { fault, .. } => Error::Arm {
            segment: Some(segment),
            fault,
        },
        other => other,
    }
}

/// The eye's direction at the start: the path's tangent at the first point, from the one-sided
/// fourth-order difference `−25p0 + 48p1 − 36p2 + 16p3 − 3p4` of equal-length points (lower
/// orders for shorter paths, the chord `p1 − p0` for one segment), in the surface's tangent plane.
fn start_tangent(points: &[SurfacePoint]) -> Vector3<f64> {
    let p = |k: usize| points[k].point.coords;
    let t = match points.len() {
        2 => p(1) - p(0),
        3 => -3.0 * p(0) + 4.0 * p(1) - p(2),
        4 => -11.0 * p(0) + 18.0 * p(1) - 9.0 * p(2) + 2.0 * p(3),
        _ => -25.0 * p(0) + 48.0 * p(1) - 36.0 * p(2) + 16.0 * p(3) - 3.0 * p(4),
    };
    let n = points[0].normal;
    t - n * t.dot(&n)
}

/// Plans one path through `points` (equal-length segment ends on the mandrel, mandrel frame).
/// `clearance_mm` gives a point's distance to the mandrel surface (negative inside).
///
/// Three passes: the eye and eq 3.7's angle at every point ([`eyes_and_angles`]); the steps with
/// the remainder carried, the commanded angle and the arm's pose ([`Poser`]); the segments'
/// times and speeds ([`timed_segments`]).
pub fn plan(
    points: &[SurfacePoint],
    clearance_mm: impl Fn(&Point3<f64>) -> f64,
    setup: &Setup,
    speeds: &Speeds,
) -> Result<PathPlan, Error> {
    setup.validate()?;
    speeds.validate()?;
    if points.len() < 2 {
        return Err(Error::OutOfRange {
            name: "segments",
            value: points.len().saturating_sub(1) as f64,
            expected: "must be at least 1",
        });
    }
    if let Some(six) = &setup.six_axis {
        return crate::arm::winding::plan(points, clearance_mm, setup, six, speeds);
    }
    let cell: CellTransform = setup
        .calibration
        .transform(setup.robot_distance_mm, setup.mandrel_height_mm);
    let prepared = eyes_and_angles(points, setup, cell.robot_distance_mm, 0.0)?;

    // Pass 2: steps (remainder carried), the commanded angle, the cell-frame pose, the arm.
    let step_angle = setup.gearing.step_angle_rad();
    let phi0 = prepared[0].ideal;
    let mut poser = Poser {
        points,
        prepared: &prepared,
        cell: &cell,
        setup,
        clearance_mm: &clearance_mm,
        min_clearance: f64::INFINITY,
        max_entry: 0.0,
    };
    // The elbow branch: up if it takes the start pose within the ranges, else down; kept.
    let ((start, start_trig), elbow) = match poser.pose(0, phi0, ElbowBranch::Up, None) {
        Ok(pose) => (pose, ElbowBranch::Up),
        Err(up) => match poser.pose(0, phi0, ElbowBranch::Down, None) {
            Ok(pose) => (pose, ElbowBranch::Down),
            Err(_) => return Err(up),
        },
    };
    let mut carrier = RemainderCarrier::default();
    let mut max_drift_rad = 0.0f64;
    let mut poses: Vec<(Pose, i64, JointTrig)> = Vec::with_capacity(points.len() - 1);
    for (k, prep) in prepared.iter().enumerate().skip(1) {
        let steps = carrier.next(setup.gearing.steps(prep.ideal - phi0));
        let commanded = phi0 + carrier.commanded as f64 * step_angle;
        max_drift_rad = max_drift_rad.max((commanded - prep.ideal).abs());
        let prev = poses.last().map_or(&start, |(p, _, _)| p);
        let (pose, trig) = poser.pose(k, commanded, elbow, Some(prev))?;
        poses.push((pose, steps, trig));
    }
    let (min_clearance, max_entry) = (poser.min_clearance, poser.max_entry);

    // Pass 3: the segments' times and speeds.
    let arm = &setup.arm;
    let trigs: Vec<&JointTrig> = std::iter::once(&start_trig)
        .chain(poses.iter().map(|(_, _, t)| t))
        .collect();
    let joints = |pose: &Pose| pose.joints.irb62().copied().unwrap_or_default();
    let robot_time_s = |i: usize, prev: &Pose, pose: &Pose| {
        let travel_v = pose.eye_mm - prev.eye_mm;
        let travel = travel_v.norm();
        let linear_s = if travel > 1e-9 {
            let dir = Unit::new_unchecked(travel_v / travel);
            let fastest = arm
                .max_tool_speed_at(trigs[i], &dir)
                .min(arm.max_tool_speed_at(trigs[i + 1], &dir))
                .min(speeds.max_speed_mm_s);
            travel / fastest
        } else {
            0.0
        };
        linear_s.max(arm.joint_time_s(&joints(prev), &joints(pose)))
    };
    let stepped: Vec<(Pose, i64)> = poses.iter().map(|(p, s, _)| (*p, *s)).collect();
    let segments = timed_segments(&start, &stepped, setup, speeds, robot_time_s)?;
    Ok(PathPlan {
        sync_drive_rad: setup.calibration.drive_angle_rad(start.mandrel_rad),
        start,
        segments,
        arm: PathArm::Irb62(elbow),
        max_drift_rad,
        min_eye_clearance_mm: min_clearance,
        max_entry_angle_rad: max_entry,
    })
}

/// Pass 1: the eye in the mandrel frame (eqs 3.8–3.14; the start eye on the path's tangent) and
/// eq 3.7's angle at every point, unwrapped by the path's own angle around the spine, on the
/// flank that keeps the eye between the robot (at `b` mm from the rotation axis) and the mandrel.
/// Eq 3.7 places the robot on the drive frame's `−x` side; `turn_rad` is the robot's angle
/// about the axis from there (0 in the thesis cell), added to every angle.
pub(crate) fn eyes_and_angles(
    points: &[SurfacePoint],
    setup: &Setup,
    b: f64,
    turn_rad: f64,
) -> Result<Vec<Prepared>, Error> {
    // The flank that keeps the eye between the robot and the mandrel: the fibre must travel toward
    // the robot, i.e. along the counter-clockwise horizontal tangent on the left flank.
    let n0 = points[0].normal;
    let chord = points[1].point - points[0].point;
    let flank = if chord.x * -n0.y + chord.y * n0.x >= 0.0 {
        Flank::Left
    } else {
        Flank::Right
    };
    let beta_mid = match flank {
        Flank::Left => FRAC_PI_2,
        Flank::Right => -FRAC_PI_2,
    };
    let mut prepared: Vec<Prepared> = Vec::with_capacity(points.len());
    for (k, p) in points.iter().enumerate() {
        let eye = if k == 0 {
            eye::position(
                &(p.point - start_tangent(points)),
                &p.point,
                setup.offset_mm,
            )
        } else {
            eye::position(&points[k - 1].point, &p.point, setup.offset_mm)
        }
        .ok_or(Error::DegenerateSegment { segment: k.max(1) })?;
        let point_xy = Vector2::new(p.point.x, p.point.y);
        let normal_xy = Vector2::new(p.normal.x, p.normal.y);
        let angle = tangent::solve(point_xy, normal_xy, b, flank).map_err(|argument| {
            Error::TangentUndefined {
                robot_distance_mm: b,
                segment: k,
                argument: argument.abs(),
            }
        })?;
        // φ = β − α: β within a quarter revolution of ±90°, α the path's own continuous angle.
        let reference = beta_mid - p.around_rad;
        let ideal = angle.rad + TAU * ((reference - angle.rad) / TAU).round();
        if let Some(previous) = prepared.last() {
            let turn = ideal - previous.ideal;
            if turn.abs() > std::f64::consts::PI {
                return Err(Error::SegmentTurnsTooFar {
                    segment: k,
                    turn_deg: turn.to_degrees(),
                });
            }
        }
        prepared.push(Prepared {
            eye,
            cos: angle.cos,
            sin: angle.sin,
            ideal,
        });
    }
    if turn_rad != 0.0 {
        let (s, c) = turn_rad.sin_cos();
        for p in &mut prepared {
            (p.cos, p.sin) = (p.cos * c - p.sin * s, p.sin * c + p.cos * s);
            p.ideal += turn_rad;
        }
    }

    Ok(prepared)
}

/// Pass 2's pose at one point: the eye and the tow line in the cell frame at the commanded
/// mandrel angle, the arm through them (eq 3.7's plane, App. A's wrist), every check of the
/// pose; it keeps the least eye clearance and the largest entry angle of the poses it made.
struct Poser<'a, F> {
    points: &'a [SurfacePoint],
    prepared: &'a [Prepared],
    cell: &'a CellTransform,
    setup: &'a Setup,
    clearance_mm: &'a F,
    min_clearance: f64,
    max_entry: f64,
}

impl<F: Fn(&Point3<f64>) -> f64> Poser<'_, F> {
    /// The pose at point `k` with the mandrel at `commanded` rad, on `branch`, continuous with
    /// `previous`.
    fn pose(
        &mut self,
        k: usize,
        commanded: f64,
        branch: ElbowBranch,
        previous: Option<&Pose>,
    ) -> Result<(Pose, JointTrig), Error> {
        let prep = &self.prepared[k];
        // R_z(commanded) = R_z(ideal) R_z(δ), |δ| ≤ half a step: sin δ, cos δ by their series
        // (the next terms are below 1e-17 for a step of 0.2°).
        let delta = commanded - prep.ideal;
        let d2 = delta * delta;
        let (sin_d, cos_d) = (delta * (1.0 - d2 / 6.0), 1.0 - d2 / 2.0 + d2 * d2 / 24.0);
        let (c, s) = (
            prep.cos * cos_d - prep.sin * sin_d,
            prep.sin * cos_d + prep.cos * sin_d,
        );
        let rotate = |p: &Point3<f64>| {
            self.cell
                .to_cell(&Point3::new(c * p.x - s * p.y, s * p.x + c * p.y, p.z))
        };
        let eye_mm = rotate(&prep.eye);
        let tow = (rotate(&self.points[k].point) - eye_mm).normalize();
        // The arm plane through the pedestal axis and the eye; the roll axis is the tow line's
        // projection onto it.
        let radial = eye_mm.coords.xy();
        let rho = radial.norm();
        if rho < 1e-9 {
            return Err(Error::Arm {
                segment: Some(k),
                fault: ArmFault::WristOnPedestalAxis,
            });
        }
        let normal = Vector3::new(-radial.y / rho, radial.x / rho, 0.0);
        let out = tow.dot(&normal);
        let roll_axis = Unit::new_normalize(tow - normal * out);
        let entry_angle_rad = out.abs().min(1.0).asin();
        let arm = &self.setup.arm;
        let (joints, trig) = arm
            .inverse_with_trig(&eye_mm, &roll_axis, FRAC_PI_2, branch)
            .and_then(|(j, t)| arm.check_joints(&j).map(|()| (j, t)))
            .map_err(|e| arm_error(e, k))?;
        if let Some(prev) = previous {
            let prev_joints = prev.joints.irb62().copied().unwrap_or_default();
            arm.check_continuity(&prev_joints, &joints)
                .map_err(|e| arm_error(e, k))?;
        }
        if entry_angle_rad > self.setup.entry_angle_max_rad {
            return Err(Error::EntryAngle {
                segment: k,
                angle_deg: entry_angle_rad.to_degrees(),
                limit_deg: self.setup.entry_angle_max_rad.to_degrees(),
            });
        }
        let clearance = (self.clearance_mm)(&prep.eye);
        if clearance <= 0.0 || clearance.is_nan() {
            return Err(Error::EyeInsideMandrel {
                segment: k,
                clearance_mm: clearance,
            });
        }
        self.min_clearance = self.min_clearance.min(clearance);
        self.max_entry = self.max_entry.max(entry_angle_rad);
        // A continuous function of the joints (half-angle sines and cosines, never wrapped), so
        // joints checked for continuity give quaternions that never flip sign between poses.
        let wrist_q = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), joints.base_yaw_rad)
            * wrist::from_pitch_roll(joints.app_a_pitch_rad(), joints.roll_rad);
        Ok::<(Pose, JointTrig), Error>((
            Pose {
                tangent_point_mm: self.points[k].point,
                normal: self.points[k].normal,
                eye_mandrel_mm: prep.eye,
                eye_mm,
                joints: ArmJoints::Irb62(joints),
                entry_angle_rad,
                wrist_q,
                ideal_mandrel_rad: prep.ideal,
                mandrel_rad: commanded,
            },
            trig,
        ))
    }
}

/// Pass 3: each segment's time (the mandrel's profile; in discrete movement slowed to the robot,
/// in program movement refused where the robot cannot keep up) and the robot's speed.
/// `robot_time_s(i, from, to)` is the robot's least time for segment `i + 1`.
pub(crate) fn timed_segments(
    start: &Pose,
    poses: &[(Pose, i64)],
    setup: &Setup,
    speeds: &Speeds,
    robot_time_s: impl Fn(usize, &Pose, &Pose) -> f64,
) -> Result<Vec<Segment>, Error> {
    let steps_per_rev = setup.gearing.steps_per_mandrel_rev();
    let total_steps: u64 = poses.iter().map(|(_, s)| s.unsigned_abs()).sum();
    let mut covered = 0u64;
    let sign = i64::from(setup.calibration.rotation_sign);
    let mut segments: Vec<Segment> = Vec::with_capacity(poses.len());
    for (i, (pose, steps)) in poses.iter().enumerate() {
        let k = i + 1;
        let prev = if i == 0 { start } else { &poses[i - 1].0 };
        let n = steps.unsigned_abs();
        let mut duration_s = match speeds.movement {
            Movement::Discrete => speeds.mandrel.duration_s(n, steps_per_rev),
            Movement::Fine | Movement::Medium | Movement::Continuous { .. } => {
                let before = speeds
                    .mandrel
                    .time_at_step_s(covered, total_steps, steps_per_rev);
                covered += n;
                speeds
                    .mandrel
                    .time_at_step_s(covered, total_steps, steps_per_rev)
                    - before
            }
        };
        let travel = (pose.eye_mm - prev.eye_mm).norm();
        let robot_time_s = robot_time_s(i, prev, pose);
        let mut mandrel = speeds.mandrel;
        let mut robot_paced = false;
        if robot_time_s > duration_s * (1.0 + 1e-12) {
            match speeds.movement {
                Movement::Discrete => {
                    mandrel = speeds.mandrel.slowed_to(n, steps_per_rev, robot_time_s);
                    duration_s = robot_time_s;
                    robot_paced = true;
                }
                Movement::Fine | Movement::Medium | Movement::Continuous { .. } => {
                    return Err(Error::RobotTooSlow {
                        segment: k,
                        speed_mm_s: if duration_s > 0.0 {
                            travel / duration_s
                        } else {
                            f64::INFINITY
                        },
                        robot_time_s,
                        duration_s,
                        mandrel_rps_fit: speeds.mandrel.max_rps * duration_s / robot_time_s,
                    });
                }
            }
        }
        if let Movement::Continuous { instruction_s } = speeds.movement
            && duration_s < instruction_s
        {
            // Segments of equal steps each last at least the instruction time at full speed
            // (the ramps only lengthen the first and last) when each has at least the whole
            // steps the mandrel turns in that time.
            let steps: Vec<u64> = poses.iter().map(|(_, s)| s.unsigned_abs()).collect();
            return Err(Error::SegmentTooShort {
                segment: k,
                duration_s,
                instruction_s,
                max_segments: continuous_fit_segments(
                    &speeds.mandrel,
                    &steps,
                    steps_per_rev,
                    instruction_s,
                ),
                mandrel_rps_fit: continuous_fit_rps(
                    &speeds.mandrel,
                    &steps,
                    steps_per_rev,
                    instruction_s,
                ),
            });
        }
        let speed_mm_s = if travel < 1e-9 || duration_s <= 0.0 {
            // Nothing to travel: any speed arrives at once; ask for the base speed.
            speeds.base_speed_mm_s
        } else {
            travel / duration_s
        };
        segments.push(Segment {
            pose: *pose,
            steps: sign * steps,
            duration_s,
            robot_time_s,
            speed_mm_s,
            speed_pct: 100.0 * speed_mm_s / speeds.base_speed_mm_s,
            mandrel,
            robot_paced,
        });
    }
    Ok(segments)
}

/// Whether every segment of one mandrel move through `total` steps, the segments ending at the
/// step counts `covered`, lasts at least `instruction_s`.
fn every_segment_lasts(
    profile: &MandrelProfile,
    mut covered: impl Iterator<Item = u64>,
    total: u64,
    steps_per_rev: f64,
    instruction_s: f64,
) -> bool {
    let mut before = 0.0;
    covered.all(|c| {
        let t = profile.time_at_step_s(c, total, steps_per_rev);
        let ok = t - before >= instruction_s;
        before = t;
        ok
    })
}

/// The most segments (0 if not even one) into which the path can be cut, the same way, with every
/// segment of one mandrel move lasting at least `instruction_s`. The path's steps are taken as
/// spread along it as in the present cut (`steps`, piecewise linear between its ends), and a new
/// cut into `n` parts gives each part the whole steps between its ends, as the planner's
/// remainder carrying does. Found by bisection on `n`.
fn continuous_fit_segments(
    profile: &MandrelProfile,
    steps: &[u64],
    steps_per_rev: f64,
    instruction_s: f64,
) -> usize {
    let total: u64 = steps.iter().sum();
    let m = steps.len() as u64;
    if total == 0 {
        // The mandrel does not turn: every segment lasts no time.
        return 0;
    }
    // Whole steps before each present segment.
    let prefix: Vec<u64> = std::iter::once(0)
        .chain(steps.iter().scan(0, |acc, n| {
            *acc += n;
            Some(*acc)
        }))
        .collect();
    // Whole steps covered at path fraction j/n, in integers: the present segment i it falls in
    // and the part r/n of it.
    let covered_at = |j: u64, n: u64| -> u64 {
        let p = j * m;
        let i = (p / n).min(m - 1);
        let r = p - i * n;
        prefix[i as usize] + r * steps[i as usize] / n
    };
    let fits = |n: usize| {
        let n = n as u64;
        every_segment_lasts(
            profile,
            (1..=n).map(|j| covered_at(j, n)),
            total,
            steps_per_rev,
            instruction_s,
        )
    };
    let (mut lo, mut hi) = (1usize, steps.len());
    if !fits(lo) {
        return 0;
    }
    while lo < hi {
        let mid = (lo + hi).div_ceil(2);
        if fits(mid) {
            lo = mid;
        } else {
            hi = mid - 1;
        }
    }
    lo
}

/// The fastest cruise speed (rev/s, down to the profile's start speed) at which every
/// segment of one mandrel move through `steps` lasts at least `instruction_s`; 0 when none does.
/// Found by bisection on the move's own timing, so segments in the ramps count with their ramp
/// times: scaling one segment's time by the speed ratio is right only at cruise.
fn continuous_fit_rps(
    profile: &MandrelProfile,
    steps: &[u64],
    steps_per_rev: f64,
    instruction_s: f64,
) -> f64 {
    let total: u64 = steps.iter().sum();
    let fits = |max_rps: f64| {
        let m = MandrelProfile {
            max_rps,
            ..*profile
        };
        let covered = steps.iter().scan(0, |acc, n| {
            *acc += n;
            Some(*acc)
        });
        every_segment_lasts(&m, covered, total, steps_per_rev, instruction_s)
    };
    let (mut lo, mut hi) = (profile.start_stop_rps.max(1e-9), profile.max_rps);
    if !fits(lo) {
        return 0.0;
    }
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if fits(mid) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    // Down to the 0.1 mrev/s the message shows, so that the figure shown fits too.
    let shown = (lo * 1e4).floor() / 1e4;
    if shown >= profile.start_stop_rps && fits(shown) {
        shown
    } else {
        lo
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geodesic::{self, Direction, PathStart};
    use crate::segment::equal_length;
    use crate::spine::{SBEND_SMOOTHING_MM, SBEND_TABLE_6_1_MM};
    use crate::{Spine, Tube};
    use approx::assert_abs_diff_eq;
    use nalgebra::Rotation3;
    use std::f64::consts::PI;

    const R: f64 = 31.75;

    fn setup() -> Setup {
        Setup {
            robot_distance_mm: 800.0,
            mandrel_height_mm: 300.0,
            offset_mm: 100.0,
            arm: Arm::default(),
            entry_angle_max_rad: ENTRY_ANGLE_MAX_DEG.to_radians(),
            calibration: Calibration::default(),
            gearing: Gearing::default(),
            six_axis: None,
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
            max_speed_mm_s: 2000.0,
            movement,
        }
    }

    fn tubes() -> [Tube; 4] {
        [
            Tube::cylinder(63.5, 178.0, 0.0, 0.0).unwrap(),
            Tube::cylinder(63.5, 178.0, 3.0 * R, 3.0 * R).unwrap(),
            Tube::cylinder(63.5, 178.0, R, 3.0 * R).unwrap(),
            sbend(),
        ]
    }

    fn sbend() -> Tube {
        Tube::new(
            Spine::smoothing(&SBEND_TABLE_6_1_MM, SBEND_SMOOTHING_MM).unwrap(),
            28.5,
        )
        .unwrap()
    }

    fn points(tube: &Tube, start: &PathStart, segments: usize) -> Vec<SurfacePoint> {
        let path = if tube.spine().is_straight() {
            geodesic::helix(tube, start, 1.0)
        } else {
            geodesic::trace(tube, start, 0.25)
        }
        .unwrap();
        equal_length(tube, &path, segments).unwrap()
    }

    fn plan_with(tube: &Tube, start: PathStart, setup: &Setup, speeds: &Speeds) -> PathPlan {
        let points = points(tube, &start, 50);
        plan(&points, |p| tube.distance_to_surface_mm(p), setup, speeds).unwrap()
    }

    fn plan_tube(tube: &Tube, start: PathStart) -> PathPlan {
        plan_with(tube, start, &setup(), &speeds(Movement::Fine))
    }

    fn cylinder_start(direction: Direction) -> PathStart {
        PathStart {
            angle_rad: 0.0,
            wind_angle_rad: 48.3f64.to_radians(),
            direction,
        }
    }

    fn poses(p: &PathPlan) -> impl Iterator<Item = &Pose> {
        std::iter::once(&p.start).chain(p.segments.iter().map(|s| &s.pose))
    }

    /// The tangent point in the cell frame (nominal cell).
    fn tangent_cell(pose: &Pose) -> Point3<f64> {
        Rotation3::from_axis_angle(&Vector3::z_axis(), pose.mandrel_rad) * pose.tangent_point_mm
            + Vector3::new(800.0, 0.0, 300.0)
    }

    #[test]
    fn every_pose_is_tangent_and_the_eye_faces_the_robot() {
        for tube in &tubes() {
            for dir in [Direction::Down, Direction::Up] {
                let p = plan_tube(tube, cylinder_start(dir));
                for pose in poses(&p) {
                    // Tangent: the horizontal line from the pedestal to the point is ⟂ the normal.
                    let rot =
                        Rotation3::from_axis_angle(&Vector3::z_axis(), pose.ideal_mandrel_rad);
                    let pt = rot * pose.tangent_point_mm;
                    let n = rot * pose.normal;
                    let line = Vector2::new(pt.x + 800.0, pt.y);
                    let nh = Vector2::new(n.x, n.y).normalize();
                    assert_abs_diff_eq!(line.dot(&nh) / line.norm(), 0.0, epsilon = 1e-9);
                    // The eye is nearer the robot than the tangent point, and 100 mm from it.
                    assert!(pose.eye_mm.x < tangent_cell(pose).x);
                    assert_abs_diff_eq!(
                        (pose.eye_mandrel_mm - pose.tangent_point_mm).norm(),
                        100.0,
                        epsilon = 1e-9
                    );
                }
                assert!(p.max_drift_rad <= 0.5 * Gearing::default().step_angle_rad() + 1e-12);
                assert!(p.min_eye_clearance_mm > 0.0);
            }
        }
    }

    #[test]
    fn the_arm_holds_the_eye_with_the_roll_axis_in_its_plane_and_the_wrist_behind() {
        let arm = Arm::default();
        for tube in &tubes() {
            for dir in [Direction::Down, Direction::Up] {
                let p = plan_tube(tube, cylinder_start(dir));
                let mut worst = 0.0f64;
                let mut previous: Option<&Pose> = None;
                for pose in poses(&p) {
                    let joints = *pose.joints.irb62().unwrap();
                    let fk = arm.forward(&joints);
                    // The joints put the eye where the plan says.
                    assert_abs_diff_eq!(fk.eye_mm, pose.eye_mm, epsilon = 1e-9);
                    // The roll axis lies in the vertical plane through the pedestal axis and eye.
                    let radial = pose.eye_mm.coords.xy().normalize();
                    let normal = Vector3::new(-radial.y, radial.x, 0.0);
                    assert!(fk.roll_axis.dot(&normal).abs() < 1e-12);
                    // The entry angle is the angle between the tow line and the roll axis.
                    let tow = (tangent_cell(pose) - pose.eye_mm).normalize();
                    let angle = tow
                        .cross(&fk.roll_axis)
                        .norm()
                        .atan2(tow.dot(&fk.roll_axis));
                    assert_abs_diff_eq!(angle, pose.entry_angle_rad, epsilon = 1e-9);
                    worst = worst.max(angle);
                    // The wrist is behind the eye, away from the mandrel: farther from the
                    // rotation axis than the eye, by about the eye mechanism.
                    let axis = Point3::new(800.0, 0.0, fk.wrist_mm.z);
                    let from_axis = |q: &Point3<f64>| (q - axis).xy().norm();
                    assert!(from_axis(&fk.wrist_mm) > from_axis(&pose.eye_mm) + 10.0);
                    // The telegram's quaternion is the arm's orientation (yaw, App. A pitch and
                    // roll), with no sign flip between poses.
                    let gap = (pose.wrist_q.coords - fk.orientation.coords)
                        .norm()
                        .min((pose.wrist_q.coords + fk.orientation.coords).norm());
                    assert!(gap < 1e-12);
                    assert_abs_diff_eq!(
                        pose.wrist_q * Vector3::x(),
                        fk.roll_axis.into_inner(),
                        epsilon = 1e-12
                    );
                    if let Some(prev) = previous {
                        assert!(pose.wrist_q.coords.dot(&prev.wrist_q.coords) > 0.9);
                    }
                    // The rocker arm's plane (tool x–z) holds the tow line.
                    assert!((pose.wrist_q * Vector3::y()).dot(&tow).abs() < 1e-9);
                    // One elbow branch for the whole path.
                    assert!(joints.elbow_rad < FRAC_PI_2);
                    assert!(arm.check_joints(&joints).is_ok());
                    previous = Some(pose);
                }
                assert_eq!(p.arm.elbow(), Some(ElbowBranch::Up));
                assert_abs_diff_eq!(p.max_entry_angle_rad, worst, epsilon = 1e-15);
            }
        }
    }

    #[test]
    fn steps_sum_to_the_rotation_for_any_segment_count_that_fits() {
        // On the axis the mandrel turns back the path's own turn around the axis:
        // tan(48.3°) · 178 / 31.75 rad, clockwise, 1846.15 steps per revolution.
        let tube = &tubes()[0];
        let expected = -(48.3f64.to_radians().tan() * 178.0 / R) / TAU * (400.0 * 60.0 / 13.0);
        // Few segments put the eye far off the tangent (eqs 3.8–3.14 follow the chord): lift the
        // entry-angle limit, this test is about the steps.
        let wide = Setup {
            entry_angle_max_rad: 80f64.to_radians(),
            ..setup()
        };
        for segments in [5, 7, 13, 50] {
            let pts = points(tube, &cylinder_start(Direction::Down), segments);
            let p = plan(
                &pts,
                |q| tube.distance_to_surface_mm(q),
                &wide,
                &speeds(Movement::Discrete),
            )
            .unwrap();
            let total: i64 = p.segments.iter().map(|s| s.steps).sum();
            assert!(
                (total as f64 - expected).abs() <= 1.0,
                "{segments}: {total} vs {expected}"
            );
            assert!(p.segments.iter().all(|s| s.steps < 0));
        }
    }

    #[test]
    fn a_segment_turning_more_than_half_a_revolution_is_refused() {
        let tube = &tubes()[0];
        // Two segments: each turns about 180.4°.
        let pts = points(tube, &cylinder_start(Direction::Down), 2);
        let err = plan(
            &pts,
            |q| tube.distance_to_surface_mm(q),
            &setup(),
            &speeds(Movement::Fine),
        )
        .unwrap_err();
        match err {
            Error::SegmentTurnsTooFar { segment, turn_deg } => {
                assert_eq!(segment, 1);
                assert!(turn_deg < -180.0 && turn_deg > -182.0, "{turn_deg}");
            }
            other => panic!("{other}"),
        }
        // 89°: about 51 revolutions in 50 segments.
        let steep = PathStart {
            wind_angle_rad: 89f64.to_radians(),
            ..cylinder_start(Direction::Down)
        };
        let pts = points(tube, &steep, 50);
        let err = plan(
            &pts,
            |q| tube.distance_to_surface_mm(q),
            &setup(),
            &speeds(Movement::Fine),
        )
        .unwrap_err();
        assert!(
            matches!(err, Error::SegmentTurnsTooFar { segment: 1, .. }),
            "{err}"
        );
    }

    /// Continuous movement times its segments as fine and medium do and refuses a segment
    /// shorter than the robot's time per instruction, naming the segment and the most segments
    /// of equal steps that fit: on the cylinder (1.0016 rev, 50 segments of 37 steps at
    /// 0.1 rev/s of 1846.15 steps/rev: 0.2004 s at full speed) an instruction time of 0.19 s
    /// plans and 0.21 s is refused at the first full-speed segment, with at most
    /// ⌊1849 / ⌈184.615 · 0.21⌉⌋ = ⌊1849 / 39⌋ = 47 segments.
    #[test]
    fn continuous_movement_refuses_segments_shorter_than_an_instruction() {
        let tube = &tubes()[0];
        let start = cylinder_start(Direction::Down);
        let fine = plan_with(tube, start, &setup(), &speeds(Movement::Fine));
        let ok = plan_with(
            tube,
            start,
            &setup(),
            &speeds(Movement::Continuous {
                instruction_s: 0.19,
            }),
        );
        for (a, b) in fine.segments.iter().zip(&ok.segments) {
            assert_eq!(a.duration_s, b.duration_s);
            assert_eq!(a.speed_mm_s, b.speed_mm_s);
        }
        let total: i64 = fine.segments.iter().map(|s| s.steps).sum();
        assert_eq!(total.abs(), 1849);
        let points = points(tube, &start, 50);
        let err = plan(
            &points,
            |p| tube.distance_to_surface_mm(p),
            &setup(),
            &speeds(Movement::Continuous {
                instruction_s: 0.21,
            }),
        )
        .unwrap_err();
        // The first segment holds the ramp from 0.05 rev/s (longer than 0.21 s); the first
        // shorter one is where the mandrel runs at full speed.
        let first_short = fine
            .segments
            .iter()
            .position(|s| s.duration_s < 0.21)
            .unwrap()
            + 1;
        assert!(first_short >= 2);
        match err {
            Error::SegmentTooShort {
                segment,
                duration_s,
                instruction_s,
                max_segments,
                mandrel_rps_fit,
            } => {
                assert_eq!(segment, first_short);
                assert!(
                    (duration_s - 37.0 / 184.615_384_6).abs() < 0.002,
                    "{duration_s}"
                );
                assert_eq!(instruction_s, 0.21);
                // At full speed (0.1 rev/s × 400 × 60/13 = 184.6 steps/s) 0.21 s is 38.8 steps:
                // 1849 steps in 47 parts are parts of 39 or 40 whole steps (0.211 s and more);
                // in 48 parts, some of 38 (0.206 s).
                let steps: Vec<i64> = fine.segments.iter().map(|s| s.steps.abs()).collect();
                assert_eq!(steps.iter().filter(|n| **n == 36).count(), 1);
                assert_eq!(max_segments, 47);
                // The fastest speed at which the 36-step segment lasts 0.21 s: 36 / 0.21 steps/s
                // = 0.092 857 rev/s, shown to 0.1 mrev/s (the ramp segments are longer).
                assert_eq!(mandrel_rps_fit, 0.0928);
            }
            other => panic!("{other}"),
        }
    }

    #[test]
    fn the_start_eye_lies_on_the_paths_tangent() {
        let tube = &tubes()[0];
        let wind = 48.3f64.to_radians();
        let p = plan_tube(tube, cylinder_start(Direction::Down));
        // The helix's tangent at the top point (0°): down the axis at the wind angle, turning
        // counter-clockwise seen from above.
        let exact = Vector3::new(0.0, wind.sin(), -wind.cos());
        let dir = (p.start.eye_mandrel_mm - p.start.tangent_point_mm) / 100.0;
        assert!(dir.cross(&exact).norm() < 1e-4, "{dir:?}");
        // The tow line never dips into the cylinder: its least distance to the axis is r.
        let (a, b) = (p.start.eye_mandrel_mm, p.start.tangent_point_mm);
        for i in 0..=100 {
            let q = a + (b - a) * (i as f64 / 100.0);
            assert!(q.coords.xy().norm() >= R - 1e-9);
        }
    }

    #[test]
    fn speed_comes_from_the_trapezoid_and_the_arm_limits_it() {
        let tube = &tubes()[1];
        let start = cylinder_start(Direction::Down);
        let fine = plan_with(tube, start, &setup(), &speeds(Movement::Fine));
        let profile = speeds(Movement::Fine).mandrel;
        // Fine: the segments split the path's one mandrel move.
        let spr = Gearing::default().steps_per_mandrel_rev();
        let total = fine
            .segments
            .iter()
            .map(|s| s.steps.unsigned_abs())
            .sum::<u64>();
        let sum: f64 = fine.segments.iter().map(|s| s.duration_s).sum();
        assert_abs_diff_eq!(sum, profile.duration_s(total, spr), epsilon = 1e-9);
        for (k, s) in fine.segments.iter().enumerate() {
            let prev = if k == 0 {
                &fine.start
            } else {
                &fine.segments[k - 1].pose
            };
            let v = (s.pose.eye_mm - prev.eye_mm).norm() / s.duration_s;
            assert_abs_diff_eq!(s.speed_mm_s, v, epsilon = 1e-9);
            assert_abs_diff_eq!(s.speed_pct, v / 10.0, epsilon = 1e-9);
            assert!(s.robot_time_s <= s.duration_s);
            assert!(!s.robot_paced);
        }
        // Discrete: each segment is its own trapezoid.
        let discrete = plan_with(tube, start, &setup(), &speeds(Movement::Discrete));
        for s in &discrete.segments {
            let n = s.steps.unsigned_abs();
            assert_abs_diff_eq!(s.duration_s, profile.duration_s(n, spr), epsilon = 1e-12);
        }
        // A mandrel 40 times faster: fine movement is refused with the speed that fits…
        let fast = Speeds {
            mandrel: MandrelProfile {
                max_rps: 4.0,
                accel_rps2: 1000.0,
                start_stop_rps: 0.05,
            },
            ..speeds(Movement::Fine)
        };
        let pts = points(tube, &start, 50);
        let err = plan(&pts, |q| tube.distance_to_surface_mm(q), &setup(), &fast).unwrap_err();
        match err {
            Error::RobotTooSlow {
                segment,
                speed_mm_s,
                robot_time_s,
                duration_s,
                mandrel_rps_fit,
            } => {
                assert!(robot_time_s > duration_s);
                // The speed named is that segment's eye travel over the mandrel's time (the
                // poses do not depend on the movement: taken from the discrete plan).
                let d = plan(
                    &pts,
                    |q| tube.distance_to_surface_mm(q),
                    &setup(),
                    &Speeds {
                        movement: Movement::Discrete,
                        ..fast
                    },
                )
                .unwrap();
                let eye = |k: usize| {
                    if k == 0 {
                        d.start.eye_mm
                    } else {
                        d.segments[k - 1].pose.eye_mm
                    }
                };
                assert!(segment >= 1);
                let travel = (eye(segment) - eye(segment - 1)).norm();
                assert_abs_diff_eq!(speed_mm_s, travel / duration_s, epsilon = 1e-9);
                assert_abs_diff_eq!(
                    mandrel_rps_fit,
                    4.0 * duration_s / robot_time_s,
                    epsilon = 1e-12
                );
            }
            other => panic!("{other}"),
        }
        // …and discrete movement slows the mandrel on the robot's segments to the robot's time.
        let fast_discrete = Speeds {
            movement: Movement::Discrete,
            ..fast
        };
        let p = plan(
            &pts,
            |q| tube.distance_to_surface_mm(q),
            &setup(),
            &fast_discrete,
        )
        .unwrap();
        let arm = Arm::default();
        assert!(p.segments.iter().any(|s| s.robot_paced));
        for (k, s) in p.segments.iter().enumerate() {
            let prev = if k == 0 {
                &p.start
            } else {
                &p.segments[k - 1].pose
            };
            let travel = s.pose.eye_mm - prev.eye_mm;
            let dir = Unit::new_normalize(travel);
            let fastest = arm
                .max_tool_speed_mm_s(prev.joints.irb62().unwrap(), &dir)
                .min(arm.max_tool_speed_mm_s(s.pose.joints.irb62().unwrap(), &dir))
                .min(2000.0);
            // Never faster than the arm at that pose, nor than the controller.
            assert!(s.speed_mm_s <= fastest * (1.0 + 1e-9), "{k}");
            let n = s.steps.unsigned_abs();
            assert_abs_diff_eq!(s.mandrel.duration_s(n, spr), s.duration_s, epsilon = 1e-9);
            if s.robot_paced {
                assert!(s.mandrel.max_rps < 4.0);
                assert_abs_diff_eq!(s.duration_s, s.robot_time_s, epsilon = 1e-12);
            } else {
                assert_eq!(s.mandrel, fast.mandrel);
            }
        }
    }

    #[test]
    fn entry_angle_and_eye_guards() {
        let tube = &tubes()[2];
        let pts = points(tube, &cylinder_start(Direction::Up), 50);
        let p = plan(
            &pts,
            |q| tube.distance_to_surface_mm(q),
            &setup(),
            &speeds(Movement::Fine),
        )
        .unwrap();
        let tight = Setup {
            entry_angle_max_rad: 0.5 * p.max_entry_angle_rad,
            ..setup()
        };
        let err = plan(
            &pts,
            |q| tube.distance_to_surface_mm(q),
            &tight,
            &speeds(Movement::Fine),
        )
        .unwrap_err();
        assert!(matches!(err, Error::EntryAngle { .. }), "{err}");
        let err = plan(&pts, |_| -0.5, &setup(), &speeds(Movement::Fine)).unwrap_err();
        assert!(
            matches!(err, Error::EyeInsideMandrel { segment: 0, clearance_mm } if clearance_mm == -0.5),
            "{err}"
        );
        // A robot too far away for its links.
        let far = Setup {
            robot_distance_mm: 1600.0,
            ..setup()
        };
        let err = plan(
            &pts,
            |q| tube.distance_to_surface_mm(q),
            &far,
            &speeds(Movement::Fine),
        )
        .unwrap_err();
        assert!(
            matches!(
                err,
                Error::Arm {
                    segment: Some(0),
                    fault: ArmFault::OutOfReach { .. }
                }
            ),
            "{err}"
        );
    }

    #[test]
    fn calibration_moves_the_cell_frame_and_the_drive_sense() {
        let tube = &tubes()[1];
        let pts = points(tube, &cylinder_start(Direction::Down), 50);
        let moved = Setup {
            calibration: Calibration {
                axis_offset_mm: [3.0, 7.0],
                ..Calibration::default()
            },
            ..setup()
        };
        let measured = Setup {
            calibration: Calibration {
                zero_angle_rad: 0.25,
                rotation_sign: -1,
                ..moved.calibration
            },
            ..setup()
        };
        let nominal = plan(
            &pts,
            |q| tube.distance_to_surface_mm(q),
            &moved,
            &speeds(Movement::Fine),
        )
        .unwrap();
        let p = plan(
            &pts,
            |q| tube.distance_to_surface_mm(q),
            &measured,
            &speeds(Movement::Fine),
        )
        .unwrap();
        let axis = Vector3::new(803.0, 7.0, 300.0);
        for pose in poses(&p) {
            // Tangent in the measured cell: the horizontal line from the pedestal axis to the
            // point is ⟂ the normal, both in the cell frame.
            let heading = 7f64.atan2(803.0);
            let rot = Rotation3::from_axis_angle(&Vector3::z_axis(), pose.mandrel_rad + heading);
            let pt = rot * pose.tangent_point_mm + axis;
            let n = rot * pose.normal;
            let along = pt.coords.xy().normalize().dot(&n.xy().normalize());
            assert!(along.abs() < 2e-3, "{along}"); // within half a step of rotation
            assert!(pose.eye_mm.coords.xy().norm() < pt.coords.xy().norm());
        }
        for (a, b) in p.segments.iter().zip(&nominal.segments) {
            assert_eq!(a.steps, -b.steps);
        }
        assert_abs_diff_eq!(
            p.sync_drive_rad,
            -(p.start.mandrel_rad - 0.25),
            epsilon = 1e-15
        );
        assert_abs_diff_eq!(
            nominal.sync_drive_rad,
            nominal.start.mandrel_rad,
            epsilon = 1e-15
        );
    }

    /// The start direction's one-sided differences are exact on polynomials of their order
    /// (chord: lines; three points: quadratics; four: cubics; five or more: quartics), so on
    /// such a curve the start tangent is the curve's derivative at the first point, scaled, less
    /// its part along the surface normal.
    #[test]
    fn start_tangent_is_exact_on_polynomials_of_its_order() {
        let b = Vector3::new(0.3, 1.0, 0.7);
        let c2 = Vector3::new(0.5, -0.2, 0.1);
        let c3 = Vector3::new(-0.05, 0.08, 0.02);
        let c4 = Vector3::new(0.004, -0.003, 0.006);
        // A normal leaning along the derivative: the start tangent is the derivative's part in
        // the tangent plane.
        let normal = (b.cross(&Vector3::z()) + b * 0.3).normalize();
        let want = b - normal * b.dot(&normal);
        for (count, degree) in [(2, 1), (3, 2), (4, 3), (5, 4), (9, 4)] {
            let h = 0.5;
            let points: Vec<SurfacePoint> = (0..count)
                .map(|k| {
                    let t = h * k as f64;
                    // Away from the origin, so that no term vanishes at the first point.
                    let mut q = Vector3::new(100.0, -50.0, 20.0) + b * t;
                    if degree >= 2 {
                        q += c2 * t * t;
                    }
                    if degree >= 3 {
                        q += c3 * t * t * t;
                    }
                    if degree >= 4 {
                        q += c4 * t * t * t * t;
                    }
                    SurfacePoint {
                        point: Point3::from(q),
                        normal,
                        around_rad: 0.0,
                    }
                })
                .collect();
            let t = start_tangent(&points);
            let cosine = t.dot(&want) / (t.norm() * want.norm());
            assert!(cosine > 1.0 - 1e-12, "{count} points: {t} against {want}");
            assert!(t.dot(&normal).abs() < 1e-12 * t.norm());
        }
    }

    /// The flank and the reference angle of the unwrap hold wherever the path starts around
    /// the mandrel: on the cylinder, starting at 0°, 90°, 180° and 270° in both directions,
    /// and each path also wound backwards (clockwise, the right flank), the eye stays between
    /// the robot and the tangent point, and `β = φ + α` (eq 3.7's angle with the path's own
    /// angle added back) stays within a quarter revolution of +90° on the left flank or −90° on
    /// the right.
    #[test]
    fn flank_and_unwrap_hold_from_any_start_angle() {
        let tube = &tubes()[0];
        let mut flanks = [0usize; 2];
        for deg in [0.0f64, 90.0, 180.0, 270.0] {
            for (direction, backwards) in [
                (Direction::Down, false),
                (Direction::Up, false),
                (Direction::Down, true),
                (Direction::Up, true),
            ] {
                let start = PathStart {
                    angle_rad: deg.to_radians(),
                    ..cylinder_start(direction)
                };
                let mut pts = points(tube, &start, 20);
                if backwards {
                    pts.reverse();
                }
                let p = plan(
                    &pts,
                    |q| tube.distance_to_surface_mm(q),
                    &setup(),
                    &speeds(Movement::Fine),
                )
                .unwrap();
                // Which side the fibre travels on, from the first chord and normal.
                let n0 = pts[0].normal;
                let chord = pts[1].point - pts[0].point;
                let left = chord.x * -n0.y + chord.y * n0.x >= 0.0;
                flanks[usize::from(left)] += 1;
                let mid = if left { PI / 2.0 } else { -PI / 2.0 };
                for (pose, pt) in poses(&p).zip(&pts) {
                    assert!(pose.eye_mm.x < tangent_cell(pose).x, "{deg}° {direction:?}");
                    let beta = pose.ideal_mandrel_rad + pt.around_rad;
                    assert!(
                        (beta - mid).abs() <= PI / 2.0 + 1e-9,
                        "{deg}° {direction:?}: β {beta}"
                    );
                }
            }
        }
        assert!(flanks[0] > 0 && flanks[1] > 0, "{flanks:?}");
    }

    /// One segment is the shortest path; a single point is none.
    #[test]
    fn one_segment_plans_and_one_point_does_not() {
        let tube = &tubes()[0];
        let pts = &points(tube, &cylinder_start(Direction::Up), 50)[..2];
        let fit = |q: &Point3<f64>| tube.distance_to_surface_mm(q);
        let one = plan(pts, fit, &setup(), &speeds(Movement::Discrete)).unwrap();
        assert_eq!(one.segments.len(), 1);
        assert!(matches!(
            plan(&pts[..1], fit, &setup(), &speeds(Movement::Discrete)),
            Err(Error::OutOfRange {
                name: "segments",
                ..
            })
        ));
    }

    #[test]
    fn setup_validation_names_the_bad_figure() {
        assert!(setup().validate().is_ok());
        for bad in [f64::NAN, f64::INFINITY] {
            let s = Setup {
                mandrel_height_mm: bad,
                ..setup()
            };
            assert!(
                matches!(
                    s.validate(),
                    Err(Error::OutOfRange {
                        name: "mandrel_height_mm",
                        ..
                    })
                ),
                "{bad}"
            );
        }
        let with_entry = |deg: f64| Setup {
            entry_angle_max_rad: deg.to_radians(),
            ..setup()
        };
        assert!(with_entry(89.9).validate().is_ok());
        for bad in [0.0, -5.0, 90.5, f64::NAN] {
            assert!(
                matches!(
                    with_entry(bad).validate(),
                    Err(Error::OutOfRange {
                        name: "entry_angle_max_deg",
                        ..
                    })
                ),
                "{bad}"
            );
        }
        let long_eye = Setup {
            arm: Arm {
                eye_mechanism_mm: 401.0,
                ..Arm::default()
            },
            ..setup()
        };
        assert!(matches!(
            long_eye.validate(),
            Err(Error::OutOfRange {
                name: "eye_mechanism_length_mm",
                ..
            })
        ));
        let tilted = Setup {
            calibration: Calibration {
                axis_tilt_rad: [0.0, 11f64.to_radians()],
                ..Calibration::default()
            },
            ..setup()
        };
        assert!(tilted.validate().is_err());
        // Speeds: the mandrel profile and both robot speeds.
        assert!(speeds(Movement::Fine).validate().is_ok());
        for bad in [
            Speeds {
                base_speed_mm_s: 0.0,
                ..speeds(Movement::Fine)
            },
            Speeds {
                max_speed_mm_s: f64::NAN,
                ..speeds(Movement::Fine)
            },
            Speeds {
                mandrel: MandrelProfile {
                    start_stop_rps: 0.2,
                    ..speeds(Movement::Fine).mandrel
                },
                ..speeds(Movement::Fine)
            },
        ] {
            assert!(bad.validate().is_err(), "{bad:?}");
        }
    }

    /// The advised speed never lies below the profile's start speed, where no indexer profile
    /// exists: with a start speed of 0.10004 rev/s just under a top speed of 0.10005 rev/s and
    /// every segment fitting, the bisection ends at the top, whose 0.1 mrev/s floor (0.1000)
    /// lies below the start speed; the advice is then the unrounded speed.
    #[test]
    fn the_continuous_speed_advice_stays_above_the_start_speed() {
        let profile = MandrelProfile {
            accel_rps2: 1.0,
            start_stop_rps: 0.10004,
            max_rps: 0.10005,
        };
        let rps = continuous_fit_rps(&profile, &[100; 10], 400.0, 1e-3);
        assert!(rps >= profile.start_stop_rps, "{rps}");
        assert!(rps <= profile.max_rps, "{rps}");
    }

    #[test]
    fn robot_too_close_gives_tangent_undefined() {
        let tube = Tube::cylinder(63.5, 178.0, 3.0 * R, 3.0 * R).unwrap();
        let path = geodesic::helix(&tube, &cylinder_start(Direction::Up), 1.0).unwrap();
        let points = equal_length(&tube, &path, 50).unwrap();
        let close = Setup {
            robot_distance_mm: 60.0,
            ..setup()
        };
        let err = plan(
            &points,
            |p| tube.distance_to_surface_mm(p),
            &close,
            &speeds(Movement::Fine),
        )
        .unwrap_err();
        assert!(matches!(err, Error::TangentUndefined { .. }), "{err}");
    }

    #[test]
    fn sbend_start_is_at_90_deg_and_45_deg_to_the_spine() {
        let tube = sbend();
        let start = PathStart {
            angle_rad: PI / 2.0,
            wind_angle_rad: PI / 4.0,
            direction: Direction::Up,
        };
        let p = plan_tube(&tube, start);
        assert_abs_diff_eq!(p.start.tangent_point_mm.y, 28.5, epsilon = 1e-9);
        assert_eq!(p.segments.len(), 50);
        // The eye leaves the start point along the fibre, at 45° to the spine's tangent there.
        let fibre = (p.start.eye_mandrel_mm - p.start.tangent_point_mm).normalize();
        let spine = tube.spine_tangent(tube.u_min());
        let angle = fibre.dot(&spine).clamp(-1.0, 1.0).acos().to_degrees();
        assert!((angle - 45.0).abs() < 0.05, "{angle}");
    }
}
