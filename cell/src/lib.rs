//! The windcell coordinator library, cut by stage:
//!
//! - [`plan`]: the TOOL step, the collision and snag check, the plan's files and report;
//! - [`run`]: the batch, the cell file, the transfer to device commands, the journal, the devices
//!   and the coordinator;
//! - [`sim`]: the simulated cell (both device simulators and the sync lines on one clock);
//! - [`record`]: MCAP recording and the live Foxglove view, and the taps that feed them;
//! - [`predict`]: time and placement error, from runs on the simulated cell;
//! - [`verify`]: a six-axis arm's robot programs read back, checked and run on a model of the
//!   cell;
//! - [`lathe`]: the lathe-type winder (seed 000) and its G-code.
//!
//! The stages depend on each other in that order only (`plan` ← `run` ← `record` ← `sim` ←
//! `predict` ← `verify`; `lathe` stands alone); `tests/it/layering.rs` keeps it so. The `windcell` command
//! line (`src/cli/`) is built on them.

pub mod error;
pub mod lathe;
pub mod plan;
pub mod predict;
pub mod record;
pub mod run;
pub mod sim;
pub mod verify;

pub use error::Error;
