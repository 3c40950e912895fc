//! The machine-readable plan report printed by `windcell plan --json`.
//!
//! Frames (see `docs/geometry.md`): `tangent_point_mm` and `eye_mandrel_mm` are in the mandrel
//! frame (fixed to the mandrel, `z` up the rotation axis); `eye_mm` and `tangent_point_cell_mm`
//! are in the cell frame (the robot base frame: for the IRB 6/2 the rotation axis through
//! `(b, 0)`, for a six-axis arm where `[cell.mandrel]` puts it), at the segment's commanded
//! mandrel angle. `tool_q` is the tool frame's orientation in the cell frame, its `z` the eye's
//! axis toward the mandrel (six-axis arms: along the free fibre).

use serde::Serialize;

use crate::plan::tool::{JobPlan, PlannedPath};

/// One pose of the report.
#[derive(Debug, Clone, Serialize)]
pub struct PoseReport {
    /// Tangent point, mandrel frame, mm.
    pub tangent_point_mm: [f64; 3],
    /// Eye, mandrel frame, mm.
    pub eye_mandrel_mm: [f64; 3],
    /// Eye, cell frame, mm.
    pub eye_mm: [f64; 3],
    /// Tangent point, cell frame, mm.
    pub tangent_point_cell_mm: [f64; 3],
    /// Tool frame orientation, cell frame, `[w, x, y, z]`.
    pub tool_q: [f64; 4],
    /// The mandrel axis angle the robot controller commands (`drive = "robot"`), degrees.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub external_deg: Option<f64>,
    /// Wrist quaternion, scalar first.
    pub wrist_q: [f64; 4],
    /// Commanded mandrel angle, cumulative, degrees.
    pub mandrel_deg: f64,
    /// Eq 3.7 mandrel angle, degrees.
    pub ideal_mandrel_deg: f64,
    /// Motor steps for the segment ending here (0 for the start pose).
    pub steps: i64,
    /// Robot speed, % of base speed (the approach speed for the start pose).
    pub speed_pct: f64,
    /// Joint angles in axis order, degrees: the IRB 6/2's base yaw, shoulder, elbow, wrist pitch
    /// and roll; a six-axis arm's axes 1–6 as its controller counts them.
    pub joints_deg: Vec<f64>,
    /// Fibre entry angle (tow line to the eye's roll axis), degrees.
    pub entry_angle_deg: f64,
    /// The segment's time, s (0 for the start pose).
    pub duration_s: f64,
    /// The robot's least time for the segment at its speed limits, s (0 for the start pose).
    pub robot_time_s: f64,
    /// This segment's mandrel move's maximum velocity, rev/s.
    pub mandrel_max_rps: f64,
    /// Discrete movement: the robot's time set this segment's time and its mandrel move was
    /// slowed to match.
    pub robot_paced: bool,
}

/// One path of the report.
#[derive(Debug, Clone, Serialize)]
pub struct PathReport {
    /// `NAME_<prog>`.
    pub name: String,
    /// Program number.
    pub program: u8,
    /// The start pose (where the mandrel is synchronised).
    pub start: PoseReport,
    /// One entry per segment, each at the segment's end.
    pub segments: Vec<PoseReport>,
    /// Worst |commanded − ideal| mandrel angle, degrees.
    pub max_drift_deg: f64,
    /// Least eye-to-mandrel distance, mm.
    pub min_eye_clearance_mm: f64,
    /// Total motor steps.
    pub total_steps: i64,
    /// The path's time: the sum of the segments' times, s.
    pub mandrel_time_s: f64,
    /// The elbow branch of the whole path (`up` or `down`).
    pub elbow: &'static str,
    /// The configuration kept along the whole path: the IRB 6/2's `elbow up|down`, a six-axis
    /// arm's `front|back / elbow up|down / wrist flip|no flip`.
    pub configuration: String,
    /// A six-axis arm's least distance of the wrist bend from its singularity, degrees.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub least_wrist_margin_deg: Option<f64>,
    /// A six-axis arm's largest joint turn between consecutive poses, degrees.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub largest_joint_step_deg: Option<f64>,
    /// Worst fibre entry angle over the path, degrees.
    pub max_entry_angle_deg: f64,
    /// Least joint angles over the path, degrees (axis order).
    pub joints_min_deg: Vec<f64>,
    /// Greatest joint angles over the path, degrees (axis order).
    pub joints_max_deg: Vec<f64>,
    /// The least distance from any joint to either end of its range over the path, degrees.
    pub min_joint_margin_deg: f64,
    /// The joint with that least margin.
    pub min_joint_margin_joint: &'static str,
    /// Segments (1-based) whose time the robot set (discrete movement).
    pub robot_paced_segments: Vec<usize>,
}

/// A six-axis arm's joints by their axis numbers.
const SIX_AXIS_NAMES: [&str; 6] = ["axis 1", "axis 2", "axis 3", "axis 4", "axis 5", "axis 6"];

/// The whole report.
#[derive(Debug, Clone, Serialize)]
pub struct PlanReport {
    /// The job's paths.
    pub paths: Vec<PathReport>,
}

fn pose(p: &paths::Pose, setup: &paths::Setup, mandrel_max_rps: f64) -> PoseReport {
    let v = |p: &nalgebra::Point3<f64>| [p.x, p.y, p.z];
    let (tool_q, external_deg) = match p.joints {
        paths::ArmJoints::SixAxis {
            tool_q,
            external_rad,
            ..
        } => (tool_q, external_rad.map(f64::to_degrees)),
        paths::ArmJoints::Irb62(_) => (
            p.wrist_q * paths::arm::winding::tool_to_wrist().inverse(),
            None,
        ),
    };
    PoseReport {
        tangent_point_mm: v(&p.tangent_point_mm),
        eye_mandrel_mm: v(&p.eye_mandrel_mm),
        eye_mm: v(&p.eye_mm),
        tangent_point_cell_mm: v(&setup.mandrel_to_cell(p.mandrel_rad, &p.tangent_point_mm)),
        tool_q: paths::wrist::components(&tool_q),
        external_deg,
        wrist_q: paths::wrist::components(&p.wrist_q),
        mandrel_deg: p.mandrel_rad.to_degrees(),
        ideal_mandrel_deg: p.ideal_mandrel_rad.to_degrees(),
        steps: 0,
        speed_pct: crate::plan::tool::APPROACH_SPEED_PCT,
        joints_deg: p.joints.to_degrees(),
        entry_angle_deg: p.entry_angle_rad.to_degrees(),
        duration_s: 0.0,
        robot_time_s: 0.0,
        mandrel_max_rps,
        robot_paced: false,
    }
}

fn path(p: &PlannedPath, arm: &paths::Arm, setup: &paths::Setup, job_max_rps: f64) -> PathReport {
    let plan = &p.plan;
    let poses = || std::iter::once(&plan.start).chain(plan.segments.iter().map(|s| &s.pose));
    let axes = plan.start.joints.to_array().len();
    let mut lo = vec![f64::INFINITY; axes];
    let mut hi = vec![f64::NEG_INFINITY; axes];
    for pose in poses() {
        for (k, a) in pose.joints.to_degrees().into_iter().enumerate() {
            lo[k] = lo[k].min(a);
            hi[k] = hi[k].max(a);
        }
    }
    let (min_joint_margin_deg, min_joint_margin_joint) = match &setup.six_axis {
        Some(six) => (0..6)
            .map(|k| {
                let (min, max) = (
                    six.arm.limits.min_rad[k].to_degrees(),
                    six.arm.limits.max_rad[k].to_degrees(),
                );
                ((lo[k] - min).min(max - hi[k]), SIX_AXIS_NAMES[k])
            })
            .fold(
                (f64::INFINITY, ""),
                |best, m| {
                    if m.0 < best.0 { m } else { best }
                },
            ),
        None => paths::Joint::ALL
            .iter()
            .zip(&arm.joints)
            .enumerate()
            .map(|(k, (joint, limit))| {
                let margin =
                    (lo[k] - limit.min_rad.to_degrees()).min(limit.max_rad.to_degrees() - hi[k]);
                (margin, joint.name())
            })
            .fold(
                (f64::INFINITY, ""),
                |best, m| if m.0 < best.0 { m } else { best },
            ),
    };
    let (elbow, configuration, least_wrist_margin_deg, largest_joint_step_deg) = match plan.arm {
        paths::PathArm::Irb62(e) => {
            let elbow = match e {
                paths::ElbowBranch::Up => "up",
                paths::ElbowBranch::Down => "down",
            };
            (elbow, format!("elbow {elbow}"), None, None)
        }
        paths::PathArm::SixAxis(r) => (
            match r.config.elbow {
                paths::arm::Elbow::Up => "up",
                paths::arm::Elbow::Down => "down",
            },
            r.config.to_string(),
            Some(r.least_wrist_margin_deg),
            Some(r.largest_step_deg),
        ),
    };
    PathReport {
        name: p.name.clone(),
        program: p.program,
        start: pose(&plan.start, setup, job_max_rps),
        segments: plan
            .segments
            .iter()
            .map(|s| PoseReport {
                steps: s.steps,
                speed_pct: s.speed_pct,
                duration_s: s.duration_s,
                robot_time_s: s.robot_time_s,
                robot_paced: s.robot_paced,
                ..pose(&s.pose, setup, s.mandrel.max_rps)
            })
            .collect(),
        max_drift_deg: plan.max_drift_rad.to_degrees(),
        min_eye_clearance_mm: plan.min_eye_clearance_mm,
        total_steps: plan.segments.iter().map(|s| s.steps).sum(),
        mandrel_time_s: plan.segments.iter().map(|s| s.duration_s).sum(),
        elbow,
        configuration,
        least_wrist_margin_deg,
        largest_joint_step_deg,
        max_entry_angle_deg: plan.max_entry_angle_rad.to_degrees(),
        joints_min_deg: lo,
        joints_max_deg: hi,
        min_joint_margin_deg,
        min_joint_margin_joint,
        robot_paced_segments: plan
            .segments
            .iter()
            .enumerate()
            .filter(|(_, s)| s.robot_paced)
            .map(|(k, _)| k + 1)
            .collect(),
    }
}

impl PlanReport {
    /// The report of a planned job.
    pub fn new(job: &sequences::Job, plan: &JobPlan) -> Self {
        let arm = crate::plan::tool::arm(job);
        let (setup, _) = crate::plan::tool::setup(job);
        let job_max_rps = *job.cell.mandrel_speed_rps.get_ref();
        PlanReport {
            paths: plan
                .paths
                .iter()
                .map(|p| path(p, &arm, &setup, job_max_rps))
                .collect(),
        }
    }
}
