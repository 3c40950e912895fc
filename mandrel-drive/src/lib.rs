//! The mandrel drive: stepper indexer languages, simulator, sync lines (seed 001 §4.1.4–4.1.8).
//!
//! - [`units`]: physical units at the mandrel → motor steps, through [`paths::Gearing`].
//! - [`profile`]: the trapezoid with a start/stop velocity jump, analytic duration.
//! - [`xlang`], [`grbl`]: typed commands and replies of the two dialects (spec/protocols.md §2.2, §2.4).
//! - [`link`]: the byte link (serial port, in-memory pipe).
//! - [`client`]: the [`Indexer`] seam (spec §6) for both dialects.
//! - [`sim`]: indexer + translator + motor + gear simulator with a front end per dialect.
//! - [`lathe`]: the lathe winder's PD axis controller, machine-zero search, electronic gearing and
//!   the interrupt clocks (simulated, wall clock with jitter).
//! - [`servo`]: the lathe winder's DC servo axes (plant, DAC, encoders, limit switches) behind the
//!   [`servo::AxisIo`] seam (seed 000 Ch. 6–7).
//! - [`sync`]: the opto-isolated "robot in position" and "start" lines (seed 001 App. D).

pub mod client;
pub mod error;
pub mod grbl;
pub mod lathe;
pub mod link;
pub mod profile;
pub mod servo;
pub mod sim;
pub mod sync;
pub mod units;
pub mod xlang;

pub use client::{
    Direction, GrblClient, Indexer, IndexerConfig, IndexerStatus, PosMode, StopKind, XClient,
};
pub use error::Error;
pub use link::{Link, Pipe};
pub use profile::{Profile, trapezoid_duration_s};
pub use units::Drive;
