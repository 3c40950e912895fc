//! `windcell verify`: reads a six-axis job's robot programs back with windcell's own readers
//! (`sequences::program`), checks every target against the plan and the arm, and runs the program
//! on a model of the cell to check clearances and predict where the fibre lands
//! (`docs/robot-programs.md`, "What verify proves").
//!
//! # What is checked, per path (each finding names the program's file and line)
//! - the program's **targets in order**: one per pose of the plan (a missing or extra move is a
//!   finding), each at the plan's tool centre point within 0.01 mm (URScript 0.001 mm) and its
//!   orientation within 0.01°;
//! - the **configuration data** a target states (ABB `confdata`, KUKA `S`/`T`, FANUC `CONFIG`)
//!   against the joints the arm takes there: the target is solved on the configuration the data
//!   names, the joints must exist, lie within the arm's ranges, and give back the same data (turn
//!   numbers included); every target of a path on **one configuration**;
//! - the **external axis** (coupled mandrel) against the plan's mandrel angle within 0.01°;
//! - the **speeds**: the TCP speed at most the job's `max_speed_mm_s`, no joint faster than its
//!   limit over a move.
//!
//! # The simulated run
//! An interpreter walks the program's steps on one virtual clock: a move takes its programmed
//! time (or its travel at its speed), the eye on the straight line between targets; a decoupled
//! mandrel's segment starts at the start output and turns on the indexer's trapezoid
//! ([`paths::MandrelProfile`]), a wait for the in-position input lasts until that move ends; a
//! coupled mandrel turns with the move to the target's external-axis angle. The poses and times it
//! finds replace the plan's; the collision and snag check ([`paths::clearance::sweep`]) and the
//! placement model of `predict` ([`crate::predict`]) run on them.
//!
//! What only the real controller can show: its path blending inside zones, its servo lag, its
//! own joint-limit and singularity handling, the I/O wiring and the positioner's calibration.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use nalgebra::{Point3, UnitQuaternion};
use paths::Tube;
use paths::arm::{Config, MandrelAxis, MandrelDrive, SixAxisArm};
use sequences::Job;
use sequences::program::{self, ConfigData, Format, ReadProgram, ReadTarget, Step};

use crate::Error;
use crate::plan::check::{self, Checked};
use crate::plan::tool::{self, JobPlan, PlannedPath};
use crate::predict::{self, PathPrediction};

/// Largest distance of a target from the plan's, mm (URScript: [`URSCRIPT_TOLERANCE_MM`]).
pub const TOLERANCE_MM: f64 = 0.01;
/// URScript's: metres with 7 decimals.
pub const URSCRIPT_TOLERANCE_MM: f64 = 0.001;
/// Largest turn of a target's orientation, or of the external axis, from the plan's, degrees.
pub const TOLERANCE_DEG: f64 = 0.01;
/// The most bytes of program text `verify` reads from a folder.
pub const MAX_FOLDER_BYTES: u64 = 64 << 20;

/// One thing the programs do not do as planned.
#[derive(Debug, Clone, PartialEq)]
pub struct Finding {
    /// The program file.
    pub file: String,
    /// Its line.
    pub line: usize,
    /// What is wrong.
    pub message: String,
}

impl std::fmt::Display for Finding {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}:{}: {}", self.file, self.line, self.message)
    }
}

/// One path's verification.
#[derive(Debug, Clone)]
pub struct PathVerified {
    /// The path's name.
    pub name: String,
    /// Its main program file.
    pub main_file: String,
    /// Targets read.
    pub targets: usize,
    /// The simulated run's prediction (`None` when the program's targets could not be run).
    pub prediction: Option<PathPrediction>,
    /// `predict`'s prediction of the planned path, for comparison.
    pub planned: PathPrediction,
}

/// What `verify` found.
#[derive(Debug, Clone)]
pub struct Verified {
    /// The format read.
    pub format: Format,
    /// Per path.
    pub paths: Vec<PathVerified>,
    /// Every finding, per path in order.
    pub findings: Vec<Finding>,
    /// The check of the simulated run's motion (one line).
    pub check_line: String,
}

/// The program files of `dir`, all of one format: `(format, [(name, text)])`, sorted by name.
fn program_files(dir: &Path) -> Result<(Format, Vec<(String, String)>), Error> {
    let missing = |reason: String| Error::OutputPath {
        path: dir.to_path_buf(),
        reason,
    };
    let entries = std::fs::read_dir(dir).map_err(|e| missing(format!("cannot read: {e}")))?;
    let formats = [Format::Rapid, Format::Krl, Format::Fanuc, Format::UrScript];
    let mut found: Vec<(Format, PathBuf)> = Vec::new();
    for e in entries.flatten() {
        let path = e.path();
        let ext = path
            .extension()
            .and_then(|x| x.to_str())
            .map(str::to_ascii_lowercase);
        if let Some(f) = formats
            .iter()
            .find(|f| ext.as_deref().is_some_and(|x| f.extensions().contains(&x)))
        {
            found.push((*f, path));
        }
    }
    found.sort_by(|a, b| a.1.cmp(&b.1));
    let Some(format) = found.first().map(|f| f.0) else {
        return Err(missing(
            "holds no robot program (.mod, .src/.dat, .ls, .script)".into(),
        ));
    };
    if let Some(other) = found.iter().find(|f| f.0 != format) {
        return Err(missing(format!(
            "holds programs of two formats ({} and {}: {})",
            format.name(),
            other.0.name(),
            other.1.display()
        )));
    }
    let mut total = 0u64;
    let mut files = Vec::with_capacity(found.len());
    for (_, path) in found {
        let text = sequences::source::read_text(&path, MAX_FOLDER_BYTES)?;
        total += text.len() as u64;
        if total > MAX_FOLDER_BYTES {
            return Err(missing(format!(
                "holds more than {} MB of programs",
                MAX_FOLDER_BYTES >> 20
            )));
        }
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        files.push((name, text));
    }
    Ok((format, files))
}

/// What programs are verified against: a job's plan and what follows from it (its mandrel,
/// setup and speeds, and `predict`'s prediction of each planned path once it is asked for). Made
/// once per job, it serves every folder of programs posted from the job (one per format):
/// [`verify`] makes one and verifies one folder; [`verify_with`] verifies a folder against one
/// already made.
#[derive(Debug)]
pub struct Reference {
    plan: JobPlan,
    tube: Tube,
    setup: paths::Setup,
    speeds: paths::Speeds,
    axis: MandrelAxis,
    opt: predict::Options,
    /// `predict`'s prediction of each planned path, made when first asked for.
    planned: Vec<OnceLock<PathPrediction>>,
}

impl Reference {
    /// Plans `job` (read from `file`, text `text`).
    pub fn new(job: &Job, text: &str, file: &Path, opt: &predict::Options) -> Result<Self, Error> {
        let plan = tool::plan(job, text, file)?;
        Self::of_plan(job, text, file, plan, opt)
    }

    /// The reference of a plan of `job` already made ([`tool::plan`], as `post` makes it).
    pub fn of_plan(
        job: &Job,
        text: &str,
        file: &Path,
        plan: JobPlan,
        opt: &predict::Options,
    ) -> Result<Self, Error> {
        let (setup, speeds) = tool::setup(job);
        let tube = tool::mandrel_in(job, text, file)?;
        Ok(Reference {
            planned: plan.paths.iter().map(|_| OnceLock::new()).collect(),
            plan,
            tube,
            setup,
            speeds,
            axis: job.mandrel_axis(),
            opt: opt.clone(),
        })
    }

    /// The plan.
    pub fn plan(&self) -> &JobPlan {
        &self.plan
    }

    fn coupled(&self) -> bool {
        self.axis.drive == MandrelDrive::Robot
    }

    /// `predict`'s prediction of a path of the plan, or of a simulated run of one.
    fn predict(&self, path: &PlannedPath) -> Result<PathPrediction, Error> {
        predict::six_axis::predict_path(
            path,
            &self.tube,
            &self.setup,
            &self.speeds,
            self.coupled(),
            &self.opt,
        )
    }

    /// `predict`'s prediction of the plan's path `i`, made once.
    fn planned(&self, i: usize) -> Result<PathPrediction, Error> {
        if let Some(p) = self.planned[i].get() {
            return Ok(p.clone());
        }
        let p = self.predict(&self.plan.paths[i])?;
        Ok(self.planned[i].get_or_init(|| p).clone())
    }
}

/// Verifies the programs in `dir` against `job` (read from `file`, text `text`).
pub fn verify(
    job: &Job,
    text: &str,
    file: &Path,
    dir: &Path,
    opt: &predict::Options,
) -> Result<Verified, Error> {
    let (format, files) = program_files(dir)?;
    let arm = crate::plan::post::six_axis_arm(job, text, file, format)?;
    let reference = Reference::new(job, text, file, opt)?;
    verify_files(job, text, file, dir, &reference, &arm, format, &files)
}

/// Verifies the programs in `dir` against `reference`, made from `job` (read from `file`, text
/// `text`): the same as [`verify`] without planning the job again.
pub fn verify_with(
    job: &Job,
    text: &str,
    file: &Path,
    dir: &Path,
    reference: &Reference,
) -> Result<Verified, Error> {
    let (format, files) = program_files(dir)?;
    let arm = crate::plan::post::six_axis_arm(job, text, file, format)?;
    verify_files(job, text, file, dir, reference, &arm, format, &files)
}

/// One path's program, read and checked: its report without the predictions, its findings and
/// its simulated run (or the finding that stopped it).
struct PathRead {
    main_file: String,
    targets: usize,
    found: Vec<Finding>,
    run: Result<PlannedPath, Finding>,
}

/// Reads path `path`'s programs of `files` (in `dir`), checks their targets and runs them.
fn read_path(
    path: &PlannedPath,
    reference: &Reference,
    arm: &SixAxisArm,
    format: Format,
    files: &[(String, String)],
    (file, dir): (&Path, &Path),
) -> Result<PathRead, Error> {
    let main = program::main_file_name(format, &path.name);
    if !files.iter().any(|(n, _)| *n == main) {
        return Err(Error::OutputPath {
            path: dir.to_path_buf(),
            reason: format!(
                "has no {main}, the program of path {} of {}: programs of another job?",
                path.name,
                file.display()
            ),
        });
    }
    // The path's own set: its main program and its parts (`NAME_Pnn`).
    let id = program::identifier(format, &path.name);
    let own: Vec<(String, String)> = files
        .iter()
        .filter(|(n, _)| {
            let stem = n.rsplit_once('.').map_or(n.as_str(), |(s, _)| s);
            stem == id || stem.strip_prefix(&id).is_some_and(|r| r.starts_with("_P"))
        })
        .cloned()
        .collect();
    let read = program::read(format, &own, Some(&main))
        .map_err(|e| Error::File(e.in_file(dir.join(&main))))?;
    let mut found = Vec::new();
    let context = TargetCheck {
        path,
        arm,
        axis: &reference.axis,
        format,
        speeds: &reference.speeds,
    };
    check_targets(&read, &context, &mut found);
    let run = run_program(
        &read,
        path,
        arm,
        &reference.axis,
        reference.setup.gearing.steps_per_mandrel_rev(),
    );
    Ok(PathRead {
        main_file: main,
        targets: read.targets().count(),
        found,
        run,
    })
}

/// The work of [`verify`] on the program files read from `dir`. The paths' predictions and the
/// check of the simulated run are made on threads of their own; what is reported (and the first
/// error returned) is as if each path were verified in turn and the run checked after them.
#[allow(clippy::too_many_arguments)]
fn verify_files(
    job: &Job,
    text: &str,
    file: &Path,
    dir: &Path,
    reference: &Reference,
    arm: &SixAxisArm,
    format: Format,
    files: &[(String, String)],
) -> Result<Verified, Error> {
    let plan = &reference.plan;
    let mut reads = Vec::with_capacity(plan.paths.len());
    for path in &plan.paths {
        let read = read_path(path, reference, arm, format, files, (file, dir));
        let stop = read.is_err();
        reads.push(read);
        if stop {
            break;
        }
    }
    let runs: Vec<&PlannedPath> = reads
        .iter()
        .filter_map(|r| r.as_ref().ok().and_then(|r| r.run.as_ref().ok()))
        .collect();
    let all_ran = runs.len() == plan.paths.len();
    type Predicted = (
        Result<PathPrediction, Error>,
        Option<Result<PathPrediction, Error>>,
    );
    let (predicted, ran): (Vec<Predicted>, Option<Result<Checked, Error>>) =
        std::thread::scope(|scope| {
            // The collision and snag check of the simulated run's motion.
            let checked = all_ran.then(|| {
                let runs = crate::plan::tool::JobPlan {
                    paths: runs.iter().map(|r| (*r).clone()).collect(),
                    mesh_solid: plan.mesh_solid.clone(),
                };
                scope.spawn(move || check::check(job, text, file, runs))
            });
            let handles: Vec<_> = reads
                .iter()
                .enumerate()
                .filter_map(|(i, r)| r.as_ref().ok().map(|r| (i, r)))
                .map(|(i, r)| {
                    let run = r.run.as_ref().ok();
                    scope.spawn(move || {
                        let planned = reference.planned(i);
                        let ran = run.map(|run| reference.predict(run));
                        (planned, ran)
                    })
                })
                .collect();
            let predicted = handles.into_iter().map(joined).collect();
            (predicted, checked.map(joined))
        });
    let mut findings = Vec::new();
    let mut paths_out = Vec::new();
    let mut predicted = predicted.into_iter();
    for (path, read) in plan.paths.iter().zip(reads) {
        let read = read?;
        let Some((planned, ran)) = predicted.next() else {
            break;
        };
        let planned = planned?;
        let mut found = read.found;
        let prediction = match (ran, read.run) {
            (Some(ran), _) => Some(ran?),
            (None, Err(f)) => {
                found.push(f);
                None
            }
            (None, Ok(_)) => None,
        };
        paths_out.push(PathVerified {
            name: path.name.clone(),
            main_file: read.main_file,
            targets: read.targets,
            prediction,
            planned,
        });
        findings.extend(found);
    }
    let check_line = match ran {
        Some(ran) => {
            let ran = ran?;
            for f in &ran.report.findings {
                let p = &paths_out[f.path - 1];
                findings.push(Finding {
                    file: p.main_file.clone(),
                    line: 1,
                    message: format!("the simulated run: {}", check::finding_line(&ran, f)),
                });
            }
            check::summary(&ran)
        }
        None => "check: not run (a program's targets could not be run)".to_string(),
    };
    Ok(Verified {
        format,
        paths: paths_out,
        findings,
        check_line,
    })
}

/// The result of a scoped thread; its panic goes on in the caller.
fn joined<T>(handle: std::thread::ScopedJoinHandle<'_, T>) -> T {
    handle
        .join()
        .unwrap_or_else(|panic| std::panic::resume_unwind(panic))
}

/// The tool frame of a read target in the robot base frame and the mandrel angle it implies
/// (coupled: its external axis; decoupled: the plan's, `plan_rad`).
fn base_pose(
    t: &ReadTarget,
    axis: &MandrelAxis,
    plan_rad: f64,
) -> (Point3<f64>, UnitQuaternion<f64>, f64) {
    let p = Point3::from(t.position_mm);
    let [w, x, y, z] = t.orientation;
    let q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(w, x, y, z));
    match (axis.drive, t.external_deg) {
        (MandrelDrive::Robot, Some(e)) => {
            let phi = e.to_radians();
            let frame = axis.frame(phi);
            (frame * p, frame.rotation * q, phi)
        }
        _ => (p, q, plan_rad),
    }
}

/// The plan's tool frame at a pose, base frame.
fn planned_tool(pose: &paths::Pose) -> Option<(Point3<f64>, UnitQuaternion<f64>)> {
    match pose.joints {
        paths::ArmJoints::SixAxis { tool_q, .. } => Some((pose.eye_mm, tool_q)),
        paths::ArmJoints::Irb62(_) => None,
    }
}

/// What the targets of one path's program are checked against.
struct TargetCheck<'a> {
    path: &'a PlannedPath,
    arm: &'a SixAxisArm,
    axis: &'a MandrelAxis,
    format: Format,
    speeds: &'a paths::Speeds,
}

impl TargetCheck<'_> {
    /// The largest distance of a target from the plan's, mm.
    fn tolerance_mm(&self) -> f64 {
        if self.format == Format::UrScript {
            URSCRIPT_TOLERANCE_MM
        } else {
            TOLERANCE_MM
        }
    }
}

/// A finding at a read target.
fn finding(t: &ReadTarget, message: String) -> Finding {
    Finding {
        file: t.file.clone(),
        line: t.line,
        message,
    }
}

/// Compares each read target with the plan's pose, its configuration data with its joints.
fn check_targets(read: &ReadProgram, c: &TargetCheck<'_>, out: &mut Vec<Finding>) {
    let path = c.path;
    let poses: Vec<&paths::Pose> = std::iter::once(&path.plan.start)
        .chain(path.plan.segments.iter().map(|s| &s.pose))
        .collect();
    let targets: Vec<&ReadTarget> = read.targets().collect();
    let mut path_config: Option<Config> = None;
    let mut previous: Option<(paths::arm::Joints6, &ReadTarget)> = None;
    for (k, t) in targets.iter().enumerate() {
        let Some(pose) = poses.get(k) else {
            out.push(finding(
                t,
                format!(
                    "target {} is one more than the plan's {} poses of {}",
                    k + 1,
                    poses.len(),
                    path.name
                ),
            ));
            break;
        };
        let (eye, q, _) = base_pose(t, c.axis, pose.mandrel_rad);
        let Some(planned) = planned_tool(pose) else {
            return;
        };
        if let Some(message) = pose_mismatch(c, k, (eye, q), planned, poses.get(k + 1)) {
            out.push(finding(t, message));
            return;
        }
        if c.axis.drive == MandrelDrive::Robot {
            check_external_axis(k, t, pose, out);
        }
        let Some(joints) = check_joints(c, k, t, pose, (eye, q), &mut path_config, out) else {
            continue;
        };
        check_speeds(c, k, t, &joints, previous, out);
        previous = Some((joints, t));
    }
    if targets.len() < poses.len() {
        let (file, line) = targets
            .last()
            .map_or((read.main_file.clone(), 1), |t| (t.file.clone(), t.line));
        out.push(Finding {
            file,
            line,
            message: format!(
                "{} targets of the plan's {} poses of {}: the last {} are missing",
                targets.len(),
                poses.len(),
                path.name,
                poses.len() - targets.len()
            ),
        });
    }
}

/// The finding of target `k` (tool frame `at`, base frame) farther from the plan's pose
/// (`planned`) than the tolerances: a missing move when it is the plan's next pose (`next`).
fn pose_mismatch(
    c: &TargetCheck<'_>,
    k: usize,
    (eye, q): (Point3<f64>, UnitQuaternion<f64>),
    (plan_eye, plan_q): (Point3<f64>, UnitQuaternion<f64>),
    next: Option<&&paths::Pose>,
) -> Option<String> {
    let tolerance_mm = c.tolerance_mm();
    let off_mm = (eye - plan_eye).norm();
    let off_deg = q.angle_to(&plan_q).to_degrees();
    if off_mm <= tolerance_mm && off_deg <= TOLERANCE_DEG {
        return None;
    }
    // A missing move: this target is the plan's next pose.
    let next = next.and_then(|p| planned_tool(p));
    Some(match next {
        Some((e, nq))
            if (eye - e).norm() <= tolerance_mm
                && q.angle_to(&nq).to_degrees() <= TOLERANCE_DEG =>
        {
            format!(
                "target {} is the plan's pose {}: pose {} (segment {}) of {} is missing",
                k + 1,
                k + 2,
                k + 1,
                k,
                c.path.name
            )
        }
        _ => format!(
            "target {} lies {} mm and {}° from the plan's pose {} of {} (at most {} mm and {}°)",
            k + 1,
            shown(off_mm),
            shown(off_deg),
            k + 1,
            c.path.name,
            tolerance_mm,
            TOLERANCE_DEG
        ),
    })
}

/// Target `k`'s external axis (a coupled mandrel) against the plan's mandrel angle.
fn check_external_axis(k: usize, t: &ReadTarget, pose: &paths::Pose, out: &mut Vec<Finding>) {
    match t.external_deg {
        None => out.push(finding(
            t,
            format!("target {} has no external axis (the mandrel)", k + 1),
        )),
        Some(e) => {
            let d = (e - pose.mandrel_rad.to_degrees()).abs();
            if d > TOLERANCE_DEG {
                out.push(finding(
                    t,
                    format!(
                        "target {}: the external axis {}° is {}° from the plan's mandrel angle",
                        k + 1,
                        shown(e),
                        shown(d)
                    ),
                ));
            }
        }
    }
}

/// The joints the controller takes at target `k` (tool frame `at`, base frame): the
/// configuration the data names, or (URScript, which states none) the path's, one per path
/// (`path_config`); their ranges and the configuration data they give back. `None` where there
/// are none to take.
fn check_joints(
    c: &TargetCheck<'_>,
    k: usize,
    t: &ReadTarget,
    pose: &paths::Pose,
    (eye, q): (Point3<f64>, UnitQuaternion<f64>),
    path_config: &mut Option<Config>,
    out: &mut Vec<Finding>,
) -> Option<paths::arm::Joints6> {
    let arm = c.arm;
    let config = t.config.arm_config(arm).or(match pose.joints {
        paths::ArmJoints::SixAxis { joints, .. } => Some(arm.kind.config_of(&joints)),
        paths::ArmJoints::Irb62(_) => None,
    })?;
    if let Some(previous) = *path_config
        && previous != config
    {
        out.push(finding(
            t,
            format!(
                "target {} changes the configuration from {previous} to {config} (one per path)",
                k + 1
            ),
        ));
    }
    path_config.get_or_insert(config);
    let joints = match paths::arm::winding::joints_for_tool(arm, &eye, &q, config) {
        Ok(j) => j,
        Err(fault) => {
            out.push(finding(
                t,
                format!("target {}: the arm cannot take it: {fault}", k + 1),
            ));
            return None;
        }
    };
    // The controller's joints: the plan's, where the solution is the same pose (the turn
    // numbers pick among equal angles 360° apart).
    let joints = match pose.joints {
        paths::ArmJoints::SixAxis {
            joints: planned, ..
        } => std::array::from_fn(|i| unwrap_near(joints[i], planned[i])),
        paths::ArmJoints::Irb62(_) => joints,
    };
    for (i, q) in joints.iter().enumerate() {
        let (lo, hi) = (arm.limits.min_rad[i], arm.limits.max_rad[i]);
        if !(lo..=hi).contains(q) {
            out.push(finding(
                t,
                format!(
                    "target {}: axis {} at {}° is outside its range {}..{}°",
                    k + 1,
                    i + 1,
                    shown(q.to_degrees()),
                    shown(lo.to_degrees()),
                    shown(hi.to_degrees())
                ),
            ));
        }
    }
    let expected = ConfigData::of(c.format, arm, &joints.map(f64::to_degrees));
    if !matches!(t.config, ConfigData::None) && t.config != expected {
        out.push(finding(
            t,
            format!(
                "target {}: configuration data {:?} do not match the joints (expected {:?})",
                k + 1,
                t.config,
                expected
            ),
        ));
    }
    Some(joints)
}

/// Target `k`'s TCP speed against the controller's, and its joints' rates from the previous
/// target's (`previous`) against their limits.
fn check_speeds(
    c: &TargetCheck<'_>,
    k: usize,
    t: &ReadTarget,
    joints: &paths::arm::Joints6,
    previous: Option<(paths::arm::Joints6, &ReadTarget)>,
    out: &mut Vec<Finding>,
) {
    let max_speed_mm_s = c.speeds.max_speed_mm_s;
    if let Some(v) = t.speed_mm_s
        && v > max_speed_mm_s * (1.0 + 1e-9)
    {
        out.push(finding(
            t,
            format!(
                "target {}: TCP speed {} mm/s above the controller's {} mm/s",
                k + 1,
                shown(v),
                shown(max_speed_mm_s)
            ),
        ));
    }
    let (Some((prev, from)), Some(limit)) = (previous, c.arm.limits.speed_rad_s) else {
        return;
    };
    let Some(time) = move_time_s(t, Some(from)).filter(|t| *t > 0.0) else {
        return;
    };
    for i in 0..6 {
        let rate = (joints[i] - prev[i]).abs() / time;
        if rate > limit[i] * (1.0 + 1e-9) {
            out.push(finding(
                t,
                format!(
                    "target {}: axis {} turns at {}°/s, above its {}°/s",
                    k + 1,
                    i + 1,
                    shown(rate.to_degrees()),
                    shown(limit[i].to_degrees())
                ),
            ));
        }
    }
}

/// The angle `a` moved by whole turns to lie within half a turn of `near`.
fn unwrap_near(a: f64, near: f64) -> f64 {
    let tau = std::f64::consts::TAU;
    a + tau * ((near - a) / tau).round()
}

/// A move's time: its programmed time, else its travel at its speed.
fn move_time_s(t: &ReadTarget, from: Option<&ReadTarget>) -> Option<f64> {
    if let Some(d) = t.duration_s {
        return Some(d);
    }
    let from = from?;
    let travel: f64 = (0..3)
        .map(|i| (t.position_mm[i] - from.position_mm[i]).powi(2))
        .sum::<f64>()
        .sqrt();
    t.speed_mm_s.filter(|v| *v > 0.0).map(|v| travel / v)
}

/// The simulated run: the interpreter of the module documentation. Returns the path as the
/// program winds it: the plan's path with the program's poses (the joints the arm takes there on
/// the plan's configuration) and the run's segment times.
fn run_program(
    read: &ReadProgram,
    path: &PlannedPath,
    arm: &SixAxisArm,
    axis: &MandrelAxis,
    steps_per_rev: f64,
) -> Result<PlannedPath, Finding> {
    let mut run = path.clone();
    let coupled = axis.drive == MandrelDrive::Robot;
    let mut clock_s = 0.0;
    let mut mandrel_done_s = 0.0f64;
    // When each target is reached and the program goes on (after the wait that follows it).
    let mut reached_s: Vec<f64> = Vec::with_capacity(path.plan.segments.len() + 1);
    let mut previous: Option<&ReadTarget> = None;
    for step in &read.steps {
        match step {
            Step::Output { on: true, .. } if !coupled => {
                // The indexer starts the segment the next move belongs to (segment k, k the
                // targets reached so far), on its own profile.
                if let Some(s) = path.plan.segments.get(reached_s.len().wrapping_sub(1)) {
                    mandrel_done_s =
                        clock_s + s.mandrel.duration_s(s.steps.unsigned_abs(), steps_per_rev);
                }
            }
            Step::Wait { on: true, .. } if !coupled => {
                clock_s = clock_s.max(mandrel_done_s);
                if let Some(last) = reached_s.last_mut() {
                    *last = clock_s;
                }
            }
            Step::Move(t) => {
                if previous.is_some() {
                    clock_s += move_time_s(t, previous).unwrap_or(0.0);
                }
                let k = reached_s.len();
                let pose = if k == 0 {
                    Some(&mut run.plan.start)
                } else {
                    run.plan.segments.get_mut(k - 1).map(|s| &mut s.pose)
                };
                let Some(pose) = pose else {
                    return Err(Finding {
                        file: t.file.clone(),
                        line: t.line,
                        message: "the simulated run stops: more moves than the plan's poses".into(),
                    });
                };
                let paths::ArmJoints::SixAxis { joints, .. } = pose.joints else {
                    return Err(Finding {
                        file: t.file.clone(),
                        line: t.line,
                        message: "the plan holds no six-axis pose here".into(),
                    });
                };
                let (eye, q, phi) = base_pose(t, axis, pose.mandrel_rad);
                let config = arm.kind.config_of(&joints);
                let taken = paths::arm::winding::joints_for_tool(arm, &eye, &q, config).map_err(
                    |fault| Finding {
                        file: t.file.clone(),
                        line: t.line,
                        message: format!(
                            "the simulated run stops: the arm cannot take it: {fault}"
                        ),
                    },
                )?;
                pose.eye_mm = eye;
                pose.eye_mandrel_mm = axis.frame(phi).inverse_transform_point(&eye);
                pose.mandrel_rad = phi;
                pose.wrist_q = q * paths::arm::winding::tool_to_wrist();
                pose.joints = paths::ArmJoints::SixAxis {
                    joints: std::array::from_fn(|i| unwrap_near(taken[i], joints[i])),
                    tool_q: q,
                    external_rad: coupled.then_some(phi),
                };
                reached_s.push(clock_s);
                previous = Some(t);
            }
            _ => {}
        }
    }
    if reached_s.len() != path.plan.segments.len() + 1 {
        let (file, line) =
            previous.map_or((read.main_file.clone(), 1), |t| (t.file.clone(), t.line));
        return Err(Finding {
            file,
            line,
            message: format!(
                "the simulated run stops: {} moves for the plan's {} poses",
                reached_s.len(),
                path.plan.segments.len() + 1
            ),
        });
    }
    for (i, s) in run.plan.segments.iter_mut().enumerate() {
        s.duration_s = (reached_s[i + 1] - reached_s[i]).max(0.0);
    }
    Ok(run)
}

fn shown(v: f64) -> String {
    sequences::error::shown(v)
}

impl Verified {
    /// The report in words: per path the targets read and the simulated run's placement error
    /// beside `predict`'s, the check of the run's motion, and every finding.
    pub fn text(&self) -> String {
        let mut out = String::new();
        for p in &self.paths {
            out += &format!(
                "{} ({}): {} targets read; the simulated run: {}; predict of the plan: error {:.3} mm, {:.2} s\n",
                p.name,
                p.main_file,
                p.targets,
                p.prediction
                    .as_ref()
                    .map_or("not run".to_string(), |r| format!(
                        "error {:.3} mm, {:.2} s",
                        r.max_error_mm, r.time_s
                    )),
                p.planned.max_error_mm,
                p.planned.time_s,
            );
        }
        out += &self.check_line;
        out.push('\n');
        for f in &self.findings {
            out += &f.to_string();
            out.push('\n');
        }
        out += &if self.findings.is_empty() {
            format!("verify: clean ({} programs)\n", self.format.name())
        } else {
            format!(
                "verify: {} findings; first: {}\n",
                self.findings.len(),
                self.findings[0]
            )
        };
        out
    }
}
