//! The byte-link contract (`paths::link::contract`) on every link of this crate: the serial port
//! on a pseudo-terminal pair, the tap and the fault injector (with no faults) over a pipe, and
//! the paced virtual-time wire.

use std::time::Duration;

use asea_protocol::clock::{Clock as _, VirtualClock};
use asea_protocol::link::{FaultRates, Faults, Faulty, Paced, Peer, Pipe, SerialLink, Tap};
use paths::link::contract::{self, Harness, Pair};
use paths::link::{Cancel, POLL_PERIOD};

/// The serial link on a pseudo-terminal pair: the slave end checked, the master its far end,
/// a write at the master waiting at the slave once the slave counts it.
#[cfg(unix)]
#[test]
fn the_serial_link_keeps_the_contract_on_a_pseudo_terminal() {
    let (master, slave) = SerialLink::pty_pair().unwrap();
    contract::check(&mut Pair::new(slave, master).with_arrival(Box::new(|near| near.waiting())));
}

/// The tap records and passes everything through; the fault injector with every rate 0 is the
/// line itself.
#[test]
fn the_tap_and_the_fault_injector_keep_the_contract_over_a_pipe() {
    let (near, far) = Pipe::pair();
    let (tap, log) = Tap::new(near);
    contract::check(&mut Pair::new(tap, far));
    assert!(!log.lock().unwrap().is_empty());
    let (near, far) = Pipe::pair();
    let none = Faults::new(FaultRates::uniform(0.0), 1);
    contract::check(&mut Pair::new(Faulty::new(near, none), far));
}

/// A device at the far end of a paced wire: it keeps what it receives, sends what it is given,
/// and sets a cancel token at a given time of the wire's clock.
#[derive(Debug, Default)]
struct Far {
    received: Vec<u8>,
    outbox: Vec<u8>,
    cancel_at: Option<(Duration, Cancel)>,
}

impl Peer for Far {
    fn receive(&mut self, bytes: &[u8], _now: Duration) {
        self.received.extend_from_slice(bytes);
    }
    fn poll(&mut self, now: Duration) {
        if let Some((at, cancel)) = &self.cancel_at
            && now >= *at
        {
            cancel.cancel();
            self.cancel_at = None;
        }
    }
    fn take_output(&mut self) -> Vec<u8> {
        std::mem::take(&mut self.outbox)
    }
    fn deadline(&self) -> Option<Duration> {
        self.cancel_at.as_ref().map(|(at, _)| *at)
    }
}

/// The paced wire in virtual time, its device inside it.
#[derive(Debug)]
struct PacedHarness {
    wire: Paced<Far>,
    clock: VirtualClock,
}

impl Harness for PacedHarness {
    type Near = Paced<Far>;
    type Time = VirtualClock;

    fn parts(&mut self) -> (&mut Paced<Far>, &VirtualClock) {
        (&mut self.wire, &self.clock)
    }

    fn far_send(&mut self, bytes: &[u8]) {
        self.wire.peer.outbox.extend_from_slice(bytes);
        // Taken at the end of the step, then on the line a byte time each.
        let on_line = self.wire.byte_time() * (u32::try_from(bytes.len()).unwrap() + 1);
        self.wire.run_for(Duration::ZERO);
        self.wire.run_for(on_line);
    }

    fn far_receive(&mut self, n: usize) -> Vec<u8> {
        let end = self.clock.now() + Duration::from_secs(1);
        while self.wire.peer.received.len() < n && self.clock.now() < end {
            self.wire.run_for(Duration::from_millis(1));
        }
        std::mem::take(&mut self.wire.peer.received)
    }

    fn cancel_after(&mut self, cancel: &Cancel, after: Duration) {
        self.wire.peer.cancel_at = Some((self.clock.now() + after, cancel.clone()));
    }

    fn lateness(&self) -> Duration {
        Duration::ZERO
    }

    fn close_far(&mut self) -> bool {
        false
    }
}

/// The paced wire at 9600 baud keeps the contract in virtual time, and a cancelled read ends
/// exactly at the end of the poll period in which the token was set.
#[test]
fn the_paced_wire_keeps_the_contract_in_virtual_time() {
    let clock = VirtualClock::new();
    let mut h = PacedHarness {
        wire: Paced::new(clock.clone(), 9600, Far::default()),
        clock,
    };
    let m = contract::check(&mut h);
    assert!(m.cancel_latency <= POLL_PERIOD, "{m:?}");
}
