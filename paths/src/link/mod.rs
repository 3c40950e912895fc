//! The byte link between the coordinator and a device, and the time it runs in: one plumbing for
//! the robot computer's telegram link (`asea-protocol`) and the indexer's command lines
//! (`mandrel-drive`), which must not depend on each other (docs/ARCHITECTURE.md, "One device
//! plumbing").
//!
//! - [`Link`]: write, read with a timeout, discard stale input; [`contract`] states what every
//!   implementation does and checks it.
//! - [`Pipe`]: an in-memory duplex pipe between two threads.
//! - [`Cancel`]: abandons a blocking exchange from another thread within [`POLL_PERIOD`] of the
//!   link's time ([`read_within`]).
//! - [`Clock`]: the link's time, [`WallClock`] (monotonic wall time) or [`VirtualClock`] (moves
//!   only when told: a whole program simulated in milliseconds).
//!
//! No device I/O: the serial-port links live in the device crates (`asea_protocol::link`,
//! `mandrel_drive::link`), beside the protocols that set their line.

pub mod contract;
pub mod serial;

use std::collections::VecDeque;
use std::io;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex, Weak};
use std::time::{Duration, Instant};

/// A byte link: write, read with a timeout, discard stale input ([`contract`]).
pub trait Link: Send {
    /// Writes all of `bytes` and waits until they are handed to the line.
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()>;
    /// Reads at least one byte into `buf` within `timeout` (of the link's time); `Ok(0)` on
    /// timeout, an error once the far end has closed and nothing is left to read.
    fn read_timeout(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize>;
    /// Drops any input received and not yet read.
    fn discard_input(&mut self) -> io::Result<()>;
}

impl<L: Link + ?Sized> Link for Box<L> {
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        (**self).write_all(bytes)
    }
    fn read_timeout(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        (**self).read_timeout(buf, timeout)
    }
    fn discard_input(&mut self) -> io::Result<()> {
        (**self).discard_input()
    }
}

/// A port read's result as a link read: a timeout, a would-block or a signal arriving during the
/// wait is a short read of 0 bytes, not a failure (for the serial-port links of the device
/// crates).
pub fn quiet_as_zero(read: io::Result<usize>) -> io::Result<usize> {
    match read {
        Err(e)
            if matches!(
                e.kind(),
                io::ErrorKind::TimedOut | io::ErrorKind::WouldBlock | io::ErrorKind::Interrupted
            ) =>
        {
            Ok(0)
        }
        r => r,
    }
}

#[derive(Debug, Default)]
struct Queue {
    bytes: Mutex<VecDeque<u8>>,
    ready: Condvar,
}

/// One end of an in-memory duplex byte pipe (wall time, between threads). Clones share the end;
/// once every clone of the far end is dropped, reading what is left and then an error
/// ([`io::ErrorKind::BrokenPipe`]), and writing is an error: a closed far end, as on a serial
/// line whose other side has gone.
#[derive(Debug)]
pub struct Pipe {
    rx: Arc<Queue>,
    tx: Arc<Queue>,
    /// This end's life: the far end sees it closed when no clone holds it.
    alive: Option<Arc<()>>,
    far: Weak<()>,
}

impl Pipe {
    /// Two connected ends.
    pub fn pair() -> (Pipe, Pipe) {
        let (a, b) = (Arc::new(Queue::default()), Arc::new(Queue::default()));
        let (a_alive, b_alive) = (Arc::new(()), Arc::new(()));
        (
            Pipe {
                rx: a.clone(),
                tx: b.clone(),
                far: Arc::downgrade(&b_alive),
                alive: Some(a_alive.clone()),
            },
            Pipe {
                rx: b,
                tx: a,
                far: Arc::downgrade(&a_alive),
                alive: Some(b_alive),
            },
        )
    }

    fn far_closed(&self) -> bool {
        self.far.strong_count() == 0
    }
}

impl Clone for Pipe {
    fn clone(&self) -> Self {
        Pipe {
            rx: self.rx.clone(),
            tx: self.tx.clone(),
            alive: self.alive.clone(),
            far: self.far.clone(),
        }
    }
}

impl Drop for Pipe {
    fn drop(&mut self) {
        // Let go of this end first, then wake a reader of the far end to see it closed (taking
        // its lock first: a reader between its look and its wait is not missed).
        self.alive = None;
        drop(self.tx.bytes.lock());
        self.tx.ready.notify_all();
    }
}

fn poisoned() -> io::Error {
    io::Error::other("pipe lock poisoned")
}

fn closed() -> io::Error {
    io::Error::new(
        io::ErrorKind::BrokenPipe,
        "the far end of the pipe is closed",
    )
}

impl Link for Pipe {
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        if self.far_closed() {
            return Err(closed());
        }
        self.tx
            .bytes
            .lock()
            .map_err(|_| poisoned())?
            .extend(bytes.iter().copied());
        self.tx.ready.notify_all();
        Ok(())
    }

    fn read_timeout(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        let deadline = Instant::now() + timeout;
        let mut q = self.rx.bytes.lock().map_err(|_| poisoned())?;
        while q.is_empty() {
            if self.far_closed() {
                return Err(closed());
            }
            let now = Instant::now();
            if now >= deadline {
                return Ok(0);
            }
            q = self
                .rx
                .ready
                .wait_timeout(q, deadline - now)
                .map_err(|_| poisoned())?
                .0;
        }
        let n = buf.len().min(q.len());
        for (slot, byte) in buf.iter_mut().zip(q.drain(..n)) {
            *slot = byte;
        }
        Ok(n)
    }

    fn discard_input(&mut self) -> io::Result<()> {
        self.rx.bytes.lock().map_err(|_| poisoned())?.clear();
        Ok(())
    }
}

/// Longest wait of one read of a cancellable exchange ([`read_within`]): a cancelled exchange is
/// abandoned within this of the link's time. The stop path counts on it (docs/ARCHITECTURE.md,
/// the coordinator's stop; docs/benchmarks.md, "Stop latency"): small beside the robot link's
/// urgent gap.
pub const POLL_PERIOD: Duration = Duration::from_millis(1);

/// A token that cancels a client's blocking exchanges from another thread or task; clones share
/// it. The exchange under way ends at its next look, within [`POLL_PERIOD`] ([`read_within`]);
/// a client's stop goes through while it is set.
#[derive(Debug, Clone, Default)]
pub struct Cancel(Arc<AtomicBool>);

impl Cancel {
    /// A token not set.
    pub fn new() -> Self {
        Self::default()
    }
    /// Cancels the exchange under way and every later one until [`Cancel::reset`].
    pub fn cancel(&self) {
        self.0.store(true, Ordering::SeqCst);
    }
    /// Lets exchanges run again.
    pub fn reset(&self) {
        self.0.store(false, Ordering::SeqCst);
    }
    /// True while set.
    pub fn is_cancelled(&self) -> bool {
        self.0.load(Ordering::SeqCst)
    }
}

/// How a [`read_within`] ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Wait {
    /// This many bytes (at least one) were read.
    Bytes(usize),
    /// The timeout passed with nothing read.
    TimedOut,
    /// The token was set.
    Cancelled,
}

/// Reads at least one byte from `link` within `timeout` of `clock` (the link's own time: a
/// virtual clock only with a link that moves it, such as a paced wire), in reads of at most
/// [`POLL_PERIOD`], and gives up as soon as `cancel` is set, looked at before every read.
pub fn read_within<L: Link + ?Sized, C: Clock + ?Sized>(
    link: &mut L,
    clock: &C,
    cancel: Option<&Cancel>,
    buf: &mut [u8],
    timeout: Duration,
) -> io::Result<Wait> {
    let deadline = clock.now() + timeout;
    loop {
        if cancel.is_some_and(Cancel::is_cancelled) {
            return Ok(Wait::Cancelled);
        }
        let now = clock.now();
        if now >= deadline {
            return Ok(Wait::TimedOut);
        }
        let n = link.read_timeout(buf, (deadline - now).min(POLL_PERIOD))?;
        if n > 0 {
            return Ok(Wait::Bytes(n));
        }
    }
}

/// How [`drain_until_quiet`] ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Drained {
    /// Bytes read and dropped.
    pub dropped: usize,
    /// True when the line stayed quiet for the asked span; false when bytes kept coming until
    /// the limit.
    pub quiet: bool,
}

/// Waits until `link` has been quiet for `quiet` (of `clock`), reading and dropping whatever
/// comes meanwhile, for at most `limit`: a client that attaches to a device a killed run left
/// talking (stale echoes, replies to commands the device still had buffered) starts on a line
/// that says nothing, so that the first answer it reads is the answer to its own query. A quiet
/// span is measured from the last byte read.
pub fn drain_until_quiet<L: Link + ?Sized, C: Clock + ?Sized>(
    link: &mut L,
    clock: &C,
    quiet: Duration,
    limit: Duration,
) -> io::Result<Drained> {
    let deadline = clock.now() + limit;
    let mut last = clock.now();
    let mut dropped = 0;
    let mut buf = [0u8; 256];
    loop {
        let now = clock.now();
        if now.saturating_sub(last) >= quiet {
            return Ok(Drained {
                dropped,
                quiet: true,
            });
        }
        if now >= deadline {
            return Ok(Drained {
                dropped,
                quiet: false,
            });
        }
        let left = (last + quiet).min(deadline).saturating_sub(now);
        let n = link.read_timeout(&mut buf, left.clamp(Duration::from_nanos(1), POLL_PERIOD))?;
        if n > 0 {
            dropped += n;
            last = clock.now();
        }
    }
}

/// A monotonic clock: time since its epoch.
pub trait Clock: Send + Sync + std::fmt::Debug {
    /// Time since the epoch.
    fn now(&self) -> Duration;
    /// Seconds since the epoch.
    fn now_s(&self) -> f64 {
        self.now().as_secs_f64()
    }
}

impl<C: Clock + ?Sized> Clock for Arc<C> {
    fn now(&self) -> Duration {
        (**self).now()
    }
}

impl<C: Clock + ?Sized> Clock for &C {
    fn now(&self) -> Duration {
        (**self).now()
    }
}

/// Wall-clock time since creation.
#[derive(Debug, Clone, Copy)]
pub struct WallClock {
    epoch: Instant,
}

impl WallClock {
    /// A clock at zero now.
    pub fn new() -> Self {
        WallClock {
            epoch: Instant::now(),
        }
    }
}

impl Default for WallClock {
    fn default() -> Self {
        Self::new()
    }
}

impl Clock for WallClock {
    fn now(&self) -> Duration {
        self.epoch.elapsed()
    }
}

/// A simulated clock shared by its clones, counted in nanoseconds; it moves only when told and
/// never goes backwards.
///
/// A paced clock ([`VirtualClock::paced`]) also keeps in step with the wall clock: a step forward
/// waits until the wall time since its first step, times the speed factor, has reached the new
/// time, so that a simulation runs at `speed` times the speed of the machine it models (a viewer
/// can watch it). A step that comes later than its wall time (the process was busy) does not
/// wait, and once more than [`PACE_MAX_LAG`] late the pace starts again from that step, so the
/// simulation never races to catch up.
#[derive(Debug, Clone, Default)]
pub struct VirtualClock {
    nanos: Arc<AtomicU64>,
    pace: Option<Arc<Pace>>,
}

/// How far a paced [`VirtualClock`] may fall behind the wall clock before it stops trying to
/// catch up and paces from where it stands.
pub const PACE_MAX_LAG: Duration = Duration::from_millis(100);

/// The wall-clock pacing of a [`VirtualClock`].
#[derive(Debug)]
struct Pace {
    /// Virtual seconds per wall second.
    speed: f64,
    /// The wall instant and the virtual time paced from (set by the first step).
    origin: Mutex<Option<(Instant, Duration)>>,
}

impl VirtualClock {
    /// A clock at zero.
    pub fn new() -> Self {
        Self::default()
    }
    /// A clock at zero that runs at `speed` virtual seconds per wall second (1: real time);
    /// `None` unless `speed` is finite and positive.
    pub fn paced(speed: f64) -> Option<Self> {
        (speed.is_finite() && speed > 0.0).then(|| VirtualClock {
            nanos: Arc::default(),
            pace: Some(Arc::new(Pace {
                speed,
                origin: Mutex::new(None),
            })),
        })
    }
    /// The speed factor of a paced clock; `None` for one that runs as fast as it is told.
    pub fn speed(&self) -> Option<f64> {
        self.pace.as_ref().map(|p| p.speed)
    }
    /// On a paced clock, waits until the wall clock has caught up with virtual time `t`.
    fn pace_to(&self, t: Duration) {
        let Some(pace) = &self.pace else { return };
        let now_v = Duration::from_nanos(self.nanos.load(Ordering::Relaxed));
        if t <= now_v {
            return;
        }
        let mut origin = pace.origin.lock().unwrap_or_else(|p| p.into_inner());
        let (wall0, virt0) = *origin.get_or_insert((Instant::now(), now_v));
        let due = wall0 + t.saturating_sub(virt0).div_f64(pace.speed);
        let now = Instant::now();
        if due > now {
            drop(origin);
            std::thread::sleep(due - now);
        } else if now - due > PACE_MAX_LAG {
            *origin = Some((now, t));
        }
    }
    /// Moves the clock forward by `dt`.
    pub fn advance(&self, dt: Duration) {
        let dt = u64::try_from(dt.as_nanos()).unwrap_or(u64::MAX);
        if self.pace.is_some() {
            let now = self.nanos.load(Ordering::Relaxed);
            self.pace_to(Duration::from_nanos(now.saturating_add(dt)));
        }
        self.nanos.fetch_add(dt, Ordering::Relaxed);
    }
    /// Moves the clock forward by `dt_s` seconds (a negative or not finite value is ignored).
    pub fn advance_s(&self, dt_s: f64) {
        if let Ok(dt) = Duration::try_from_secs_f64(dt_s) {
            self.advance(dt);
        }
    }
    /// Moves the clock to `t` if that is later than now.
    pub fn advance_to(&self, t: Duration) {
        self.pace_to(t);
        let t = u64::try_from(t.as_nanos()).unwrap_or(u64::MAX);
        self.nanos.fetch_max(t, Ordering::Relaxed);
    }
}

impl Clock for VirtualClock {
    fn now(&self) -> Duration {
        Duration::from_nanos(self.nanos.load(Ordering::Relaxed))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The pipe keeps the whole contract, its far end closed by dropping it.
    #[test]
    fn the_pipe_keeps_the_link_contract() {
        contract::check(&mut contract::Pair::pipes());
    }

    /// Bytes both ways, a quiet read, stale input dropped: the robot's bytes and an indexer line.
    #[test]
    fn pipe_carries_bytes_both_ways() {
        let (mut a, mut b) = Pipe::pair();
        a.write_all(&[5, 6]).unwrap();
        let mut buf = [0u8; 8];
        assert_eq!(
            b.read_timeout(&mut buf, Duration::from_millis(10)).unwrap(),
            2
        );
        assert_eq!(
            a.read_timeout(&mut buf, Duration::from_millis(1)).unwrap(),
            0
        );
        b.write_all(b"junk").unwrap();
        a.discard_input().unwrap();
        assert_eq!(
            a.read_timeout(&mut buf, Duration::from_millis(1)).unwrap(),
            0
        );
        a.write_all(b"1R\r").unwrap();
        assert_eq!(
            b.read_timeout(&mut buf, Duration::from_millis(10)).unwrap(),
            3
        );
        assert_eq!(&buf[..3], b"1R\r");
    }

    /// A read on an empty pipe waits for bytes written meanwhile from another thread, up to its
    /// timeout.
    #[test]
    fn a_pipe_read_waits_for_bytes_to_come() {
        let (mut a, mut b) = Pipe::pair();
        let writer = std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(20));
            a.write_all(&[7]).unwrap();
            a
        });
        let mut buf = [0u8; 4];
        assert_eq!(b.read_timeout(&mut buf, Duration::from_secs(5)).unwrap(), 1);
        assert_eq!(buf[0], 7);
        drop(writer.join().unwrap());
    }

    /// What is left when the far end closes is still read, then the read is an error; a clone
    /// of the far end keeps it open.
    #[test]
    fn a_pipe_reads_what_was_left_before_its_far_end_closed() {
        let (mut a, mut b) = Pipe::pair();
        a.write_all(&[8]).unwrap();
        let mut buf = [0u8; 1];
        // A clone of the far end keeps it open.
        let a2 = a.clone();
        drop(a);
        assert_eq!(
            b.read_timeout(&mut buf, Duration::from_millis(1)).unwrap(),
            1
        );
        assert_eq!(buf[0], 8);
        assert_eq!(
            b.read_timeout(&mut buf, Duration::from_millis(1)).unwrap(),
            0
        );
        drop(a2);
        let e = b
            .read_timeout(&mut buf, Duration::from_millis(1))
            .unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::BrokenPipe);
        assert_eq!(
            b.write_all(b"x").unwrap_err().kind(),
            io::ErrorKind::BrokenPipe
        );
    }

    /// A reader waiting on an empty pipe learns at once that the far end closed, not at its
    /// timeout.
    #[test]
    fn a_waiting_reader_is_woken_by_the_far_end_closing() {
        let (a, mut b) = Pipe::pair();
        let closer = std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(20));
            drop(a);
        });
        let t0 = Instant::now();
        let mut buf = [0u8; 4];
        assert!(b.read_timeout(&mut buf, Duration::from_secs(30)).is_err());
        assert!(t0.elapsed() < Duration::from_secs(10), "{:?}", t0.elapsed());
        closer.join().unwrap();
    }

    /// A timeout, would-block or signal is a read of nothing; any other error stays one.
    #[test]
    fn quiet_port_reads_are_zero_bytes() {
        for kind in [
            io::ErrorKind::TimedOut,
            io::ErrorKind::WouldBlock,
            io::ErrorKind::Interrupted,
        ] {
            assert_eq!(quiet_as_zero(Err(io::Error::from(kind))).unwrap(), 0);
        }
        assert_eq!(quiet_as_zero(Ok(3)).unwrap(), 3);
        assert!(quiet_as_zero(Err(io::Error::from(io::ErrorKind::BrokenPipe))).is_err());
    }

    /// The virtual clock moves by what it is told, never backwards, in whole nanoseconds; a
    /// negative step in seconds is ignored; clones share it; the wall clock moves by itself.
    #[test]
    fn clocks_move_as_told() {
        let c = VirtualClock::new();
        let shared = c.clone();
        c.advance(Duration::from_millis(3));
        c.advance_s(0.000_5);
        c.advance_s(-1.0);
        c.advance_s(f64::NAN);
        assert_eq!(shared.now(), Duration::from_micros(3_500));
        c.advance_to(Duration::from_millis(1));
        assert_eq!(c.now(), Duration::from_micros(3_500));
        c.advance_to(Duration::from_millis(10));
        assert_eq!(c.now_s(), 0.01);
        let arc: Arc<dyn Clock> = Arc::new(c.clone());
        assert_eq!(arc.now(), Duration::from_millis(10));
        let w = WallClock::default();
        let t0 = w.now();
        std::thread::sleep(Duration::from_millis(2));
        assert!(w.now() >= t0 + Duration::from_millis(2));
    }

    /// A paced clock's steps take their virtual time divided by the speed in wall time (here
    /// 0.4 s of virtual time in 20 steps at speed 4: 0.1 s), a plain one's none; a speed that is
    /// not finite and positive makes no clock.
    #[test]
    fn a_paced_clock_keeps_in_step_with_the_wall_clock() {
        let c = VirtualClock::paced(4.0).unwrap();
        assert_eq!(c.speed(), Some(4.0));
        let t0 = Instant::now();
        for k in 1..=20u64 {
            if k % 2 == 0 {
                c.advance(Duration::from_millis(20));
            } else {
                c.advance_to(Duration::from_millis(20 * k));
            }
        }
        let wall = t0.elapsed();
        assert_eq!(c.now(), Duration::from_millis(400));
        assert!(wall >= Duration::from_millis(95), "{wall:?}");
        assert!(wall < Duration::from_millis(400), "{wall:?}");
        // A step back or to the same time does not wait.
        let t1 = Instant::now();
        c.advance_to(Duration::from_millis(100));
        assert!(t1.elapsed() < Duration::from_millis(20));
        let fast = VirtualClock::new();
        let t2 = Instant::now();
        fast.advance(Duration::from_secs(3600));
        assert!(t2.elapsed() < Duration::from_millis(50));
        assert_eq!(fast.speed(), None);
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert!(VirtualClock::paced(bad).is_none(), "{bad}");
        }
    }

    /// A line that talks for a while is drained until it has been quiet for the span asked,
    /// measured from its last byte; a line that never stops talking ends at the limit, not quiet.
    #[test]
    fn a_line_is_drained_until_it_goes_quiet() {
        let (mut a, mut b) = Pipe::pair();
        let talker = std::thread::spawn(move || {
            for _ in 0..5 {
                a.write_all(b"1G\r").unwrap();
                std::thread::sleep(Duration::from_millis(20));
            }
            a
        });
        let clock = WallClock::new();
        let t0 = Instant::now();
        let d = drain_until_quiet(
            &mut b,
            &clock,
            Duration::from_millis(80),
            Duration::from_secs(5),
        )
        .unwrap();
        let a = talker.join().unwrap();
        assert!(d.quiet);
        assert_eq!(d.dropped, 15);
        // Five lines 20 ms apart, then 80 ms of quiet.
        assert!(
            t0.elapsed() >= Duration::from_millis(80 + 4 * 20),
            "{:?}",
            t0.elapsed()
        );
        let mut buf = [0u8; 4];
        assert_eq!(
            b.read_timeout(&mut buf, Duration::from_millis(1)).unwrap(),
            0
        );
        // A line that keeps talking: the limit ends the wait.
        let stop = Arc::new(AtomicBool::new(false));
        let s2 = stop.clone();
        let mut a2 = a.clone();
        let chatter = std::thread::spawn(move || {
            while !s2.load(Ordering::SeqCst) {
                let _ = a2.write_all(b"x");
                std::thread::sleep(Duration::from_millis(5));
            }
        });
        let d = drain_until_quiet(
            &mut b,
            &clock,
            Duration::from_millis(50),
            Duration::from_millis(200),
        )
        .unwrap();
        stop.store(true, Ordering::SeqCst);
        chatter.join().unwrap();
        assert!(!d.quiet && d.dropped > 0, "{d:?}");
        drop(a);
    }

    /// A cancel token shared by clones: set, seen, reset.
    #[test]
    fn a_cancel_token_is_shared_by_its_clones() {
        let c = Cancel::new();
        let other = c.clone();
        assert!(!other.is_cancelled());
        c.cancel();
        assert!(other.is_cancelled());
        other.reset();
        assert!(!c.is_cancelled());
    }
}
