//! `windcell run JOB.toml | DIR/NAME.SEQ [--run DIR/NAME.RUN]`: wind a batch on the cell (seed 001
//! §5.3.3–5.3.4, §5.6.4).
//!
//! Tasks (tokio): the coordinator runs on a blocking thread that owns both devices and the sync
//! lines; a signal task (Ctrl-C) and a console task (`s` + Enter) set the shared stop request the
//! coordinator looks at every control tick; the coordinator's events go through a channel to the
//! display task, which prints progress lines or `--json` events. docs/ARCHITECTURE.md, "Run".

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

use cell::batch::{self, Loaded};
use cell::cellfile::{self, Cell};
use cell::coordinator::{Batch, Coordinator, Devices, Event, Halt, Reach, ResumePoint, RunMode};
use cell::journal::Journal;
use cell::simcell::{SimCell, SimCellConfig};
use clap::{Args, ValueEnum};
use serde_json::json;

use super::Failure;

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
    /// The journal to write (default: beside the sequence or job, `NAME.journal`).
    #[arg(long, value_name = "FILE")]
    pub journal: Option<PathBuf>,
    /// Resume the batch this journal records.
    #[arg(long, value_name = "JOURNAL")]
    pub resume: Option<PathBuf>,
    /// Run every program in the robot's standby mode first (§5.3.1).
    #[arg(long)]
    pub standby: bool,
    /// Override the collision gate (written to the journal).
    #[arg(long)]
    pub force: bool,
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
            let (setup, _) = cell::tool::setup(&job);
            setup
                .calibration
                .transform(setup.robot_distance_mm, setup.mandrel_height_mm)
                .origin
        },
    );
    if let Some(sim) = sim {
        let r = rec.clone();
        let mut next = 0.0;
        sim.with(|p| {
            p.observer = Some(cell::simcell::Observer(Box::new(
                move |t, xyz, q, drive| {
                    if t < next {
                        return;
                    }
                    next = t + RECORD_STEP_S;
                    let eye = nalgebra::Point3::from(xyz);
                    let q = nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
                        q[0], q[1], q[2], q[3],
                    ));
                    r.eye(t, &eye, &q, true);
                    r.mandrel_frame(t, &origin, drive);
                    r.mandrel_angle(t, drive, drive);
                },
            )));
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
    }
}

/// Loads the batch and the cell: a job is planned in memory.
fn load(args: &RunArgs) -> Result<(Loaded, Cell, Reach, String), Failure> {
    let mode = args.mode.map(mode_of);
    let is_job = args
        .input
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("toml"));
    let (loaded, job_cell, reach, name) = if is_job {
        let (job, text) = sequences::Job::load(&args.input).map_err(Failure::input)?;
        let plan = cell::tool::plan(&job, &text, &args.input).map_err(Failure::from_cell)?;
        // The collision and snag check gates the run (exit 3); only --force overrides it, and
        // the run's `started` record says so.
        let checked = cell::check::check(&job, &text, &args.input, plan.clone())
            .map_err(Failure::from_cell)?;
        if !checked.report.is_clear() && !args.force {
            return Err(Failure {
                message: format!(
                    "{}: {} (windcell check {} shows where; --force winds anyway)",
                    args.input.display(),
                    cell::check::summary(&checked),
                    args.input.display()
                ),
                exit_code: super::check::EXIT_FINDING,
            });
        }
        let files = batch::files_of_job(
            &cell::tool::control_files(&job, &plan).map_err(Failure::from_cell)?,
        );
        let dir = args.input.parent().unwrap_or(Path::new("."));
        let mut loaded =
            batch::from_files(&files, mode, dir, &dir.join("RUN")).map_err(Failure::from_cell)?;
        loaded.sequence_path = args.input.clone();
        // The arm's envelope: the eye is at most the two links and the eye mechanism from the
        // shoulder (the full five-axis check is the plan's, which this job has just passed).
        let arm = cell::tool::arm(&job);
        let stretch = arm.upper_arm_mm + arm.forearm_mm + arm.eye_mechanism_mm;
        let reach = Reach {
            max_radius_mm: stretch,
            min_radius_mm: 0.0,
            z_range_mm: (
                arm.shoulder_height_mm - stretch,
                arm.shoulder_height_mm + stretch,
            ),
        };
        let c = Cell::of_job(&job, &args.input).map_err(Failure::from_cell)?;
        (loaded, Some(c), reach, job.name.get_ref().clone())
    } else {
        let loaded =
            batch::load(&args.input, args.run_file.as_deref(), mode).map_err(Failure::from_cell)?;
        let name = args
            .input
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or("batch")
            .to_string();
        (loaded, None, Reach::default(), name)
    };
    let cell = match &args.cell {
        Some(p) => Cell::load(p).map_err(Failure::from_cell)?,
        None => job_cell.unwrap_or_else(Cell::simulated),
    };
    Ok((loaded, cell, reach, name))
}

fn open_port(path: &str) -> Result<Box<dyn serialport::SerialPort>, Failure> {
    asea_protocol::link::open_serial(
        path,
        asea_protocol::link::DEFAULT_BAUD,
        asea_protocol::link::DEFAULT_CHAR_FORMAT,
    )
    .map_err(|e| Failure::input(format!("{path}: {e}")))
}

/// The devices of `cell` (and the simulated cell, to keep its log).
pub fn devices(cell: &Cell, log: Option<&Path>) -> Result<(Devices, Option<SimCell>), Failure> {
    match &cell.devices {
        cellfile::Devices::Simulated => {
            let sim = SimCell::new(&SimCellConfig {
                drive: cell.drive,
                opto_delay_s: cell.opto_delay_s,
                ..SimCellConfig::default()
            });
            if let Some(p) = log {
                let f = std::fs::File::create(p)
                    .map_err(|e| Failure::input(format!("{}: {e}", p.display())))?;
                sim.log_to(f).map_err(Failure::runtime)?;
            }
            Ok((sim.devices(cell.drive), Some(sim)))
        }
        cellfile::Devices::Serial {
            robot,
            indexer,
            sync,
        } => {
            use mandrel_drive::sync::{ModemLine, Pin};
            let robot_port = open_port(robot)?;
            let indexer_port = open_port(indexer)?;
            let sync: Box<dyn cell::device::SyncLines> = match sync {
                Some(path) if path.starts_with("unix:") => {
                    let p = Path::new(path.trim_start_matches("unix:"));
                    Box::new(
                        cell::device::SocketSync::connect(p)
                            .map_err(|e| Failure::input(format!("{}: {e}", p.display())))?,
                    )
                }
                Some(path) => {
                    let port = Arc::new(Mutex::new(open_port(path)?));
                    Box::new(cell::device::WiredSync {
                        start: Box::new(ModemLine::new(port.clone(), Pin::Rts, false)),
                        in_position: Box::new(ModemLine::new(port.clone(), Pin::Cts, false)),
                        estop: Some(Box::new(ModemLine::new(port, Pin::Dsr, false))),
                    })
                }
                None => Box::new(cell::device::NoSync),
            };
            let client =
                asea_protocol::Client::new(robot_port, asea_protocol::ClientConfig::default());
            let x = mandrel_drive::XClient::new(
                indexer_port,
                mandrel_drive::IndexerConfig {
                    drive: cell.drive,
                    ..mandrel_drive::IndexerConfig::default()
                },
            );
            let setup = cell::transfer::IndexerSetup {
                drive: cell.drive,
                start_velocity_command: true,
            };
            Ok((
                Devices {
                    robot: Box::new(cell::device::ProtocolRobot::new(client)),
                    mandrel: Box::new(cell::device::XIndexer::new(x, setup)),
                    sync,
                    time: Arc::new(cell::device::WallClock::new()),
                },
                None,
            ))
        }
    }
}

/// How the display prints.
struct Display {
    json: bool,
    terminal: bool,
}

impl Display {
    fn line(&self, text: &str) {
        let _ = super::print(&format!("{text}\n"));
    }

    fn event(&self, e: &Event) {
        match e {
            Event::Started { .. } | Event::Uploaded { .. } | Event::PathDone { .. } => {}
            Event::Segment {
                item,
                program,
                path,
                segment,
                segments,
                time_s,
            } => {
                if self.json {
                    self.line(
                        &json!({"event": "segment", "item": item, "program": program,
                            "path": path, "segment": segment, "time_s": time_s})
                        .to_string(),
                    );
                } else if self.terminal {
                    let _ = super::print(&format!(
                        "\r  path {item} {path}: segment {segment}/{segments}  t = {time_s:.1} s   "
                    ));
                    if segment == segments {
                        self.line("");
                    }
                } else if segment == segments || segment % 10 == 0 {
                    self.line(&format!(
                        "  path {item} {path}: segment {segment}/{segments}, t = {time_s:.1} s"
                    ));
                }
            }
            Event::Program {
                item,
                program,
                path,
                done,
                time_s,
            } => {
                if self.json {
                    self.line(
                        &json!({"event": "program", "item": item, "program": program,
                            "path": path, "done": done, "time_s": time_s})
                        .to_string(),
                    );
                } else {
                    self.line(&format!(
                        "  path {item} {path}: program {program} {} at t = {time_s:.1} s",
                        if *done { "done" } else { "started" }
                    ));
                }
            }
        }
    }
}

/// Runs `windcell run`.
pub fn run(args: RunArgs) -> Result<(), Failure> {
    let (loaded, cell, reach, name) = load(&args)?;
    // The pre-run check: every file converted and checked before anything is sent.
    let batch = Batch::new(
        loaded.items.clone(),
        loaded.mode,
        loaded.job_id.clone(),
        cell.drive,
        reach,
    )
    .map_err(Failure::from_cell)?;
    let journal_path = args
        .resume
        .clone()
        .or(args.journal.clone())
        .unwrap_or_else(|| {
            loaded
                .sequence_path
                .with_file_name(format!("{name}.journal"))
        });
    let (journal, from, fresh) = match &args.resume {
        Some(p) => {
            if !p.exists() {
                return Err(Failure::input(format!(
                    "{}: no such journal to resume",
                    p.display()
                )));
            }
            let (j, records) = Journal::resume(p).map_err(Failure::input)?;
            let from =
                cell::coordinator::resume_point(&batch, &records).map_err(Failure::from_cell)?;
            if records
                .last()
                .is_some_and(|r| r.get("rec").and_then(|v| v.as_str()) == Some("done"))
            {
                return Err(Failure::input(format!(
                    "{}: the batch is already done",
                    p.display()
                )));
            }
            (j, from, false)
        }
        None => (
            Journal::create(&journal_path).map_err(Failure::runtime)?,
            ResumePoint::default(),
            true,
        ),
    };
    let (devices, sim) = devices(&cell, args.log.as_deref())?;
    let rec = recorder(&args, sim.as_ref())?;
    let rec_events = rec.clone();
    let display = Display {
        json: args.json,
        terminal: std::io::stdout().is_terminal(),
    };
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
            display.line(&format!(
                "resuming after path {} ({} segments of the next confirmed)",
                from.items_done, from.segments_done
            ));
        }
    }

    let stop = Arc::new(AtomicBool::new(false));
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .map_err(Failure::runtime)?;
    let reason = Arc::new(Mutex::new(String::from("interrupted")));
    let (tx, mut rx) = tokio::sync::mpsc::unbounded_channel::<Event>();
    let standby = args.standby;
    let force = args.force;
    let engine_stop = stop.clone();
    let engine_reason = reason.clone();
    let batch_for_engine = batch.clone();
    let outcome = runtime.block_on(async move {
        // Ctrl-C.
        let (s1, r1) = (stop.clone(), reason.clone());
        tokio::spawn(async move {
            if tokio::signal::ctrl_c().await.is_ok() {
                if let Ok(mut r) = r1.lock() {
                    *r = "Ctrl-C".into();
                }
                s1.store(true, Ordering::Relaxed);
            }
        });
        // The console: `s` + Enter.
        let (s2, r2) = (stop.clone(), reason.clone());
        tokio::spawn(async move {
            use tokio::io::AsyncBufReadExt;
            let mut lines = tokio::io::BufReader::new(tokio::io::stdin()).lines();
            while let Ok(Some(line)) = lines.next_line().await {
                if line.trim() == "s" {
                    if let Ok(mut r) = r2.lock() {
                        *r = "the console's stop".into();
                    }
                    s2.store(true, Ordering::Relaxed);
                }
            }
        });
        // The coordinator, owning the devices.
        let engine = tokio::task::spawn_blocking(move || {
            let mut sink = |e: Event| {
                let _ = tx.send(e);
            };
            let mut c = Coordinator::new(devices, engine_stop, journal, &mut sink);
            c.stop_reason = engine_reason;
            let t0 = std::time::Instant::now();
            let r = c.run(&batch_for_engine, &from, fresh, standby, force);
            (r, t0.elapsed())
        });
        // The display.
        let mut paths = Vec::new();
        while let Some(e) = rx.recv().await {
            display.event(&e);
            if let Some(r) = &rec_events {
                let t = match &e {
                    Event::Segment { time_s, .. }
                    | Event::Program { time_s, .. }
                    | Event::PathDone { time_s, .. } => *time_s,
                    _ => 0.0,
                };
                r.log(t, cell::record::Level::Info, &format!("{e:?}"));
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
    let (result, wall) =
        joined.map_err(|e| Failure::runtime(format!("the coordinator thread failed: {e}")))?;
    if let Some(r) = rec {
        // Detach the simulated cell's observer, then finalise (summary and indexes).
        if let Some(sim) = &sim {
            let _ = sim.with(|p| p.observer = None);
        }
        if let Ok(r) = Arc::try_unwrap(r) {
            r.finish().map_err(Failure::from_cell)?;
        }
    }
    let cell_time = sim.as_ref().map(|s| {
        use asea_protocol::clock::Clock as _;
        s.clock().now_s()
    });
    match result {
        Ok(()) => {
            if display.json {
                let list: Vec<_> = paths
                    .iter()
                    .map(|(n, p, t)| json!({"name": n, "program": p, "mode": batch.mode.keyword(), "time_s": t}))
                    .collect();
                display.line(&json!({"event": "done", "paths": list}).to_string());
            } else {
                for (n, p, t) in &paths {
                    display.line(&format!(
                        "done: {n} (program {p}, {}) in {t:.1} s",
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
                Halt::Fault { message } => (message.clone(), super::EXIT_RUNTIME, "fault"),
            };
            let resume = format!(
                "windcell run {} --resume {}",
                args.input.display(),
                journal_path.display()
            );
            if display.json {
                display.line(
                    &json!({"event": event, "item": stopped.item, "path": stopped.path,
                        "segments_done": stopped.segments_done, "reason": why,
                        "stop_errors": stopped.stop_errors, "resume": resume})
                    .to_string(),
                );
            }
            Err(Failure {
                message: format!(
                    "stopped at path {} ({}) after {} segments ({why}){}; both axes told to stop; resume with: {resume}",
                    stopped.item,
                    stopped.path,
                    stopped.segments_done,
                    if stopped.stop_errors.is_empty() {
                        String::new()
                    } else {
                        format!("; stop failed: {}", stopped.stop_errors.join(", "))
                    }
                ),
                exit_code: code,
            })
        }
    }
}
