//! The robot's byte link: the serial port at the robot computer's line settings, a fault
//! injector, a tap, and a paced virtual-time wire that connects a client to a simulated robot
//! without threads. The [`Link`] contract, the in-memory [`Pipe`] and the clocks are the ones
//! both device crates share ([`paths::link`]).

use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::io;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

pub use paths::link::{Link, Pipe};

use crate::clock::{Clock, VirtualClock};

/// Character format on the serial line (docs/protocol.md §1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum CharFormat {
    /// 8 data bits, no parity, 1 stop bit (the default).
    #[default]
    EightN1,
    /// 7 data bits, even parity, 1 stop bit, in case the real controller needs it. Telegram
    /// bytes at or above 0x80 cannot pass such a line.
    SevenE1,
}

/// The serial character format used unless configured otherwise.
pub const DEFAULT_CHAR_FORMAT: CharFormat = CharFormat::EightN1;
/// The baud rate used unless configured otherwise (spec §5.1).
pub const DEFAULT_BAUD: u32 = 9600;

/// Bits on the line per character (start + data + parity + stop).
pub fn bits_per_char(format: CharFormat) -> u32 {
    match format {
        CharFormat::EightN1 => 10,
        CharFormat::SevenE1 => 10,
    }
}

/// Opens a real serial port at `baud` with `format`, as a [`Link`].
pub fn open_serial(
    path: &str,
    baud: u32,
    format: CharFormat,
) -> Result<SerialLink<Box<dyn serialport::SerialPort>>, serialport::Error> {
    use std::os::fd::AsRawFd;
    let (bits, parity) = match format {
        CharFormat::EightN1 => (serialport::DataBits::Eight, serialport::Parity::None),
        CharFormat::SevenE1 => (serialport::DataBits::Seven, serialport::Parity::Even),
    };
    // Not the library's exclusive mode: its TIOCEXCL is a flag on the device that outlives a
    // process killed with SIGKILL (every later open but root's fails, EBUSY). The library takes
    // a shared advisory lock (flock) on the descriptor instead, which is turned into an
    // exclusive one here: the kernel drops it when the process dies, however it dies.
    let port = serialport::new(path, baud)
        .data_bits(bits)
        .parity(parity)
        .stop_bits(serialport::StopBits::One)
        .flow_control(serialport::FlowControl::None)
        .timeout(Duration::from_millis(100))
        .exclusive(false)
        .open_native()
        .map_err(held_elsewhere)?;
    nix::fcntl::flock(
        port.as_raw_fd(),
        nix::fcntl::FlockArg::LockExclusiveNonblock,
    )
    .map_err(|e| {
        if e == nix::errno::Errno::EWOULDBLOCK {
            port_held()
        } else {
            serialport::Error::from(std::io::Error::from(e))
        }
    })?;
    Ok(SerialLink(Box::new(port)))
}

/// The error of a port another process holds (its advisory lock).
fn port_held() -> serialport::Error {
    serialport::Error::new(serialport::ErrorKind::NoDevice, PORT_HELD)
}

/// What [`open_serial`] says of a port another process holds.
pub const PORT_HELD: &str =
    "in use: another program (another windcell?) holds the port's lock; stop it first";

/// The library's refusal of its shared lock (another process holds an exclusive one) in the
/// words of [`PORT_HELD`].
fn held_elsewhere(e: serialport::Error) -> serialport::Error {
    if e.kind() == serialport::ErrorKind::NoDevice && e.description.contains("lock") {
        port_held()
    } else {
        e
    }
}

paths::serial_link!();

/// A small seeded generator (SplitMix64): reproducible faults without a dependency.
#[derive(Debug, Clone)]
pub struct Rng(u64);

impl Rng {
    /// A generator from `seed`.
    pub fn new(seed: u64) -> Self {
        Rng(seed)
    }
    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Byte fault rates (each a probability per byte) and a seed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FaultRates {
    /// The byte is lost.
    pub drop: f64,
    /// The byte arrives with one to eight bits flipped.
    pub corrupt: f64,
    /// The line stalls before the byte for up to `max_delay`.
    pub delay: f64,
    /// The byte arrives twice.
    pub duplicate: f64,
    /// Longest stall.
    pub max_delay: Duration,
}

impl FaultRates {
    /// `rate` split evenly over drop, corrupt, delay and duplicate; stalls up to 300 ms (beyond
    /// `T_CHAR`).
    pub fn uniform(rate: f64) -> Self {
        FaultRates {
            drop: rate / 4.0,
            corrupt: rate / 4.0,
            delay: rate / 4.0,
            duplicate: rate / 4.0,
            max_delay: Duration::from_millis(300),
        }
    }
}

/// Counts of injected faults.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FaultCounts {
    /// Bytes seen.
    pub bytes: u64,
    /// Dropped.
    pub dropped: u64,
    /// Corrupted.
    pub corrupted: u64,
    /// Delayed.
    pub delayed: u64,
    /// Duplicated.
    pub duplicated: u64,
    /// NAK corrupted into ACK (the single-byte answers differ in three bits).
    pub nak_to_ack: u64,
}

/// A seeded fault injector.
#[derive(Debug, Clone)]
pub struct Faults {
    rates: FaultRates,
    rng: Rng,
    counts: FaultCounts,
}

/// What happens to one byte.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Fate {
    /// Stall before it.
    pub delay: Duration,
    /// Copies that arrive (0, 1 or 2) and the value they carry.
    pub copies: u8,
    /// The value.
    pub byte: u8,
}

impl Faults {
    /// An injector with `rates`, seeded.
    pub fn new(rates: FaultRates, seed: u64) -> Self {
        Faults {
            rates,
            rng: Rng::new(seed),
            counts: FaultCounts::default(),
        }
    }
    /// Counts so far.
    pub fn counts(&self) -> FaultCounts {
        self.counts
    }
    /// Decides the fate of `byte`.
    pub fn apply(&mut self, byte: u8) -> Fate {
        self.counts.bytes += 1;
        let r = self.rates;
        let u = self.rng.unit();
        let mut fate = Fate {
            delay: Duration::ZERO,
            copies: 1,
            byte,
        };
        if u < r.drop {
            self.counts.dropped += 1;
            fate.copies = 0;
        } else if u < r.drop + r.corrupt {
            self.counts.corrupted += 1;
            let mask = (self.rng.next_u64() % 255 + 1) as u8;
            fate.byte = byte ^ mask;
            if byte == crate::frame::NAK && fate.byte == crate::frame::ACK {
                self.counts.nak_to_ack += 1;
            }
        } else if u < r.drop + r.corrupt + r.delay {
            self.counts.delayed += 1;
            fate.delay = r.max_delay.mul_f64(self.rng.unit());
        } else if u < r.drop + r.corrupt + r.delay + r.duplicate {
            self.counts.duplicated += 1;
            fate.copies = 2;
        }
        fate
    }
}

/// A real-time link wrapper that drops, corrupts and duplicates the bytes it writes (stalls are
/// slept). For threads and pseudo-terminals; the paced wire models faults in virtual time.
#[derive(Debug)]
pub struct Faulty<L> {
    inner: L,
    faults: Faults,
}

impl<L: Link> Faulty<L> {
    /// Wraps `inner`.
    pub fn new(inner: L, faults: Faults) -> Self {
        Faulty { inner, faults }
    }
    /// Counts so far.
    pub fn counts(&self) -> FaultCounts {
        self.faults.counts()
    }
}

impl<L: Link> Link for Faulty<L> {
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        for &b in bytes {
            let fate = self.faults.apply(b);
            if !fate.delay.is_zero() {
                std::thread::sleep(fate.delay);
            }
            for _ in 0..fate.copies {
                self.inner.write_all(&[fate.byte])?;
            }
        }
        Ok(())
    }
    fn read_timeout(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        self.inner.read_timeout(buf, timeout)
    }
    fn discard_input(&mut self) -> io::Result<()> {
        self.inner.discard_input()
    }
}

/// Direction of a recorded chunk.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Direction {
    /// Written by this side.
    Tx,
    /// Read by this side.
    Rx,
}

/// One recorded chunk of traffic.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TapRecord {
    /// Wall time since the tap was made.
    pub at: Duration,
    /// Direction.
    pub dir: Direction,
    /// The bytes.
    pub bytes: Vec<u8>,
}

/// A link wrapper that records all traffic (for `/link/trace` and debugging).
#[derive(Debug)]
pub struct Tap<L> {
    inner: L,
    epoch: Instant,
    log: Arc<Mutex<Vec<TapRecord>>>,
}

impl<L: Link> Tap<L> {
    /// The wrapped link.
    pub fn inner(&mut self) -> &mut L {
        &mut self.inner
    }

    /// Wraps `inner`; the returned log fills as traffic passes.
    pub fn new(inner: L) -> (Self, Arc<Mutex<Vec<TapRecord>>>) {
        let log = Arc::new(Mutex::new(Vec::new()));
        (
            Tap {
                inner,
                epoch: Instant::now(),
                log: log.clone(),
            },
            log,
        )
    }
    fn record(&self, dir: Direction, bytes: &[u8]) {
        if let Ok(mut log) = self.log.lock() {
            log.push(TapRecord {
                at: self.epoch.elapsed(),
                dir,
                bytes: bytes.to_vec(),
            });
        }
    }
}

impl<L: Link> Link for Tap<L> {
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.record(Direction::Tx, bytes);
        self.inner.write_all(bytes)
    }
    fn read_timeout(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        let n = self.inner.read_timeout(buf, timeout)?;
        if n > 0 {
            self.record(Direction::Rx, buf.get(..n).unwrap_or_default());
        }
        Ok(n)
    }
    fn discard_input(&mut self) -> io::Result<()> {
        self.inner.discard_input()
    }
}

/// The far end of a [`Paced`] wire: a device driven by bytes and time (the robot simulator).
pub trait Peer {
    /// Bytes arriving at `now`.
    fn receive(&mut self, bytes: &[u8], now: Duration);
    /// Time passes to `now`.
    fn poll(&mut self, now: Duration);
    /// Bytes the device sends.
    fn take_output(&mut self) -> Vec<u8>;
    /// When the device next needs [`Peer::poll`].
    fn deadline(&self) -> Option<Duration>;
}

impl<P: Peer + ?Sized> Peer for &mut P {
    fn receive(&mut self, bytes: &[u8], now: Duration) {
        (**self).receive(bytes, now)
    }
    fn poll(&mut self, now: Duration) {
        (**self).poll(now)
    }
    fn take_output(&mut self) -> Vec<u8> {
        (**self).take_output()
    }
    fn deadline(&self) -> Option<Duration> {
        (**self).deadline()
    }
}

type Arrivals = BinaryHeap<Reverse<(Duration, u64, u8)>>;

/// A serial line in virtual time between this end (the host) and a [`Peer`], paced at a baud
/// rate, with optional faults on both directions. Writing blocks (in virtual time) until the last
/// byte has left, like `tcdrain`; reading advances the clock to the next arriving byte or the
/// timeout. Single-threaded and deterministic.
#[derive(Debug)]
pub struct Paced<P> {
    clock: VirtualClock,
    byte_time: Duration,
    /// The device.
    pub peer: P,
    to_peer: Arrivals,
    to_host: Arrivals,
    host_free: Duration,
    peer_free: Duration,
    seq: u64,
    faults_to_peer: Option<Faults>,
    faults_to_host: Option<Faults>,
    busy_line: Duration,
}

impl<P: Peer> Paced<P> {
    /// A wire at `baud` (the default character format's 10 bits per byte) on `clock` to `peer`.
    pub fn new(clock: VirtualClock, baud: u32, peer: P) -> Self {
        let bits = f64::from(bits_per_char(DEFAULT_CHAR_FORMAT));
        let byte_time = Duration::from_secs_f64(bits / f64::from(baud.max(1)));
        Paced {
            clock,
            byte_time,
            peer,
            to_peer: BinaryHeap::new(),
            to_host: BinaryHeap::new(),
            host_free: Duration::ZERO,
            peer_free: Duration::ZERO,
            seq: 0,
            faults_to_peer: None,
            faults_to_host: None,
            busy_line: Duration::ZERO,
        }
    }

    /// Injects faults: `to_peer` on host→device bytes, `to_host` on device→host bytes.
    pub fn with_faults(mut self, to_peer: Faults, to_host: Faults) -> Self {
        self.faults_to_peer = Some(to_peer);
        self.faults_to_host = Some(to_host);
        self
    }

    /// Time one byte takes on the line.
    pub fn byte_time(&self) -> Duration {
        self.byte_time
    }

    /// Total time the host→device line carried bytes.
    pub fn host_line_busy(&self) -> Duration {
        self.busy_line
    }

    /// Injected fault counts (host→device, device→host).
    pub fn fault_counts(&self) -> (FaultCounts, FaultCounts) {
        (
            self.faults_to_peer
                .as_ref()
                .map(Faults::counts)
                .unwrap_or_default(),
            self.faults_to_host
                .as_ref()
                .map(Faults::counts)
                .unwrap_or_default(),
        )
    }

    /// The shared clock.
    pub fn clock(&self) -> &VirtualClock {
        &self.clock
    }

    /// Lets `dt` of virtual time pass with the host silent: the device runs (and may send).
    pub fn run_for(&mut self, dt: Duration) {
        let end = self.clock.now() + dt;
        self.run_peer_until(end);
        self.clock.advance_to(end);
        self.peer.poll(end);
        self.peer_output(end);
    }

    fn schedule(
        heap: &mut Arrivals,
        faults: &mut Option<Faults>,
        free: &mut Duration,
        seq: &mut u64,
        byte_time: Duration,
        now: Duration,
        bytes: &[u8],
    ) {
        let mut t = (*free).max(now);
        for &b in bytes {
            let fate = match faults {
                Some(f) => f.apply(b),
                None => Fate {
                    delay: Duration::ZERO,
                    copies: 1,
                    byte: b,
                },
            };
            t += fate.delay;
            for _ in 0..fate.copies {
                t += byte_time;
                *seq += 1;
                heap.push(Reverse((t, *seq, fate.byte)));
            }
            if fate.copies == 0 {
                // The byte used the line but never arrived.
                t += byte_time;
            }
        }
        *free = t;
    }

    fn peer_output(&mut self, now: Duration) {
        let out = self.peer.take_output();
        if !out.is_empty() {
            Self::schedule(
                &mut self.to_host,
                &mut self.faults_to_host,
                &mut self.peer_free,
                &mut self.seq,
                self.byte_time,
                now,
                &out,
            );
        }
    }

    /// The next device-side event time.
    fn next_peer_event(&self) -> Option<Duration> {
        let arrival = self.to_peer.peek().map(|Reverse((t, _, _))| *t);
        match (arrival, self.peer.deadline()) {
            (Some(a), Some(d)) => Some(a.min(d)),
            (a, d) => a.or(d),
        }
    }

    /// Runs the device side up to and including `t_end`.
    fn run_peer_until(&mut self, t_end: Duration) {
        let mut guard = 0u32;
        while let Some(t) = self.next_peer_event() {
            if t > t_end {
                break;
            }
            let t = t.max(self.clock.now());
            self.clock.advance_to(t);
            if let Some(Reverse((ta, _, b))) = self.to_peer.peek().copied()
                && ta <= t
            {
                self.to_peer.pop();
                self.peer.receive(&[b], t);
            } else {
                self.peer.poll(t);
                guard += 1;
                if guard > 1_000_000 {
                    break;
                }
            }
            self.peer_output(t);
        }
    }
}

impl<P: Peer + Send> Link for Paced<P> {
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        let now = self.clock.now();
        let start = self.host_free.max(now);
        Self::schedule(
            &mut self.to_peer,
            &mut self.faults_to_peer,
            &mut self.host_free,
            &mut self.seq,
            self.byte_time,
            now,
            bytes,
        );
        self.busy_line += self.host_free.saturating_sub(start);
        let done = self.host_free;
        self.run_peer_until(done);
        self.clock.advance_to(done);
        Ok(())
    }

    fn read_timeout(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        let deadline = self.clock.now() + timeout;
        loop {
            let host_next = self.to_host.peek().map(|Reverse((t, _, _))| *t);
            match host_next {
                Some(t) if t <= deadline => {
                    self.run_peer_until(t);
                    // The device may have produced earlier output meanwhile.
                    let Some(Reverse((t, _, _))) = self.to_host.peek().copied() else {
                        continue;
                    };
                    self.clock.advance_to(t);
                    let mut n = 0;
                    while let (Some(slot), Some(Reverse((ta, _, b)))) =
                        (buf.get_mut(n), self.to_host.peek().copied())
                    {
                        if ta > t {
                            break;
                        }
                        *slot = b;
                        self.to_host.pop();
                        n += 1;
                    }
                    return Ok(n);
                }
                _ => {
                    let before = self.to_host.len();
                    self.run_peer_until(deadline);
                    if self.to_host.len() == before {
                        self.clock.advance_to(deadline);
                        return Ok(0);
                    }
                }
            }
        }
    }

    fn discard_input(&mut self) -> io::Result<()> {
        let now = self.clock.now();
        while let Some(Reverse((t, _, _))) = self.to_host.peek() {
            if *t > now {
                break;
            }
            self.to_host.pop();
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Start bit, data bits, parity bit and stop bit.
    #[test]
    fn both_character_formats_take_ten_bits() {
        assert_eq!(bits_per_char(CharFormat::EightN1), 1 + 8 + 1);
        assert_eq!(bits_per_char(CharFormat::SevenE1), 1 + 7 + 1 + 1);
    }

    /// Reads until `want` bytes came or a second passed.
    fn read_all<L: Link>(l: &mut L, want: usize) -> Vec<u8> {
        let mut got = Vec::new();
        let mut buf = [0u8; 64];
        let t0 = std::time::Instant::now();
        while got.len() < want && t0.elapsed() < Duration::from_secs(1) {
            let n = l.read_timeout(&mut buf, Duration::from_millis(20)).unwrap();
            got.extend_from_slice(&buf[..n]);
        }
        got
    }

    /// Waits until `l` has bytes waiting (a pseudo-terminal passes them on asynchronously).
    fn wait_for_input(l: &mut serialport::TTYPort) {
        use serialport::SerialPort as _;
        let t0 = std::time::Instant::now();
        while l.bytes_to_read().unwrap() == 0 && t0.elapsed() < Duration::from_secs(1) {
            std::thread::sleep(Duration::from_millis(1));
        }
        assert!(l.bytes_to_read().unwrap() > 0, "nothing arrived");
    }

    /// The serial-port links on a pseudo-terminal pair (no hardware): bytes written on one end
    /// are read on the other, a read with nothing waiting times out as 0 bytes, and input
    /// waiting is discarded, however much of it; the same through a boxed port (as
    /// `open_serial` returns it) and a boxed link. (The indexer's serial link is the same code,
    /// `paths::serial_link!`.)
    #[cfg(unix)]
    #[test]
    fn serial_ports_carry_bytes_time_out_and_discard_input() {
        let (mut a, mut b) = SerialLink::pty_pair().unwrap();
        Link::write_all(&mut a, b"hello").unwrap();
        assert_eq!(read_all(&mut b, 5), b"hello");
        let mut buf = [0u8; 8];
        assert_eq!(
            b.read_timeout(&mut buf, Duration::from_millis(20)).unwrap(),
            0
        );
        Link::write_all(&mut a, b"stale").unwrap();
        wait_for_input(&mut b);
        b.discard_input().unwrap();
        assert_eq!(
            b.read_timeout(&mut buf, Duration::from_millis(50)).unwrap(),
            0
        );
        // More than one read's worth (256 bytes) waiting: every byte of it goes.
        Link::write_all(&mut a, &[b'x'; 600]).unwrap();
        let t0 = std::time::Instant::now();
        while b.waiting().unwrap() < 600 && t0.elapsed() < Duration::from_secs(1) {
            std::thread::sleep(Duration::from_millis(1));
        }
        assert_eq!(b.waiting().unwrap(), 600);
        b.discard_input().unwrap();
        assert_eq!(
            b.read_timeout(&mut buf, Duration::from_millis(50)).unwrap(),
            0
        );

        let (mut a, b) = SerialLink::pty_pair().unwrap();
        let mut boxed = SerialLink(b.0 as Box<dyn serialport::SerialPort>);
        Link::write_all(&mut boxed, b"ping").unwrap();
        assert_eq!(read_all(&mut a, 4), b"ping");
        Link::write_all(&mut a, b"pong").unwrap();
        assert_eq!(read_all(&mut boxed, 4), b"pong");
        Link::write_all(&mut a, b"stale").unwrap();
        let t0 = std::time::Instant::now();
        while boxed.bytes_to_read().unwrap() == 0 && t0.elapsed() < Duration::from_secs(1) {
            std::thread::sleep(Duration::from_millis(1));
        }
        Link::discard_input(&mut boxed).unwrap();
        assert_eq!(
            boxed
                .read_timeout(&mut buf, Duration::from_millis(50))
                .unwrap(),
            0
        );

        let (p, mut q) = Pipe::pair();
        let mut link: Box<Pipe> = Box::new(p);
        link.write_all(b"ab").unwrap();
        assert_eq!(read_all(&mut q, 2), b"ab");
        q.write_all(b"cd").unwrap();
        assert_eq!(read_all(&mut link, 2), b"cd");
        q.write_all(b"ef").unwrap();
        link.discard_input().unwrap();
        assert_eq!(
            link.read_timeout(&mut buf, Duration::from_millis(1))
                .unwrap(),
            0
        );
    }

    /// A port whose other end has gone is an error, not a quiet line.
    #[cfg(unix)]
    #[test]
    fn a_serial_port_whose_other_end_closed_is_an_error() {
        let (a, mut b) = SerialLink::pty_pair().unwrap();
        drop(a);
        let mut buf = [0u8; 8];
        assert!(b.read_timeout(&mut buf, Duration::from_millis(50)).is_err());
    }

    /// SplitMix64's published outputs for seed 1 234 567 (the reference implementation's test
    /// vector), and for seed 0.
    #[test]
    fn the_generator_is_splitmix64() {
        let mut r = Rng::new(1_234_567);
        let want = [
            6_457_827_717_110_365_317,
            3_203_168_211_198_807_973,
            9_817_491_932_198_370_423,
            4_593_380_528_125_082_431,
            16_408_922_859_458_223_821,
        ];
        for w in want {
            assert_eq!(r.next_u64(), w);
        }
        let mut r = Rng::new(0);
        assert_eq!(r.next_u64(), 0xE220_A839_7B1D_CDAF);
        assert_eq!(r.next_u64(), 0x6E78_9E6A_A1B9_65F4);
        // unit() takes the top 53 bits.
        let mut r = Rng::new(0);
        assert_eq!(
            r.unit(),
            (0xE220_A839_7B1D_CDAFu64 >> 11) as f64 / 2f64.powi(53)
        );
    }

    /// Each kind of fault alone, at rate 1, does what it says to every byte and is counted; at
    /// rate 0 nothing happens.
    #[test]
    fn each_fault_kind_alone_does_what_it_says() {
        let only = |drop, corrupt, delay, duplicate| FaultRates {
            drop,
            corrupt,
            delay,
            duplicate,
            max_delay: Duration::from_millis(300),
        };
        let n = 10_000u32;
        // Corrupted: one to eight bits flipped, never none.
        let mut f = Faults::new(only(0.0, 1.0, 0.0, 0.0), 3);
        for i in 0..n {
            let b = i as u8;
            let fate = f.apply(b);
            assert_ne!(fate.byte, b);
            assert_eq!((fate.copies, fate.delay), (1, Duration::ZERO));
        }
        let c = f.counts();
        assert_eq!(
            (c.bytes, c.corrupted, c.dropped),
            (u64::from(n), u64::from(n), 0)
        );
        // Dropped.
        let mut f = Faults::new(only(1.0, 0.0, 0.0, 0.0), 3);
        assert!((0..n).all(|i| f.apply(i as u8).copies == 0));
        assert_eq!(f.counts().dropped, u64::from(n));
        // Delayed by up to the longest stall, and not all by the same.
        let mut f = Faults::new(only(0.0, 0.0, 1.0, 0.0), 3);
        let delays: Vec<Duration> = (0..n).map(|i| f.apply(i as u8).delay).collect();
        assert!(delays.iter().all(|d| *d <= Duration::from_millis(300)));
        assert!(delays.iter().any(|d| *d > Duration::from_millis(150)));
        assert!(delays.iter().any(|d| *d < Duration::from_millis(150)));
        assert_eq!(f.counts().delayed, u64::from(n));
        // Duplicated.
        let mut f = Faults::new(only(0.0, 0.0, 0.0, 1.0), 3);
        assert!((0..n).all(|i| f.apply(i as u8)
            == Fate {
                delay: Duration::ZERO,
                copies: 2,
                byte: i as u8
            }));
        assert_eq!(f.counts().duplicated, u64::from(n));
        // None.
        let mut f = Faults::new(only(0.0, 0.0, 0.0, 0.0), 3);
        assert!((0..n).all(|i| f.apply(i as u8)
            == Fate {
                delay: Duration::ZERO,
                copies: 1,
                byte: i as u8
            }));
        let c = f.counts();
        assert_eq!(c.dropped + c.corrupted + c.delayed + c.duplicated, 0);
        assert_eq!(c.bytes, u64::from(n));
        // A NAK corrupted into an ACK (the one corruption that turns a refusal into an
        // acceptance) is counted as such, and only that.
        let mut f = Faults::new(only(0.0, 1.0, 0.0, 0.0), 5);
        let mut naks_to_acks = 0;
        for i in 0..100_000u32 {
            let b = if i % 2 == 0 {
                crate::frame::NAK
            } else {
                crate::frame::ACK
            };
            let fate = f.apply(b);
            if b == crate::frame::NAK && fate.byte == crate::frame::ACK {
                naks_to_acks += 1;
            }
        }
        // 50 000 NAKs, one mask in 255 turns each into an ACK: about 196.
        assert!((120..280).contains(&naks_to_acks), "{naks_to_acks}");
        assert_eq!(f.counts().nak_to_ack, naks_to_acks);
    }

    #[test]
    fn faults_are_seeded_and_near_their_rates() {
        let mut a = Faults::new(FaultRates::uniform(0.1), 7);
        let mut b = Faults::new(FaultRates::uniform(0.1), 7);
        for i in 0..10_000u32 {
            assert_eq!(a.apply(i as u8), b.apply(i as u8));
        }
        let c = a.counts();
        let hit = c.dropped + c.corrupted + c.delayed + c.duplicated;
        assert!((800..1200).contains(&hit), "{c:?}");
    }

    /// Echoes every byte back.
    #[derive(Debug, Default)]
    struct Echo(Vec<u8>);
    impl Peer for Echo {
        fn receive(&mut self, bytes: &[u8], _now: Duration) {
            self.0.extend_from_slice(bytes);
        }
        fn poll(&mut self, _now: Duration) {}
        fn take_output(&mut self) -> Vec<u8> {
            std::mem::take(&mut self.0)
        }
        fn deadline(&self) -> Option<Duration> {
            None
        }
    }

    #[test]
    fn paced_wire_takes_wire_time() {
        let clock = VirtualClock::new();
        let mut w = Paced::new(clock.clone(), 9600, Echo::default());
        w.write_all(&[1, 2, 3]).unwrap();
        // Three bytes at 10 bits / 9600 baud.
        assert_eq!(clock.now(), w.byte_time() * 3);
        let mut buf = [0u8; 8];
        let mut got = Vec::new();
        while got.len() < 3 {
            let n = w.read_timeout(&mut buf, Duration::from_millis(50)).unwrap();
            assert!(n > 0);
            got.extend_from_slice(&buf[..n]);
        }
        assert_eq!(got, [1, 2, 3]);
        // The echo of the last byte arrives one byte time after the last byte was received.
        assert_eq!(clock.now(), w.byte_time() * 4);
        assert_eq!(
            w.read_timeout(&mut buf, Duration::from_millis(5)).unwrap(),
            0
        );
        assert_eq!(clock.now(), w.byte_time() * 4 + Duration::from_millis(5));
    }

    /// Bytes written later leave from the clock's time then, the line's busy time counts only
    /// the bytes' own time, and the wire's clock is the one it was given.
    #[test]
    fn paced_wire_schedules_from_now_and_counts_busy_time() {
        let clock = VirtualClock::new();
        let mut w = Paced::new(clock.clone(), 9600, Echo::default());
        let bt = w.byte_time();
        w.run_for(Duration::from_millis(10));
        w.write_all(&[1, 2, 3]).unwrap();
        assert_eq!(clock.now(), Duration::from_millis(10) + bt * 3);
        assert_eq!(w.clock().now(), clock.now());
        assert_eq!(w.host_line_busy(), bt * 3);
        w.run_for(Duration::from_millis(10));
        w.write_all(&[4]).unwrap();
        assert_eq!(w.host_line_busy(), bt * 4);
    }

    /// A read times out at its deadline even when a byte comes just after it, and a discard
    /// drops a byte that arrives at the very moment it is made.
    #[test]
    fn paced_wire_reads_keep_their_deadline_and_discard_what_has_arrived() {
        let clock = VirtualClock::new();
        let mut w = Paced::new(clock.clone(), 9600, Echo::default());
        let bt = w.byte_time();
        let mut buf = [0u8; 8];
        // The echo of a byte written at 0 arrives at 2 byte times; the clock stands at 1.
        w.write_all(&[7]).unwrap();
        assert_eq!(w.read_timeout(&mut buf, bt / 2).unwrap(), 0);
        assert_eq!(clock.now(), bt + bt / 2);
        assert_eq!(w.read_timeout(&mut buf, bt).unwrap(), 1);
        assert_eq!((buf[0], clock.now()), (7, bt * 2));
        // An echo arriving exactly now is in, and discarded.
        let t0 = clock.now();
        w.write_all(&[8]).unwrap();
        w.run_for(bt);
        assert_eq!(clock.now(), t0 + bt * 2);
        w.discard_input().unwrap();
        assert_eq!(
            w.read_timeout(&mut buf, Duration::from_millis(5)).unwrap(),
            0
        );
    }

    /// A device that always wants polling now (its deadline never moves on) cannot hold the
    /// wire: the peer loop gives up after a million polls and time goes on.
    #[test]
    fn a_device_stuck_at_its_deadline_does_not_hang_the_wire() {
        #[derive(Debug, Default)]
        struct Stuck {
            now: Duration,
            polls: u64,
        }
        impl Peer for Stuck {
            fn receive(&mut self, _: &[u8], now: Duration) {
                self.now = now;
            }
            fn poll(&mut self, now: Duration) {
                self.now = now;
                self.polls += 1;
            }
            fn take_output(&mut self) -> Vec<u8> {
                Vec::new()
            }
            fn deadline(&self) -> Option<Duration> {
                Some(self.now)
            }
        }
        let clock = VirtualClock::new();
        let mut w = Paced::new(clock.clone(), 9600, Stuck::default());
        w.run_for(Duration::from_millis(1));
        assert_eq!(clock.now(), Duration::from_millis(1));
        // The guard's million polls, one more that breaks out, and the final poll at the end.
        assert_eq!(w.peer.polls, 1_000_002);
    }

    /// The paced wire counts each direction's faults apart: every byte to the peer dropped, none
    /// of the (absent) echoes faulted on the way back.
    #[test]
    fn paced_wire_counts_each_directions_faults() {
        let clock = VirtualClock::new();
        let drop_all = FaultRates {
            drop: 1.0,
            corrupt: 0.0,
            delay: 0.0,
            duplicate: 0.0,
            max_delay: Duration::ZERO,
        };
        let mut w = Paced::new(clock, 9600, Echo::default()).with_faults(
            Faults::new(drop_all, 1),
            Faults::new(FaultRates::uniform(0.0), 2),
        );
        w.write_all(&[1, 2, 3]).unwrap();
        let mut buf = [0u8; 8];
        assert_eq!(
            w.read_timeout(&mut buf, Duration::from_millis(5)).unwrap(),
            0
        );
        let (to_peer, to_host) = w.fault_counts();
        assert_eq!((to_peer.bytes, to_peer.dropped), (3, 3));
        assert_eq!(to_host.bytes, 0);
    }
}

#[cfg(test)]
mod wrapper_tests {
    use super::*;

    #[test]
    fn faulty_drops_and_duplicates_and_tap_records() {
        let (a, mut b) = Pipe::pair();
        let rates = FaultRates {
            drop: 0.5,
            corrupt: 0.0,
            delay: 0.0,
            duplicate: 0.5,
            max_delay: Duration::ZERO,
        };
        let (mut tap, log) = Tap::new(Faulty::new(a, Faults::new(rates, 3)));
        tap.write_all(&[1, 2, 3, 4, 5, 6, 7, 8]).unwrap();
        let mut buf = [0u8; 64];
        let n = b.read_timeout(&mut buf, Duration::from_millis(10)).unwrap();
        let c = tap.inner().counts();
        assert_eq!(c.dropped + c.duplicated, 8);
        assert_eq!(n as u64, 8 - c.dropped + c.duplicated);
        b.write_all(&[9]).unwrap();
        assert_eq!(
            tap.read_timeout(&mut buf, Duration::from_millis(10))
                .unwrap(),
            1
        );
        let log = log.lock().unwrap();
        assert_eq!(log.len(), 2);
        assert_eq!((log[0].dir, log[1].dir), (Direction::Tx, Direction::Rx));
        assert_eq!(log[1].bytes, [9]);
    }
}
