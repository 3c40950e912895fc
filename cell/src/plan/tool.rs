//! The TOOL step (seed 001 §5.6): from a job file to robot and mandrel control files.
//!
//! For each path of the job: build the mandrel model, trace the fibre path, cut it into equal-length
//! segments, plan poses, steps and speeds ([`paths::plan`]), then write `NAME_<prog>.ROB`,
//! `NAME_<prog>.IND`, the sequence file and the run file.

use std::ops::Range;
use std::path::Path;

use paths::geodesic::{self, PathStart};
use paths::plan::ENTRY_ANGLE_MAX_DEG;
use paths::{Arm, Calibration, MandrelProfile, PathPlan, Setup, Speeds, Spine, Tube};
use sequences::Movement;
use sequences::job::{Direction, Job, MandrelKind, PathSpec};
use sequences::rob::{Header, Instruction, Interpolation, Reference};
use sequences::{MandrelFile, MandrelMove, RobotFile};

use crate::Error;

/// Speed of the first instruction, which brings the eye to the start pose, in % of base speed.
pub const APPROACH_SPEED_PCT: f64 = 10.0;
/// Arc-length step of the geodesic integrator, mm (see `paths::geodesic::trace`: at this step the
/// S-bend paths lie within a micrometre of the converged solution).
pub const GEODESIC_STEP_MM: f64 = 0.25;
/// Arc-length sample spacing of the exact helix, mm (its interpolation is exact).
pub const HELIX_STEP_MM: f64 = 1.0;

/// One planned path.
#[derive(Debug, Clone)]
pub struct PlannedPath {
    /// `NAME_<prog>`, the control files' stem.
    pub name: String,
    /// Program number.
    pub program: u8,
    /// The plan.
    pub plan: PathPlan,
    /// Mesh mandrels: the largest distance between the traced and the smoothed path, mm.
    pub smoothing_deviation_mm: Option<f64>,
    /// Imported (DXF) paths: each drawing point's signed distance to the mandrel surface, mm,
    /// in path order (negative inside).
    pub surface_distances_mm: Option<Vec<f64>>,
    /// The desired fibre path, mandrel frame, mm: the traced helix or geodesic at its own sample
    /// spacing (analytic tubes), else the cut points (mesh and imported paths, already smoothed).
    pub desired_mm: Vec<nalgebra::Point3<f64>>,
}

/// Every path of a job, planned.
#[derive(Debug, Clone)]
pub struct JobPlan {
    /// In the job's order.
    pub paths: Vec<PlannedPath>,
    /// The mandrel mesh the paths were traced on as the collision check's solid, when the
    /// mandrel is a mesh: built from the same prepared triangles, on a second thread while the
    /// paths are traced and planned, so the check neither loads the file again nor waits for it.
    pub mesh_solid: Option<std::sync::Arc<paths::clearance::MeshSolid>>,
}

/// A planning error at the job-file place `span` of `text`, read from `file`.
fn located(text: &str, file: &Path, source: paths::Error, span: Range<usize>) -> Error {
    let (line, column) = sequences::error::line_column(text, span.start);
    Error::Plan {
        file: file.to_path_buf(),
        line,
        column,
        source,
    }
}

/// A problem with a file the job names at `span` of `text`: a file that cannot be read, or a
/// problem of the whole file (a drawing without a path, a layer that is not there, a mesh with no
/// triangles) is reported at the job's place, then the file's own message; an error at a place
/// inside the named file keeps that place.
fn named(text: &str, file: &Path, span: Range<usize>, error: Error) -> Error {
    let whole_file = match &error {
        Error::File(e) => !matches!(e, sequences::Error::Parse { .. }),
        Error::Mesh { source, .. } => matches!(
            source,
            paths::Error::MeshSyntax { line: None, .. }
                | paths::Error::MeshInvalid { triangle: None, .. }
        ),
        _ => false,
    };
    if whole_file {
        let (line, column) = sequences::error::line_column(text, span.start);
        Error::Named {
            job: file.to_path_buf(),
            line,
            column,
            source: Box::new(error),
        }
    } else {
        error
    }
}

/// The mandrel model a job describes, with a `spine_dxf` profile read relative to the job `file`.
/// `text` locates errors in the job file.
pub fn mandrel_in(job: &Job, text: &str, file: &Path) -> Result<Tube, Error> {
    let located = |source, span| located(text, file, source, span);
    let knots = match &job.mandrel.spine_dxf {
        Some(dxf) => {
            let dxf_file = file.parent().unwrap_or(Path::new("")).join(dxf.get_ref());
            let drawing = load_dxf(&dxf_file).map_err(|e| named(text, file, dxf.span(), e))?;
            let layer = job.mandrel.spine_layer.as_ref();
            let profile = drawing
                .profile(layer.map(|l| l.get_ref().as_str()))
                .map_err(|e| {
                    let span = layer.map_or(dxf.span(), |l| l.span());
                    named(text, file, span, Error::File(e.in_file(&dxf_file)))
                })?;
            Some(profile)
        }
        None => None,
    };
    mandrel_with(job, knots).map_err(|(e, span)| located(e, span))
}

fn load_dxf(file: &Path) -> Result<sequences::dxf::Drawing, Error> {
    sequences::dxf::Drawing::load(file).map_err(Error::File)
}

/// The mandrel model a job describes (its spine from `spine_mm`).
pub fn mandrel(job: &Job) -> Result<Tube, (paths::Error, Range<usize>)> {
    mandrel_with(job, None)
}

fn mandrel_with(
    job: &Job,
    dxf_knots: Option<Vec<(f64, f64)>>,
) -> Result<Tube, (paths::Error, Range<usize>)> {
    let m = &job.mandrel;
    let diameter = *m.diameter_mm.get_ref();
    match m.kind.get_ref() {
        MandrelKind::Cylinder => {
            let length = m.length_mm.as_ref().map_or(0.0, |l| *l.get_ref());
            let bottom = m.bottom_offset_mm.as_ref().map_or(0.0, |o| *o.get_ref());
            let top = m.top_offset_mm.as_ref().map_or(bottom, |o| *o.get_ref());
            Tube::cylinder(diameter, length, bottom, top)
                .map_err(|e| (e, m.length_mm.as_ref().map_or(m.kind.span(), |l| l.span())))
        }
        MandrelKind::Tube | MandrelKind::Mesh => {
            let spine_field = m.spine_mm.as_ref();
            let span = m
                .spine_dxf
                .as_ref()
                .map(|d| d.span())
                .or_else(|| spine_field.map(|s| s.span()))
                .unwrap_or(m.kind.span());
            let knots: Vec<(f64, f64)> = dxf_knots.unwrap_or_else(|| {
                spine_field.map_or_else(Vec::new, |s| {
                    s.get_ref().iter().map(|k| (k[0], k[1])).collect()
                })
            });
            let smoothing = m.spine_smoothing_mm.as_ref().map_or(0.0, |s| *s.get_ref());
            let spine = Spine::smoothing(&knots, smoothing).map_err(|e| (e, span.clone()))?;
            Tube::new(spine, diameter / 2.0).map_err(|e| (e, span))
        }
    }
}

/// The arm a job describes: `[cell.robot]` over the IRB 6/2 defaults, with the job's eye
/// mechanism.
pub fn arm(job: &Job) -> Arm {
    let c = &job.cell;
    let mut arm = Arm {
        eye_mechanism_mm: *c.eye_mechanism_length_mm.get_ref(),
        ..Arm::default()
    };
    let Some(r) = &c.robot else {
        return arm;
    };
    let value = |field: &Option<toml::Spanned<f64>>, default: f64| {
        field.as_ref().map_or(default, |v| *v.get_ref())
    };
    arm.shoulder_height_mm = value(&r.shoulder_height_mm, arm.shoulder_height_mm);
    arm.upper_arm_mm = value(&r.upper_arm_mm, arm.upper_arm_mm);
    arm.forearm_mm = value(&r.forearm_mm, arm.forearm_mm);
    arm.eye_mechanism_max_mm = value(&r.eye_mechanism_max_mm, arm.eye_mechanism_max_mm);
    for (limit, range) in arm.joints.iter_mut().zip([
        &r.base_yaw_deg,
        &r.shoulder_deg,
        &r.elbow_deg,
        &r.pitch_deg,
        &r.roll_deg,
    ]) {
        if let Some(range) = range {
            let [lo, hi] = *range.get_ref();
            limit.min_rad = lo.to_radians();
            limit.max_rad = hi.to_radians();
        }
    }
    if let Some(speeds) = &r.joint_speed_deg_s {
        for (limit, speed) in arm.joints.iter_mut().zip(speeds.get_ref()) {
            limit.max_speed_rad_s = speed.to_radians();
        }
    }
    arm
}

/// A continuous plan's speed advice is for the profile as the indexer runs it
/// ([`as_the_indexer_runs`]): the job's figure that the indexer's 0.01 motor rev/s rounds to
/// no more than that speed, down to the 0.1 mrev/s the message shows.
fn as_the_job_says(job: &Job, e: paths::Error) -> paths::Error {
    let paths::Error::SegmentTooShort {
        segment,
        duration_s,
        instruction_s,
        max_segments,
        mandrel_rps_fit,
    } = e
    else {
        return e;
    };
    let d = &job.cell.drive;
    let [motor_teeth, mandrel_teeth] = *d.gear_ratio.get_ref();
    let ratio = f64::from(mandrel_teeth) / f64::from(motor_teeth);
    let on_grid = (mandrel_rps_fit * ratio * 100.0).floor() / 100.0 / ratio;
    let shown = (on_grid * 1e4).floor() / 1e4;
    paths::Error::SegmentTooShort {
        segment,
        duration_s,
        instruction_s,
        max_segments,
        mandrel_rps_fit: shown,
    }
}

/// The profile the indexer runs for `p`: the X-language gives acceleration, velocity and start
/// velocity in motor rev/s (rev/s²) to two decimals (`A`, `V`, `VS`; the OEM guide's 0.01
/// resolution), so a mandrel speed of 0.1 rev/s through 60:13 is sent as `V0.46` and turns the
/// mandrel at 0.09967 rev/s, 0.33 % slow. Continuous movement plans the robot against that
/// motion (docs/continuous.md); the thesis's modes keep the job's figures, as the thesis did.
/// `motor_per_mandrel` is motor revolutions per mandrel revolution.
pub fn as_the_indexer_runs(p: MandrelProfile, motor_per_mandrel: f64) -> MandrelProfile {
    let sent = |mandrel: f64| -> f64 {
        let motor = format!("{:.2}", mandrel * motor_per_mandrel);
        motor.parse::<f64>().unwrap_or(f64::NAN) / motor_per_mandrel
    };
    MandrelProfile {
        accel_rps2: sent(p.accel_rps2),
        start_stop_rps: sent(p.start_stop_rps),
        max_rps: sent(p.max_rps),
    }
}

/// The cell setup and speeds a job describes.
pub fn setup(job: &Job) -> (Setup, Speeds) {
    let c = &job.cell;
    let [motor_teeth, mandrel_teeth] = *c.drive.gear_ratio.get_ref();
    let entry_angle_max_deg = c
        .robot
        .as_ref()
        .and_then(|r| r.entry_angle_max_deg.as_ref())
        .map_or(ENTRY_ANGLE_MAX_DEG, |a| *a.get_ref());
    let calibration = c
        .calibration
        .as_ref()
        .map_or_else(Calibration::default, |k| {
            let pair =
                |v: &Option<toml::Spanned<[f64; 2]>>| v.as_ref().map_or([0.0; 2], |v| *v.get_ref());
            Calibration {
                axis_offset_mm: pair(&k.axis_offset_mm),
                axis_tilt_rad: pair(&k.axis_tilt_deg).map(f64::to_radians),
                zero_angle_rad: k
                    .zero_angle_deg
                    .as_ref()
                    .map_or(0.0, |z| z.get_ref().to_radians()),
                rotation_sign: k.rotation_sign.as_ref().map_or(1, |s| *s.get_ref()),
            }
        });
    (
        Setup {
            robot_distance_mm: *c.robot_distance_mm.get_ref(),
            mandrel_height_mm: *c.start_height_mm.get_ref(),
            offset_mm: *c.offset_mm.get_ref(),
            arm: arm(job),
            entry_angle_max_rad: entry_angle_max_deg.to_radians(),
            calibration,
            gearing: paths::Gearing {
                steps_per_motor_rev: *c.drive.steps_per_rev.get_ref(),
                motor_teeth,
                mandrel_teeth,
            },
            six_axis: job.six_axis_arm().map(|arm| paths::SixAxisCell {
                arm,
                axis: job.mandrel_axis(),
            }),
        },
        Speeds {
            mandrel: {
                let nominal = MandrelProfile {
                    accel_rps2: *c.drive.accel_rps2.get_ref(),
                    start_stop_rps: *c.drive.start_stop_rps.get_ref(),
                    max_rps: *c.mandrel_speed_rps.get_ref(),
                };
                if *c.movement.get_ref() == Movement::Continuous {
                    as_the_indexer_runs(nominal, f64::from(mandrel_teeth) / f64::from(motor_teeth))
                } else {
                    nominal
                }
            },
            base_speed_mm_s: *c.base_speed_mm_s.get_ref(),
            max_speed_mm_s: *c.max_speed_mm_s.get_ref(),
            movement: match c.movement.get_ref() {
                Movement::Discrete => paths::Movement::Discrete,
                Movement::Fine => paths::Movement::Fine,
                Movement::Medium => paths::Movement::Medium,
                Movement::Continuous => paths::Movement::Continuous {
                    instruction_s: CONTINUOUS_INSTRUCTION_S,
                },
            },
        },
    )
}

/// The least time of a segment in continuous movement, s: the robot computer's time per flying
/// instruction in the medium zone (`asea_protocol::command::INTERPRETATION_S`, from App. B's
/// fastest medium windings) with a 10 % margin, so the robot is never paced by its own
/// interpretation and stays in step with the mandrel (docs/continuous.md).
pub const CONTINUOUS_INSTRUCTION_S: f64 = 1.1 * asea_protocol::command::INTERPRETATION_S[1];

/// Where in the job file a planning error belongs: the field whose value the error is about
/// (the path's `program` for a pose the arm cannot take).
fn error_span(job: &Job, spec: &PathSpec, error: &paths::Error) -> Range<usize> {
    let c = &job.cell;
    let entry_limit = c
        .robot
        .as_ref()
        .and_then(|r| r.entry_angle_max_deg.as_ref())
        .map(|a| a.span());
    let robot_table = c.robot.as_ref().and(Some(c.robot_distance_mm.span()));
    let calibration = c.calibration.as_ref().and_then(|k| {
        k.axis_tilt_deg
            .as_ref()
            .map(|v| v.span())
            .or(k.axis_offset_mm.as_ref().map(|v| v.span()))
            .or(k.rotation_sign.as_ref().map(|v| v.span()))
            .or(k.zero_angle_deg.as_ref().map(|v| v.span()))
    });
    match error {
        paths::Error::TangentUndefined { .. } => c.robot_distance_mm.span(),
        paths::Error::EntryAngle { .. } => entry_limit.unwrap_or(spec.program.span()),
        paths::Error::SegmentTurnsTooFar { .. } => spec.segments.span(),
        paths::Error::RobotTooSlow { .. } => c.mandrel_speed_rps.span(),
        paths::Error::SegmentTooShort { .. } => spec.segments.span(),
        paths::Error::EyeInsideMandrel { .. } => c.offset_mm.span(),
        paths::Error::OutOfRange { name, .. } => match *name {
            "eye_mechanism_length_mm" => c.eye_mechanism_length_mm.span(),
            "entry_angle_max_deg" => entry_limit.unwrap_or(spec.program.span()),
            "axis_tilt_deg" | "axis_offset_mm" | "rotation_sign" | "zero_angle_deg" => {
                calibration.unwrap_or(spec.program.span())
            }
            "shoulder_height_mm"
            | "upper_arm_mm"
            | "forearm_mm"
            | "eye_mechanism_max_mm"
            | "joint_speed_deg_s"
            | "base_yaw_deg"
            | "shoulder_deg"
            | "elbow_deg"
            | "pitch_deg"
            | "roll_deg" => robot_table.unwrap_or(spec.program.span()),
            _ => spec.program.span(),
        },
        _ => spec.program.span(),
    }
}

/// Refuses a job for a six-axis arm in `command`, a command that drives or simulates the IRB 6/2
/// cell (`run`, `predict`): one line at the job's `[cell.robot] kind`.
pub fn irb62_only(job: &Job, text: &str, file: &Path, command: &'static str) -> Result<(), Error> {
    let name = match job.robot_kind() {
        sequences::job::RobotKind::Irb6 => return Ok(()),
        sequences::job::RobotKind::Opw => "opw",
        sequences::job::RobotKind::Ur => "ur",
    };
    let (line, column) = kind_place(job, text);
    Err(Error::SixAxisNotDriven {
        file: file.to_path_buf(),
        line,
        column,
        kind: name,
        command,
    })
}

/// Where a refusal about the job's arm points: `[cell.robot] kind`, or the job's name when the
/// job names no kind (the IRB 6/2 by default), as line and column of `text`.
pub fn kind_place(job: &Job, text: &str) -> (usize, usize) {
    let span = job
        .cell
        .robot
        .as_ref()
        .and_then(|r| r.kind.as_ref().map(|k| k.span()))
        .unwrap_or_else(|| job.name.span());
    sequences::error::line_column(text, span.start)
}

/// Plans every path of `job`. `text` and `file` locate errors in the job file.
pub fn plan(job: &Job, text: &str, file: &Path) -> Result<JobPlan, Error> {
    let located = |source, span| located(text, file, source, span);
    // The whole job's work is bounded before any of it starts.
    let mut total = 0usize;
    for spec in &job.paths {
        total += *spec.segments.get_ref() as usize;
        paths::limits::at_most(
            "segments in all paths",
            total as f64,
            paths::limits::MAX_JOB_SEGMENTS as f64,
        )
        .map_err(|e| located(e, spec.segments.span()))?;
    }
    let tube = mandrel_in(job, text, file)?;
    let mesh = match (&job.mandrel.kind.get_ref(), &job.mandrel.mesh) {
        (MandrelKind::Mesh, Some(mesh)) => {
            let dir = file.parent().unwrap_or(Path::new(""));
            let weld = job
                .mandrel
                .weld_mm
                .as_ref()
                .map_or(paths::mesh::DEFAULT_WELD_MM, |w| *w.get_ref());
            Some((dir.join(mesh.get_ref()), weld, mesh.span()))
        }
        _ => None,
    };
    let Some((mesh_file, weld, span)) = mesh else {
        return Ok(JobPlan {
            paths: plan_paths(job, text, file, &tube, None)?,
            mesh_solid: None,
        });
    };
    // The mesh made ready for the last plan, when it is this very file (size and checksum) at
    // this tolerance.
    let key = crate::plan::mesh::ready_key(&mesh_file, weld);
    if let Some(ready) = key
        .as_ref()
        .and_then(|k| crate::plan::mesh::ready_kept(&mesh_file, k))
    {
        return Ok(JobPlan {
            paths: plan_paths(job, text, file, &tube, Some(&ready.tracer))?,
            mesh_solid: Some(ready.solid),
        });
    }
    let (prepared, adjacency) =
        crate::plan::mesh::load_prepared(&mesh_file, weld, paths::mesh::Closure::Closed)
            .map_err(|e| named(text, file, span.clone(), e))?;
    let mesh_error = |source| {
        named(
            text,
            file,
            span.clone(),
            Error::Mesh {
                file: mesh_file.clone(),
                source,
            },
        )
    };
    std::thread::scope(|scope| {
        let solid =
            scope.spawn(|| paths::clearance::MeshSolid::with_adjacency(&prepared, &adjacency));
        let tracer = paths::mesh::trace::Tracer::new(
            prepared.clone(),
            &adjacency,
            paths::mesh::trace::DEFAULT_CREASE_DEG,
        )
        .map_err(mesh_error)?;
        let planned = plan_paths(job, text, file, &tube, Some(&tracer))?;
        let solid = solid
            .join()
            .unwrap_or_else(|panic| std::panic::resume_unwind(panic))
            .map_err(mesh_error)?;
        let solid = std::sync::Arc::new(solid);
        if let Some(key) = key {
            let ready = crate::plan::mesh::Ready {
                tracer: std::sync::Arc::new(tracer),
                solid: solid.clone(),
            };
            crate::plan::mesh::keep_ready(&mesh_file, key, ready);
        }
        Ok(JobPlan {
            paths: planned,
            mesh_solid: Some(solid),
        })
    })
}

/// Plans every path of `job` on `tube`, or on the mesh of `tracer` when the mandrel is a mesh.
fn plan_paths(
    job: &Job,
    text: &str,
    file: &Path,
    tube: &Tube,
    tracer: Option<&paths::mesh::trace::Tracer>,
) -> Result<Vec<PlannedPath>, Error> {
    let located = |source, span| located(text, file, source, span);
    let (setup, speeds) = setup(job);
    let dir = file.parent().unwrap_or(Path::new(""));
    // Imported (DXF) paths on an analytic mandrel are projected onto the tube itself (its nearest
    // surface point and normal).
    let mut projection: Option<paths::clearance::TubeSolid> = None;
    let mut planned = Vec::with_capacity(job.paths.len());
    for spec in &job.paths {
        let segments = *spec.segments.get_ref() as usize;
        if setup.six_axis.is_none() {
            // The IRB 6/2's robot computer stores fine and medium programs.
            program_fits_memory(job, spec, text, file)?;
        }
        let mut surface_distances_mm = None;
        let mut desired_mm = None;
        let (points, smoothing_deviation_mm) = if let Some(dxf) = &spec.dxf {
            let dxf_file = dir.join(dxf.get_ref());
            let drawing = load_dxf(&dxf_file).map_err(|e| named(text, file, dxf.span(), e))?;
            let layer = spec.layer.as_ref();
            let imported = crate::plan::imported::ImportedPath::new(
                &dxf_file,
                &drawing,
                layer.map(|l| l.get_ref().as_str()),
            )
            .map_err(|e| named(text, file, layer.map_or(dxf.span(), |l| l.span()), e))?;
            imported.check_length()?;
            let tolerance_mm = spec
                .surface_tolerance_mm
                .as_ref()
                .map_or(sequences::job::DEFAULT_SURFACE_TOLERANCE_MM, |t| {
                    *t.get_ref()
                });
            surface_distances_mm = Some(match tracer {
                Some(t) => imported.surface_distances(
                    |p| {
                        t.locate(p).map_or(f64::INFINITY, |at| {
                            at.distance_mm.copysign((p - at.point).dot(&at.normal))
                        })
                    },
                    tolerance_mm,
                )?,
                None => {
                    imported.surface_distances(|p| tube.distance_to_surface_mm(p), tolerance_mm)?
                }
            });
            let raw = imported.points;
            let surface: &dyn paths::mesh::resegment::Projection = match tracer {
                Some(t) => t,
                None => projection.get_or_insert_with(|| paths::clearance::TubeSolid::new(tube)),
            };
            let cut = paths::mesh::resegment::smooth_and_cut(
                surface,
                &raw,
                segments,
                paths::mesh::resegment::DEFAULT_SPACING_MM,
            )
            .map_err(|e| located(e, dxf.span()))?;
            (cut.points, Some(cut.max_deviation_mm))
        } else {
            let (Some(angle), Some(wind), Some(direction)) = (
                spec.start_angle_deg.as_ref(),
                spec.wind_angle_deg.as_ref(),
                spec.direction.as_ref(),
            ) else {
                return Err(located(
                    paths::Error::OutOfRange {
                        name: "path",
                        value: 0.0,
                        expected: "needs direction, wind_angle_deg and start_angle_deg, or dxf",
                    },
                    spec.program.span(),
                ));
            };
            let start = PathStart {
                angle_rad: angle.get_ref().to_radians(),
                wind_angle_rad: wind.get_ref().to_radians(),
                direction: match direction.get_ref() {
                    Direction::Down => paths::Direction::Down,
                    Direction::Up => paths::Direction::Up,
                },
            };
            if let Some(tracer) = tracer {
                // Mesh mandrel: trace on the mesh, smooth, cut into equal lengths on the surface.
                let (_, cut) = paths::mesh::resegment::wind(
                    tracer,
                    tube,
                    &start,
                    segments,
                    &paths::mesh::trace::TraceOptions::default(),
                )
                .map_err(|e| located(e, wind.span()))?;
                (cut.points, Some(cut.max_deviation_mm))
            } else {
                // A tube along a measured spine is cut with horizontal end planes unless the job
                // says otherwise (the S-bend is 0–350 mm long); its paths run from end to end.
                let ends = match job.mandrel.ends.as_ref().map(|e| *e.get_ref()) {
                    Some(sequences::job::Ends::Square) => geodesic::Ends::Square,
                    _ if *job.mandrel.kind.get_ref() == MandrelKind::Cylinder => {
                        geodesic::Ends::Square
                    }
                    _ => geodesic::Ends::Horizontal,
                };
                let path = if tube.spine().is_straight() && ends == geodesic::Ends::Square {
                    geodesic::helix(tube, &start, HELIX_STEP_MM)
                } else {
                    geodesic::trace_to(tube, &start, GEODESIC_STEP_MM, ends)
                }
                .map_err(|e| located(e, wind.span()))?;
                let points = paths::segment::equal_length(tube, &path, segments)
                    .map_err(|e| located(e, spec.segments.span()))?;
                desired_mm = Some(
                    path.samples
                        .iter()
                        .map(|s| tube.point(s.u, s.v))
                        .collect::<Vec<_>>(),
                );
                (points, None)
            }
        };
        let plan = paths::plan::plan(&points, |p| tube.distance_to_surface_mm(p), &setup, &speeds)
            .map_err(|e| {
                let e = as_the_job_says(job, e);
                let span = culprit(job, &e).unwrap_or_else(|| error_span(job, spec, &e));
                located(e, span)
            })?;
        if setup.six_axis.is_none() {
            check_speeds(job, &plan).map_err(|e| located(e, spec.program.span()))?;
        }
        planned.push(PlannedPath {
            name: format!("{}_{}", job.name.get_ref(), spec.program.get_ref()),
            program: *spec.program.get_ref(),
            plan,
            smoothing_deviation_mm,
            surface_distances_mm,
            desired_mm: desired_mm.unwrap_or_else(|| points.iter().map(|p| p.point).collect()),
        });
    }
    Ok(planned)
}

/// Refuses a path whose stored program (fine and medium movement) would not fit the robot's
/// memory, at the path's `segments`, before anything is traced. Discrete movement sends each
/// position as it is needed and stores nothing (seed 001 §5.4.1).
fn program_fits_memory(
    job: &Job,
    spec: &sequences::job::PathSpec,
    text: &str,
    file: &Path,
) -> Result<(), Error> {
    let movement = *job.cell.movement.get_ref();
    if movement == sequences::Movement::Discrete {
        return Ok(());
    }
    let segments = *spec.segments.get_ref() as usize;
    // The approach and one positioning per segment.
    let positioning = segments + 1;
    let max_positioning = crate::plan::program::max_positioning_instructions();
    if positioning <= max_positioning {
        return Ok(());
    }
    let (line, column) = sequences::error::line_column(text, spec.segments.span().start);
    Err(Error::ProgramMemory {
        file: file.to_path_buf(),
        line,
        column,
        program: *spec.program.get_ref(),
        positioning,
        control: crate::plan::program::PROGRAM_CONTROL_INSTRUCTIONS,
        max_segments: max_positioning - 1,
        movement: movement.keyword(),
    })
}

/// The cell of seed 001 §6.4 the examples describe: robot distance b, mandrel diameter, tow
/// distance, eye mechanism length and start height, mm.
const THESIS_CELL_MM: [f64; 5] = [800.0, 63.5, 100.0, 150.0, 300.0];

/// The job value an arm or eq 3.7 failure points at. A pose the arm cannot take (out of reach, a
/// joint out of range), or eq 3.7 without a solution, comes from where the cell puts the eye: the
/// robot distance b, how far the eye stands from the rotation axis (the mandrel radius, the tow
/// distance and the eye mechanism) and the start height. Of those five, the value furthest (by ratio) from the
/// thesis cell's is the one named, the likeliest slip of the operator's hand; when none is more
/// than twice or half the thesis cell's, the arm's own settings are named instead.
fn culprit(job: &Job, error: &paths::Error) -> Option<Range<usize>> {
    let c = &job.cell;
    match error {
        paths::Error::Arm { .. } | paths::Error::TangentUndefined { .. } => {
            let fields = [
                &c.robot_distance_mm,
                &job.mandrel.diameter_mm,
                &c.offset_mm,
                &c.eye_mechanism_length_mm,
                &c.start_height_mm,
            ];
            let ratio = |v: f64, nominal: f64| {
                let r = v.abs().max(1e-9) / nominal;
                r.max(1.0 / r)
            };
            let (field, worst) = fields
                .iter()
                .zip(THESIS_CELL_MM)
                .map(|(field, nominal)| (field, ratio(*field.get_ref(), nominal)))
                .max_by(|a, b| a.1.total_cmp(&b.1))?;
            (worst > 2.0).then(|| field.span())
        }
        _ => None,
    }
}

/// Every instruction speed as the `.ROB` file will carry it (4 decimals) lies in (0, max]: a
/// segment too slow to write, or faster than the controller's maximum, is an error, never a clamp.
fn check_speeds(job: &Job, plan: &PathPlan) -> Result<(), paths::Error> {
    let c = &job.cell;
    let max_pct = 100.0 * c.max_speed_mm_s.get_ref() / c.base_speed_mm_s.get_ref();
    for s in &plan.segments {
        let written = round_to(s.speed_pct, 4);
        if !(written > 0.0 && written <= max_pct * (1.0 + 1e-12)) {
            return Err(paths::Error::OutOfRange {
                name: "speed_pct",
                value: s.speed_pct,
                expected: "an instruction speed must round to more than 0 and at most the \
                           maximum speed (4 decimals in the .ROB file)",
            });
        }
    }
    Ok(())
}

/// `value` rounded to `decimals` decimal places, as the nearest `f64` to that decimal (so it
/// prints short), with no negative zero.
fn round_to(value: f64, decimals: usize) -> f64 {
    let r: f64 = format!("{value:.decimals$}").parse().unwrap_or(value);
    if r == 0.0 { 0.0 } else { r }
}

/// The robot control file for one planned path. Fails if an instruction number does not fit the
/// robot's 16 bits (a path of more than 65 534 segments).
pub fn robot_file(job: &Job, path: &PlannedPath) -> Result<RobotFile, Error> {
    let c = &job.cell;
    let base = *c.base_speed_mm_s.get_ref();
    let max_pct = 100.0 * c.max_speed_mm_s.get_ref() / base;
    let mandrel = |profile: &MandrelProfile, steps: i64| MandrelMove {
        accel_rps2: profile.accel_rps2,
        start_stop_rps: profile.start_stop_rps,
        max_rps: profile.max_rps,
        steps,
    };
    let job_profile = MandrelProfile {
        accel_rps2: *c.drive.accel_rps2.get_ref(),
        start_stop_rps: *c.drive.start_stop_rps.get_ref(),
        max_rps: *c.mandrel_speed_rps.get_ref(),
    };
    let instruction = |number: usize,
                       speed_pct: f64,
                       pose: &paths::Pose,
                       profile: &MandrelProfile,
                       steps: i64| {
        let e = pose.eye_mm;
        let q = paths::wrist::components(&pose.wrist_q);
        let number = u16::try_from(number).map_err(|_| Error::InstructionNumber {
            program: path.program,
            number,
        })?;
        Ok::<_, Error>(Instruction {
            number,
            // Checked by `plan` to lie in (0, max] at this rounding.
            speed_pct: round_to(speed_pct, 4),
            position_mm: [round_to(e.x, 4), round_to(e.y, 4), round_to(e.z, 4)],
            q: q.map(|c| round_to(c, 9)),
            interpolation: Interpolation::Rectangular,
            reference: Reference::Absolute,
            mandrel: mandrel(profile, steps),
        })
    };
    let plan = &path.plan;
    let mut instructions = vec![instruction(
        1,
        APPROACH_SPEED_PCT.min(max_pct),
        &plan.start,
        &job_profile,
        0,
    )?];
    for (k, s) in plan.segments.iter().enumerate() {
        instructions.push(instruction(
            k + 2,
            s.speed_pct,
            &s.pose,
            &s.mandrel,
            s.steps,
        )?);
    }
    Ok(RobotFile {
        header: Header {
            program: path.program,
            base_speed_mm_s: base,
            max_speed_mm_s: *c.max_speed_mm_s.get_ref(),
            movement: *c.movement.get_ref(),
            // The indexer's position at the start pose, in its own sense of rotation.
            sync_mandrel_deg: round_to(plan.sync_drive_rad.to_degrees(), 6),
        },
        instructions,
    })
}

/// The mandrel control file for one planned path: one move of the path's total steps.
pub fn mandrel_file(job: &Job, path: &PlannedPath) -> MandrelFile {
    let c = &job.cell;
    MandrelFile {
        path_move: MandrelMove {
            accel_rps2: *c.drive.accel_rps2.get_ref(),
            start_stop_rps: *c.drive.start_stop_rps.get_ref(),
            max_rps: *c.mandrel_speed_rps.get_ref(),
            steps: path.plan.segments.iter().map(|s| s.steps).sum(),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The thesis drive (60:13): 0.1 rev/s is 0.4615 motor rev/s, sent as `V0.46` (0.46 · 13/60
    /// = 0.099667 rev/s); 1 rev/s² is `A4.62` (1.001 rev/s²); 0.05 rev/s is `VS0.23`
    /// (0.049833 rev/s). Each by hand from the X-language's two decimals.
    #[test]
    fn the_indexer_runs_the_profile_its_two_decimals_can_say() {
        let p = as_the_indexer_runs(
            MandrelProfile {
                accel_rps2: 1.0,
                start_stop_rps: 0.05,
                max_rps: 0.1,
            },
            60.0 / 13.0,
        );
        assert!((p.max_rps - 0.46 * 13.0 / 60.0).abs() < 1e-15, "{p:?}");
        assert!((p.accel_rps2 - 4.62 * 13.0 / 60.0).abs() < 1e-15, "{p:?}");
        assert!(
            (p.start_stop_rps - 0.23 * 13.0 / 60.0).abs() < 1e-15,
            "{p:?}"
        );
        // Sent again, the figures say the same.
        let q = as_the_indexer_runs(p, 60.0 / 13.0);
        assert!((q.max_rps - p.max_rps).abs() < 1e-15);
        assert!((q.accel_rps2 - p.accel_rps2).abs() < 1e-15);
    }

    /// The arm carries the job's eye mechanism, not the default's: the cylinder example with
    /// `eye_mechanism_length_mm = 200` (the IRB 6/2 default is 150 mm). The wrist of every
    /// planned pose, found from its joints and the link lengths alone (shoulder 300 mm above the
    /// base, upper arm 450 mm, forearm 670 mm: `paths::robot`'s model, no `[cell.robot]` in the
    /// job), lies 200 mm behind the planned eye along the roll axis (pitched `q4` below the
    /// horizontal in the arm plane at base yaw `q1`). An arm built with the default 150 mm puts
    /// every eye 50 mm off its planned place.
    #[test]
    fn the_planned_arm_carries_the_jobs_eye_mechanism() {
        let text = include_str!("../../../examples/cylinder.toml").replace(
            "eye_mechanism_length_mm = 150.0",
            "eye_mechanism_length_mm = 200.0",
        );
        assert!(text.contains("eye_mechanism_length_mm = 200.0"));
        let job = Job::parse(&text).unwrap();
        assert_eq!(arm(&job).eye_mechanism_mm, 200.0);
        let planned = plan(&job, &text, Path::new("examples/cylinder.toml")).unwrap();
        assert_eq!(planned.paths.len(), 2);
        let (shoulder_height, upper, fore) = (300.0, 450.0, 670.0);
        let mut poses = 0;
        for path in &planned.paths {
            let plan = &path.plan;
            for pose in std::iter::once(&plan.start).chain(plan.segments.iter().map(|s| &s.pose)) {
                let j = &pose.joints;
                let j = j.irb62().unwrap();
                let (s1, c1) = j.base_yaw_rad.sin_cos();
                let rho = upper * j.shoulder_rad.sin() + fore * j.elbow_rad.cos();
                let z = shoulder_height + upper * j.shoulder_rad.cos() + fore * j.elbow_rad.sin();
                let wrist = nalgebra::Point3::new(rho * c1, rho * s1, z);
                let (sp, cp) = j.pitch_rad.sin_cos();
                let roll_axis = nalgebra::Vector3::new(cp * c1, cp * s1, -sp);
                let want = wrist + roll_axis * 200.0;
                let off = (pose.eye_mm - want).norm();
                assert!(off < 1e-6, "{}: eye {} mm off the arm's", path.name, off);
                poses += 1;
            }
        }
        assert_eq!(poses, 2 * 51);
    }
}
