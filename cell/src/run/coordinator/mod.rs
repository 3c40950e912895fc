//! The cell coordinator (seed 001 §5.3.3–5.3.4, §5.6.4): winds a batch of control files on a
//! robot and a mandrel drive in discrete (file control) or fine/medium (program control) mode,
//! stops both devices on request or on a fault, journals every confirmed step and resumes.
//!
//! Every move is expressed as a *destination*: the robot to an absolute eye position, the mandrel
//! to an absolute step count of the indexer's counter (zeroed once, when a batch starts). Whatever
//! stopped the run (an operator, a fault, `kill -9` after which the devices finish on their own),
//! finishing a segment is "go to its destination from wherever the device stands", so a resume
//! asks the devices where they are and no segment is skipped or wound twice.
//!
//! Program mode wraps each stored program in the App. D handshake: output 1 ("in position") low,
//! wait for input 1 (the PC's start), the positions, output 1 high, End ([`handshake_program`]).

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use asea_protocol::command::{
    CONTROL_UNITS, IN_POSITION_OUTPUT, MEMORY_UNITS, POSITION_UNITS, START_INPUT,
};
use asea_protocol::{Control, Instruction, Positioning, State};
use mandrel_drive::Drive;
use paths::MandrelProfile;
use sequences::rob::{Movement, Reference};
use sequences::{MandrelFile, MandrelMove, RobotFile};
use serde_json::json;

use crate::Error;
use crate::run::device::{DeviceError, Interrupt, MandrelDevice, RobotDevice, SyncLines, Timebase};
use crate::run::journal::{Journal, JournalError};
use crate::run::transfer;

/// The coordinator's control tick: the longest it goes without looking at the stop request and
/// the e-stop input while it waits.
pub const CONTROL_TICK: Duration = Duration::from_millis(10);
/// How often an immediate move's end waits out an in-position level seen high while the robot
/// still runs (the previous move's level, behind the opto delay) before it is a fault.
pub const STALE_IN_POSITION_WAITS: u32 = 2;
/// A robot position within this of its target is reached (the telegram's 0.0625 mm LSB, twice).
pub const POSITION_TOLERANCE_MM: f64 = 0.125;
/// The program number a resumed program-mode path is stored under.
pub const RESUME_PROGRAM: u8 = 255;
/// Robot instructions before the first position in a handshake program.
pub const HANDSHAKE_LEAD: u16 = 2;
/// Longest wait for one robot or mandrel move, s (of the cell's time).
pub const MOVE_TIMEOUT_S: f64 = 600.0;
/// Longest wait for home synchronisation, s.
pub const HOME_TIMEOUT_S: f64 = 60.0;
/// A stored program runs unwatched (no robot telegram) for this many times the mandrel move's
/// time, plus [`PROGRAM_QUIET_MARGIN_S`]; only a program that overruns that is polled for errors.
pub const PROGRAM_QUIET_FACTOR: f64 = 1.5;
/// See [`PROGRAM_QUIET_FACTOR`], s.
pub const PROGRAM_QUIET_MARGIN_S: f64 = 1.0;
/// Control ticks between two status reads of a program that overran its quiet time.
pub const PROGRAM_POLL_TICKS: u32 = 50;

/// How the batch is wound (seed 001 §5.4).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RunMode {
    /// File control: one robot and one mandrel instruction at a time, both stopping at each.
    Discrete,
    /// Program control, 1 mm zone.
    Fine,
    /// Program control, 10 mm zone.
    Medium,
    /// Program control, 10 mm zone, kept in step with the mandrel (ours; docs/continuous.md):
    /// the stored program starts at the path's second point, the eye being at the first from
    /// the approach, so the robot's first flying move starts on the start edge with the mandrel.
    Continuous,
}

impl RunMode {
    /// The keyword (`discrete`, `fine`, `medium`, `continuous`).
    pub fn keyword(self) -> &'static str {
        match self {
            RunMode::Discrete => "discrete",
            RunMode::Fine => "fine",
            RunMode::Medium => "medium",
            RunMode::Continuous => "continuous",
        }
    }
    /// From a keyword.
    pub fn from_keyword(s: &str) -> Option<Self> {
        match s {
            "discrete" => Some(RunMode::Discrete),
            "fine" => Some(RunMode::Fine),
            "medium" => Some(RunMode::Medium),
            "continuous" => Some(RunMode::Continuous),
            _ => None,
        }
    }
    /// From a control file's movement.
    pub fn from_movement(m: Movement) -> Self {
        match m {
            Movement::Discrete => RunMode::Discrete,
            Movement::Fine => RunMode::Fine,
            Movement::Medium => RunMode::Medium,
            Movement::Continuous => RunMode::Continuous,
        }
    }
    /// The control files' movement type of this mode.
    pub fn movement(self) -> Movement {
        match self {
            RunMode::Discrete => Movement::Discrete,
            RunMode::Fine => Movement::Fine,
            RunMode::Medium => Movement::Medium,
            RunMode::Continuous => Movement::Continuous,
        }
    }
    /// Path points before a stored program's first position: 1 in continuous mode (the
    /// approach puts the eye at the first point), else 0.
    pub fn points_before_program(self) -> usize {
        usize::from(self == RunMode::Continuous)
    }
}

/// One path of the batch: a robot control file and, for program mode, its mandrel file.
#[derive(Debug, Clone)]
pub struct Item {
    /// Control-file name (`SBEND_1`).
    pub name: String,
    /// The robot control file.
    pub rob: RobotFile,
    /// The mandrel control file (program mode).
    pub ind: Option<MandrelFile>,
}

/// What the pre-run check made of one item.
#[derive(Debug, Clone)]
struct Prepared {
    /// Absolute robot target of each instruction, mm.
    targets_mm: Vec<[f64; 3]>,
    /// Each instruction as an immediate move.
    immediate: Vec<Positioning>,
    /// The mandrel move of each instruction.
    mandrel: Vec<MandrelMove>,
    /// Steps from the path's start after each instruction (index 0 = before the first).
    cumulative_steps: Vec<i64>,
    /// The stored program with the handshake (program mode).
    program: Option<Vec<Instruction>>,
}

/// The robot's working range the pre-run check holds every instruction to.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reach {
    /// Greatest horizontal distance from the pedestal axis, mm.
    pub max_radius_mm: f64,
    /// Least horizontal distance, mm.
    pub min_radius_mm: f64,
    /// Lowest and highest height, mm.
    pub z_range_mm: (f64, f64),
}

impl Default for Reach {
    /// The robot computer's own range check (`asea_protocol::sim::MotionParams`: 1600 mm,
    /// ±2047.9375 mm of height).
    fn default() -> Self {
        Reach {
            max_radius_mm: 1600.0,
            min_radius_mm: 0.0,
            z_range_mm: (-2047.9375, 2047.9375),
        }
    }
}

/// A checked batch, ready to wind.
#[derive(Debug, Clone)]
pub struct Batch {
    /// Items in winding order.
    pub items: Vec<Item>,
    /// The mode.
    pub mode: RunMode,
    /// Identifies the job's files (a hash of their texts): a journal names it.
    pub job_id: String,
    /// Motor, belt and translator.
    pub drive: Drive,
    prepared: Vec<Prepared>,
}

/// The App. D handshake around a stored program's positions: lower "in position", wait for the
/// PC's start, the positions, raise "in position", End. Control instructions already in
/// `instructions` are replaced, so a program that has its own handshake is not wrapped twice.
pub fn handshake_program(instructions: &[Instruction]) -> Vec<Instruction> {
    let mut out = vec![
        Instruction::Control(Control::SetOutput {
            line: IN_POSITION_OUTPUT,
            on: false,
        }),
        Instruction::Control(Control::WaitInput {
            line: START_INPUT,
            on: true,
        }),
    ];
    out.extend(
        instructions
            .iter()
            .filter(|i| matches!(i, Instruction::Position(_)))
            .copied(),
    );
    out.push(Instruction::Control(Control::SetOutput {
        line: IN_POSITION_OUTPUT,
        on: true,
    }));
    out.push(Instruction::Control(Control::End));
    out
}

/// Memory units a program takes in the robot computer (seed 001 §4.1.2).
pub fn program_units(instructions: &[Instruction]) -> u32 {
    instructions
        .iter()
        .map(|i| match i {
            Instruction::Position(_) => POSITION_UNITS,
            Instruction::Control(_) => CONTROL_UNITS,
        })
        .sum()
}

impl Batch {
    /// The pre-run check (every file as the plan checks it: conversion to the devices' units and
    /// ranges, reach, memory) and the batch it makes. Nothing is sent.
    pub fn new(
        items: Vec<Item>,
        mode: RunMode,
        job_id: String,
        drive: Drive,
        reach: Reach,
    ) -> Result<Batch, Error> {
        let setup = transfer::IndexerSetup {
            drive,
            start_velocity_command: true,
        };
        let mut prepared = Vec::with_capacity(items.len());
        let mut seen: Vec<u8> = Vec::new();
        let mut units = 0u32;
        for item in &items {
            // Continuous mode's timing is a property of the plan (every segment at least the
            // robot's time per instruction): files planned for another movement are refused.
            if mode == RunMode::Continuous && item.rob.header.movement != Movement::Continuous {
                return Err(Error::Run {
                    message: format!(
                        "{}: planned for {} movement; continuous mode needs files planned for it (movement = \"continuous\" in the job)",
                        item.name,
                        item.rob.header.movement.keyword()
                    ),
                    input: true,
                });
            }
            let mut rob = item.rob.clone();
            rob.header.movement = mode.movement();
            let program = rob.header.program;
            let immediate: Vec<Positioning> = transfer::immediate_moves(&rob)?
                .into_iter()
                .filter_map(|c| match c {
                    asea_protocol::Command::MoveImmediate(p) => Some(p),
                    _ => None,
                })
                .collect();
            let mut targets_mm = Vec::with_capacity(rob.instructions.len());
            let mut cumulative_steps = vec![0i64];
            let mut mandrel = Vec::new();
            for (i, p) in rob.instructions.iter().zip(&immediate) {
                if i.reference != Reference::Absolute {
                    return Err(Error::Run {
                        message: format!(
                            "{}: instruction {}: relative positions cannot be resumed; the coordinator needs absolute ones",
                            item.name, i.number
                        ),
                        input: true,
                    });
                }
                let t = p.pose.xyz_mm();
                let radius = t[0].hypot(t[1]);
                if radius > reach.max_radius_mm
                    || radius < reach.min_radius_mm
                    || t[2] < reach.z_range_mm.0
                    || t[2] > reach.z_range_mm.1
                {
                    return Err(Error::Run {
                        message: format!(
                            "{}: instruction {}: the eye at ({:.1}, {:.1}, {:.1}) mm is out of the arm's reach ({:.0}–{:.0} mm from the axis, height {:.0}–{:.0} mm)",
                            item.name,
                            i.number,
                            t[0],
                            t[1],
                            t[2],
                            reach.min_radius_mm,
                            reach.max_radius_mm,
                            reach.z_range_mm.0,
                            reach.z_range_mm.1
                        ),
                        input: true,
                    });
                }
                transfer::indexer_move(&i.mandrel, &setup, Some(i.number))?;
                targets_mm.push(t);
                mandrel.push(i.mandrel);
                let last = cumulative_steps.last().copied().unwrap_or(0);
                cumulative_steps.push(last + i.mandrel.steps);
            }
            if targets_mm.is_empty() {
                return Err(Error::Run {
                    message: format!("{}: the robot control file has no instruction", item.name),
                    input: true,
                });
            }
            let program_list = if mode == RunMode::Discrete {
                None
            } else {
                let ind = item.ind.as_ref().ok_or_else(|| Error::Run {
                    message: format!("{}.IND: missing (program mode needs it)", item.name),
                    input: true,
                })?;
                transfer::indexer_program(ind, &setup)?;
                let total = cumulative_steps.last().copied().unwrap_or(0);
                if ind.path_move.steps != total {
                    return Err(Error::Run {
                        message: format!(
                            "{}.IND: the move turns {} steps, the .ROB's instructions {}",
                            item.name, ind.path_move.steps, total
                        ),
                        input: true,
                    });
                }
                let positions = transfer::robot_program(&rob)?.instructions;
                let prog = handshake_program(
                    &positions
                        .iter()
                        .filter(|i| matches!(i, Instruction::Position(_)))
                        .skip(mode.points_before_program())
                        .copied()
                        .collect::<Vec<_>>(),
                );
                if !seen.contains(&program) {
                    seen.push(program);
                    units += program_units(&prog);
                }
                Some(prog)
            };
            prepared.push(Prepared {
                targets_mm,
                immediate,
                mandrel,
                cumulative_steps,
                program: program_list,
            });
        }
        if mode != RunMode::Discrete {
            // Room for a resumed program as long as the longest path.
            let longest = prepared
                .iter()
                .filter_map(|p| p.program.as_ref())
                .map(|p| program_units(p))
                .max()
                .unwrap_or(0);
            if units + longest > MEMORY_UNITS {
                return Err(Error::Run {
                    message: format!(
                        "the batch needs {} memory units of the robot's {} ({} for {} programs + {} kept free to resume the longest): it does not fit",
                        units + longest,
                        MEMORY_UNITS,
                        units,
                        seen.len(),
                        longest
                    ),
                    input: true,
                });
            }
        }
        Ok(Batch {
            items,
            mode,
            job_id,
            drive,
            prepared,
        })
    }
}

/// What the operator sees (and `--json` prints).
#[derive(Debug, Clone, PartialEq)]
pub enum Event {
    /// The run started.
    Started {
        /// Mode.
        mode: RunMode,
        /// Items in the batch.
        items: usize,
        /// True when resuming.
        resumed: bool,
    },
    /// Programs uploaded and read back (program mode).
    Uploaded {
        /// Programs.
        programs: Vec<u8>,
    },
    /// A discrete segment confirmed.
    Segment {
        /// Batch item, from 1.
        item: usize,
        /// Program number.
        program: u8,
        /// Path name.
        path: String,
        /// Segment, from 1.
        segment: usize,
        /// Segments in the path.
        segments: usize,
        /// Cell time, s.
        time_s: f64,
    },
    /// A stored program started (`done` false) or finished (`done` true).
    Program {
        /// Batch item, from 1.
        item: usize,
        /// Program number run.
        program: u8,
        /// Path name.
        path: String,
        /// Finished.
        done: bool,
        /// Cell time, s.
        time_s: f64,
    },
    /// A path finished.
    PathDone {
        /// Batch item, from 1.
        item: usize,
        /// Path name.
        path: String,
        /// Program number.
        program: u8,
        /// Winding time of the path, s.
        time_s: f64,
    },
}

/// Why the run stopped before the end.
#[derive(Debug, Clone, PartialEq)]
pub enum Halt {
    /// Ctrl-C, the console's `s`, or the e-stop input.
    Interrupted {
        /// Which.
        reason: String,
    },
    /// A device failed (both devices were told to stop).
    Fault {
        /// What failed.
        message: String,
    },
}

impl Halt {
    /// Why the run stopped, in words (the interruption's reason or the fault's message).
    pub fn reason(&self) -> &str {
        match self {
            Halt::Interrupted { reason } => reason,
            Halt::Fault { message } => message,
        }
    }
}

/// Where a stopped run stood.
#[derive(Debug, Clone, PartialEq)]
pub struct Stopped {
    /// Why.
    pub halt: Halt,
    /// Batch item (from 1) and path name.
    pub item: usize,
    /// Path name.
    pub path: String,
    /// Segments confirmed in that path.
    pub segments_done: usize,
    /// Results of the stop commands (robot, indexer).
    pub stop_errors: Vec<String>,
}

/// The devices of a cell and its time.
#[derive(Debug)]
pub struct Devices {
    /// The robot computer.
    pub robot: Box<dyn RobotDevice>,
    /// The indexer.
    pub mandrel: Box<dyn MandrelDevice>,
    /// The sync lines.
    pub sync: Box<dyn SyncLines>,
    /// The cell's time.
    pub time: Arc<dyn Timebase>,
}

impl std::fmt::Debug for dyn RobotDevice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("RobotDevice")
    }
}

impl std::fmt::Debug for dyn MandrelDevice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("MandrelDevice")
    }
}

impl Devices {
    /// What abandons the devices' exchanges under way from another thread.
    pub fn interrupters(&self) -> Vec<Arc<dyn Interrupt>> {
        self.robot
            .interrupter()
            .into_iter()
            .chain(self.mandrel.interrupter())
            .collect()
    }
}

/// The stop request the signal, the console and the e-stop share with the coordinator. Making
/// it ([`StopRequest::request`]) sets the flag the coordinator looks at, abandons the exchange
/// under way on both links (their cancel tokens) and wakes the coordinator from its control
/// tick, so that it sends the stop commands at once (seed 001 §5.3: the operator's stop).
#[derive(Debug, Clone)]
pub struct StopRequest {
    flag: Arc<AtomicBool>,
    reason: Arc<std::sync::Mutex<String>>,
    interrupters: Vec<Arc<dyn Interrupt>>,
    waiter: Arc<std::sync::Mutex<Option<std::thread::Thread>>>,
}

impl StopRequest {
    /// A request not made, for `devices` (whose exchanges it abandons).
    pub fn new(devices: &Devices) -> Self {
        Self::from_flag(Arc::new(AtomicBool::new(false)), devices)
    }

    /// A request that is made when `flag` is set, too (by whoever holds it).
    pub fn from_flag(flag: Arc<AtomicBool>, devices: &Devices) -> Self {
        StopRequest {
            flag,
            reason: Arc::new(std::sync::Mutex::new("interrupted".into())),
            interrupters: devices.interrupters(),
            waiter: Arc::new(std::sync::Mutex::new(None)),
        }
    }

    /// Asks the coordinator to stop both devices now, saying why.
    pub fn request(&self, reason: &str) {
        if let Ok(mut r) = self.reason.lock() {
            *r = reason.to_string();
        }
        self.flag.store(true, Ordering::SeqCst);
        for i in &self.interrupters {
            i.interrupt();
        }
        if let Ok(w) = self.waiter.lock()
            && let Some(t) = w.as_ref()
        {
            t.unpark();
        }
    }

    /// True once requested.
    pub fn is_requested(&self) -> bool {
        self.flag.load(Ordering::SeqCst)
    }

    /// Why.
    pub fn reason(&self) -> String {
        self.reason
            .lock()
            .map(|r| r.clone())
            .unwrap_or_else(|_| "interrupted".into())
    }

    /// Lets the devices' exchanges run again (the stop commands and their confirmation).
    fn clear_interrupts(&self) {
        for i in &self.interrupters {
            i.clear();
        }
    }
}

/// Where to resume: from the journal.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ResumePoint {
    /// Items already finished.
    pub items_done: usize,
    /// The indexer counter the current item's sync aimed at, if its sync was journaled.
    pub sync_counter: Option<i64>,
    /// Segments confirmed in the current item (discrete).
    pub segments_done: usize,
    /// The current item's program was started (program mode).
    pub program_started: bool,
}

/// Reads a journal's records into a resume point, checking it belongs to `batch`.
pub fn resume_point(
    batch: &Batch,
    records: &[serde_json::Map<String, serde_json::Value>],
) -> Result<ResumePoint, Error> {
    let bad = |m: String| Error::Run {
        message: m,
        input: true,
    };
    let begin = records
        .first()
        .filter(|r| r.get("rec").and_then(|v| v.as_str()) == Some("begin"))
        .ok_or_else(|| bad("the journal does not start with its begin record".into()))?;
    if begin.get("job").and_then(|v| v.as_str()) != Some(batch.job_id.as_str()) {
        return Err(bad(
            "the journal belongs to another job (its control files differ)".into(),
        ));
    }
    if begin.get("mode").and_then(|v| v.as_str()) != Some(batch.mode.keyword()) {
        return Err(bad(format!(
            "the journal was written in {} mode, this run is {}",
            begin.get("mode").and_then(|v| v.as_str()).unwrap_or("?"),
            batch.mode.keyword()
        )));
    }
    let mut p = ResumePoint::default();
    for r in records {
        let int = |k: &str| r.get(k).and_then(serde_json::Value::as_i64);
        match r.get("rec").and_then(|v| v.as_str()) {
            Some("item") => {
                p.sync_counter = None;
                p.segments_done = 0;
                p.program_started = false;
            }
            Some("sync") => p.sync_counter = int("counter"),
            Some("segment") => p.segments_done = int("segment").unwrap_or(0) as usize,
            Some("program") => p.program_started = true,
            Some("item_done") => {
                p.items_done = int("item").unwrap_or(0) as usize;
                p.sync_counter = None;
                p.segments_done = 0;
                p.program_started = false;
            }
            _ => {}
        }
    }
    Ok(p)
}

/// The coordinator: drives the devices through a batch.
pub struct Coordinator<'a> {
    dev: Devices,
    stop: StopRequest,
    journal: Journal,
    events: &'a mut dyn FnMut(Event),
    item: usize,
    segments_done: usize,
}

impl std::fmt::Debug for Coordinator<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Coordinator")
            .field("dev", &self.dev)
            .field("item", &self.item)
            .finish()
    }
}

enum Step {
    Halt(Halt),
}

impl From<DeviceError> for Step {
    fn from(e: DeviceError) -> Self {
        Step::Halt(Halt::Fault {
            message: e.to_string(),
        })
    }
}

impl From<JournalError> for Step {
    fn from(e: JournalError) -> Self {
        Step::Halt(Halt::Fault {
            message: e.to_string(),
        })
    }
}

fn distance_mm(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

impl<'a> Coordinator<'a> {
    /// A coordinator on `dev`, stopping when `stop` is set (at its next control tick or between
    /// two exchanges), journaling to `journal`.
    pub fn new(
        dev: Devices,
        stop: Arc<AtomicBool>,
        journal: Journal,
        events: &'a mut dyn FnMut(Event),
    ) -> Self {
        let stop = StopRequest::from_flag(stop, &dev);
        Self::with_stop(dev, stop, journal, events)
    }

    /// A coordinator on `dev` that `stop` interrupts at once ([`StopRequest::request`]).
    pub fn with_stop(
        dev: Devices,
        stop: StopRequest,
        journal: Journal,
        events: &'a mut dyn FnMut(Event),
    ) -> Self {
        Coordinator {
            dev,
            stop,
            journal,
            events,
            item: 0,
            segments_done: 0,
        }
    }

    /// The stop request this coordinator obeys (clone it into a signal handler or console).
    pub fn stop_request(&self) -> StopRequest {
        self.stop.clone()
    }

    /// The devices back (tests look at them after a run).
    pub fn into_devices(self) -> Devices {
        self.dev
    }

    fn check(&mut self) -> Result<(), Step> {
        if self.stop.is_requested() {
            return Err(Step::Halt(Halt::Interrupted {
                reason: self.stop.reason(),
            }));
        }
        if self.dev.sync.estop()? {
            return Err(Step::Halt(Halt::Interrupted {
                reason: "e-stop input".into(),
            }));
        }
        Ok(())
    }

    /// Waits (one control tick at a time, looking at the stop request) until `done`.
    fn wait(
        &mut self,
        what: &str,
        timeout_s: f64,
        mut done: impl FnMut(&mut Devices) -> Result<bool, DeviceError>,
    ) -> Result<(), Step> {
        let t0 = self.dev.time.now_s();
        loop {
            self.check()?;
            if done(&mut self.dev)? {
                return Ok(());
            }
            if self.dev.time.now_s() - t0 > timeout_s {
                return Err(Step::Halt(Halt::Fault {
                    message: format!("{what}: not done after {timeout_s:.0} s"),
                }));
            }
            self.dev.time.tick(CONTROL_TICK);
        }
    }

    /// Stops both devices (each tried whatever the other did); returns the errors.
    fn stop_devices(&mut self) -> Vec<String> {
        // The exchange a stop request abandoned is over: the stops and their confirmations
        // run. The indexer's `S` first, on the wire at once without waiting for its echo; then
        // the robot's STOP session (STOP before any status read); then the indexer's stop
        // again, confirmed by its echo.
        self.stop.clear_interrupts();
        let mut errors = Vec::new();
        let early = self.dev.mandrel.stop_on_wire();
        if let Err(e) = self.dev.robot.stop() {
            errors.push(e.to_string());
        }
        if let Err(e) = self.dev.mandrel.stop() {
            errors.push(early.err().unwrap_or(e).to_string());
        }
        let _ = self.dev.sync.set_start(false);
        errors
    }

    /// Winds `batch` from `from` (the start, or a journal's resume point).
    pub fn run(
        &mut self,
        batch: &Batch,
        from: &ResumePoint,
        fresh: bool,
        standby: bool,
        force: bool,
    ) -> Result<(), Stopped> {
        self.item = from.items_done;
        self.segments_done = from.segments_done;
        if let Ok(mut w) = self.stop.waiter.lock() {
            *w = Some(std::thread::current());
        }
        match self.run_inner(batch, from, fresh, standby, force) {
            Ok(()) => Ok(()),
            Err(Step::Halt(halt)) => {
                let stop_errors = self.stop_devices();
                // An exchange the stop request abandoned is the request, not a fault.
                let halt = match halt {
                    Halt::Fault { .. } if self.stop.is_requested() => Halt::Interrupted {
                        reason: self.stop.reason(),
                    },
                    h => h,
                };
                let item = self.item.min(batch.items.len().saturating_sub(1));
                let _ = self.journal.append(json!({
                    "rec": "stopped",
                    "item": item,
                    "segments_done": self.segments_done,
                    "reason": halt.reason(),
                    "t_s": self.dev.time.now_s(),
                }));
                Err(Stopped {
                    halt,
                    item: item + 1,
                    path: batch
                        .items
                        .get(item)
                        .map(|i| i.name.clone())
                        .unwrap_or_default(),
                    segments_done: self.segments_done,
                    stop_errors,
                })
            }
        }
    }

    fn run_inner(
        &mut self,
        batch: &Batch,
        from: &ResumePoint,
        fresh: bool,
        standby: bool,
        force: bool,
    ) -> Result<(), Step> {
        (self.events)(Event::Started {
            mode: batch.mode,
            items: batch.items.len(),
            resumed: !fresh,
        });
        if fresh {
            self.journal.append(json!({
                "rec": "begin", "job": batch.job_id, "mode": batch.mode.keyword(),
                "items": batch.items.iter().map(|i| i.name.clone()).collect::<Vec<_>>(),
                "force": force,
            }))?;
        } else {
            self.journal
                .append(json!({"rec": "resume", "items_done": from.items_done}))?;
        }
        self.check()?;
        // Attach: the indexer without zeroing, then zero it once for a fresh batch.
        self.dev.sync.set_start(false)?;
        self.cancel_armed_move()?;
        let counter = self.dev.mandrel.attach()?;
        if fresh {
            self.dev.mandrel.zero()?;
            self.journal
                .append(json!({"rec": "mandrel_zero", "counter_before": counter}))?;
        }
        self.ready_robot()?;
        if batch.mode != RunMode::Discrete {
            if !self.dev.sync.wired() {
                return Err(Step::Halt(Halt::Fault {
                    message: "program mode needs the sync lines: name a sync port".into(),
                }));
            }
            self.upload(batch, standby)?;
        }
        for k in from.items_done..batch.items.len() {
            self.item = k;
            let resume = if k == from.items_done && !fresh {
                Some(from)
            } else {
                None
            };
            let t0 = self.dev.time.now_s();
            if resume.is_none_or(|r| r.sync_counter.is_none() && r.segments_done == 0) {
                self.journal
                    .append(json!({"rec": "item", "item": k, "name": batch.items[k].name}))?;
            }
            match batch.mode {
                RunMode::Discrete => self.discrete_item(batch, k, resume)?,
                _ => self.program_item(batch, k, resume)?,
            }
            let item = &batch.items[k];
            self.journal
                .append(json!({"rec": "item_done", "item": k + 1, "name": item.name}))?;
            (self.events)(Event::PathDone {
                item: k + 1,
                path: item.name.clone(),
                program: item.rob.header.program,
                time_s: self.dev.time.now_s() - t0,
            });
            self.segments_done = 0;
        }
        self.journal.append(json!({"rec": "done"}))?;
        Ok(())
    }

    /// Manual control (seed 001 §5.3.2, §5.4): one robot position and one mandrel instruction
    /// sent together, each confirmed. `relative` positions are added to the robot's position now.
    /// The wrist quaternion of `p` is the App. A pitch and roll in the arm's vertical plane: the
    /// five-axis arm has no wrist yaw (§4.1.1), so the base yaw that turns that plane to the
    /// target, `atan2(y, x)`, is put in front of it (a pose out of the plane would be refused,
    /// error 9). Returns the robot's position (mm) and the indexer's counter (steps) afterwards.
    pub fn jog(
        &mut self,
        speeds: (asea_protocol::Speed, asea_protocol::Speed),
        mut p: Positioning,
        relative: bool,
        mandrel: Option<MandrelMove>,
        reach: Reach,
    ) -> Result<([f64; 3], i64), Stopped> {
        let r = (|| -> Result<([f64; 3], i64), Step> {
            self.check()?;
            let counter = self.dev.mandrel.attach()?;
            self.ready_robot()?;
            let mut target = p.pose.xyz_mm();
            if relative {
                let here = self.dev.robot.position_mm()?;
                target = [
                    here[0] + target[0],
                    here[1] + target[1],
                    here[2] + target[2],
                ];
                p.pose = asea_protocol::Pose::from_mm(target, p.pose.q.wxyz()).map_err(|e| {
                    Step::Halt(Halt::Fault {
                        message: format!("the relative move leaves the telegram's range: {e}"),
                    })
                })?;
                p.flags.reference = asea_protocol::Reference::Absolute;
            }
            let yaw = nalgebra::UnitQuaternion::from_axis_angle(
                &nalgebra::Vector3::z_axis(),
                target[1].atan2(target[0]),
            );
            let [w, x, y, z] = p.pose.q.wxyz();
            let q = yaw
                * nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(w, x, y, z));
            p.pose = asea_protocol::Pose::from_mm(target, [q.w, q.i, q.j, q.k]).map_err(|e| {
                Step::Halt(Halt::Fault {
                    message: format!("the jog's pose: {e}"),
                })
            })?;
            let radius = target[0].hypot(target[1]);
            if radius > reach.max_radius_mm
                || radius < reach.min_radius_mm
                || target[2] < reach.z_range_mm.0
                || target[2] > reach.z_range_mm.1
            {
                return Err(Step::Halt(Halt::Fault {
                    message: format!(
                        "the eye at ({:.1}, {:.1}, {:.1}) mm is out of the arm's reach",
                        target[0], target[1], target[2]
                    ),
                }));
            }
            self.dev.robot.set_speeds(speeds.0, speeds.1)?;
            let end = counter + mandrel.map_or(0, |m| m.steps);
            let moving = match mandrel {
                Some(m) => self.mandrel_start(m, counter, end, false)?,
                None => false,
            };
            self.robot_to(p, target)?;
            if moving {
                self.mandrel_finish(end)?;
            }
            Ok((self.dev.robot.position_mm()?, end))
        })();
        r.map_err(|Step::Halt(halt)| Stopped {
            halt,
            item: 0,
            path: String::new(),
            segments_done: 0,
            stop_errors: self.stop_devices(),
        })
    }

    /// Cancels a mandrel move armed on the start line that never saw its start edge (the PC
    /// stopped between arming the indexer and the edge, and nobody cancelled it since): it holds
    /// the indexer's command buffer, so that nothing buffered after it (the attach's position
    /// request) is answered. A move still turning (its step count moves within 100 ms) is left
    /// to finish.
    fn cancel_armed_move(&mut self) -> Result<(), Step> {
        if self.dev.mandrel.busy()?.0 {
            let before = self.dev.mandrel.move_steps()?;
            self.dev.time.sleep(Duration::from_millis(100));
            if self.dev.mandrel.move_steps()? == before {
                self.dev.mandrel.stop()?;
            }
        }
        Ok(())
    }

    /// Operate mode and homed (homing again if the robot lost it).
    fn ready_robot(&mut self) -> Result<(), Step> {
        let s = self.dev.robot.state()?;
        if s.state == State::Running
            && s.instruction == HANDSHAKE_LEAD
            && !self.dev.sync.in_position()?
        {
            // A program left waiting for the start edge: it never began; cancel it and the
            // mandrel's armed move.
            self.dev.robot.stop()?;
            self.dev.mandrel.stop()?;
        }
        let s = self.dev.robot.state()?;
        if s.state == State::Running {
            // A program or move left running (a coordinator killed mid-run): let it finish, as
            // the robot computer would without us.
            self.wait("the robot's unfinished motion", MOVE_TIMEOUT_S, |d| {
                Ok(d.robot.state()?.state != State::Running)
            })?;
        }
        let s = self.dev.robot.state()?;
        if !s.operate {
            self.dev.robot.set_operate(true)?;
        }
        if !s.homed {
            self.dev.robot.start_home()?;
            self.journal.append(json!({"rec": "home"}))?;
            self.wait("home synchronisation", HOME_TIMEOUT_S, |d| {
                let s = d.robot.state()?;
                Ok(s.homed && s.state == State::Idle)
            })?;
        }
        Ok(())
    }

    /// Uploads every program of the batch (verified stores), reads them all back, and runs each
    /// in standby first when asked (seed 001 §5.3.1).
    fn upload(&mut self, batch: &Batch, standby: bool) -> Result<(), Step> {
        let mut programs: Vec<(u8, &Vec<Instruction>)> = Vec::new();
        for (item, prep) in batch.items.iter().zip(&batch.prepared) {
            let p = item.rob.header.program;
            if let Some(list) = &prep.program
                && !programs.iter().any(|(q, _)| *q == p)
            {
                programs.push((p, list));
            }
        }
        for (p, list) in &programs {
            self.check()?;
            self.dev.robot.delete_program(*p)?;
            self.dev.robot.upload(*p, list)?;
        }
        for (p, list) in &programs {
            self.check()?;
            self.dev.robot.read_back(*p, list)?;
        }
        if standby {
            self.dev.robot.set_operate(false)?;
            for (p, _) in &programs {
                self.dev.robot.run_program(*p)?;
            }
            self.dev.robot.set_operate(true)?;
        }
        let nums: Vec<u8> = programs.iter().map(|(p, _)| *p).collect();
        self.journal
            .append(json!({"rec": "uploaded", "programs": nums, "standby": standby}))?;
        (self.events)(Event::Uploaded { programs: nums });
        Ok(())
    }

    /// Robot to `target` as an immediate move unless it is there; waits and confirms.
    fn robot_to(&mut self, p: Positioning, target: [f64; 3]) -> Result<(), Step> {
        let here = self.dev.robot.position_mm()?;
        if self.robot_send(p, target, here)? {
            self.robot_settle(target)?;
        }
        Ok(())
    }

    /// Sends the immediate move to `target` (confirmed executed once) unless the robot, at
    /// `here`, is there already; whether it was sent.
    fn robot_send(
        &mut self,
        p: Positioning,
        target: [f64; 3],
        here: [f64; 3],
    ) -> Result<bool, Step> {
        if distance_mm(here, target) <= POSITION_TOLERANCE_MM {
            return Ok(false);
        }
        self.dev.robot.move_immediate(p)?;
        Ok(true)
    }

    /// Waits for the robot's immediate move to `target` to end, then confirms its state (idle,
    /// no error) and its position, which it returns.
    ///
    /// The in-position line is seen through the opto-isolators' delay (App. D): right after
    /// the move's telegram and its confirming reads it may still show the level the previous
    /// move left high. The state read that follows the line tells a stale level (the robot still
    /// running) from the move's end; a stale level is waited out, low and then high again, at
    /// most [`STALE_IN_POSITION_WAITS`] times.
    fn robot_settle(&mut self, target: [f64; 3]) -> Result<[f64; 3], Step> {
        let s = if self.dev.sync.wired() {
            let mut waits = 0;
            loop {
                self.wait("robot move", MOVE_TIMEOUT_S, |d| d.sync.in_position())?;
                let s = self.dev.robot.state()?;
                if s.state != State::Running || waits == STALE_IN_POSITION_WAITS {
                    break s;
                }
                waits += 1;
                self.wait("robot move", MOVE_TIMEOUT_S, |d| {
                    Ok(!d.sync.in_position()?)
                })?;
            }
        } else {
            self.wait("robot move", MOVE_TIMEOUT_S, |d| {
                Ok(d.robot.state()?.state != State::Running)
            })?;
            self.dev.robot.state()?
        };
        if s.state != State::Idle || s.last_error != 0 {
            return Err(Step::Halt(Halt::Fault {
                message: format!(
                    "robot: state {:?}, error {} after a move",
                    s.state, s.last_error
                ),
            }));
        }
        let here = self.dev.robot.position_mm()?;
        if distance_mm(here, target) > POSITION_TOLERANCE_MM {
            return Err(Step::Halt(Halt::Fault {
                message: format!(
                    "robot: at ({:.2}, {:.2}, {:.2}) mm, {:.2} mm from its target",
                    here[0],
                    here[1],
                    here[2],
                    distance_mm(here, target)
                ),
            }));
        }
        Ok(here)
    }

    /// Starts a mandrel move to counter `target` from `counter` (nothing if equal).
    fn mandrel_start(
        &mut self,
        profile: MandrelMove,
        counter: i64,
        target: i64,
        armed: bool,
    ) -> Result<bool, Step> {
        let steps = target - counter;
        if steps == 0 {
            return Ok(false);
        }
        self.dev
            .mandrel
            .start_move(&MandrelMove { steps, ..profile }, armed)?;
        Ok(true)
    }

    fn mandrel_finish(&mut self, target: i64) -> Result<(), Step> {
        self.wait("mandrel move", MOVE_TIMEOUT_S, |d| {
            let (busy, fault) = d.mandrel.busy()?;
            if fault {
                return Err(DeviceError::Indexer(mandrel_drive::Error::Stalled));
            }
            Ok(!busy)
        })?;
        let c = self.dev.mandrel.counter_steps()?;
        if c != target {
            return Err(Step::Halt(Halt::Fault {
                message: format!("indexer: counter at {c} steps, expected {target}"),
            }));
        }
        Ok(())
    }

    /// The counter the item's sync aims at: the path's start angle (`sync_mandrel_deg`) nearest
    /// the mandrel's angle now.
    fn sync_target(&self, batch: &Batch, k: usize, counter: i64) -> i64 {
        let per_rev = batch.drive.steps_per_mandrel_rev();
        let want = batch.items[k].rob.header.sync_mandrel_deg / 360.0 * per_rev;
        let now = counter as f64;
        let delta = (want - now).rem_euclid(per_rev);
        let delta = if delta > per_rev / 2.0 {
            delta - per_rev
        } else {
            delta
        };
        counter + delta.round() as i64
    }

    /// Sync mandrel to robot: the robot at the path's first point, the mandrel at its start angle.
    fn sync_item(
        &mut self,
        batch: &Batch,
        k: usize,
        resume: Option<&ResumePoint>,
    ) -> Result<i64, Step> {
        let prep = &batch.prepared[k];
        let counter = self.dev.mandrel.counter_steps()?;
        let target = match resume.and_then(|r| r.sync_counter) {
            Some(t) => t,
            None => {
                let t = self.sync_target(batch, k, counter);
                self.journal
                    .append(json!({"rec": "sync", "item": k, "counter": t}))?;
                t
            }
        };
        let (base, max) = transfer::speeds(&batch.items[k].rob.header).map_err(|e| {
            Step::Halt(Halt::Fault {
                message: e.to_string(),
            })
        })?;
        self.dev.robot.set_speeds(base, max)?;
        let moving = self.mandrel_start(prep.mandrel[0], counter, target, false)?;
        if moving {
            self.mandrel_finish(target)?;
        }
        Ok(target)
    }

    fn discrete_item(
        &mut self,
        batch: &Batch,
        k: usize,
        resume: Option<&ResumePoint>,
    ) -> Result<(), Step> {
        let prep = &batch.prepared[k];
        let item = &batch.items[k];
        let base = self.sync_item(batch, k, resume)?;
        let from = resume.map_or(0, |r| r.segments_done);
        self.segments_done = from;
        let n = prep.targets_mm.len();
        // Where the robot is: read before the first segment, then what each segment confirmed.
        let mut here = None;
        for s in from..n {
            self.check()?;
            let target = base + prep.cumulative_steps[s + 1];
            // Send both, then wait for both (seed 001 §5.3.3).
            let counter = if s == from {
                self.dev.mandrel.counter_steps()?
            } else {
                base + prep.cumulative_steps[s]
            };
            // With the sync lines wired the mandrel's move waits for the start line, raised once
            // the robot's move is confirmed: both devices start together, where the indexer's
            // command and the robot's confirmation would otherwise put the mandrel 0.1–0.2 s
            // ahead of the arm on every segment.
            let wired = self.dev.sync.wired();
            let moving = self.mandrel_start(prep.mandrel[s], counter, target, wired)?;
            let at = match here {
                Some(p) => p,
                None => self.dev.robot.position_mm()?,
            };
            let sent = self.robot_send(prep.immediate[s], prep.targets_mm[s], at)?;
            // The mandrel's shorter move is confirmed while the arm still moves (its reads are
            // on the indexer's link, which does not hold the arm).
            if moving {
                if wired {
                    self.dev.sync.set_start(true)?;
                }
                self.mandrel_finish(target)?;
                if wired {
                    self.dev.sync.set_start(false)?;
                }
            }
            here = Some(if sent {
                self.robot_settle(prep.targets_mm[s])?
            } else {
                at
            });
            self.segments_done = s + 1;
            self.journal.append(json!({
                "rec": "segment", "item": k, "segment": s + 1,
                "robot_mm": prep.targets_mm[s], "counter": target,
                "t_s": self.dev.time.now_s(),
            }))?;
            (self.events)(Event::Segment {
                item: k + 1,
                program: item.rob.header.program,
                path: item.name.clone(),
                segment: s + 1,
                segments: n,
                time_s: self.dev.time.now_s(),
            });
        }
        Ok(())
    }

    fn program_item(
        &mut self,
        batch: &Batch,
        k: usize,
        resume: Option<&ResumePoint>,
    ) -> Result<(), Step> {
        let prep = &batch.prepared[k];
        let item = &batch.items[k];
        let n = prep.targets_mm.len();
        let last = prep.targets_mm[n - 1];
        let mut program = item.rob.header.program;
        let mut base = None;
        let ind = item
            .ind
            .as_ref()
            .map(|f| f.path_move)
            .unwrap_or(prep.mandrel[0]);
        if let Some(r) = resume.filter(|r| r.program_started)
            && let Some(sync) = r.sync_counter
        {
            // The program was started: ask the devices what they finished.
            let end = sync + prep.cumulative_steps[n];
            let s = self.dev.robot.state()?;
            let here = self.dev.robot.position_mm()?;
            // A move still turning (the devices ran on after `kill -9`) finishes (an armed
            // move that never saw its start edge was cancelled before the attach).
            self.wait("mandrel move", MOVE_TIMEOUT_S, |d| Ok(!d.mandrel.busy()?.0))?;
            let counter = self.dev.mandrel.counter_steps()?;
            if distance_mm(here, last) <= POSITION_TOLERANCE_MM && counter == end {
                return Ok(());
            }
            // The robot's instruction when it stopped; before the first position: start again.
            let reached = usize::from(s.instruction.saturating_sub(HANDSHAKE_LEAD));
            if reached >= 1 && counter != sync {
                let rest: Vec<Instruction> = prep
                    .program
                    .iter()
                    .flatten()
                    .filter(|i| matches!(i, Instruction::Position(_)))
                    .skip(reached - 1)
                    .copied()
                    .collect();
                let list = handshake_program(&rest);
                self.dev.robot.delete_program(RESUME_PROGRAM)?;
                self.dev.robot.upload(RESUME_PROGRAM, &list)?;
                self.dev.robot.read_back(RESUME_PROGRAM, &list)?;
                self.journal.append(json!({
                    "rec": "resume_program", "item": k, "program": RESUME_PROGRAM,
                    "from_instruction": reached,
                }))?;
                program = RESUME_PROGRAM;
                base = Some((sync, counter));
            }
        }
        let (sync, counter) = match base {
            Some(b) => b,
            None => {
                let sync = self.sync_item(batch, k, resume)?;
                // The approach: robot at the first point before the start edge.
                self.robot_to(prep.immediate[0], prep.targets_mm[0])?;
                (sync, sync)
            }
        };
        let end = sync + prep.cumulative_steps[n];
        self.journal
            .append(json!({"rec": "program", "item": k, "program": program}))?;
        (self.events)(Event::Program {
            item: k + 1,
            program,
            path: item.name.clone(),
            done: false,
            time_s: self.dev.time.now_s(),
        });
        // Handshake (App. D): run; the program lowers "in position" and waits for start.
        self.dev.robot.run_program(program)?;
        self.wait("the robot's handshake", MOVE_TIMEOUT_S, |d| {
            Ok(!d.sync.in_position()?)
        })?;
        // The mandrel's move, armed on the start line.
        let armed = self.mandrel_start(ind, counter, end, true)?;
        // While the program flies nothing is said to the robot: the robot computer holds the
        // arm while it serves the link (seed 001 §4.1.2), so every status read would stall the
        // eye against the turning mandrel (a read every half second put the eye 0.06 s per
        // second behind, timing drift of 7–14 mm on the S-bend). The start and in-position lines
        // pace the program, as in the thesis's program control (§5.6.4); the stop request and
        // the e-stop input are still looked at every control tick. A program that overruns its
        // mandrel move by half again plus a second is then read for errors.
        let mandrel_s = MandrelProfile {
            accel_rps2: ind.accel_rps2,
            start_stop_rps: ind.start_stop_rps,
            max_rps: ind.max_rps,
        }
        .duration_s(
            (end - counter).unsigned_abs(),
            batch.drive.steps_per_mandrel_rev(),
        );
        self.dev.sync.set_start(true)?;
        let quiet_until_s =
            self.dev.time.now_s() + PROGRAM_QUIET_FACTOR * mandrel_s + PROGRAM_QUIET_MARGIN_S;
        let mut polls = 0u32;
        self.wait("the robot's program", MOVE_TIMEOUT_S, |d| {
            if d.time.now_s() < quiet_until_s {
                return d.sync.in_position();
            }
            polls += 1;
            if polls.is_multiple_of(PROGRAM_POLL_TICKS) {
                let s = d.robot.state()?;
                if s.state == State::Error || s.last_error != 0 {
                    return Err(DeviceError::RobotState {
                        what: format!("error {} at instruction {}", s.last_error, s.instruction),
                    });
                }
            }
            d.sync.in_position()
        })?;
        // The program's end: one status read (the arm is at rest now) for an error shown
        // while it ran.
        let s = self.dev.robot.state()?;
        if s.state == State::Error || s.last_error != 0 {
            return Err(Step::Halt(Halt::Fault {
                message: format!(
                    "robot: error {} at instruction {} of program {program}",
                    s.last_error, s.instruction
                ),
            }));
        }
        self.dev.sync.set_start(false)?;
        if armed {
            self.mandrel_finish(end)?;
        }
        let here = self.dev.robot.position_mm()?;
        if distance_mm(here, last) > POSITION_TOLERANCE_MM {
            return Err(Step::Halt(Halt::Fault {
                message: format!(
                    "robot: program {program} ended {:.2} mm from its last point",
                    distance_mm(here, last)
                ),
            }));
        }
        self.segments_done = n;
        (self.events)(Event::Program {
            item: k + 1,
            program,
            path: item.name.clone(),
            done: true,
            time_s: self.dev.time.now_s(),
        });
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distance_is_euclidean_and_mode_keywords_round_trip() {
        // The 3-4-12 right triangle: 13.
        assert_eq!(distance_mm([1.0, 2.0, 3.0], [4.0, 6.0, 15.0]), 13.0);
        for m in [
            RunMode::Discrete,
            RunMode::Fine,
            RunMode::Medium,
            RunMode::Continuous,
        ] {
            assert_eq!(RunMode::from_keyword(m.keyword()), Some(m));
            assert_eq!(RunMode::from_movement(m.movement()), m);
        }
        assert_eq!(RunMode::from_keyword("coarse"), None);
        // Only continuous mode starts its program at the path's second point.
        assert_eq!(RunMode::Continuous.points_before_program(), 1);
        assert_eq!(RunMode::Medium.points_before_program(), 0);
    }
}
