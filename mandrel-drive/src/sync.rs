//! The opto-isolated sync lines between robot, PC and indexer (seed 001 App. D, Figure D.1;
//! docs/hardware.md).
//!
//! "Robot in position" is an input to the PC (the robot's 24 V output through an opto-isolator);
//! "start" is an output from the PC to robot and indexer together. [`Wire`] simulates one line with
//! an opto delay on a clock; `ModemLine` (feature `hardware`) drives the real lines on a
//! serial port's modem-control pins.

use std::collections::VecDeque;
use std::io;
use std::sync::{Arc, Mutex};

use crate::sim::Clock;

/// A line the PC reads ("robot in position", or the indexer's trigger input).
pub trait SyncInput: Send + std::fmt::Debug {
    /// The current level (true = asserted).
    fn level(&mut self) -> io::Result<bool>;
}

/// A line the PC drives ("start").
pub trait SyncOutput: Send + std::fmt::Debug {
    /// Asserts (true) or releases (false) the line.
    fn set(&mut self, level: bool) -> io::Result<()>;
}

/// A typical opto-coupler propagation delay (s); configurable per wire.
pub const OPTO_DELAY_S: f64 = 20e-6;

#[derive(Debug)]
struct Line {
    /// (clock time, level) transitions, oldest first; the first entry is the settled level.
    edges: VecDeque<(f64, bool)>,
}

/// A simulated line: one driver, any number of receivers, each seeing a level change `delay_s`
/// after it was driven (the opto-isolator), on a shared clock.
#[derive(Debug, Clone)]
pub struct Wire {
    line: Arc<Mutex<Line>>,
    clock: Arc<dyn Clock>,
    delay_s: f64,
}

impl Wire {
    /// A released line with the given opto delay.
    pub fn new(clock: Arc<dyn Clock>, delay_s: f64) -> Self {
        Wire {
            line: Arc::new(Mutex::new(Line {
                edges: VecDeque::from([(f64::NEG_INFINITY, false)]),
            })),
            clock,
            delay_s: delay_s.max(0.0),
        }
    }

    /// The level seen at the receiving side now.
    pub fn received(&self) -> io::Result<bool> {
        let seen_at = self.clock.now_s() - self.delay_s;
        let mut line = self
            .line
            .lock()
            .map_err(|_| io::Error::other("wire lock"))?;
        // Drop edges that every receiver has already seen past.
        while line.edges.len() > 1 && line.edges.get(1).is_some_and(|(t, _)| *t <= seen_at) {
            line.edges.pop_front();
        }
        Ok(line
            .edges
            .iter()
            .rev()
            .find(|(t, _)| *t <= seen_at)
            .is_some_and(|(_, l)| *l))
    }

    /// Drives the line at the current clock time.
    pub fn drive(&self, level: bool) -> io::Result<()> {
        let now = self.clock.now_s();
        let mut line = self
            .line
            .lock()
            .map_err(|_| io::Error::other("wire lock"))?;
        if line.edges.back().is_none_or(|(_, l)| *l != level) {
            line.edges.push_back((now, level));
        }
        Ok(())
    }
}

impl SyncInput for Wire {
    fn level(&mut self) -> io::Result<bool> {
        self.received()
    }
}

impl SyncOutput for Wire {
    fn set(&mut self, level: bool) -> io::Result<()> {
        self.drive(level)
    }
}

#[cfg(feature = "hardware")]
pub use modem::{ModemLine, Pin};

#[cfg(feature = "hardware")]
mod modem {
    //! Real lines on RS-232 modem-control pins (docs/hardware.md).

    use std::io;
    use std::sync::{Arc, Mutex};

    use super::{SyncInput, SyncOutput};

    /// A modem-control pin of a serial port.
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub enum Pin {
        /// Clear To Send (input, DB9 pin 8).
        Cts,
        /// Data Set Ready (input, DB9 pin 6).
        Dsr,
        /// Request To Send (output, DB9 pin 7).
        Rts,
        /// Data Terminal Ready (output, DB9 pin 4).
        Dtr,
    }

    /// One sync line on a modem-control pin; several lines may share a port.
    pub struct ModemLine {
        port: Arc<Mutex<Box<dyn serialport::SerialPort>>>,
        pin: Pin,
        inverted: bool,
    }

    impl std::fmt::Debug for ModemLine {
        fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            f.debug_struct("ModemLine")
                .field("pin", &self.pin)
                .field("inverted", &self.inverted)
                .finish()
        }
    }

    impl ModemLine {
        /// A line on `pin` of the shared `port`; `inverted` flips the level (an opto-isolator that
        /// pulls the pin low when the robot side is at 24 V).
        pub fn new(
            port: Arc<Mutex<Box<dyn serialport::SerialPort>>>,
            pin: Pin,
            inverted: bool,
        ) -> Self {
            ModemLine {
                port,
                pin,
                inverted,
            }
        }
    }

    fn lock_err() -> io::Error {
        io::Error::other("serial port lock poisoned")
    }

    impl SyncInput for ModemLine {
        fn level(&mut self) -> io::Result<bool> {
            let mut port = self.port.lock().map_err(|_| lock_err())?;
            let raw = match self.pin {
                Pin::Cts => port.read_clear_to_send(),
                Pin::Dsr => port.read_data_set_ready(),
                Pin::Rts | Pin::Dtr => {
                    return Err(io::Error::new(
                        io::ErrorKind::InvalidInput,
                        "RTS and DTR are outputs",
                    ));
                }
            }
            .map_err(io::Error::from)?;
            Ok(raw != self.inverted)
        }
    }

    impl SyncOutput for ModemLine {
        fn set(&mut self, level: bool) -> io::Result<()> {
            let mut port = self.port.lock().map_err(|_| lock_err())?;
            let raw = level != self.inverted;
            match self.pin {
                Pin::Rts => port.write_request_to_send(raw),
                Pin::Dtr => port.write_data_terminal_ready(raw),
                Pin::Cts | Pin::Dsr => {
                    return Err(io::Error::new(
                        io::ErrorKind::InvalidInput,
                        "CTS and DSR are inputs",
                    ));
                }
            }
            .map_err(io::Error::from)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::VirtualClock;

    #[test]
    fn wire_delays_edges() {
        let clock = VirtualClock::new();
        let start = Wire::new(Arc::new(clock.clone()), 0.001);
        let mut robot_side = start.clone();
        let mut indexer_side = start.clone();
        let mut pc = start.clone();
        assert!(!robot_side.level().unwrap());
        pc.set(true).unwrap();
        clock.advance_s(0.0005);
        assert!(!robot_side.level().unwrap());
        clock.advance_s(0.0006);
        assert!(robot_side.level().unwrap());
        assert!(indexer_side.level().unwrap());
        pc.set(false).unwrap();
        assert!(indexer_side.level().unwrap());
        clock.advance_s(0.002);
        assert!(!indexer_side.level().unwrap());
    }

    /// A line toggled for a whole shift keeps only the edges a receiver may still see: memory
    /// stays bounded however long the cell runs, and every level read is the one driven a delay
    /// earlier.
    #[test]
    fn a_wire_forgets_edges_every_receiver_has_seen() {
        let clock = VirtualClock::new();
        let mut pc = Wire::new(Arc::new(clock.clone()), 0.001);
        let mut robot_side = pc.clone();
        for k in 0..10_000u32 {
            let level = k % 2 == 0;
            pc.set(level).unwrap();
            clock.advance_s(0.0015);
            assert_eq!(robot_side.level().unwrap(), level);
            assert!(pc.line.lock().unwrap().edges.len() <= 2);
        }
        // Within the delay the earlier level is still seen, so its edge is kept.
        pc.set(true).unwrap();
        clock.advance_s(0.0005);
        assert!(!robot_side.level().unwrap());
        assert_eq!(pc.line.lock().unwrap().edges.len(), 2);
    }
}
