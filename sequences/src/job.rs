//! The job file (TOML): the cell (robot distance, heights, speeds, drive, ports) and what to wind
//! (the mandrel and its paths). `docs/file-formats.md` lists every field.
//!
//! Fields that are checked after parsing keep their place in the text ([`Spanned`]) so that every
//! error names the line and column of the offending value.

use std::ops::Range;
use std::path::Path;

use serde::{Deserialize, Serialize};
use toml::Spanned;

use crate::{Error, Movement};

mod arm;

/// A whole job file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Job {
    /// Base name of the control files: `NAME_<prog>.ROB`.
    pub name: Spanned<String>,
    /// The cell.
    pub cell: Cell,
    /// The mandrel.
    pub mandrel: Mandrel,
    /// The fibre paths, `[[path]]` tables.
    #[serde(rename = "path")]
    pub paths: Vec<PathSpec>,
}

/// The cell: where the robot stands, how fast things move, the drive and the serial ports.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Cell {
    /// `b`: robot pedestal to the mandrel drive's rotation axis, mm (seed 001 §5.6 c).
    pub robot_distance_mm: Spanned<f64>,
    /// Height of the mandrel's lower end (spine distance 0) above the robot base, mm (§5.6 d).
    pub start_height_mm: Spanned<f64>,
    /// Mandrel speed, rev/s (§5.6 e).
    pub mandrel_speed_rps: Spanned<f64>,
    /// Length of the payout-eye mechanism, mm (§5.6 f).
    pub eye_mechanism_length_mm: Spanned<f64>,
    /// Tow distance from the mandrel surface to the eye, mm (§5.6 g).
    pub offset_mm: Spanned<f64>,
    /// Robot base speed, mm/s (§5.4.1).
    pub base_speed_mm_s: Spanned<f64>,
    /// Robot maximum speed, mm/s.
    pub max_speed_mm_s: Spanned<f64>,
    /// Movement type: `discrete`, `fine` or `medium`.
    pub movement: Spanned<Movement>,
    /// The mandrel drive.
    pub drive: Drive,
    /// The robot arm; absent means the IRB 6/2 defaults.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub robot: Option<Robot>,
    /// The measured cell; absent means the nominal cell.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub calibration: Option<Calibration>,
    /// Serial ports; absent means the built-in simulated cell.
    #[serde(default, skip_serializing_if = "Ports::is_empty")]
    pub ports: Ports,
    /// The payout-eye mechanism for the clearance check; absent means the defaults.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub eye: Option<Eye>,
    /// Obstacles in the cell frame (floor, mandrel-drive frame, fences), `[[cell.obstacle]]`.
    #[serde(default, rename = "obstacle", skip_serializing_if = "Vec::is_empty")]
    pub obstacles: Vec<Obstacle>,
    /// A six-axis arm's payout eye on its flange (`[cell.tool]`); required for `kind = "opw"`
    /// and `"ur"`, refused for the IRB 6/2 (whose eye sits on its roll axis).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tool: Option<Tool>,
    /// Where the mandrel's rotation axis is and who turns it (`[cell.mandrel]`); absent means
    /// the thesis cell: vertical through `(robot_distance_mm, 0, start_height_mm)`, the indexer.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mandrel: Option<MandrelPlacement>,
}

/// A six-axis arm's payout eye (`[cell.tool]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Tool {
    /// The eye in the flange frame, mm.
    pub tcp_mm: Spanned<[f64; 3]>,
    /// The tool frame's turn in the flange frame: roll, pitch, yaw about the flange's fixed
    /// `x`, `y`, `z`, degrees (absent: axes parallel to the flange's). The tool's `z` is the
    /// eye's axis, from the eye along the free fibre.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rpy_deg: Option<Spanned<[f64; 3]>>,
}

/// Who turns the mandrel (`[cell.mandrel] drive`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum MandrelDrive {
    /// windcell's indexer (decoupled; the default).
    Indexer,
    /// The robot controller, as an external axis (coupled; `kind = "opw"` only).
    Robot,
}

/// The mandrel's rotation axis in the robot base frame (`[cell.mandrel]`).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MandrelPlacement {
    /// A point of the axis, the mandrel's start (spine distance 0), base frame, mm (default
    /// `[robot_distance_mm, 0, start_height_mm]`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub axis_origin_mm: Option<Spanned<[f64; 3]>>,
    /// The axis direction, base frame, any length (default `[0, 0, 1]`, vertical).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub axis_direction: Option<Spanned<[f64; 3]>>,
    /// `"indexer"` (default) or `"robot"`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub drive: Option<Spanned<MandrelDrive>>,
}

/// The arm's kind (`[cell.robot] kind`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum RobotKind {
    /// The five-axis ASEA IRB 6/2 of seed 001 (the default).
    #[serde(rename = "irb6-2")]
    Irb6,
    /// A 6R arm with an ortho-parallel base and a spherical wrist.
    #[serde(rename = "opw")]
    Opw,
    /// A Universal Robots arm.
    #[serde(rename = "ur")]
    Ur,
}

/// The payout-eye mechanism as the clearance check sees it (seed 001 §5.7): a capsule from the
/// eye back along the tool axis.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Eye {
    /// From the eye to the wrist, mm (default: `eye_mechanism_length_mm`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub length_mm: Option<Spanned<f64>>,
    /// Capsule radius, mm (default 10).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub radius_mm: Option<Spanned<f64>>,
    /// Depth inside the mandrel at which the free fibre snags, mm (default 0.01).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub snag_tolerance_mm: Option<Spanned<f64>>,
    /// The eye's home position, cell frame, mm: where the approach to the first path starts
    /// (absent: that approach is not checked).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub home_mm: Option<Spanned<[f64; 3]>>,
}

/// An axis-aligned box in the cell frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Obstacle {
    /// What it is (`floor`, `drive frame`).
    pub name: Spanned<String>,
    /// Least corner, mm.
    pub min_mm: Spanned<[f64; 3]>,
    /// Greatest corner, mm.
    pub max_mm: Spanned<[f64; 3]>,
}

/// The mandrel drive (seed 001 §4.1.4–4.1.6).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Drive {
    /// Motor steps per motor revolution (400 half-steps).
    pub steps_per_rev: Spanned<u32>,
    /// Timing belt: `[motor pulley teeth, mandrel pulley teeth]` (`[13, 60]`).
    pub gear_ratio: Spanned<[u32; 2]>,
    /// Mandrel acceleration, rev/s².
    pub accel_rps2: Spanned<f64>,
    /// Mandrel start/stop velocity, rev/s.
    pub start_stop_rps: Spanned<f64>,
}

/// The robot arm (`[cell.robot]`): every field optional, absent ones take the IRB 6/2 defaults
/// of `paths::robot::Arm` (which documents where each figure comes from).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Robot {
    /// Height of the shoulder axis above the robot base, mm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shoulder_height_mm: Option<Spanned<f64>>,
    /// Shoulder axis to elbow axis, mm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub upper_arm_mm: Option<Spanned<f64>>,
    /// Elbow axis to wrist axis, mm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub forearm_mm: Option<Spanned<f64>>,
    /// The longest eye mechanism the wrist can carry, mm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub eye_mechanism_max_mm: Option<Spanned<f64>>,
    /// Base yaw range `[least, greatest]`, degrees.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub base_yaw_deg: Option<Spanned<[f64; 2]>>,
    /// Shoulder range (upper arm from the vertical), degrees.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shoulder_deg: Option<Spanned<[f64; 2]>>,
    /// Elbow range (forearm elevation), degrees.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub elbow_deg: Option<Spanned<[f64; 2]>>,
    /// Wrist pitch range (roll axis below the horizontal), degrees.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pitch_deg: Option<Spanned<[f64; 2]>>,
    /// Wrist roll range, degrees.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub roll_deg: Option<Spanned<[f64; 2]>>,
    /// Joint speed limits in axis order, degrees/s: five for the IRB 6/2 (base yaw, shoulder,
    /// elbow, pitch, roll), six for a six-axis arm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub joint_speed_deg_s: Option<Spanned<Vec<f64>>>,
    /// Largest fibre entry angle (tow line to the eye's roll axis), degrees (IRB 6/2 only: a
    /// six-axis eye takes the tow line exactly).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub entry_angle_max_deg: Option<Spanned<f64>>,
    /// `"irb6-2"` (default), `"opw"` or `"ur"`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub kind: Option<Spanned<RobotKind>>,
    /// A built-in arm of the kind (`docs/arms.md`); the keys below override its values one by one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub model: Option<Spanned<String>>,
    /// OPW: axis 2's offset from axis 1, mm. UR: not used (see `a2_mm`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub a1_mm: Option<Spanned<f64>>,
    /// OPW: the forearm's offset, mm. UR: the DH `a2` (upper arm, negative), mm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub a2_mm: Option<Spanned<f64>>,
    /// OPW: the wrist centre's lateral offset, mm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub b_mm: Option<Spanned<f64>>,
    /// OPW: height of axis 2 above the base, mm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub c1_mm: Option<Spanned<f64>>,
    /// OPW: axis 2 to axis 3, mm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub c2_mm: Option<Spanned<f64>>,
    /// OPW: axis 3 to the wrist centre, mm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub c3_mm: Option<Spanned<f64>>,
    /// OPW: wrist centre to the flange, mm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub c4_mm: Option<Spanned<f64>>,
    /// OPW: the six model angle offsets, degrees (`q = sign · joint − offset`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub offsets_deg: Option<Spanned<Vec<f64>>>,
    /// OPW: the six sign corrections, each 1 or -1.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub signs: Option<Spanned<Vec<i64>>>,
    /// UR: the DH `d1`, mm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub d1_mm: Option<Spanned<f64>>,
    /// UR: the DH `a3` (forearm, negative), mm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub a3_mm: Option<Spanned<f64>>,
    /// UR: the DH `d4`, mm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub d4_mm: Option<Spanned<f64>>,
    /// UR: the DH `d5`, mm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub d5_mm: Option<Spanned<f64>>,
    /// UR: the DH `d6`, mm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub d6_mm: Option<Spanned<f64>>,
    /// Six-axis: least joint angles, degrees.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub joint_min_deg: Option<Spanned<Vec<f64>>>,
    /// Six-axis: greatest joint angles, degrees.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub joint_max_deg: Option<Spanned<Vec<f64>>>,
    /// Six-axis: the seven link capsule radii (base, shoulder, upper arm, elbow, forearm, wrist,
    /// tool), mm (defaults in `paths::arm::default_link_radii_mm`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub link_radii_mm: Option<Spanned<Vec<f64>>>,
    /// Six-axis: distance kept from either end of every joint range, degrees (default 2).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub limit_margin_deg: Option<Spanned<f64>>,
    /// Six-axis: least distance of the wrist bend from its singularity, degrees (default 5).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub wrist_margin_deg: Option<Spanned<f64>>,
    /// Six-axis: largest turn of any joint between consecutive poses, degrees (default 45).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub joint_step_max_deg: Option<Spanned<f64>>,
}

/// The measured cell (`[cell.calibration]`, seed 001 §6.2.1 item 2); absent fields are nominal.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Calibration {
    /// Where the rotation axis crosses the mandrel's start height, relative to `(b, 0)`,
    /// `[x, y]` in the cell frame, mm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub axis_offset_mm: Option<Spanned<[f64; 2]>>,
    /// The rotation axis's lean from the vertical toward `+x` and toward `+y`, degrees.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub axis_tilt_deg: Option<Spanned<[f64; 2]>>,
    /// The mandrel angle at the indexer's zero, degrees (counter-clockwise from above).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub zero_angle_deg: Option<Spanned<f64>>,
    /// `1` when positive steps turn the mandrel counter-clockwise seen from above, `-1` clockwise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rotation_sign: Option<Spanned<i8>>,
}

/// Serial ports of the real cell.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Ports {
    /// The robot computer's link (`/dev/ttyS0`, `COM1`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub robot: Option<String>,
    /// The indexer's link.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub indexer: Option<String>,
    /// The port whose modem-control lines carry the sync signals.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sync: Option<String>,
}

impl Ports {
    /// True when no port is named (the simulated cell).
    pub fn is_empty(&self) -> bool {
        self.robot.is_none() && self.indexer.is_none() && self.sync.is_none()
    }
}

/// The mandrel's kind.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum MandrelKind {
    /// A straight cylinder, on the axis, offset or tilted (seed 001 §6.4 configurations 1–3).
    Cylinder,
    /// A tube swept along a measured spine (the S-bend, configuration 4).
    Tube,
    /// A triangulated mandrel (STL or OBJ file) with the spine of its sections (eq 3.7).
    Mesh,
}

/// The mandrel. Which fields apply depends on `kind`; [`Job::parse`] checks them.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Mandrel {
    /// `cylinder` or `tube`.
    pub kind: Spanned<MandrelKind>,
    /// Diameter, mm.
    pub diameter_mm: Spanned<f64>,
    /// Cylinder: length along its axis, mm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub length_mm: Option<Spanned<f64>>,
    /// Cylinder: axis offset from the rotation axis at the bottom, mm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bottom_offset_mm: Option<Spanned<f64>>,
    /// Cylinder: axis offset at the top, mm (differs from the bottom for a tilted mandrel).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub top_offset_mm: Option<Spanned<f64>>,
    /// Tube: spine knots `[[height_mm, offset_mm], …]` (Table 6.1 for the S-bend).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spine_mm: Option<Spanned<Vec<[f64; 2]>>>,
    /// Tube: how far the smoothed spine may depart from the knots, mm (0 interpolates).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spine_smoothing_mm: Option<Spanned<f64>>,
    /// Tube or mesh: the spine profile as a DXF drawing instead of `spine_mm` (its path read as
    /// (height, offset) = (x, y), mm; seed 001 §5.6), relative to the job file's folder.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spine_dxf: Option<Spanned<String>>,
    /// The DXF layer holding the spine profile (default: any).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spine_layer: Option<Spanned<String>>,
    /// Tube: where its paths end (default `horizontal`: the planes through the spine's end
    /// points, as a mandrel made along a measured spine is cut; `square`: the end sections
    /// perpendicular to the spine).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ends: Option<Spanned<Ends>>,
    /// Mesh: the STL or OBJ file, relative to the job file's folder.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mesh: Option<Spanned<String>>,
    /// Mesh: vertex welding tolerance, mm (default 1e-4).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub weld_mm: Option<Spanned<f64>>,
}

/// How a tube mandrel's ends are cut.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Ends {
    /// Horizontal planes through the spine's end points (the S-bend: 0–350 mm).
    Horizontal,
    /// Sections perpendicular to the spine at its end points.
    Square,
}

/// Winding direction.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Direction {
    /// From the top down.
    Down,
    /// From the bottom up.
    Up,
}

/// One fibre path.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PathSpec {
    /// Program number 1–255; also the file suffix `NAME_<prog>`.
    pub program: Spanned<u8>,
    /// `down` or `up` (a traced path; not with `dxf`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub direction: Option<Spanned<Direction>>,
    /// Angle between fibre and spine, degrees, in (0, 90) (a traced path; not with `dxf`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub wind_angle_deg: Option<Spanned<f64>>,
    /// Angle around the spine at the start, degrees (0 = toward the spine's offset side; a traced
    /// path; not with `dxf`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub start_angle_deg: Option<Spanned<f64>>,
    /// An imported path instead of a traced one: a DXF drawing (POINT, LINE, POLYLINE or
    /// LWPOLYLINE, mandrel frame, mm; seed 001 §5.5), relative to the job file's folder.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dxf: Option<Spanned<String>>,
    /// The DXF layer holding the path (default: any layer).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub layer: Option<Spanned<String>>,
    /// Number of equal-length segments (50 in the thesis), [`MIN_SEGMENTS`] to [`MAX_SEGMENTS`].
    pub segments: Spanned<u32>,
    /// An imported path: the farthest any of its DXF points may lie from the mandrel surface,
    /// mm (default [`DEFAULT_SURFACE_TOLERANCE_MM`]; only with `dxf`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub surface_tolerance_mm: Option<Spanned<f64>>,
}

/// The fewest segments a path may have. One segment would be a single straight move of the eye
/// from the path's start to its end: no point of the path between its ends would be placed, so
/// nothing of its shape would be wound. Two is the least that puts a path point between the ends.
pub const MIN_SEGMENTS: u32 = 2;

/// Default of `surface_tolerance_mm`: how far an imported path point may lie from the mandrel
/// surface, mm.
pub const DEFAULT_SURFACE_TOLERANCE_MM: f64 = 0.5;

/// Longest job name, characters (it names the control files: `NAME_255.ROB` must stay a short
/// file name).
pub const MAX_NAME_CHARS: usize = 64;
/// Most segments of one path (the same limit as `paths::limits::MAX_SEGMENTS`). The robot control
/// file numbers the approach and one instruction per segment with the robot's 16-bit instruction
/// numbers (seed 001 §5.6.1), which this keeps far inside; stored programs (fine, medium) are
/// held to the robot's memory as well when the job is planned (470 positioning instructions,
/// §4.1.2).
pub const MAX_SEGMENTS: u32 = 10_000;
/// Largest length in a job (every `_mm` value), mm: 100 m, far beyond any winding cell.
pub const MAX_LENGTH_MM: f64 = 100_000.0;
/// Most spine knots (the same limit as `paths::limits::MAX_SPINE_KNOTS`; Table 6.1 has 36).
pub const MAX_SPINE_KNOTS: usize = 1_000;
/// Largest other magnitude in a job (speeds, accelerations, angles).
pub const MAX_MAGNITUDE: f64 = 1e6;

/// Where `span` starts, as a located error.
pub fn error_at(text: &str, span: Range<usize>, message: impl Into<String>) -> Error {
    Error::at_offset(text, span.start, message)
}

/// Checks `value` against `ok`, that it is finite, and its magnitude against [`MAX_LENGTH_MM`]
/// when its key names a length (ends in `_mm`, see [`key_of`]) or [`MAX_MAGNITUDE`] otherwise.
fn check(text: &str, value: &Spanned<f64>, ok: bool, what: &str) -> Result<(), Error> {
    let v = *value.get_ref();
    if !(ok && v.is_finite()) {
        return Err(error_at(
            text,
            value.span(),
            format!("{} {what}", crate::error::shown(v)),
        ));
    }
    let key = key_of(text, value);
    let (limit, unit) = if key.ends_with("_mm") {
        (MAX_LENGTH_MM, " mm")
    } else {
        (MAX_MAGNITUDE, "")
    };
    if v.abs() > limit {
        return Err(error_at(
            text,
            value.span(),
            format!(
                "{key} = {} is larger than the limit of {}{unit} (docs/ARCHITECTURE.md, \"Limits\")",
                crate::error::shown(v),
                crate::error::shown(limit)
            ),
        ));
    }
    Ok(())
}

/// The key in front of `value` on its line of `text` (`diameter_mm`); a key ending in `_mm` is a
/// length.
fn key_of<'t>(text: &'t str, value: &Spanned<f64>) -> &'t str {
    let before = text.get(..value.span().start).unwrap_or_default();
    let line = before.rsplit('\n').next().unwrap_or_default();
    line.split('=').next().unwrap_or_default().trim()
}

fn positive(text: &str, value: &Spanned<f64>, name: &str) -> Result<(), Error> {
    check(
        text,
        value,
        *value.get_ref() > 0.0,
        &format!("is not a valid {name}: must be > 0"),
    )
}

fn finite(text: &str, value: &Spanned<f64>, name: &str) -> Result<(), Error> {
    check(
        text,
        value,
        true,
        &format!("is not a valid {name}: must be finite"),
    )
}

impl Job {
    /// Parses and checks the text of a job file.
    pub fn parse(text: &str) -> Result<Job, Error> {
        let job: Job = toml::from_str(text).map_err(|e| {
            let (offset, message) = crate::error::toml_refusal(&e);
            let hint = other_kind_of_file(&message, text);
            Error::at_offset(text, offset, format!("{message}{hint}"))
        })?;
        job.validate(text)?;
        Ok(job)
    }

    /// Reads and parses a job file; errors name the file.
    pub fn load(path: &Path) -> Result<(Job, String), Error> {
        let text = crate::source::read_text(path, crate::source::MAX_JOB_BYTES)?;
        let job = Job::parse(&text).map_err(|e| e.in_file(path))?;
        Ok((job, text))
    }

    /// Writes the job as TOML (parsing it again gives the same job). Refuses
    /// ([`Error::Unwritable`]) a job that [`Job::parse`] would refuse: a field out of range, a
    /// mandrel field of another kind, no path, program 0, a program used twice, …
    pub fn write(&self) -> Result<String, Error> {
        let text = toml::to_string(self).map_err(|e| Error::Unwritable {
            format: "job file",
            line: 1,
            column: 1,
            message: e.to_string().trim().to_string(),
        })?;
        crate::error::written("job file", self, text, Job::parse)
    }

    /// Checks every value the types do not: the name, the cell, the mandrel, the paths, in that
    /// order (the first refusal is the one reported).
    fn validate(&self, text: &str) -> Result<(), Error> {
        if self.name.get_ref().chars().count() > MAX_NAME_CHARS {
            return Err(error_at(
                text,
                self.name.span(),
                format!(
                    "name has {} characters, more than the limit of {MAX_NAME_CHARS} (it names the control files)",
                    self.name.get_ref().chars().count()
                ),
            ));
        }
        if !crate::sequence::is_valid_name(self.name.get_ref()) {
            return Err(error_at(
                text,
                self.name.span(),
                "name must be letters, digits, `_` or `-` (it names the control files)",
            ));
        }
        validate_cell(text, &self.cell)?;
        self.validate_mandrel(text)?;
        self.validate_paths(text)
    }

    /// Every `[[path]]`: a program number once each, the fields of its kind (set or imported),
    /// its segments and surface tolerance.
    fn validate_paths(&self, text: &str) -> Result<(), Error> {
        if self.paths.is_empty() {
            return Err(Error::at_offset(
                text,
                text.len(),
                "the job has no [[path]]",
            ));
        }
        let mut programs = Vec::new();
        for p in &self.paths {
            if *p.program.get_ref() == 0 {
                return Err(error_at(
                    text,
                    p.program.span(),
                    "program numbers run from 1 to 255",
                ));
            }
            if programs.contains(p.program.get_ref()) {
                return Err(error_at(
                    text,
                    p.program.span(),
                    format!("program {} is used twice", p.program.get_ref()),
                ));
            }
            programs.push(*p.program.get_ref());
            validate_path_source(text, p)?;
            let segments = *p.segments.get_ref();
            if !(MIN_SEGMENTS..=MAX_SEGMENTS).contains(&segments) {
                return Err(error_at(
                    text,
                    p.segments.span(),
                    format!(
                        "segments = {segments} is out of range: a path has {MIN_SEGMENTS} to \
                         {MAX_SEGMENTS} segments (one segment places no point between the \
                         path's ends; docs/ARCHITECTURE.md, \"Limits\")"
                    ),
                ));
            }
            if let Some(tolerance) = &p.surface_tolerance_mm {
                if p.dxf.is_none() {
                    return Err(error_at(
                        text,
                        tolerance.span(),
                        "`surface_tolerance_mm` applies only to a path imported from `dxf`",
                    ));
                }
                positive(text, tolerance, "surface tolerance")?;
            }
        }
        Ok(())
    }

    fn validate_mandrel(&self, text: &str) -> Result<(), Error> {
        let m = &self.mandrel;
        positive(text, &m.diameter_mm, "diameter")?;
        let kind_span = m.kind.span();
        let require = |field: bool, name: &str| {
            if field {
                Ok(())
            } else {
                Err(error_at(
                    text,
                    kind_span.clone(),
                    format!("missing field `{name}` for this mandrel kind"),
                ))
            }
        };
        let forbid = |span: Option<Range<usize>>, name: &str| match span {
            Some(span) => Err(error_at(
                text,
                span,
                format!("`{name}` does not apply to this mandrel kind"),
            )),
            None => Ok(()),
        };
        if *m.kind.get_ref() != MandrelKind::Tube {
            forbid(m.ends.as_ref().map(Spanned::span), "ends")?;
        }
        if *m.kind.get_ref() != MandrelKind::Mesh {
            forbid(m.mesh.as_ref().map(Spanned::span), "mesh")?;
            forbid(m.weld_mm.as_ref().map(Spanned::span), "weld_mm")?;
        }
        match m.kind.get_ref() {
            MandrelKind::Cylinder => {
                require(m.length_mm.is_some(), "length_mm")?;
                forbid(m.spine_dxf.as_ref().map(Spanned::span), "spine_dxf")?;
                forbid(m.spine_layer.as_ref().map(Spanned::span), "spine_layer")?;
                forbid(m.spine_mm.as_ref().map(Spanned::span), "spine_mm")?;
                forbid(
                    m.spine_smoothing_mm.as_ref().map(Spanned::span),
                    "spine_smoothing_mm",
                )?;
                if let Some(length) = &m.length_mm {
                    positive(text, length, "length")?;
                }
                for offset in [&m.bottom_offset_mm, &m.top_offset_mm]
                    .into_iter()
                    .flatten()
                {
                    finite(text, offset, "offset")?;
                }
            }
            MandrelKind::Tube | MandrelKind::Mesh => {
                require(m.spine_mm.is_some() || m.spine_dxf.is_some(), "spine_mm")?;
                if let (Some(_), Some(dxf)) = (&m.spine_mm, &m.spine_dxf) {
                    return Err(error_at(
                        text,
                        dxf.span(),
                        "give the spine as `spine_mm` or `spine_dxf`, not both",
                    ));
                }
                if m.spine_dxf.is_none() {
                    forbid(m.spine_layer.as_ref().map(Spanned::span), "spine_layer")?;
                }
                if *m.kind.get_ref() == MandrelKind::Mesh {
                    require(m.mesh.is_some(), "mesh")?;
                    if let Some(w) = &m.weld_mm {
                        positive(text, w, "weld tolerance")?;
                    }
                }
                forbid(m.length_mm.as_ref().map(Spanned::span), "length_mm")?;
                forbid(
                    m.bottom_offset_mm.as_ref().map(Spanned::span),
                    "bottom_offset_mm",
                )?;
                forbid(m.top_offset_mm.as_ref().map(Spanned::span), "top_offset_mm")?;
                if let Some(spine) = &m.spine_mm {
                    let knots = spine.get_ref();
                    if knots.len() < 2 {
                        return Err(error_at(
                            text,
                            spine.span(),
                            "spine_mm needs at least 2 knots",
                        ));
                    }
                    if knots.len() > MAX_SPINE_KNOTS {
                        return Err(error_at(
                            text,
                            spine.span(),
                            format!(
                                "spine_mm has {} knots, more than the limit of {MAX_SPINE_KNOTS} (docs/ARCHITECTURE.md, \"Limits\")",
                                knots.len()
                            ),
                        ));
                    }
                    for (i, k) in knots.iter().enumerate() {
                        if !k[0].is_finite()
                            || !k[1].is_finite()
                            || k[0].abs() > MAX_LENGTH_MM
                            || k[1].abs() > MAX_LENGTH_MM
                            || (i > 0 && k[0] <= knots[i - 1][0])
                        {
                            return Err(error_at(
                                text,
                                spine.span(),
                                format!(
                                    "spine_mm knot {} must be finite, within ±100000 mm and higher than the one before",
                                    i + 1
                                ),
                            ));
                        }
                    }
                }
                if let Some(s) = &m.spine_smoothing_mm {
                    check(
                        text,
                        s,
                        *s.get_ref() >= 0.0,
                        "is not a valid spine smoothing: must be ≥ 0",
                    )?;
                }
            }
        }
        Ok(())
    }
}

/// `[cell]`: the robot's place and speeds, the drive, the eye, the arm and its placement, the
/// obstacles, the calibration.
fn validate_cell(text: &str, c: &Cell) -> Result<(), Error> {
    positive(text, &c.robot_distance_mm, "robot distance")?;
    finite(text, &c.start_height_mm, "start height")?;
    positive(text, &c.mandrel_speed_rps, "mandrel speed")?;
    check(
        text,
        &c.eye_mechanism_length_mm,
        *c.eye_mechanism_length_mm.get_ref() >= 0.0,
        "is not a valid eye mechanism length: must be ≥ 0",
    )?;
    positive(text, &c.offset_mm, "offset")?;
    positive(text, &c.base_speed_mm_s, "base speed")?;
    positive(text, &c.max_speed_mm_s, "maximum speed")?;
    if c.max_speed_mm_s.get_ref() < c.base_speed_mm_s.get_ref() {
        return Err(error_at(
            text,
            c.max_speed_mm_s.span(),
            "max_speed_mm_s is below base_speed_mm_s",
        ));
    }
    validate_drive(text, c)?;
    if let Some(eye) = &c.eye {
        if let Some(l) = &eye.length_mm {
            positive(text, l, "eye mechanism length")?;
        }
        if let Some(r) = &eye.radius_mm {
            positive(text, r, "eye radius")?;
        }
        if let Some(t) = &eye.snag_tolerance_mm {
            positive(text, t, "snag tolerance")?;
        }
        if let Some(h) = &eye.home_mm
            && !h.get_ref().iter().all(|v| v.is_finite())
        {
            return Err(error_at(text, h.span(), "home_mm must be finite"));
        }
    }
    if c.robot.is_none() {
        arm::validate_robot(text, &Robot::default(), c)?;
    }
    arm::validate_placement(text, c)?;
    validate_obstacles(text, &c.obstacles)?;
    if let Some(r) = &c.robot {
        validate_robot_section(text, r, c)?;
    }
    if let Some(k) = &c.calibration {
        validate_calibration(text, k)?;
    }
    Ok(())
}

/// `[cell.drive]`: steps, teeth, acceleration, and a start/stop speed below the mandrel speed.
fn validate_drive(text: &str, c: &Cell) -> Result<(), Error> {
    let d = &c.drive;
    if *d.steps_per_rev.get_ref() == 0 {
        return Err(error_at(
            text,
            d.steps_per_rev.span(),
            "steps_per_rev must be > 0",
        ));
    }
    if d.gear_ratio.get_ref().contains(&0) {
        return Err(error_at(
            text,
            d.gear_ratio.span(),
            "gear_ratio teeth must be > 0",
        ));
    }
    positive(text, &d.accel_rps2, "acceleration")?;
    check(
        text,
        &d.start_stop_rps,
        *d.start_stop_rps.get_ref() >= 0.0,
        "is not a valid start/stop velocity: must be ≥ 0",
    )?;
    if d.start_stop_rps.get_ref() > c.mandrel_speed_rps.get_ref() {
        return Err(error_at(
            text,
            d.start_stop_rps.span(),
            "start_stop_rps exceeds mandrel_speed_rps",
        ));
    }
    Ok(())
}

/// `[[cell.obstacle]]`: a named box, finite, its corners in order.
fn validate_obstacles(text: &str, obstacles: &[Obstacle]) -> Result<(), Error> {
    for o in obstacles {
        let (lo, hi) = (o.min_mm.get_ref(), o.max_mm.get_ref());
        if !lo.iter().chain(hi).all(|v| v.is_finite()) || (0..3).any(|k| lo[k] > hi[k]) {
            return Err(error_at(
                text,
                o.max_mm.span(),
                "max_mm must be finite and not below min_mm on any axis",
            ));
        }
        if o.name.get_ref().is_empty() {
            return Err(error_at(text, o.name.span(), "an obstacle needs a name"));
        }
    }
    Ok(())
}

/// `[cell.robot]`: lengths, joint ranges and speeds, the model's keys, the entry angle limit.
fn validate_robot_section(text: &str, r: &Robot, c: &Cell) -> Result<(), Error> {
    for length in [
        &r.shoulder_height_mm,
        &r.upper_arm_mm,
        &r.forearm_mm,
        &r.eye_mechanism_max_mm,
    ]
    .into_iter()
    .flatten()
    {
        positive(text, length, "length")?;
    }
    for range in [
        &r.base_yaw_deg,
        &r.shoulder_deg,
        &r.elbow_deg,
        &r.pitch_deg,
        &r.roll_deg,
    ]
    .into_iter()
    .flatten()
    {
        let [lo, hi] = *range.get_ref();
        if !(lo.is_finite() && hi.is_finite() && lo < hi && lo >= -360.0 && hi <= 360.0) {
            return Err(error_at(
                text,
                range.span(),
                "a joint range is [least, greatest] degrees, finite, least below \
                 greatest, within ±360°",
            ));
        }
    }
    if let Some(speeds) = &r.joint_speed_deg_s
        && !speeds.get_ref().iter().all(|v| v.is_finite() && *v > 0.0)
    {
        return Err(error_at(
            text,
            speeds.span(),
            "joint speeds must be finite and > 0 degrees/s",
        ));
    }
    arm::validate_robot(text, r, c)?;
    if let Some(a) = &r.entry_angle_max_deg {
        check(
            text,
            a,
            *a.get_ref() > 0.0 && *a.get_ref() <= 90.0,
            "is not a valid entry angle limit: must lie in (0°, 90°]",
        )?;
    }
    Ok(())
}

/// `[cell.calibration]`: finite offsets and tilt, a tilt within ±10°, a rotation sign of ±1.
fn validate_calibration(text: &str, k: &Calibration) -> Result<(), Error> {
    for pair in [&k.axis_offset_mm, &k.axis_tilt_deg].into_iter().flatten() {
        if !pair.get_ref().iter().all(|v| v.is_finite()) {
            return Err(error_at(text, pair.span(), "values must be finite"));
        }
    }
    if let Some(tilt) = &k.axis_tilt_deg
        && !tilt.get_ref().iter().all(|v| v.abs() < 10.0)
    {
        return Err(error_at(
            text,
            tilt.span(),
            "axis tilt must lie within ±10° (a measured misalignment)",
        ));
    }
    if let Some(zero) = &k.zero_angle_deg {
        finite(text, zero, "zero angle")?;
    }
    if let Some(sign) = &k.rotation_sign
        && !matches!(sign.get_ref(), 1 | -1)
    {
        return Err(error_at(text, sign.span(), "rotation_sign must be 1 or -1"));
    }
    Ok(())
}

/// A path's source: the fields an imported (`dxf`) path must not have and a file name, or the
/// fields a set path needs (direction, wind and start angle) and no `layer`.
fn validate_path_source(text: &str, p: &PathSpec) -> Result<(), Error> {
    if let Some(dxf) = &p.dxf {
        for (span, name) in [
            (p.direction.as_ref().map(Spanned::span), "direction"),
            (
                p.wind_angle_deg.as_ref().map(Spanned::span),
                "wind_angle_deg",
            ),
            (
                p.start_angle_deg.as_ref().map(Spanned::span),
                "start_angle_deg",
            ),
        ] {
            if let Some(span) = span {
                return Err(error_at(
                    text,
                    span,
                    format!("`{name}` does not apply to a path imported from `dxf`"),
                ));
            }
        }
        if dxf.get_ref().is_empty() {
            return Err(error_at(text, dxf.span(), "dxf must name a file"));
        }
    } else {
        let missing = |name: &str| {
            error_at(
                text,
                p.program.span(),
                format!("missing field `{name}` (or `dxf` for an imported path)"),
            )
        };
        if p.direction.is_none() {
            return Err(missing("direction"));
        }
        let wind = p
            .wind_angle_deg
            .as_ref()
            .ok_or_else(|| missing("wind_angle_deg"))?;
        let start = p
            .start_angle_deg
            .as_ref()
            .ok_or_else(|| missing("start_angle_deg"))?;
        let angle = *wind.get_ref();
        check(
            text,
            wind,
            angle > 0.0 && angle < 90.0,
            "is not a valid wind angle: must lie in (0°, 90°)",
        )?;
        finite(text, start, "start angle")?;
        if let Some(layer) = &p.layer {
            return Err(error_at(
                text,
                layer.span(),
                "`layer` applies only to a path imported from `dxf`",
            ));
        }
    }
    Ok(())
}

/// When the job refuses a top-level table that belongs to another of windcell's files, what
/// that file is and where it goes: a cell file (docs/file-formats.md, "Cell file") is given with
/// `--cell`, a vessel job (docs/lathe.md) is the lathe winder's. Empty otherwise.
fn other_kind_of_file(message: &str, text: &str) -> &'static str {
    let Some(key) = message
        .strip_prefix("unknown field `")
        .and_then(|rest| rest.split('`').next())
    else {
        return "";
    };
    let header = |l: &str| {
        let l = l.split('#').next().unwrap_or_default().trim();
        l == format!("[{key}]") || l == format!("[[{key}]]")
    };
    if !text.lines().any(header) {
        return "";
    }
    match key {
        "drive" | "ports" | "tolerance" => " (this looks like a cell file: give it with --cell)",
        "layer" | "tow" | "machine" => {
            " (this looks like a lathe winder's vessel job: `windcell lathe plan` takes it)"
        }
        _ => "",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The cylinder job of the examples with its first path only, without comments (the line
    /// and column figures of the tests count on its layout).
    pub(crate) const CYLINDER: &str = include_str!("../tests/data/cylinder-one-path.toml");

    #[test]
    fn robot_and_calibration_tables_parse_and_round_trip() {
        let text = CYLINDER.replacen(
            "[mandrel]",
            "[cell.robot]\nshoulder_height_mm = 320.0\nelbow_deg = [-50.0, 20.0]\n\
             joint_speed_deg_s = [100.0, 50.0, 60.0, 180.0, 200.0]\nentry_angle_max_deg = 25.0\n\n\
             [cell.calibration]\naxis_offset_mm = [0.5, -0.2]\naxis_tilt_deg = [0.03, 0.05]\n\
             zero_angle_deg = 12.5\nrotation_sign = -1\n\n[mandrel]",
            1,
        );
        let job = Job::parse(&text).unwrap();
        let r = job.cell.robot.as_ref().unwrap();
        assert_eq!(*r.shoulder_height_mm.as_ref().unwrap().get_ref(), 320.0);
        assert_eq!(*r.elbow_deg.as_ref().unwrap().get_ref(), [-50.0, 20.0]);
        assert!(r.forearm_mm.is_none());
        let k = job.cell.calibration.as_ref().unwrap();
        assert_eq!(*k.rotation_sign.as_ref().unwrap().get_ref(), -1);
        assert_eq!(Job::parse(&job.write().unwrap()).unwrap(), job);
    }

    #[test]
    fn parses_and_round_trips() {
        let job = Job::parse(CYLINDER).unwrap();
        assert_eq!(job.name.get_ref(), "CYL");
        assert_eq!(*job.cell.movement.get_ref(), Movement::Fine);
        assert_eq!(
            *job.paths[0].direction.as_ref().unwrap().get_ref(),
            Direction::Down
        );
        let again = Job::parse(&job.write().unwrap()).unwrap();
        assert_eq!(again, job);
        assert_eq!(
            Job::parse(&again.write().unwrap())
                .unwrap()
                .write()
                .unwrap(),
            job.write().unwrap()
        );
    }

    fn error_for(from: &str, to: &str) -> String {
        let text = CYLINDER.replacen(from, to, 1);
        assert_ne!(text, CYLINDER, "{from} not found");
        Job::parse(&text).unwrap_err().to_string()
    }

    #[test]
    fn bad_values_are_located() {
        let cases = [
            ("diameter_mm = 63.5", "diameter_mm = -63.5", "21:15:"),
            ("wind_angle_deg = 48.3", "wind_angle_deg = 90.0", "27:18:"),
            ("offset_mm = 100.0", "offset_mm = 0.0", "8:13:"),
            ("segments = 50", "segments = 0", "29:12:"),
            (
                "segments = 50",
                "segments = 1",
                "29:12: segments = 1 is out of range",
            ),
            (
                "segments = 50",
                "segments = 70000",
                "29:12: segments = 70000 is out",
            ),
            (
                "segments = 50",
                "segments = 50\nsurface_tolerance_mm = 1.0",
                "30:24: `surface_tolerance_mm` applies only",
            ),
            (
                "robot_distance_mm = 800.0",
                "robot_distance_mm = \"far\"",
                "4:21:",
            ),
            ("movement = \"fine\"", "movement = \"coarse\"", "11:12:"),
            (
                "length_mm = 178.0",
                "length_mm = 178.0\ncolour = 1",
                "23:1:",
            ),
            ("offset_mm = 100.0\n", "", "missing field `offset_mm`"),
            (
                "length_mm = 178.0",
                "spine_mm = [[0.0, 0.0], [1.0, 0.0]]",
                "missing field `length_mm`",
            ),
            ("gear_ratio = [13, 60]", "gear_ratio = [0, 60]", "15:14:"),
            (
                "[mandrel]",
                "[cell.robot]\nelbow_deg = [30.0, -60.0]\n\n[mandrel]",
                "20:13:",
            ),
            (
                "[mandrel]",
                "[cell.calibration]\nrotation_sign = 2\n\n[mandrel]",
                "20:17:",
            ),
            (
                "[mandrel]",
                "[cell.robot]\nentry_angle_max_deg = 95.0\n\n[mandrel]",
                "20:23:",
            ),
        ];
        for (from, to, expected) in cases {
            let err = error_for(from, to);
            assert!(err.contains(expected), "{err} should contain {expected}");
        }
    }

    /// A cell file or a vessel job given where a robot job goes is named as what it is; a key
    /// of the same name inside one of the job's own tables is not.
    #[test]
    fn another_kind_of_file_is_named() {
        let cell = "name = \"cell\"\n\n[drive]\nsteps_per_rev = 400\n";
        let e = Job::parse(cell).unwrap_err().to_string();
        assert!(e.starts_with("3:2: unknown field `drive`"), "{e}");
        assert!(
            e.ends_with("(this looks like a cell file: give it with --cell)"),
            "{e}"
        );
        let vessel = "name = \"V\"\n[[layer]]  # hoop\nangle_deg = 89\n";
        let e = Job::parse(vessel).unwrap_err().to_string();
        assert!(e.contains("unknown field `layer`"), "{e}");
        assert!(e.ends_with("`windcell lathe plan` takes it)"), "{e}");
        // `drive` as a key of [mandrel] is a plain unknown field.
        let nested = CYLINDER.replace("[mandrel]", "[mandrel]\ndrive = 1");
        let e = Job::parse(&nested).unwrap_err().to_string();
        assert!(e.contains("unknown field `drive`"), "{e}");
        assert!(!e.contains("looks like"), "{e}");
    }
}
