//! The indexer's byte link: a serial port. The [`Link`] contract, the in-memory [`Pipe`], the
//! [`Cancel`] token and the clocks are the ones both device crates share ([`paths::link`]).

pub use paths::link::{Cancel, Clock, Link, Pipe, VirtualClock, WallClock};

paths::serial_link!();
