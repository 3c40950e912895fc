//! The machine-readable plan report printed by `windcell plan --json`.
//!
//! Frames (see `docs/geometry.md`): `tangent_point_mm` and `eye_mandrel_mm` are in the mandrel
//! frame (fixed to the mandrel, `z` up the rotation axis); `eye_mm` is in the cell frame (robot base
//! at the origin, rotation axis through `(b, 0)`), at the segment's commanded mandrel angle.

use serde::Serialize;

use crate::tool::{JobPlan, PlannedPath};

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
    /// True when the maximum speed capped this segment.
    pub speed_limited: bool,
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
    /// Mandrel time for the path at the mandrel speed, s.
    pub mandrel_time_s: f64,
}

/// The whole report.
#[derive(Debug, Clone, Serialize)]
pub struct PlanReport {
    /// The job's paths.
    pub paths: Vec<PathReport>,
}

fn pose(p: &paths::Pose, steps: i64, speed_pct: f64, speed_limited: bool) -> PoseReport {
    let v = |p: &nalgebra::Point3<f64>| [p.x, p.y, p.z];
    PoseReport {
        tangent_point_mm: v(&p.tangent_point_mm),
        eye_mandrel_mm: v(&p.eye_mandrel_mm),
        eye_mm: v(&p.eye_mm),
        wrist_q: paths::wrist::components(&p.wrist_q),
        mandrel_deg: p.mandrel_rad.to_degrees(),
        ideal_mandrel_deg: p.ideal_mandrel_rad.to_degrees(),
        steps,
        speed_pct,
        speed_limited,
    }
}

fn path(p: &PlannedPath) -> PathReport {
    let plan = &p.plan;
    PathReport {
        name: p.name.clone(),
        program: p.program,
        start: pose(&plan.start, 0, crate::tool::APPROACH_SPEED_PCT, false),
        segments: plan
            .segments
            .iter()
            .map(|s| pose(&s.pose, s.steps, s.speed_pct, s.speed_limited))
            .collect(),
        max_drift_deg: plan.max_drift_rad.to_degrees(),
        min_eye_clearance_mm: plan.min_eye_clearance_mm,
        total_steps: plan.segments.iter().map(|s| s.steps).sum(),
        mandrel_time_s: plan.segments.iter().map(|s| s.duration_s).sum(),
    }
}

impl PlanReport {
    /// The report of a planned job.
    pub fn new(plan: &JobPlan) -> Self {
        PlanReport {
            paths: plan.paths.iter().map(path).collect(),
        }
    }
}
