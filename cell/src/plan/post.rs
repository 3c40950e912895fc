//! `windcell post`: a six-axis job's plan as programs for the arm's own controller, through
//! `sequences::program` (`docs/robot-programs.md`).
//!
//! Every pose of the plan becomes one target, in order: the path's start pose (reached at the
//! approach speed), then one per segment end, each reached in the segment's planned time.
//! - **Decoupled** (`[cell.mandrel] drive = "indexer"`): the targets in the robot base frame,
//!   every segment a sync point (the robot starts the indexer's segment and waits for it in
//!   position, seed 001 §5.4.1, App. D), stop points: discrete movement. A decoupled job in fine,
//!   medium or continuous movement is refused: the robot's own controller cannot keep its flying
//!   moves in step with an indexer it only meets at stop points.
//! - **Coupled** (`drive = "robot"`): the targets in the mandrel frame (which the controller turns
//!   with the external axis), each with the commanded mandrel angle on external axis 1, the
//!   controller interpolating both in one coordinated move.

use nalgebra::{Point3, UnitQuaternion};
use paths::arm::{MandrelDrive, SixAxisArm};
use sequences::Job;
use sequences::program::{
    ExternalAxis, Format, Frame, MandrelCoupling, ProgramPath, ProgramTarget, SyncSignals,
};

use crate::Error;
use crate::plan::tool::{self, APPROACH_SPEED_PCT, JobPlan, PlannedPath};

/// The zone (blending radius) of a flying move in fine movement, mm: the thesis robot's fine
/// zone (seed 001 §5.4.2).
pub const FINE_ZONE_MM: f64 = 1.0;
/// The zone of a flying move in medium and continuous movement, mm (seed 001 §5.4.2's medium
/// zone).
pub const MEDIUM_ZONE_MM: f64 = 5.0;

/// The name of the positioner's mechanical unit in the programs of a coupled mandrel (ABB
/// `ufmec`; KUKA and FANUC number the axis instead).
pub const POSITIONER_UNIT: &str = "STN1";

/// A unit quaternion as `[w, x, y, z]`, `w ≥ 0`.
fn wxyz(q: &UnitQuaternion<f64>) -> [f64; 4] {
    let c = q.coords;
    let s = if c[3] < 0.0 { -1.0 } else { 1.0 };
    [s * c[3], s * c[0], s * c[1], s * c[2]]
}

/// The arm of a six-axis job, or the refusal of an IRB 6/2 job: `post` writes programs for the
/// controllers of six-axis arms (`what` names the command).
pub fn six_axis_arm(
    job: &Job,
    text: &str,
    file: &std::path::Path,
    format: Format,
) -> Result<SixAxisArm, Error> {
    if let Some(arm) = job.six_axis_arm() {
        return Ok(arm);
    }
    let (line, column) = tool::kind_place(job, text);
    Err(Error::PostNeedsSixAxis {
        file: file.to_path_buf(),
        line,
        column,
        format: format.name(),
    })
}

/// The tool frame in the flange frame, as the programs declare it.
pub fn tool_frame(arm: &SixAxisArm) -> Frame {
    let f = arm.tool.frame();
    let q = f.quaternion();
    Frame {
        position_mm: [f.translation_mm.x, f.translation_mm.y, f.translation_mm.z],
        orientation: wxyz(&q),
    }
}

/// The programs' motion: one [`ProgramPath`] per planned path.
pub fn program_paths(
    job: &Job,
    plan: &JobPlan,
    arm: &SixAxisArm,
    sync: SyncSignals,
) -> Result<Vec<ProgramPath>, Error> {
    let (_, speeds) = tool::setup(job);
    let axis = job.mandrel_axis();
    let coupled = axis.drive == MandrelDrive::Robot;
    let discrete = matches!(speeds.movement, paths::Movement::Discrete);
    if !coupled && !discrete {
        return Err(Error::PostDecoupledFlying {
            job: job.name.get_ref().clone(),
            movement: match speeds.movement {
                paths::Movement::Fine => "fine",
                paths::Movement::Medium => "medium",
                _ => "continuous",
            },
        });
    }
    let zone_mm = match speeds.movement {
        paths::Movement::Discrete => 0.0,
        paths::Movement::Fine => FINE_ZONE_MM,
        paths::Movement::Medium | paths::Movement::Continuous { .. } => MEDIUM_ZONE_MM,
    };
    let approach_mm_s = speeds.base_speed_mm_s * APPROACH_SPEED_PCT / 100.0;
    plan.paths
        .iter()
        .map(|path| {
            let targets = targets_of(path, &axis, coupled, discrete, zone_mm, approach_mm_s)?;
            Ok(ProgramPath {
                name: path.name.clone(),
                tool: tool_frame(arm),
                work: Frame::IDENTITY,
                mandrel: if coupled {
                    MandrelCoupling::Coupled {
                        axis: ExternalAxis {
                            number: 1,
                            mechanical_unit: POSITIONER_UNIT.to_string(),
                        },
                    }
                } else {
                    MandrelCoupling::Decoupled { sync }
                },
                targets,
            })
        })
        .collect()
}

/// One path's targets: the tool frame of every pose in the work frame.
fn targets_of(
    path: &PlannedPath,
    axis: &paths::arm::MandrelAxis,
    coupled: bool,
    discrete: bool,
    zone_mm: f64,
    approach_mm_s: f64,
) -> Result<Vec<ProgramTarget>, Error> {
    let plan = &path.plan;
    let poses = std::iter::once((&plan.start, None))
        .chain(plan.segments.iter().map(|s| (&s.pose, Some(s))));
    let mut out = Vec::with_capacity(plan.segments.len() + 1);
    let mut previous: Option<Point3<f64>> = None;
    for (pose, segment) in poses {
        let paths::ArmJoints::SixAxis { joints, tool_q, .. } = pose.joints else {
            return Err(Error::PostNotSixAxisPlan {
                path: path.name.clone(),
            });
        };
        // Coupled: the tool frame in the mandrel frame at the commanded angle.
        let (position, orientation) = if coupled {
            let frame = axis.frame(pose.mandrel_rad);
            let p = frame.inverse_transform_point(&pose.eye_mm);
            let q = frame.rotation.inverse() * tool_q;
            (p, q)
        } else {
            (pose.eye_mm, tool_q)
        };
        let (duration_s, speed_mm_s) = match segment {
            None => (0.0, approach_mm_s),
            Some(s) => {
                let travel = previous.map_or(0.0, |p| (position - p).norm());
                let speed = if s.duration_s > 0.0 && travel > 0.0 {
                    travel / s.duration_s
                } else {
                    approach_mm_s
                };
                (s.duration_s, speed)
            }
        };
        previous = Some(position);
        out.push(ProgramTarget {
            position_mm: [position.x, position.y, position.z],
            orientation: wxyz(&orientation),
            joints_deg: joints.map(f64::to_degrees),
            external_deg: coupled.then(|| pose.mandrel_rad.to_degrees()),
            duration_s,
            speed_mm_s,
            zone_mm: if segment.is_none() || discrete {
                0.0
            } else {
                zone_mm
            },
            sync: !coupled && segment.is_some(),
        });
    }
    // The last target is a stop point: the path ends there.
    if let Some(last) = out.last_mut() {
        last.zone_mm = 0.0;
    }
    Ok(out)
}

/// Every file of the job's programs in `format`, as `(file name, contents)`: each path's set
/// (main program first).
pub fn program_files(
    job: &Job,
    plan: &JobPlan,
    arm: &SixAxisArm,
    format: Format,
    sync: SyncSignals,
) -> Result<Vec<(std::path::PathBuf, String)>, Error> {
    let mut files = Vec::new();
    for path in program_paths(job, plan, arm, sync)? {
        let set = sequences::program::write(format, &path, arm, Default::default())?;
        files.extend(
            set.into_iter()
                .map(|(n, t)| (std::path::PathBuf::from(n), t)),
        );
    }
    Ok(files)
}
