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
use std::sync::atomic::AtomicBool;
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

mod checked;
mod discrete;
mod halt;
mod jog;
mod moves;
mod program;
mod resume;
mod stop;

pub use checked::{Batch, Item, ItemPlaces, Reach, handshake_program, program_units};
pub use halt::{ArmWitness, Disagreement, Fault, Halt, Stopped};
pub use resume::{ARM_WITNESS_MM, ResumePoint, distance_to_segment_mm, resume_point};
pub use stop::StopRequest;

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
    /// A phase of the run began that is not winding a segment.
    Phase {
        /// Which.
        phase: Phase,
        /// Cell time, s.
        time_s: f64,
    },
    /// Program upload progress (program mode): telegram exchanges done of those the upload
    /// takes (each instruction stored, verified and read back: three per instruction).
    Upload {
        /// Exchanges done.
        done: usize,
        /// Exchanges in all.
        total: usize,
        /// Cell time, s.
        time_s: f64,
    },
    /// Programs uploaded and read back (program mode).
    Uploaded {
        /// Programs.
        programs: Vec<u8>,
    },
    /// A segment of the plan wound, numbered as the plan numbers them (1..N; the approach to the
    /// path's first point is not a segment). In discrete mode the robot and the indexer both
    /// confirmed it; in program mode the indexer's steps through the path's single move passed
    /// the segment's end (the robot is not asked while its program runs, seed 001 §4.1.2).
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
        /// Who confirmed it.
        witness: Witness,
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

/// The phases of a run that wind no segment, as the operator sees them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    /// The robot's home synchronisation (seed 001 §5.3.1).
    Homing,
    /// The batch's programs stored in the robot computer and read back (program mode).
    Upload,
    /// Item `item` (from 1): the mandrel to the path's start angle and the arm to its first
    /// point, before segment 1.
    Approach {
        /// Batch item, from 1.
        item: usize,
    },
    /// Item `item` (from 1): the approach done, its segments (discrete) or its program begin.
    Winding {
        /// Batch item, from 1.
        item: usize,
    },
}

impl Phase {
    /// The word `--json` prints.
    pub fn keyword(self) -> &'static str {
        match self {
            Phase::Homing => "homing",
            Phase::Upload => "upload",
            Phase::Approach { .. } => "approach",
            Phase::Winding { .. } => "winding",
        }
    }
}

/// Who confirmed a segment (see [`Event::Segment`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Witness {
    /// Both devices, each its own move (discrete mode).
    Both,
    /// The indexer's step count through the path's move (program mode).
    Indexer,
}

impl Witness {
    /// The word `--json` prints.
    pub fn keyword(self) -> &'static str {
        match self {
            Witness::Both => "robot and indexer",
            Witness::Indexer => "indexer",
        }
    }
}

/// The event in words, as the recording's `/log` shows it (`path 1 SBEND_1: segment 3/50 wound
/// at t = 61.2 s (indexer)`).
impl std::fmt::Display for Event {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Event::Started {
                mode,
                items,
                resumed,
            } => write!(
                f,
                "{} {items} path{} in {} mode",
                if *resumed { "resumed" } else { "started" },
                if *items == 1 { "" } else { "s" },
                mode.keyword()
            ),
            Event::Uploaded { programs } => {
                let list: Vec<String> = programs.iter().map(u8::to_string).collect();
                write!(
                    f,
                    "program{} {} uploaded and read back",
                    if programs.len() == 1 { "" } else { "s" },
                    list.join(", ")
                )
            }
            Event::Segment {
                item,
                path,
                segment,
                segments,
                witness,
                time_s,
                ..
            } => write!(
                f,
                "path {item} {path}: segment {segment}/{segments} wound at t = {time_s:.1} s ({})",
                witness.keyword()
            ),
            Event::Phase { phase, time_s } => match phase {
                Phase::Homing => write!(f, "homing the robot at t = {time_s:.1} s"),
                Phase::Upload => write!(f, "uploading the programs at t = {time_s:.1} s"),
                Phase::Approach { item } => {
                    write!(f, "path {item}: to its start at t = {time_s:.1} s")
                }
                Phase::Winding { item } => write!(f, "path {item}: winding at t = {time_s:.1} s"),
            },
            Event::Upload {
                done,
                total,
                time_s,
            } => write!(f, "upload: {done}/{total} exchanges at t = {time_s:.1} s"),
            Event::Program {
                item,
                program,
                path,
                done,
                time_s,
            } => write!(
                f,
                "path {item} {path}: program {program} {} at t = {time_s:.1} s",
                if *done { "done" } else { "started" }
            ),
            Event::PathDone {
                item,
                path,
                program,
                time_s,
            } => write!(
                f,
                "path {item} {path} done (program {program}) in {time_s:.1} s"
            ),
        }
    }
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

/// The coordinator: drives the devices through a batch.
pub struct Coordinator<'a> {
    dev: Devices,
    stop: StopRequest,
    journal: Journal,
    events: &'a mut dyn FnMut(Event),
    item: usize,
    segments_done: usize,
    /// The indexer's counter minus the batch's counter (a re-reference's offset, 0 before any).
    offset_steps: i64,
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
        Step::Halt(Halt::Fault(e.into()))
    }
}

impl From<JournalError> for Step {
    fn from(e: JournalError) -> Self {
        Step::Halt(Halt::Fault(e.into()))
    }
}

impl From<Fault> for Step {
    fn from(f: Fault) -> Self {
        Step::Halt(Halt::Fault(f))
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
            offset_steps: 0,
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

    /// The indexer's counter in the batch's frame (a re-reference's offset taken off).
    fn counter(&mut self) -> Result<i64, DeviceError> {
        Ok(self.dev.mandrel.counter_steps()? - self.offset_steps)
    }

    /// Waits (one control tick at a time, looking at the stop request) until `done`.
    fn wait(
        &mut self,
        what: &'static str,
        timeout_s: f64,
        mut done: impl FnMut(&mut Devices) -> Result<bool, DeviceError>,
    ) -> Result<(), Step> {
        self.wait_reporting(what, timeout_s, |d, _| done(d))
    }

    /// [`Self::wait`], with `done` also handed the event sink (to report progress while it
    /// waits).
    fn wait_reporting(
        &mut self,
        what: &'static str,
        timeout_s: f64,
        mut done: impl FnMut(&mut Devices, &mut dyn FnMut(Event)) -> Result<bool, DeviceError>,
    ) -> Result<(), Step> {
        let t0 = self.dev.time.now_s();
        loop {
            self.check()?;
            if done(&mut self.dev, &mut *self.events)? {
                return Ok(());
            }
            if self.dev.time.now_s() - t0 > timeout_s {
                return Err(Fault::Timeout { what, timeout_s }.into());
            }
            self.dev.time.tick(CONTROL_TICK);
        }
    }

    fn phase(&mut self, phase: Phase) {
        let time_s = self.dev.time.now_s();
        (self.events)(Event::Phase { phase, time_s });
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
                    Halt::Fault(_) if self.stop.is_requested() => Halt::Interrupted {
                        reason: self.stop.reason(),
                    },
                    h => h,
                };
                let item = self.item.min(batch.items.len().saturating_sub(1));
                // A stall is kept as a flag: its counter is no witness on the resume.
                let stall = halt.fault().is_some_and(Fault::is_stall);
                let _ = self.journal.append(json!({
                    "rec": "stopped",
                    "item": item,
                    "segments_done": self.segments_done,
                    "reason": halt.reason(),
                    "stall": stall,
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
        // Attach: each link resynchronised before its first command (a run killed before this
        // one may have left stale bytes, a move under way, an armed move, a robot homing); the
        // indexer without zeroing, then zeroed once for a fresh batch.
        self.dev.sync.set_start(false)?;
        self.dev.robot.attach()?;
        let counter = self.dev.mandrel.attach()?;
        if fresh {
            self.dev.mandrel.zero()?;
            self.journal
                .append(json!({"rec": "mandrel_zero", "counter_before": counter}))?;
        } else {
            // Never one witness: the counter against the journal before anything turns.
            self.reconcile_mandrel(batch, from, counter)?;
        }
        self.ready_robot()?;
        if batch.mode != RunMode::Discrete {
            if !self.dev.sync.wired() {
                return Err(Fault::NoSyncLines.into());
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
