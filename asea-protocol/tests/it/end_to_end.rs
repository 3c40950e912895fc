//! Client ↔ simulated robot: over the paced virtual-time wire (program flow, silence, NAK storm,
//! fault injection with exactly-once accounting) and over a pseudo-terminal in real time.

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use asea_protocol::clock::{Clock, VirtualClock, WallClock};
use asea_protocol::command::IN_POSITION_OUTPUT;
use asea_protocol::command::{Control, Instruction};
use asea_protocol::link::{FaultRates, Faults, Paced, Peer};
use asea_protocol::session::{N_ENQ, N_TX, T_BUSY, T_ENQ, Timers};
use asea_protocol::sim::{Malformed, MotionParams, Robot, serve};
use asea_protocol::{
    Checksum, Client, ClientConfig, Command, Error, Flags, FrameConfig, LinkError, Mode, Pose,
    Positioning, Speed, Zone,
};

/// A positioning with the eye's roll axis (the quaternion's X axis) horizontal and radial, in
/// the arm's vertical plane: a pose the simulated five-axis arm can take.
fn positioning(x: f64, y: f64, z: f64, zone: Zone) -> Positioning {
    let half = y.atan2(x) / 2.0;
    Positioning {
        flags: Flags {
            zone,
            ..Flags::default()
        },
        pose: Pose::from_mm([x, y, z], [half.cos(), 0.0, 0.0, half.sin()]).unwrap(),
        speed: Speed::from_value("speed", 0.5).unwrap(),
    }
}

/// A 50-instruction winding-like program: a zig-zag of 47 points in medium zone, then "in
/// position" on output 1, wait for the PC's start on input 1, end.
fn program_50() -> Vec<Instruction> {
    program_50_zigzag(100.0)
}

fn program_50_zigzag(half_width_mm: f64) -> Vec<Instruction> {
    let mut v: Vec<Instruction> = (0..47)
        .map(|k| {
            let k = f64::from(k);
            let y = if (k as i32) % 2 == 0 {
                -half_width_mm
            } else {
                half_width_mm
            };
            Instruction::Position(positioning(900.0, y, 400.0 + 5.0 * k, Zone::Medium))
        })
        .collect();
    v.push(Instruction::Control(Control::SetOutput {
        line: IN_POSITION_OUTPUT,
        on: true,
    }));
    v.push(Instruction::Control(Control::WaitInput {
        line: 1,
        on: true,
    }));
    v.push(Instruction::Control(Control::End));
    v
}

fn paced(cfg: FrameConfig) -> (Client<Paced<Robot>, VirtualClock>, VirtualClock) {
    let clock = VirtualClock::new();
    let robot = Robot::new(cfg, Timers::default(), MotionParams::default());
    let wire = Paced::new(clock.clone(), 9600, robot);
    let ccfg = ClientConfig {
        frame: cfg,
        ..ClientConfig::default()
    };
    (Client::with_clock(wire, clock.clone(), ccfg), clock)
}

#[test]
fn program_flow_in_virtual_time() {
    let (mut c, clock) = paced(FrameConfig::default());
    // An empty program is refused: the confirmed RUN_PROGRAM reports the robot's error.
    let e = c.run_program(1).unwrap_err();
    assert!(
        matches!(
            e,
            Error::Robot {
                code: 5,
                count: 1,
                ..
            }
        ),
        "{e}"
    );
    // It was reported once: the latch was acknowledged, the next check is clean.
    assert_eq!(c.check_status().unwrap().last_error, 0);
    c.operate().unwrap();
    c.sync_home().unwrap();
    c.link_mut().run_for(Duration::from_secs(4));
    let s = c.check_status().unwrap();
    assert!(s.homed);
    assert_eq!(s.mode, Mode::Operate);

    let prog = program_50();
    c.upload(7, &prog).unwrap();
    let report = c.verify(7, &prog).unwrap();
    assert_eq!((report.checked, report.restored), (50, 0));
    assert_eq!(c.read_back(7, 51).unwrap(), None);

    let t_run = clock.now();
    c.run_program(7).unwrap();
    // The program runs 47 moves, raises output 1 and waits for input 1.
    c.link_mut().run_for(Duration::from_secs(60));
    let io = c.link().peer.machine.io().clone();
    assert!(io.output(IN_POSITION_OUTPUT));
    assert_eq!(c.status().unwrap().state, asea_protocol::State::Running);
    io.set_input(1, true);
    c.link_mut().run_for(Duration::from_millis(100));
    let s = c.status().unwrap();
    assert_eq!(s.state, asea_protocol::State::Idle);
    let pose = c.position().unwrap();
    assert_eq!(pose.xyz_mm(), [900.0, -100.0, 400.0 + 5.0 * 46.0]);
    let first_stop = c.link().peer.machine.trace.first().unwrap().0;
    // 47 flying moves of about 200 mm at half the 1 m/s base speed (0.4 s each, less the 10 mm
    // corners the medium zone cuts): they take their motion time, not the 540 ms plateau Table 6.2
    // measured on isolated moves.
    let m = &c.link().peer.machine;
    let first = m.trace.first().unwrap().0;
    let last = m.trace.get(46).unwrap().0;
    assert!(first > t_run.as_secs_f64());
    let run_s = last - t_run.as_secs_f64();
    eprintln!("47 flying moves: {run_s:.3} s");
    // Independent estimate: 46 legs of √(200² + 5²) mm at 500 mm/s after point 1; the medium
    // zone cuts 10 mm off both ends of each leg (500 mm/s brakes over 31 mm, more than the zone)
    // and adds the chord across the near-reversal, 10 mm × |u_in + u_out| = 10 × 10/leg; the
    // last point's stop adds the ramp down (500/4000 s, of which half is already in the leg
    // time) and the 0.385 s medium overhead.
    let leg = (200.0f64 * 200.0 + 25.0).sqrt();
    let chord = 10.0 * 10.0 / leg;
    let expected_s = 46.0 * (leg - 20.0 + chord) / 500.0 + 0.0625 + 0.385;
    let legs_s = last - first_stop;
    eprintln!("legs after point 1: {legs_s:.3} s, expected {expected_s:.3} s");
    assert!(
        (legs_s - expected_s).abs() < 0.02 * expected_s,
        "{legs_s} s against {expected_s} s"
    );
    // Discrete move: output 1 drops while moving and rises in position.
    c.move_immediate(positioning(900.0, 0.0, 500.0, Zone::Fine))
        .unwrap();
    assert!(!io.output(IN_POSITION_OUTPUT));
    c.link_mut().run_for(Duration::from_secs(2));
    assert!(io.output(IN_POSITION_OUTPUT));
    assert_eq!(c.position().unwrap().xyz_mm(), [900.0, 0.0, 500.0]);
}

/// The simulated robot is the five-axis arm by default (`sim::ArmModel`): a pose whose roll axis
/// leaves the arm's vertical plane needs a wrist yaw the IRB 6/2 lacks (seed 001 §4.1.1) and is
/// refused with code 9, in a program at its instruction (the client names it) and at once for
/// an immediate move. The same point with the roll axis in the plane is taken.
#[test]
fn a_wrist_yaw_is_refused_with_the_instruction_number() {
    let (mut c, _) = paced(FrameConfig::default());
    let mut yawed = positioning(900.0, 300.0, 700.0, Zone::Fine);
    // The roll axis along x at a point 18.4° off the x axis: 18.4° out of the arm plane.
    yawed.pose = Pose::from_mm([900.0, 300.0, 700.0], [1.0, 0.0, 0.0, 0.0]).unwrap();
    let prog = vec![
        Instruction::Position(positioning(900.0, 0.0, 700.0, Zone::Fine)),
        Instruction::Position(positioning(900.0, 300.0, 700.0, Zone::Fine)),
        Instruction::Position(yawed),
        Instruction::Control(Control::End),
    ];
    c.upload(3, &prog).unwrap();
    let e = c.run_program(3).unwrap_err();
    assert!(
        matches!(
            e,
            Error::Robot {
                code: 9,
                instruction: 3,
                ..
            }
        ),
        "{e}"
    );
    c.operate().unwrap();
    c.sync_home().unwrap();
    c.link_mut().run_for(Duration::from_secs(4));
    let e = c.move_immediate(yawed).unwrap_err();
    assert!(matches!(e, Error::Robot { code: 9, .. }), "{e}");
    c.move_immediate(positioning(900.0, 300.0, 700.0, Zone::Fine))
        .unwrap();
}

/// Two stores the robot refuses in one upload raise two errors before the client's first
/// status read; the client reads the error number before its first store, so it counts both
/// (one latched, one overwritten), not only the latched one.
#[test]
fn errors_raised_before_the_first_status_read_are_all_counted() {
    let (mut c, _) = paced(FrameConfig::default());
    let mut bad = positioning(900.0, 0.0, 700.0, Zone::Fine);
    bad.pose.q = asea_protocol::command::Quaternion([8000, 0, 0, 0]);
    let prog = vec![
        Instruction::Position(bad),
        Instruction::Position(bad),
        Instruction::Control(Control::End),
    ];
    let e = c.upload(4, &prog).unwrap_err();
    assert!(matches!(e, Error::Robot { code: 3, .. }), "{e}");
    assert_eq!(c.link().peer.machine.errors_raised(), 2);
    assert_eq!(c.errors_seen(), 2);
}

#[test]
fn standby_checks_without_moving_and_memory_limits() {
    let (mut c, _) = paced(FrameConfig::default());
    // Out of reach (x = 2000 mm): stored, then caught by the standby dry run.
    let mut prog: Vec<Instruction> = (0..3)
        .map(|k| Instruction::Position(positioning(900.0, 10.0 * f64::from(k), 500.0, Zone::Fine)))
        .collect();
    prog.push(Instruction::Position(positioning(
        2000.0,
        0.0,
        500.0,
        Zone::Fine,
    )));
    c.upload(2, &prog).unwrap();
    // The standby dry run stops at instruction 4 and the client names it.
    let e = c.run_program(2).unwrap_err();
    assert!(
        matches!(
            e,
            Error::Robot {
                code: 9,
                program: 0,
                instruction: 4,
                ..
            }
        ),
        "{e}"
    );
    assert_eq!(
        c.link().peer.machine.pose().xyz_mm,
        MotionParams::default().home.xyz_mm
    );
    c.delete_program(2).unwrap();

    // 470 positioning instructions fit; the 471st does not.
    let m = &mut c.link_mut().peer.machine;
    let store = |m: &mut asea_protocol::sim::Machine, prog: u8, n: u16, i: Instruction| {
        let cmd = asea_protocol::client::store_command(prog, n, &i);
        let bytes = cmd.encode(&FrameConfig::default()).unwrap();
        let frame = asea_protocol::frame::Frame {
            code: bytes[1],
            data: bytes[3..bytes.len() - 2].to_vec(),
        };
        m.execute(&frame, 0.0);
        m.last_error()
    };
    let p = Instruction::Position(positioning(900.0, 0.0, 500.0, Zone::Fine));
    for n in 1..=470 {
        assert_eq!(store(m, 1, n, p), 0, "instruction {n}");
    }
    assert_eq!(store(m, 1, 471, p), 8);
    // Overwriting is not growth.
    assert_eq!(store(m, 1, 470, p), 8, "the error stays until read");
    let mut m2 = asea_protocol::sim::Machine::default();
    let ctl = Instruction::Control(Control::SetOutput { line: 2, on: true });
    for n in 1..=300 {
        assert_eq!(store(&mut m2, 1, n, p), 0);
    }
    for n in 301..=500 {
        assert_eq!(store(&mut m2, 1, n, ctl), 0, "control {n}");
    }
    assert_eq!(store(&mut m2, 2, 1, ctl), 8);
}

/// A device that never answers.
#[derive(Debug, Default)]
struct Silent;
impl Peer for Silent {
    fn receive(&mut self, _: &[u8], _: Duration) {}
    fn poll(&mut self, _: Duration) {}
    fn take_output(&mut self) -> Vec<u8> {
        Vec::new()
    }
    fn deadline(&self) -> Option<Duration> {
        None
    }
}

/// A device that answers every ENQ with one byte and nothing else: ACK for [`EnqOnly::mute`]
/// (it takes every session and never answers a telegram, neither ACK nor NAK), NAK for
/// [`EnqOnly::busy`] (it refuses every session as busy).
#[derive(Debug)]
struct EnqOnly {
    answer: u8,
    out: Vec<u8>,
}
impl EnqOnly {
    fn mute() -> Self {
        EnqOnly {
            answer: 0x06,
            out: Vec::new(),
        }
    }
    fn busy() -> Self {
        EnqOnly {
            answer: 0x15,
            out: Vec::new(),
        }
    }
}
impl Peer for EnqOnly {
    fn receive(&mut self, bytes: &[u8], _: Duration) {
        for &b in bytes {
            if b == 0x05 {
                self.out.push(self.answer);
            }
        }
    }
    fn poll(&mut self, _: Duration) {}
    fn take_output(&mut self) -> Vec<u8> {
        std::mem::take(&mut self.out)
    }
    fn deadline(&self) -> Option<Duration> {
        None
    }
}

#[test]
fn silence_is_no_response_within_n_enq_times_t_enq() {
    let clock = VirtualClock::new();
    let mut c = Client::with_clock(
        Paced::new(clock.clone(), 9600, Silent),
        clock.clone(),
        ClientConfig::default(),
    );
    let e = c.send(&Command::Operate).unwrap_err();
    assert!(
        matches!(e, Error::Link(LinkError::NoResponse { attempts }) if attempts == N_ENQ),
        "{e}"
    );
    let elapsed = clock.now();
    // N_ENQ timeouts of T_ENQ, plus the wire time of the ENQ bytes.
    assert!(elapsed >= T_ENQ * N_ENQ, "{elapsed:?}");
    assert!(
        elapsed < T_ENQ * N_ENQ + Duration::from_millis(50),
        "{elapsed:?}"
    );
}

/// A silent robot is reported after one session of unanswered ENQs by every call the
/// coordinator makes, not retried by each layer above (requests, agreeing status reads, the
/// confirmation of a command, the confirmation of STOP): a cell whose robot hangs hears of it
/// within `N_ENQ × T_ENQ`, and a stop that cannot reach the robot returns as soon.
#[test]
fn a_silent_robot_is_reported_after_one_session_by_every_call() {
    let window = T_ENQ * N_ENQ + Duration::from_millis(50);
    type Call = fn(&mut Client<Paced<Silent>, VirtualClock>) -> Result<(), Error>;
    let calls: [(&str, Call); 5] = [
        ("status", |c| c.status().map(|_| ())),
        ("status_agreed", |c| c.status_agreed().map(|_| ())),
        ("operate", |c| c.operate().map(|_| ())),
        ("stop_at_once", |c| c.stop_at_once().map(|_| ())),
        ("position", |c| c.position().map(|_| ())),
    ];
    for (name, call) in calls {
        let clock = VirtualClock::new();
        let mut c = Client::with_clock(
            Paced::new(clock.clone(), 9600, Silent),
            clock.clone(),
            ClientConfig::default(),
        );
        let e = call(&mut c).unwrap_err();
        assert!(
            matches!(e, Error::Link(LinkError::NoResponse { attempts }) if attempts == N_ENQ),
            "{name}: {e}"
        );
        let elapsed = clock.now();
        assert!(elapsed < window, "{name}: {elapsed:?}");
    }
}

/// A robot busy through every ENQ: a request asks again in `request_sessions` new sessions
/// (the robot may be busy for a while), but nothing above repeats that, and STOP, which must
/// not wait, gives up after its one session.
#[test]
fn a_robot_busy_throughout_is_reported_after_the_request_sessions() {
    // N_ENQ refusals, T_BUSY between them.
    let session = T_BUSY * (N_ENQ - 1);
    let sessions = ClientConfig::default().retry.request_sessions;
    type Call = fn(&mut Client<Paced<EnqOnly>, VirtualClock>) -> Result<(), Error>;
    let calls: [(&str, Call, u32); 4] = [
        ("status", |c| c.status().map(|_| ()), sessions),
        ("status_agreed", |c| c.status_agreed().map(|_| ()), sessions),
        ("operate", |c| c.operate().map(|_| ()), sessions),
        ("stop_at_once", |c| c.stop_at_once().map(|_| ()), 1),
    ];
    for (name, call, n) in calls {
        let clock = VirtualClock::new();
        let mut c = Client::with_clock(
            Paced::new(clock.clone(), 9600, EnqOnly::busy()),
            clock.clone(),
            ClientConfig::default(),
        );
        let e = call(&mut c).unwrap_err();
        assert!(
            matches!(e, Error::Link(LinkError::Busy { attempts }) if attempts == N_ENQ),
            "{name}: {e}"
        );
        let elapsed = clock.now();
        assert!(
            elapsed >= session * n && elapsed < (session + Duration::from_millis(100)) * n,
            "{name}: {elapsed:?} for {n} sessions of {session:?}"
        );
    }
}

#[test]
fn nak_storm_is_a_retries_error() {
    // The robot answers ENQ and then NAKs: on a wire whose device NAKs each frame at its end.
    #[derive(Debug, Default)]
    struct Storm {
        out: Vec<u8>,
        in_frame: usize,
    }
    impl Peer for Storm {
        fn receive(&mut self, bytes: &[u8], _: Duration) {
            for &b in bytes {
                if self.in_frame > 0 {
                    self.in_frame += 1;
                    // STX CMD LEN ETX CS for a zero-data telegram (MODE_OPERATE): 5 bytes.
                    if self.in_frame == 5 {
                        self.out.push(0x15);
                        self.in_frame = 0;
                    }
                } else if b == 0x05 {
                    self.out.push(0x06);
                } else if b == 0x02 {
                    self.in_frame = 1;
                }
            }
        }
        fn poll(&mut self, _: Duration) {}
        fn take_output(&mut self) -> Vec<u8> {
            std::mem::take(&mut self.out)
        }
        fn deadline(&self) -> Option<Duration> {
            None
        }
    }
    let clock = VirtualClock::new();
    let mut c = Client::with_clock(
        Paced::new(clock.clone(), 9600, Storm::default()),
        clock.clone(),
        ClientConfig::default(),
    );
    let e = c.send(&Command::Operate).unwrap_err();
    assert!(
        matches!(e, Error::Link(LinkError::Retries { attempts }) if attempts == N_TX),
        "{e}"
    );
    assert!(clock.now() < Duration::from_secs(1));
    assert_eq!(c.stats().frames_sent, u64::from(N_TX));
    // A device that only acknowledges ENQ: every telegram waits T_ACK, N_TX times.
    let clock = VirtualClock::new();
    let mut c = Client::with_clock(
        Paced::new(clock.clone(), 9600, EnqOnly::mute()),
        clock.clone(),
        ClientConfig::default(),
    );
    assert!(matches!(
        c.send(&Command::Stop),
        Err(Error::Link(LinkError::Retries { attempts: 6 }))
    ));
    assert!(
        clock.now() >= asea_protocol::session::T_ACK * N_TX,
        "{:?}",
        clock.now()
    );
    assert_eq!(c.stats().timeouts, u64::from(N_TX));
    assert_eq!(c.stats().nak_received, 0);
}

/// Outcome of a fault-injection run.
#[derive(Debug, Default)]
struct Tally {
    sent: usize,
    delivered: usize,
    errors: usize,
    /// Reported delivered but not executed exactly once.
    violations: usize,
    /// Executed more than once.
    twice: usize,
    /// Executed frames that no one sent (corruption the check value missed).
    foreign: usize,
}

impl std::ops::AddAssign for Tally {
    fn add_assign(&mut self, t: Tally) {
        self.sent += t.sent;
        self.delivered += t.delivered;
        self.errors += t.errors;
        self.violations += t.violations;
        self.twice += t.twice;
        self.foreign += t.foreign;
    }
}

/// Link set-up of a fault-injection run.
#[derive(Debug, Clone, Copy)]
struct Setup {
    checksum: Checksum,
    malformed: Malformed,
    ack_window: Option<Duration>,
}

/// The spec's link: one-byte sum, malformed telegrams acknowledged with an error code.
const SPEC: Setup = Setup {
    checksum: Checksum::Sum8,
    malformed: Malformed::AckWithError,
    ack_window: None,
};

/// The strong link: CRC-16 and a 10 ms ACK window.
const STRONG: Setup = Setup {
    checksum: Checksum::Crc16,
    malformed: Malformed::AckWithError,
    ack_window: Some(Duration::from_millis(10)),
};

/// A client and a simulated robot on the 9600-baud virtual wire with `setup` on both ends and
/// seeded byte faults at `rate` in both directions.
fn fault_client(
    setup: Setup,
    rate: f64,
    seed: u64,
) -> (Client<Paced<Robot>, VirtualClock>, FrameConfig) {
    let cfg = FrameConfig {
        checksum: setup.checksum,
        ..FrameConfig::default()
    };
    let timers = Timers {
        t_ack_window: setup.ack_window,
        ..Timers::default()
    };
    let clock = VirtualClock::new();
    let robot = Robot::new(cfg, timers, MotionParams::default()).with_malformed(setup.malformed);
    let wire = Paced::new(clock.clone(), 9600, robot).with_faults(
        Faults::new(FaultRates::uniform(rate), seed),
        Faults::new(FaultRates::uniform(rate), seed ^ 0xA5A5),
    );
    let client = Client::with_clock(
        wire,
        clock,
        ClientConfig {
            frame: cfg,
            timers,
            ..ClientConfig::default()
        },
    );
    (client, cfg)
}

/// Telegram `k` of a fault run: a slot of programs 1–3 and a position no other telegram has.
fn fault_telegram(k: usize) -> (u8, u16, Instruction) {
    let kf = k as f64;
    (
        1 + (k % 3) as u8,
        (k % 150) as u16 + 1,
        Instruction::Position(positioning(
            500.0 + kf * 0.5,
            -200.0 + kf * 0.25,
            300.0 + kf,
            Zone::Fine,
        )),
    )
}

/// Counts how often the robot executed each sent store (`outcomes`: the telegram and whether the
/// client reported it delivered) into `tally`: executed twice, and delivered but not executed
/// exactly once. Returns how many executed frames were sent stores.
fn account(
    tally: &mut Tally,
    executed: &[asea_protocol::frame::Frame],
    outcomes: &[(Command, bool)],
    cfg: &FrameConfig,
) -> usize {
    let mut counts: HashMap<(u8, Vec<u8>), usize> = HashMap::new();
    for f in executed {
        *counts.entry((f.code, f.data.clone())).or_default() += 1;
    }
    let mut known = 0;
    for (cmd, ok) in outcomes {
        let bytes = cmd.encode(cfg).unwrap();
        let key = (bytes[1], bytes[3..3 + usize::from(bytes[2])].to_vec());
        let n = counts.get(&key).copied().unwrap_or(0);
        known += n;
        if n > 1 {
            tally.twice += 1;
        }
        if *ok && n != 1 {
            tally.violations += 1;
        }
    }
    known
}

fn fault_run(setup: Setup, rate: f64, telegrams: usize, seed: u64) -> Tally {
    let (mut c, cfg) = fault_client(setup, rate, seed);
    let mut tally = Tally::default();
    let mut outcomes = Vec::with_capacity(telegrams);
    for k in 0..telegrams {
        let (program, instruction, i) = fault_telegram(k);
        let cmd = asea_protocol::client::store_command(program, instruction, &i);
        tally.sent += 1;
        let ok = c.send(&cmd).is_ok();
        if ok {
            tally.delivered += 1;
        } else {
            tally.errors += 1;
        }
        outcomes.push((cmd, ok));
    }
    let executed = &c.link().peer.machine.executed;
    // Only stores were sent: anything else executed is foreign too.
    tally.foreign = executed.len() - account(&mut tally, executed, &outcomes, &cfg);
    tally
}

/// The configuration that meets the target: CRC-16 check value and a 10 ms ACK window. 1 000 telegrams at 1 % and at
/// 10 % byte errors (drop, corrupt, stall, duplicate, both directions): every telegram reported
/// delivered was executed exactly once, none twice.
#[test]
fn exactly_once_with_crc16_and_ack_window_at_1_and_10_percent_byte_errors() {
    for (rate, seed) in [(0.01, 1), (0.10, 2)] {
        let t = fault_run(STRONG, rate, 1000, seed);
        eprintln!("crc16 {rate}: {t:?}");
        assert_eq!(t.sent, 1000);
        assert_eq!(t.delivered + t.errors, t.sent);
        assert_eq!(t.violations, 0, "{t:?}");
        assert_eq!(t.twice, 0, "{t:?}");
        assert_eq!(t.foreign, 0, "{t:?}");
        assert!(t.delivered > if rate < 0.05 { 990 } else { 300 }, "{t:?}");
    }
}

/// The spec's one-byte sum: never twice, but it misses some multi-byte corruptions, so a few
/// telegrams reported delivered were replaced by a corrupted twin (rates in docs/protocol.md;
/// not asserted to be zero because they are not).
#[test]
fn sum8_never_executes_twice() {
    for (rate, seed) in [(0.01, 1), (0.10, 3)] {
        let t = fault_run(SPEC, rate, 1000, seed);
        eprintln!("sum8 {rate}: {t:?}");
        assert_eq!(t.twice, 0, "{t:?}");
        assert_eq!(t.delivered + t.errors, t.sent);
    }
}

/// The spec's one-byte sum with verified stores (`Client::store_verified`: store, then read back
/// until the answers agree, store again only when three answers in a row agree on something
/// else). At 1 % and 10 % byte errors over 1 000 telegrams each: every store reported delivered
/// was executed exactly once, every other one was reported as an error, none was executed twice,
/// and after the closing verification pass every slot holds its last delivered instruction (or a
/// later one whose store was reported failed).
#[test]
fn exactly_once_with_sum8_and_verified_stores_at_1_and_10_percent_byte_errors() {
    for (rate, seed) in [(0.01, 5), (0.10, 6)] {
        let t = verified_fault_run(SPEC, rate, 1000, seed);
        eprintln!("sum8 verified {rate}: {t:?}");
        assert_eq!(t.tally.sent, 1000);
        assert_eq!(t.tally.delivered + t.tally.errors, t.tally.sent);
        assert_eq!(t.tally.violations, 0, "{t:?}");
        assert_eq!(t.tally.twice, 0, "{t:?}");
        assert_eq!(t.wrong_after_repair, 0, "{t:?}");
        assert!(
            t.tally.delivered > if rate < 0.05 { 990 } else { 850 },
            "{t:?}"
        );
    }
}

/// A 50-instruction program uploaded with `upload_verified` over the spec's Sum8 link at 10 %
/// byte errors in both directions: the robot's program is exactly the one sent, and it runs.
#[test]
fn verified_upload_over_a_noisy_sum8_link_stores_the_exact_program() {
    let cfg = FrameConfig::default();
    let timers = Timers::default();
    let clock = VirtualClock::new();
    let robot = Robot::new(cfg, timers, MotionParams::default());
    let wire = Paced::new(clock.clone(), 9600, robot).with_faults(
        Faults::new(FaultRates::uniform(0.10), 21),
        Faults::new(FaultRates::uniform(0.10), 22),
    );
    let mut c = Client::with_clock(
        wire,
        clock,
        ClientConfig {
            frame: cfg,
            timers,
            ..ClientConfig::default()
        },
    );
    let prog = program_50();
    let report = c.upload_verified(4, &prog).unwrap();
    eprintln!("verified upload at 10 %: {report:?}");
    let machine = &c.link().peer.machine;
    for (n, want) in (1u16..).zip(&prog) {
        assert_eq!(machine.instruction(4, n), Some(want), "instruction {n}");
        // Stored once, or again only to overwrite a corrupted twin: never the same store twice in a row.
        let bytes = asea_protocol::client::store_command(4, n, want)
            .encode(&cfg)
            .unwrap();
        let data = &bytes[3..3 + usize::from(bytes[2])];
        let times = machine
            .executed
            .iter()
            .filter(|f| f.code == bytes[1] && f.data == data)
            .count();
        assert!(times >= 1, "instruction {n} never stored");
        assert!(
            times <= 1 + report.restored,
            "instruction {n} stored {times} times"
        );
    }
}

/// A verified upload the robot cannot hold (471 positioning instructions, memory for 470) fails
/// with the robot's own reason, not a bare verification error.
#[test]
fn verified_upload_beyond_the_memory_names_the_robots_reason() {
    let (mut c, _clock) = paced(FrameConfig::default());
    let prog: Vec<Instruction> = (0..471)
        .map(|k| Instruction::Position(positioning(500.0, 0.0, 300.0 + f64::from(k), Zone::Fine)))
        .collect();
    let err = c.upload_verified(1, &prog).unwrap_err();
    assert!(matches!(err, Error::Robot { .. }), "{err:?}");
    assert_eq!(c.link().peer.machine.program_len(1), 470);
}

/// Measurement of verified stores on the spec's link over 50 seeds (figures in
/// docs/protocol.md §7): `cargo test -p asea-protocol --release --test end_to_end
/// verified_fault_matrix -- --ignored --nocapture`
#[test]
#[ignore]
fn verified_fault_matrix() {
    for (name, setup) in [("sum8", SPEC), ("sum8+nak-malformed", SPEC_NAK_MALFORMED)] {
        for rate in [0.01, 0.10] {
            let mut sum = VerifiedTally::default();
            for seed in 0..50 {
                sum += verified_fault_run(setup, rate, 1000, 300 + seed);
            }
            println!(
                "{name:>20} verified {:>3.0}%: sent {} delivered {} errors {} delivered-not-once {} twice {} foreign {} stores {} damaged-slots {} after-repair {} extra-slots {}",
                rate * 100.0,
                sum.tally.sent,
                sum.tally.delivered,
                sum.tally.errors,
                sum.tally.violations,
                sum.tally.twice,
                sum.tally.foreign,
                sum.stores,
                sum.wrong_slots,
                sum.wrong_after_repair,
                sum.extra_slots
            );
        }
    }
}

/// The spec's check value, refusing malformed telegrams with a NAK.
const SPEC_NAK_MALFORMED: Setup = Setup {
    checksum: Checksum::Sum8,
    malformed: Malformed::Nak,
    ack_window: None,
};

/// Outcome of a verified fault-injection run.
#[derive(Debug, Default)]
struct VerifiedTally {
    tally: Tally,
    /// Store telegrams sent in all (first stores and re-stores).
    stores: usize,
    /// Slots whose content after the run is not their last delivered instruction.
    wrong_slots: usize,
    /// Stores of the closing verification pass.
    repair_stores: usize,
    /// Wrong slots after the closing verification pass.
    wrong_after_repair: usize,
    /// Stored instructions in no slot the run wrote (a corrupted program or instruction number).
    extra_slots: usize,
}

impl std::ops::AddAssign for VerifiedTally {
    fn add_assign(&mut self, t: VerifiedTally) {
        self.tally += t.tally;
        self.stores += t.stores;
        self.wrong_slots += t.wrong_slots;
        self.repair_stores += t.repair_stores;
        self.wrong_after_repair += t.wrong_after_repair;
        self.extra_slots += t.extra_slots;
    }
}

fn verified_fault_run(setup: Setup, rate: f64, telegrams: usize, seed: u64) -> VerifiedTally {
    let (mut c, cfg) = fault_client(setup, rate, seed);
    let mut t = VerifiedTally::default();
    let mut outcomes = Vec::with_capacity(telegrams);
    let mut last_delivered: HashMap<(u8, u16), Instruction> = HashMap::new();
    // Failed stores to a slot after its last delivered one: any of them may have been stored.
    let mut failed_since: HashMap<(u8, u16), Vec<Instruction>> = HashMap::new();
    for k in 0..telegrams {
        let (program, instruction, i) = fault_telegram(k);
        t.tally.sent += 1;
        let result = c.store_verified(program, instruction, &i);
        let ok = result.is_ok();
        if let Ok(stores) = result {
            t.stores += stores;
            t.tally.delivered += 1;
            last_delivered.insert((program, instruction), i);
            failed_since.remove(&(program, instruction));
        } else {
            t.tally.errors += 1;
            failed_since
                .entry((program, instruction))
                .or_default()
                .push(i);
        }
        let cmd = asea_protocol::client::store_command(program, instruction, &i);
        outcomes.push((cmd, ok));
    }
    let machine = &c.link().peer.machine;
    let known = account(&mut t.tally, &machine.executed, &outcomes, &cfg);
    // Read-backs are executed too; count the foreign stores.
    let store_code = outcomes
        .first()
        .map_or(0, |(cmd, _)| cmd.encode(&cfg).unwrap()[1]);
    t.tally.foreign = machine
        .executed
        .iter()
        .filter(|f| f.code == store_code)
        .count()
        - known;
    let wrong = |machine: &asea_protocol::sim::Machine| {
        last_delivered
            .iter()
            .filter(|((program, instruction), want)| {
                let got = machine.instruction(*program, *instruction);
                let later_failed = failed_since
                    .get(&(*program, *instruction))
                    .is_some_and(|v| v.iter().any(|i| Some(i) == got));
                got != Some(*want) && !later_failed
            })
            .map(|(slot, want)| (*slot, *want))
            .collect::<Vec<_>>()
    };
    let damaged = wrong(machine);
    t.wrong_slots = damaged.len();
    // The closing pass of a verified upload (`Client::verify`): a corrupted twin that the sum let
    // through into another, already confirmed slot is found and overwritten. On a noisy link a
    // pass can fail; the host runs it again.
    for ((program, instruction), want) in damaged {
        for _ in 0..5 {
            if let Ok(stores) = c.ensure_stored(program, instruction, &want) {
                t.repair_stores += stores;
                break;
            }
        }
    }
    let machine = &c.link().peer.machine;
    t.wrong_after_repair = wrong(machine).len();
    let stored: usize = (1..=255u8).map(|p| machine.program_len(p)).sum();
    t.extra_slots = stored.saturating_sub(last_delivered.len());
    t
}

/// Read-backs under 10 % byte errors in both directions (reverse sessions, request retries): with
/// the strong link every answer is the stored instruction or an error.
#[test]
fn read_backs_under_faults_are_true_or_errors() {
    let setup = STRONG;
    let cfg = FrameConfig {
        checksum: setup.checksum,
        ..FrameConfig::default()
    };
    let timers = Timers {
        t_ack_window: setup.ack_window,
        ..Timers::default()
    };
    let clock = VirtualClock::new();
    let mut robot = Robot::new(cfg, timers, MotionParams::default());
    let prog = program_50();
    for (n, i) in (1u16..).zip(&prog) {
        let f = asea_protocol::client::store_command(5, n, i).to_frame();
        robot.machine.execute(&f, 0.0);
    }
    let wire = Paced::new(clock.clone(), 9600, robot).with_faults(
        Faults::new(FaultRates::uniform(0.10), 11),
        Faults::new(FaultRates::uniform(0.10), 12),
    );
    let mut c = Client::with_clock(
        wire,
        clock,
        ClientConfig {
            frame: cfg,
            timers,
            ..ClientConfig::default()
        },
    );
    let (mut ok, mut err) = (0, 0);
    for k in 0..200u16 {
        let n = k % 50 + 1;
        match c.read_back(5, n) {
            Ok(got) => {
                assert_eq!(
                    got.as_ref(),
                    prog.get(usize::from(n - 1)),
                    "instruction {n}"
                );
                ok += 1;
            }
            Err(_) => err += 1,
        }
    }
    eprintln!("read-backs at 10 %: {ok} answered, {err} errors");
    assert!(ok > 50, "{ok} answered, {err} errors");
}

/// Uploading 470 positioning instructions at 9600 baud takes the wire time of every byte both
/// ways plus `T_GAP` between sessions, and no more: the host adds no idle time of its own
/// (figure in docs/benchmarks.md, "Robot link").
#[test]
fn upload_of_470_instructions_adds_no_idle_time() {
    let (mut c, clock) = paced(FrameConfig::default());
    let prog: Vec<Instruction> = (0..470)
        .map(|k| Instruction::Position(positioning(600.0 + f64::from(k), 0.0, 500.0, Zone::Medium)))
        .collect();
    let t0 = clock.now();
    for (n, i) in (1u16..).zip(&prog) {
        c.store(4, n, i).unwrap();
    }
    let elapsed = (clock.now() - t0).as_secs_f64();
    // Host: ENQ, telegram (25 bytes), EOT; robot: ACK, ACK; per session, sessions back to back
    // with T_GAP between the end of one EOT and the next ENQ.
    let byte_s = 10.0 / 9600.0;
    let per_session_bytes = 1.0 + 25.0 + 1.0 + 1.0 + 1.0;
    let sessions = prog.len() as f64;
    let gaps = (sessions - 1.0) * asea_protocol::session::T_GAP.as_secs_f64();
    let reference = sessions * per_session_bytes * byte_s + gaps;
    let ratio = elapsed / reference;
    eprintln!("upload 470: {elapsed:.3} s, wire + gaps {reference:.3} s, ratio {ratio:.4}");
    assert!(ratio <= 1.02, "ratio {ratio}");
    assert_eq!(c.link().peer.machine.program_len(4), 470);
    assert_eq!(c.stats().frames_sent, 470);
}

/// Pseudo-terminal tests run one at a time.
static PTY: Mutex<()> = Mutex::new(());

#[cfg(unix)]
#[test]
fn program_over_a_pseudo_terminal() {
    use asea_protocol::link::SerialLink;
    let _guard = PTY.lock().unwrap_or_else(|e| e.into_inner());
    let (master, slave) = SerialLink::pty_pair().expect("pty pair");
    // Fast arm constants so that the 47 moves run in a fraction of a second of real time.
    let params = MotionParams {
        accel_mm_s2: 1.0e6,
        overhead_s: [0.0; 3],
        floor_s: [0.002; 3],
        flying_floor_s: [0.0; 3],
        home_s: 0.01,
        ..MotionParams::default()
    };
    let robot = Arc::new(Mutex::new(Robot::new(
        FrameConfig::default(),
        Timers::default(),
        params,
    )));
    let stop = Arc::new(AtomicBool::new(false));
    let server = {
        let (robot, stop) = (robot.clone(), stop.clone());
        std::thread::spawn(move || serve(master, &robot, &WallClock::new(), &stop))
    };
    let mut c = Client::new(slave, ClientConfig::default());
    // A narrow zig-zag at full speed, so that the run takes a fraction of a second.
    let prog = program_50_zigzag(5.0);
    c.set_base_speed(Speed::from_value("base", 7.9).unwrap())
        .unwrap();
    c.set_max_speed(Speed::from_value("max", 7.9).unwrap())
        .unwrap();
    if let Err(e) = c.upload(9, &prog) {
        panic!("upload: {e}; {:?}", c.stats());
    }
    for (n, want) in (1u16..).zip(&prog) {
        assert_eq!(c.read_back(9, n).unwrap().as_ref(), Some(want));
    }
    c.operate().unwrap();
    c.sync_home().unwrap();
    std::thread::sleep(Duration::from_millis(50));
    c.run_program(9).unwrap();
    let io = robot.lock().unwrap().machine.io().clone();
    let clock = WallClock::new();
    while !io.output(IN_POSITION_OUTPUT) {
        assert!(
            clock.now() < Duration::from_secs(5),
            "program did not reach its end"
        );
        std::thread::sleep(Duration::from_millis(10));
    }
    io.set_input(1, true);
    std::thread::sleep(Duration::from_millis(20));
    let s = c.check_status().unwrap();
    assert_eq!(s.state, asea_protocol::State::Idle);
    assert_eq!(c.position().unwrap().xyz_mm(), [900.0, -5.0, 630.0]);
    stop.store(true, Ordering::Relaxed);
    server.join().unwrap().unwrap();
}

/// CRC-16 with and without the ACK window, 50 seeds × 1 000 telegrams at 10 % (figures in
/// docs/protocol.md):
/// `cargo test -p asea-protocol --release --test end_to_end fault_long_run -- --ignored --nocapture`
#[test]
#[ignore]
fn fault_long_run() {
    for (name, setup) in [
        ("crc16+window", STRONG),
        (
            "crc16",
            Setup {
                ack_window: None,
                ..STRONG
            },
        ),
    ] {
        let mut sum = Tally::default();
        for seed in 1000..1050 {
            sum += fault_run(setup, 0.10, 1000, seed);
        }
        println!("{name} 10 %: {sum:?}");
        assert_eq!(sum.twice, 0);
    }
}

/// Measurement over several seeds and configurations (figures in docs/protocol.md):
/// `cargo test -p asea-protocol --release --test end_to_end fault_matrix -- --ignored --nocapture`
#[test]
#[ignore]
fn fault_matrix() {
    let with = |checksum, malformed, ack_window| Setup {
        checksum,
        malformed,
        ack_window,
    };
    let w = Some(Duration::from_millis(10));
    for (name, setup) in [
        ("sum8", SPEC),
        ("sum8+nak-malformed", SPEC_NAK_MALFORMED),
        (
            "sum8+nak-malformed+window",
            with(Checksum::Sum8, Malformed::Nak, w),
        ),
        (
            "crc16",
            with(Checksum::Crc16, Malformed::AckWithError, None),
        ),
        ("crc16+window", STRONG),
    ] {
        for rate in [0.01, 0.10] {
            let mut sum = Tally::default();
            for seed in 0..10 {
                sum += fault_run(setup, rate, 1000, 100 + seed);
            }
            println!(
                "{name:>26} {:>4.0}%: sent {} delivered {} errors {} delivered-not-once {} twice {} foreign {}",
                rate * 100.0,
                sum.sent,
                sum.delivered,
                sum.errors,
                sum.violations,
                sum.twice,
                sum.foreign
            );
        }
    }
}

#[test]
fn a_missing_serial_port_is_a_typed_error() {
    let e = Client::open("/dev/windcell-no-such-port", ClientConfig::default()).unwrap_err();
    assert!(matches!(e, Error::Serial(_)), "{e}");
}

/// What [`Mangle`] does to the robot's first status replies.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum How {
    /// The reply is lost.
    Drop,
    /// The reply arrives with `last_error` zeroed and a check value that matches (a corruption a
    /// one-byte sum cannot see).
    ForgeNoError,
    /// The reply arrives twice.
    Duplicate,
}

/// The robot with its first `left` status replies mangled on the way to the host.
#[derive(Debug)]
struct Mangle {
    robot: Robot,
    how: How,
    left: usize,
}

impl Peer for Mangle {
    fn receive(&mut self, bytes: &[u8], now: Duration) {
        self.robot.receive(bytes, now);
    }
    fn poll(&mut self, now: Duration) {
        self.robot.poll(now);
    }
    fn deadline(&self) -> Option<Duration> {
        self.robot.deadline()
    }
    fn take_output(&mut self) -> Vec<u8> {
        let mut out = self.robot.take_output();
        let len = asea_protocol::command::STATUS_REPLY_LEN;
        let head = [0x02, 0x86, len as u8, 0];
        if self.left > 0
            && let Some(i) = out.windows(4).position(|w| w == head)
        {
            let end = i + 3 + len + 2;
            match self.how {
                How::Drop => {
                    out.drain(i..end);
                }
                How::ForgeNoError => {
                    out[i + 3 + 6] = 0;
                    let sum = out[i + 1..end - 1]
                        .iter()
                        .fold(0u8, |a, b| a.wrapping_add(*b));
                    out[end - 1] = sum;
                }
                How::Duplicate => {
                    let frame = out[i..end].to_vec();
                    out.splice(end..end, frame);
                }
            }
            self.left -= 1;
        }
        out
    }
}

/// The robot latches an error until the host acknowledges it by its sequence number: with the
/// status reply dropped, forged to show no error (twice in a row, which even two agreeing reads
/// accept), or duplicated, the error is reported exactly once and then acknowledged; never lost.
#[test]
fn a_robot_error_survives_a_lost_forged_or_duplicated_status_reply() {
    for (how, left) in [
        (How::Drop, 1),
        (How::Drop, 3),
        (How::ForgeNoError, 1),
        (How::ForgeNoError, 2),
        (How::Duplicate, 2),
    ] {
        let clock = VirtualClock::new();
        let robot = Robot::default();
        let wire = Paced::new(
            clock.clone(),
            9600,
            Mangle {
                robot,
                how,
                left: 0,
            },
        );
        let mut c = Client::with_clock(wire, clock, ClientConfig::default());
        // A clean start, then error 5 (no such program) from a plain send.
        assert_eq!(c.check_status().unwrap().last_error, 0);
        c.send(&Command::RunProgram { program: 9 }).unwrap();
        assert_eq!(c.link().peer.robot.machine.last_error(), 5);
        c.link_mut().peer.left = left;
        let mut reported = Vec::new();
        for _ in 0..4 {
            match c.check_status() {
                Ok(_) => {}
                Err(Error::Robot { code, count, .. }) => reported.push((code, count)),
                Err(e) => panic!("{how:?} ×{left}: {e}"),
            }
        }
        assert_eq!(reported, [(5, 1)], "{how:?} ×{left}");
        let m = &c.link().peer.robot.machine;
        assert_eq!(m.last_error(), 0, "{how:?} ×{left}: not acknowledged");
        assert_eq!(c.errors_seen(), m.errors_raised());
    }
}

/// A blocked exchange (a long upload) is cancelled from another thread within one poll period;
/// the link is then free for STOP, which goes through while the token is still set.
#[test]
fn an_upload_is_cancelled_from_another_thread_and_stop_still_goes_through() {
    use asea_protocol::client::{Cancel, POLL_PERIOD};
    use asea_protocol::link::Pipe;
    let (host_end, robot_end) = Pipe::pair();
    let robot = Arc::new(Mutex::new(Robot::default()));
    let halt = Arc::new(AtomicBool::new(false));
    let server = {
        let (robot, halt) = (robot.clone(), halt.clone());
        std::thread::spawn(move || serve(robot_end, &robot, &WallClock::new(), &halt))
    };
    let c = Client::new(host_end, ClientConfig::default());
    let token: Cancel = c.cancel_token();
    let prog: Vec<Instruction> = (0..470)
        .map(|k| Instruction::Position(positioning(600.0 + f64::from(k), 0.0, 500.0, Zone::Fine)))
        .collect();
    let upload = std::thread::spawn(move || {
        let mut c = c;
        let r = c.upload_verified(1, &prog);
        (c, r)
    });
    std::thread::sleep(Duration::from_millis(300));
    let t = std::time::Instant::now();
    token.cancel();
    let (mut c, r) = upload.join().unwrap();
    let took = t.elapsed();
    assert!(matches!(r, Err(Error::Cancelled)), "{r:?}");
    // No read waits longer than the poll period; the rest is the threads' scheduling (the
    // join included), allowed 20 ms on a loaded machine.
    assert!(
        took <= POLL_PERIOD + Duration::from_millis(20),
        "cancel took {took:?}"
    );
    let stored = robot.lock().unwrap().machine.program_len(1);
    assert!(stored > 0 && stored < 470, "{stored} stored");
    let s = c.stop().unwrap();
    assert_eq!(s.state, asea_protocol::State::Stopped);
    assert!(matches!(c.check_status(), Err(Error::Cancelled)));
    token.reset();
    assert_eq!(
        c.check_status().unwrap().state,
        asea_protocol::State::Stopped
    );
    halt.store(true, Ordering::Relaxed);
    server.join().unwrap().unwrap();
}
