//! The TOOL step (seed 001 §5.6): from a job file to robot and mandrel control files.
//!
//! For each path of the job: build the mandrel model, trace the fibre path, cut it into equal-length
//! segments, plan poses, steps and speeds ([`paths::plan`]), then write `NAME_<prog>.ROB`,
//! `NAME_<prog>.IND`, the sequence file and the run file.

use std::ops::Range;
use std::path::{Path, PathBuf};

use paths::geodesic::{self, PathStart};
use paths::{PathPlan, Robot, Setup, Speeds, Spine, Tube};
use sequences::job::{Direction, Job, MandrelKind};
use sequences::rob::{Header, Instruction, Interpolation, Reference};
use sequences::{MandrelFile, MandrelMove, RobotFile, RunFile, SequenceFile};

use crate::Error;

/// Speed of the first instruction, which brings the eye to the start pose, in % of base speed.
pub const APPROACH_SPEED_PCT: f64 = 10.0;
/// Arc-length step of the geodesic integrator, mm (see `paths::geodesic::trace`: at this step the
/// S-bend paths lie within a micrometre of the converged solution).
pub const GEODESIC_STEP_MM: f64 = 0.25;
/// Arc-length sample spacing of the exact helix, mm (its interpolation is exact).
pub const HELIX_STEP_MM: f64 = 1.0;
/// Facets per circumference of the mesh that imported paths are projected onto (analytic mandrels).
pub const PROJECTION_FACETS: usize = 256;
/// Section spacing of that mesh, mm.
pub const PROJECTION_SPACING_MM: f64 = 1.0;

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
}

/// Every path of a job, planned.
#[derive(Debug, Clone)]
pub struct JobPlan {
    /// In the job's order.
    pub paths: Vec<PlannedPath>,
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
        Error::Read { .. } => true,
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

/// The cell setup and speeds a job describes.
pub fn setup(job: &Job) -> (Setup, Speeds) {
    let c = &job.cell;
    let [motor_teeth, mandrel_teeth] = *c.drive.gear_ratio.get_ref();
    let robot = c.robot.as_ref().map_or_else(Robot::default, |r| Robot {
        reach_min_mm: *r.reach_min_mm.get_ref(),
        reach_max_mm: *r.reach_max_mm.get_ref(),
        z_min_mm: *r.z_min_mm.get_ref(),
        z_max_mm: *r.z_max_mm.get_ref(),
        max_speed_mm_s: *r.max_speed_mm_s.get_ref(),
    });
    (
        Setup {
            robot_distance_mm: *c.robot_distance_mm.get_ref(),
            mandrel_height_mm: *c.start_height_mm.get_ref(),
            offset_mm: *c.offset_mm.get_ref(),
            eye_mechanism_length_mm: *c.eye_mechanism_length_mm.get_ref(),
            robot,
            gearing: paths::Gearing {
                steps_per_motor_rev: *c.drive.steps_per_rev.get_ref(),
                motor_teeth,
                mandrel_teeth,
            },
        },
        Speeds {
            mandrel_rps: *c.mandrel_speed_rps.get_ref(),
            base_speed_mm_s: *c.base_speed_mm_s.get_ref(),
            max_speed_mm_s: *c.max_speed_mm_s.get_ref(),
        },
    )
}

/// Plans every path of `job`. `text` and `file` locate errors in the job file.
pub fn plan(job: &Job, text: &str, file: &Path) -> Result<JobPlan, Error> {
    let located = |source, span| located(text, file, source, span);
    let tube = mandrel_in(job, text, file)?;
    let tracer = match (&job.mandrel.kind.get_ref(), &job.mandrel.mesh) {
        (MandrelKind::Mesh, Some(mesh)) => {
            let dir = file.parent().unwrap_or(Path::new(""));
            let weld = job
                .mandrel
                .weld_mm
                .as_ref()
                .map_or(paths::mesh::DEFAULT_WELD_MM, |w| *w.get_ref());
            Some(
                crate::mesh::load(
                    &dir.join(mesh.get_ref()),
                    weld,
                    paths::mesh::Closure::Closed,
                    paths::mesh::trace::DEFAULT_CREASE_DEG,
                )
                .map_err(|e| named(text, file, mesh.span(), e))?,
            )
        }
        _ => None,
    };
    let (setup, speeds) = setup(job);
    let dir = file.parent().unwrap_or(Path::new(""));
    // Imported (DXF) paths on an analytic mandrel are projected onto its TRIASYM mesh.
    let mut projection: Option<paths::mesh::trace::Tracer> = None;
    let mut planned = Vec::with_capacity(job.paths.len());
    for spec in &job.paths {
        let segments = *spec.segments.get_ref() as usize;
        let (points, smoothing_deviation_mm) = if let Some(dxf) = &spec.dxf {
            let dxf_file = dir.join(dxf.get_ref());
            let drawing = load_dxf(&dxf_file).map_err(|e| named(text, file, dxf.span(), e))?;
            let layer = spec.layer.as_ref();
            let raw: Vec<nalgebra::Point3<f64>> = drawing
                .path(layer.map(|l| l.get_ref().as_str()))
                .map_err(|e| {
                    let span = layer.map_or(dxf.span(), |l| l.span());
                    named(text, file, span, Error::File(e.in_file(&dxf_file)))
                })?
                .into_iter()
                .map(nalgebra::Point3::from)
                .collect();
            let surface = match &tracer {
                Some(t) => t,
                None => {
                    if projection.is_none() {
                        let mesh = paths::mesh::triasym::tube(
                            &tube,
                            PROJECTION_FACETS,
                            PROJECTION_SPACING_MM,
                            true,
                        )
                        .map_err(|e| located(e, job.mandrel.kind.span()))?;
                        let adjacency = mesh
                            .validate(paths::mesh::Closure::Closed)
                            .map_err(|e| located(e, job.mandrel.kind.span()))?;
                        projection = Some(
                            paths::mesh::trace::Tracer::new(
                                mesh,
                                &adjacency,
                                paths::mesh::trace::DEFAULT_CREASE_DEG,
                            )
                            .map_err(|e| located(e, job.mandrel.kind.span()))?,
                        );
                    }
                    projection.as_ref().ok_or_else(|| {
                        located(
                            paths::Error::TooFewPoints {
                                what: "mandrel mesh",
                                count: 0,
                                needed: 1,
                            },
                            job.mandrel.kind.span(),
                        )
                    })?
                }
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
            if let Some(tracer) = &tracer {
                // Mesh mandrel: trace on the mesh, smooth, cut into equal lengths on the surface.
                let (_, cut) = paths::mesh::resegment::wind(
                    tracer,
                    &tube,
                    &start,
                    segments,
                    &paths::mesh::trace::TraceOptions::default(),
                )
                .map_err(|e| located(e, wind.span()))?;
                (cut.points, Some(cut.max_deviation_mm))
            } else {
                let path = if tube.spine().is_straight() {
                    geodesic::helix(&tube, &start, HELIX_STEP_MM)
                } else {
                    geodesic::trace(&tube, &start, GEODESIC_STEP_MM)
                }
                .map_err(|e| located(e, wind.span()))?;
                let points = paths::segment::equal_length(&tube, &path, segments)
                    .map_err(|e| located(e, spec.segments.span()))?;
                (points, None)
            }
        };
        let plan = paths::plan::plan(&points, |p| tube.distance_to_surface_mm(p), &setup, &speeds)
            .map_err(|e| {
                let span = culprit(job, &e).unwrap_or(spec.program.span());
                located(e, span)
            })?;
        planned.push(PlannedPath {
            name: format!("{}_{}", job.name.get_ref(), spec.program.get_ref()),
            program: *spec.program.get_ref(),
            plan,
            smoothing_deviation_mm,
        });
    }
    Ok(JobPlan { paths: planned })
}

/// The cell of seed 001 §6.4 the examples describe: robot distance b, mandrel diameter, tow
/// distance, eye mechanism length, mm.
const THESIS_CELL_MM: [f64; 4] = [800.0, 63.5, 100.0, 150.0];

/// The job value a reach or eq 3.7 failure points at. A height outside the robot's range is the
/// start height's doing. A horizontal distance out of reach, or eq 3.7 without a solution, comes
/// from the robot distance b against how far the eye stands from the rotation axis (mandrel
/// radius + tow distance + eye mechanism): of those four, the value furthest (by ratio) from the
/// thesis cell's is the one named, the likeliest slip of the operator's hand.
fn culprit(job: &Job, error: &paths::Error) -> Option<Range<usize>> {
    let c = &job.cell;
    match error {
        paths::Error::OutOfReach { limit, .. } if *limit == "height range" => {
            Some(c.start_height_mm.span())
        }
        paths::Error::OutOfReach { .. } | paths::Error::TangentUndefined { .. } => {
            let fields = [
                &c.robot_distance_mm,
                &job.mandrel.diameter_mm,
                &c.offset_mm,
                &c.eye_mechanism_length_mm,
            ];
            let ratio = |v: f64, nominal: f64| {
                let r = v.abs().max(1e-9) / nominal;
                r.max(1.0 / r)
            };
            fields
                .iter()
                .zip(THESIS_CELL_MM)
                .max_by(|(a, na), (b, nb)| {
                    ratio(*a.get_ref(), *na).total_cmp(&ratio(*b.get_ref(), *nb))
                })
                .map(|(field, _)| field.span())
        }
        _ => None,
    }
}

/// `value` rounded to `decimals` decimal places, as the nearest `f64` to that decimal (so it
/// prints short), with no negative zero.
fn round_to(value: f64, decimals: usize) -> f64 {
    let r: f64 = format!("{value:.decimals$}").parse().unwrap_or(value);
    if r == 0.0 { 0.0 } else { r }
}

/// The robot control file for one planned path.
pub fn robot_file(job: &Job, path: &PlannedPath) -> RobotFile {
    let c = &job.cell;
    let base = *c.base_speed_mm_s.get_ref();
    let max_pct = 100.0 * c.max_speed_mm_s.get_ref() / base;
    let mandrel = |steps: i64| MandrelMove {
        accel_rps2: *c.drive.accel_rps2.get_ref(),
        start_stop_rps: *c.drive.start_stop_rps.get_ref(),
        max_rps: *c.mandrel_speed_rps.get_ref(),
        steps,
    };
    let instruction = |number: usize, speed_pct: f64, pose: &paths::Pose, steps: i64| {
        let e = pose.eye_mm;
        let q = paths::wrist::components(&pose.wrist_q);
        Instruction {
            number: number as u16,
            speed_pct: round_to(speed_pct, 4).clamp(1e-4, max_pct),
            position_mm: [round_to(e.x, 4), round_to(e.y, 4), round_to(e.z, 4)],
            q: q.map(|c| round_to(c, 9)),
            interpolation: Interpolation::Rectangular,
            reference: Reference::Absolute,
            mandrel: mandrel(steps),
        }
    };
    let plan = &path.plan;
    let mut instructions = vec![instruction(
        1,
        APPROACH_SPEED_PCT.min(max_pct),
        &plan.start,
        0,
    )];
    for (k, s) in plan.segments.iter().enumerate() {
        instructions.push(instruction(k + 2, s.speed_pct, &s.pose, s.steps));
    }
    RobotFile {
        header: Header {
            program: path.program,
            base_speed_mm_s: base,
            max_speed_mm_s: *c.max_speed_mm_s.get_ref(),
            movement: *c.movement.get_ref(),
            sync_mandrel_deg: round_to(plan.start.mandrel_rad.to_degrees(), 6),
        },
        instructions,
    }
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

/// Every output file of a planned job: `(file name, contents)`.
pub fn control_files(job: &Job, plan: &JobPlan) -> Vec<(PathBuf, String)> {
    let mut files = Vec::new();
    for path in &plan.paths {
        files.push((
            PathBuf::from(format!("{}.ROB", path.name)),
            robot_file(job, path).write(),
        ));
        files.push((
            PathBuf::from(format!("{}.IND", path.name)),
            mandrel_file(job, path).write(),
        ));
    }
    let sequence = SequenceFile {
        names: plan.paths.iter().map(|p| p.name.clone()).collect(),
    };
    let run = RunFile {
        programs: plan.paths.iter().map(|p| p.program).collect(),
    };
    files.push((
        PathBuf::from(format!("{}.SEQ", job.name.get_ref())),
        sequence.write(),
    ));
    files.push((
        PathBuf::from(format!("{}.RUN", job.name.get_ref())),
        run.write(),
    ));
    files
}
