//! Why a run stopped: the operator's stop, or a [`Fault`] that keeps its cause.
//!
//! A fault's words (its `Display`) are what the operator reads, the journal's `stopped` record
//! keeps and `predict` reports; what a program decides on (the exit code, whether `predict` places
//! a stall at the drive's acceleration) comes from the variant and the error it carries.

use std::sync::Arc;

use asea_protocol::State;

use crate::run::device::DeviceError;
use crate::run::journal::JournalError;

/// Why the run stopped before the end.
#[derive(Debug, Clone)]
pub enum Halt {
    /// Ctrl-C, the console's `s`, or the e-stop input.
    Interrupted {
        /// Which.
        reason: String,
    },
    /// A device failed, or the cell did not show what a command asked for (both devices were
    /// told to stop).
    Fault(Fault),
}

impl Halt {
    /// Why the run stopped, in words (the interruption's reason or the fault's message).
    pub fn reason(&self) -> String {
        match self {
            Halt::Interrupted { reason } => reason.clone(),
            Halt::Fault(fault) => fault.to_string(),
        }
    }

    /// The fault, if the run stopped on one.
    pub fn fault(&self) -> Option<&Fault> {
        match self {
            Halt::Fault(fault) => Some(fault),
            Halt::Interrupted { .. } => None,
        }
    }
}

/// What went wrong while the devices moved, with its cause. Device and journal errors are shared
/// (`Arc`) so that a halt can be cloned into the events, the journal and the report.
#[derive(Debug, Clone, thiserror::Error)]
#[non_exhaustive]
pub enum Fault {
    /// A device's link or the device itself (the robot's error code, the indexer's stall, a
    /// timeout on the wire): [`DeviceError`] as the device layer reported it.
    #[error("{0}")]
    Device(Arc<DeviceError>),
    /// The journal could not be written: the run stops rather than move without a record.
    #[error("{0}")]
    Journal(Arc<JournalError>),
    /// A wait ran past its limit ([`super::MOVE_TIMEOUT_S`], [`super::HOME_TIMEOUT_S`]).
    #[error("{what}: not done after {timeout_s:.0} s")]
    Timeout {
        /// What was waited for.
        what: &'static str,
        /// The limit, s of the cell's time.
        timeout_s: f64,
    },
    /// Program mode on a cell without sync lines (App. D: the start and in-position lines pace
    /// a stored program).
    #[error("program mode needs the sync lines: name a sync port")]
    NoSyncLines,
    /// A jog's target does not fit the telegram (relative to where the robot stands, or the
    /// pose with the base yaw put in front).
    #[error("{what}: {source}")]
    JogTelegram {
        /// Which conversion.
        what: &'static str,
        /// The telegram's range error (boxed: a halt travels in every run's result).
        source: Box<asea_protocol::EncodeError>,
    },
    /// A jog's eye target outside the arm's working range.
    #[error(
        "the eye at ({:.1}, {:.1}, {:.1}) mm is out of the arm's reach",
        eye_mm[0], eye_mm[1], eye_mm[2]
    )]
    OutOfReach {
        /// The target, cell frame, mm.
        eye_mm: [f64; 3],
    },
    /// The robot was not idle and error-free at the end of an immediate move.
    #[error("robot: state {state:?}, error {error} after a move")]
    NotIdleAfterMove {
        /// The state it reported.
        state: State,
        /// Its last error code (seed 001 §5.2; 0: none).
        error: u8,
    },
    /// The robot ended an immediate move away from its target.
    #[error(
        "robot: at ({:.2}, {:.2}, {:.2}) mm, {off_mm:.2} mm from its target",
        at_mm[0], at_mm[1], at_mm[2]
    )]
    OffTarget {
        /// Where it stands, cell frame, mm.
        at_mm: [f64; 3],
        /// How far from the target, mm.
        off_mm: f64,
    },
    /// The indexer's counter after a move is not the move's destination.
    #[error("indexer: counter at {counter_steps} steps, expected {expected_steps}")]
    CounterMismatch {
        /// The counter read back, steps.
        counter_steps: i64,
        /// The destination, steps.
        expected_steps: i64,
    },
    /// A control file's value could not be converted (a bug: the pre-run check converts them
    /// all).
    #[error("{0}")]
    Transfer(Arc<crate::Error>),
    /// The robot reported an error at the end of a stored program.
    #[error("robot: error {error} at instruction {instruction} of program {program}")]
    ProgramError {
        /// The robot's error code.
        error: u8,
        /// The instruction it stood at.
        instruction: u16,
        /// The program.
        program: u8,
    },
    /// A stored program ended away from the path's last point.
    #[error("robot: program {program} ended {off_mm:.2} mm from its last point")]
    ProgramEndedOff {
        /// The program.
        program: u8,
        /// How far from the last point, mm.
        off_mm: f64,
    },
    /// On a resume the witnesses of the mandrel's angle disagree: the indexer's counter is not
    /// where the journal leaves the mandrel (a power-cycled indexer reads 0, a journal cut short
    /// is behind the devices), or the run before stopped on a stall (its counter counted steps
    /// the motor never made). Winding on would wind off-angle; the mandrel is re-referenced
    /// first.
    #[error(
        "indexer: {cause}: the counter reads {counter_steps} steps where the journal leaves the mandrel at {}; re-reference the mandrel: turn it to step {confirmed_steps} of the batch ({confirmed_deg:.1}° from the batch's zero, the last confirmed step) and resume with --rereference, or start over with --restart",
        window(*confirmed_steps, *next_steps)
    )]
    MandrelUnreferenced {
        /// Which witness failed.
        cause: Disagreement,
        /// The indexer's counter in the batch's frame, steps.
        counter_steps: i64,
        /// The journal's last confirmed destination, steps.
        confirmed_steps: i64,
        /// The destination of the step that may have been under way, steps.
        next_steps: Option<i64>,
        /// The last confirmed destination as a mandrel angle from the batch's zero, degrees.
        confirmed_deg: f64,
    },
    /// On a discrete resume the arm does not stand where the journal leaves it (on the move
    /// from the last confirmed point to the next): homed again after a power loss, or moved by
    /// hand.
    #[error("{0}")]
    ArmUnreferenced(Box<ArmWitness>),
}

/// Where the arm stands against the journal on a discrete resume ([`Fault::ArmUnreferenced`]).
#[derive(Debug, Clone, thiserror::Error)]
#[error(
    "robot: the arm stands at ({:.1}, {:.1}, {:.1}) mm, {off_mm:.1} mm from segment {segment}'s move where the journal leaves it; bring it to the last confirmed point with `windcell jog --pos {:.3},{:.3},{:.3}` and resume",
    at_mm[0], at_mm[1], at_mm[2], confirmed_mm[0], confirmed_mm[1], confirmed_mm[2]
)]
pub struct ArmWitness {
    /// Where the arm stands, cell frame, mm.
    pub at_mm: [f64; 3],
    /// The last confirmed point, cell frame, mm.
    pub confirmed_mm: [f64; 3],
    /// How far from the move it may have been on, mm.
    pub off_mm: f64,
    /// The segment (from 1) after the last confirmed one.
    pub segment: usize,
}

/// Which witness of the mandrel's angle disagreed on a resume ([`Fault::MandrelUnreferenced`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Disagreement {
    /// The counter is outside what the journal allows.
    Counter,
    /// The run before stopped on a stall.
    Stalled,
}

impl std::fmt::Display for Disagreement {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Disagreement::Counter => {
                "the counter and the journal disagree (a power-cycled indexer, a journal cut short, or a counter moved by another program)"
            }
            Disagreement::Stalled => {
                "the motor stalled in the run before, so its counter holds steps the mandrel never made"
            }
        })
    }
}

fn window(confirmed: i64, next: Option<i64>) -> String {
    match next {
        Some(n) => format!("{confirmed} to {n} steps"),
        None => format!("{confirmed} steps"),
    }
}

impl Fault {
    /// True where the run stopped because the mandrel must be re-referenced before a resume.
    pub fn needs_rereference(&self) -> bool {
        matches!(self, Fault::MandrelUnreferenced { .. })
    }

    /// The device error behind the fault, if a device reported it.
    pub fn device_error(&self) -> Option<&DeviceError> {
        match self {
            Fault::Device(e) => Some(e),
            _ => None,
        }
    }

    /// True for the indexer's stall (the motor lost its pull-in torque, seed 001 §4.1.4): the
    /// job's drive profile is the figure to change.
    pub fn is_stall(&self) -> bool {
        matches!(
            self.device_error(),
            Some(DeviceError::Indexer(mandrel_drive::Error::Stalled))
        )
    }

    /// True where the fault is the input's (a jog target the arm or the telegram cannot take),
    /// found before anything moved: `windcell` exits with code 2 for these, 1 for the others.
    pub fn is_input(&self) -> bool {
        matches!(self, Fault::JogTelegram { .. } | Fault::OutOfReach { .. })
    }
}

impl From<DeviceError> for Fault {
    fn from(e: DeviceError) -> Self {
        Fault::Device(Arc::new(e))
    }
}

impl From<JournalError> for Fault {
    fn from(e: JournalError) -> Self {
        Fault::Journal(Arc::new(e))
    }
}

/// Where a stopped run stood.
#[derive(Debug, Clone)]
pub struct Stopped {
    /// Why.
    pub halt: Halt,
    /// Batch item (from 1) and path name.
    pub item: usize,
    /// Path name.
    pub path: String,
    /// Segments confirmed in that path.
    pub segments_done: usize,
    /// The stop commands that failed (robot, indexer), each with its device error.
    pub stop_errors: Vec<Arc<DeviceError>>,
}
