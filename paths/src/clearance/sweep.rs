//! The clearance sweep of a whole job: every segment of every path, and the moves between paths.
//!
//! # Motion between segment ends
//! Over segment `k` (from the pose at point `k − 1` to the pose at point `k`, time `τ ∈ [0, 1]`
//! of its duration) the eye moves on the straight line between its cell-frame positions (the
//! robot's rectangular interpolation), the wrist turns by spherical interpolation of its
//! quaternions, the mandrel turns linearly between its commanded angles, and the tangent point
//! moves along the chord between the two tangent points, projected onto the surface.
//!
//! # What each check finds, and what it can miss
//! - **Eye mechanism** (a capsule from the eye back along the tool axis) against the mandrel
//!   (mandrel frame) and the obstacles (cell frame), and the **arm's links** against both:
//!   continuous in time. Clearance changes at most `L` mm per unit `τ`: the eye's travel, plus
//!   the mechanism length times the wrist's turn, plus the mandrel's turn times the smaller of the
//!   part's and the mandrel's largest distance from the rotation axis ([`Solid::axis_radius_mm`]).
//!   So clearance is `L`-Lipschitz in `τ`, and [`certified_min_below`] finds every dip below zero
//!   deeper than [`super::RESOLUTION_MM`] and the job's least clearance of each part to 1 % of
//!   itself (0.001 mm near contact). A move's own least clearance is certified only where it
//!   could undercut the least found on the poses and moves before it (its ends are found
//!   exactly only then), so a row of the report may hold only a bound for its move, and the
//!   least over all rows is the certified one. The arm's links (pedestal, upper arm, forearm,
//!   wrist) hang on the first three joints: their `L` is those joints' travel times the links'
//!   distance from each joint's axis (doubled, since joints do not move linearly in `τ`).
//! - **Free fibre** (the tow line from the tangent point to the eye) against the mandrel:
//!   its clearance sits at 0 along the whole sweep (the fibre touches at its tangent point), so a
//!   Lipschitz bound would need thousands of evaluations per segment. It is **sampled**: at both
//!   segment ends and at instants no more than [`TOW_SAMPLE_MM`] of eye travel (mandrel frame)
//!   apart; each sampled tow line is checked exactly along its length. Between two samples every
//!   point of the tow line moves at most `TOW_SAMPLE_MM` (the tangent point moves less than the
//!   eye), so a snag deeper than `snag_tolerance_mm + TOW_SAMPLE_MM / 2` cannot fall between two
//!   samples unseen; a shallower one can.
//! - **Approach and link moves** (home → first point of path 1, last point of path `n` → first
//!   point of path `n + 1`): the eye and the arm, continuous as above, the mandrel turning from
//!   the previous path's last angle to the next path's start (the synchronisation of §5.6 step 8).
//!   No fibre is checked on them. They are reported as segment 0 of the path they lead into.

use nalgebra::{Matrix3, Point3, Unit, UnitQuaternion, Vector3};

use super::minimum::Minimum;
use super::{Capsule, EyeMechanism, Obstacle, RESOLUTION_MM, Solid, certified_min_below};
use crate::arm::winding::{
    joints_for_tool, lever_arms_mm, link_lever_arms_mm, tool_reach_mm, tool_to_wrist,
};
use crate::arm::{self, Config, Joints6, MandrelAxis, SixAxisArm};
use crate::plan::{ArmJoints, PathArm, PathPlan, Pose};
use crate::robot::{Arm, ElbowBranch};
use crate::{Error, Setup};

/// Largest eye travel (mandrel frame) between two sampled tow lines, mm.
pub const TOW_SAMPLE_MM: f64 = 0.5;

/// Links of the IRB 6/2 checked against the mandrel and the obstacles (the pedestal stands on
/// the floor and the eye mechanism is the eye's capsule, so they are checked against the mandrel
/// only, and not at all, respectively).
const LINK_NAMES: [&str; 5] = ["pedestal", "upper arm", "forearm", "wrist", "eye mechanism"];

/// The arm whose links are checked.
#[derive(Debug, Clone, Copy)]
pub enum SweptArm<'a> {
    /// The IRB 6/2 on one elbow branch: its joints from the eye and the tool axis.
    Irb62(&'a Arm, ElbowBranch),
    /// A six-axis arm: on a path its joints from the eye and the tool frame on the path's
    /// configuration (the plan's [`PathArm::SixAxis`]); approach and link moves are straight
    /// moves on the next path's configuration too, or joint moves (the joints interpolated
    /// linearly) where the two paths keep different configurations. Its base
    /// is checked against the mandrel only (it stands on the floor), the other links and the tool
    /// against the mandrel and the obstacles.
    SixAxis(&'a SixAxisArm),
}

/// What was checked: the cell around the paths.
#[derive(Debug, Clone, Copy)]
pub struct Cell<'a> {
    /// Robot distance and mandrel height (the mandrel frame's place in the cell frame).
    pub setup: &'a Setup,
    /// The payout-eye mechanism.
    pub eye: EyeMechanism,
    /// Depth inside the mandrel at which the free fibre snags, mm.
    pub snag_tolerance_mm: f64,
    /// Boxes in the cell frame.
    pub obstacles: &'a [Obstacle],
    /// The eye's home position (cell frame), the start of the approach to path 1; `None` skips
    /// that approach.
    pub home_mm: Option<Point3<f64>>,
    /// Speed of approach and link moves, mm/s.
    pub approach_speed_mm_s: f64,
    /// The arm; `None` checks no links.
    pub arm: Option<SweptArm<'a>>,
}

/// The part that comes too close.
#[derive(Debug, Clone, PartialEq)]
pub enum Part {
    /// The payout-eye mechanism's capsule.
    EyeMechanism,
    /// The free fibre between the tangent point and the eye.
    FreeFibre,
    /// One of the arm's links.
    Link(&'static str),
}

impl Part {
    /// The part in words.
    pub fn name(&self) -> &'static str {
        match self {
            Part::EyeMechanism => "eye mechanism",
            Part::FreeFibre => "free fibre",
            Part::Link(name) => name,
        }
    }
}

/// A collision or a snag.
#[derive(Debug, Clone, PartialEq)]
pub struct Finding {
    /// Path, from 1 in the job's order.
    pub path: usize,
    /// Segment, from 1; 0 is the approach or link move into the path.
    pub segment: usize,
    /// Time from the path's first point, s (negative on the approach).
    pub time_s: f64,
    /// Clearance there, mm (negative: inside).
    pub clearance_mm: f64,
    /// What hit.
    pub part: Part,
    /// What it hit: `mandrel` or an obstacle's name.
    pub against: String,
    /// The eye there, cell frame.
    pub eye_mm: Point3<f64>,
    /// The unit tool axis there (eye toward the tangent point), cell frame.
    pub axis: Vector3<f64>,
    /// The mandrel angle there, rad.
    pub mandrel_rad: f64,
    /// A six-axis arm's joints there, rad.
    pub joints: Option<Joints6>,
}

/// The least clearances found over one segment (or approach move). The least of each field over
/// all rows is the job's least clearance of that part, to 1 % of itself (see the module
/// documentation). A row's own value is its move's least clearance to that tolerance wherever
/// the move could undercut the job's poses and the moves of its path checked before it;
/// elsewhere it is only a bound at or above their least.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SegmentClearance {
    /// Segment, from 1; 0 is the approach or link move.
    pub segment: usize,
    /// Start time from the path's first point, s.
    pub start_s: f64,
    /// Duration, s.
    pub duration_s: f64,
    /// Eye mechanism against the mandrel and the obstacles, mm.
    pub eye_mm: f64,
    /// Free fibre against the mandrel (0 when it only touches at its tangent point; negative
    /// inside), mm; `None` on approach moves.
    pub tow_mm: Option<f64>,
    /// Arm links against the mandrel and the obstacles, mm; `None` without an arm.
    pub arm_mm: Option<f64>,
}

/// A pose within a move, for drawing the worst one.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Instant {
    /// Path from 1, segment (0 = approach), and `τ` in the segment.
    pub path: usize,
    /// Segment.
    pub segment: usize,
    /// Fraction of the segment's time.
    pub tau: f64,
    /// Eye, cell frame.
    pub eye_mm: Point3<f64>,
    /// Unit tool axis, from the eye toward the tangent point, cell frame.
    pub axis: Vector3<f64>,
    /// Mandrel angle, rad.
    pub mandrel_rad: f64,
    /// A six-axis arm's joints there, rad.
    pub joints: Option<Joints6>,
    /// The least clearance of the eye and the arm there, mm.
    pub clearance_mm: f64,
}

/// Everything the sweep found.
#[derive(Debug, Clone, PartialEq)]
pub struct Report {
    /// Per path, its approach (segment 0) and then its segments.
    pub paths: Vec<Vec<SegmentClearance>>,
    /// Every finding, in path, segment and time order (at most one per part and thing hit per
    /// segment: the first).
    pub findings: Vec<Finding>,
    /// The pose with the least eye or arm clearance.
    pub worst: Option<Instant>,
}

impl Report {
    /// True when nothing was found.
    pub fn is_clear(&self) -> bool {
        self.findings.is_empty()
    }
}

/// One end of a move: the eye, the wrist frame (its `x` the tool axis), the mandrel angle, the
/// tangent point (none on approach and link moves) and, for a six-axis arm, the joints and the
/// path's configuration.
#[derive(Debug, Clone, Copy)]
struct End {
    eye: Point3<f64>,
    q: UnitQuaternion<f64>,
    phi: f64,
    tangent: Option<Point3<f64>>,
    joints: Option<Joints6>,
    config: Option<Config>,
}

impl End {
    fn of(pose: &Pose, plan: &PathPlan) -> End {
        End {
            eye: pose.eye_mm,
            q: pose.wrist_q,
            phi: pose.mandrel_rad,
            tangent: Some(pose.tangent_point_mm),
            joints: match pose.joints {
                ArmJoints::SixAxis { joints, .. } => Some(joints),
                ArmJoints::Irb62(_) => None,
            },
            config: match plan.arm {
                PathArm::SixAxis(report) => Some(report.config),
                PathArm::Irb62(_) => None,
            },
        }
    }
}

/// The arm and the eye at one instant of a move.
#[derive(Debug, Clone, Copy)]
struct At {
    eye: Point3<f64>,
    q: UnitQuaternion<f64>,
    phi: f64,
    /// A six-axis arm's joints, when the move is a joint move (else found from the eye, the
    /// wrist frame and `config`).
    joints: Option<Joints6>,
    config: Option<Config>,
}

impl At {
    fn axis(&self) -> Vector3<f64> {
        axis_of(&self.q)
    }
}

/// The link capsules at one instant, with their names; the first is checked against the mandrel
/// only.
#[derive(Clone, Copy)]
struct Links {
    capsules: [Capsule; arm::LINKS],
    count: usize,
    names: &'static [&'static str],
}

/// The tool axis of a wrist orientation: the roll axis, the tool `x` axis of `paths::robot`
/// (from the wrist through the eye, toward the mandrel).
fn axis_of(q: &UnitQuaternion<f64>) -> Vector3<f64> {
    q * Vector3::x()
}

/// The cell and the solid, with the frame change: the mandrel frame at angle 0 has its origin at
/// `origin` and its axes the columns of `align` (base frame); the thesis cell's is the identity.
struct Context<'a> {
    cell: &'a Cell<'a>,
    solid: &'a dyn Solid,
    origin: Point3<f64>,
    align_t: Matrix3<f64>,
    direction: Vector3<f64>,
    /// A six-axis arm's lever arms ([`lever_arms_mm`]), with the eye mechanism beyond the eye.
    levers_mm: [f64; 6],
    /// A six-axis arm's lever arms per link: `[k][j]`, the links' length from joint `j`'s axis
    /// to the far end of link `k` (joints after the link: 0).
    link_levers_mm: [[f64; 6]; arm::LINKS],
    /// For the links that move with the tool frame (the wrist link on axis 6 and the tool), the
    /// farthest of their points from the eye, mm.
    tool_reach_mm: [Option<f64>; arm::LINKS],
}

impl<'a> Context<'a> {
    fn new(cell: &'a Cell<'a>, solid: &'a dyn Solid) -> Self {
        let axis = match &cell.setup.six_axis {
            Some(six) => six.axis,
            None => MandrelAxis::thesis(cell.setup.robot_distance_mm, cell.setup.mandrel_height_mm),
        };
        let frame = axis.frame(0.0);
        let levers_mm = match cell.arm {
            Some(SweptArm::SixAxis(arm)) => lever_arms_mm(arm, cell.eye.length_mm),
            _ => [0.0; 6],
        };
        let (link_levers_mm, tool_reach_mm) = match cell.arm {
            Some(SweptArm::SixAxis(arm)) => (link_lever_arms_mm(arm), tool_reach_mm(arm)),
            _ => ([[0.0; 6]; arm::LINKS], [None; arm::LINKS]),
        };
        Context {
            cell,
            solid,
            origin: axis.origin_mm,
            align_t: frame.rotation.to_rotation_matrix().into_inner().transpose(),
            direction: axis.direction.into_inner(),
            levers_mm,
            link_levers_mm,
            tool_reach_mm,
        }
    }

    fn to_mandrel(&self, p: &Point3<f64>, phi: f64) -> Point3<f64> {
        let (s, c) = phi.sin_cos();
        let w = self.align_t * (p - self.origin);
        Point3::new(c * w.x + s * w.y, -s * w.x + c * w.y, w.z)
    }

    /// Distance of a base-frame point from the rotation axis, mm.
    fn distance_to_axis_mm(&self, p: &Point3<f64>) -> f64 {
        let w = p - self.origin;
        (w - self.direction * w.dot(&self.direction)).norm()
    }

    /// Least clearance of a cell-frame capsule against the mandrel at angle `phi` and the
    /// obstacles, with what it was against; at or above `cap`, any value from `cap` up to it
    /// ([`Solid::segment_min_capped_mm`]).
    fn capsule(
        &self,
        a: &Point3<f64>,
        b: &Point3<f64>,
        radius: f64,
        phi: f64,
        obstacles: bool,
        cap: f64,
    ) -> (f64, usize) {
        let mut best = (
            self.solid.segment_min_capped_mm(
                &self.to_mandrel(a, phi),
                &self.to_mandrel(b, phi),
                cap + radius,
            ) - radius,
            0,
        );
        if obstacles {
            for (i, o) in self.cell.obstacles.iter().enumerate() {
                let d = o.distance_to_segment_mm(a, b) - radius;
                if d < best.0 {
                    best = (d, i + 1);
                }
            }
        }
        best
    }

    fn against(&self, index: usize) -> String {
        if index == 0 {
            "mandrel".to_string()
        } else {
            self.cell.obstacles[index - 1].name.clone()
        }
    }

    /// The link capsules at an instant. IRB 6/2: from the eye and the tool axis ([`irb_joints`]).
    /// Six-axis: the joints of
    /// a joint move, else those of the path's configuration that put the tool frame there.
    fn links(&self, at: &At) -> Result<Option<(Option<Joints6>, Links)>, Error> {
        match self.cell.arm {
            None => Ok(None),
            Some(SweptArm::Irb62(arm, branch)) => {
                let joints = irb_joints(arm, branch, at)?;
                let five = arm.links(&joints);
                let mut capsules = [five[0]; arm::LINKS];
                capsules[..5].copy_from_slice(&five);
                Ok(Some((
                    None,
                    Links {
                        capsules,
                        count: 4,
                        names: &LINK_NAMES,
                    },
                )))
            }
            Some(SweptArm::SixAxis(arm)) => {
                let joints = match (at.joints, at.config) {
                    (Some(q), _) => q,
                    (None, Some(config)) => {
                        let tool_q = at.q * tool_to_wrist().inverse();
                        joints_for_tool(arm, &at.eye, &tool_q, config).map_err(|fault| {
                            Error::SixAxis {
                                segment: None,
                                fault,
                            }
                        })?
                    }
                    (None, None) => {
                        return Err(Error::OutOfRange {
                            name: "configuration",
                            value: 0.0,
                            expected: "must be known for a six-axis pose",
                        });
                    }
                };
                Ok(Some((
                    Some(joints),
                    Links {
                        capsules: arm.links(&joints),
                        count: arm::LINKS,
                        names: &arm::LINK_NAMES,
                    },
                )))
            }
        }
    }

    /// Least clearance of the arm's links (the first, the base, against the mandrel only; the
    /// others against the mandrel and the obstacles), with the link's name and what it was
    /// against; at or above `cap`, any value from `cap` up to it.
    fn arm(&self, at: &At, cap: f64) -> Result<Option<(f64, &'static str, usize)>, Error> {
        let Some((_, links)) = self.links(at)? else {
            return Ok(None);
        };
        let mut best = (f64::INFINITY, links.names[0], 0);
        for (i, link) in links.capsules.iter().enumerate().take(links.count) {
            let (d, against) = self.capsule(&link.a, &link.b, link.radius_mm, at.phi, i > 0, cap);
            if d < best.0 {
                best = (d, links.names[i], against);
            }
        }
        Ok(Some(best))
    }
}

/// Checks every path of a job (`paths` in order) against `solid`, the mandrel in its own frame.
/// Errors only when the arm cannot take a pose on the way.
pub fn sweep(cell: &Cell<'_>, solid: &dyn Solid, paths: &[&PathPlan]) -> Result<Report, Error> {
    let ctx = Context::new(cell, solid);
    let mut report = Report {
        paths: Vec::with_capacity(paths.len()),
        findings: Vec::new(),
        worst: None,
    };
    // The least clearances at the poses themselves bound the job's least from above: with them
    // as ceilings from the start, a move is searched only where it could undercut them (each
    // found with the least so far as its cap, so most stop early).
    let mut least = Least {
        eye_mm: f64::INFINITY,
        arm_mm: f64::INFINITY,
    };
    for plan in paths {
        for pose in std::iter::once(&plan.start).chain(plan.segments.iter().map(|s| &s.pose)) {
            let end = End::of(pose, plan);
            let axis = axis_of(&pose.wrist_q);
            let back = pose.eye_mm - axis * cell.eye.length_mm;
            let (eye, _) = ctx.capsule(
                &pose.eye_mm,
                &back,
                cell.eye.radius_mm,
                pose.mandrel_rad,
                true,
                least.eye_mm,
            );
            least.eye_mm = least.eye_mm.min(eye);
            if let Some((arm, _, _)) = ctx.arm(&end.at_rest(), least.arm_mm)? {
                least.arm_mm = least.arm_mm.min(arm);
            }
        }
    }
    // Where each path's approach or link move starts: home before the first, then the end of the
    // path before (the plan's poses, not the check's results, so the paths are independent).
    let mut previous: Vec<Option<End>> = Vec::with_capacity(paths.len());
    let mut last: Option<End> = match (cell.home_mm, paths.first()) {
        (Some(home), first) => Some(home_end(cell, home, first)?),
        (None, _) => None,
    };
    for plan in paths {
        previous.push(last);
        last = Some(
            plan.segments
                .last()
                .map_or(End::of(&plan.start, plan), |s| End::of(&s.pose, plan)),
        );
    }
    // The paths are checked on up to as many threads as the machine has cores, each thread a
    // run of consecutive paths with the poses' least clearances as its first ceilings.
    let workers = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .clamp(1, paths.len().max(1));
    let per_worker = paths.len().div_ceil(workers).max(1);
    let run = |first: usize| -> Vec<Result<Report, Error>> {
        let mut least = least;
        (first..(first + per_worker).min(paths.len()))
            .map(|n| sweep_path(&ctx, n, paths[n], previous[n], &mut least))
            .collect()
    };
    let chunks: Vec<Vec<Result<Report, Error>>> = if workers == 1 {
        vec![run(0)]
    } else {
        std::thread::scope(|scope| {
            let handles: Vec<_> = (0..paths.len())
                .step_by(per_worker)
                .map(|first| scope.spawn(move || run(first)))
                .collect();
            handles
                .into_iter()
                .map(|h| {
                    h.join()
                        .unwrap_or_else(|panic| std::panic::resume_unwind(panic))
                })
                .collect()
        })
    };
    // Merged in path order: the first error, every path's rows and findings, and the least pose
    // (the earliest of equals).
    for one in chunks.into_iter().flatten() {
        let one = one?;
        report.paths.extend(one.paths);
        report.findings.extend(one.findings);
        if let Some(w) = one.worst
            && report
                .worst
                .is_none_or(|best| w.clearance_mm < best.clearance_mm)
        {
            report.worst = Some(w);
        }
    }
    Ok(report)
}

/// Path `n` (from 0) of a job: its approach or link move from `previous` (none: a row with no
/// move) and its segments, as a report of that path alone.
fn sweep_path(
    ctx: &Context<'_>,
    n: usize,
    plan: &PathPlan,
    previous: Option<End>,
    least: &mut Least,
) -> Result<Report, Error> {
    let cell = ctx.cell;
    let mut report = Report {
        paths: Vec::with_capacity(1),
        findings: Vec::new(),
        worst: None,
    };
    let mut rows = Vec::with_capacity(plan.segments.len() + 1);
    let start = End::of(&plan.start, plan);
    // Approach or link move: no fibre.
    match previous {
        Some(from) => {
            let mut to = start;
            to.tangent = None;
            // The mandrel turns the short way to the next start.
            let mut from = from;
            from.tangent = None;
            let turn = (to.phi - from.phi).rem_euclid(std::f64::consts::TAU);
            let turn = if turn > std::f64::consts::PI {
                turn - std::f64::consts::TAU
            } else {
                turn
            };
            from.phi = to.phi - turn;
            let duration = (to.eye - from.eye).norm() / cell.approach_speed_mm_s;
            let row = check_move(
                ctx,
                &from,
                &to,
                n + 1,
                0,
                -duration,
                duration,
                &mut report,
                least,
            )?;
            rows.push(row);
        }
        None => rows.push(SegmentClearance {
            segment: 0,
            start_s: 0.0,
            duration_s: 0.0,
            eye_mm: f64::INFINITY,
            tow_mm: None,
            arm_mm: None,
        }),
    }
    let mut from = start;
    let mut t = 0.0;
    for (k, segment) in plan.segments.iter().enumerate() {
        let to = End::of(&segment.pose, plan);
        let row = check_move(
            ctx,
            &from,
            &to,
            n + 1,
            k + 1,
            t,
            segment.duration_s,
            &mut report,
            least,
        )?;
        rows.push(row);
        t += segment.duration_s;
        from = to;
    }
    report.paths.push(rows);
    Ok(report)
}

/// Where the approach to path 1 starts: the eye at `home`, the wrist as at path 1's start; a
/// six-axis arm there on path 1's configuration (an error when it cannot take that pose).
fn home_end(cell: &Cell<'_>, home: Point3<f64>, first: Option<&&PathPlan>) -> Result<End, Error> {
    let mut end = End {
        eye: home,
        q: first.map_or(UnitQuaternion::identity(), |p| p.start.wrist_q),
        phi: first.map_or(0.0, |p| p.start.mandrel_rad),
        tangent: None,
        joints: None,
        config: None,
    };
    if let (Some(SweptArm::SixAxis(arm)), Some(plan)) = (cell.arm, first) {
        let start = End::of(&plan.start, plan);
        if let Some(config) = start.config {
            let tool_q = end.q * tool_to_wrist().inverse();
            end.joints = Some(
                joints_for_tool(arm, &home, &tool_q, config).map_err(|fault| Error::SixAxis {
                    segment: Some(0),
                    fault,
                })?,
            );
            end.config = Some(config);
        }
    }
    Ok(end)
}

impl End {
    /// The arm and the eye standing at this end.
    fn at_rest(&self) -> At {
        At {
            eye: self.eye,
            q: self.q,
            phi: self.phi,
            joints: self.joints,
            config: self.config,
        }
    }
}

/// How many intervals a move's free fibre is sampled at so that the eye travels at most
/// [`TOW_SAMPLE_MM`] in the mandrel frame between two samples. With the eye at `o + w(τ)` (cell
/// frame, `o` on the rotation axis) moving on a straight line and the mandrel turning linearly
/// by `Δφ`, the eye seen from the mandrel, `R_z(−φ) w`, moves at `|Δw − Δφ ẑ × w(τ)|` per unit
/// `τ`: the norm of a function affine in `τ`, so convex, and greatest at one of the move's ends.
fn tow_sample_count(ctx: &Context<'_>, from: &End, to: &End) -> usize {
    let travel = to.eye - from.eye;
    let d_phi = to.phi - from.phi;
    let speed = |eye: &Point3<f64>| {
        let w = eye - ctx.origin;
        (travel - ctx.direction.cross(&w) * d_phi).norm()
    };
    let swept = speed(&from.eye).max(speed(&to.eye));
    (swept / TOW_SAMPLE_MM).ceil().max(1.0) as usize
}

/// The eye capsule's Lipschitz bound over a move, mm per unit `τ`: the eye's travel, plus the
/// mechanism's length times the wrist's turn, plus the mandrel's turn times the smaller of the
/// capsule's and the mandrel's largest distance from the rotation axis.
fn eye_lipschitz(ctx: &Context<'_>, from: &End, to: &End) -> f64 {
    if let Some((a, b)) = joint_move(ctx, from, to) {
        // A point of the eye capsule is within the lever arm (eye mechanism included) of each
        // joint's axis.
        return joint_travel_lipschitz(ctx, &a, &b)
            + (to.phi - from.phi).abs() * ctx.solid.axis_radius_mm();
    }
    let eye_len = ctx.cell.eye.length_mm;
    let horizontal = |p: &Point3<f64>| ctx.distance_to_axis_mm(p);
    let d_phi = (to.phi - from.phi).abs();
    let turn = from.q.angle_to(&to.q);
    let travel = (to.eye - from.eye).norm();
    let reach = horizontal(&from.eye).max(horizontal(&to.eye)) + eye_len;
    travel + eye_len * turn + d_phi * reach.min(ctx.solid.axis_radius_mm())
}

/// The IRB 6/2's joints for an eye and tool axis: the roll axis is the tool axis projected into
/// the arm plane (the vertical plane through the pedestal axis and the eye; a five-axis arm has
/// no wrist yaw, seed 001 §4.1.1).
fn irb_joints(arm: &Arm, branch: ElbowBranch, at: &At) -> Result<crate::Joints, Error> {
    irb_joints_at(arm, branch, &at.eye, &at.axis())
}

/// [`irb_joints`] for an eye (cell frame) and a tool axis (eye toward the mandrel).
pub fn irb_joints_at(
    arm: &Arm,
    branch: ElbowBranch,
    eye: &Point3<f64>,
    axis: &Vector3<f64>,
) -> Result<crate::Joints, Error> {
    let rho = eye.x.hypot(eye.y);
    let across = if rho > 1e-9 {
        Vector3::new(-eye.y / rho, eye.x / rho, 0.0)
    } else {
        Vector3::zeros()
    };
    let in_plane = axis - across * axis.dot(&across);
    let roll_axis = Unit::try_new(in_plane, 1e-9).ok_or(Error::OutOfRange {
        name: "tool axis",
        value: axis.dot(&across),
        expected: "must not be normal to the arm plane",
    })?;
    arm.inverse(eye, &roll_axis, 0.0, branch)
}

/// The IRB 6/2's links' Lipschitz bound over a move, mm per unit `τ`. The links checked
/// (pedestal, upper arm, forearm, wrist) hang on the first three joints only: pitch and roll turn
/// the eye mechanism, not them. A point of them lies within `upper + forearm` of the base's axis
/// and of the shoulder's, and within the forearm of the elbow's, so it moves at most `(|Δq1| +
/// |Δq2|)(upper + forearm) + |Δq3| forearm` (doubled, since joints do not move linearly in `τ`);
/// the mandrel's turn adds its angle times the smaller of the arm's and the mandrel's largest
/// distance from the rotation axis.
fn irb_link_lipschitz(
    ctx: &Context<'_>,
    arm: &Arm,
    instant: &dyn Fn(f64) -> At,
    d_phi: f64,
) -> Result<f64, Error> {
    let Some(SweptArm::Irb62(_, branch)) = ctx.cell.arm else {
        return Ok(0.0);
    };
    let (a, b) = (
        irb_joints(arm, branch, &instant(0.0))?,
        irb_joints(arm, branch, &instant(1.0))?,
    );
    let travel = [
        (a.base_yaw_rad - b.base_yaw_rad).abs(),
        (a.shoulder_rad - b.shoulder_rad).abs(),
        (a.elbow_rad - b.elbow_rad).abs(),
    ];
    let chain = arm.upper_arm_mm + arm.forearm_mm;
    let link_motion = (travel[0] + travel[1]) * chain + travel[2] * arm.forearm_mm;
    let arm_reach = arm.shoulder_height_mm + chain;
    let base_from_axis = ctx.distance_to_axis_mm(&Point3::origin());
    Ok(2.0 * link_motion + d_phi * (base_from_axis + arm_reach).min(ctx.solid.axis_radius_mm()))
}

/// A six-axis arm's approach or link move between two configurations is a joint move: its end
/// joints. Between poses of one configuration it is a straight move, as on a path.
fn joint_move(ctx: &Context<'_>, from: &End, to: &End) -> Option<(Joints6, Joints6)> {
    match (ctx.cell.arm, from.joints, to.joints) {
        (Some(SweptArm::SixAxis(_)), Some(a), Some(b))
            if (from.tangent.is_none() || to.tangent.is_none()) && from.config != to.config =>
        {
            Some((a, b))
        }
        _ => None,
    }
}

/// How fast, in mm per unit `τ`, any point of a six-axis arm's links, tool and eye mechanism can
/// move when the joints go from `a` to `b`: `Σ |Δqⱼ| · lever[j]`, doubled (the joints of a
/// Cartesian move do not move linearly in `τ`).
fn joint_travel_lipschitz(ctx: &Context<'_>, a: &Joints6, b: &Joints6) -> f64 {
    2.0 * (0..6)
        .map(|j| (b[j] - a[j]).abs() * ctx.levers_mm[j])
        .sum::<f64>()
}

/// A six-axis move as the link search sees it: its ends, whether it is a joint move (else a
/// straight move of the tool frame: the eye along a line, its orientation turning about one
/// axis at a steady rate) and the mandrel's turn over it, rad.
#[derive(Clone, Copy)]
struct SixAxisMove<'e> {
    from: &'e End,
    to: &'e End,
    joint_move: bool,
    d_phi: f64,
}

/// How fast, in mm per unit `τ`, any point of link `k` can move over a six-axis move from joints
/// `a` to `b`, seen from the mandrel.
///
/// - A joint moves the links after it: a point of link `k` lies within the links' length from
///   joint `j`'s axis to the link's far end (`link_levers_mm[k][j]`), so it moves at most
///   `Σ_{j≤k} |Δqⱼ| · lever`, doubled (the joints of a straight move do not turn linearly in `τ`).
/// - On a straight move the wrist link (wrist centre to flange, on axis 6) and the tool (flange
///   to eye) move with the tool frame: a point of them at `r` from the eye moves at most the
///   eye's travel plus the frame's turn times `r`, exactly, whatever the joints do.
/// - The mandrel's turn adds its angle times the mandrel's largest distance from its axis.
fn link_lipschitz(
    ctx: &Context<'_>,
    k: usize,
    a: &Joints6,
    b: &Joints6,
    mv: SixAxisMove<'_>,
) -> f64 {
    let spin = mv.d_phi * ctx.solid.axis_radius_mm();
    let joints = 2.0
        * (0..=k.min(5))
            .map(|j| (b[j] - a[j]).abs() * ctx.link_levers_mm[k][j])
            .sum::<f64>();
    let moving = match ctx.tool_reach_mm[k] {
        Some(reach) if !mv.joint_move => {
            (mv.to.eye - mv.from.eye).norm() + mv.from.q.angle_to(&mv.to.q) * reach
        }
        _ => joints,
    };
    moving + spin
}

/// The least clearance of a six-axis arm's links over a move: each link searched on its own,
/// with its own Lipschitz bound ([`link_lipschitz`]), below the job's least so far (`ceiling`).
/// The links far from the mandrel end after their two ends; the tool and wrist, near it, are
/// searched with the tool frame's own motion rather than the whole chain's. The minimum is the
/// least link's, the first dip the earliest of any link's.
fn six_axis_links_min(
    ctx: &Context<'_>,
    instant: &dyn Fn(f64) -> At,
    mv: SixAxisMove<'_>,
    mut ceiling: f64,
) -> Result<Minimum, Error> {
    // The arm at the move's ends, posed once: every link's search starts there.
    let (start, end) = (ctx.links(&instant(0.0))?, ctx.links(&instant(1.0))?);
    let joints_of =
        |l: &Option<(Option<Joints6>, Links)>| l.as_ref().and_then(|(q, _)| *q).unwrap_or([0.0; 6]);
    let (q0, q1) = (joints_of(&start), joints_of(&end));
    let mut failure: Option<Error> = None;
    let mut combined: Option<Minimum> = None;
    let mut first: Option<(f64, f64)> = None;
    let mut evaluations = 0;
    let mut complete = true;
    for k in 0..arm::LINKS {
        let mut link_fn = |tau: f64, cap: f64| {
            let at = instant(tau);
            let posed = if tau == 0.0 {
                Ok(start.as_ref().map(|(_, l)| *l))
            } else if tau == 1.0 {
                Ok(end.as_ref().map(|(_, l)| *l))
            } else {
                ctx.links(&at).map(|l| l.map(|(_, l)| l))
            };
            match posed {
                Ok(Some(links)) => {
                    let c = links.capsules[k];
                    ctx.capsule(&c.a, &c.b, c.radius_mm, at.phi, k > 0, cap).0
                }
                Ok(None) => f64::INFINITY,
                Err(e) => {
                    failure.get_or_insert(e);
                    f64::INFINITY
                }
            }
        };
        let lipschitz = link_lipschitz(ctx, k, &q0, &q1, mv);
        let m = certified_min_below(&mut link_fn, lipschitz, RESOLUTION_MM, 0.0, ceiling);
        if let Some(e) = failure {
            return Err(e);
        }
        ceiling = ceiling.min(m.value);
        evaluations += m.evaluations;
        complete &= m.complete;
        if let Some((tau, d)) = m.first_below
            && first.is_none_or(|(t, _)| tau < t)
        {
            first = Some((tau, d));
        }
        if combined.is_none_or(|c| m.value < c.value) {
            combined = Some(m);
        }
    }
    let least = combined.unwrap_or(Minimum {
        value: f64::INFINITY,
        at: 0.0,
        first_below: None,
        evaluations: 0,
        complete: true,
    });
    Ok(Minimum {
        first_below: first,
        evaluations,
        complete,
        ..least
    })
}

/// The least clearances found on the moves checked so far: a later move's minimum is certified
/// only where it could lie below them.
#[derive(Debug, Clone, Copy)]
struct Least {
    eye_mm: f64,
    arm_mm: f64,
}

/// One move as its checks see it: its place in the job and its pose at each `τ` in `[0, 1]`.
struct Move<'m, 'a> {
    ctx: &'m Context<'a>,
    from: &'m End,
    to: &'m End,
    path: usize,
    segment: usize,
    start_s: f64,
    duration_s: f64,
    /// The joints at the two ends of a six-axis joint move ([`joint_move`]).
    joints: Option<(Joints6, Joints6)>,
    six: Option<&'a SixAxisArm>,
    to_wrist: UnitQuaternion<f64>,
}

impl<'m, 'a> Move<'m, 'a> {
    fn new(
        ctx: &'m Context<'a>,
        from: &'m End,
        to: &'m End,
        path: usize,
        segment: usize,
        start_s: f64,
        duration_s: f64,
    ) -> Self {
        let six = match ctx.cell.arm {
            Some(SweptArm::SixAxis(arm)) => Some(arm),
            _ => None,
        };
        Move {
            ctx,
            from,
            to,
            path,
            segment,
            start_s,
            duration_s,
            joints: joint_move(ctx, from, to),
            six,
            to_wrist: tool_to_wrist(),
        }
    }

    /// The pose at `τ`: a six-axis joint move's joints interpolated linearly, else the eye
    /// along the straight line and the wrist by slerp; the mandrel angle linearly.
    fn instant(&self, tau: f64) -> At {
        let (from, to) = (self.from, self.to);
        let phi = from.phi + (to.phi - from.phi) * tau;
        match (self.joints, self.six) {
            (Some((a, b)), Some(arm)) => {
                let q: Joints6 = std::array::from_fn(|j| a[j] + (b[j] - a[j]) * tau);
                let frame = arm.tool_frame(&q);
                At {
                    eye: frame.origin(),
                    q: frame.quaternion() * self.to_wrist,
                    phi,
                    joints: Some(q),
                    config: None,
                }
            }
            _ => At {
                eye: from.eye + (to.eye - from.eye) * tau,
                q: from.q.try_slerp(&to.q, tau, 1e-12).unwrap_or(to.q),
                phi,
                joints: None,
                config: to.config,
            },
        }
    }

    /// The eye, its axis and the mandrel angle at `τ`.
    fn at(&self, tau: f64) -> (Point3<f64>, Vector3<f64>, f64) {
        let i = self.instant(tau);
        (i.eye, i.axis(), i.phi)
    }

    /// [`Move::at`] with a six-axis arm's joints, as a finding reports them.
    fn worst_at(&self, tau: f64) -> (Point3<f64>, Vector3<f64>, f64, Option<Joints6>) {
        let i = self.instant(tau);
        let joints = match self.six {
            Some(_) => self.ctx.links(&i).ok().flatten().and_then(|(q, _)| q),
            None => None,
        };
        (i.eye, i.axis(), i.phi, joints)
    }

    /// Adds a finding at `τ`.
    fn record(&self, report: &mut Report, tau: f64, clearance: f64, part: Part, against: String) {
        let (eye_mm, axis, mandrel_rad, joints) = self.worst_at(tau);
        report.findings.push(Finding {
            path: self.path,
            segment: self.segment,
            time_s: self.start_s + tau * self.duration_s,
            clearance_mm: clearance,
            part,
            against,
            eye_mm,
            axis,
            mandrel_rad,
            joints,
        });
    }

    /// The eye mechanism's least clearance, certified below `least.eye_mm`; its first contact
    /// and the worst instant noted.
    fn check_eye(&self, report: &mut Report, least: &mut Least) -> Minimum {
        let (ctx, cell) = (self.ctx, self.ctx.cell);
        let eye_len = cell.eye.length_mm;
        // Lipschitz bound of the eye capsule's points in τ. Turning the mandrel moves a point of
        // the capsule, seen from the mandrel, by at most `d_phi` times its distance from the
        // axis, and the mandrel's own points by at most `d_phi` times the solid's radius: either
        // bounds the change in distance.
        let l_eye = eye_lipschitz(ctx, self.from, self.to);
        let mut eye_fn = |tau: f64, cap: f64| {
            let (eye, axis, phi) = self.at(tau);
            ctx.capsule(
                &eye,
                &(eye - axis * eye_len),
                cell.eye.radius_mm,
                phi,
                true,
                cap,
            )
            .0
        };
        let eye = certified_min_below(&mut eye_fn, l_eye, RESOLUTION_MM, 0.0, least.eye_mm);
        least.eye_mm = least.eye_mm.min(eye.value);
        if let Some((tau, d)) = eye.first_below {
            // Name what the first contact was against.
            let (e, axis, phi) = self.at(tau);
            let (_, against) = ctx.capsule(
                &e,
                &(e - axis * eye_len),
                cell.eye.radius_mm,
                phi,
                true,
                f64::INFINITY,
            );
            let against = ctx.against(against);
            self.record(report, tau, d, Part::EyeMechanism, against);
        }
        note_worst(report, &eye, self.path, self.segment, &|tau| {
            self.worst_at(tau)
        });
        eye
    }

    /// The free fibre's least clearance (sampled), where both ends have a tangent point; its
    /// first snag recorded.
    fn check_free_fibre(&self, report: &mut Report) -> Option<f64> {
        let (Some(t0), Some(t1)) = (self.from.tangent, self.to.tangent) else {
            return None;
        };
        let first_segment = self.segment == 1;
        let (least, first) = free_fibre_min(
            self.ctx,
            self.from,
            self.to,
            (t0, t1),
            first_segment,
            &|tau| self.at(tau),
        );
        if let Some((tau, d)) = first {
            self.record(report, tau, d, Part::FreeFibre, "mandrel".to_string());
        }
        Some(least)
    }

    /// The arm links' least clearance, certified below `least.arm_mm`, where the cell has an
    /// arm; their first contact and the worst instant noted.
    fn check_links(&self, report: &mut Report, least: &mut Least) -> Result<Option<f64>, Error> {
        let ctx = self.ctx;
        let Some(swept) = ctx.cell.arm else {
            return Ok(None);
        };
        let instant = |tau: f64| self.instant(tau);
        let d_phi = (self.to.phi - self.from.phi).abs();
        let m = match swept {
            SweptArm::Irb62(arm, _) => {
                let l_arm = irb_link_lipschitz(ctx, arm, &instant, d_phi)?;
                let mut failure: Option<Error> = None;
                let mut arm_fn = |tau: f64, cap: f64| match ctx.arm(&instant(tau), cap) {
                    Ok(Some((d, _, _))) => d,
                    Ok(None) => f64::INFINITY,
                    Err(e) => {
                        failure.get_or_insert(e);
                        f64::INFINITY
                    }
                };
                let m = certified_min_below(&mut arm_fn, l_arm, RESOLUTION_MM, 0.0, least.arm_mm);
                if let Some(e) = failure {
                    return Err(e);
                }
                m
            }
            SweptArm::SixAxis(_) => six_axis_links_min(
                ctx,
                &instant,
                SixAxisMove {
                    from: self.from,
                    to: self.to,
                    joint_move: self.joints.is_some(),
                    d_phi,
                },
                least.arm_mm,
            )?,
        };
        least.arm_mm = least.arm_mm.min(m.value);
        if let Some((tau, d)) = m.first_below
            && let Some((_, link, against)) = ctx.arm(&instant(tau), f64::INFINITY)?
        {
            self.record(report, tau, d, Part::Link(link), ctx.against(against));
        }
        note_worst(report, &m, self.path, self.segment, &|tau| {
            self.worst_at(tau)
        });
        Ok(Some(m.value))
    }
}

/// Checks one move (the eye mechanism, the free fibre, the arm links, in that order), adds its
/// findings, returns its row.
#[allow(clippy::too_many_arguments)]
fn check_move(
    ctx: &Context<'_>,
    from: &End,
    to: &End,
    path: usize,
    segment: usize,
    start_s: f64,
    duration_s: f64,
    report: &mut Report,
    least: &mut Least,
) -> Result<SegmentClearance, Error> {
    let mv = Move::new(ctx, from, to, path, segment, start_s, duration_s);
    let eye = mv.check_eye(report, least);
    let tow_mm = mv.check_free_fibre(report);
    let arm_mm = mv.check_links(report, least)?;
    Ok(SegmentClearance {
        segment,
        start_s,
        duration_s,
        eye_mm: eye.value,
        tow_mm,
        arm_mm,
    })
}

/// The free fibre of a move, sampled (`tow_sample_count`): the least of
/// [`Solid::inside_beyond`] over the samples, and the first sample where the fibre lies deeper
/// in the mandrel than the snag tolerance (`tau`, depth). `(t0, t1)` are the tangent points at
/// the move's ends; `at(tau)` is the eye, its axis and the mandrel angle.
fn free_fibre_min(
    ctx: &Context<'_>,
    from: &End,
    to: &End,
    (t0, t1): (Point3<f64>, Point3<f64>),
    first_segment: bool,
    at: &dyn Fn(f64) -> (Point3<f64>, Vector3<f64>, f64),
) -> (f64, Option<(f64, f64)>) {
    let cell = ctx.cell;
    let count = tow_sample_count(ctx, from, to);
    let skip = 0.5 * cell.snag_tolerance_mm;
    let mut least = f64::INFINITY;
    let mut first: Option<(f64, f64)> = None;
    // The start pose's tow line runs along the first chord (the plan's start convention, eqs
    // 3.8–3.14 need a previous point), under the surface by that chord's sagitta: the first
    // segment's fibre is checked at its end only.
    let from_sample = if first_segment { count } else { 0 };
    for i in from_sample..=count {
        let tau = i as f64 / count as f64;
        let (eye, _, phi) = at(tau);
        let e = ctx.to_mandrel(&eye, phi);
        let t = if i == 0 {
            t0
        } else if i == count {
            t1
        } else {
            ctx.solid.surface_point(&(t0 + (t1 - t0) * tau))
        };
        let Some(dir) = (e - t).try_normalize(1e-9) else {
            continue;
        };
        // Within half the tolerance of the tangent point the fibre cannot be deeper than the
        // tolerance (signed distance is 1-Lipschitz), so the check starts there.
        let (d, below) = ctx
            .solid
            .inside_beyond(&(t + dir * skip), &e, cell.snag_tolerance_mm);
        least = least.min(d);
        if let (None, Some((_, depth))) = (first, below) {
            first = Some((tau, depth));
        }
    }
    (least, first)
}

fn note_worst(
    report: &mut Report,
    m: &Minimum,
    path: usize,
    segment: usize,
    at: &dyn Fn(f64) -> (Point3<f64>, Vector3<f64>, f64, Option<Joints6>),
) {
    if report.worst.is_none_or(|w| m.value < w.clearance_mm) {
        let (eye_mm, axis, mandrel_rad, joints) = at(m.at);
        report.worst = Some(Instant {
            path,
            segment,
            tau: m.at,
            eye_mm,
            axis,
            mandrel_rad,
            joints,
            clearance_mm: m.value,
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::clearance::TubeSolid;
    use crate::clearance::test_support::uniform;
    use crate::geodesic::{self, Direction, PathStart};
    use crate::plan::{ENTRY_ANGLE_MAX_DEG, plan};
    use crate::segment::equal_length;
    use crate::{Calibration, Gearing, MandrelProfile, Movement, Speeds, Tube};

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

    /// The cylinder of `examples/cylinder.toml` wound at 48.3° in 10 long segments.
    fn cylinder_plan(setup: &Setup) -> (Tube, PathPlan) {
        cylinder_plan_at(setup, 48.3)
    }

    fn cylinder_plan_at(setup: &Setup, wind_angle_deg: f64) -> (Tube, PathPlan) {
        let tube = Tube::cylinder(63.5, 178.0, 0.0, 0.0).unwrap();
        let start = PathStart {
            angle_rad: 0.0,
            wind_angle_rad: wind_angle_deg.to_radians(),
            direction: Direction::Up,
        };
        let path = geodesic::helix(&tube, &start, 1.0).unwrap();
        let points = equal_length(&tube, &path, 10).unwrap();
        let speeds = Speeds {
            mandrel: MandrelProfile {
                accel_rps2: 1.0,
                start_stop_rps: 0.05,
                max_rps: 0.1,
            },
            base_speed_mm_s: 1000.0,
            max_speed_mm_s: 2000.0,
            movement: Movement::Fine,
        };
        let p = plan(&points, |p| tube.distance_to_surface_mm(p), setup, &speeds).unwrap();
        (tube, p)
    }

    /// The eye mechanism's capsule radius in these tests, mm.
    const EYE_RADIUS_MM: f64 = 2.0;

    fn cell<'a>(setup: &'a Setup, obstacles: &'a [Obstacle]) -> Cell<'a> {
        Cell {
            setup,
            eye: EyeMechanism {
                length_mm: 150.0,
                radius_mm: EYE_RADIUS_MM,
            },
            snag_tolerance_mm: crate::clearance::DEFAULT_SNAG_TOLERANCE_MM,
            obstacles,
            home_mm: None,
            approach_speed_mm_s: 100.0,
            arm: None,
        }
    }

    /// A 0.2 mm cube on the straight line the eye travels between the ends of segment 5: at
    /// both ends the eye mechanism's capsule is clear of it (an endpoint-only check passes),
    /// but halfway the eye runs through it. The sweep names that segment.
    #[test]
    fn a_thin_obstacle_between_two_segment_ends_is_found() {
        let setup = setup();
        let (tube, p) = cylinder_plan(&setup);
        let solid = TubeSolid::new(&tube);
        let clear = sweep(&cell(&setup, &[]), &solid, &[&p]).unwrap();
        assert!(clear.is_clear(), "{:?}", clear.findings);

        let e0 = p.segments[3].pose.eye_mm;
        let e1 = p.segments[4].pose.eye_mm;
        let travel = (e1 - e0).norm();
        assert!(travel > 4.0 * EYE_RADIUS_MM, "eye travel {travel} mm");
        let mid = e0 + (e1 - e0) * 0.5;
        let half = Vector3::repeat(0.1);
        let cube = Obstacle {
            name: "wire".into(),
            min_mm: mid - half,
            max_mm: mid + half,
        };
        // The naive check: the capsule at every segment end.
        let mut poses = vec![&p.start];
        poses.extend(p.segments.iter().map(|s| &s.pose));
        for pose in poses {
            let back = pose.eye_mm - axis_of(&pose.wrist_q) * 150.0;
            let d = cube.distance_to_segment_mm(&pose.eye_mm, &back) - EYE_RADIUS_MM;
            assert!(d > 1.0, "an end pose already touches: {d} mm");
        }
        let obstacles = [cube];
        let r = sweep(&cell(&setup, &obstacles), &solid, &[&p]).unwrap();
        let f = r.findings.first().expect("the cube is found");
        assert_eq!((f.path, f.segment), (1, 5), "{f:?}");
        assert_eq!(f.part, Part::EyeMechanism);
        assert_eq!(f.against, "wire");
        assert!(f.clearance_mm < 0.0);
        // First contact inside segment 5, no later than the eye reaching the cube's centre (the
        // capsule's body behind the eye can meet it first).
        let t4 = p.segments[..4].iter().map(|s| s.duration_s).sum::<f64>();
        let t_mid = t4 + 0.5 * p.segments[4].duration_s;
        assert!(
            f.time_s > t4 && f.time_s <= t_mid + 1e-9,
            "{} vs {t4}..{t_mid}",
            f.time_s
        );
    }

    /// A finding on the approach from home is stamped before the path's first point by the eye's
    /// remaining travel over the approach speed. Home is 400 mm behind the start eye along the
    /// tool axis, so the approach (the wrist and the mandrel still: home takes the start's
    /// orientation and angle) runs the eye down its own axis toward the mandrel for 400 mm /
    /// 100 mm/s = 4 s. A 0.02 mm cube sits on that line 250 mm before the start eye, clear of
    /// the 150 mm capsule at both ends of the move. The capsule's front, the eye's 2 mm sphere,
    /// first touches the cube when the eye is `s` short of the cube's centre, `s` solved from the
    /// box's distance along the line (`Σ max(s |uᵢ| − h, 0)² = r²`, bisection); so the contact is
    /// at `−(250 + s) / 100` s, within the 0.001 mm resolution's travel.
    #[test]
    fn a_finding_on_the_approach_is_timed_by_the_travel_left_to_the_path() {
        let setup = setup();
        let (tube, p) = cylinder_plan(&setup);
        let solid = TubeSolid::new(&tube);
        let axis = axis_of(&p.start.wrist_q);
        let home = p.start.eye_mm - axis * 400.0;
        let centre = p.start.eye_mm - axis * 250.0;
        let h = 0.01;
        let half = Vector3::repeat(h);
        let obstacles = [Obstacle {
            name: "wire".into(),
            min_mm: centre - half,
            max_mm: centre + half,
        }];
        let mut c = cell(&setup, &obstacles);
        c.home_mm = Some(home);
        let r = sweep(&c, &solid, &[&p]).unwrap();
        let f = r.findings.first().expect("the cube is found");
        assert_eq!((f.path, f.segment), (1, 0), "{f:?}");
        assert_eq!(f.part, Part::EyeMechanism);
        assert_eq!(f.against, "wire");
        assert!(f.clearance_mm < 0.0, "{f:?}");
        // Where the eye's sphere meets the box: the eye at `centre − u s`, `u` the unit axis.
        let gap = |s: f64| {
            axis.iter()
                .map(|u| (s * u.abs() - h).max(0.0).powi(2))
                .sum::<f64>()
                .sqrt()
        };
        let (mut lo, mut hi) = (0.0, 10.0);
        for _ in 0..200 {
            let m = 0.5 * (lo + hi);
            if gap(m) > EYE_RADIUS_MM {
                hi = m;
            } else {
                lo = m;
            }
        }
        let s = 0.5 * (lo + hi);
        assert!(s > EYE_RADIUS_MM && s < EYE_RADIUS_MM + 2.0 * h, "{s}");
        let want = -(250.0 + s) / c.approach_speed_mm_s;
        assert!((f.time_s - want).abs() < 1e-4, "{} s vs {want} s", f.time_s);
        // The eye reported there is on the line, that far from the start.
        let back = (p.start.eye_mm - f.eye_mm).norm();
        assert!((back - (250.0 + s)).abs() < 0.01, "{back} mm");
        // The approach row: 400 mm at 100 mm/s, ending at the path's first point.
        let row = &r.paths[0][0];
        assert_eq!(row.segment, 0);
        assert!((row.duration_s - 4.0).abs() < 1e-9, "{row:?}");
        assert!((row.start_s + 4.0).abs() < 1e-9, "{row:?}");
    }

    /// A job of four paths (wind angles 40°, 48.3°, 55° and 40° again) with a thin wire on the
    /// third path's eye line, checked as the threads check it (runs of consecutive paths): the
    /// rows come back in path order, every link move starts where the path before ended (its
    /// duration the eye's travel over the approach speed), the only findings are the third
    /// path's, and the worst pose is there too. The same paths checked one by one agree on
    /// every segment row.
    #[test]
    fn paths_checked_on_threads_come_back_in_order_with_their_own_findings() {
        let setup = setup();
        let plans: Vec<(Tube, PathPlan)> = [40.0, 48.3, 55.0, 40.0]
            .iter()
            .map(|&a| cylinder_plan_at(&setup, a))
            .collect();
        let solid = TubeSolid::new(&plans[0].0);
        let p3 = &plans[2].1;
        let (e0, e1) = (p3.segments[3].pose.eye_mm, p3.segments[4].pose.eye_mm);
        let mid = e0 + (e1 - e0) * 0.5;
        let half = Vector3::repeat(0.1);
        let obstacles = [Obstacle {
            name: "wire".into(),
            min_mm: mid - half,
            max_mm: mid + half,
        }];
        let c = cell(&setup, &obstacles);
        let refs: Vec<&PathPlan> = plans.iter().map(|(_, p)| p).collect();
        let r = sweep(&c, &solid, &refs).unwrap();
        assert_eq!(r.paths.len(), 4);
        for (n, rows) in r.paths.iter().enumerate() {
            assert_eq!(rows.len(), refs[n].segments.len() + 1, "path {n}");
            if n > 0 {
                let before = refs[n - 1].segments.last().unwrap().pose.eye_mm;
                let travel = (refs[n].start.eye_mm - before).norm();
                let want = travel / c.approach_speed_mm_s;
                assert!((rows[0].duration_s - want).abs() < 1e-9, "path {n}");
                assert!(want > 0.01, "path {n}: the link move has length");
            }
        }
        assert!(!r.findings.is_empty());
        assert!(r.findings.iter().all(|f| f.path == 3), "{:?}", r.findings);
        assert_eq!(r.findings[0].segment, 5);
        let worst = r.worst.expect("a worst pose");
        assert_eq!(worst.path, 3);
        assert!(worst.clearance_mm < 0.0);
        // Each path alone (the first with no move before it, as in the job).
        for (n, p) in refs.iter().enumerate() {
            let alone = sweep(&c, &solid, &[p]).unwrap();
            for (a, b) in alone.paths[0][1..].iter().zip(&r.paths[n][1..]) {
                assert_eq!(a.segment, b.segment);
                assert_eq!(a.tow_mm, b.tow_mm);
                // Eye rows agree where they undercut the ceiling both searches share; a row
                // above it is only a bound.
                if a.eye_mm < 5.0 {
                    assert!((a.eye_mm - b.eye_mm).abs() < 0.01, "path {n}: {a:?} {b:?}");
                }
            }
        }
    }

    /// The job's least eye clearance, certified across moves: a small box beside the middle of
    /// segment 5 (where neither end shows it, and after moves whose least clearance is larger)
    /// sets it; dense sampling of every move agrees to the stated tolerance, and no row reports
    /// less than the sampled truth allows.
    #[test]
    fn least_clearance_over_the_job_agrees_with_dense_sampling() {
        let setup = setup();
        let (tube, p) = cylinder_plan(&setup);
        let solid = TubeSolid::new(&tube);
        let e0 = p.segments[3].pose.eye_mm;
        let e1 = p.segments[4].pose.eye_mm;
        let mid = e0 + (e1 - e0) * 0.5;
        // Beside the eye's line, 4 mm off it (the capsule's radius is 2 mm).
        let side = (e1 - e0).cross(&Vector3::z()).normalize() * 4.0;
        let half = Vector3::repeat(0.1);
        let obstacles = [Obstacle {
            name: "post".into(),
            min_mm: mid + side - half,
            max_mm: mid + side + half,
        }];
        let c = cell(&setup, &obstacles);
        let r = sweep(&c, &solid, &[&p]).unwrap();
        assert!(r.is_clear(), "{:?}", r.findings);
        let least = r.paths[0]
            .iter()
            .map(|row| row.eye_mm)
            .fold(f64::INFINITY, f64::min);
        let ctx = Context::new(&c, &solid);
        let mut ends = vec![End::of(&p.start, &p)];
        ends.extend(p.segments.iter().map(|s| End::of(&s.pose, &p)));
        let mut dense = f64::INFINITY;
        let mut per_move = Vec::new();
        for w in ends.windows(2) {
            let (from, to) = (&w[0], &w[1]);
            let mut m = f64::INFINITY;
            for i in 0..=4000 {
                let tau = i as f64 / 4000.0;
                let eye = from.eye + (to.eye - from.eye) * tau;
                let q = from.q.try_slerp(&to.q, tau, 1e-12).unwrap_or(to.q);
                let phi = from.phi + (to.phi - from.phi) * tau;
                let back = eye - axis_of(&q) * 150.0;
                let d = ctx
                    .capsule(&eye, &back, EYE_RADIUS_MM, phi, true, f64::INFINITY)
                    .0;
                m = m.min(d);
            }
            per_move.push(m);
            dense = dense.min(m);
        }
        // The least is on segment 5, against the post, below every other move's least.
        let at = per_move
            .iter()
            .enumerate()
            .min_by(|a, b| a.1.total_cmp(b.1))
            .unwrap()
            .0;
        assert_eq!(at, 4, "{per_move:?}");
        assert!(dense < 2.5 && dense > 0.1, "{dense}");
        let tol = RESOLUTION_MM.max(super::super::minimum::RELATIVE * dense) + 0.01;
        assert!((least - dense).abs() <= tol, "{least} vs {dense}");
        // Each row is a value its move takes: never below that move's sampled least by more
        // than the sampling step allows.
        for (row, m) in r.paths[0][1..].iter().zip(&per_move) {
            assert!(row.eye_mm >= m - 0.05, "{} vs {m}", row.eye_mm);
        }
    }

    /// A six-axis arm (IRB 2600, eye 200 mm out on the flange's axis, the mandrel on a horizontal
    /// positioner as in `examples/irb2600-positioner.toml`) winding the cylinder: the links' least
    /// clearance over the job, searched link by link with each link's own bound, equals the
    /// least of every link sampled densely along every move (the arm posed by its inverse
    /// kinematics at each sample), and the link searches stop early far from the mandrel.
    #[test]
    fn six_axis_links_least_clearance_agrees_with_dense_sampling() {
        let (arm, setup, tube, p) = irb2600_on_a_positioner();
        let solid = TubeSolid::new(&tube);
        let config = match p.arm {
            PathArm::SixAxis(report) => report.config,
            PathArm::Irb62(_) => panic!("a six-axis plan"),
        };
        let instant = |from: &End, to: &End, tau: f64| At {
            eye: from.eye + (to.eye - from.eye) * tau,
            q: from.q.try_slerp(&to.q, tau, 1e-12).unwrap_or(to.q),
            phi: from.phi + (to.phi - from.phi) * tau,
            joints: None,
            config: Some(config),
        };
        // A 0.2 mm cube 3 mm off the tool's capsule halfway along segment 5, away from the eye's
        // travel: the tool's ends pass it by far more.
        let (e4, e5) = (
            End::of(&p.segments[3].pose, &p),
            End::of(&p.segments[4].pose, &p),
        );
        let post = {
            let mut c0 = cell(&setup, &[]);
            c0.arm = Some(SweptArm::SixAxis(&arm));
            let ctx = Context::new(&c0, &solid);
            let (_, links) = ctx.links(&instant(&e4, &e5, 0.5)).unwrap().unwrap();
            let tool = links.capsules[6];
            let along = tool.b - tool.a;
            let off = along.cross(&(e5.eye - e4.eye)).normalize();
            let centre = tool.a + along * 0.5 + off * (tool.radius_mm + 3.1);
            let half = Vector3::repeat(0.1);
            [Obstacle {
                name: "post".into(),
                min_mm: centre - half,
                max_mm: centre + half,
            }]
        };
        let mut c = cell(&setup, &post);
        c.arm = Some(SweptArm::SixAxis(&arm));
        let r = sweep(&c, &solid, &[&p]).unwrap();
        let least = r.paths[0]
            .iter()
            .filter_map(|row| row.arm_mm)
            .fold(f64::INFINITY, f64::min);
        let ctx = Context::new(&c, &solid);
        let mut ends = vec![End::of(&p.start, &p)];
        ends.extend(p.segments.iter().map(|s| End::of(&s.pose, &p)));
        let mut dense = f64::INFINITY;
        for w in ends.windows(2) {
            let (from, to) = (&w[0], &w[1]);
            for i in 0..=400 {
                let at = instant(from, to, i as f64 / 400.0);
                let (_, links) = ctx.links(&at).unwrap().unwrap();
                for (k, l) in links.capsules.iter().enumerate() {
                    let d = ctx.capsule(&l.a, &l.b, l.radius_mm, at.phi, k > 0, f64::INFINITY);
                    dense = dense.min(d.0);
                }
            }
        }
        // The least is the tool's pass by the post, mid-move.
        assert!((2.0..3.2).contains(&dense), "{dense}");
        assert!(r.is_clear(), "{:?}", r.findings);
        let tol = RESOLUTION_MM.max(super::super::minimum::RELATIVE * dense);
        // Certified: never above the true least by more than the tolerance; a value the links
        // take, so never below the densely sampled least by more than a sampling step allows.
        assert!(least <= dense + tol, "{least} above the sampled {dense}");
        assert!(
            least >= dense - 0.5,
            "{least} far below the sampled {dense}"
        );
        assert_eq!(r.worst.map(|w| w.clearance_mm <= least), Some(true));
    }

    /// The eye capsule's clearance never changes faster in `τ` than the move's Lipschitz bound
    /// (finite differences over 4 000 steps of every move of the cylinder plan, on the tube and
    /// with a post beside the eye's line), and the capsule's clearance is the solid's segment
    /// minimum less the radius, found independently in the mandrel frame.
    #[test]
    fn eye_clearance_changes_no_faster_than_its_bound() {
        let setup = setup();
        let (tube, p) = cylinder_plan(&setup);
        let solid = TubeSolid::new(&tube);
        let e0 = p.segments[3].pose.eye_mm;
        let e1 = p.segments[4].pose.eye_mm;
        let side = (e1 - e0).cross(&Vector3::z()).normalize() * 4.0;
        let mid = e0 + (e1 - e0) * 0.5 + side;
        let obstacles = [Obstacle {
            name: "post".into(),
            min_mm: mid - Vector3::repeat(0.1),
            max_mm: mid + Vector3::repeat(0.1),
        }];
        let c = cell(&setup, &obstacles);
        let ctx = Context::new(&c, &solid);
        let mut ends = vec![End::of(&p.start, &p)];
        ends.extend(p.segments.iter().map(|s| End::of(&s.pose, &p)));
        let mut tightest = 0.0f64;
        for w in ends.windows(2) {
            let (from, to) = (&w[0], &w[1]);
            let bound = eye_lipschitz(&ctx, from, to);
            let value = |tau: f64| {
                let eye = from.eye + (to.eye - from.eye) * tau;
                let q = from.q.try_slerp(&to.q, tau, 1e-12).unwrap_or(to.q);
                let phi = from.phi + (to.phi - from.phi) * tau;
                let back = eye - axis_of(&q) * 150.0;
                let got = ctx
                    .capsule(&eye, &back, EYE_RADIUS_MM, phi, false, f64::INFINITY)
                    .0;
                // Independently: into the mandrel frame by hand, the solid's own minimum.
                let (s, c) = phi.sin_cos();
                let m = |p: Point3<f64>| {
                    let w = p - ctx.origin;
                    Point3::new(c * w.x + s * w.y, -s * w.x + c * w.y, w.z)
                };
                let want = solid.segment_min_mm(&m(eye), &m(back)) - EYE_RADIUS_MM;
                assert!((got - want).abs() < 1e-9, "{got} vs {want}");
                ctx.capsule(&eye, &back, EYE_RADIUS_MM, phi, true, f64::INFINITY)
                    .0
            };
            let n = 4000;
            let mut previous = value(0.0);
            for i in 1..=n {
                let v = value(i as f64 / n as f64);
                let slope = (v - previous).abs() * n as f64;
                assert!(
                    slope <= bound + 1e-6,
                    "slope {slope} above the bound {bound}"
                );
                tightest = tightest.max(slope / bound);
                previous = v;
            }
        }
        // The bound is not vacuous: somewhere the clearance changes at a fair share of it.
        assert!(tightest > 0.2, "{tightest}");
    }

    /// A capsule asked with a cap, on a mesh mandrel (whose queries honour caps) and beside a
    /// box: the exact clearance when it is below the cap, otherwise a value from the cap up to
    /// it, never less; on random capsules around the cylinder at five caps each.
    #[test]
    fn capped_capsule_is_exact_below_its_cap_and_a_bound_above() {
        use crate::mesh::{Closure, DEFAULT_WELD_MM, prepare, triasym};
        let setup = setup();
        let tube = Tube::cylinder(63.5, 178.0, 0.0, 0.0).unwrap();
        let mesh = {
            let raw = triasym::tube(&tube, 64, 4.0, true).unwrap();
            prepare(&raw, DEFAULT_WELD_MM, Closure::Closed).unwrap().0
        };
        let solid = crate::clearance::MeshSolid::new(&mesh).unwrap();
        let origin = Vector3::new(setup.robot_distance_mm, 0.0, setup.mandrel_height_mm);
        let post = origin + Vector3::new(-60.0, 10.0, 80.0);
        let obstacles = [Obstacle {
            name: "post".into(),
            min_mm: Point3::from(post - Vector3::repeat(5.0)),
            max_mm: Point3::from(post + Vector3::repeat(5.0)),
        }];
        let c = cell(&setup, &obstacles);
        let ctx = Context::new(&c, &solid);
        let mut next = uniform(0x5851_f42d_4c95_7f2du64);
        let mut stopped = 0;
        for _ in 0..200 {
            let mut p = || {
                Point3::from(
                    origin
                        + Vector3::new(
                            -120.0 + 240.0 * next(),
                            -120.0 + 240.0 * next(),
                            -20.0 + 220.0 * next(),
                        ),
                )
            };
            let (a, b) = (p(), p());
            let phi = next() * std::f64::consts::TAU;
            let exact = ctx.capsule(&a, &b, 2.0, phi, true, f64::INFINITY).0;
            for cap in [exact - 5.0, exact - 0.1, exact + 0.1, exact + 5.0, 1.0] {
                let got = ctx.capsule(&a, &b, 2.0, phi, true, cap).0;
                if exact < cap - RESOLUTION_MM {
                    assert!(
                        (got - exact).abs() <= RESOLUTION_MM,
                        "{got} vs {exact} below {cap}"
                    );
                } else {
                    assert!(got >= cap - RESOLUTION_MM, "{got} below its cap {cap}");
                    assert!(got <= exact + RESOLUTION_MM, "{got} above {exact}");
                    stopped += usize::from(got < exact - 1e-6);
                }
            }
        }
        assert!(stopped > 20, "{stopped}");
    }

    /// The bound on what the free-fibre sampling can miss: between consecutive sampled tow
    /// lines the eye travels at most [`TOW_SAMPLE_MM`] along its path in the mandrel frame (arc
    /// length, summed over 200 sub-steps), on every segment of the cylinder plan; and the
    /// sampling is not wasteful: no more than 1.5 times the intervals that arc length needs,
    /// plus one.
    #[test]
    fn tow_samples_are_no_farther_apart_than_the_stated_bound() {
        let setup = setup();
        let (tube, p) = cylinder_plan(&setup);
        let solid = TubeSolid::new(&tube);
        let c = cell(&setup, &[]);
        let ctx = Context::new(&c, &solid);
        let eye_at = |from: &End, to: &End, tau: f64| {
            let eye = from.eye + (to.eye - from.eye) * tau;
            let phi = from.phi + (to.phi - from.phi) * tau;
            ctx.to_mandrel(&eye, phi)
        };
        let mut ends = vec![End::of(&p.start, &p)];
        ends.extend(p.segments.iter().map(|s| End::of(&s.pose, &p)));
        for w in ends.windows(2) {
            let (from, to) = (&w[0], &w[1]);
            let count = tow_sample_count(&ctx, from, to);
            let mut worst = 0.0f64;
            let mut total = 0.0;
            for i in 0..count {
                let mut arc = 0.0;
                let mut previous = eye_at(from, to, i as f64 / count as f64);
                for k in 1..=200 {
                    let tau = (i as f64 + k as f64 / 200.0) / count as f64;
                    let e = eye_at(from, to, tau);
                    arc += (e - previous).norm();
                    previous = e;
                }
                worst = worst.max(arc);
                total += arc;
            }
            assert!(worst <= TOW_SAMPLE_MM + 1e-9, "{worst} mm between samples");
            let needed = (total / TOW_SAMPLE_MM).ceil();
            assert!(
                count as f64 <= 1.5 * needed + 1.0,
                "{count} samples where {needed} do"
            );
        }
    }

    /// Each link's Lipschitz bound by hand on the IRB 2600 (OPW parameters `c1 = 445`, `a1 =
    /// 150`, `c2 = 700`, `|a2| = 115`, `c3 = 795`, `c4 = 85` mm, the eye 200 mm out on the
    /// flange): the chain from the base through the link points is 445, 150, 700, 115, 795, 85
    /// and 200 mm long, so link `k` lies within the chain's length from link point `j` to its far
    /// end of joint `j`'s axis (`j ≤ k`). A joint move from `a` to `b` bounds link `k` by
    /// `2 Σ_{j≤k} |bⱼ − aⱼ| · lever` plus the mandrel's turn times its radius (31.75 mm, the
    /// 63.5 mm cylinder); on a straight move the wrist link and the tool move with the tool frame:
    /// the eye's travel plus the frame's turn times their farthest point from the eye (the wrist
    /// centre, 85 + 200 mm, and the flange, 200 mm), plus the same turn of the mandrel.
    #[test]
    fn each_links_bound_is_its_levers_by_hand() {
        use crate::arm::Tool;
        let arm = SixAxisArm::opw_preset(
            "irb2600-12/1.65",
            Tool {
                tcp_mm: [0.0, 0.0, 200.0],
                rpy_deg: [0.0, 0.0, 0.0],
            },
        )
        .unwrap();
        let setup = setup();
        let tube = Tube::cylinder(63.5, 178.0, 0.0, 0.0).unwrap();
        let solid = TubeSolid::new(&tube);
        let mut c = cell(&setup, &[]);
        c.arm = Some(SweptArm::SixAxis(&arm));
        let ctx = Context::new(&c, &solid);
        let chain = [445.0, 150.0, 700.0, 115.0, 795.0, 85.0, 200.0];
        // along[i]: the chain's length from the base to link point i (7: the eye).
        let mut along = [0.0f64; 8];
        for i in 1..8 {
            along[i] = along[i - 1] + chain[i - 1];
        }
        let radius_mm = 31.75;
        let a: Joints6 = [0.1, -0.2, 0.3, -0.4, 0.5, -0.6];
        let b: Joints6 = [0.25, -0.1, 0.1, 0.0, 0.2, -0.3];
        let turn_rad = 0.2;
        let from = End {
            eye: Point3::new(1000.0, 20.0, 900.0),
            q: UnitQuaternion::identity(),
            phi: 0.4,
            tangent: None,
            joints: Some(a),
            config: None,
        };
        let to = End {
            eye: Point3::new(1003.0, 24.0, 900.0),
            q: UnitQuaternion::from_axis_angle(&Vector3::z_axis(), turn_rad),
            phi: 0.7,
            ..from
        };
        let d_phi = 0.3;
        let spin = d_phi * radius_mm;
        for joint_move in [true, false] {
            let mv = SixAxisMove {
                from: &from,
                to: &to,
                joint_move,
                d_phi,
            };
            for k in 0..arm::LINKS {
                let by_joints: f64 = 2.0
                    * (0..=k.min(5))
                        .map(|j| (b[j] - a[j]).abs() * (along[k + 1] - along[j]))
                        .sum::<f64>();
                let by_frame = match k {
                    5 => Some(5.0 + turn_rad * (85.0 + 200.0)),
                    6 => Some(5.0 + turn_rad * 200.0),
                    _ => None,
                };
                let want = match by_frame {
                    Some(frame) if !joint_move => frame,
                    _ => by_joints,
                } + spin;
                let got = link_lipschitz(&ctx, k, &a, &b, mv);
                assert!(
                    (got - want).abs() < 1e-9,
                    "link {k}, joint move {joint_move}: {got} vs {want}"
                );
            }
        }
    }

    /// The IRB 2600 on a horizontal positioner with a slim wrist and tool (clear of the mandrel),
    /// and its cylinder plan.
    fn irb2600_on_a_positioner() -> (SixAxisArm, Setup, Tube, PathPlan) {
        use crate::arm::{MandrelDrive, Tool};
        use crate::plan::SixAxisCell;
        let mut arm = SixAxisArm::opw_preset(
            "irb2600-12/1.65",
            Tool {
                tcp_mm: [0.0, 0.0, 200.0],
                rpy_deg: [0.0, 0.0, 0.0],
            },
        )
        .unwrap();
        arm.link_radii_mm[5] = 10.0;
        arm.link_radii_mm[6] = 5.0;
        let mut setup = setup();
        setup.six_axis = Some(SixAxisCell {
            arm,
            axis: MandrelAxis::new([1000.0, -90.0, 700.0], [0.0, 1.0, 0.0], MandrelDrive::Robot)
                .unwrap(),
        });
        let (tube, p) = cylinder_plan(&setup);
        (arm, setup, tube, p)
    }

    /// The base stands on the floor and is checked against the mandrel only: a slab under it,
    /// 60 mm into its 200 mm capsule, is no finding. The same slab raised to 15 mm into the
    /// shoulder link's capsule (its axis 445 mm up, radius 160 mm, so its underside at 285 mm
    /// whatever axis 1 does) is found on the first move, named, 15 mm deep.
    #[test]
    fn the_six_axis_base_is_not_checked_against_obstacles() {
        let (arm, setup, tube, p) = irb2600_on_a_positioner();
        let solid = TubeSolid::new(&tube);
        let slab = |top_mm: f64| Obstacle {
            name: "floor".into(),
            min_mm: Point3::new(-400.0, -400.0, top_mm - 50.0),
            max_mm: Point3::new(400.0, 400.0, top_mm),
        };
        let under = [slab(-140.0)];
        let mut c = cell(&setup, &under);
        c.arm = Some(SweptArm::SixAxis(&arm));
        let r = sweep(&c, &solid, &[&p]).unwrap();
        assert!(r.is_clear(), "{:?}", r.findings);
        let raised = [slab(300.0)];
        let mut c = cell(&setup, &raised);
        c.arm = Some(SweptArm::SixAxis(&arm));
        let r = sweep(&c, &solid, &[&p]).unwrap();
        let f = r.findings.first().expect("the shoulder meets the slab");
        assert_eq!(f.part, Part::Link("shoulder"), "{f:?}");
        assert_eq!(f.against, "floor");
        assert!((f.clearance_mm + 15.0).abs() < 0.01, "{f:?}");
    }

    /// Two links dip below zero on one move, the later-searched link first: a 0.2 mm cube
    /// 0.3 mm inside the tool's leading side a fifth of the way along segment 5, another inside
    /// the forearm's leading side halfway, which the forearm then runs deeper into than the tool
    /// into its own. The move's finding is the earliest contact of any link (not the deepest),
    /// found by sampling every link densely (2 000 instants), and names the tool.
    #[test]
    fn a_moves_first_link_contact_is_the_earliest_of_any_link() {
        let (arm, setup, tube, p) = irb2600_on_a_positioner();
        let solid = TubeSolid::new(&tube);
        let config = match p.arm {
            PathArm::SixAxis(report) => report.config,
            PathArm::Irb62(_) => panic!("a six-axis plan"),
        };
        let (from, to) = (
            End::of(&p.segments[3].pose, &p),
            End::of(&p.segments[4].pose, &p),
        );
        let instant = |tau: f64| At {
            eye: from.eye + (to.eye - from.eye) * tau,
            q: from.q.try_slerp(&to.q, tau, 1e-12).unwrap_or(to.q),
            phi: from.phi + (to.phi - from.phi) * tau,
            joints: None,
            config: Some(config),
        };
        let (tool, forearm) = (6, 4);
        let cubes = {
            let mut c0 = cell(&setup, &[]);
            c0.arm = Some(SweptArm::SixAxis(&arm));
            let ctx = Context::new(&c0, &solid);
            let capsule =
                |k: usize, tau: f64| ctx.links(&instant(tau)).unwrap().unwrap().1.capsules[k];
            let ahead = |k: usize, tau: f64, name: &str| {
                let c = capsule(k, tau);
                let mid = |c: Capsule| c.a + (c.b - c.a) * 0.5;
                let along = (c.b - c.a).normalize();
                let v = mid(capsule(k, tau + 1e-3)) - mid(capsule(k, tau - 1e-3));
                let n = (v - along * v.dot(&along)).normalize();
                let centre = mid(c) + n * (c.radius_mm - 0.3);
                Obstacle {
                    name: name.into(),
                    min_mm: centre - Vector3::repeat(0.1),
                    max_mm: centre + Vector3::repeat(0.1),
                }
            };
            [
                ahead(tool, 0.2, "tool post"),
                ahead(forearm, 0.5, "forearm post"),
            ]
        };
        let mut c = cell(&setup, &cubes);
        c.arm = Some(SweptArm::SixAxis(&arm));
        let ctx = Context::new(&c, &solid);
        // Each link's first sampled instant below zero.
        let n = 2000;
        let mut first = [None; arm::LINKS];
        let mut least = [f64::INFINITY; arm::LINKS];
        for i in 0..=n {
            let tau = i as f64 / n as f64;
            let at = instant(tau);
            let (_, links) = ctx.links(&at).unwrap().unwrap();
            for (k, l) in links.capsules.iter().enumerate() {
                let d = ctx
                    .capsule(&l.a, &l.b, l.radius_mm, at.phi, k > 0, f64::INFINITY)
                    .0;
                if d < 0.0 && first[k].is_none() {
                    first[k] = Some(tau);
                }
                least[k] = least[k].min(d);
            }
        }
        let t_tool = first[tool].expect("the tool meets its post");
        let t_forearm = first[forearm].expect("the forearm meets its post");
        assert!(t_tool < 0.25 && t_forearm > 0.45, "{first:?}");
        // The forearm goes deeper than the tool: the earliest contact is not the deepest.
        assert!(least[forearm] < least[tool] - 1.0, "{least:?}");
        assert!(
            first.iter().flatten().all(|&t| t >= t_tool),
            "another link first: {first:?}"
        );
        let r = sweep(&c, &solid, &[&p]).unwrap();
        let f = r
            .findings
            .iter()
            .find(|f| f.segment == 5 && matches!(f.part, Part::Link(_)))
            .expect("a link finding on segment 5");
        assert_eq!(f.part, Part::Link("tool"), "{f:?}");
        assert_eq!(f.against, "tool post");
        let t4: f64 = p.segments[..4].iter().map(|s| s.duration_s).sum();
        let tau = (f.time_s - t4) / p.segments[4].duration_s;
        assert!((tau - t_tool).abs() < 0.01, "{tau} vs {t_tool}");
    }
}
