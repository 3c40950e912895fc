//! The clearance check of a job before it runs (seed 001 §5.7, Figure 5.9): the payout-eye
//! mechanism, the free fibre and the arm's links against the turning mandrel and the cell's
//! obstacles, over every segment of every path and the moves between them
//! ([`paths::clearance::sweep`]).
//!
//! [`run`] plans and checks a job file; [`check`] checks a plan already made (what `windcell
//! plan` and the gate of `windcell run` call). The report's [`Report::is_clear`] decides: exit
//! code 0 when clear, 3 on a finding.

use std::path::Path;

use nalgebra::Point3;
use paths::clearance::{
    self, DEFAULT_EYE_RADIUS_MM, DEFAULT_SNAG_TOLERANCE_MM, EyeMechanism, Obstacle, Report, Solid,
    TubeSolid,
    sweep::{Cell, SweptArm},
};
use paths::{Arm, ElbowBranch, Tube};
use sequences::job::Job;

use crate::Error;
use crate::plan::tool::{self, JobPlan};

/// The elbow branch the check poses the arm on (the IRB 6/2 winds elbow up, §4.1.1).
pub const ELBOW_BRANCH: ElbowBranch = ElbowBranch::Up;

/// A planned and checked job.
#[derive(Debug)]
pub struct Checked {
    /// The plan.
    pub plan: JobPlan,
    /// What the check found.
    pub report: Report,
    /// The analytic tube of the job (its spine and radius; drawn as the mandrel's sections).
    pub tube: Tube,
    /// The eye mechanism checked.
    pub eye: EyeMechanism,
    /// The obstacles checked.
    pub obstacles: Vec<Obstacle>,
    /// The arm checked.
    pub arm: Arm,
    /// Where the robot and the mandrel stand.
    pub setup: paths::Setup,
}

/// The eye mechanism, snag tolerance, obstacles and home position a job describes, with the
/// documented defaults (`docs/file-formats.md`).
pub fn cell_of(job: &Job) -> (EyeMechanism, f64, Vec<Obstacle>, Option<Point3<f64>>) {
    let c = &job.cell;
    let eye = c.eye.as_ref();
    let mechanism = EyeMechanism {
        length_mm: eye
            .and_then(|e| e.length_mm.as_ref())
            .map_or(*c.eye_mechanism_length_mm.get_ref(), |l| *l.get_ref()),
        radius_mm: eye
            .and_then(|e| e.radius_mm.as_ref())
            .map_or(DEFAULT_EYE_RADIUS_MM, |r| *r.get_ref()),
    };
    let snag = eye
        .and_then(|e| e.snag_tolerance_mm.as_ref())
        .map_or(DEFAULT_SNAG_TOLERANCE_MM, |t| *t.get_ref());
    let home = eye
        .and_then(|e| e.home_mm.as_ref())
        .map(|h| Point3::from(*h.get_ref()));
    let obstacles = c
        .obstacles
        .iter()
        .map(|o| Obstacle {
            name: o.name.get_ref().clone(),
            min_mm: Point3::from(*o.min_mm.get_ref()),
            max_mm: Point3::from(*o.max_mm.get_ref()),
        })
        .collect();
    (mechanism, snag, obstacles, home)
}

/// The mandrel solid of a job: the analytic tube, or the mesh the plan was traced on (a mesh
/// mandrel, built by [`tool::plan`]).
pub fn solid(plan: &JobPlan, tube: &Tube) -> std::sync::Arc<dyn Solid> {
    match &plan.mesh_solid {
        Some(mesh) => mesh.clone(),
        None => std::sync::Arc::new(TubeSolid::new(tube)),
    }
}

/// Plans `job` (read from `file`, whose text is `text`) and checks the plan.
pub fn run(job: &Job, text: &str, file: &Path) -> Result<Checked, Error> {
    let plan = tool::plan(job, text, file)?;
    check(job, text, file, plan)
}

/// Checks a plan of `job`. An eye point inside the mandrel is bad input (the job must change),
/// located at the job's `offset_mm`; so is a pose the arm cannot take.
pub fn check(job: &Job, text: &str, file: &Path, plan: JobPlan) -> Result<Checked, Error> {
    let located = |source: paths::Error, span: std::ops::Range<usize>| {
        let (line, column) = sequences::error::line_column(text, span.start);
        Error::Plan {
            file: file.to_path_buf(),
            line,
            column,
            source,
        }
    };
    // An eye point inside the mandrel was refused by the plan (paths::plan's guard).
    let tube = tool::mandrel_in(job, text, file)?;
    let solid = solid(&plan, &tube);
    let (setup, speeds) = tool::setup(job);
    let (eye, snag_tolerance_mm, obstacles, home_mm) = cell_of(job);
    let arm = tool::arm(job);
    let cell = Cell {
        setup: &setup,
        eye,
        snag_tolerance_mm,
        obstacles: &obstacles,
        home_mm,
        approach_speed_mm_s: speeds.base_speed_mm_s * tool::APPROACH_SPEED_PCT / 100.0,
        arm: Some(match &setup.six_axis {
            Some(six) => SweptArm::SixAxis(&six.arm),
            None => SweptArm::Irb62(&arm, ELBOW_BRANCH),
        }),
    };
    let plans: Vec<&paths::PathPlan> = plan.paths.iter().map(|p| &p.plan).collect();
    let report = clearance::sweep(&cell, solid.as_ref(), &plans)
        .map_err(|e| located(e, job.cell.robot_distance_mm.span()))?;
    Ok(Checked {
        plan,
        report,
        tube,
        eye,
        obstacles,
        arm,
        setup,
    })
}

impl Checked {
    /// A cell-frame point in the mandrel frame with the mandrel at `phi` rad: the check's frames
    /// (the IRB 6/2's nominal cell, the rotation axis through `(b, 0, h)`; a six-axis cell's
    /// `[cell.mandrel]` axis).
    pub fn to_mandrel(&self, p: &Point3<f64>, phi: f64) -> Point3<f64> {
        match &self.setup.six_axis {
            Some(six) => six.axis.frame(phi).inverse_transform_point(p),
            None => {
                let s = &self.setup;
                let w = p - nalgebra::Vector3::new(s.robot_distance_mm, 0.0, s.mandrel_height_mm);
                let (sn, cs) = phi.sin_cos();
                Point3::new(cs * w.x + sn * w.y, -sn * w.x + cs * w.y, w.z)
            }
        }
    }

    /// A cell-frame direction in the mandrel frame with the mandrel at `phi` rad.
    pub fn direction_to_mandrel(
        &self,
        v: &nalgebra::Vector3<f64>,
        phi: f64,
    ) -> nalgebra::Vector3<f64> {
        self.to_mandrel(&Point3::from(*v), phi) - self.to_mandrel(&Point3::origin(), phi)
    }

    /// The arm's links that the check tests, cell frame, with the eye at `eye_mm` and the tool
    /// axis `axis` (eye toward the mandrel): the IRB 6/2's pedestal, upper arm, forearm and wrist
    /// from its inverse kinematics (elbow up, the roll axis in the arm plane); a six-axis arm's
    /// seven capsules from `joints` (none without them). Empty where the arm cannot take the pose.
    pub fn links_at(
        &self,
        eye_mm: &Point3<f64>,
        axis: &nalgebra::Vector3<f64>,
        joints: Option<&paths::arm::Joints6>,
    ) -> Vec<paths::Capsule> {
        if let Some(six) = &self.setup.six_axis {
            return joints.map_or_else(Vec::new, |q| six.arm.links(q).to_vec());
        }
        if eye_mm.x.hypot(eye_mm.y) <= 1e-9 {
            return Vec::new();
        }
        match clearance::sweep::irb_joints_at(&self.arm, ELBOW_BRANCH, eye_mm, axis) {
            Ok(j) => self.arm.links(&j).iter().take(4).copied().collect(),
            Err(_) => Vec::new(),
        }
    }
}

/// One line: clear with the least clearances, or the number of findings and the first.
pub fn summary(checked: &Checked) -> String {
    let r = &checked.report;
    let rows = r.paths.iter().flatten();
    let least = |f: &dyn Fn(&clearance::SegmentClearance) -> Option<f64>| {
        rows.clone()
            .filter_map(f)
            .filter(|v| v.is_finite())
            .fold(f64::INFINITY, f64::min)
    };
    let eye = least(&|s| Some(s.eye_mm));
    let tow = least(&|s| s.tow_mm);
    let arm = least(&|s| s.arm_mm);
    let segments: usize = r.paths.iter().map(|p| p.len() - 1).sum();
    let fmt = clearance_shown;
    match r.findings.first() {
        None => format!(
            "check: clear over {} paths, {segments} segments: eye ≥ {}, free fibre ≥ {}, arm ≥ {}",
            r.paths.len(),
            fmt(eye),
            fmt(tow),
            fmt(arm)
        ),
        Some(f) => format!(
            "check: {} finding{}; first: {}",
            r.findings.len(),
            if r.findings.len() == 1 { "" } else { "s" },
            finding_line(checked, f)
        ),
    }
}

/// A least clearance for the summary line, mm to three decimals; one that rounds to zero reads
/// `0.000`, not `-0.000` (a free fibre touching the mandrel at its contact point, within the
/// solver's 1e-6 mm); none (no such segment) reads `—`.
fn clearance_shown(v: f64) -> String {
    if v.is_finite() {
        let shown = (v * 1000.0).round() / 1000.0;
        format!("{:.3} mm", if shown == 0.0 { 0.0 } else { shown })
    } else {
        "—".to_string()
    }
}

/// One finding in words: path, segment, time, clearance, what hit what.
pub fn finding_line(checked: &Checked, f: &clearance::Finding) -> String {
    let program = checked
        .plan
        .paths
        .get(f.path - 1)
        .map_or(String::new(), |p| format!(" ({})", p.name));
    let segment = if f.segment == 0 {
        "segment 0 (approach)".to_string()
    } else {
        format!("segment {}", f.segment)
    };
    let verb = if f.part == clearance::Part::FreeFibre {
        "snags inside"
    } else {
        "hits"
    };
    format!(
        "path {}{program} {segment} at {:.3} s: {} {verb} {} ({:.3} mm)",
        f.path,
        f.time_s,
        f.part.name(),
        f.against,
        f.clearance_mm
    )
}

/// The `--json` document: every segment of every path (numbered from 1; 0 is the approach or
/// link move into the path) with its least eye, free-fibre and arm clearances in mm, then the
/// findings.
pub fn json(checked: &Checked) -> serde_json::Value {
    use serde_json::json;
    let num = |v: Option<f64>| match v {
        Some(v) if v.is_finite() => json!(v),
        _ => serde_json::Value::Null,
    };
    let paths: Vec<serde_json::Value> = checked
        .report
        .paths
        .iter()
        .zip(&checked.plan.paths)
        .enumerate()
        .map(|(i, (rows, planned))| {
            let segments: Vec<serde_json::Value> = rows
                .iter()
                .map(|s| {
                    json!({
                        "segment": s.segment,
                        "start_s": s.start_s,
                        "duration_s": s.duration_s,
                        "eye_clearance_mm": num(Some(s.eye_mm)),
                        "tow_clearance_mm": num(s.tow_mm),
                        "arm_clearance_mm": num(s.arm_mm),
                    })
                })
                .collect();
            json!({
                "path": i + 1,
                "name": planned.name,
                "program": planned.program,
                "segments": segments,
            })
        })
        .collect();
    let findings: Vec<serde_json::Value> = checked
        .report
        .findings
        .iter()
        .map(|f| {
            json!({
                "path": f.path,
                "segment": f.segment,
                "time_s": f.time_s,
                "clearance_mm": f.clearance_mm,
                "part": f.part.name(),
                "against": f.against,
            })
        })
        .collect();
    json!({
        "clear": checked.report.is_clear(),
        "summary": summary(checked),
        "eye": { "length_mm": checked.eye.length_mm, "radius_mm": checked.eye.radius_mm },
        "paths": paths,
        "findings": findings,
    })
}

#[cfg(test)]
mod tests {
    /// The summary's clearances: rounded to the micrometre, a tiny negative shown as zero, a
    /// real one kept with its sign.
    #[test]
    fn clearances_read_to_the_micrometre_without_a_negative_zero() {
        assert_eq!(super::clearance_shown(-0.0004), "0.000 mm");
        assert_eq!(super::clearance_shown(-1e-9), "0.000 mm");
        assert_eq!(super::clearance_shown(0.0016), "0.002 mm");
        assert_eq!(super::clearance_shown(-0.0016), "-0.002 mm");
        assert_eq!(super::clearance_shown(17.2394), "17.239 mm");
        assert_eq!(super::clearance_shown(f64::INFINITY), "—");
    }
}
