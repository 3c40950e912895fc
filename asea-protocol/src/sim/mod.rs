//! The robot-computer simulator (seed 001 §4.1.2, §5.2–5.4, §6.7, App. D): the link's robot side,
//! program memory with the thesis' limits, standby and operate modes, home synchronisation, the
//! output and input lines, and the motion model of [`motion`].
//!
//! [`Robot`] is driven by bytes and time ([`Peer`]): over a [`crate::link::Paced`] wire in virtual
//! time (a whole program in milliseconds), or by [`serve`] on any [`Link`] in real time.

pub mod kinematics;
pub mod motion;

use std::collections::BTreeMap;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU8, Ordering};
use std::time::Duration;

pub use kinematics::{ArmModel, Kinematics, Reach};
pub use motion::{EyePose, MotionParams, Move, Speeds, Trajectory};

use crate::clock::Clock;
use crate::command::{
    CONTROL_UNITS, Command, Control, IN_POSITION_OUTPUT, Instruction, Length, MEMORY_UNITS, Mode,
    POSITION_UNITS, Pose, Positioning, QUATERNION_NORM_TOLERANCE, Quaternion, Reply, RobotError,
    Selector, State, Status,
};
use crate::error::Result;
use crate::frame::{Frame, FrameConfig};
use crate::link::{Link, Peer};
use crate::session::{RobotSession, Timers};

/// Longest [`Machine::executed`] and [`Machine::trace`]; beyond it the older half is dropped, so
/// that a simulator serving for days stays bounded.
pub const RECORD_LIMIT: usize = 100_000;

fn push_bounded<T>(v: &mut Vec<T>, item: T) {
    if v.len() >= RECORD_LIMIT {
        v.drain(..RECORD_LIMIT / 2);
    }
    v.push(item);
}

fn units(i: &Instruction) -> u32 {
    match i {
        Instruction::Position(_) => POSITION_UNITS,
        Instruction::Control(_) => CONTROL_UNITS,
    }
}

/// The six output and six input lines, shared with whoever wires them (the cell's sync I/O).
#[derive(Debug, Clone, Default)]
pub struct IoLines {
    outputs: Arc<AtomicU8>,
    inputs: Arc<AtomicU8>,
}

fn bit(line: u8) -> u8 {
    1u8.checked_shl(u32::from(line.saturating_sub(1)))
        .unwrap_or(0)
}

impl IoLines {
    /// Level of output `line` (1–6).
    pub fn output(&self, line: u8) -> bool {
        self.outputs.load(Ordering::Relaxed) & bit(line) != 0
    }
    /// Level of input `line` (1–6).
    pub fn input(&self, line: u8) -> bool {
        self.inputs.load(Ordering::Relaxed) & bit(line) != 0
    }
    /// Drives input `line` (the PC's side).
    pub fn set_input(&self, line: u8, on: bool) {
        if on {
            self.inputs.fetch_or(bit(line), Ordering::Relaxed);
        } else {
            self.inputs.fetch_and(!bit(line), Ordering::Relaxed);
        }
    }
    fn set_output(&self, line: u8, on: bool) {
        if on {
            self.outputs.fetch_or(bit(line), Ordering::Relaxed);
        } else {
            self.outputs.fetch_and(!bit(line), Ordering::Relaxed);
        }
    }
}

#[derive(Debug, Clone, PartialEq)]
enum Activity {
    Idle,
    Homing {
        until: f64,
    },
    Moving {
        traj: Trajectory,
        next: usize,
        discrete: bool,
    },
    /// Decelerating to rest after STOP.
    Stopping {
        traj: Trajectory,
    },
    Waiting {
        line: u8,
        on: bool,
        next: usize,
    },
}

/// The robot computer without its link: memory, modes, execution, motion.
#[derive(Debug, Clone)]
pub struct Machine {
    /// Motion constants.
    pub params: MotionParams,
    programs: BTreeMap<u8, BTreeMap<u16, Instruction>>,
    used_units: u32,
    mode: Mode,
    homed: bool,
    last_error: u8,
    error_seq: u8,
    errors_raised: u64,
    redundant_stores: u64,
    executed_count: u16,
    last_digest: u16,
    error_state: bool,
    stopped: bool,
    speeds: Speeds,
    pose: EyePose,
    last_target: [f64; 3],
    activity: Activity,
    running: Option<(u8, Vec<(u16, Instruction)>)>,
    current_instruction: u16,
    io: IoLines,
    kinematics: Arc<dyn Kinematics>,
    now_s: f64,
    /// Every telegram executed, in order (the link delivered it once); the last
    /// [`RECORD_LIMIT`] at most.
    pub executed: Vec<Frame>,
    /// Eye poses at every instruction end: (time s, pose); the last [`RECORD_LIMIT`] at most.
    pub trace: Vec<(f64, EyePose)>,
}

impl Default for Machine {
    fn default() -> Self {
        Machine::new(MotionParams::default())
    }
}

impl Machine {
    /// A powered-up robot computer: standby, not homed, empty memory, at the home pose.
    pub fn new(params: MotionParams) -> Self {
        Machine {
            programs: BTreeMap::new(),
            used_units: 0,
            mode: Mode::Standby,
            homed: false,
            last_error: 0,
            error_seq: 0,
            errors_raised: 0,
            redundant_stores: 0,
            executed_count: 0,
            last_digest: 0,
            error_state: false,
            stopped: false,
            speeds: Speeds::default(),
            pose: params.home,
            last_target: params.home.xyz_mm,
            activity: Activity::Idle,
            running: None,
            current_instruction: 0,
            io: IoLines::default(),
            kinematics: Arc::new(ArmModel::default()),
            now_s: 0.0,
            executed: Vec::new(),
            trace: Vec::new(),
            params,
        }
    }

    /// Uses `k` to decide which poses the arm can take ([`kinematics`]; default [`ArmModel`]).
    pub fn with_kinematics(mut self, k: Arc<dyn Kinematics>) -> Self {
        self.kinematics = k;
        self
    }

    /// The I/O lines (clone to wire them elsewhere).
    pub fn io(&self) -> &IoLines {
        &self.io
    }

    /// Memory units in use.
    pub fn used_units(&self) -> u32 {
        self.used_units
    }

    /// A stored instruction.
    pub fn instruction(&self, program: u8, instruction: u16) -> Option<&Instruction> {
        self.programs.get(&program)?.get(&instruction)
    }

    /// Instructions stored in `program`.
    pub fn program_len(&self, program: u8) -> usize {
        self.programs.get(&program).map_or(0, BTreeMap::len)
    }

    /// The mode.
    pub fn mode(&self) -> Mode {
        self.mode
    }

    /// True once home synchronisation has completed.
    pub fn homed(&self) -> bool {
        self.homed
    }

    /// The latched error code (0: none).
    pub fn last_error(&self) -> u8 {
        self.last_error
    }

    /// Errors raised since power-up (wrapping at 256): the sequence number of the latest.
    pub fn error_seq(&self) -> u8 {
        self.error_seq
    }

    /// Errors raised since power-up (the simulator's truth, not on the wire).
    pub fn errors_raised(&self) -> u64 {
        self.errors_raised
    }

    /// Stores executed into a slot that already held exactly that instruction: a store executed
    /// twice (the simulator's truth, not on the wire).
    pub fn redundant_stores(&self) -> u64 {
        self.redundant_stores
    }

    /// The eye pose now (after the last [`Machine::advance`]).
    pub fn pose(&self) -> EyePose {
        self.pose
    }

    /// The planned motion currently under way, if any.
    pub fn trajectory(&self) -> Option<&Trajectory> {
        match &self.activity {
            Activity::Moving { traj, .. } | Activity::Stopping { traj } => Some(traj),
            _ => None,
        }
    }

    /// The status as ENQUIRE reports it (without clearing the error).
    pub fn status(&self) -> Status {
        Status {
            mode: self.mode,
            state: match self.activity {
                _ if self.error_state => State::Error,
                Activity::Idle | Activity::Stopping { .. } if self.stopped => State::Stopped,
                Activity::Idle => State::Idle,
                Activity::Homing { .. } => State::Homing,
                Activity::Moving { .. } | Activity::Waiting { .. } | Activity::Stopping { .. } => {
                    State::Running
                }
            },
            program: self.running.as_ref().map_or(0, |(p, _)| *p),
            instruction: self.current_instruction,
            last_error: self.last_error,
            homed: self.homed,
            error_seq: self.error_seq,
            executed: self.executed_count,
            last_digest: self.last_digest,
        }
    }

    /// Latches `e` until the host acknowledges it (a new error replaces the code and advances
    /// the sequence number, so the host sees that it happened).
    fn fail(&mut self, e: RobotError) {
        self.last_error = e.code();
        self.error_seq = self.error_seq.wrapping_add(1);
        self.errors_raised += 1;
    }

    fn busy(&self) -> bool {
        self.activity != Activity::Idle
    }

    /// Checks a positioning instruction against the workspace (standby's "syntax and range
    /// check", seed 001 §5.3.1).
    fn check_positioning(
        &self,
        p: &Positioning,
        prev: [f64; 3],
    ) -> std::result::Result<[f64; 3], RobotError> {
        if p.pose.q.norm_error() > QUATERNION_NORM_TOLERANCE {
            return Err(RobotError::Range);
        }
        let t = motion::target_of(p, prev);
        if p.speed.0 == 0 {
            return Err(RobotError::Range);
        }
        self.kinematics.check(t, p.pose.q.wxyz())?;
        Ok(t)
    }

    /// Executes one delivered telegram at time `now_s`; the reply, if the command has one.
    pub fn execute(&mut self, frame: &Frame, now_s: f64) -> Option<Reply> {
        self.advance(now_s);
        push_bounded(&mut self.executed, frame.clone());
        let parsed = Command::from_frame(frame);
        if !matches!(
            parsed,
            Ok(Command::Enquire(_)
                | Command::ReadBack { .. }
                | Command::ProgramInfo { .. }
                | Command::AckError { .. })
        ) {
            self.executed_count = self.executed_count.wrapping_add(1);
            self.last_digest = crate::frame::telegram_digest(frame.code, &frame.data);
        }
        let cmd = match parsed {
            Ok(c) => c,
            Err(e) => {
                self.fail(RobotError::from_parse(&e));
                return None;
            }
        };
        match cmd {
            Command::StorePos {
                program,
                instruction,
                positioning,
            } => {
                if positioning.pose.q.norm_error() > QUATERNION_NORM_TOLERANCE {
                    self.fail(RobotError::Range);
                } else {
                    self.store(program, instruction, Instruction::Position(positioning));
                }
            }
            Command::StoreControl {
                program,
                instruction,
                control,
            } => self.store(program, instruction, Instruction::Control(control)),
            Command::RunProgram { program } => self.run(program, now_s),
            Command::Standby => {
                if self.busy() {
                    self.fail(RobotError::Busy);
                } else {
                    self.mode = Mode::Standby;
                }
            }
            Command::Operate => {
                if self.busy() {
                    self.fail(RobotError::Busy);
                } else {
                    self.mode = Mode::Operate;
                }
            }
            Command::SyncHome => {
                if self.busy() {
                    self.fail(RobotError::Busy);
                } else if self.mode != Mode::Operate {
                    self.fail(RobotError::NotOperate);
                } else {
                    self.error_state = false;
                    self.stopped = false;
                    self.activity = Activity::Homing {
                        until: now_s + self.params.home_s,
                    };
                }
            }
            Command::Enquire(Selector::Status) => return Some(Reply::Status(self.status())),
            Command::AckError { seq } => {
                if seq == self.error_seq {
                    self.last_error = 0;
                }
            }
            Command::Enquire(Selector::Position) => return Some(Reply::Position(self.wire_pose())),
            Command::DeleteProgram { program } => {
                if self.running.as_ref().is_some_and(|(p, _)| *p == program) && self.busy() {
                    self.fail(RobotError::Busy);
                } else if let Some(prog) = self.programs.remove(&program) {
                    self.used_units -= prog.values().map(units).sum::<u32>();
                } else {
                    self.fail(RobotError::NoProgram);
                }
            }
            Command::MoveImmediate(p) => self.move_immediate(p, now_s),
            Command::SetBaseSpeed(s) => {
                if s.0 == 0 {
                    self.fail(RobotError::Range);
                } else {
                    self.speeds.base_mm_s = s.value() * 1000.0;
                }
            }
            Command::SetMaxSpeed(s) => {
                if s.0 == 0 {
                    self.fail(RobotError::Range);
                } else {
                    self.speeds.max_mm_s = s.value() * 1000.0;
                }
            }
            Command::Stop => self.stop(now_s),
            Command::ProgramInfo { program } => {
                let prog = self.programs.get(&program);
                let clip = |n: usize| u16::try_from(n).unwrap_or(u16::MAX);
                return Some(Reply::ProgramInfo {
                    program,
                    count: clip(prog.map_or(0, BTreeMap::len)),
                    highest: prog
                        .and_then(|p| p.keys().next_back().copied())
                        .unwrap_or(0),
                    total: clip(self.programs.values().map(BTreeMap::len).sum()),
                });
            }
            Command::ReadBack {
                program,
                instruction,
            } => {
                return Some(Reply::ReadBack {
                    program,
                    instruction,
                    stored: self.instruction(program, instruction).copied(),
                });
            }
        }
        None
    }

    fn wire_pose(&self) -> Pose {
        let p = self.pose;
        let l = |v: f64| Length(((v / 0.0625).round()).clamp(-32767.0, 32767.0) as i16);
        Pose {
            x: l(p.xyz_mm[0]),
            y: l(p.xyz_mm[1]),
            z: l(p.xyz_mm[2]),
            q: Quaternion::from_wxyz(p.q[0], p.q[1], p.q[2], p.q[3]).unwrap_or_default(),
        }
    }

    fn store(&mut self, program: u8, instruction: u16, i: Instruction) {
        if self.instruction(program, instruction) == Some(&i) {
            self.redundant_stores += 1;
        }
        let old = self.instruction(program, instruction).map_or(0, units);
        let new_used = self.used_units - old + units(&i);
        if new_used > MEMORY_UNITS {
            self.fail(RobotError::MemoryFull);
            return;
        }
        self.used_units = new_used;
        self.programs
            .entry(program)
            .or_default()
            .insert(instruction, i);
    }

    fn move_immediate(&mut self, p: Positioning, now_s: f64) {
        if self.busy() {
            return self.fail(RobotError::Busy);
        }
        let target = match self.check_positioning(&p, self.last_target) {
            Ok(t) => t,
            Err(e) => return self.fail(e),
        };
        if self.mode == Mode::Standby {
            // Checked, not moved.
            self.last_target = target;
            return;
        }
        if !self.homed {
            return self.fail(RobotError::NotHomed);
        }
        let traj = motion::plan(self.pose, &[(0, p)], self.speeds, &self.params, now_s, true);
        self.stopped = false;
        self.last_target = target;
        self.io.set_output(IN_POSITION_OUTPUT, false);
        self.running = None;
        self.activity = Activity::Moving {
            traj,
            next: 0,
            discrete: true,
        };
    }

    fn run(&mut self, program: u8, now_s: f64) {
        if self.busy() {
            return self.fail(RobotError::Busy);
        }
        let Some(prog) = self.programs.get(&program).filter(|p| !p.is_empty()) else {
            return self.fail(RobotError::NoProgram);
        };
        let list: Vec<(u16, Instruction)> = prog.iter().map(|(n, i)| (*n, *i)).collect();
        self.error_state = false;
        self.stopped = false;
        if self.mode == Mode::Standby {
            // Execute in memory only: check every instruction, stop at the first error.
            if self.check_program(&list) {
                self.current_instruction = list.last().map_or(0, |(n, _)| *n);
            }
            return;
        }
        if !self.homed {
            return self.fail(RobotError::NotHomed);
        }
        if !self.check_program(&list) {
            return;
        }
        self.error_state = false;
        // "In position" from an earlier move or program is stale once a program starts.
        self.io.set_output(IN_POSITION_OUTPUT, false);
        self.running = Some((program, list));
        self.step_program(0, now_s);
    }

    /// Checks every positioning of `list` in order (syntax, range, reach); at the first bad one
    /// stops there in the error state and returns false.
    fn check_program(&mut self, list: &[(u16, Instruction)]) -> bool {
        let mut prev = self.last_target;
        for (n, i) in list {
            if let Instruction::Position(p) = i {
                match self.check_positioning(p, prev) {
                    Ok(t) => prev = t,
                    Err(e) => {
                        self.current_instruction = *n;
                        self.error_state = true;
                        self.fail(e);
                        return false;
                    }
                }
            }
        }
        true
    }

    /// Continues the running program at list index `next`, time `t`.
    fn step_program(&mut self, mut next: usize, t: f64) {
        let Some((_, list)) = self.running.as_ref() else {
            self.activity = Activity::Idle;
            return;
        };
        let list = list.clone();
        let mut chunk: Vec<(u16, Positioning)> = Vec::new();
        while let Some((n, i)) = list.get(next) {
            match i {
                Instruction::Position(p) => {
                    chunk.push((*n, *p));
                    next += 1;
                }
                Instruction::Control(_) if !chunk.is_empty() => break,
                Instruction::Control(c) => {
                    self.current_instruction = *n;
                    match *c {
                        Control::SetOutput { line, on } => {
                            self.io.set_output(line, on);
                            next += 1;
                        }
                        Control::WaitInput { line, on } => {
                            if self.io.input(line) == on {
                                next += 1;
                            } else {
                                self.activity = Activity::Waiting {
                                    line,
                                    on,
                                    next: next + 1,
                                };
                                return;
                            }
                        }
                        Control::End => {
                            next = list.len();
                        }
                    }
                }
            }
        }
        if chunk.is_empty() {
            self.running = None;
            self.activity = Activity::Idle;
            return;
        }
        let traj = motion::plan(self.pose, &chunk, self.speeds, &self.params, t, false);
        if let Some(m) = traj.moves.last() {
            self.last_target = m.target_mm;
        }
        self.activity = Activity::Moving {
            traj,
            next,
            discrete: false,
        };
    }

    /// STOP: ends the program and decelerates the arm at [`MotionParams::accel_mm_s2`] along its
    /// current direction of travel to rest; "in position" stays low and the state is
    /// [`State::Stopped`] until the next move, program or home synchronisation.
    fn stop(&mut self, now_s: f64) {
        self.running = None;
        self.stopped = true;
        self.io.set_output(IN_POSITION_OUTPUT, false);
        let traj = match &self.activity {
            Activity::Moving { traj, .. } | Activity::Stopping { traj } => Some(traj),
            _ => None,
        };
        self.activity = match traj.and_then(|t| motion::braking(t, now_s, &self.params)) {
            Some(traj) => {
                if let Some(m) = traj.moves.last() {
                    self.last_target = m.target_mm;
                }
                Activity::Stopping { traj }
            }
            None => {
                self.last_target = self.pose.xyz_mm;
                Activity::Idle
            }
        };
    }

    /// The link holds the robot computer from the last event to `now_s` (seed 001 §4.1.2: it "can
    /// only perform one task at a time which idles the robot manipulator during an external data
    /// link"): motion and home synchronisation resume later by as much.
    pub fn hold(&mut self, now_s: f64) {
        let dt = now_s - self.now_s;
        if dt <= 0.0 {
            return;
        }
        self.now_s = now_s;
        match &mut self.activity {
            Activity::Moving { traj, .. } | Activity::Stopping { traj } => traj.delay(dt),
            Activity::Homing { until } => *until += dt,
            Activity::Idle | Activity::Waiting { .. } => {}
        }
    }

    /// When the machine next changes on its own (clock time, s): the end of the current move
    /// (the next instruction starts, or the in-position output rises), the end of a stop's
    /// deceleration, or the end of home synchronisation. `None` when idle or waiting for an
    /// input (only a telegram or an input edge can change anything). Advancing at these times,
    /// and whenever a telegram or an edge arrives, gives the same states at the same times as
    /// advancing at every instant.
    pub fn next_event_s(&self) -> Option<f64> {
        match &self.activity {
            Activity::Idle | Activity::Waiting { .. } => None,
            Activity::Homing { until } => Some(*until),
            Activity::Stopping { traj } => Some(traj.t1()),
            Activity::Moving { traj, .. } => Some(
                traj.move_at(self.now_s)
                    .map_or_else(|| traj.t1(), |m| m.t1()),
            ),
        }
    }

    /// Lets time run to `now_s`: moves progress, programs continue, homing completes.
    pub fn advance(&mut self, now_s: f64) {
        let now_s = now_s.max(self.now_s);
        self.now_s = now_s;
        for _ in 0..10_000 {
            match &self.activity {
                Activity::Idle => return,
                Activity::Homing { until } => {
                    if now_s < *until {
                        return;
                    }
                    self.pose = self.params.home;
                    self.last_target = self.pose.xyz_mm;
                    self.homed = true;
                    self.activity = Activity::Idle;
                    return;
                }
                Activity::Waiting { line, on, next } => {
                    if self.io.input(*line) != *on {
                        return;
                    }
                    let next = *next;
                    self.step_program(next, now_s);
                }
                Activity::Stopping { traj } => {
                    if now_s < traj.t1() {
                        self.pose = traj.pose_at(now_s);
                        return;
                    }
                    self.pose = traj.end_pose();
                    self.activity = Activity::Idle;
                    return;
                }
                Activity::Moving {
                    traj,
                    next,
                    discrete,
                } => {
                    if let Some(m) = traj.move_at(now_s) {
                        self.current_instruction = if *discrete { 0 } else { m.instruction };
                        self.pose = traj.pose_at(now_s);
                        return;
                    }
                    let (end, t1, next, discrete) = (traj.end_pose(), traj.t1(), *next, *discrete);
                    for m in &traj.moves {
                        push_bounded(&mut self.trace, (m.t1(), m.pose_at(m.t1())));
                    }
                    self.pose = end;
                    if discrete {
                        self.io.set_output(IN_POSITION_OUTPUT, true);
                        self.activity = Activity::Idle;
                    } else {
                        self.step_program(next, t1);
                    }
                }
            }
        }
    }
}

/// What the robot does with a well-framed telegram that does not parse (unknown code, LEN not
/// matching the code, reserved flag bits or zone, program or instruction 0, quaternion norm off
/// by more than 0.01).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Malformed {
    /// Acknowledge it and set `last_error` (docs/protocol.md §6: NAK only for link errors).
    #[default]
    AckWithError,
    /// Treat it as a transmission error: NAK, so that the host retransmits. Most corruptions
    /// that a one-byte sum misses are caught this way; a host that really sends such a telegram
    /// gets a retries error instead of an error code.
    Nak,
}

/// The robot's policy unless configured otherwise.
pub const DEFAULT_MALFORMED: Malformed = Malformed::AckWithError;

/// The simulated robot computer on a link: session + machine.
#[derive(Debug)]
pub struct Robot {
    /// The link's robot side.
    pub session: RobotSession,
    /// The robot computer.
    pub machine: Machine,
    frame: FrameConfig,
}

impl Robot {
    /// A robot with framing `frame`, link `timers` and motion `params`.
    pub fn new(frame: FrameConfig, timers: Timers, params: MotionParams) -> Self {
        Robot {
            session: RobotSession::new(frame, timers),
            machine: Machine::new(params),
            frame,
        }
        .with_malformed(DEFAULT_MALFORMED)
    }

    /// Sets the policy for telegrams that do not parse.
    pub fn with_malformed(mut self, policy: Malformed) -> Self {
        self.session.validate = match policy {
            Malformed::AckWithError => None,
            Malformed::Nak => Some(crate::command::well_formed),
        };
        self
    }
}

impl Default for Robot {
    fn default() -> Self {
        Robot::new(
            FrameConfig::default(),
            Timers::default(),
            MotionParams::default(),
        )
    }
}

impl Robot {
    /// Lets the machine's time run to `now`: held while a link session was open (§4.1.2), else
    /// advanced.
    fn run_to(&mut self, now: Duration) {
        let now_s = now.as_secs_f64();
        if self.machine.params.link_idles_arm && self.session.in_session() {
            self.machine.hold(now_s);
        } else {
            self.machine.advance(now_s);
        }
    }
}

impl Peer for Robot {
    fn receive(&mut self, bytes: &[u8], now: Duration) {
        self.run_to(now);
        for f in self.session.on_bytes(bytes, now) {
            if let Some(reply) = self.machine.execute(&f, now.as_secs_f64())
                && let Ok(bytes) = reply.encode(&self.frame)
            {
                self.session.queue_reply(bytes);
            }
        }
    }
    fn poll(&mut self, now: Duration) {
        self.run_to(now);
        self.session.on_time(now);
        self.run_to(now);
    }
    fn take_output(&mut self) -> Vec<u8> {
        self.session.take_output()
    }
    fn deadline(&self) -> Option<Duration> {
        self.session.deadline()
    }
}

/// How long [`serve`] waits for host bytes before letting the clock run.
pub const POLL_PERIOD: Duration = Duration::from_millis(2);
/// The simulator's turnaround in real time: it answers no sooner than this after the byte that
/// prompts the answer, as a UART robot computer would (spec §5.4: under 50 ms).
pub const TURNAROUND: Duration = Duration::from_millis(3);

/// Serves `robot` over `link` in real time until `stop` is set. An answer to received bytes
/// goes out [`TURNAROUND`] after them; the simulator keeps reading meanwhile, so that every byte
/// is taken at the time it arrives (the robot's rule on the silence before an ENQ, docs/protocol.md
/// §6 rule 7, measures the line, not the simulator's own delay).
pub fn serve<L: Link>(
    mut link: L,
    robot: &std::sync::Mutex<Robot>,
    clock: &dyn Clock,
    stop: &AtomicBool,
) -> Result<()> {
    let mut buf = [0u8; 256];
    let mut out = Vec::new();
    let mut send_at = Duration::ZERO;
    while !stop.load(Ordering::Relaxed) {
        let wait = if out.is_empty() {
            POLL_PERIOD
        } else {
            send_at.saturating_sub(clock.now()).min(POLL_PERIOD)
        };
        let n = if wait.is_zero() {
            0
        } else {
            link.read_timeout(&mut buf, wait)?
        };
        // The bytes' arrival time is taken as the read returns, before the lock (which the log
        // watcher may hold): a robot's UART notes a byte when it comes, and the host's urgent
        // ENQ counts on the robot measuring the silence before it to within its margin
        // (`session::URGENT_MARGIN`).
        let now = clock.now();
        {
            let mut r = robot
                .lock()
                .map_err(|_| std::io::Error::other("simulator lock poisoned"))?;
            if let Some(bytes) = buf.get(..n)
                && n > 0
            {
                r.receive(bytes, now);
            }
            r.poll(now);
            let more = r.take_output();
            if !more.is_empty() {
                if out.is_empty() {
                    // An answer to bytes just received waits out the turnaround; one a timer
                    // prompts goes at once.
                    send_at = if n > 0 { now + TURNAROUND } else { now };
                }
                out.extend_from_slice(&more);
            }
        }
        if !out.is_empty() && now >= send_at {
            link.write_all(&out)?;
            out.clear();
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::command::{Flags, Reference, START_INPUT, Speed, Zone};

    fn frame(cmd: Command) -> Frame {
        cmd.to_frame()
    }

    /// A positioning at `xyz`; an absolute one with the eye's roll axis (the quaternion's X
    /// axis) horizontal and radial, in the arm's vertical plane, so that the five-axis arm can
    /// take it (a yaw about the vertical by the point's azimuth).
    fn pos(xyz: [f64; 3], reference: Reference) -> Positioning {
        let q = match reference {
            Reference::Absolute => radial(xyz),
            Reference::Relative => [1.0, 0.0, 0.0, 0.0],
        };
        Positioning {
            flags: Flags {
                reference,
                zone: Zone::Fine,
                ..Flags::default()
            },
            pose: Pose::from_mm(xyz, q).unwrap(),
            speed: Speed::from_value("speed", 0.5).unwrap(),
        }
    }

    /// Sends `m` an immediate move to `xyz` at `t_s`.
    fn move_immediate(m: &mut Machine, xyz: [f64; 3], reference: Reference, t_s: f64) {
        m.execute(&frame(Command::MoveImmediate(pos(xyz, reference))), t_s);
    }

    /// The wrist quaternion whose X axis (the roll axis) is horizontal and radial at `xyz`.
    fn radial(xyz: [f64; 3]) -> [f64; 4] {
        let half = xyz[1].atan2(xyz[0]) / 2.0;
        [half.cos(), 0.0, 0.0, half.sin()]
    }

    fn homed_operate() -> Machine {
        let mut m = Machine::default();
        m.execute(&frame(Command::Operate), 0.0);
        m.execute(&frame(Command::SyncHome), 0.0);
        assert_eq!(m.status().state, State::Homing);
        m.advance(3.0);
        assert!(m.homed());
        m
    }

    #[test]
    fn immediate_moves_need_operate_and_home_and_stop_at_the_point() {
        let mut m = Machine::default();
        // Standby: checked, not moved.
        move_immediate(&mut m, [900.0, 50.0, 800.0], Reference::Absolute, 0.0);
        assert_eq!(m.last_error(), 0);
        assert_eq!(m.pose().xyz_mm, MotionParams::default().home.xyz_mm);
        // Operate without home.
        m.execute(&frame(Command::Operate), 0.0);
        move_immediate(&mut m, [900.0, 50.0, 800.0], Reference::Absolute, 0.0);
        assert_eq!(m.last_error(), RobotError::NotHomed.code());

        let mut m = homed_operate();
        // Relative, with the roll axis radial at the point it leads to; every coordinate moves.
        let mut rel = pos([20.0, 100.0, -30.0], Reference::Relative);
        rel.pose = Pose::from_mm([20.0, 100.0, -30.0], radial([920.0, 100.0, 770.0])).unwrap();
        m.execute(&frame(Command::MoveImmediate(rel)), 10.0);
        assert!(!m.io().output(IN_POSITION_OUTPUT));
        // A second move while the first runs is refused.
        move_immediate(&mut m, [900.0, 0.0, 800.0], Reference::Absolute, 10.1);
        assert_eq!(m.last_error(), RobotError::Busy.code());
        m.advance(12.0);
        assert!(m.io().output(IN_POSITION_OUTPUT));
        assert_eq!(m.pose().xyz_mm, [920.0, 100.0, 770.0]);
        // Reading the status does not clear the error: it stays latched until acknowledged by
        // its sequence number, and an acknowledgement of another number leaves it.
        let r = m.execute(&frame(Command::Enquire(Selector::Status)), 12.0);
        let Some(Reply::Status(s)) = r else {
            panic!("{r:?}")
        };
        assert_eq!(s.last_error, 7);
        let again = m.execute(&frame(Command::Enquire(Selector::Status)), 12.0);
        assert_eq!(again, Some(Reply::Status(s)));
        m.execute(
            &frame(Command::AckError {
                seq: s.error_seq.wrapping_sub(1),
            }),
            12.0,
        );
        assert_eq!(m.last_error(), 7);
        m.execute(&frame(Command::AckError { seq: s.error_seq }), 12.0);
        assert_eq!(m.last_error(), 0);
        // A late duplicate of the acknowledgement does not clear a newer error.
        m.execute(&frame(Command::DeleteProgram { program: 9 }), 12.0);
        m.execute(&frame(Command::AckError { seq: s.error_seq }), 12.0);
        assert_eq!(m.last_error(), RobotError::NoProgram.code());
        assert_eq!(m.error_seq(), s.error_seq.wrapping_add(1));
    }

    /// The machine names the instants it changes on its own: the end of home synchronisation,
    /// the end of a move (in-position rises there, not a microsecond earlier), and nothing while
    /// idle or waiting for an input.
    #[test]
    fn next_event_is_where_the_state_changes() {
        let mut m = Machine::default();
        assert_eq!(m.next_event_s(), None, "standby");
        m.execute(&frame(Command::Operate), 0.0);
        m.execute(&frame(Command::SyncHome), 0.0);
        let homed_at = m.next_event_s().unwrap();
        assert!(homed_at > 0.0);
        m.advance(homed_at - 1e-6);
        assert!(!m.homed());
        m.advance(homed_at);
        assert!(m.homed());
        assert_eq!(m.next_event_s(), None, "idle");

        move_immediate(&mut m, [900.0, 300.0, 800.0], Reference::Absolute, 10.0);
        let end = m.next_event_s().unwrap();
        assert_eq!(end, m.trajectory().unwrap().t1());
        assert!(end > 10.0);
        m.advance(end - 1e-6);
        assert!(!m.io().output(IN_POSITION_OUTPUT));
        m.advance(end);
        assert!(m.io().output(IN_POSITION_OUTPUT));
        assert_eq!(m.next_event_s(), None);

        // A stop names the end of its braking ramp.
        move_immediate(&mut m, [900.0, -300.0, 800.0], Reference::Absolute, 20.0);
        let planned = m.next_event_s().unwrap();
        m.advance(20.2);
        m.execute(&frame(Command::Stop), 20.2);
        let braked = m.next_event_s().unwrap();
        assert!(braked > 20.2 && braked < planned, "{braked} {planned}");
        let y = |m: &mut Machine, t: f64| {
            m.advance(t);
            m.pose().xyz_mm[1]
        };
        let at_end = y(&mut m, braked);
        assert_eq!(y(&mut m, braked + 1.0), at_end, "at rest after the ramp");
        assert_eq!(m.next_event_s(), None);
    }

    #[test]
    fn stop_decelerates_to_rest_and_leaves_in_position_low() {
        let mut m = homed_operate();
        move_immediate(&mut m, [900.0, 400.0, 800.0], Reference::Absolute, 10.0);
        m.advance(10.3);
        let y0 = m.pose().xyz_mm[1];
        let v = (y0 - m.trajectory().unwrap().pose_at(10.3 - 1e-3).xyz_mm[1]) / 1e-3;
        assert!(v > 100.0, "{v}");
        m.execute(&frame(Command::Stop), 10.3);
        assert_eq!(m.status().state, State::Stopped);
        m.advance(20.0);
        let y = m.pose().xyz_mm[1];
        // Braking at the path acceleration from v covers v²/2a, not zero (an instant halt) and
        // not the rest of the move.
        let a = MotionParams::default().accel_mm_s2;
        assert!((y - y0 - v * v / (2.0 * a)).abs() < 0.5, "{y} {y0} {v}");
        assert!(y < 400.0);
        assert_eq!(m.status().state, State::Stopped);
        assert!(!m.io().output(IN_POSITION_OUTPUT));
    }

    #[test]
    fn a_program_run_lowers_in_position_and_waits_for_start() {
        let mut m = homed_operate();
        move_immediate(&mut m, [900.0, 0.0, 700.0], Reference::Absolute, 10.0);
        m.advance(15.0);
        assert!(m.io().output(IN_POSITION_OUTPUT));
        let store = |m: &mut Machine, n: u16, i: Instruction| {
            let cmd = crate::client::store_command(3, n, &i);
            m.execute(&frame(cmd), 15.0);
        };
        store(
            &mut m,
            1,
            Instruction::Control(Control::WaitInput {
                line: START_INPUT,
                on: true,
            }),
        );
        store(
            &mut m,
            2,
            Instruction::Position(pos([900.0, 50.0, 700.0], Reference::Absolute)),
        );
        store(
            &mut m,
            3,
            Instruction::Control(Control::SetOutput {
                line: IN_POSITION_OUTPUT,
                on: true,
            }),
        );
        store(&mut m, 4, Instruction::Control(Control::End));
        m.execute(&frame(Command::RunProgram { program: 3 }), 16.0);
        assert!(
            !m.io().output(IN_POSITION_OUTPUT),
            "stale in-position after RUN"
        );
        m.advance(30.0);
        assert_eq!(m.status().state, State::Running);
        assert_eq!(m.pose().xyz_mm, [900.0, 0.0, 700.0]);
        m.io().set_input(START_INPUT, true);
        m.advance(30.1);
        assert!(!m.io().output(IN_POSITION_OUTPUT));
        m.advance(40.0);
        assert!(m.io().output(IN_POSITION_OUTPUT));
        assert_eq!(m.status().state, State::Idle);
    }

    #[test]
    fn read_back_delete_and_bad_telegrams() {
        let mut m = Machine::default();
        let p = pos([900.0, 0.0, 800.0], Reference::Absolute);
        m.execute(
            &frame(Command::StorePos {
                program: 4,
                instruction: 2,
                positioning: p,
            }),
            0.0,
        );
        let r = m.execute(
            &frame(Command::ReadBack {
                program: 4,
                instruction: 2,
            }),
            0.0,
        );
        assert_eq!(
            r,
            Some(Reply::ReadBack {
                program: 4,
                instruction: 2,
                stored: Some(Instruction::Position(p))
            })
        );
        assert_eq!(m.used_units(), POSITION_UNITS);
        m.execute(&frame(Command::DeleteProgram { program: 4 }), 0.0);
        assert_eq!(m.used_units(), 0);
        m.execute(&frame(Command::DeleteProgram { program: 4 }), 0.0);
        assert_eq!(m.last_error(), RobotError::NoProgram.code());
        // A telegram that does not parse sets an error and changes nothing.
        m.execute(
            &Frame {
                code: 0x01,
                data: vec![0; 3],
            },
            0.0,
        );
        assert_eq!(m.last_error(), RobotError::Length.code());
        m.execute(
            &Frame {
                code: 0x20,
                data: vec![],
            },
            0.0,
        );
        assert_eq!(m.last_error(), RobotError::UnknownCommand.code());
        // A bad quaternion is refused.
        let mut bad = p;
        bad.pose.q = Quaternion([16384, 16384, 0, 0]);
        m.execute(
            &frame(Command::StorePos {
                program: 1,
                instruction: 1,
                positioning: bad,
            }),
            0.0,
        );
        assert_eq!(m.last_error(), RobotError::Range.code());
        assert_eq!(m.program_len(1), 0);
    }

    /// The link idles the arm (seed 001 §4.1.2): while the robot computer serves a session the
    /// arm stands where it was, and its move, and a home synchronisation, end later by as long
    /// as the session lasted.
    #[test]
    fn a_link_session_holds_the_arm_and_the_move_ends_later_by_as_much() {
        let mut m = homed_operate();
        move_immediate(&mut m, [900.0, 400.0, 800.0], Reference::Absolute, 10.0);
        let planned_end = m.trajectory().unwrap().t1();
        m.advance(10.2);
        let held = m.pose().xyz_mm;
        m.hold(10.5);
        assert_eq!(m.pose().xyz_mm, held);
        m.advance(10.5);
        assert_eq!(m.pose().xyz_mm, held, "0.3 s of link: no motion");
        m.advance(planned_end + 0.29);
        assert!(!m.io().output(IN_POSITION_OUTPUT));
        m.advance(planned_end + 0.31);
        assert!(m.io().output(IN_POSITION_OUTPUT));
        // Home synchronisation (3 s) held 1 s ends at 4 s.
        let mut m = Machine::default();
        m.execute(&frame(Command::Operate), 0.0);
        m.execute(&frame(Command::SyncHome), 0.0);
        m.advance(1.0);
        m.hold(2.0);
        m.advance(3.9);
        assert!(!m.homed());
        m.advance(4.01);
        assert!(m.homed());
    }

    /// The same through the robot's side of the link: an ENQ opens a session while the arm
    /// moves and the host's EOT closes it 0.3 s later; the arm stood still meanwhile. With
    /// `link_idles_arm` off it moves on.
    #[test]
    fn the_robot_holds_its_arm_from_enq_to_eot() {
        use crate::frame::{ENQ, EOT};
        let at = |s: f64| Duration::from_secs_f64(s);
        for idles in [true, false] {
            let params = MotionParams {
                link_idles_arm: idles,
                ..MotionParams::default()
            };
            let mut r = Robot::new(FrameConfig::default(), Timers::default(), params);
            r.machine.execute(&frame(Command::Operate), 0.0);
            r.machine.execute(&frame(Command::SyncHome), 0.0);
            r.poll(at(3.0));
            move_immediate(
                &mut r.machine,
                [900.0, 400.0, 800.0],
                Reference::Absolute,
                10.0,
            );
            r.poll(at(10.2));
            let y0 = r.machine.pose().xyz_mm[1];
            r.receive(&[ENQ], at(10.2));
            assert!(r.session.in_session());
            r.poll(at(10.4));
            r.receive(&[EOT], at(10.5));
            let y1 = r.machine.pose().xyz_mm[1];
            if idles {
                assert_eq!(y1, y0);
            } else {
                assert!(y1 > y0 + 10.0, "{y0} {y1}");
            }
        }
    }

    /// A STOP leaves the arm where its braking ends, and that is where the robot stands: a
    /// relative move after it goes from there, and once the ramp is over (v/a) the robot takes
    /// the next move. A STOP while the arm already rests (settling at the end of a move) leaves
    /// it where it is.
    #[test]
    fn after_a_stop_the_next_move_starts_where_the_arm_came_to_rest() {
        // Down from home (900, 0, 800) towards z = 400, in the xz plane, so that the relative
        // move's level roll axis (+x) stays radial.
        let mut m = homed_operate();
        move_immediate(&mut m, [900.0, 0.0, 400.0], Reference::Absolute, 10.0);
        m.advance(10.3);
        let v =
            (m.trajectory().unwrap().pose_at(10.3 - 1e-3).xyz_mm[2] - m.pose().xyz_mm[2]) / 1e-3;
        assert!(v > 100.0, "{v}");
        let z_stop = m.pose().xyz_mm[2];
        m.execute(&frame(Command::Stop), 10.3);
        let a = MotionParams::default().accel_mm_s2;
        // Half way through the ramp, v·t − a·t²/2 = 3v²/8a further on.
        m.advance(10.3 + v / (2.0 * a));
        let mid = m.pose().xyz_mm[2];
        assert!(
            (z_stop - mid - 3.0 * v * v / (8.0 * a)).abs() < 0.05,
            "{z_stop} {mid} {v}"
        );
        m.advance(10.3 + v / a + 1e-3);
        let rest = m.pose().xyz_mm;
        assert!(rest[2] > 400.0);
        assert!((z_stop - rest[2] - v * v / (2.0 * a)).abs() < 0.05);
        move_immediate(
            &mut m,
            [0.0, 0.0, 10.0],
            Reference::Relative,
            10.3 + v / a + 1e-3,
        );
        assert_eq!(m.status().last_error, 0, "taken once the ramp is over");
        assert_eq!(m.status().state, State::Running);
        m.advance(20.0);
        let end = m.pose().xyz_mm;
        assert!((end[2] - rest[2] - 10.0).abs() < 1e-6, "{rest:?} {end:?}");
        assert!((end[0] - rest[0]).abs() < 1e-6 && (end[1] - rest[1]).abs() < 1e-6);

        // At rest in the settling time of a move: the STOP leaves the arm at the point.
        let mut m = homed_operate();
        move_immediate(&mut m, [900.0, 0.0, 750.0], Reference::Absolute, 10.0);
        let t1 = m.trajectory().unwrap().t1();
        m.advance(t1 - 0.05);
        let here = m.pose().xyz_mm;
        assert!((here[2] - 750.0).abs() < 1e-9, "settling at the point");
        m.execute(&frame(Command::Stop), t1 - 0.05);
        m.advance(t1 + 1.0);
        move_immediate(&mut m, [0.0, 0.0, 10.0], Reference::Relative, t1 + 1.0);
        m.advance(t1 + 10.0);
        let end = m.pose().xyz_mm;
        assert!(end.iter().all(|c| c.is_finite()), "{end:?}");
        assert!((end[2] - 760.0).abs() < 1e-6, "{end:?}");
    }

    /// The six lines are six bits: each line is driven and read on its own, and clearing one
    /// leaves the others.
    #[test]
    fn io_lines_are_independent() {
        let io = IoLines::default();
        io.set_input(1, true);
        io.set_input(3, true);
        assert!(io.input(1) && !io.input(2) && io.input(3) && !io.input(6));
        io.set_input(3, false);
        assert!(io.input(1) && !io.input(3));
        io.set_input(6, true);
        assert!(io.input(6) && !io.input(5));
    }

    /// The machine's own accessors and switches: the mode it is in, the kinematic model it was
    /// given (the radius model takes a wrist yaw the five-axis arm refuses), and the count of
    /// stores executed twice (the same instruction into the same slot; another instruction into
    /// it is a new store).
    #[test]
    fn mode_kinematics_and_repeated_stores() {
        let mut m = Machine::default();
        assert_eq!(m.mode(), Mode::Standby);
        m.execute(&frame(Command::Operate), 0.0);
        assert_eq!(m.mode(), Mode::Operate);
        m.execute(&frame(Command::Standby), 0.0);
        assert_eq!(m.mode(), Mode::Standby);

        // A roll axis 20° out of the arm's plane: a wrist yaw.
        let h = 10f64.to_radians();
        let mut yawed = pos([900.0, 0.0, 800.0], Reference::Absolute);
        yawed.pose = Pose::from_mm([900.0, 0.0, 800.0], [h.cos(), 0.0, 0.0, h.sin()]).unwrap();
        let store = |m: &mut Machine, p: Positioning| {
            m.execute(
                &frame(Command::StorePos {
                    program: 5,
                    instruction: 1,
                    positioning: p,
                }),
                0.0,
            );
        };
        let mut arm = Machine::default();
        store(&mut arm, yawed);
        arm.execute(&frame(Command::RunProgram { program: 5 }), 0.0);
        assert_eq!(arm.last_error(), RobotError::Kinematics.code());
        let mut radius = Machine::default().with_kinematics(Arc::new(Reach::default()));
        store(&mut radius, yawed);
        radius.execute(&frame(Command::RunProgram { program: 5 }), 0.0);
        assert_eq!(radius.last_error(), 0);

        let mut m = Machine::default();
        let p = pos([900.0, 0.0, 800.0], Reference::Absolute);
        store(&mut m, p);
        assert_eq!(m.redundant_stores(), 0);
        store(&mut m, p);
        assert_eq!(m.redundant_stores(), 1);
        store(&mut m, pos([900.0, 0.0, 700.0], Reference::Absolute));
        assert_eq!(m.redundant_stores(), 1);
        store(&mut m, pos([900.0, 0.0, 700.0], Reference::Absolute));
        assert_eq!(m.redundant_stores(), 2);
    }

    /// A program checked in standby stops at its first bad instruction in the error state; an
    /// immediate move with a quaternion far from unit length is refused (error 3) and the arm
    /// does not move.
    #[test]
    fn bad_positions_are_refused() {
        let mut m = Machine::default();
        m.execute(
            &frame(Command::StorePos {
                program: 6,
                instruction: 1,
                positioning: pos([900.0, 0.0, 800.0], Reference::Absolute),
            }),
            0.0,
        );
        // 2000 mm out: inside the wire's range, beyond the arm's reach.
        let far = pos([2000.0, 0.0, 800.0], Reference::Absolute);
        m.execute(
            &frame(Command::StorePos {
                program: 6,
                instruction: 2,
                positioning: far,
            }),
            0.0,
        );
        m.execute(&frame(Command::RunProgram { program: 6 }), 0.0);
        let s = m.status();
        assert_eq!(s.state, State::Error);
        assert_eq!(s.instruction, 2);
        assert_eq!(s.last_error, RobotError::Kinematics.code());

        let mut m = homed_operate();
        let mut half = pos([900.0, 0.0, 700.0], Reference::Absolute);
        // Q1.14: 8192 is 0.5, a quaternion of norm 0.5 (the host normalises; the wire does not).
        half.pose.q = crate::command::Quaternion([8192, 0, 0, 0]);
        m.execute(&frame(Command::MoveImmediate(half)), 10.0);
        assert_eq!(m.last_error(), RobotError::Range.code());
        m.advance(20.0);
        assert_eq!(m.pose().xyz_mm, MotionParams::default().home.xyz_mm);
    }

    /// The base speed scales every instruction's fraction, the maximum caps it: a 100 mm stop
    /// move at 0.25 of a 0.5 m/s base runs at 125 mm/s and takes 0.5 s of settling + 0.8 s +
    /// the ramp's v/a; with the maximum set to 0.0625 m/s a move at 0.5 of the 1 m/s base runs
    /// at 62.5 mm/s. (Every figure is exact on the wire's 1/8192 m/s.)
    #[test]
    fn base_speed_scales_and_maximum_caps() {
        let a = MotionParams::default().accel_mm_s2;
        let run = |base: f64, max: f64, frac: f64| {
            let mut m = homed_operate();
            for c in [
                Command::SetBaseSpeed(Speed::from_value("base", base).unwrap()),
                Command::SetMaxSpeed(Speed::from_value("max", max).unwrap()),
            ] {
                m.execute(&frame(c), 5.0);
                assert_eq!(m.last_error(), 0);
            }
            let mut p = pos([900.0, 0.0, 700.0], Reference::Absolute);
            p.speed = Speed::from_value("speed", frac).unwrap();
            m.execute(&frame(Command::MoveImmediate(p)), 10.0);
            m.trajectory().unwrap().t1() - 10.0
        };
        let want = |v: f64| 0.5 + 100.0 / v + v / a;
        assert!((run(0.5, 2.0, 0.25) - want(125.0)).abs() < 1e-9);
        assert!((run(1.0, 0.0625, 0.5) - want(62.5)).abs() < 1e-9);
    }

    /// A program may not be deleted while it runs (error 7); another one may.
    #[test]
    fn a_running_program_cannot_be_deleted() {
        let mut m = homed_operate();
        for program in [1, 2] {
            m.execute(
                &frame(Command::StorePos {
                    program,
                    instruction: 1,
                    positioning: pos([900.0, 0.0, 400.0], Reference::Absolute),
                }),
                5.0,
            );
        }
        m.execute(&frame(Command::RunProgram { program: 1 }), 10.0);
        m.advance(10.1);
        assert_eq!(m.status().state, State::Running);
        m.execute(&frame(Command::DeleteProgram { program: 2 }), 10.1);
        assert_eq!(m.last_error(), 0);
        m.execute(&frame(Command::DeleteProgram { program: 1 }), 10.1);
        assert_eq!(m.last_error(), RobotError::Busy.code());
    }

    /// A `WaitInput` whose input is already at its level does not wait: the program runs on to
    /// its move at once.
    #[test]
    fn a_wait_for_an_input_already_set_does_not_wait() {
        let mut m = homed_operate();
        let store = |m: &mut Machine, n: u16, i: Instruction| {
            m.execute(&frame(crate::client::store_command(3, n, &i)), 5.0);
        };
        store(
            &mut m,
            1,
            Instruction::Control(Control::SetOutput { line: 2, on: true }),
        );
        store(
            &mut m,
            2,
            Instruction::Control(Control::WaitInput {
                line: START_INPUT,
                on: true,
            }),
        );
        store(
            &mut m,
            3,
            Instruction::Position(pos([900.0, 0.0, 700.0], Reference::Absolute)),
        );
        store(&mut m, 4, Instruction::Control(Control::End));
        m.io().set_input(START_INPUT, true);
        m.execute(&frame(Command::RunProgram { program: 3 }), 10.0);
        m.advance(10.1);
        assert!(m.io().output(2));
        assert!(m.pose().xyz_mm[2] < 800.0, "moving at once: {:?}", m.pose());
        m.advance(20.0);
        assert_eq!(m.pose().xyz_mm, [900.0, 0.0, 700.0]);
        assert_eq!(m.status().state, State::Idle);
    }

    /// The record of executed telegrams keeps the last [`RECORD_LIMIT`] at most: at the limit it
    /// drops the older half.
    #[test]
    fn the_executed_record_is_bounded() {
        let mut m = Machine::default();
        for _ in 0..RECORD_LIMIT + 10 {
            m.execute(&frame(Command::Enquire(Selector::Status)), 0.0);
        }
        assert_eq!(m.executed.len(), RECORD_LIMIT / 2 + 10);
    }

    /// Bytes written, each with the clock time of its write.
    type Writes = Arc<std::sync::Mutex<Vec<(Duration, Vec<u8>)>>>;

    /// A line for [`serve`] on a virtual clock: each read waits its whole timeout (the clock
    /// runs on by it) unless a scripted byte is due within it, which it then returns at its time;
    /// every write is noted with its time; once the script is done and the clock has passed
    /// `until` it stops the server.
    struct ScriptedLine {
        clock: Arc<crate::clock::VirtualClock>,
        script: Vec<(Duration, Vec<u8>)>,
        writes: Writes,
        stop: Arc<AtomicBool>,
        until: Duration,
    }

    impl Link for ScriptedLine {
        fn write_all(&mut self, bytes: &[u8]) -> std::io::Result<()> {
            self.writes
                .lock()
                .unwrap()
                .push((self.clock.now(), bytes.to_vec()));
            Ok(())
        }
        fn read_timeout(&mut self, buf: &mut [u8], timeout: Duration) -> std::io::Result<usize> {
            let now = self.clock.now();
            if let Some((at, bytes)) = self.script.first().cloned()
                && at <= now + timeout
            {
                self.clock.advance_to(at.max(now));
                self.script.remove(0);
                buf[..bytes.len()].copy_from_slice(&bytes);
                return Ok(bytes.len());
            }
            self.clock.advance(timeout);
            if self.script.is_empty() && self.clock.now() > self.until {
                self.stop.store(true, Ordering::Relaxed);
            }
            Ok(0)
        }
        fn discard_input(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    /// The simulator answers bytes [`TURNAROUND`] after they came, once, and not sooner: an ENQ
    /// at 10 ms is acknowledged at 13 ms.
    #[test]
    fn serve_answers_after_the_turnaround() {
        use crate::frame::{ACK, ENQ};
        let clock = Arc::new(crate::clock::VirtualClock::new());
        let writes = Arc::new(std::sync::Mutex::new(Vec::new()));
        let stop = Arc::new(AtomicBool::new(false));
        let line = ScriptedLine {
            clock: clock.clone(),
            script: vec![(Duration::from_millis(10), vec![ENQ])],
            writes: writes.clone(),
            stop: stop.clone(),
            until: Duration::from_millis(60),
        };
        let robot = std::sync::Mutex::new(Robot::default());
        serve(line, &robot, clock.as_ref(), &stop).unwrap();
        let writes = writes.lock().unwrap();
        assert_eq!(
            *writes,
            vec![(Duration::from_millis(10) + TURNAROUND, vec![ACK])]
        );
    }

    /// What a timer prompts goes out without the turnaround: the robot's reply session opens
    /// with its ENQ 3 ms after the host's EOT (bytes prompted it), and when the host does not
    /// answer, the ENQ is sent again when the robot's own timer says, within the loop's poll
    /// period.
    #[test]
    fn serve_sends_what_a_timer_prompts_at_once() {
        use crate::frame::{ACK, ENQ, EOT};
        let clock = Arc::new(crate::clock::VirtualClock::new());
        let writes = Arc::new(std::sync::Mutex::new(Vec::new()));
        let stop = Arc::new(AtomicBool::new(false));
        let status_again = || {
            Command::Enquire(Selector::Status)
                .encode(&FrameConfig::default())
                .unwrap()
        };
        let status = status_again();
        let ms = Duration::from_millis;
        let line = ScriptedLine {
            clock: clock.clone(),
            script: vec![(ms(10), vec![ENQ]), (ms(20), status), (ms(40), vec![EOT])],
            writes: writes.clone(),
            stop: stop.clone(),
            until: ms(43) + crate::session::T_ENQ + ms(5),
        };
        let robot = std::sync::Mutex::new(Robot::default());
        serve(line, &robot, clock.as_ref(), &stop).unwrap();
        let writes = writes.lock().unwrap();
        // The same robot driven by hand: its reply session's ENQ comes with the EOT, and its
        // own timer asks for the ENQ again at its next deadline.
        let mut r = Robot::default();
        r.receive(&[ENQ], ms(10));
        r.receive(&status_again(), ms(20));
        r.take_output();
        r.receive(&[EOT], ms(40));
        r.poll(ms(40));
        assert!(r.take_output().contains(&ENQ));
        let retry = r.deadline().expect("the ENQ's timer");
        assert!(retry >= ms(40) + crate::session::T_ENQ, "{retry:?}");
        assert_eq!(
            writes[..3],
            [
                (ms(13), vec![ACK]),
                (ms(23), vec![ACK]),
                (ms(43), vec![ENQ]),
            ]
        );
        // The loop looks at the robot's timers once a poll period: the retry goes within one
        // of its deadline, with no turnaround added.
        let (at, bytes) = &writes[3];
        assert_eq!(bytes, &vec![ENQ]);
        assert!(
            *at >= retry && *at <= retry + POLL_PERIOD,
            "{at:?} {retry:?}"
        );
    }
}
