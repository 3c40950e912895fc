//! The indexer simulator: indexer card, translator, stepper motor and belt, on a clock, with a
//! front end per dialect (docs/mandrel-drive.md; seed 001 §4.1.4–4.1.8, §5.3.2).

pub mod grbl;
pub mod machine;
pub mod marlin;
pub mod motion;
pub mod motor;
pub mod serial;
pub mod winder;
pub mod xlang;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

pub use machine::Machine;
/// The simulator's clocks: the ones both device crates share ([`paths::link`]).
pub use paths::link::{Clock, VirtualClock, WallClock};

use crate::error::Result;
use crate::link::Link;

/// A dialect front end: bytes in, bytes out, time passing.
pub trait Frontend: Send {
    /// Takes bytes from the host at clock time `now_s`.
    fn receive(&mut self, bytes: &[u8], now_s: f64);
    /// Lets the clock run to `now_s`: moves progress, buffered commands continue.
    fn poll(&mut self, now_s: f64);
    /// Bytes to send to the host.
    fn take_output(&mut self) -> Vec<u8>;
    /// The simulated hardware (mandrel angle, steps, flags).
    fn machine(&self) -> &Machine;
    /// When the front end next needs [`Frontend::poll`] for its timing to be exact (clock time,
    /// s), `sample_s` being the finest step a ramp needs ([`Machine::next_event_s`]); `None`
    /// when only bytes from the host or a trigger can change anything.
    fn next_event_s(&self, sample_s: f64) -> Option<f64> {
        self.machine().next_event_s(sample_s)
    }
}

/// How long the serving loop waits for host bytes before letting the clock run.
pub const POLL_PERIOD: Duration = Duration::from_millis(2);

/// Serves `front` over `link` until `stop` is set: host bytes in, replies and notifications out,
/// motion advanced on `clock`. The front end stays shared so that its mandrel can be watched.
pub fn serve<L: Link, F: Frontend>(
    mut link: L,
    front: &Arc<Mutex<F>>,
    clock: &dyn Clock,
    stop: &AtomicBool,
) -> Result<()> {
    let mut buf = [0u8; 256];
    while !stop.load(Ordering::Relaxed) {
        let n = link.read_timeout(&mut buf, POLL_PERIOD)?;
        let out = {
            let mut f = front
                .lock()
                .map_err(|_| std::io::Error::other("simulator lock poisoned"))?;
            let now = clock.now_s();
            if let Some(bytes) = buf.get(..n)
                && n > 0
            {
                f.receive(bytes, now);
            }
            f.poll(now);
            f.take_output()
        };
        if !out.is_empty() {
            link.write_all(&out)?;
        }
    }
    Ok(())
}
