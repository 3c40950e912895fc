//! Winding a batch on a cell (seed 001 §5.3, §5.6.3–5.6.4): the batch and the cell file, the
//! conversion of control files into device commands, the journal, the devices and the
//! coordinator.
//!
//! ```text
//! batch (job planned in memory, or .SEQ/.RUN + .ROB/.IND) + cellfile (ports, drive, sync lines)
//!   │ transfer: .ROB → telegrams, .IND → indexer commands (pure)
//!   ▼
//! coordinator ── device (RobotDevice, MandrelDevice, SyncLines, Timebase) ──► links
//!   │ journal: one synced record per confirmed step
//!   ▼
//! events (progress, --json, recording)
//! ```
//!
//! Production code here knows the devices only through `device`'s traits and the device crates'
//! protocol modules; the simulated cell (`crate::sim`) implements the same traits.

pub mod batch;
pub mod cellfile;
pub mod coordinator;
pub mod device;
pub mod journal;
pub mod transfer;
