//! The machine-readable plan report printed by `windcell plan --json`.
//!
//! Frames (see `docs/geometry.md`): `tangent_point_mm` and `eye_mandrel_mm` are in the mandrel
//! frame (fixed to the mandrel, `z` up the rotation axis); `eye_mm` is in the cell frame (robot base
//! at the origin, rotation axis through `(b, 0)`), at the segment's commanded mandrel angle.

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
    /// Joint angles: base yaw, shoulder, elbow, wrist pitch, wrist roll, degrees.
    pub joints_deg: [f64; 5],
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
    /// Worst fibre entry angle over the path, degrees.
    pub max_entry_angle_deg: f64,
    /// Least joint angles over the path, degrees (axis order).
    pub joints_min_deg: [f64; 5],
    /// Greatest joint angles over the path, degrees (axis order).
    pub joints_max_deg: [f64; 5],
    /// The least distance from any joint to either end of its range over the path, degrees.
    pub min_joint_margin_deg: f64,
    /// The joint with that least margin.
    pub min_joint_margin_joint: &'static str,
    /// Segments (1-based) whose time the robot set (discrete movement).
    pub robot_paced_segments: Vec<usize>,
}

/// The whole report.
#[derive(Debug, Clone, Serialize)]
pub struct PlanReport {
    /// The job's paths.
    pub paths: Vec<PathReport>,
}

fn pose(p: &paths::Pose, mandrel_max_rps: f64) -> PoseReport {
    let v = |p: &nalgebra::Point3<f64>| [p.x, p.y, p.z];
    PoseReport {
        tangent_point_mm: v(&p.tangent_point_mm),
        eye_mandrel_mm: v(&p.eye_mandrel_mm),
        eye_mm: v(&p.eye_mm),
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

fn path(p: &PlannedPath, arm: &paths::Arm, job_max_rps: f64) -> PathReport {
    let plan = &p.plan;
    let poses = || std::iter::once(&plan.start).chain(plan.segments.iter().map(|s| &s.pose));
    let mut lo = [f64::INFINITY; 5];
    let mut hi = [f64::NEG_INFINITY; 5];
    for pose in poses() {
        for (k, a) in pose.joints.to_degrees().into_iter().enumerate() {
            lo[k] = lo[k].min(a);
            hi[k] = hi[k].max(a);
        }
    }
    let (min_joint_margin_deg, min_joint_margin_joint) = paths::Joint::ALL
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
        );
    PathReport {
        name: p.name.clone(),
        program: p.program,
        start: pose(&plan.start, job_max_rps),
        segments: plan
            .segments
            .iter()
            .map(|s| PoseReport {
                steps: s.steps,
                speed_pct: s.speed_pct,
                duration_s: s.duration_s,
                robot_time_s: s.robot_time_s,
                robot_paced: s.robot_paced,
                ..pose(&s.pose, s.mandrel.max_rps)
            })
            .collect(),
        max_drift_deg: plan.max_drift_rad.to_degrees(),
        min_eye_clearance_mm: plan.min_eye_clearance_mm,
        total_steps: plan.segments.iter().map(|s| s.steps).sum(),
        mandrel_time_s: plan.segments.iter().map(|s| s.duration_s).sum(),
        elbow: match plan.elbow {
            paths::ElbowBranch::Up => "up",
            paths::ElbowBranch::Down => "down",
        },
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
        let job_max_rps = *job.cell.mandrel_speed_rps.get_ref();
        PlanReport {
            paths: plan
                .paths
                .iter()
                .map(|p| path(p, &arm, job_max_rps))
                .collect(),
        }
    }
}
