//! The simulated cell (seed 001 §4.1, App. D): the robot-computer simulator, the X-language
//! indexer simulator and the opto-isolated sync lines on exactly one clock.
//!
//! Wiring, as in Figure D.1: the robot's output [`IN_POSITION_OUTPUT`] drives the PC's
//! "in position" input; the PC's start output drives the robot's input [`START_INPUT`] and the
//! indexer's trigger input 1 together. Each line passes an opto-isolator of `opto_delay_s`
//! ([`mandrel_drive::sync::OPTO_DELAY_S`] by default). The robot's link and the indexer's link are
//! serial lines at `baud`, paced in the same virtual time.
//!
//! Time is one [`VirtualClock`]: it moves only when the coordinator waits (a link read, a
//! [`Timebase::sleep`]), and then both simulators and the lines run to the new time, polled at
//! each event that can change the cell: a move's end on either device, a reset's end, a byte's
//! arrival, a line edge's arrival through its opto-isolator, a link timer. Between events each
//! simulator's motion is in closed form, so nothing is lost by not looking (a test compares a
//! long sleep with polling every [`TICK`]). While a [`Trace`] or an [`Observer`] samples the
//! motion the cell is also polled every [`TICK`]. An hour of winding runs in a fraction of a
//! millisecond. With [`SimCellConfig::speed`] the clock is paced: each step waits for the wall
//! clock, so the cell runs at the real cell's speed (or a chosen multiple) for a viewer.
//!
//! Both simulators can log every instruction they execute as JSON lines (docs/file-formats.md,
//! "Simulator logs") with the cell's clock time.

pub mod wiretap;

use std::collections::VecDeque;
use std::io::{self, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

use asea_protocol::command::{IN_POSITION_OUTPUT, START_INPUT};
use asea_protocol::link::{Paced, Peer};
use asea_protocol::sim::{EyePose, MotionParams, Robot};
use asea_protocol::{FrameConfig, Instruction, State, Timers};
use mandrel_drive::sim::xlang::Card;
use mandrel_drive::sim::{Frontend, Machine as IndexerMachine};
use mandrel_drive::sync::{OPTO_DELAY_S, Wire};
use mandrel_drive::{Drive, sim::machine::PULL_IN_SPS};
use paths::link::{Clock as _, Link, VirtualClock};

use crate::record::linktap::{LinkTap, RecordSlot, SyncTap};
use crate::run::device::{DeviceError, DeviceResult, SyncLines, Timebase};

/// How often the cell polls both simulators while time passes (virtual seconds).
pub const TICK: Duration = Duration::from_millis(5);
/// The indexer card's address on its link.
pub const INDEXER_ADDRESS: u8 = 1;

/// How the simulated cell is built.
#[derive(Debug, Clone)]
pub struct SimCellConfig {
    /// Serial speed of both links, baud.
    pub baud: u32,
    /// Opto-isolator delay of every sync line, s.
    pub opto_delay_s: f64,
    /// The mandrel drive (gearing, pulse limit).
    pub drive: Drive,
    /// Robot motion constants.
    pub robot: MotionParams,
    /// The five-axis arm the simulated robot checks every pose against (error 9 for a pose it
    /// cannot take: a wrist yaw, a joint outside its range).
    pub arm: paths::robot::Arm,
    /// `None`: the cell's clock runs as fast as the coordinator waits on it (a batch in
    /// milliseconds); `Some(k)`: it keeps in step with the wall clock at `k` cell seconds per wall
    /// second (1: the speed of the real cell; [`paths::link::VirtualClock::paced`]), so that a
    /// live viewer can watch it.
    pub speed: Option<f64>,
}

/// The speed factors a paced simulated cell accepts (`windcell run --speed`): from ten times
/// slower to a thousand times faster than the real cell, so that no run is endless.
pub const SPEED_RANGE: (f64, f64) = (0.1, 1000.0);

impl Default for SimCellConfig {
    fn default() -> Self {
        SimCellConfig {
            baud: 9600,
            opto_delay_s: OPTO_DELAY_S,
            drive: Drive::default(),
            robot: MotionParams::default(),
            arm: paths::robot::Arm::default(),
            speed: None,
        }
    }
}

/// One executed instruction or move, as the simulators log it.
#[derive(Debug, Clone, PartialEq)]
pub enum LogRecord {
    /// The robot finished a move: an immediate move (`program` 0) or instruction `instruction`
    /// of a stored program.
    Robot {
        /// Cell clock, s.
        t_s: f64,
        /// Program number, 0 for an immediate move.
        program: u8,
        /// Instruction number, 0 for an immediate move.
        instruction: u16,
        /// The target position, mm.
        target_mm: [f64; 3],
        /// False when STOP ended it before the target.
        completed: bool,
    },
    /// The indexer finished a move.
    Indexer {
        /// Cell clock, s.
        t_s: f64,
        /// Steps turned.
        steps: i64,
        /// False when a stop command ended it.
        completed: bool,
    },
}

impl LogRecord {
    /// The record as one JSON line (without the newline).
    pub fn json(&self) -> String {
        match self {
            LogRecord::Robot {
                t_s,
                program,
                instruction,
                target_mm,
                completed,
            } => serde_json::json!({
                "device": "robot", "t_s": t_s, "program": program,
                "instruction": instruction, "target_mm": target_mm, "completed": completed,
            })
            .to_string(),
            LogRecord::Indexer {
                t_s,
                steps,
                completed,
            } => serde_json::json!({
                "device": "indexer", "t_s": t_s, "steps": steps, "completed": completed,
            })
            .to_string(),
        }
    }
}

/// Watches a robot computer and reports each move as it finishes (the simulators' logs).
#[derive(Debug, Default)]
pub struct RobotWatch {
    running: Option<(u8, u16)>,
    immediate: Option<[f64; 3]>,
    executed_seen: usize,
    /// State, program, instruction and executed telegrams at the last look: while they stay the
    /// same nothing new can have finished.
    last_seen: Option<(State, u8, u16, u16, usize)>,
}

fn target_of(m: &asea_protocol::sim::Machine, program: u8, instruction: u16) -> [f64; 3] {
    match m.instruction(program, instruction) {
        Some(Instruction::Position(p)) => p.pose.xyz_mm(),
        _ => [f64::NAN; 3],
    }
}

impl RobotWatch {
    /// The records of what finished since the last call, at cell time `now`.
    pub fn watch(&mut self, machine: &asea_protocol::sim::Machine, now: f64) -> Vec<LogRecord> {
        let mut out = Vec::new();
        let m = machine;
        let status = m.status();
        let seen = (
            status.state,
            status.program,
            status.instruction,
            status.executed,
            m.executed.len(),
        );
        if self.last_seen == Some(seen) {
            return out;
        }
        self.last_seen = Some(seen);
        let running = (status.state == State::Running && status.program != 0)
            .then_some((status.program, status.instruction));
        // A newly executed MOVE_IMMEDIATE or STOP telegram.
        let new: Vec<_> = m.executed.get(self.executed_seen..).unwrap_or(&[]).to_vec();
        self.executed_seen = m.executed.len();
        for f in new {
            match asea_protocol::Command::from_frame(&f) {
                Ok(asea_protocol::Command::Stop) => {
                    if let Some(target) = self.immediate.take() {
                        out.push(LogRecord::Robot {
                            t_s: now,
                            program: 0,
                            instruction: 0,
                            target_mm: target,
                            completed: false,
                        });
                    }
                    if let Some((p, i)) = self.running.take() {
                        let target = target_of(m, p, i);
                        out.push(LogRecord::Robot {
                            t_s: now,
                            program: p,
                            instruction: i,
                            target_mm: target,
                            completed: false,
                        });
                    }
                }
                Ok(asea_protocol::Command::MoveImmediate(_))
                    if m.status().state == State::Running =>
                {
                    self.immediate = m
                        .trajectory()
                        .and_then(|t| t.moves.last())
                        .map(|mv| mv.target_mm);
                }
                _ => {}
            }
        }
        let status = m.status();
        if self.immediate.is_some() && status.state != State::Running {
            let target = self.immediate.take().unwrap_or_default();
            out.push(LogRecord::Robot {
                t_s: now,
                program: 0,
                instruction: 0,
                target_mm: target,
                completed: true,
            });
        }
        if self.running != running {
            if let Some((p, i)) = self.running {
                // Every positioning from the last one seen up to (not including) the current.
                let until = match running {
                    Some((q, j)) if q == p => j,
                    _ => u16::MAX,
                };
                let mut n = i;
                while n < until {
                    match m.instruction(p, n) {
                        Some(Instruction::Position(_)) => {
                            let target = target_of(m, p, n);
                            out.push(LogRecord::Robot {
                                t_s: now,
                                program: p,
                                instruction: n,
                                target_mm: target,
                                completed: true,
                            });
                        }
                        Some(Instruction::Control(_)) => {}
                        None => break,
                    }
                    n += 1;
                }
            }
            self.running = running;
        }
        out
    }
}

/// The devices of the cell, driven as the far end of the robot's paced wire.
#[derive(Debug)]
pub struct CellPeer {
    /// The robot computer.
    pub robot: Robot,
    /// The indexer card.
    pub card: Card,
    clock: VirtualClock,
    start: Wire,
    in_position: Wire,
    /// The level last driven on `in_position`.
    in_position_driven: Option<bool>,
    delay: Duration,
    byte_time: Duration,
    to_card: VecDeque<(Duration, u8)>,
    to_card_free: Duration,
    from_card: VecDeque<(Duration, u8)>,
    from_card_free: Duration,
    last_poll: Duration,
    edge_due: Option<Duration>,
    // Logging state.
    robot_watch: RobotWatch,
    card_token: Vec<u8>,
    card_moving: bool,
    card_stop_sent: bool,
    /// Every logged record, in order.
    pub log: Vec<LogRecord>,
    /// Fault injection: the robot computer stops answering (its output is lost).
    pub robot_silent: bool,
    /// Fault injection: a NAK storm, every ACK the robot computer sends arrives as NAK (the host
    /// sees every ENQ and telegram refused).
    pub robot_nak_storm: bool,
    log_file: Option<io::BufWriter<std::fs::File>>,
    /// When set, where the eye and the mandrel are over time (the placement prediction's input).
    pub trace: Option<Trace>,
    /// When set, told where the eye and the mandrel are at every poll (recording, live view).
    pub observer: Option<Observer>,
}

/// What an [`Observer`] is told at each poll of the cell.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Observation {
    /// The cell time, s.
    pub t_s: f64,
    /// The eye position (cell frame, mm) and orientation (w, x, y, z).
    pub eye: EyePose,
    /// The point the stored program's move under way is commanded to (its instruction's pose),
    /// if a program moves the arm (a MOVE_IMMEDIATE's point is in its telegram).
    pub target: Option<EyePose>,
    /// The mandrel's drive angle, rad: where the motor really is.
    pub drive_rad: f64,
    /// The drive angle the indexer's step counter commands, rad (parts from `drive_rad` by the
    /// steps lost).
    pub commanded_drive_rad: f64,
}

/// Told at each poll of the cell.
pub type ObserverFn = Box<dyn FnMut(&Observation) + Send>;

/// Watches the devices' true motion as the cell's time passes.
pub struct Observer(pub ObserverFn);

impl std::fmt::Debug for Observer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Observer")
    }
}

/// The devices' true motion over the cell's time, as the prediction of placement error reads it
/// (`cell::predict`): the eye sampled every [`TRACE_EYE_STEP_S`] from the robot computer's own
/// trajectory, the mandrel angle at every poll of the cell (at most [`TICK`] apart).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Trace {
    /// `(t_s, eye)`: the eye position, cell frame, mm.
    pub eye_mm: Vec<(f64, [f64; 3])>,
    /// `(t_s, angle)`: the mandrel's drive angle from the indexer's zero (motor steps through
    /// the belt, lost steps included), rad.
    pub drive_rad: Vec<(f64, f64)>,
}

/// Spacing of the eye samples of a [`Trace`], s (1 ms: a millimetre-zone corner is passed in
/// several samples at the arm's speeds in App. B).
pub const TRACE_EYE_STEP_S: f64 = 1e-3;

impl Trace {
    fn sample(&mut self, robot: &asea_protocol::sim::Machine, card: &IndexerMachine, now: f64) {
        let last = self.eye_mm.last().map_or(now - TRACE_EYE_STEP_S, |s| s.0);
        let pose_at = |t: f64| {
            robot
                .trajectory()
                .map_or(robot.pose().xyz_mm, |tr| tr.pose_at(t).xyz_mm)
        };
        let mut t = last + TRACE_EYE_STEP_S;
        while t < now {
            self.eye_mm.push((t, pose_at(t)));
            t += TRACE_EYE_STEP_S;
        }
        if now > last {
            self.eye_mm.push((now, pose_at(now)));
        }
        if self.drive_rad.last().is_none_or(|s| now > s.0) {
            self.drive_rad.push((now, card.mandrel_angle_rad()));
        }
    }
}

impl CellPeer {
    fn now_s(&self) -> f64 {
        self.clock.now_s()
    }

    fn wire_lines(&mut self) {
        let io = self.robot.machine.io();
        let level = io.output(IN_POSITION_OUTPUT);
        // The wire keeps edges only: drive it when the output changed.
        if self.in_position_driven != Some(level) && self.in_position.drive(level).is_ok() {
            self.in_position_driven = Some(level);
        }
        io.set_input(START_INPUT, self.start.received().unwrap_or(false));
    }

    fn record(&mut self, r: LogRecord) {
        if let Some(f) = self.log_file.as_mut() {
            let _ = writeln!(f, "{}", r.json());
            let _ = f.flush();
        }
        self.log.push(r);
    }

    /// Logs robot instructions as they finish.
    fn watch_robot(&mut self) {
        let now = self.now_s();
        for r in self.robot_watch.watch(&self.robot.machine, now) {
            self.record(r);
        }
    }

    /// Logs indexer moves as they finish.
    fn watch_card(&mut self) {
        let moving = self.card.machine().is_moving();
        if self.card_moving && !moving {
            let steps = self.card.machine().steps_since_move_start();
            let completed = !self.card_stop_sent;
            let t = self.now_s();
            self.record(LogRecord::Indexer {
                t_s: t,
                steps,
                completed,
            });
        }
        if !self.card_moving && moving {
            self.card_stop_sent = false;
        }
        self.card_moving = moving;
    }

    fn card_bytes(&mut self, bytes: &[u8]) {
        for &b in bytes {
            if b == b'\r' {
                let token = std::mem::take(&mut self.card_token);
                let cmd = token.trim_ascii_start();
                let cmd: Vec<u8> = cmd.iter().copied().skip_while(u8::is_ascii_digit).collect();
                if (cmd == b"S" || cmd == b"K") && self.card_moving {
                    self.card_stop_sent = true;
                }
            } else if self.card_token.len() < 64 {
                self.card_token.push(b);
            }
        }
        let now = self.now_s();
        self.card.receive(bytes, now);
    }

    fn run_card(&mut self, now: Duration) {
        // Host bytes that have arrived.
        let mut arrived = Vec::new();
        while let Some(&(t, b)) = self.to_card.front() {
            if t > now {
                break;
            }
            arrived.push(b);
            self.to_card.pop_front();
        }
        if !arrived.is_empty() {
            self.card_bytes(&arrived);
        }
        self.card.poll(now.as_secs_f64());
        self.watch_card();
        let out = self.card.take_output();
        let mut t = self.from_card_free.max(now);
        for b in out {
            t += self.byte_time;
            self.from_card.push_back((t, b));
        }
        self.from_card_free = t;
    }
}

impl Peer for CellPeer {
    fn receive(&mut self, bytes: &[u8], now: Duration) {
        self.robot.receive(bytes, now);
        self.wire_lines();
        self.watch_robot();
    }

    fn poll(&mut self, now: Duration) {
        self.last_poll = now;
        if self.edge_due.is_some_and(|t| t <= now) {
            self.edge_due = None;
        }
        self.wire_lines();
        self.robot.poll(now);
        self.wire_lines();
        self.watch_robot();
        self.run_card(now);
        if let Some(trace) = self.trace.as_mut() {
            trace.sample(&self.robot.machine, self.card.machine(), now.as_secs_f64());
        }
        if let Some(Observer(f)) = self.observer.as_mut() {
            let t_s = now.as_secs_f64();
            let m = &self.robot.machine;
            let target = m
                .trajectory()
                .and_then(|traj| traj.move_at(t_s))
                .filter(|mv| mv.instruction != 0)
                .map(|mv| mv.target());
            f(&Observation {
                t_s,
                eye: m.pose(),
                target,
                drive_rad: self.card.machine().mandrel_angle_rad(),
                commanded_drive_rad: self.card.machine().commanded_angle_rad(),
            });
        }
    }

    fn take_output(&mut self) -> Vec<u8> {
        let mut out = self.robot.take_output();
        if self.robot_silent {
            return Vec::new();
        }
        if self.robot_nak_storm {
            for b in &mut out {
                if *b == asea_protocol::frame::ACK {
                    *b = asea_protocol::frame::NAK;
                }
            }
        }
        out
    }

    /// The next time anything in the cell can change on its own: the robot link's timers, the
    /// robot's and the indexer's next mechanical events (a move's end, a reset's end; every
    /// [`TICK`] while the indexer ramps towards a rate its translator cannot pass), a byte
    /// reaching the card, an edge crossing an opto-isolator. While a [`Trace`] or an
    /// [`Observer`] watches the motion, also every [`TICK`] (they sample the cell at each poll).
    /// Between these events nothing is polled: an hour of steady winding is a few thousand polls.
    fn deadline(&self) -> Option<Duration> {
        let mut d: Option<Duration> = None;
        let mut at = |t: Duration| d = Some(d.map_or(t, |x: Duration| x.min(t)));
        if self.trace.is_some() || self.observer.is_some() {
            at(self.last_poll + TICK);
        }
        if let Some(r) = self.robot.deadline() {
            at(r);
        }
        // A mechanical event the last poll did not reach (rounding of the clock) is polled
        // again a microsecond later, never in a loop at one instant.
        let mechanical = |t_s: f64| {
            Duration::try_from_secs_f64(t_s.max(0.0))
                .unwrap_or(Duration::MAX)
                .max(self.last_poll + Duration::from_micros(1))
        };
        if let Some(t) = self.robot.machine.next_event_s() {
            at(mechanical(t));
        }
        if let Some(t) = self.card.next_event_s(TICK.as_secs_f64()) {
            at(mechanical(t));
        }
        if let Some(&(t, _)) = self.to_card.front() {
            at(t);
        }
        if let Some(e) = self.edge_due {
            at(e);
        }
        d
    }
}

type Shared = Arc<Mutex<Paced<CellPeer>>>;

fn lock(cell: &Shared) -> io::Result<MutexGuard<'_, Paced<CellPeer>>> {
    cell.lock()
        .map_err(|_| io::Error::other("simulated cell lock poisoned"))
}

/// The simulated cell: both simulators and the sync lines on one virtual clock.
#[derive(Debug, Clone)]
pub struct SimCell {
    shared: Shared,
    clock: VirtualClock,
    estop: Arc<AtomicBool>,
}

impl SimCell {
    /// A powered-up cell: robot in standby, not homed, at home; indexer at rest at 0.
    pub fn new(cfg: &SimCellConfig) -> Self {
        let clock = cfg.speed.and_then(VirtualClock::paced).unwrap_or_default();
        let cell_clock: Arc<dyn paths::link::Clock> = Arc::new(clock.clone());
        let start = Wire::new(cell_clock.clone(), cfg.opto_delay_s);
        let in_position = Wire::new(cell_clock, cfg.opto_delay_s);
        let card = Card::new(IndexerMachine::new(cfg.drive, PULL_IN_SPS), INDEXER_ADDRESS)
            .with_trigger(Box::new(start.clone()));
        let mut robot = Robot::new(FrameConfig::default(), Timers::default(), cfg.robot);
        robot.machine = std::mem::take(&mut robot.machine)
            .with_kinematics(Arc::new(asea_protocol::sim::ArmModel { arm: cfg.arm }));
        let estop = Arc::new(AtomicBool::new(false));
        let byte_time = Duration::from_secs_f64(10.0 / f64::from(cfg.baud.max(1)));
        let peer = CellPeer {
            robot,
            card,
            clock: clock.clone(),
            start,
            in_position,
            delay: Duration::from_secs_f64(cfg.opto_delay_s.max(0.0)),
            byte_time,
            to_card: VecDeque::new(),
            to_card_free: Duration::ZERO,
            from_card: VecDeque::new(),
            from_card_free: Duration::ZERO,
            last_poll: Duration::ZERO,
            edge_due: None,
            robot_watch: RobotWatch::default(),
            card_token: Vec::new(),
            card_moving: false,
            card_stop_sent: false,
            in_position_driven: None,
            log: Vec::new(),
            robot_silent: false,
            robot_nak_storm: false,
            log_file: None,
            trace: None,
            observer: None,
        };
        SimCell {
            shared: Arc::new(Mutex::new(Paced::new(clock.clone(), cfg.baud, peer))),
            clock,
            estop,
        }
    }

    /// Also writes every log record to `file` as a JSON line.
    pub fn log_to(&self, file: std::fs::File) -> io::Result<()> {
        lock(&self.shared)?.peer.log_file = Some(io::BufWriter::new(file));
        Ok(())
    }

    /// The cell's clock.
    pub fn clock(&self) -> &VirtualClock {
        &self.clock
    }

    /// The robot's link (host side).
    pub fn robot_link(&self) -> SimRobotLink {
        SimRobotLink(self.shared.clone())
    }

    /// The indexer's link (host side).
    pub fn indexer_link(&self) -> SimIndexerLink {
        SimIndexerLink(self.shared.clone())
    }

    /// The PC's side of the sync lines.
    pub fn sync_lines(&self) -> SimSync {
        SimSync {
            shared: self.shared.clone(),
            estop: self.estop.clone(),
        }
    }

    /// The e-stop button.
    pub fn estop_button(&self) -> Arc<AtomicBool> {
        self.estop.clone()
    }

    /// The coordinator's devices on this cell: the robot client and the X-language client on the
    /// cell's links, the PC side of the sync lines, the cell's time.
    pub fn devices(&self, drive: Drive) -> crate::run::coordinator::Devices {
        self.recorded_devices(drive, &RecordSlot::default())
    }

    /// [`SimCell::devices`] with taps on both links and the sync lines that write to the
    /// recorder `slot` will hold ([`crate::record::linktap`]).
    pub fn recorded_devices(
        &self,
        drive: Drive,
        slot: &RecordSlot,
    ) -> crate::run::coordinator::Devices {
        let time: Arc<dyn Timebase> = Arc::new(self.timebase());
        let client_cfg = asea_protocol::ClientConfig::default();
        let robot_link = LinkTap::robot(
            self.robot_link(),
            client_cfg.frame,
            slot.clone(),
            time.clone(),
        );
        let client = asea_protocol::Client::with_clock(robot_link, self.clock.clone(), client_cfg);
        // The X client runs on the cell's clock, as the robot's does: its attach polls the card
        // until at rest before it asks the position (`PR`, answered only when the card's buffer
        // reaches it), so no reply waits on a move of the run before.
        let x = mandrel_drive::XClient::with_clock(
            LinkTap::indexer(self.indexer_link(), slot.clone(), time.clone()),
            self.clock.clone(),
            mandrel_drive::IndexerConfig {
                drive,
                address: INDEXER_ADDRESS,
                start_velocity_command: true,
                device_id: false,
                ..mandrel_drive::IndexerConfig::default()
            },
        );
        crate::run::coordinator::Devices {
            robot: Box::new(crate::run::device::ProtocolRobot::new(client)),
            mandrel: Box::new(crate::run::device::XIndexer::new(
                x,
                crate::run::transfer::IndexerSetup {
                    drive,
                    start_velocity_command: true,
                },
            )),
            sync: Box::new(SyncTap::new(
                Box::new(self.sync_lines()),
                slot.clone(),
                time.clone(),
            )),
            time,
        }
    }

    /// The cell's time as the coordinator waits in it.
    pub fn timebase(&self) -> SimTime {
        SimTime(self.shared.clone(), self.clock.clone())
    }

    /// Looks at (or changes) the devices: tests and the log.
    pub fn with<R>(&self, f: impl FnOnce(&mut CellPeer) -> R) -> io::Result<R> {
        Ok(f(&mut lock(&self.shared)?.peer))
    }
}

/// The robot's link to the simulated cell.
#[derive(Debug, Clone)]
pub struct SimRobotLink(Shared);

impl Link for SimRobotLink {
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        lock(&self.0)?.write_all(bytes)
    }
    fn read_timeout(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        lock(&self.0)?.read_timeout(buf, timeout)
    }
    fn discard_input(&mut self) -> io::Result<()> {
        lock(&self.0)?.discard_input()
    }
}

/// The indexer's link to the simulated cell.
#[derive(Debug, Clone)]
pub struct SimIndexerLink(Shared);

impl Link for SimIndexerLink {
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        let mut w = lock(&self.0)?;
        let now = w.clock().now();
        let peer = &mut w.peer;
        let mut t = peer.to_card_free.max(now);
        for &b in bytes {
            t += peer.byte_time;
            peer.to_card.push_back((t, b));
        }
        peer.to_card_free = t;
        // Writing returns when the last byte has left, as on a serial line.
        w.run_for(t.saturating_sub(now));
        Ok(())
    }

    fn read_timeout(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        let mut w = lock(&self.0)?;
        let deadline = w.clock().now() + timeout;
        loop {
            let now = w.clock().now();
            let mut n = 0;
            while let (Some(slot), Some(&(t, b))) = (buf.get_mut(n), w.peer.from_card.front()) {
                if t > now {
                    break;
                }
                *slot = b;
                w.peer.from_card.pop_front();
                n += 1;
            }
            if n > 0 {
                return Ok(n);
            }
            if now >= deadline {
                return Ok(0);
            }
            // Up to the first byte due, or the cell's next event (which may queue an earlier
            // one: the card's answer when its move ends).
            let mut next = w
                .peer
                .from_card
                .front()
                .map_or(deadline, |(t, _)| (*t).min(deadline));
            if let Some(event) = w.peer.deadline() {
                next = next.min(event);
            }
            let step = next.saturating_sub(now).max(Duration::from_nanos(1));
            w.run_for(step);
        }
    }

    fn discard_input(&mut self) -> io::Result<()> {
        let mut w = lock(&self.0)?;
        let now = w.clock().now();
        while w.peer.from_card.front().is_some_and(|(t, _)| *t <= now) {
            w.peer.from_card.pop_front();
        }
        Ok(())
    }
}

/// The PC's side of the simulated sync lines.
#[derive(Debug, Clone)]
pub struct SimSync {
    shared: Shared,
    estop: Arc<AtomicBool>,
}

impl SyncLines for SimSync {
    fn set_start(&mut self, on: bool) -> DeviceResult<()> {
        let mut w = lock(&self.shared).map_err(DeviceError::Sync)?;
        w.peer.start.drive(on).map_err(DeviceError::Sync)?;
        // Poll exactly when the edge has crossed the opto-isolator (plus 1 µs of rounding).
        let due = w.clock().now() + w.peer.delay + Duration::from_micros(1);
        w.peer.edge_due = Some(w.peer.edge_due.map_or(due, |d| d.min(due)));
        Ok(())
    }
    fn in_position(&mut self) -> DeviceResult<bool> {
        let w = lock(&self.shared).map_err(DeviceError::Sync)?;
        w.peer.in_position.received().map_err(DeviceError::Sync)
    }
    fn estop(&mut self) -> DeviceResult<bool> {
        Ok(self.estop.load(Ordering::Relaxed))
    }
}

/// The simulated cell's time: sleeping runs both simulators.
#[derive(Debug, Clone)]
pub struct SimTime(Shared, VirtualClock);

impl Timebase for SimTime {
    fn now_s(&self) -> f64 {
        self.1.now_s()
    }
    fn sleep(&self, dt: Duration) {
        if let Ok(mut w) = lock(&self.0) {
            w.run_for(dt);
        }
    }
}
