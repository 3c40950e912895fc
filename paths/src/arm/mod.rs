//! Six-axis arms beside the IRB 6/2: one interface ([`ArmModel`]) over the five-axis arm of
//! seed 001 ([`crate::robot::Arm`], unchanged) and the six-axis kinds a winding cell uses today.
//!
//! - [`opw`]: any 6R arm with an ortho-parallel base and a spherical wrist (M. Brandstötter,
//!   A. Angerer, M. Hofbaur, "An analytical solution of the inverse kinematics problem of
//!   industrial serial manipulators with an ortho-parallel basis and a spherical wrist", Austrian
//!   Robotics Workshop 2014), in the parameter convention of ROS-Industrial's `opw_kinematics`
//!   (`q = sign · joint − offset`), with presets by model name (`docs/arms.md`).
//! - [`ur`]: Universal Robots e-Series arms from UR's published Denavit–Hartenberg table.
//! - [`path`]: the winding pose solver: the eye's position and the tow direction fix five of the
//!   six degrees of freedom; the turn about the tow line is chosen per pose, with the branch, so
//!   that a whole path keeps one configuration, away from the joint limits and the wrist
//!   singularity, turning the joints as little as the path needs.
//! - [`mandrel`]: where the mandrel's rotation axis is in the robot base frame and who turns it.
//!
//! # Frames and units
//! The **base frame** is the robot's base (for the IRB 6/2 the cell frame of [`crate::robot`]):
//! `z` along axis 1, up. The **flange frame** is the arm's mounting flange (`tool0` in
//! ROS-Industrial's models): `z` out of the flange along axis 6. The **tool frame** is the payout
//! eye: its origin the eye ([`Tool::tcp_mm`] in the flange frame), its `z` axis the eye's axis,
//! pointing from the eye along the free fibre toward the tangent point. Joint angles are the
//! controller's, radians; millimetres throughout.

pub mod mandrel;
pub mod opw;
pub mod path;
mod presets;
pub mod ur;
pub mod winding;

use std::f64::consts::{PI, TAU};
use std::fmt;

use nalgebra::{Matrix3, Point3, Rotation3, UnitQuaternion, Vector3};

use crate::Error;
use crate::robot::{Arm, Capsule};

pub use mandrel::{MandrelAxis, MandrelDrive};
pub use opw::Opw;
pub use path::{EyeTarget, Margins, PathReport, SolvedPath};
pub use ur::Ur;

/// Six joint angles, radians, in axis order (the controller's angles).
pub type Joints6 = [f64; 6];

/// Number of link capsules of a six-axis arm ([`SixAxisArm::links`]).
pub const LINKS: usize = 7;

/// The names of the six-axis link capsules, in [`SixAxisArm::links`] order.
pub const LINK_NAMES: [&str; LINKS] = [
    "base",
    "shoulder",
    "upper arm",
    "elbow",
    "forearm",
    "wrist",
    "tool",
];

/// A frame in the base frame: `p_base = rotation · p_frame + translation_mm`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose6 {
    /// The frame's axes as columns, base frame.
    pub rotation: Matrix3<f64>,
    /// The frame's origin, base frame, mm.
    pub translation_mm: Vector3<f64>,
}

impl Pose6 {
    /// The frame's origin as a point.
    pub fn origin(&self) -> Point3<f64> {
        Point3::from(self.translation_mm)
    }

    /// The orientation as a unit quaternion (`[w, x, y, z]` from its `coords` as `w = coords[3]`).
    pub fn quaternion(&self) -> UnitQuaternion<f64> {
        UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(self.rotation))
    }

    /// This frame followed by `other` (expressed in this frame).
    pub fn then(&self, other: &Pose6) -> Pose6 {
        Pose6 {
            rotation: self.rotation * other.rotation,
            translation_mm: self.rotation * other.translation_mm + self.translation_mm,
        }
    }
}

/// Which side of axis 1 the wrist is on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Shoulder {
    /// The wrist centre in front of axis 1 (on the arm's own `+x` side).
    Front,
    /// The arm turned over the top: the wrist centre behind axis 1.
    Back,
}

/// Which way the elbow bends.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Elbow {
    /// OPW: the forearm turned positively from the upper arm's line (`q3 + ψ3 ∈ [0, π]`); UR:
    /// `θ3 ∈ [0, π]`.
    Up,
    /// The other bend.
    Down,
}

/// Which of the wrist's two solutions.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Wrist {
    /// The wrist bend (OPW `q5`, UR `θ5`) has a non-negative sine.
    NoFlip,
    /// The wrist bend has a negative sine (axis 4 and 6 turned by half a revolution).
    Flip,
}

/// One of the eight branches of a six-axis arm's inverse kinematics: the arm configuration a
/// controller keeps along a path (a shoulder, elbow or wrist flip changes it).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Config {
    /// Shoulder side.
    pub shoulder: Shoulder,
    /// Elbow bend.
    pub elbow: Elbow,
    /// Wrist solution.
    pub wrist: Wrist,
}

impl Config {
    /// The eight configurations in [`Config::index`] order.
    pub const ALL: [Config; 8] = [
        Config::from_index(0),
        Config::from_index(1),
        Config::from_index(2),
        Config::from_index(3),
        Config::from_index(4),
        Config::from_index(5),
        Config::from_index(6),
        Config::from_index(7),
    ];

    /// 0–7: shoulder (back = 4) + elbow (down = 2) + wrist (flip = 1).
    pub const fn index(self) -> usize {
        (matches!(self.shoulder, Shoulder::Back) as usize) * 4
            + (matches!(self.elbow, Elbow::Down) as usize) * 2
            + matches!(self.wrist, Wrist::Flip) as usize
    }

    /// The configuration with the given [`Config::index`] (taken modulo 8).
    pub const fn from_index(i: usize) -> Config {
        Config {
            shoulder: if i & 4 == 0 {
                Shoulder::Front
            } else {
                Shoulder::Back
            },
            elbow: if i & 2 == 0 { Elbow::Up } else { Elbow::Down },
            wrist: if i & 1 == 0 {
                Wrist::NoFlip
            } else {
                Wrist::Flip
            },
        }
    }
}

impl fmt::Display for Config {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} / elbow {} / wrist {}",
            match self.shoulder {
                Shoulder::Front => "front",
                Shoulder::Back => "back",
            },
            match self.elbow {
                Elbow::Up => "up",
                Elbow::Down => "down",
            },
            match self.wrist {
                Wrist::NoFlip => "no flip",
                Wrist::Flip => "flip",
            }
        )
    }
}

/// All eight inverse-kinematics solutions of one flange pose, indexed by [`Config::index`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Solutions {
    /// The joints of each branch (meaningless where not `valid`), each wrapped into (−π, π].
    pub joints: [Joints6; 8],
    /// Whether the branch exists (the wrist centre within reach on that shoulder side).
    pub valid: [bool; 8],
}

/// Why a six-axis arm cannot take a pose (inside [`Error::SixAxis`]).
#[derive(Debug, Clone, PartialEq)]
pub enum SixAxisFault {
    /// The wrist centre is outside the arm's reach on the configuration's shoulder side.
    OutOfReach {
        /// The configuration tried.
        config: Config,
        /// Distance from the shoulder (axis 2) to the wrist centre asked for, mm.
        distance_mm: f64,
        /// Least reachable distance, mm.
        min_mm: f64,
        /// Greatest reachable distance, mm.
        max_mm: f64,
    },
    /// The wrist centre lies within the arm's lateral offset of axis 1 (OPW `|b|`, UR `|d4|`),
    /// where no branch reaches; or on axis 1 itself, where axis 1's angle is undefined.
    InsideAxisOne {
        /// The configuration tried.
        config: Config,
        /// Distance of the wrist centre from axis 1, mm.
        radius_mm: f64,
        /// The lateral offset, mm.
        offset_mm: f64,
    },
    /// A joint outside its range less the margin.
    JointLimit {
        /// Axis number, 1–6.
        axis: usize,
        /// The angle, degrees.
        value_deg: f64,
        /// Least angle, degrees.
        min_deg: f64,
        /// Greatest angle, degrees.
        max_deg: f64,
        /// The margin kept from either end, degrees.
        margin_deg: f64,
    },
    /// The wrist bend is nearer its singularity than the margin.
    WristSingular {
        /// Distance of the wrist bend from its singular angle, degrees.
        distance_deg: f64,
        /// The margin, degrees.
        margin_deg: f64,
    },
    /// A joint would turn further between consecutive poses than the continuity limit.
    JointStep {
        /// Axis number, 1–6.
        axis: usize,
        /// The change, degrees.
        change_deg: f64,
        /// The limit, degrees.
        limit_deg: f64,
    },
    /// No configuration keeps the whole path: the one that went furthest and why it stopped.
    NoConfiguration {
        /// The configuration that went furthest.
        config: Config,
        /// Why it stopped.
        reason: Box<SixAxisFault>,
    },
}

impl fmt::Display for SixAxisFault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SixAxisFault::OutOfReach {
                config,
                distance_mm,
                min_mm,
                max_mm,
            } => {
                let nearest = if distance_mm > max_mm {
                    distance_mm - max_mm
                } else {
                    min_mm - distance_mm
                };
                write!(
                    f,
                    "out of reach ({config}): the wrist centre is {distance_mm:.1} mm from the \
                     shoulder, the arm reaches {min_mm:.1}–{max_mm:.1} mm ({nearest:.1} mm short)"
                )
            }
            SixAxisFault::InsideAxisOne {
                config,
                radius_mm,
                offset_mm,
            } => write!(
                f,
                "out of reach ({config}): the wrist centre is {radius_mm:.1} mm from axis 1, \
                 {:.1} mm inside the arm's {offset_mm:.1} mm lateral offset, where no branch \
                 reaches (on axis 1 its angle is undefined)",
                offset_mm - radius_mm
            ),
            SixAxisFault::JointLimit {
                axis,
                value_deg,
                min_deg,
                max_deg,
                margin_deg,
            } => write!(
                f,
                "axis {axis} at {value_deg:.2}° is outside its range {min_deg:.1}°..{max_deg:.1}° \
                 less the {margin_deg}° margin"
            ),
            SixAxisFault::WristSingular {
                distance_deg,
                margin_deg,
            } => write!(
                f,
                "the wrist is {distance_deg:.2}° from its singularity, less than the \
                 {margin_deg}° margin (wrist_margin_deg)"
            ),
            SixAxisFault::JointStep {
                axis,
                change_deg,
                limit_deg,
            } => write!(
                f,
                "axis {axis} turns {change_deg:.2}° from the previous pose (more than \
                 {limit_deg}°, joint_step_max_deg)"
            ),
            SixAxisFault::NoConfiguration { config, reason } => write!(
                f,
                "no arm configuration keeps the whole path; the one that went furthest \
                 ({config}) stops: {reason}"
            ),
        }
    }
}

/// The payout eye on the flange (`[cell.tool]`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tool {
    /// The eye in the flange frame, mm.
    pub tcp_mm: [f64; 3],
    /// The tool frame's orientation in the flange frame: roll, pitch, yaw about the flange's
    /// fixed `x`, `y`, `z` axes in that order (`R = Rz(yaw) · Ry(pitch) · Rx(roll)`), degrees.
    pub rpy_deg: [f64; 3],
}

impl Default for Tool {
    /// The eye at the flange, axes parallel to the flange's.
    fn default() -> Self {
        Tool {
            tcp_mm: [0.0; 3],
            rpy_deg: [0.0; 3],
        }
    }
}

impl Tool {
    /// Checks that every figure is finite and the eye within [`crate::limits`]' reach of a cell.
    pub fn validate(&self) -> Result<(), Error> {
        for v in self.tcp_mm {
            if !(v.is_finite() && v.abs() <= 10_000.0) {
                return Err(Error::OutOfRange {
                    name: "tcp_mm",
                    value: v,
                    expected: "must be finite and within ±10 000 mm",
                });
            }
        }
        for v in self.rpy_deg {
            if !(v.is_finite() && v.abs() <= 360.0) {
                return Err(Error::OutOfRange {
                    name: "rpy_deg",
                    value: v,
                    expected: "must be finite and within ±360°",
                });
            }
        }
        Ok(())
    }

    /// The tool frame in the flange frame.
    pub fn frame(&self) -> Pose6 {
        let [r, p, y] = self.rpy_deg.map(f64::to_radians);
        Pose6 {
            rotation: *Rotation3::from_euler_angles(r, p, y).matrix(),
            translation_mm: Vector3::from(self.tcp_mm),
        }
    }
}

/// The two kinds of six-axis kinematics.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SixAxisKind {
    /// Ortho-parallel base, spherical wrist.
    Opw(Opw),
    /// Universal Robots (offset wrist).
    Ur(Ur),
}

impl SixAxisKind {
    /// Flange frame in the base frame for the joints.
    pub fn forward(&self, q: &Joints6) -> Pose6 {
        match self {
            SixAxisKind::Opw(o) => o.forward(q),
            SixAxisKind::Ur(u) => u.forward(q),
        }
    }

    /// All eight branches for a flange pose.
    pub fn inverse(&self, flange: &Pose6) -> Solutions {
        match self {
            SixAxisKind::Opw(o) => o.inverse(flange),
            SixAxisKind::Ur(u) => u.inverse(flange),
        }
    }

    /// One branch for a flange pose, or why it does not exist.
    pub fn inverse_branch(&self, flange: &Pose6, config: Config) -> Result<Joints6, SixAxisFault> {
        match self {
            SixAxisKind::Opw(o) => o.inverse_branch(flange, config),
            SixAxisKind::Ur(u) => u.inverse_branch(flange, config),
        }
    }

    /// The configuration the joints are in.
    pub fn config_of(&self, q: &Joints6) -> Config {
        match self {
            SixAxisKind::Opw(o) => o.config_of(q),
            SixAxisKind::Ur(u) => u.config_of(q),
        }
    }

    /// The wrist bend's distance from its singular angle (0 or π), rad, in [0, π/2].
    pub fn wrist_distance_rad(&self, q: &Joints6) -> f64 {
        let bend = match self {
            SixAxisKind::Opw(o) => o.model_angle(q, 4),
            SixAxisKind::Ur(_) => q[4],
        };
        singular_distance(bend)
    }

    /// The joint origins the link capsules join, base frame: base, axis-1 top, shoulder, elbow,
    /// forearm start, wrist centre, flange ([`SixAxisArm::links`]).
    pub fn link_points(&self, q: &Joints6) -> [Point3<f64>; 7] {
        match self {
            SixAxisKind::Opw(o) => o.link_points(q),
            SixAxisKind::Ur(u) => u.link_points(q),
        }
    }

    /// `"opw"` or `"ur"`.
    pub fn kind_name(&self) -> &'static str {
        match self {
            SixAxisKind::Opw(_) => "opw",
            SixAxisKind::Ur(_) => "ur",
        }
    }

    /// Checks the parameters.
    pub fn validate(&self) -> Result<(), Error> {
        match self {
            SixAxisKind::Opw(o) => o.validate(),
            SixAxisKind::Ur(u) => u.validate(),
        }
    }
}

/// The distance of a wrist bend angle from 0 and ±π (where axes 4 and 6 line up), rad.
pub(crate) fn singular_distance(bend_rad: f64) -> f64 {
    let a = wrap(bend_rad).abs();
    a.min(PI - a)
}

/// Ranges and speeds of six joints.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointLimits6 {
    /// Least angles, rad.
    pub min_rad: Joints6,
    /// Greatest angles, rad.
    pub max_rad: Joints6,
    /// Fastest turns, rad/s (`None`: not given; time is then not weighed per joint).
    pub speed_rad_s: Option<Joints6>,
}

impl JointLimits6 {
    /// From degrees.
    pub fn degrees(min_deg: Joints6, max_deg: Joints6, speed_deg_s: Option<Joints6>) -> Self {
        JointLimits6 {
            min_rad: min_deg.map(f64::to_radians),
            max_rad: max_deg.map(f64::to_radians),
            speed_rad_s: speed_deg_s.map(|s| s.map(f64::to_radians)),
        }
    }

    /// Checks that every range is finite with its least below its greatest, spans at most two
    /// turns each side of zero, and every speed is finite and positive.
    pub fn validate(&self) -> Result<(), Error> {
        for i in 0..6 {
            let (lo, hi) = (self.min_rad[i], self.max_rad[i]);
            if !(lo.is_finite() && hi.is_finite()) {
                return Err(Error::OutOfRange {
                    name: "joint_min_deg / joint_max_deg",
                    value: if lo.is_finite() { hi } else { lo },
                    expected: "must be finite",
                });
            }
            if lo >= hi {
                return Err(Error::OutOfRange {
                    name: "joint_min_deg",
                    value: lo.to_degrees(),
                    expected: "must be below joint_max_deg of the same axis",
                });
            }
            if lo < -2.0 * TAU || hi > 2.0 * TAU {
                return Err(Error::OutOfRange {
                    name: "joint_max_deg",
                    value: if hi > 2.0 * TAU { hi } else { lo }.to_degrees(),
                    expected: "must lie within ±720°",
                });
            }
        }
        if let Some(s) = self.speed_rad_s {
            for v in s {
                if !(v > 0.0 && v.is_finite()) {
                    return Err(Error::OutOfRange {
                        name: "joint_speed_deg_s",
                        value: v.to_degrees(),
                        expected: "must be > 0",
                    });
                }
            }
        }
        Ok(())
    }
}

/// A six-axis arm in a cell: its kinematics, joint limits, the eye on its flange, its link
/// radii and the margins the pose solver keeps.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SixAxisArm {
    /// The kinematics.
    pub kind: SixAxisKind,
    /// Joint ranges and speeds.
    pub limits: JointLimits6,
    /// The payout eye on the flange.
    pub tool: Tool,
    /// Capsule radii in [`LINK_NAMES`] order, mm.
    pub link_radii_mm: [f64; LINKS],
    /// What the pose solver keeps away from and how far a joint may turn between poses.
    pub margins: Margins,
}

impl SixAxisArm {
    /// An arm of the given kinematics with its default link radii ([`default_link_radii_mm`])
    /// and the default margins.
    pub fn new(kind: SixAxisKind, limits: JointLimits6, tool: Tool) -> Self {
        SixAxisArm {
            kind,
            limits,
            tool,
            link_radii_mm: default_link_radii_mm(&kind),
            margins: Margins::default(),
        }
    }

    /// A built-in OPW arm by model name (`docs/arms.md`) with the tool, default radii and margins.
    pub fn opw_preset(model: &str, tool: Tool) -> Result<Self, Error> {
        let p = opw::named(model)?;
        Ok(SixAxisArm::new(SixAxisKind::Opw(p.opw), p.limits(), tool))
    }

    /// A built-in UR arm by model name with the tool, default radii and margins.
    pub fn ur_preset(model: &str, tool: Tool) -> Result<Self, Error> {
        let p = ur::named(model)?;
        Ok(SixAxisArm::new(SixAxisKind::Ur(p.ur), p.limits(), tool))
    }

    /// Checks the kinematics, limits, tool, radii and margins.
    pub fn validate(&self) -> Result<(), Error> {
        self.kind.validate()?;
        self.limits.validate()?;
        self.tool.validate()?;
        for r in self.link_radii_mm {
            if !(r >= 0.0 && r.is_finite() && r <= 10_000.0) {
                return Err(Error::OutOfRange {
                    name: "link_radii_mm",
                    value: r,
                    expected: "must be ≥ 0 and finite",
                });
            }
        }
        self.margins.validate()
    }

    /// The tool frame (eye, tool axes) in the base frame for the joints.
    pub fn tool_frame(&self, q: &Joints6) -> Pose6 {
        self.kind.forward(q).then(&self.tool.frame())
    }

    /// The link capsules, base frame, in [`LINK_NAMES`] order: base column, shoulder offset,
    /// upper arm, elbow offset, forearm, wrist (centre to flange) and tool (flange to eye).
    pub fn links(&self, q: &Joints6) -> [Capsule; LINKS] {
        let p = self.kind.link_points(q);
        let eye = self.tool_frame(q).origin();
        let r = self.link_radii_mm;
        std::array::from_fn(|i| Capsule {
            a: p[i],
            b: if i + 1 < 7 { p[i + 1] } else { eye },
            radius_mm: r[i],
        })
    }

    /// Whether the robot controller can drive the mandrel as an external axis (`drive =
    /// "robot"`): the industrial controllers of the OPW arms can (KUKA E1, ABB positioner
    /// mechanical units, FANUC motion groups); a UR controller has no external axes.
    pub fn has_external_axis(&self) -> bool {
        matches!(self.kind, SixAxisKind::Opw(_))
    }
}

/// Default capsule radii, mm, in [`LINK_NAMES`] order (an **assumption** that encloses the
/// castings of arms of each class; measure the real arm and set `link_radii_mm`): an OPW arm of
/// the 10–60 kg class 200 (base), 160, 120, 110, 90, 70 and 25 (tool); a UR e-Series arm 75, 75,
/// 60, 55, 50, 45 and 25 (UR's link tubes and joint housings are 90–150 mm across).
pub fn default_link_radii_mm(kind: &SixAxisKind) -> [f64; LINKS] {
    match kind {
        SixAxisKind::Opw(_) => [200.0, 160.0, 120.0, 110.0, 90.0, 70.0, 25.0],
        SixAxisKind::Ur(_) => [75.0, 75.0, 60.0, 55.0, 50.0, 45.0, 25.0],
    }
}

/// Any arm windcell plans for, chosen by `[cell.robot] kind`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ArmModel {
    /// `"irb6-2"`: the five-axis ASEA IRB 6/2 of seed 001 (the default).
    Irb6(Arm),
    /// `"opw"` or `"ur"`: a six-axis arm.
    SixAxis(SixAxisArm),
}

impl Default for ArmModel {
    fn default() -> Self {
        ArmModel::Irb6(Arm::default())
    }
}

impl ArmModel {
    /// `"irb6-2"`, `"opw"` or `"ur"`.
    pub fn kind_name(&self) -> &'static str {
        match self {
            ArmModel::Irb6(_) => "irb6-2",
            ArmModel::SixAxis(a) => a.kind.kind_name(),
        }
    }

    /// 5 or 6.
    pub fn axes(&self) -> usize {
        match self {
            ArmModel::Irb6(_) => 5,
            ArmModel::SixAxis(_) => 6,
        }
    }

    /// Checks the arm's figures.
    pub fn validate(&self) -> Result<(), Error> {
        match self {
            ArmModel::Irb6(a) => a.validate(),
            ArmModel::SixAxis(a) => a.validate(),
        }
    }

    /// Whether `[cell.mandrel] drive = "robot"` is possible (the IRB 6/2's mandrel is turned by
    /// windcell's indexer, seed 001 §4.1.4).
    pub fn has_external_axis(&self) -> bool {
        match self {
            ArmModel::Irb6(_) => false,
            ArmModel::SixAxis(a) => a.has_external_axis(),
        }
    }
}

/// `atan(k/16)` for k = 0..16 (correctly rounded).
const ATAN_SIXTEENTHS: [f64; 17] = [
    0.0,
    0.062_418_809_995_957_35,
    0.124_354_994_546_761_44,
    0.185_347_949_995_694_76,
    0.244_978_663_126_864_14,
    0.302_884_868_374_971_4,
    0.358_770_670_270_572_25,
    0.412_410_441_597_387_3,
    0.463_647_609_000_806_1,
    0.512_389_460_310_737_7,
    0.558_599_315_343_562_4,
    0.602_287_346_134_964_2,
    0.643_501_108_793_284_4,
    0.682_316_554_874_748_1,
    0.718_829_999_621_624_5,
    0.753_151_280_962_194_4,
    std::f64::consts::FRAC_PI_4,
];

/// `atan2(y, x)` for the inverse kinematics, within a few units in the last place of the
/// library's (tested against it): the ratio of the smaller to the larger magnitude `t ∈ [0, 1]`
/// is reduced by the nearest sixteenth `c` to `u = (t − c)/(1 + t·c)`, `|u| ≤ 1/32`, and
/// `atan t = atan c + atan u` with the Taylor series of `atan u` to `u⁹` (remainder below
/// `32⁻¹¹/11 ≈ 3·10⁻¹⁸`, under a unit in the last place of any result), evaluated in two
/// independent halves (Estrin's scheme) to shorten the chain of dependent operations the
/// inverse kinematics waits on. Zeros, infinities and NaN go to the library; a `y` of `−0`
/// against a finite `x` gives the library's `−0` or `−π`.
#[inline]
pub(crate) fn atan2(y: f64, x: f64) -> f64 {
    let (ax, ay) = (x.abs(), y.abs());
    if !(ax.max(ay) > 0.0 && ax.max(ay) < f64::INFINITY) {
        return y.atan2(x);
    }
    let swap = ay > ax;
    let t = if swap { ax / ay } else { ay / ax };
    let k = ((t * 16.0 + 0.5) as usize).min(16);
    let c = k as f64 * 0.0625;
    let u = (t - c) / (1.0 + t * c);
    let u2 = u * u;
    let u4 = u2 * u2;
    let series =
        u * ((1.0 - u2 * (1.0 / 3.0)) + u4 * ((0.2 - u2 * (1.0 / 7.0)) + u4 * (1.0 / 9.0)));
    let mut a = ATAN_SIXTEENTHS[k] + series;
    if swap {
        a = std::f64::consts::FRAC_PI_2 - a;
    }
    if x < 0.0 {
        a = PI - a;
    }
    // The sign of `y`'s zero counts as the library's does: `atan2(−0, −1) = −π`, not `π`.
    if y.is_sign_negative() { -a } else { a }
}

/// Wraps an angle into (−π, π] (one add for angles within two turns, which is what sums of
/// arctangents give; a floating remainder otherwise).
pub(crate) fn wrap(a: f64) -> f64 {
    if a > -PI && a <= PI {
        a
    } else if a > PI && a <= PI + TAU {
        a - TAU
    } else if a <= -PI && a > -PI - TAU {
        a + TAU
    } else {
        let w = a.rem_euclid(TAU);
        if w > PI { w - TAU } else { w }
    }
}

/// The configuration by its definitions' three signs, for the tests of both arm kinds: the wrist
/// point ahead of axis 1 (front), the elbow bend positive (up), the wrist bend positive (no
/// flip); written here once, apart from each kind's own `config_of`.
#[cfg(test)]
pub(crate) fn config_by_signs(ahead: f64, elbow_bend: f64, wrist_bend: f64) -> Config {
    Config {
        shoulder: if ahead > 0.0 {
            Shoulder::Front
        } else {
            Shoulder::Back
        },
        elbow: if elbow_bend > 0.0 {
            Elbow::Up
        } else {
            Elbow::Down
        },
        wrist: if wrist_bend > 0.0 {
            Wrist::NoFlip
        } else {
            Wrist::Flip
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn config_index_round_trips() {
        for (i, c) in Config::ALL.iter().enumerate() {
            assert_eq!(c.index(), i);
            assert_eq!(Config::from_index(i), *c);
        }
        assert_eq!(
            Config::from_index(5).to_string(),
            "back / elbow up / wrist flip"
        );
    }

    /// The fast arctangent against the library's over every octant and the edges.
    #[test]
    fn atan2_matches_the_library() {
        let mut seed = 0x1234_5678_9abc_def0u64;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        let mut worst: f64 = 0.0;
        for _ in 0..200_000 {
            let (y, x) = (next() * 1e3, next() * 1e3);
            worst = worst.max((atan2(y, x) - y.atan2(x)).abs());
        }
        for (y, x) in [
            (1.0, 1.0),
            (-1.0, 1.0),
            (1.0, -1.0),
            (-1.0, -1.0),
            (0.0, 1.0),
            (0.0, -1.0),
            (1.0, 0.0),
            (-1.0, 0.0),
            (1e-300, 1.0),
            (1.0, 1e-300),
            (3.0, 7.0 / 8.0 * 3.0),
        ] {
            worst = worst.max((atan2(y, x) - y.atan2(x)).abs());
        }
        assert!(worst < 2e-15, "{worst}");
        assert!(atan2(f64::NAN, 1.0).is_nan());
        assert_eq!(atan2(0.0, 0.0), 0.0);
    }

    /// The fast arctangent in units in the last place of the library's, at every scale: both
    /// magnitudes from 2⁻¹⁰⁰⁰ to 2¹⁰⁰⁰ (so ratios down to the subnormals), every octant and
    /// both signs, at most 2 units apart; the sixteenths' boundaries (`t = (k ± ½)/16`, where
    /// the reduction's `|u|` is largest) at most 2 as well. The inputs the library is left with
    /// give its own result bit for bit: both zeros of either sign, infinities (`∞/∞` is `±π/4`
    /// or `±3π/4`, not `0/0`), NaN in either place, and a signed zero against a finite `x`
    /// (`atan2(−0, −1) = −π`, `atan2(−0, 1) = −0`).
    #[test]
    fn atan2_is_the_librarys_to_two_units_in_the_last_place() {
        // A monotone map of the finite doubles onto the integers: adjacent doubles differ by 1.
        fn key(v: f64) -> i64 {
            let i = v.to_bits() as i64;
            if i < 0 { i64::MIN - i } else { i }
        }
        let ulps = |y: f64, x: f64| (key(atan2(y, x)) - key(y.atan2(x))).unsigned_abs();
        let mut seed = 0x0ddc_0ffe_e15e_a5edu64;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed
        };
        let mut worst = 0;
        for _ in 0..200_000 {
            let (a, b) = (next(), next());
            let mantissa = |r: u64| 1.0 + (r >> 12) as f64 / (1u64 << 52) as f64;
            let sign = |r: u64| if r & 1 == 0 { 1.0 } else { -1.0 };
            let scale = |r: u64| 2f64.powi((r % 2001) as i32 - 1000);
            // Half the draws at like scales (ratios near 1, every sixteenth), half anywhere.
            let (ey, ex) = if a & 2 == 0 {
                (scale(b), scale(b) * 2f64.powi((a >> 2) as i32 % 4))
            } else {
                (scale(b), scale(b >> 11))
            };
            let (y, x) = (sign(a) * mantissa(a) * ey, sign(a >> 1) * mantissa(b) * ex);
            worst = worst.max(ulps(y, x));
        }
        assert!(worst <= 2, "{worst} units in the last place");
        // Either side of every sixteenth's boundary, in each octant.
        for k in 0..16 {
            for d in [-1e-9, 0.0, 1e-9] {
                let t = (k as f64 + 0.5) / 16.0 + d;
                for (y, x) in [(t, 1.0), (1.0, t), (-t, 1.0), (t, -1.0), (-1.0, -t)] {
                    let u = ulps(y, x);
                    assert!(u <= 2, "atan2({y}, {x}): {u} units in the last place");
                }
            }
        }
        let same = |y: f64, x: f64| {
            let (ours, lib) = (atan2(y, x), y.atan2(x));
            assert!(
                ours.to_bits() == lib.to_bits() || (ours.is_nan() && lib.is_nan()),
                "atan2({y}, {x}) = {ours}, the library's {lib}"
            );
        };
        let inf = f64::INFINITY;
        for y in [0.0, -0.0, 1.0, -1.0, inf, -inf, f64::NAN] {
            for x in [0.0, -0.0, 1.0, -1.0, inf, -inf, f64::NAN] {
                same(y, x);
            }
        }
        assert_eq!(atan2(inf, inf), std::f64::consts::FRAC_PI_4);
        assert_eq!(atan2(-inf, -inf), -3.0 * std::f64::consts::FRAC_PI_4);
        assert_eq!(atan2(-0.0, -1.0), -PI);
    }

    #[test]
    fn wrap_is_into_minus_pi_pi() {
        for a in [-7.0, -PI, -1.0, 0.0, PI, 4.0, 13.0] {
            let w = wrap(a);
            assert!(w > -PI && w <= PI, "{a} → {w}");
            assert!(((a - w) / TAU - ((a - w) / TAU).round()).abs() < 1e-12);
        }
        assert!((singular_distance(0.1) - 0.1).abs() < 1e-15);
        assert!((singular_distance(PI - 0.2) - 0.2).abs() < 1e-12);
        assert!((singular_distance(-PI + 0.3) - 0.3).abs() < 1e-12);
    }

    /// Whole multiples of π, which are exact in binary (π's double has trailing zero bits, so
    /// `k·π` is exact for odd `k` up to 9 and `fmod` is exact): an odd multiple wraps to π, never
    /// −π, and an even one to 0, at the ends of the one-add branches (±π, ±3π) and beyond them
    /// (±5π, ±7π, ±9π, ±4π, ±8π); a hair inside −3π and 3π keeps its one add.
    #[test]
    fn wrap_takes_odd_multiples_of_pi_to_pi_and_even_ones_to_zero() {
        for k in [1.0, 3.0, 5.0, 7.0, 9.0] {
            assert_eq!(wrap(k * PI), PI, "{k}π");
            assert_eq!(wrap(-k * PI), PI, "−{k}π");
        }
        for k in [0.0, 2.0, 4.0, 8.0] {
            assert_eq!(wrap(k * PI), 0.0, "{k}π");
            assert_eq!(wrap(-k * PI), 0.0, "−{k}π");
        }
        // An angle inside (−π, π] is returned as it is, however small (a remainder of −10⁻²⁰
        // by 2π would round to 2π and give 0); one within a turn beyond either end is one add
        // of 2π away (exact there: both are within a factor 2 of 2π).
        assert_eq!(wrap(-1e-20), -1e-20);
        assert_eq!(wrap(1e-20), 1e-20);
        let a = -TAU - 0.1;
        assert_eq!(wrap(a), a + TAU);
        let a = TAU + 0.1;
        assert_eq!(wrap(a), a - TAU);
        // Just inside the one-add branches: 3π less a thousandth, −3π plus one.
        assert_eq!(wrap(3.0 * PI - 1e-3), 3.0 * PI - 1e-3 - TAU);
        assert_eq!(wrap(-3.0 * PI + 1e-3), -3.0 * PI + 1e-3 + TAU);
        // Far out: a million radians is 159 154.94 turns, so 159 155 turns less 0.358 rad.
        let w = wrap(1e6);
        assert!((w - (1e6 - 159_155.0 * TAU)).abs() < 1e-9, "{w}");
        assert!((wrap(-1e6) + w).abs() < 1e-9);
    }

    /// The wrist bend's distance from its singular angles is taken on the model angle of axis 5
    /// for an OPW arm (`sign·q − offset`) and on the joint itself for a UR: by hand, 0.3 rad
    /// from 0, π − 2.9 rad from π, and with axis 5 reversed and offset by 0.5 rad a joint angle
    /// of 0.2 rad is a bend of −0.7 rad, 0.7 rad from 0.
    #[test]
    fn the_wrist_distance_is_the_bend_from_zero_or_half_a_turn() {
        let irb = SixAxisArm::opw_preset("irb2600-12/1.65", Tool::default()).unwrap();
        let ur = SixAxisArm::ur_preset("ur10e", Tool::default()).unwrap();
        let bent = |b: f64| [0.1, 0.2, 0.3, 0.4, b, 0.6];
        for kind in [irb.kind, ur.kind] {
            assert!((kind.wrist_distance_rad(&bent(0.3)) - 0.3).abs() < 1e-15);
            assert!((kind.wrist_distance_rad(&bent(2.9)) - (PI - 2.9)).abs() < 1e-15);
            assert!((kind.wrist_distance_rad(&bent(-2.9)) - (PI - 2.9)).abs() < 1e-15);
        }
        let SixAxisKind::Opw(mut o) = irb.kind else {
            unreachable!()
        };
        o.signs[4] = -1;
        o.offsets_rad[4] = 0.5;
        let reversed = SixAxisKind::Opw(o);
        assert!((reversed.wrist_distance_rad(&bent(0.2)) - 0.7).abs() < 1e-15);
    }

    /// The default link radii are the table of `docs/arms.md` ("Default radii"), read from
    /// the document, for both kinds, and a new arm takes them.
    #[test]
    fn default_link_radii_are_the_documented_table() {
        let doc = include_str!("../../../docs/arms.md");
        let row = |kind: &str| -> Vec<f64> {
            let start = format!("| `{kind}` | ");
            let line = doc
                .lines()
                .find(|l| l.starts_with(&start) && l.split('|').count() == LINKS + 3)
                .unwrap_or_else(|| panic!("no radii row for {kind} in docs/arms.md"));
            line.split('|')
                .skip(2)
                .take(LINKS)
                .map(|c| c.trim().parse().unwrap())
                .collect()
        };
        let irb = SixAxisArm::opw_preset("irb2600-12/1.65", Tool::default()).unwrap();
        let ur = SixAxisArm::ur_preset("ur10e", Tool::default()).unwrap();
        assert_eq!(default_link_radii_mm(&irb.kind).to_vec(), row("opw"));
        assert_eq!(default_link_radii_mm(&ur.kind).to_vec(), row("ur"));
        assert_eq!(irb.link_radii_mm.to_vec(), row("opw"));
        assert_eq!(ur.link_radii_mm.to_vec(), row("ur"));
    }

    #[test]
    fn tool_frame_is_roll_pitch_yaw_about_fixed_axes() {
        let t = Tool {
            tcp_mm: [10.0, 0.0, 200.0],
            rpy_deg: [0.0, 90.0, 0.0],
        };
        let f = t.frame();
        // A pitch of 90° about y takes the tool z onto the flange x.
        let z = f.rotation * Vector3::z();
        assert!((z - Vector3::x()).norm() < 1e-12);
        assert_eq!(f.translation_mm, Vector3::new(10.0, 0.0, 200.0));
        assert!(
            Tool {
                tcp_mm: [f64::NAN, 0.0, 0.0],
                ..t
            }
            .validate()
            .is_err()
        );
    }

    /// The name and value of an [`Error::OutOfRange`], or a panic naming what came instead.
    fn refused<T: fmt::Debug>(r: Result<T, Error>) -> (&'static str, f64) {
        match r {
            Err(Error::OutOfRange { name, value, .. }) => (name, value),
            other => panic!("expected a refusal, got {other:?}"),
        }
    }

    /// The tool's bounds are inclusive: an eye 10 000 mm out on any axis and a turn of 360° are
    /// taken; a hair beyond, a NaN or an infinity is refused with its name and value.
    #[test]
    fn tool_figures_are_taken_up_to_their_bounds_and_refused_beyond() {
        let edge = Tool {
            tcp_mm: [10_000.0, -10_000.0, 0.0],
            rpy_deg: [360.0, -360.0, 0.0],
        };
        edge.validate().unwrap();
        for v in [10_000.001, -10_000.001, f64::INFINITY, f64::NAN] {
            for i in 0..3 {
                let mut t = edge;
                t.tcp_mm[i] = v;
                let (name, value) = refused(t.validate());
                assert_eq!(name, "tcp_mm");
                assert!(
                    value == v || (v.is_nan() && value.is_nan()),
                    "{value} for {v}"
                );
            }
        }
        for v in [360.001, -360.001, f64::NEG_INFINITY, f64::NAN] {
            for i in 0..3 {
                let mut t = edge;
                t.rpy_deg[i] = v;
                let (name, value) = refused(t.validate());
                assert_eq!(name, "rpy_deg");
                assert!(
                    value == v || (v.is_nan() && value.is_nan()),
                    "{value} for {v}"
                );
            }
        }
    }

    /// Joint ranges: any range inside two turns each side of zero with its least below its
    /// greatest is taken, the ±720° ends included; an infinite end is refused naming that end,
    /// an empty or reversed range naming its least end, an end beyond ±720° naming that end (in
    /// degrees), and a speed that is not finite and positive naming the speed.
    #[test]
    fn joint_limits_are_taken_up_to_two_turns_and_refused_beyond() {
        let turns = 2.0 * TAU;
        let wide = JointLimits6 {
            min_rad: [-turns; 6],
            max_rad: [turns; 6],
            speed_rad_s: Some([1e-6; 6]),
        };
        wide.validate().unwrap();
        for axis in 0..6 {
            let mut l = wide;
            l.min_rad[axis] = f64::NEG_INFINITY;
            assert_eq!(
                refused(l.validate()),
                ("joint_min_deg / joint_max_deg", f64::NEG_INFINITY)
            );
            let mut l = wide;
            l.max_rad[axis] = f64::INFINITY;
            assert_eq!(
                refused(l.validate()),
                ("joint_min_deg / joint_max_deg", f64::INFINITY)
            );
            // Empty and reversed ranges.
            for hi in [0.5, 0.25] {
                let mut l = wide;
                l.min_rad[axis] = 0.5;
                l.max_rad[axis] = hi;
                assert_eq!(
                    refused(l.validate()),
                    ("joint_min_deg", 0.5f64.to_degrees())
                );
            }
            // A hair beyond two turns at either end.
            let beyond = turns * (1.0 + 1e-12);
            let mut l = wide;
            l.max_rad[axis] = beyond;
            assert_eq!(
                refused(l.validate()),
                ("joint_max_deg", beyond.to_degrees())
            );
            let mut l = wide;
            l.min_rad[axis] = -beyond;
            assert_eq!(
                refused(l.validate()),
                ("joint_max_deg", -beyond.to_degrees())
            );
            // Speeds.
            for v in [0.0, -1.0, f64::INFINITY] {
                let mut l = wide;
                let mut speed = [1.0; 6];
                speed[axis] = v;
                l.speed_rad_s = Some(speed);
                assert_eq!(refused(l.validate()), ("joint_speed_deg_s", v.to_degrees()));
            }
            let mut l = wide;
            let mut speed = [1.0; 6];
            speed[axis] = f64::NAN;
            l.speed_rad_s = Some(speed);
            assert_eq!(refused(l.validate()).0, "joint_speed_deg_s");
        }
        let no_speeds = JointLimits6 {
            speed_rad_s: None,
            ..wide
        };
        no_speeds.validate().unwrap();
        // Degrees in, radians kept.
        let d = JointLimits6::degrees([-90.0; 6], [180.0; 6], Some([360.0; 6]));
        assert_eq!(d.min_rad, [-std::f64::consts::FRAC_PI_2; 6]);
        assert_eq!(d.max_rad, [PI; 6]);
        assert_eq!(d.speed_rad_s, Some([TAU; 6]));
    }

    /// Link radii from 0 to 10 000 mm are taken; a negative, NaN, infinite or larger one is
    /// refused naming `link_radii_mm`, on every link.
    #[test]
    fn link_radii_are_taken_from_zero_to_ten_metres() {
        let mut arm = SixAxisArm::ur_preset("ur5e", Tool::default()).unwrap();
        arm.link_radii_mm = [0.0, 10_000.0, 0.0, 10_000.0, 0.0, 10_000.0, 0.0];
        arm.validate().unwrap();
        for k in 0..LINKS {
            for v in [-0.001, 10_000.001, f64::INFINITY, f64::NAN] {
                let mut a = arm;
                a.link_radii_mm[k] = v;
                let (name, value) = refused(a.validate());
                assert_eq!(name, "link_radii_mm");
                assert!(
                    value == v || (v.is_nan() && value.is_nan()),
                    "{value} for {v}"
                );
            }
        }
    }

    /// The out-of-reach message gives the shortfall from the nearer end of the reach: 2 000 mm
    /// asked of a 300–1 500 mm reach is 500 mm short, 100 mm is 200 mm short.
    #[test]
    fn an_out_of_reach_message_gives_the_shortfall() {
        let config = Config::from_index(0);
        let fault = |distance_mm: f64| SixAxisFault::OutOfReach {
            config,
            distance_mm,
            min_mm: 300.0,
            max_mm: 1500.0,
        };
        assert_eq!(
            fault(2000.0).to_string(),
            "out of reach (front / elbow up / wrist no flip): the wrist centre is 2000.0 mm from \
             the shoulder, the arm reaches 300.0–1500.0 mm (500.0 mm short)"
        );
        assert!(
            fault(100.0).to_string().ends_with("(200.0 mm short)"),
            "{}",
            fault(100.0)
        );
    }

    /// What each arm kind is called, how many axes it has and whether its controller can turn
    /// the mandrel: the IRB 6/2 (the default) five axes and windcell's indexer; the OPW arms'
    /// industrial controllers take an external axis; a UR controller does not.
    #[test]
    fn arm_kinds_name_their_axes_and_external_axis() {
        let irb = ArmModel::default();
        assert_eq!(
            (irb.kind_name(), irb.axes(), irb.has_external_axis()),
            ("irb6-2", 5, false)
        );
        irb.validate().unwrap();
        let opw = SixAxisArm::opw_preset("irb2600-12/1.65", Tool::default()).unwrap();
        let ur = SixAxisArm::ur_preset("ur10e", Tool::default()).unwrap();
        let (opw_model, ur_model) = (ArmModel::SixAxis(opw), ArmModel::SixAxis(ur));
        assert_eq!((opw_model.kind_name(), opw_model.axes()), ("opw", 6));
        assert_eq!((ur_model.kind_name(), ur_model.axes()), ("ur", 6));
        assert!(opw_model.has_external_axis() && opw.has_external_axis());
        assert!(!ur_model.has_external_axis() && !ur.has_external_axis());
        opw_model.validate().unwrap();
        ur_model.validate().unwrap();
        // Each model's validation is the arm's own.
        let mut bad = ur;
        bad.link_radii_mm[0] = -1.0;
        assert!(ArmModel::SixAxis(bad).validate().is_err());
        let short = Arm {
            forearm_mm: -1.0,
            ..Arm::default()
        };
        assert!(ArmModel::Irb6(short).validate().is_err());
        // The kinematics' own figures are checked with the arm's.
        let mut opw_bad = opw;
        if let SixAxisKind::Opw(o) = &mut opw_bad.kind {
            o.c2_mm = f64::NAN;
        }
        assert!(opw_bad.validate().is_err());
        let mut ur_bad = ur;
        if let SixAxisKind::Ur(u) = &mut ur_bad.kind {
            u.a2_mm = 0.0;
        }
        assert!(ur_bad.validate().is_err());
    }
}
