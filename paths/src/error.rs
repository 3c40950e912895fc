//! The one error type of the `paths` crate.

use thiserror::Error;

use crate::arm::SixAxisFault;
use crate::limits::{fixed, shown};
use crate::robot::ArmFault;

/// Everything that can go wrong while building mandrel models and planning paths.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum Error {
    /// A length, radius, count or angle that must lie in a range does not.
    #[error("{name} = {} is out of range: {expected}", shown(*value))]
    OutOfRange {
        /// The quantity's name, with its unit (`radius_mm`, `wind_angle_deg`).
        name: &'static str,
        /// The offending value.
        value: f64,
        /// What would have been accepted, in words (`must be > 0`).
        expected: &'static str,
    },
    /// A quantity that sizes an allocation or a loop is above its limit ([`crate::limits`]).
    #[error(
        "{name} = {} exceeds the limit of {} (docs/ARCHITECTURE.md, \"Limits\")",
        shown(*value),
        shown(*limit)
    )]
    OverLimit {
        /// The quantity's name, with its unit.
        name: &'static str,
        /// The value asked for.
        value: f64,
        /// The largest accepted value.
        limit: f64,
    },
    /// Spine knots must be at strictly increasing heights, at least two of them.
    #[error("spine knot {index} at height {} mm does not rise above the previous one", shown(*height_mm))]
    SpineNotIncreasing {
        /// Index of the offending knot.
        index: usize,
        /// Its height.
        height_mm: f64,
    },
    /// The spine bends more tightly than the mandrel radius, so the tube would fold onto itself.
    #[error(
        "the spine bends with a radius of {bend_radius_mm:.1} mm at {height_mm:.1} mm, tighter than \
         the mandrel radius {} mm (smooth the spine more)",
        shown(*radius_mm)
    )]
    SpineTooTight {
        /// Height of the tightest bend.
        height_mm: f64,
        /// Its radius of curvature.
        bend_radius_mm: f64,
        /// The mandrel radius.
        radius_mm: f64,
    },
    /// Eq 3.7 has no solution: the robot is too close for the tangent line to reach the point.
    #[error(
        "robot distance b = {} mm makes eq 3.7 undefined at segment {segment} \
         (|(-r - R cos Ψ)/b| = {} > 1)",
        shown(*robot_distance_mm),
        fixed(*argument, 4)
    )]
    TangentUndefined {
        /// b, the robot pedestal to rotation axis distance.
        robot_distance_mm: f64,
        /// The segment end point index (0 = start point).
        segment: usize,
        /// |argument of arccos| found.
        argument: f64,
    },
    /// A geodesic left the surface's parameter range before reaching the mandrel's far end.
    #[error(
        "the fibre path turned back at {height_mm:.2} mm before reaching the end of the mandrel"
    )]
    PathTurnedBack {
        /// Where along the spine it turned.
        height_mm: f64,
    },
    /// A segment turns the mandrel more than half a revolution: its end angles cannot say which
    /// way the mandrel went, and the robot's straight move cannot follow the fibre.
    #[error(
        "segment {segment} turns the mandrel {turn_deg:.1}°, more than half a revolution \
         (use more segments or a smaller wind angle)"
    )]
    SegmentTurnsTooFar {
        /// The segment index (1-based).
        segment: usize,
        /// The segment's ideal mandrel turn.
        turn_deg: f64,
    },
    /// The tow line enters the eye at a larger angle to its roll axis than the eye accepts.
    #[error(
        "segment {segment}: the fibre enters the eye at {angle_deg:.2}° to its roll axis, more than \
         the {limit_deg:.2}° limit (entry_angle_max_deg)"
    )]
    EntryAngle {
        /// The segment end point index (0 = start point).
        segment: usize,
        /// The entry angle.
        angle_deg: f64,
        /// The limit.
        limit_deg: f64,
    },
    /// The payout eye would lie inside (or on) the mandrel.
    #[error("segment {segment}: the payout eye is {clearance_mm:.3} mm inside the mandrel surface", clearance_mm = -clearance_mm)]
    EyeInsideMandrel {
        /// The segment end point index (0 = start point).
        segment: usize,
        /// The eye's distance to the surface (≤ 0).
        clearance_mm: f64,
    },
    /// In fine or medium movement the robot cannot cover a segment in the mandrel's time.
    #[error(
        "segment {segment}: the eye would have to move at {speed_mm_s:.0} mm/s; the robot needs \
         {robot_time_s:.4} s at its fastest for this pose but the mandrel takes {duration_s:.4} s \
         (a mandrel speed of at most {mandrel_rps_fit:.4} rev/s would fit)"
    )]
    RobotTooSlow {
        /// The segment index (1-based).
        segment: usize,
        /// The eye speed the mandrel's time asks for.
        speed_mm_s: f64,
        /// The robot's least time for the segment.
        robot_time_s: f64,
        /// The mandrel's time for the segment.
        duration_s: f64,
        /// The mandrel speed that scales this segment's time up to the robot's.
        mandrel_rps_fit: f64,
    },
    /// In continuous movement a segment is shorter than the robot's time per instruction, so
    /// the eye would fall behind the mandrel (docs/continuous.md).
    #[error(
        "segment {segment}: the mandrel takes {duration_s:.4} s but the robot needs \
         {instruction_s:.4} s per instruction in continuous movement (at most \
         {max_segments} segments, or a mandrel speed of at most {mandrel_rps_fit:.4} rev/s)"
    )]
    SegmentTooShort {
        /// The segment index (1-based).
        segment: usize,
        /// The mandrel's time for the segment.
        duration_s: f64,
        /// The robot's least time per instruction.
        instruction_s: f64,
        /// The most segments the path can be cut into with every one lasting the robot's time,
        /// the path's steps spread along it as in the present cut (0 when not even one fits).
        max_segments: usize,
        /// The fastest mandrel speed at which every segment, ramps included, lasts the robot's
        /// time (0 when none down to the start speed does).
        mandrel_rps_fit: f64,
    },
    /// The arm cannot take a pose: out of reach, off the arm plane, a joint out of range or a
    /// joint jump between consecutive poses.
    #[error("{}{fault}", segment.map(|s| format!("segment {s}: ")).unwrap_or_default())]
    Arm {
        /// The segment end point index (0 = start point), when the pose belongs to a path.
        segment: Option<usize>,
        /// What the arm cannot do.
        fault: ArmFault,
    },
    /// A six-axis arm cannot take a pose or keep one configuration along a path.
    #[error("{}{fault}", segment.map(|s| format!("segment {s}: ")).unwrap_or_default())]
    SixAxis {
        /// The pose index (0 = the path's start pose), when the pose belongs to a path.
        segment: Option<usize>,
        /// What the arm cannot do.
        fault: SixAxisFault,
    },
    /// An arm model name that windcell does not know.
    #[error("unknown {kind} model \"{model}\" (known: {known})")]
    UnknownArmModel {
        /// The arm kind (`opw`, `ur`).
        kind: &'static str,
        /// The name asked for.
        model: String,
        /// The names windcell knows, quoted, comma-separated.
        known: String,
    },
    /// Two consecutive segment end points coincide, so the fibre direction is undefined.
    #[error("segment {segment} has zero length")]
    DegenerateSegment {
        /// The segment index (1-based).
        segment: usize,
    },
    /// A spline needs more points than were given.
    #[error("{count} points given, a {what} needs at least {needed}")]
    TooFewPoints {
        /// What was being built (`cubic interpolant`, `b-spline`).
        what: &'static str,
        /// Points given.
        count: usize,
        /// Points needed.
        needed: usize,
    },
    /// A point has a NaN or infinite coordinate.
    #[error("point {index} has a coordinate that is not finite")]
    NonFinitePoint {
        /// Index of the offending point.
        index: usize,
    },
    /// Two consecutive points coincide, so chord-length parameters are not strictly increasing.
    #[error("points {} and {index} coincide", index - 1)]
    CoincidentPoints {
        /// Index of the second of the two points.
        index: usize,
    },
    /// A knot vector is not a clamped, non-decreasing vector of the right length.
    #[error("knot {index}: {reason}")]
    BadKnots {
        /// Index of the offending knot (or the knot count for a length mismatch).
        index: usize,
        /// What is wrong, in words.
        reason: &'static str,
    },
    /// A spline's linear system has a zero pivot (the points do not determine the curve).
    #[error("the {system} system is singular at row {row}")]
    SingularSystem {
        /// Which system (`interpolation`, `least-squares`).
        system: &'static str,
        /// The row where elimination met a zero pivot.
        row: usize,
    },
    /// A mesh file could not be read: the line and column (ASCII STL, OBJ) or the byte offset
    /// (binary STL) where known, and what is wrong.
    #[error(
        "{}{message}",
        match (line, column, byte) {
            (Some(l), Some(c), _) => format!("line {l}, column {c}: "),
            (Some(l), None, _) => format!("line {l}: "),
            (None, _, Some(b)) => format!("byte {b}: "),
            _ => String::new(),
        }
    )]
    MeshSyntax {
        /// 1-based line of a text format, `None` for binary STL.
        line: Option<usize>,
        /// 1-based column (in characters) on that line, where known.
        column: Option<usize>,
        /// 0-based byte offset in a binary file, where known.
        byte: Option<u64>,
        /// What is wrong, in lower case.
        message: String,
    },
    /// A mesh parsed but is not a surface the tracer can use.
    #[error("{}{reason}", triangle.map(|t| format!("triangle {t}: ")).unwrap_or_default())]
    MeshInvalid {
        /// 0-based index of the offending triangle (in file order), where one is at fault.
        triangle: Option<usize>,
        /// What is wrong, in lower case.
        reason: String,
    },
    /// A slip ratio the friction cannot hold (seed 000 §2.9: the slippage tendency must not exceed μ).
    #[error(
        "slip ratio λ = {} exceeds the friction coefficient μ = {}: the fibre would slip",
        shown(*lambda),
        shown(*mu)
    )]
    SlipExceedsFriction {
        /// The requested |λ| = |k_g / k_n|.
        lambda: f64,
        /// The friction coefficient.
        mu: f64,
    },
    /// A start point too far from the mesh surface.
    #[error(
        "start point is {distance_mm:.3} mm from the mesh surface (more than {} mm); the nearest \
         surface point is {:.3},{:.3},{:.3}",
        shown(*limit_mm),
        nearest_mm[0],
        nearest_mm[1],
        nearest_mm[2]
    )]
    OffSurface {
        /// The nearest surface point, mm (a start point that would be accepted).
        nearest_mm: [f64; 3],
        /// Distance to the nearest surface point.
        distance_mm: f64,
        /// The largest accepted distance.
        limit_mm: f64,
    },
    /// The fibre's contact with the mandrel cannot be followed (placement model).
    #[error("the fibre contact at height {height_mm:.2} mm is undefined: {reason}")]
    ContactUndefined {
        /// Height of the contact's spine point.
        height_mm: f64,
        /// Why, in words.
        reason: &'static str,
    },
    /// The fibre's contact left the mandrel past one of its ends.
    #[error("the fibre contact left the mandrel at {height_mm:.2} mm, t = {time_s:.3} s")]
    ContactOffSurface {
        /// When, s.
        time_s: f64,
        /// Height of the contact's spine point.
        height_mm: f64,
    },
    /// A helical layer's pattern does not close (seed 002 Eqs. 7–8), with the nearest choices that do.
    #[error("the winding pattern does not close: {reason}; nearest valid: {alternatives}")]
    PatternNotClosed {
        /// Why, in words, with the numbers.
        reason: String,
        /// The nearest pattern numbers, dwell and wind angle that close, in words.
        alternatives: String,
    },
    /// The delivery eye's circle does not clear the laminate (seed 002 Eq. 12 needs Re > Rc).
    #[error(
        "layer {layer}: the eye circle radius {eye_radius_mm} mm does not clear the winding \
         radius {winding_radius_mm:.3} mm"
    )]
    EyeInsideLaminate {
        /// 1-based layer number.
        layer: usize,
        /// Re.
        eye_radius_mm: f64,
        /// The winding surface's radius at this layer (mandrel plus laminate below).
        winding_radius_mm: f64,
    },
    /// A planned move needs an axis beyond its travel.
    #[error("layer {layer}: {axis} reaches {value:.3}, beyond its travel {min}..{max}")]
    BeyondTravel {
        /// 1-based layer number.
        layer: usize,
        /// The axis name (`carriage_mm`, `cross_feed_mm`, `eye_deg`).
        axis: &'static str,
        /// The value reached.
        value: f64,
        /// Travel minimum.
        min: f64,
        /// Travel maximum.
        max: f64,
    },
    /// A tube helical layer breaks a coverage rule (pattern number, skip index, lock, lead-in).
    #[error("layer {layer}: {reason}")]
    WindRule {
        /// 1-based layer number.
        layer: usize,
        /// The rule broken, with the numbers and the nearest valid values.
        reason: String,
    },
    /// A layer of a job could not be planned.
    #[error("layer {layer}: {source}")]
    Layer {
        /// 1-based layer number.
        layer: usize,
        /// Why.
        source: Box<Error>,
    },
}
