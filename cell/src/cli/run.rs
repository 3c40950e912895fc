//! `windcell run JOB.toml | DIR/NAME.SEQ [--run DIR/NAME.RUN]`: wind a batch on the cell (seed 001
//! §5.3.3–5.3.4, §5.6.4).
//!
//! Tasks (tokio): the coordinator runs on a blocking thread that owns both devices and the sync
//! lines; a signal task (Ctrl-C) and a console task (`s` + Enter) set the shared stop request the
//! coordinator looks at every control tick; the coordinator's events go through a channel to the
//! display task, which prints progress lines or `--json` events. docs/ARCHITECTURE.md, "Run".

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use cell::record::linktap::{LinkTap, RecordSlot, SyncTap};
use cell::run::batch::{self, Loaded};
use cell::run::cellfile::{self, Cell};
use cell::run::coordinator::{
    Batch, Coordinator, Devices, Event, Halt, Reach, ResumePoint, RunMode, StopRequest,
};
use cell::run::journal::{self, Journal};
use cell::sim::{SimCell, SimCellConfig};
use clap::{Args, ValueEnum};
use nalgebra::Point3;
use paths::wrist::from_components;
use serde_json::json;

use super::Failure;
use super::progress::Display;

/// Exit code when the run was interrupted (Ctrl-C, the console's `s`, the e-stop input).
pub const EXIT_INTERRUPTED: u8 = 130;

/// `--mode`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ModeArg {
    /// File control: one instruction pair at a time.
    Discrete,
    /// Program control, 1 mm zone.
    Fine,
    /// Program control, 10 mm zone.
    Medium,
    /// Program control kept in step with the mandrel (docs/continuous.md).
    Continuous,
}

/// Wind a batch: a job (planned first) or control files already written.
#[derive(Debug, Args)]
pub struct RunArgs {
    /// The job file (TOML) or a sequence file (`DIR/NAME.SEQ`).
    pub input: PathBuf,
    /// The run file (program mode; default: the sequence's `.RUN`).
    #[arg(long = "run", value_name = "FILE")]
    pub run_file: Option<PathBuf>,
    /// Movement type, overriding the control files'.
    #[arg(long, value_enum)]
    pub mode: Option<ModeArg>,
    /// The cell description (wins over the job's `[cell]`).
    #[arg(long, value_name = "CELL.toml")]
    pub cell: Option<PathBuf>,
    /// The journal to write (default: `NAME.journal` beside the sequence, or in the current
    /// folder for a job planned in memory). A journal of an unfinished batch is never
    /// overwritten: resume it, or start over with `--restart`.
    #[arg(long, value_name = "FILE")]
    pub journal: Option<PathBuf>,
    /// Start the batch over although the journal records it unfinished: the old journal is kept
    /// as `NAME.journal.N` (the first free N) and the mandrel is zeroed where it stands.
    #[arg(long, conflicts_with = "resume")]
    pub restart: bool,
    /// Resume the batch this journal records.
    #[arg(long, value_name = "JOURNAL")]
    pub resume: Option<PathBuf>,
    /// With `--resume`: the operator confirms that the mandrel stands at the angle of the
    /// journal's last confirmed step (the step and angle the refusal named); the indexer's
    /// counter is re-referenced to it, and journaled (docs/operator.md, "Re-referencing").
    #[arg(long, requires = "resume")]
    pub rereference: bool,
    /// Run every program in the robot's standby mode first (§5.3.1).
    #[arg(long)]
    pub standby: bool,
    /// Override the collision gate (written to the journal).
    #[arg(long)]
    pub force: bool,
    /// The job a sequence's control files were planned from: each file must be the job's plan,
    /// line for line, and the job's collision and snag check gates the run.
    #[arg(long, value_name = "JOB.toml")]
    pub job: Option<PathBuf>,
    /// One JSON object per line on standard output.
    #[arg(long)]
    pub json: bool,
    /// The simulated cell's log of executed instructions (JSON lines).
    #[arg(long, value_name = "FILE")]
    pub log: Option<PathBuf>,
    /// Record the run as MCAP for Foxglove (docs/operator.md).
    #[arg(long, value_name = "FILE.mcap")]
    pub record: Option<PathBuf>,
    /// Serve the run live over Foxglove's WebSocket protocol (default 127.0.0.1:8765).
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = DEFAULT_LIVE)]
    pub live: Option<String>,
    /// The simulated cell's clock: `real` at the real cell's speed (times `--speed`; the default
    /// with `--live`), `fast` as fast as it runs (the default otherwise).
    #[arg(long, value_enum)]
    pub clock: Option<super::run_clock::ClockArg>,
    /// Cell seconds per wall second of the real clock (0.1–1000, default 1).
    #[arg(long, value_name = "FACTOR", value_parser = super::run_clock::speed_factor)]
    pub speed: Option<f64>,
}

/// The command that resumes the batch `args` started, from `journal`.
fn resume_command(args: &RunArgs, mode: RunMode, journal: &Path) -> String {
    let mut resume = format!("windcell run {}", args.input.display());
    if args.mode.is_some() {
        resume += &format!(" --mode {}", mode.keyword());
    }
    if let Some(r) = &args.run_file {
        resume += &format!(" --run {}", r.display());
    }
    if let Some(c) = &args.cell {
        resume += &format!(" --cell {}", c.display());
    }
    if let Some(j) = &args.job {
        resume += &format!(" --job {}", j.display());
    }
    if args.force {
        resume += " --force";
    }
    resume + &format!(" --resume {}", journal.display())
}

/// True for a job file (`.toml`, planned in memory), false for a sequence of control files.
fn is_job_file(input: &Path) -> bool {
    input
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("toml"))
}

/// The journal's place when `--journal` is not given: beside the control files of a sequence
/// (the plan's folder, which the operator wrote), in the current folder for a job planned in
/// memory (never into the folder a job file came from, such as `examples/`).
fn default_journal(args: &RunArgs, sequence_path: &Path, name: &str) -> PathBuf {
    if is_job_file(&args.input) {
        PathBuf::from(format!("{name}.journal"))
    } else {
        sequence_path.with_file_name(format!("{name}.journal"))
    }
}

/// A fresh run over a journal that records an unfinished batch would lose the only record of
/// where the half-wound mandrel stands: refused (exit 2, nothing sent), naming the `--resume`
/// command. With `--restart` the name the old journal is to be kept under, `NAME.journal.N`
/// (never an existing file), is returned: it is moved there just before the new journal is
/// written. A journal whose batch is done may be replaced.
fn keep_unfinished_journal(
    args: &RunArgs,
    mode: RunMode,
    journal_path: &Path,
) -> Result<Option<PathBuf>, Failure> {
    if !journal_path.exists() {
        return Ok(None);
    }
    let state = match journal::read(journal_path) {
        Ok(records) => {
            if journal::batch_done(&records) {
                return Ok(None);
            }
            let items = records
                .iter()
                .filter(|r| journal::kind(r) == Some("item_done"))
                .count();
            format!("an unfinished batch, {items} paths done")
        }
        Err(e) => format!("a batch this run cannot read ({e})"),
    };
    if !args.restart {
        return Err(Failure::input(format!(
            "{}: the journal records {state}; nothing was sent. Resume it with: {}; or start \
             over with --restart (the journal is kept as {}.N)",
            journal_path.display(),
            resume_command(args, mode, journal_path),
            journal_path.display()
        )));
    }
    let kept = (1..10_000)
        .map(|n| PathBuf::from(format!("{}.{n}", journal_path.display())))
        .find(|p| !p.exists())
        .ok_or_else(|| {
            Failure::input(format!(
                "{}: no free name to keep the old journal under",
                journal_path.display()
            ))
        })?;
    Ok(Some(kept))
}

/// Where `--live` serves when no address is named: loopback only.
pub const DEFAULT_LIVE: &str = "127.0.0.1:8765";

/// Cell time between two recorded eye poses on the simulated cell, s.
pub const RECORD_STEP_S: f64 = 0.02;

/// `HOST:PORT` of `--live`.
fn live_address(a: &str) -> Result<(String, u16), Failure> {
    let (host, port) = a
        .rsplit_once(':')
        .ok_or_else(|| Failure::input(format!("--live {a}: expected HOST:PORT")))?;
    let port = port
        .parse::<u16>()
        .map_err(|_| Failure::input(format!("--live {a}: the port must be 0–65535")))?;
    Ok((host.trim_matches(['[', ']']).to_string(), port))
}

/// Opens the recording and live server the run asks for, and on the simulated cell makes the
/// cell report the eye and the mandrel to them.
fn recorder(
    args: &RunArgs,
    sim: Option<&SimCell>,
    drive: &mandrel_drive::Drive,
    contacts: Vec<(Point3<f64>, Point3<f64>)>,
) -> Result<Option<Arc<cell::record::Recorder>>, Failure> {
    if args.record.is_none() && args.live.is_none() {
        return Ok(None);
    }
    let sinks = cell::record::Sinks {
        mcap: args.record.clone(),
        live: args.live.as_deref().map(live_address).transpose()?,
    };
    let epoch_ns = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64);
    let rec = Arc::new(cell::record::Recorder::open(&sinks, epoch_ns).map_err(Failure::from_cell)?);
    // The rotation axis's foot in the cell frame: the job's cell, else the thesis cell.
    let origin = sequences::Job::load(&args.input).ok().map_or(
        nalgebra::Vector3::new(800.0, 0.0, 300.0),
        |(job, _)| {
            let (setup, _) = cell::plan::tool::setup(&job);
            setup
                .calibration
                .transform(setup.robot_distance_mm, setup.mandrel_height_mm)
                .origin
        },
    );
    rec.set_mandrel_axis(origin, drive.steps_per_deg());
    if let Some(sim) = sim {
        let r = rec.clone();
        let mut next = 0.0;
        let mut commanded = None;
        sim.with(|p| {
            p.observer = Some(cell::sim::Observer(Box::new(move |o| {
                // The commanded pose whenever the move under way changes (a stored program's
                // points; a MOVE_IMMEDIATE is recorded from its telegram by the link's tap).
                if let Some(c) = o.target
                    && o.target != commanded
                {
                    commanded = o.target;
                    r.eye(o.t_s, &Point3::from(c.xyz_mm), &from_components(c.q), false);
                }
                if o.t_s < next {
                    return;
                }
                next = o.t_s + RECORD_STEP_S;
                r.eye(
                    o.t_s,
                    &Point3::from(o.eye.xyz_mm),
                    &from_components(o.eye.q),
                    true,
                );
                r.mandrel_frame(o.t_s, &origin, o.drive_rad);
                r.mandrel_angle(o.t_s, o.commanded_drive_rad, o.drive_rad);
                // The free fibre: from the eye to the tangent point of the planned pose nearest
                // the eye, carried into the cell frame by the mandrel's angle as `/tf` carries the
                // fibre's scene.
                let eye = Point3::from(o.eye.xyz_mm);
                if let Some((_, tangent)) = contacts.iter().min_by(|a, b| {
                    (a.0 - eye)
                        .norm_squared()
                        .total_cmp(&(b.0 - eye).norm_squared())
                }) {
                    let turn = nalgebra::UnitQuaternion::from_axis_angle(
                        &nalgebra::Vector3::z_axis(),
                        o.drive_rad,
                    );
                    r.free_fibre(o.t_s, &eye, &(Point3::from(origin) + turn * tangent.coords));
                }
            })));
        })
        .map_err(Failure::runtime)?;
    }
    if let Some(port) = rec.live_port() {
        let _ = super::print(&format!(
            "serving the run live for Foxglove on port {port}\n"
        ));
    }
    Ok(Some(rec))
}

fn mode_of(m: ModeArg) -> RunMode {
    match m {
        ModeArg::Discrete => RunMode::Discrete,
        ModeArg::Fine => RunMode::Fine,
        ModeArg::Medium => RunMode::Medium,
        ModeArg::Continuous => RunMode::Continuous,
    }
}

/// The collision and snag check of `job`'s plan: a finding is exit code 3 unless `--force`.
fn clearance_gate(
    job: &sequences::Job,
    text: &str,
    path: &Path,
    plan: cell::plan::tool::JobPlan,
    force: bool,
) -> Result<(), Failure> {
    let checked = cell::plan::check::check(job, text, path, plan).map_err(Failure::from_cell)?;
    if !checked.report.is_clear() && !force {
        return Err(Failure {
            message: format!(
                "{}: {} (windcell check {} shows where; --force winds anyway)",
                path.display(),
                cell::plan::check::summary(&checked),
                path.display()
            ),
            exit_code: super::check::EXIT_FINDING,
        });
    }
    Ok(())
}

/// The pre-run gate of a sequence (seed 001 §5.6.3): with `--job`, every control file the
/// sequence loads must be that job's plan line for line (so the plan's checks of limits, reach,
/// entry angle and speeds hold for it: exit code 2 otherwise, no override), then the job's
/// collision check gates the run (exit code 3 unless `--force`). Without the job there is no
/// mandrel to check the clearance against: the gate fails unless `--force`.
fn sequence_gate(args: &RunArgs, loaded: &Loaded) -> Result<Option<Clearance>, Failure> {
    let Some(job_path) = &args.job else {
        return Ok(None);
    };
    let (job, text) = sequences::Job::load(job_path).map_err(Failure::input)?;
    // A sequence of more paths than the job has is its sweep (`windcell sweep`, one path per
    // program): the job expanded as the sweep did is the plan to hold the files to.
    let job = match u8::try_from(loaded.items.len())
        .ok()
        .and_then(std::num::NonZeroU8::new)
    {
        Some(n) if usize::from(n.get()) != job.paths.len() => {
            cell::plan::sweep::expand(&job, job_path, n).unwrap_or(job)
        }
        _ => job,
    };
    let plan = cell::plan::tool::plan(&job, &text, job_path).map_err(Failure::from_cell)?;
    let planned = batch::files_of_job(
        &cell::plan::files::control_files(&job, &plan).map_err(Failure::from_cell)?,
    );
    let dir = args.input.parent().unwrap_or(Path::new("."));
    let run_path = args
        .run_file
        .clone()
        .unwrap_or_else(|| args.input.with_extension("RUN"));
    let mut names: Vec<(PathBuf, String)> = vec![(args.input.clone(), "SEQ".into())];
    if run_path.exists() {
        names.push((run_path, "RUN".into()));
    }
    for item in &loaded.items {
        names.push((
            dir.join(format!("{}.ROB", item.name)),
            format!("{}.ROB", item.name),
        ));
        if item.ind.is_some() {
            names.push((
                dir.join(format!("{}.IND", item.name)),
                format!("{}.IND", item.name),
            ));
        }
    }
    for (path, key) in names {
        let on_disk = std::fs::read_to_string(&path)
            .map_err(|e| Failure::input(format!("{}: {e}", path.display())))?;
        let Some(want) = planned.get(&key) else {
            return Err(Failure::input(format!(
                "{}:1:1: not a file of the plan of {} (plan the job again: windcell plan {} -o DIR)",
                path.display(),
                job_path.display(),
                job_path.display()
            )));
        };
        if let Some(line) = first_difference(&on_disk, want) {
            return Err(Failure::input(format!(
                "{}:{line}:1: differs from the plan of {} (edited by hand or planned from another job: plan it again with windcell plan {} -o DIR)",
                path.display(),
                job_path.display(),
                job_path.display()
            )));
        }
    }
    Ok(Some(Clearance {
        job,
        text,
        path: job_path.clone(),
        plan,
    }))
}

/// Facets per circumference of the mandrel surface a recording shows.
const SCENE_FACETS: usize = 48;
/// Section spacing of the mandrel surface a recording shows, mm.
const SCENE_SPACING_MM: f64 = 5.0;

/// What a recording shows of the job: the mandrel surface (TRIASYM, [`SCENE_FACETS`] facets,
/// sections at most [`SCENE_SPACING_MM`] apart) and each path's desired fibre at the start, and
/// on the simulated cell each path's laid fibre at its end (the placement model over the cell's
/// trace, `cell::predict::laid_in_run`). Mandrel frame. Made without the job (a bare sequence)
/// or when the mandrel cannot be meshed: never.
struct Scene {
    job: sequences::Job,
    tube: paths::Tube,
    triangles: Vec<[Point3<f64>; 3]>,
    paths: Vec<cell::plan::tool::PlannedPath>,
}

fn scene(c: &Clearance) -> Option<Scene> {
    let tube = cell::plan::tool::mandrel_in(&c.job, &c.text, &c.path).ok()?;
    let mesh = paths::mesh::triasym::tube(&tube, SCENE_FACETS, SCENE_SPACING_MM, true).ok()?;
    let triangles = (0..mesh.triangles().len())
        .map(|t| mesh.corners(t))
        .collect();
    Some(Scene {
        job: c.job.clone(),
        tube,
        triangles,
        paths: c.plan.paths.clone(),
    })
}

impl Scene {
    /// The surface and every desired fibre, at the run's start.
    fn record_start(&self, rec: &cell::record::Recorder) {
        rec.mandrel_surface(0.0, &self.triangles);
        for p in &self.paths {
            rec.fibre(0.0, &p.name, &p.desired_mm, &[]);
        }
    }

    /// Path `name`'s laid fibre over `trace` between `after_s` and `done_s` (cell time), recorded
    /// at `done_s`; a placement that fails is logged as a warning, the run goes on.
    fn record_laid(
        &self,
        rec: &cell::record::Recorder,
        name: &str,
        trace: &cell::sim::Trace,
        after_s: f64,
        done_s: f64,
    ) {
        let Some(path) = self.paths.iter().find(|p| p.name == name) else {
            return;
        };
        match cell::predict::laid_in_run(&self.job, &self.tube, path, trace, after_s, done_s) {
            Ok(laid) => rec.fibre(done_s, name, &path.desired_mm, &laid),
            Err(e) => rec.log(done_s, cell::record::Level::Warning, &e.to_string()),
        }
    }
}

/// What the collision gate checks: the job, its text and file, its plan.
struct Clearance {
    job: sequences::Job,
    text: String,
    path: PathBuf,
    plan: cell::plan::tool::JobPlan,
}

/// The collision gate, after every exit-code-2 check: the job's check (exit 3 on a finding), or
/// no job to check against (exit 3); `--force` passes either (and the journal says so).
fn gate(args: &RunArgs, clearance: Option<Clearance>) -> Result<(), Failure> {
    match clearance {
        Some(c) => clearance_gate(&c.job, &c.text, &c.path, c.plan, args.force),
        None if args.force => Ok(()),
        None => Err(Failure {
            message: format!(
                "{}: no collision check without the job the files were planned from (--job JOB.toml; --force winds anyway)",
                args.input.display()
            ),
            exit_code: super::check::EXIT_FINDING,
        }),
    }
}

/// The first line (from 1) where `a` and `b` differ, if they do.
fn first_difference(a: &str, b: &str) -> Option<usize> {
    let (mut la, mut lb) = (a.lines(), b.lines());
    let mut n = 1;
    loop {
        match (la.next(), lb.next()) {
            (None, None) => return None,
            (x, y) if x != y => return Some(n),
            _ => n += 1,
        }
    }
}

/// Loads the batch and the cell: a job is planned in memory.
type Load = (Loaded, Cell, Reach, String, Option<Clearance>);

fn load(args: &RunArgs) -> Result<Load, Failure> {
    let mode = args.mode.map(mode_of);
    let (loaded, job_cell, reach, name, clearance) = if is_job_file(&args.input) {
        let (mut job, text) = sequences::Job::load(&args.input).map_err(Failure::input)?;
        cell::plan::tool::irb62_only(&job, &text, &args.input, "run")
            .map_err(Failure::from_cell)?;
        // A mode given on the command line is planned for (its speeds and guards), not only
        // applied to files planned for another.
        if let Some(m) = mode {
            let span = job.cell.movement.span();
            job.cell.movement = toml::Spanned::new(span, m.movement());
        }
        let plan = cell::plan::tool::plan(&job, &text, &args.input).map_err(Failure::from_cell)?;
        let files = cell::plan::files::control_files(&job, &plan).map_err(Failure::from_cell)?;
        // Read back as from disk; the pre-run check (`check`) is then the one every input gets.
        let loaded = batch::of_job(&args.input, &files, mode).map_err(Failure::from_cell)?;
        let reach = batch::envelope(&job);
        let name = job.name.get_ref().clone();
        let c = Cell::of_job(&job, &args.input).map_err(Failure::from_cell)?;
        // The collision and snag check gates the run (exit 3) once every exit-2 check passed;
        // only --force overrides it, and the run's `started` record says so.
        let clearance = Clearance {
            job,
            text,
            path: args.input.clone(),
            plan,
        };
        (loaded, Some(c), reach, name, Some(clearance))
    } else {
        let loaded =
            batch::load(&args.input, args.run_file.as_deref(), mode).map_err(Failure::from_cell)?;
        let name = args
            .input
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or("batch")
            .to_string();
        let clearance = sequence_gate(args, &loaded)?;
        let reach = clearance
            .as_ref()
            .map_or_else(Reach::default, |c| batch::envelope(&c.job));
        (loaded, None, reach, name, clearance)
    };
    // The drive the job's steps were planned with: the job's own cell, or the job a sequence
    // was checked against.
    let planned = match (&job_cell, &clearance) {
        (Some(c), _) => Some((c.drive, args.input.clone())),
        (None, Some(c)) => Some((
            Cell::of_job(&c.job, &c.path)
                .map_err(Failure::from_cell)?
                .drive,
            c.path.clone(),
        )),
        (None, None) => None,
    };
    let cell = match &args.cell {
        Some(p) => Cell::load(p).map_err(Failure::from_cell)?,
        None => job_cell.unwrap_or_else(Cell::simulated),
    };
    if let Some((drive, job)) = planned {
        super::same_drive(&cell, drive, &job)?;
    }
    Ok((loaded, cell, reach, name, clearance))
}

fn open_port(
    path: &str,
) -> Result<asea_protocol::link::SerialLink<Box<dyn serialport::SerialPort>>, Failure> {
    asea_protocol::link::open_serial(
        path,
        asea_protocol::link::DEFAULT_BAUD,
        asea_protocol::link::DEFAULT_CHAR_FORMAT,
    )
    .map_err(|e| Failure::input(format!("{path}: {e}")))
}

/// Longest wait for one indexer reply line on a serial port.
const INDEXER_REPLY_TIMEOUT: std::time::Duration = std::time::Duration::from_millis(1500);

/// The devices of `cell` (and the simulated cell, to keep its log). A serial port is opened with
/// an exclusive lock (`serialport`'s `flock`): a port another program holds is refused as bad
/// input.
pub fn devices(
    cell: &Cell,
    log: Option<&Path>,
    slot: &RecordSlot,
) -> Result<(Devices, Option<SimCell>), Failure> {
    paced_devices(cell, log, slot, None)
}

/// [`devices`] with the simulated cell's clock paced at `speed` (`None`: the fast clock;
/// `cli::run_clock`).
pub fn paced_devices(
    cell: &Cell,
    log: Option<&Path>,
    slot: &RecordSlot,
    speed: Option<f64>,
) -> Result<(Devices, Option<SimCell>), Failure> {
    match &cell.devices {
        cellfile::Devices::Simulated => {
            let sim = SimCell::new(&SimCellConfig {
                drive: cell.drive,
                opto_delay_s: cell.opto_delay_s,
                arm: cell.arm,
                speed,
                ..SimCellConfig::default()
            });
            if let Some(p) = log {
                let f = std::fs::File::create(p)
                    .map_err(|e| Failure::input(format!("{}: {e}", p.display())))?;
                sim.log_to(f).map_err(Failure::runtime)?;
            }
            Ok((sim.recorded_devices(cell.drive, slot), Some(sim)))
        }
        cellfile::Devices::Serial {
            robot,
            indexer,
            sync,
        } => {
            use mandrel_drive::sync::{ModemLine, Pin};
            let robot_port = open_port(robot)?;
            let indexer_port = open_port(indexer)?;
            let sync: Box<dyn cell::run::device::SyncLines> = match sync {
                Some(path) if path.starts_with("unix:") => {
                    let p = Path::new(path.trim_start_matches("unix:"));
                    Box::new(
                        cell::run::device::SocketSync::connect(p)
                            .map_err(|e| Failure::input(format!("{}: {e}", p.display())))?,
                    )
                }
                Some(path) => {
                    let port = Arc::new(Mutex::new(open_port(path)?.0));
                    Box::new(cell::run::device::WiredSync {
                        start: Box::new(ModemLine::new(port.clone(), Pin::Rts, false)),
                        in_position: Box::new(ModemLine::new(port.clone(), Pin::Cts, false)),
                        estop: Some(Box::new(ModemLine::new(port, Pin::Dsr, false))),
                    })
                }
                None => Box::new(cell::run::device::NoSync),
            };
            let time: Arc<dyn cell::run::device::Timebase> =
                Arc::new(cell::run::device::WallClock::new());
            let client_cfg = asea_protocol::ClientConfig::default();
            // On serial ports the devices' own reports are the only source of `/tf`.
            let robot_port =
                LinkTap::robot(robot_port, client_cfg.frame, slot.clone(), time.clone())
                    .reporting_positions();
            let client = asea_protocol::Client::new(robot_port, client_cfg);
            let indexer_cfg = mandrel_drive::IndexerConfig {
                drive: cell.drive,
                // A card answers within milliseconds; the margin is for the host (a loaded
                // PC, or simulators on pseudo-terminals sharing its cores), where 500 ms
                // stopped runs at their first status poll.
                reply_timeout: INDEXER_REPLY_TIMEOUT,
                ..mandrel_drive::IndexerConfig::default()
            };
            let indexer_link =
                LinkTap::indexer(indexer_port, slot.clone(), time.clone()).reporting_positions();
            let setup = cell::run::transfer::IndexerSetup {
                drive: cell.drive,
                start_velocity_command: true,
            };
            let mandrel: Box<dyn cell::run::device::MandrelDevice> = match cell.dialect {
                cellfile::IndexerDialect::X => Box::new(cell::run::device::XIndexer::new(
                    mandrel_drive::XClient::new(indexer_link, indexer_cfg),
                    setup,
                )),
                cellfile::IndexerDialect::Grbl => Box::new(cell::run::device::GrblIndexer::new(
                    mandrel_drive::GrblClient::new(indexer_link, indexer_cfg),
                    setup,
                )),
            };
            Ok((
                Devices {
                    robot: Box::new(cell::run::device::ProtocolRobot::new(client)),
                    mandrel,
                    sync: Box::new(SyncTap::new(sync, slot.clone(), time.clone())),
                    time,
                },
                None,
            ))
        }
    }
}

/// Runs `windcell run`.
pub fn run(args: RunArgs) -> Result<(), Failure> {
    // SIGXFSZ caught, not left to its default action: a file-size limit comes back as EFBIG
    // from the journal's write, which the journal cuts back to its last whole record, and the
    // run stops both devices and says so in one line, where the signal would kill the process
    // with no stop sent and no line.
    signal_hook::flag::register(
        signal_hook::consts::SIGXFSZ,
        Arc::new(std::sync::atomic::AtomicBool::new(false)),
    )
    .map_err(Failure::runtime)?;
    let checked = check(&args)?;
    let Checked {
        batch,
        cell,
        journal_path,
        keep_as,
        resumed,
        devices,
        sim,
        slot,
        scene,
    } = checked;
    let (journal, from, fresh) = open_journal(&journal_path, keep_as, resumed)?;
    // Each planned pose's eye (cell frame) and tangent point (mandrel frame), for the free fibre.
    let contacts = scene.as_ref().map_or_else(Vec::new, |sc| {
        sc.paths
            .iter()
            .flat_map(|p| {
                std::iter::once(&p.plan.start)
                    .chain(p.plan.segments.iter().map(|s| &s.pose))
                    .map(|pose| (pose.eye_mm, pose.tangent_point_mm))
            })
            .collect()
    });
    let rec = recorder(&args, sim.as_ref(), &cell.drive, contacts)?;
    if let Some(r) = &rec {
        slot.set(r.clone());
        if let Some(sc) = &scene {
            sc.record_start(r);
        }
    }
    let display = Display::new(args.json, std::io::stdout().is_terminal(), &batch, &from);
    announce(&display, &args, &batch, &cell, &journal_path, fresh, &from);
    let wound = wind(
        &args,
        &batch,
        devices,
        sim.as_ref(),
        rec.clone(),
        scene,
        journal,
        from,
        fresh,
        display,
    )?;
    if let Some(r) = rec {
        // Detach the simulated cell's observer, then finalise (summary and indexes).
        if let Some(sim) = &sim {
            let _ = sim.with(|p| p.observer = None);
        }
        if let Ok(r) = Arc::try_unwrap(r) {
            r.finish().map_err(Failure::from_cell)?;
        }
    }
    let cell_time_s = sim.as_ref().map(|s| {
        use asea_protocol::clock::Clock as _;
        s.clock().now_s()
    });
    report(&args, &batch, &journal_path, wound, cell_time_s)
}

/// What the checks hand to the winding: everything decided before a byte is sent.
struct Checked {
    batch: Batch,
    cell: Cell,
    journal_path: PathBuf,
    /// Where an unfinished journal is kept when `--restart` starts over.
    keep_as: Option<PathBuf>,
    /// The journal to resume and where it stands.
    resumed: Option<(Journal, ResumePoint)>,
    devices: Devices,
    sim: Option<SimCell>,
    slot: RecordSlot,
    scene: Option<Scene>,
}

/// The one rule for outputs (`cell::plan::output::check_outputs`): the journal, the log and the
/// recording, against every file the run reads and against each other.
fn check_outputs(args: &RunArgs, batch: &Batch, journal: &Path) -> Result<(), Failure> {
    // The live server's address is an output too: refused here, before the journal is made.
    if let Some(a) = &args.live {
        live_address(a)?;
    }
    let dir = args.input.parent().unwrap_or(Path::new(""));
    let mut inputs = vec![args.input.clone()];
    if args.input.extension().is_some_and(|e| e == "SEQ") {
        inputs.push(args.input.with_extension("RUN"));
    }
    inputs.extend(
        args.run_file
            .iter()
            .chain(&args.job)
            .chain(&args.cell)
            .cloned(),
    );
    for item in &batch.items {
        inputs.push(dir.join(format!("{}.ROB", item.name)));
        inputs.push(dir.join(format!("{}.IND", item.name)));
    }
    for file in std::iter::once(journal)
        .chain(args.log.as_deref())
        .chain(args.record.as_deref())
    {
        cell::plan::output::check_file(file).map_err(Failure::from_cell)?;
    }
    let outputs: Vec<&Path> = std::iter::once(journal)
        .chain(args.log.as_deref())
        .chain(args.record.as_deref())
        .collect();
    cell::plan::output::check_outputs(&outputs, &inputs).map_err(Failure::from_cell)
}

/// Every refusal `run` can make before it moves (exit 2: the files, the pre-run check of every
/// instruction, the sync lines for the mode, the journal; exit 3: the collision gate), then the
/// devices made (nothing sent yet).
fn check(args: &RunArgs) -> Result<Checked, Failure> {
    let (loaded, cell, reach, name, clearance) = load(args)?;
    // The pre-run check: every file converted and checked before anything is sent.
    let batch = Batch::new(
        loaded.items.clone(),
        loaded.mode,
        loaded.job_id.clone(),
        cell.drive,
        reach,
    )
    .map_err(|e| match &clearance {
        // A job's files are planned here: the refusal is placed at the job's value, as `plan`
        // places it.
        Some(c) => batch::not_runnable(&c.job, &c.text, &c.path, e),
        None => e,
    })
    .map_err(Failure::from_cell)?;
    let journal_path = args
        .resume
        .clone()
        .or(args.journal.clone())
        .unwrap_or_else(|| default_journal(args, &loaded.sequence_path, &name));
    // A GRBL indexer has no trigger input: program mode cannot arm its moves.
    if batch.mode != RunMode::Discrete && cell.dialect == cellfile::IndexerDialect::Grbl {
        return Err(Failure::from_cell(cell::Error::Cell {
            file: PathBuf::from(&cell.source),
            place: cell.dialect_place,
            problem: cell::error::CellProblem::DialectMode {
                dialect: cell.dialect.keyword(),
                mode: batch.mode.keyword(),
            },
        }));
    }
    check_outputs(args, &batch, &journal_path)?;
    // Everything `run` can know before it moves is refused here, before the journal is written
    // or a device touched: program mode needs the sync lines.
    if batch.mode != RunMode::Discrete
        && let cell::run::cellfile::Devices::Serial { sync: None, .. } = &cell.devices
    {
        return Err(Failure::input(format!(
            "{}: {} mode needs the sync lines (App. D: the start and in-position lines pace a \
             stored program): name a sync port in the cell file (examples/cell-serial.toml), or \
             wind in discrete mode",
            cell.source,
            batch.mode.keyword()
        )));
    }
    let keep_as = match args.resume {
        None => keep_unfinished_journal(args, batch.mode, &journal_path)?,
        Some(_) => None,
    };
    let resumed = match &args.resume {
        Some(p) => {
            if !p.exists() {
                return Err(Failure::input(format!(
                    "{}: no such journal to resume",
                    p.display()
                )));
            }
            let (j, records) = Journal::resume(p).map_err(Failure::input)?;
            let from = cell::run::coordinator::resume_point(&batch, &records)
                .map_err(|e| Failure::from_cell(e.in_journal(p)))?;
            if journal::batch_done(&records) {
                return Err(Failure::input(format!(
                    "{}: the batch is already done",
                    p.display()
                )));
            }
            Some((
                j,
                ResumePoint {
                    // The built-in simulated cell is powered up anew by each process: it stands
                    // where the journal says because nothing else can say otherwise.
                    rereference: args.rereference
                        || matches!(cell.devices, cell::run::cellfile::Devices::Simulated),
                    ..from
                },
            ))
        }
        None => None,
    };
    let slot = RecordSlot::default();
    let speed = super::run_clock::pace(
        args.clock,
        args.speed,
        args.live.is_some(),
        matches!(cell.devices, cellfile::Devices::Simulated),
    )?;
    let (devices, sim) = paced_devices(&cell, args.log.as_deref(), &slot, speed)?;
    let scene = if args.record.is_some() || args.live.is_some() {
        clearance.as_ref().and_then(scene)
    } else {
        None
    };
    // Every exit-code-2 check has passed: the collision gate (exit 3 unless --force).
    gate(args, clearance)?;
    Ok(Checked {
        batch,
        cell,
        journal_path,
        keep_as,
        resumed,
        devices,
        sim,
        slot,
        scene,
    })
}

/// The journal: the resumed one, or a new one (an unfinished one kept first under `keep_as`).
fn open_journal(
    journal_path: &Path,
    keep_as: Option<PathBuf>,
    resumed: Option<(Journal, ResumePoint)>,
) -> Result<(Journal, ResumePoint, bool), Failure> {
    if let Some((j, from)) = resumed {
        return Ok((j, from, false));
    }
    if let Some(kept) = &keep_as {
        std::fs::rename(journal_path, kept).map_err(|e| {
            Failure::input(format!(
                "{}: cannot keep the old journal as {}: {e}",
                journal_path.display(),
                kept.display()
            ))
        })?;
    }
    let journal = Journal::create(journal_path).map_err(Failure::input)?;
    Ok((journal, ResumePoint::default(), true))
}

/// The run's first line (or `started` event).
fn announce(
    display: &Display,
    args: &RunArgs,
    batch: &Batch,
    cell: &Cell,
    journal_path: &Path,
    fresh: bool,
    from: &ResumePoint,
) {
    if args.json {
        display.line(
            &json!({"event": "started", "job": args.input.display().to_string(),
                "mode": batch.mode.keyword(), "cell": cell.source,
                "journal": journal_path.display().to_string(), "resumed": !fresh,
                "force": args.force})
            .to_string(),
        );
    } else {
        display.line(&format!(
            "winding {} ({} paths, {} mode) on {}{}; journal {}",
            args.input.display(),
            batch.items.len(),
            batch.mode.keyword(),
            cell.source,
            if args.cell.is_some() {
                " (--cell wins over the job's [cell])"
            } else {
                ""
            },
            journal_path.display()
        ));
        if !fresh {
            let item = from.items_done + 1;
            let name = batch
                .items
                .get(from.items_done)
                .map_or("", |i| i.name.as_str());
            let segments = display.segments_of(item);
            display.line(&if from.program_started {
                format!(
                    "resuming path {item} ({name}) in its program, from where the devices stand"
                )
            } else {
                format!(
                    "resuming path {item} ({name}) after segment {} of {segments}",
                    display.position().segment
                )
            });
        }
    }
}

/// What the winding left: the coordinator's result and wall time, the paths done, the display.
struct Wound {
    result: Result<(), cell::run::coordinator::Stopped>,
    wall: std::time::Duration,
    paths: Vec<(String, u8, f64)>,
    display: Display,
}

/// The work: the coordinator on its own thread owning the devices, the Ctrl-C and console tasks
/// that stop it, and the display of its events (docs/ARCHITECTURE.md, "`windcell run`").
#[allow(clippy::too_many_arguments)]
fn wind(
    args: &RunArgs,
    batch: &Batch,
    devices: Devices,
    sim: Option<&SimCell>,
    rec: Option<Arc<cell::record::Recorder>>,
    scene: Option<Scene>,
    journal: Journal,
    from: ResumePoint,
    fresh: bool,
    display: Display,
) -> Result<Wound, Failure> {
    // One stop request for the signal, the console and the coordinator: making it abandons the
    // exchange under way on both links and wakes the coordinator, which sends the stops at once.
    let stop = StopRequest::new(&devices);
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .map_err(Failure::runtime)?;
    let rec_events = rec.clone();
    let (tx, mut rx) = tokio::sync::mpsc::unbounded_channel::<(f64, Event)>();
    let clock = devices.time.clone();
    // The laid fibre needs the recorder, the simulated cell's trace and the job's scene.
    let laying = match (&rec, sim, scene) {
        (Some(r), Some(sim), Some(sc)) => {
            sim.with(|p| p.trace = Some(cell::sim::Trace::default()))
                .map_err(Failure::runtime)?;
            Some((r.clone(), sim.clone(), sc))
        }
        _ => None,
    };
    let standby = args.standby;
    let force = args.force;
    let engine_stop = stop.clone();
    let batch_for_engine = batch.clone();
    let outcome = runtime.block_on(async move {
        // Ctrl-C.
        let s1 = stop.clone();
        tokio::spawn(async move {
            if tokio::signal::ctrl_c().await.is_ok() {
                s1.request("Ctrl-C");
            }
        });
        // The console: `s` + Enter.
        let s2 = stop.clone();
        tokio::spawn(async move {
            use tokio::io::AsyncBufReadExt;
            let mut lines = tokio::io::BufReader::new(tokio::io::stdin()).lines();
            while let Ok(Some(line)) = lines.next_line().await {
                if line.trim() == "s" {
                    s2.request("the console's stop");
                }
            }
        });
        // The coordinator, owning the devices. Each event is stamped with the cell's clock as it
        // happens; at each path's end on the simulated cell the recording gets its laid fibre
        // (the coordinator waits meanwhile; the virtual clock with it).
        let engine = tokio::task::spawn_blocking(move || {
            let mut after_s = 0.0;
            let mut sink = |e: Event| {
                let t = clock.now_s();
                if let (Event::PathDone { path, .. }, Some((r, sim, sc))) = (&e, &laying) {
                    // The trace restarts with each path: its memory is one path's.
                    if let Ok(Some(trace)) =
                        sim.with(|p| p.trace.replace(cell::sim::Trace::default()))
                    {
                        sc.record_laid(r, path, &trace, after_s, t);
                    }
                    after_s = t;
                }
                let _ = tx.send((t, e));
            };
            let mut c = Coordinator::with_stop(devices, engine_stop, journal, &mut sink);
            let t0 = std::time::Instant::now();
            let r = c.run(&batch_for_engine, &from, fresh, standby, force);
            (r, t0.elapsed())
        });
        // The display.
        let mut paths = Vec::new();
        while let Some((t, e)) = rx.recv().await {
            display.event(&e);
            if let Some(r) = &rec_events {
                r.log(t, cell::record::Level::Info, &e.to_string());
            }
            if let Event::PathDone {
                path,
                program,
                time_s,
                ..
            } = &e
            {
                paths.push((path.clone(), *program, *time_s));
            }
        }
        (engine.await, paths, display)
    });
    runtime.shutdown_background();
    let (joined, paths, display) = outcome;
    display.finish();
    let (result, wall) =
        joined.map_err(|e| Failure::runtime(format!("the coordinator thread failed: {e}")))?;
    Ok(Wound {
        result,
        wall,
        paths,
        display,
    })
}

/// The run's last lines: each path's time and the batch's, or where it stopped and the resume
/// command (exit 130 for the operator's stop, 1 for a fault).
fn report(
    args: &RunArgs,
    batch: &Batch,
    journal_path: &Path,
    wound: Wound,
    cell_time: Option<f64>,
) -> Result<(), Failure> {
    let Wound {
        result,
        wall,
        paths,
        display,
    } = wound;
    match result {
        Ok(()) => {
            if display.json {
                let first = batch.items.len() - paths.len();
                let list: Vec<_> = paths
                    .iter()
                    .enumerate()
                    .map(|(k, (n, p, t))| {
                        let mut path = json!({"name": n, "program": p, "mode": batch.mode.keyword(), "time_s": t});
                        if let Some((approach, winding)) = display.split_s(first + k + 1, *t) {
                            path["approach_s"] = json!(approach);
                            path["winding_s"] = json!(winding);
                        }
                        path
                    })
                    .collect();
                display.line(&json!({"event": "done", "paths": list}).to_string());
            } else {
                let first = batch.items.len() - paths.len();
                for (k, (n, p, t)) in paths.iter().enumerate() {
                    // The path's time from its approach to its end, and what it holds (`plan`
                    // and `predict` time the winding alone).
                    let split = display.split_s(first + k + 1, *t).map_or(
                        String::new(),
                        |(approach, winding)| {
                            format!(": approach {approach:.1} s, winding {winding:.1} s")
                        },
                    );
                    display.line(&format!(
                        "done: {n} (program {p}, {}) in {t:.1} s{split}",
                        batch.mode.keyword()
                    ));
                }
                display.line(&format!(
                    "batch done: {} paths{}",
                    paths.len(),
                    cell_time
                        .map(|t| format!(
                            ", {t:.1} s of simulated cell time in {:.2} s",
                            wall.as_secs_f64()
                        ))
                        .unwrap_or_default()
                ));
            }
            Ok(())
        }
        Err(stopped) => {
            let (why, code, event) = match &stopped.halt {
                Halt::Interrupted { reason } => (reason.clone(), EXIT_INTERRUPTED, "stopped"),
                Halt::Fault(fault) => (fault.to_string(), super::EXIT_RUNTIME, "fault"),
            };
            let mut resume = resume_command(args, batch.mode, journal_path);
            if stopped
                .halt
                .fault()
                .is_some_and(cell::run::coordinator::Fault::needs_rereference)
            {
                resume += " --rereference";
            }
            let stop_errors: Vec<String> =
                stopped.stop_errors.iter().map(|e| e.to_string()).collect();
            // The segment as the events named it (in program mode the indexer's count).
            let at = display.position();
            let wound_segment = if at.item == stopped.item {
                at.segment
            } else {
                0
            };

            if display.json {
                display.line(
                    &json!({"event": event, "item": stopped.item, "path": stopped.path,
                        "segment": wound_segment, "segments_done": stopped.segments_done, "reason": why,
                        "stop_errors": stop_errors, "resume": resume})
                    .to_string(),
                );
            }
            Err(Failure {
                message: format!(
                    "stopped at path {} ({}) after segment {wound_segment} of {} ({why}); {}; resume with: {resume}",
                    stopped.item,
                    stopped.path,
                    display.segments_of(stopped.item),
                    if stopped.stop_errors.is_empty() {
                        "both axes told to stop".to_string()
                    } else {
                        // Only the stops that went through are claimed.
                        format!(
                            "stop failed: {}; see that both axes stand still before resuming",
                            stop_errors.join(", ")
                        )
                    }
                ),
                exit_code: code,
            })
        }
    }
}

#[cfg(test)]
mod tests {
    use std::f64::consts::FRAC_PI_2;

    use paths::robot::Joints;

    use super::*;

    /// Lines are counted from 1; a file that ends early differs at the line after its last.
    #[test]
    fn first_difference_names_the_line() {
        assert_eq!(first_difference("a\nb\n", "a\nb\n"), None);
        assert_eq!(first_difference("", ""), None);
        assert_eq!(first_difference("a\nb\nc\n", "a\nb\nd\n"), Some(3));
        assert_eq!(first_difference("a\nb\n", "a\nb\nc\n"), Some(3));
        assert_eq!(first_difference("x\n", "y\n"), Some(1));
    }

    /// `--live HOST:PORT`, an IPv6 host in brackets; no port or a port beyond 16 bits refused.
    #[test]
    fn live_addresses_are_host_and_port() {
        assert_eq!(
            live_address("127.0.0.1:8765").unwrap(),
            ("127.0.0.1".to_string(), 8765)
        );
        assert_eq!(live_address("[::1]:0").unwrap(), ("::1".to_string(), 0));
        assert_eq!(
            live_address("cell-pc.local:9000").unwrap(),
            ("cell-pc.local".to_string(), 9000)
        );
        assert!(live_address("localhost").is_err());
        assert!(live_address("localhost:65536").is_err());
    }

    /// The envelope's bounds are where the arm's forward kinematics put the eye with every link
    /// stretched out: horizontally at shoulder height (the largest radius), straight up and
    /// straight down (the height range).
    #[test]
    fn the_envelope_is_the_arm_stretched_out() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/cylinder.toml");
        let (job, _) = sequences::Job::load(&path).unwrap();
        let arm = cell::plan::tool::arm(&job);
        let reach = batch::envelope(&job);
        let eye = |shoulder_rad: f64, elbow_rad: f64, pitch_rad: f64| {
            arm.forward(&Joints {
                base_yaw_rad: 0.3,
                shoulder_rad,
                elbow_rad,
                pitch_rad,
                roll_rad: 0.0,
            })
            .eye_mm
        };
        let out = eye(FRAC_PI_2, 0.0, 0.0);
        assert!((out.x.hypot(out.y) - reach.max_radius_mm).abs() < 1e-9);
        let up = eye(0.0, FRAC_PI_2, -FRAC_PI_2);
        assert!((up.z - reach.z_range_mm.1).abs() < 1e-9, "{up} {reach:?}");
        let down = eye(std::f64::consts::PI, -FRAC_PI_2, FRAC_PI_2);
        assert!(
            (down.z - reach.z_range_mm.0).abs() < 1e-9,
            "{down} {reach:?}"
        );
        assert_eq!(reach.min_radius_mm, 0.0);
    }
}
