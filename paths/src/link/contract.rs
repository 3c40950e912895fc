//! What every [`Link`] does, as one check each implementation's tests run ([`check`]):
//!
//! 1. **Bytes both ways**: every byte value written at one end is read at the other, in order,
//!    both ways.
//! 2. **Timeouts**: a read with nothing to come returns 0 bytes once its timeout (of the link's
//!    time) has passed, not before.
//! 3. **Stale input**: [`Link::discard_input`] drops what has arrived and not been read; what
//!    comes later is read.
//! 4. **Cancel**: a [`read_within`] on a quiet link ends as cancelled within [`POLL_PERIOD`] of
//!    the link's time after its [`Cancel`] is set, and at once while it is set.
//! 5. **Closed far end**: once the far end has closed, a read is an error (not a quiet line),
//!    where the far end can close at all (a paced wire's device lives inside the wire).
//!
//! A [`Harness`] holds a link's near end (the one checked) and works its far end; [`Pair`] is
//! the harness of two links over one line (a pipe, a pseudo-terminal pair, a tap over a pipe).

use std::io;
use std::time::{Duration, Instant};

use super::{Cancel, Clock, Link, POLL_PERIOD, Pipe, Wait, WallClock, read_within};

/// A link under check and its far end.
pub trait Harness {
    /// The link checked.
    type Near: Link;
    /// The link's time.
    type Time: Clock;
    /// The link checked and its time.
    fn parts(&mut self) -> (&mut Self::Near, &Self::Time);
    /// Sends `bytes` from the far end; returns once they have arrived at the near end.
    fn far_send(&mut self, bytes: &[u8]);
    /// What the far end received, waiting up to a second of the link's time for `n` bytes.
    fn far_receive(&mut self, n: usize) -> Vec<u8>;
    /// Sets `cancel` once `after` of the link's time has passed, as another thread would.
    fn cancel_after(&mut self, cancel: &Cancel, after: Duration);
    /// How much later than [`POLL_PERIOD`] a set token may be seen: nothing in virtual time, the
    /// scheduler's allowance for a thread in wall time.
    fn lateness(&self) -> Duration;
    /// Closes the far end; false when it cannot close.
    fn close_far(&mut self) -> bool;
}

/// What [`check`] measured.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Measured {
    /// From the token being set to the read ending, in the link's time (at most one
    /// [`POLL_PERIOD`] and the harness's lateness).
    pub cancel_latency: Duration,
}

fn now<H: Harness>(h: &mut H) -> Duration {
    h.parts().1.now()
}

/// Reads from the near end until `n` bytes came or a second of its time passed.
fn read_n<H: Harness>(h: &mut H, n: usize) -> Vec<u8> {
    let (near, clock) = h.parts();
    let mut got = Vec::new();
    let mut buf = [0u8; 64];
    let deadline = clock.now() + Duration::from_secs(1);
    while got.len() < n && clock.now() < deadline {
        let k = near
            .read_timeout(&mut buf, Duration::from_millis(20))
            .expect("read");
        got.extend_from_slice(buf.get(..k).unwrap_or_default());
    }
    got
}

/// [`read_within`] on the near end, cancellable by `cancel`.
fn read_cancellable<H: Harness>(h: &mut H, cancel: &Cancel, timeout: Duration) -> Wait {
    let (near, clock) = h.parts();
    let mut buf = [0u8; 16];
    read_within(near, clock, Some(cancel), &mut buf, timeout).expect("read")
}

/// Checks the whole contract on `h` (the clauses above, in order; the far end is closed last).
/// Panics naming the clause a link breaks.
pub fn check<H: Harness>(h: &mut H) -> Measured {
    // 1. Bytes both ways, every byte value.
    let all: Vec<u8> = (0..=255u8).collect();
    h.parts().0.write_all(&all).expect("write");
    assert_eq!(
        h.far_receive(all.len()),
        all,
        "bytes written at the near end"
    );
    h.far_send(&all);
    assert_eq!(read_n(h, all.len()), all, "bytes written at the far end");

    // 2. A quiet read times out after its timeout, not before.
    let timeout = Duration::from_millis(20);
    let mut buf = [0u8; 16];
    let t0 = now(h);
    let n = h.parts().0.read_timeout(&mut buf, timeout).expect("read");
    let waited = now(h) - t0;
    assert_eq!(n, 0, "a quiet read");
    assert!(
        waited + Duration::from_millis(1) >= timeout,
        "a quiet read returned after {waited:?}, before its timeout {timeout:?}"
    );

    // 3. Stale input is dropped; later input is read.
    h.far_send(b"stale");
    h.parts().0.discard_input().expect("discard");
    let n = h.parts().0.read_timeout(&mut buf, timeout).expect("read");
    assert_eq!(n, 0, "input left after a discard");
    h.far_send(b"fresh");
    assert_eq!(read_n(h, 5), b"fresh", "input after a discard");

    // 4. Cancel: within a poll period of being set, and at once while set.
    let cancel = Cancel::new();
    let after = Duration::from_millis(5);
    let t0 = now(h);
    h.cancel_after(&cancel, after);
    let wait = read_cancellable(h, &cancel, Duration::from_secs(10));
    let took = now(h) - t0;
    assert_eq!(wait, Wait::Cancelled, "a read the token should end");
    let cancel_latency = took.saturating_sub(after);
    assert!(
        took >= after && cancel_latency <= POLL_PERIOD + h.lateness(),
        "cancelled {after:?} in, the read ended after {took:?}"
    );
    let t0 = now(h);
    assert_eq!(
        read_cancellable(h, &cancel, Duration::from_secs(10)),
        Wait::Cancelled,
        "a read while the token is set"
    );
    assert!(
        now(h) - t0 <= h.lateness(),
        "a read while the token is set waited"
    );

    // 5. A closed far end is an error.
    if h.close_far() {
        assert!(
            h.parts()
                .0
                .read_timeout(&mut buf, Duration::from_millis(50))
                .is_err(),
            "a read after the far end closed is not an error"
        );
    }
    Measured { cancel_latency }
}

/// The scheduler's allowance for a thread that sets a token in wall time (a loaded 2-core
/// machine can hold a runnable thread back for tens of milliseconds).
pub const WALL_LATENESS: Duration = Duration::from_millis(100);

/// Sets `cancel` from a thread of its own once `after` of wall time has passed.
pub fn cancel_from_thread(cancel: &Cancel, after: Duration) {
    let cancel = cancel.clone();
    std::thread::spawn(move || {
        std::thread::sleep(after);
        cancel.cancel();
    });
}

/// How many bytes wait at a near end (for links whose writes arrive a moment later, such as a
/// pseudo-terminal's).
pub type Arrived<N> = Box<dyn FnMut(&mut N) -> io::Result<usize> + Send>;

/// The harness of two links over one line in wall time: `near` is checked, `far` is its other
/// end (a [`Pipe`] pair, a pseudo-terminal pair, a tap over a pipe and the pipe's other end).
pub struct Pair<N, F> {
    near: N,
    far: Option<F>,
    clock: WallClock,
    arrived: Option<Arrived<N>>,
}

impl<N, F> std::fmt::Debug for Pair<N, F> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Pair")
    }
}

impl Pair<Pipe, Pipe> {
    /// The two ends of a new [`Pipe`].
    pub fn pipes() -> Self {
        let (near, far) = Pipe::pair();
        Pair::new(near, far)
    }
}

impl<N: Link, F: Link> Pair<N, F> {
    /// `near` checked against `far`; bytes written at one end are waiting at the other at once.
    pub fn new(near: N, far: F) -> Self {
        Pair {
            near,
            far: Some(far),
            clock: WallClock::new(),
            arrived: None,
        }
    }

    /// The same, with bytes written at the far end waiting at the near end only once `arrived`
    /// counts them there (waited for up to a second).
    pub fn with_arrival(mut self, arrived: Arrived<N>) -> Self {
        self.arrived = Some(arrived);
        self
    }

    fn far(&mut self) -> &mut F {
        self.far.as_mut().expect("the far end is open")
    }
}

impl<N: Link, F: Link> Harness for Pair<N, F> {
    type Near = N;
    type Time = WallClock;

    fn parts(&mut self) -> (&mut N, &WallClock) {
        (&mut self.near, &self.clock)
    }

    fn far_send(&mut self, bytes: &[u8]) {
        self.far().write_all(bytes).expect("far write");
        if let Some(arrived) = self.arrived.as_mut() {
            let t0 = Instant::now();
            while arrived(&mut self.near).expect("bytes waiting") < bytes.len()
                && t0.elapsed() < Duration::from_secs(1)
            {
                std::thread::sleep(Duration::from_millis(1));
            }
        }
    }

    fn far_receive(&mut self, n: usize) -> Vec<u8> {
        let mut got = Vec::new();
        let mut buf = [0u8; 64];
        let t0 = Instant::now();
        while got.len() < n && t0.elapsed() < Duration::from_secs(1) {
            let k = self
                .far()
                .read_timeout(&mut buf, Duration::from_millis(20))
                .expect("far read");
            got.extend_from_slice(buf.get(..k).unwrap_or_default());
        }
        got
    }

    fn cancel_after(&mut self, cancel: &Cancel, after: Duration) {
        cancel_from_thread(cancel, after);
    }

    fn lateness(&self) -> Duration {
        WALL_LATENESS
    }

    fn close_far(&mut self) -> bool {
        self.far = None;
        true
    }
}

/// Times `iters` cancels from another thread (for the device crates' cancel-latency benches):
/// `start` makes an exchange that blocks, and its token; the exchange runs on a thread of its
/// own and says whether it ended as cancelled; 2 ms later the token is set, and the wall time from
/// then until the thread has returned is summed.
///
/// # Panics
/// When an exchange did not end as cancelled.
pub fn time_cancels<F: FnOnce() -> bool + Send + 'static>(
    iters: u64,
    mut start: impl FnMut() -> (Cancel, F),
) -> Duration {
    let mut total = Duration::ZERO;
    for _ in 0..iters {
        let (token, exchange) = start();
        let exchange = std::thread::spawn(exchange);
        std::thread::sleep(Duration::from_millis(2));
        let t0 = Instant::now();
        token.cancel();
        let cancelled = exchange.join().unwrap_or(false);
        total += t0.elapsed();
        assert!(cancelled, "the exchange was not cancelled");
    }
    total
}
