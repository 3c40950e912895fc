//! Clocks: wall time, or a virtual clock that moves only when told (tests, benches, a whole
//! program simulated in milliseconds). The ones both device crates share ([`paths::link`]).

pub use paths::link::{Clock, VirtualClock, WallClock};
