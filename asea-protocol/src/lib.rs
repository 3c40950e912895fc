//! The ASEA robot-computer link (seed 001 §5.2; wire definition in `docs/protocol.md`).
//!
//! - [`frame`]: STX/ETX framing and the check value (docs/protocol.md §3).
//! - [`command`]: typed telegrams and scales (seed 001 §5.4; spec §5.6–5.7).
//! - [`decoder`]: the incremental, length-framed decoder that resynchronises after noise.
//! - [`session`]: the host and robot session state machines, no I/O, timers as inputs (spec §5.4–5.5).
//! - [`link`]: the byte link (serial port, in-memory pipe, fault injector, tap, paced virtual wire).
//! - [`client`]: the blocking client with its retry policy.
//! - [`clock`]: real or virtual time.
//! - [`sim`]: the robot computer: memory, programs, modes, motion model, output and input lines.

pub mod client;
pub mod clock;
pub mod command;
pub mod decoder;
pub mod error;
pub mod frame;
pub mod link;
pub mod session;
pub mod sim;

pub use client::{Client, ClientConfig, RetryPolicy};
pub use command::RobotError;
pub use command::{
    Command, Control, Flags, Instruction, Interpolation, Length, Mode, Pose, Positioning,
    Quaternion, Reference, Reply, Selector, Speed, State, Status, Zone,
};
pub use decoder::{Decoder, Token};
pub use error::{EncodeError, Error, FrameError, LinkError, ParseError, Result};
pub use frame::{Checksum, ChecksumSpan, Frame, FrameConfig};
pub use link::Link;
pub use session::{Host, RobotSession, Timers};
pub use sim::Robot;
