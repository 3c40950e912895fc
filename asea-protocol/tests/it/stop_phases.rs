//! A stop requested at every moment of a status poll (docs/protocol.md §6 rules 7, 8 and 11):
//! the client polls the simulated robot's status back to back over the paced 9600-baud wire in
//! virtual time, its cancel token is set at an instant swept across two whole poll cycles, and
//! `stop_at_once` follows, as the cell's coordinator does. For each instant the STOP telegram
//! must have reached the robot within a bound computed from the protocol's timers and the bytes
//! the wire carried before it (never from a run of the client), and the stop must be confirmed
//! with the robot STOPPED, having executed STOP exactly once.
//!
//! The bounds, with `b` the time of one byte and `G` the urgent gap (`T_GAP`/2 and its margin):
//! - the robot has seen no telegram of the host's session (its ENQ awaits the ACK): STOP goes in
//!   that session, once the ACK is in: by the ACK's arrival + 5 b (the STOP telegram);
//! - the host's telegram is on the line and its EOT is not: the host ends the session with EOT
//!   once it sees the request (at most one `POLL_PERIOD`, or the end of its own write), then
//!   keeps `G` of silence, ENQ, ACK, STOP: by then + b + G + 7 b;
//! - otherwise (in the gap, or the host's EOT out and the robot replying): nothing is sent; the
//!   STOP's ENQ follows `G` after the host's last byte, or at once if that is past: by
//!   max(request + `POLL_PERIOD`, last byte + G) + 7 b.

use std::time::Duration;

use asea_protocol::client::{Cancel, POLL_PERIOD};
use asea_protocol::clock::VirtualClock;
use asea_protocol::frame::{ACK, ENQ, EOT, STX, telegram_digest};
use asea_protocol::link::{Paced, Peer};
use asea_protocol::session::{T_GAP, Timers};
use asea_protocol::{Client, ClientConfig, Command, Error, Robot, State};

/// STOP as it goes on the wire (docs/protocol.md §3: `02 0C 00 03 0F`).
const STOP_TELEGRAM: [u8; 5] = [0x02, 0x0C, 0x00, 0x03, 0x0F];

/// Who sent a byte.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum From {
    Host,
    Robot,
}

/// The simulated robot, a cancel token set at `cancel_at`, and a log of the wire: each byte
/// with the time it was whole at the robot (host bytes) or left the robot (robot bytes).
#[derive(Debug)]
struct Wire {
    robot: Robot,
    cancel: Cancel,
    cancel_at: Option<Duration>,
    now: Duration,
    log: Vec<(Duration, From, u8)>,
    /// The robot notes each EOT this late (and the bytes behind it no sooner).
    late_eot: Option<Duration>,
    late: Vec<(Duration, u8)>,
}

impl Peer for Wire {
    fn receive(&mut self, bytes: &[u8], now: Duration) {
        self.tick(now);
        for &b in bytes {
            self.log.push((now, From::Host, b));
            match self.late_eot {
                Some(d) if b == EOT || !self.late.is_empty() => {
                    let due = if b == EOT { now + d } else { now };
                    self.late.push((due, b));
                }
                _ => self.robot.receive(&[b], now),
            }
        }
    }
    fn poll(&mut self, now: Duration) {
        self.tick(now);
        self.robot.poll(now);
    }
    fn take_output(&mut self) -> Vec<u8> {
        let out = self.robot.take_output();
        for &b in &out {
            self.log.push((self.now, From::Robot, b));
        }
        out
    }
    fn deadline(&self) -> Option<Duration> {
        [
            self.robot.deadline(),
            self.cancel_at,
            self.late.first().map(|(due, _)| *due),
        ]
        .into_iter()
        .flatten()
        .min()
    }
}

impl Wire {
    fn tick(&mut self, now: Duration) {
        self.now = now;
        if self.cancel_at.is_some_and(|t| now >= t) {
            self.cancel_at = None;
            self.cancel.cancel();
        }
        // Bytes held behind a late EOT reach the robot in order, none before its time.
        while let Some(&(due, b)) = self.late.first() {
            if due > now {
                break;
            }
            self.late.remove(0);
            self.robot.receive(&[b], now);
        }
    }
}

type TestClient = Client<Paced<Wire>, VirtualClock>;

fn client() -> (TestClient, Duration) {
    let clock = VirtualClock::new();
    let wire = Wire {
        robot: Robot::default(),
        cancel: Cancel::new(),
        cancel_at: None,
        now: Duration::ZERO,
        log: Vec::new(),
        late_eot: None,
        late: Vec::new(),
    };
    let paced = Paced::new(clock.clone(), 9600, wire);
    let b = paced.byte_time();
    let mut c = Client::with_clock(paced, clock, ClientConfig::default());
    let token = c.cancel_token();
    c.link_mut().peer.cancel = token;
    (c, b)
}

/// What the wire shows of the host's session at `t`, from the host's bytes whole at the robot
/// by then and the robot's bytes (each whole at the host `b` after it left the robot).
#[derive(Debug, PartialEq)]
enum Phase {
    /// The host's ENQ is out and the robot's ACK reaches the host at this time (after `t`).
    AwaitingAck(Duration),
    /// The host's telegram (whole at the robot at this time) is out, its EOT is not.
    TelegramOut(Duration),
    /// No host session open: the host's last byte was whole at the robot at this time.
    Closed(Duration),
}

fn phase(log: &[(Duration, From, u8)], t: Duration, b: Duration) -> Phase {
    // Host bytes begun by `t` count (a write is not interrupted).
    let host: Vec<(Duration, u8)> = log
        .iter()
        .filter(|(at, from, _)| *from == From::Host && *at < t + b)
        .map(|(at, _, byte)| (*at, *byte))
        .collect();
    let last = host.last().map_or(Duration::ZERO, |(at, _)| *at);
    let Some(enq) = host.iter().rposition(|(_, byte)| *byte == ENQ) else {
        return Phase::Closed(last);
    };
    let after = &host[enq + 1..];
    if after.iter().any(|(_, byte)| *byte == EOT) {
        return Phase::Closed(last);
    }
    if after.first().is_some_and(|(_, byte)| *byte == STX) {
        // The whole telegram goes out: STX CMD LEN DATA ETX CS.
        let all: Vec<Duration> = log
            .iter()
            .filter(|(at, from, _)| *from == From::Host && *at >= after[0].0)
            .map(|(at, _, _)| *at)
            .collect();
        let len = log
            .iter()
            .filter(|(at, from, _)| *from == From::Host && *at >= after[0].0)
            .nth(2)
            .map_or(0, |(_, _, byte)| usize::from(*byte));
        return Phase::TelegramOut(all[len + 4]);
    }
    let enq_at = host[enq].0;
    let ack = log
        .iter()
        .find(|(at, from, byte)| *from == From::Robot && *byte == ACK && *at >= enq_at)
        .map(|(at, _, _)| *at + b)
        .expect("the robot acknowledges every ENQ");
    if ack > t {
        Phase::AwaitingAck(ack)
    } else {
        // The ACK is in at `t`: the telegram follows at once, unsent while the request is seen.
        Phase::AwaitingAck(t)
    }
}

/// When the STOP telegram was whole at the robot (the first after `t`).
fn stop_arrival(log: &[(Duration, From, u8)], t: Duration) -> Option<Duration> {
    let host: Vec<(Duration, u8)> = log
        .iter()
        .filter(|(_, from, _)| *from == From::Host)
        .map(|(at, _, byte)| (*at, *byte))
        .collect();
    host.windows(STOP_TELEGRAM.len())
        .find(|w| w[0].0 >= t && w.iter().map(|(_, byte)| *byte).eq(STOP_TELEGRAM))
        .map(|w| w[STOP_TELEGRAM.len() - 1].0)
}

/// When the robot's line has sent every byte the robot handed it before `at`.
fn robot_line_free(log: &[(Duration, From, u8)], at: Duration, b: Duration) -> Duration {
    log.iter()
        .filter(|(t, from, _)| *from == From::Robot && *t < at)
        .fold(Duration::ZERO, |free, (t, _, _)| free.max(*t) + b)
}

/// One run: polls until the request at `t`, then `stop_at_once`; the latency and the phase.
fn stop_at(t: Duration) -> (Duration, Phase, Duration, Vec<(Duration, From, u8)>) {
    stop_with(t, None)
}

/// [`stop_at`] with a robot that notes each EOT `late_eot` late.
fn stop_with(
    t: Duration,
    late_eot: Option<Duration>,
) -> (Duration, Phase, Duration, Vec<(Duration, From, u8)>) {
    let (mut c, b) = client();
    c.link_mut().peer.cancel_at = Some(t);
    c.link_mut().peer.late_eot = late_eot;
    loop {
        match c.status() {
            Ok(_) => {}
            Err(Error::Cancelled) => break,
            Err(e) => panic!("status: {e}"),
        }
    }
    let executed_before = c.link().peer.robot.machine.status().executed;
    c.cancel_token().reset();
    let s = c.stop_at_once().expect("the stop is confirmed");
    assert_eq!(s.state, State::Stopped);
    let robot = c.link().peer.robot.machine.status();
    assert_eq!(robot.state, State::Stopped);
    // STOP executed exactly once (the count advanced by one with STOP's digest).
    assert_eq!(robot.executed, executed_before.wrapping_add(1), "at {t:?}");
    assert_eq!(
        robot.last_digest,
        telegram_digest(Command::Stop.code(), &[])
    );
    let log = &c.link().peer.log;
    let at = stop_arrival(log, t).expect("STOP on the wire");
    (at - t, phase(log, t, b), b, log.clone())
}

/// The urgent gap is above the `T_GAP`/2 the robot needs and below the whole gap.
#[test]
fn the_urgent_gap_is_above_half_the_gap() {
    let g = Timers::default().urgent_gap();
    assert!(g > T_GAP / 2 && g < T_GAP, "{g:?}");
}

#[test]
fn a_stop_at_any_moment_of_a_status_poll_reaches_the_wire_within_the_protocols_bound() {
    let g = Timers::default().urgent_gap();
    // Two poll cycles (a session of some 32 bytes and the gap), after a first poll.
    let start = Duration::from_millis(60);
    let step = Duration::from_micros(250);
    let mut seen = [0usize; 3];
    let mut worst = Duration::ZERO;
    for k in 0..480u32 {
        let t = start + step * k;
        let (latency, phase, b, log) = stop_at(t);
        // When the STOP's ENQ may leave the host, by the rules above.
        let enq = match phase {
            Phase::AwaitingAck(_) => None,
            Phase::TelegramOut(end) => {
                seen[1] += 1;
                Some(end.max(t) + POLL_PERIOD + b + g)
            }
            Phase::Closed(last) => {
                seen[2] += 1;
                Some((t + POLL_PERIOD).max(last + g))
            }
        };
        let bound = match (&phase, enq) {
            (Phase::AwaitingAck(ack), _) => {
                seen[0] += 1;
                *ack + b * 5 - t
            }
            (_, Some(enq)) => {
                // The robot's ACK leaves behind what it was still sending (a reply).
                let whole = enq + b;
                let ack = robot_line_free(&log, whole, b).max(whole) + b;
                ack + b * 5 - t
            }
            (_, None) => unreachable!(),
        };
        assert!(
            latency <= bound,
            "stop requested at {t:?} ({phase:?}): on the wire after {latency:?}, bound {bound:?}"
        );
        worst = worst.max(latency);
    }
    eprintln!("phases {seen:?}, worst {worst:?}");
    // Every phase was met, and no stop took longer than an abandoned session allows.
    assert!(seen.iter().all(|n| *n > 0), "{seen:?}");
    let b = Duration::from_secs_f64(10.0 / 9600.0);
    assert!(worst <= b * 7 + POLL_PERIOD + b + g + b * 7, "{worst:?}");
}

/// A robot that notes the host's EOT later than the urgent margin allows sees less than the
/// `T_GAP`/2 of silence it needs before the STOP's ENQ and takes it for data; the urgent ENQ
/// is repeated one urgent gap later, not after `T_ENQ`, so the stop still reaches the wire
/// within the bound of an abandoned session plus one urgent gap and the late noting.
#[test]
fn a_robot_that_notes_the_eot_late_takes_the_repeated_urgent_enq() {
    let timers = Timers::default();
    let g = timers.urgent_gap();
    let b = Duration::from_secs_f64(10.0 / 9600.0);
    // The robot stamps a byte at its end: between the EOT's end and the ENQ's end it sees the
    // urgent gap and the ENQ's own byte; noted later than the margin and that byte, the EOT
    // leaves it less than `T_GAP`/2.
    let late = timers.urgent_margin + b + Duration::from_millis(1);
    let bound = b * 7 + POLL_PERIOD + b + g + b * 7 + g + late;
    let start = Duration::from_millis(60);
    let mut repeated = 0;
    for k in 0..240u32 {
        let t = start + Duration::from_micros(250) * k;
        let (latency, _, _, log) = stop_with(t, Some(late));
        assert!(latency <= bound, "at {t:?}: {latency:?}, bound {bound:?}");
        // Two ENQs between the request and the STOP telegram: the first was taken for data.
        let stop_at = t + latency;
        let enqs = log
            .iter()
            .filter(|(at, from, byte)| {
                *from == From::Host && *byte == ENQ && *at > t && *at < stop_at
            })
            .count();
        if enqs >= 2 {
            repeated += 1;
        }
    }
    assert!(repeated > 0, "no stop needed the repeat");
}

/// A cancelled session is never left open on the wire: one whose telegram the robot has seen is
/// ended with EOT before the call returns; one held for a STOP (the robot has seen no telegram of
/// it) and followed by another command instead is ended with EOT before that command's ENQ.
#[test]
fn a_cancelled_session_is_ended_with_eot() {
    let start = Duration::from_millis(60);
    let (mut ended, mut held) = (0, 0);
    for k in 0..480u32 {
        let t = start + Duration::from_micros(250) * k;
        let (mut c, b) = client();
        c.link_mut().peer.cancel_at = Some(t);
        loop {
            match c.status() {
                Ok(_) => {}
                Err(Error::Cancelled) => break,
                Err(e) => panic!("status: {e}"),
            }
        }
        let sent_by_return = c.link().peer.log.len();
        match phase(&c.link().peer.log, t, b) {
            Phase::TelegramOut(_) => {
                let last = c.link().peer.log.iter().rev().find(|e| e.1 == From::Host);
                assert_eq!(last.map(|e| e.2), Some(EOT), "at {t:?}");
                ended += 1;
            }
            Phase::AwaitingAck(_) => {
                c.cancel_token().reset();
                c.status().expect("the next command goes through");
                let after: Vec<u8> = c.link().peer.log[sent_by_return..]
                    .iter()
                    .filter(|e| e.1 == From::Host)
                    .map(|e| e.2)
                    .collect();
                assert_eq!(after.first(), Some(&EOT), "at {t:?}: {after:02X?}");
                assert_eq!(after.get(1), Some(&ENQ), "at {t:?}: {after:02X?}");
                held += 1;
            }
            Phase::Closed(_) => {}
        }
    }
    assert!(ended > 0 && held > 0, "{ended} {held}");
}
