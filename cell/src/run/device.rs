//! The devices the coordinator drives (seed 001 §4.1, §5.3, App. D): the robot computer, the
//! mandrel indexer and the opto-isolated sync lines, each behind a small trait, with the
//! protocol-backed implementations over a byte link (a serial port, or the in-memory link to the
//! simulated cell of [`crate::sim`]).
//!
//! The coordinator never touches a telegram or an X-language command: it asks a [`RobotDevice`]
//! to move, store, run or stop, a [`MandrelDevice`] to move (at once or armed on the start line)
//! or stop, and a [`SyncLines`] for the start output and the in-position and e-stop inputs. Time
//! comes from a [`Timebase`]: the wall clock on a real cell, the simulated cell's one virtual
//! clock otherwise, so the same coordinator code runs both.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use asea_protocol::{Client, Instruction, Mode, Positioning, Speed, State};
use mandrel_drive::XClient;
use mandrel_drive::sync::{SyncInput, SyncOutput};
use mandrel_drive::xlang::{Command as X, Reply as XReply};
use paths::link::{Cancel, Clock, Link};
use sequences::MandrelMove;

use crate::run::transfer::{self, IndexerSetup};

/// A device failure: which device, and what its client said.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum DeviceError {
    /// The robot link or the robot computer.
    #[error("robot: {0}")]
    Robot(#[from] asea_protocol::Error),
    /// The indexer link or the indexer.
    #[error("indexer: {0}")]
    Indexer(#[from] mandrel_drive::Error),
    /// A sync line could not be read or driven.
    #[error("sync lines: {0}")]
    Sync(std::io::Error),
    /// The robot's observable state does not show what a command asked for.
    #[error("robot: {what}")]
    RobotState {
        /// What was expected and what was seen.
        what: String,
    },
    /// A conversion of a control-file value failed (a bug: the pre-run check converts them all).
    #[error("{0}")]
    Transfer(Box<crate::Error>),
}

/// Result of a device operation.
pub type DeviceResult<T> = Result<T, DeviceError>;

/// Abandons a device's exchange under way from another thread: the link's cancel token
/// ([`paths::link::Cancel`], the same for both devices). The exchange ends with a cancelled
/// error at its next read; the device's stop still goes through.
pub trait Interrupt: Send + Sync + std::fmt::Debug {
    /// Cancels the exchange under way and every later one until [`Interrupt::clear`].
    fn interrupt(&self);
    /// Lets exchanges run again.
    fn clear(&self);
}

impl Interrupt for Cancel {
    fn interrupt(&self) {
        self.cancel();
    }
    fn clear(&self) {
        self.reset();
    }
}

/// True when `e` is an exchange abandoned through the device's [`Interrupt`].
pub fn is_interrupted(e: &DeviceError) -> bool {
    matches!(
        e,
        DeviceError::Robot(asea_protocol::Error::Cancelled)
            | DeviceError::Indexer(mandrel_drive::Error::Cancelled)
    )
}

/// The time the coordinator waits in: wall time on a real cell, the simulated cell's clock on a
/// simulated one (where sleeping lets both simulators run).
pub trait Timebase: Send + Sync + std::fmt::Debug {
    /// Seconds since the epoch of this timebase.
    fn now_s(&self) -> f64;
    /// Lets `dt` pass.
    fn sleep(&self, dt: Duration);
    /// Lets at most `dt` pass while the coordinator polls: a stop request may end it early
    /// (the wall clock parks the thread, [`crate::run::coordinator::StopRequest::request`] unparks it).
    fn tick(&self, dt: Duration) {
        self.sleep(dt);
    }
}

/// Wall-clock time ([`paths::link::WallClock`], the devices' wall clock).
pub use paths::link::WallClock;

impl Timebase for WallClock {
    fn now_s(&self) -> f64 {
        Clock::now_s(self)
    }
    fn sleep(&self, dt: Duration) {
        std::thread::sleep(dt);
    }
    fn tick(&self, dt: Duration) {
        std::thread::park_timeout(dt);
    }
}

/// The robot's state as the coordinator needs it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RobotState {
    /// Operate (true) or standby.
    pub operate: bool,
    /// Idle, running, homing or error.
    pub state: State,
    /// The instruction under way (program mode), 0 otherwise.
    pub instruction: u16,
    /// Home synchronised.
    pub homed: bool,
    /// The robot's error code, 0 for none.
    pub last_error: u8,
}

/// The robot computer as the coordinator drives it (seed 001 §5.3–5.4).
pub trait RobotDevice: Send {
    /// Status (mode, state, instruction, homed, error).
    fn state(&mut self) -> DeviceResult<RobotState>;
    /// The first exchange of a run: the link resynchronised (a quiet line, stale bytes
    /// dropped, a query whose answer is recognised as its own), then the status. By default the
    /// status alone.
    fn attach(&mut self) -> DeviceResult<RobotState> {
        self.state()
    }
    /// The eye position, mm, cell frame.
    fn position_mm(&mut self) -> DeviceResult<[f64; 3]>;
    /// Base and maximum speed (the control file's header, §5.4.1).
    fn set_speeds(&mut self, base: Speed, max: Speed) -> DeviceResult<()>;
    /// Operate (true) or standby (false) mode (§5.3.1).
    fn set_operate(&mut self, operate: bool) -> DeviceResult<()>;
    /// Starts home synchronisation.
    fn start_home(&mut self) -> DeviceResult<()>;
    /// A discrete move, executed at once (§5.4.1).
    fn move_immediate(&mut self, p: Positioning) -> DeviceResult<()>;
    /// Deletes `program` if stored (no error when it is not).
    fn delete_program(&mut self, program: u8) -> DeviceResult<()>;
    /// Stores `instructions` as program `program` with verified stores (read back), calling
    /// `progress` after each instruction stored and after each verified.
    fn upload(
        &mut self,
        program: u8,
        instructions: &[Instruction],
        progress: &mut dyn FnMut(),
    ) -> DeviceResult<()>;
    /// Reads the whole program back and compares it with `instructions`, calling `progress`
    /// after each instruction.
    fn read_back(
        &mut self,
        program: u8,
        instructions: &[Instruction],
        progress: &mut dyn FnMut(),
    ) -> DeviceResult<()>;
    /// Runs a stored program.
    fn run_program(&mut self, program: u8) -> DeviceResult<()>;
    /// Stops motion at once (STOP).
    fn stop(&mut self) -> DeviceResult<()>;
    /// What abandons this device's exchange under way from another thread, if it can be.
    fn interrupter(&self) -> Option<Arc<dyn Interrupt>> {
        None
    }
}

/// The mandrel indexer as the coordinator drives it (seed 001 §5.3.2, §5.6.2).
pub trait MandrelDevice: Send {
    /// Attaches without zeroing: the link resynchronised, a move still under way waited out (a
    /// move armed on the start line that nobody will start cancelled), then the indexer's step
    /// counter as it stands.
    fn attach(&mut self) -> DeviceResult<i64>;
    /// Zeroes the step counter (`.IND` init).
    fn zero(&mut self) -> DeviceResult<()>;
    /// Starts a move at once (`armed` false) or arms it on the start line (`armed` true).
    fn start_move(&mut self, mv: &MandrelMove, armed: bool) -> DeviceResult<()>;
    /// (busy, fault): moving or waiting for its trigger; stalled or refused.
    fn busy(&mut self) -> DeviceResult<(bool, bool)>;
    /// The step counter (only at rest: the X-language reports it when its buffer is empty).
    fn counter_steps(&mut self) -> DeviceResult<i64>;
    /// Steps since the start of the current or last move (the X-language's `W3`, answered at
    /// once even while a move is buffered).
    fn move_steps(&mut self) -> DeviceResult<i64>;
    /// Stops with deceleration and clears an armed move.
    fn stop(&mut self) -> DeviceResult<()>;
    /// Puts the stop command on the wire at once without waiting for an answer (the first step
    /// of a stop of both devices; [`MandrelDevice::stop`] follows and confirms it). By default
    /// nothing: `stop` alone does it.
    fn stop_on_wire(&mut self) -> DeviceResult<()> {
        Ok(())
    }
    /// What abandons this device's exchange under way from another thread, if it can be.
    fn interrupter(&self) -> Option<Arc<dyn Interrupt>> {
        None
    }
}

/// The sync lines seen from the PC (App. D): start out, in position in, e-stop in.
pub trait SyncLines: Send + std::fmt::Debug {
    /// Drives the start output (to the robot's input and the indexer's trigger together).
    fn set_start(&mut self, on: bool) -> DeviceResult<()>;
    /// The robot's "in position" output, as the PC receives it.
    fn in_position(&mut self) -> DeviceResult<bool>;
    /// The e-stop input (true = pressed).
    fn estop(&mut self) -> DeviceResult<bool>;
    /// False when no sync lines are wired (discrete mode only: completion is read from the
    /// robot's status instead).
    fn wired(&self) -> bool {
        true
    }
}

/// No sync lines: a cell whose robot and indexer are on serial ports without a sync port (or
/// two pseudo-terminals). Discrete mode works; program mode needs the lines and is refused.
#[derive(Debug, Clone, Copy, Default)]
pub struct NoSync;

fn unwired() -> DeviceError {
    DeviceError::Sync(std::io::Error::other(
        "no sync lines are wired (name a sync port in the cell file)",
    ))
}

impl SyncLines for NoSync {
    fn set_start(&mut self, on: bool) -> DeviceResult<()> {
        if on { Err(unwired()) } else { Ok(()) }
    }
    fn in_position(&mut self) -> DeviceResult<bool> {
        Err(unwired())
    }
    fn estop(&mut self) -> DeviceResult<bool> {
        Ok(false)
    }
    fn wired(&self) -> bool {
        false
    }
}

/// The robot over its telegram link ([`asea_protocol::Client`]).
#[derive(Debug)]
pub struct ProtocolRobot<L, C> {
    client: Client<L, C>,
}

impl<L: Link, C: Clock> ProtocolRobot<L, C> {
    /// Drives the robot through `client`.
    pub fn new(client: Client<L, C>) -> Self {
        ProtocolRobot { client }
    }

    /// A command confirmed by the client (docs/protocol.md §7: executed once, proven by the
    /// status; a latched robot error is reported and acknowledged).
    fn confirmed(
        &mut self,
        f: impl FnOnce(&mut Client<L, C>) -> asea_protocol::Result<asea_protocol::Status>,
    ) -> DeviceResult<()> {
        f(&mut self.client)?;
        Ok(())
    }
}

fn robot_state(s: &asea_protocol::Status) -> RobotState {
    RobotState {
        operate: s.mode == Mode::Operate,
        state: s.state,
        instruction: s.instruction,
        homed: s.homed,
        last_error: s.last_error,
    }
}

impl<L: Link, C: Clock> RobotDevice for ProtocolRobot<L, C> {
    fn state(&mut self) -> DeviceResult<RobotState> {
        Ok(robot_state(&self.client.status()?))
    }

    fn attach(&mut self) -> DeviceResult<RobotState> {
        Ok(robot_state(&self.client.attach()?))
    }

    fn position_mm(&mut self) -> DeviceResult<[f64; 3]> {
        Ok(self.client.position()?.xyz_mm())
    }

    fn set_speeds(&mut self, base: Speed, max: Speed) -> DeviceResult<()> {
        self.client.set_base_speed(base)?;
        self.confirmed(|c| c.set_max_speed(max))
    }

    fn set_operate(&mut self, operate: bool) -> DeviceResult<()> {
        if operate {
            self.confirmed(Client::operate)
        } else {
            self.confirmed(Client::standby)
        }
    }

    fn start_home(&mut self) -> DeviceResult<()> {
        self.confirmed(Client::sync_home)
    }

    fn move_immediate(&mut self, p: Positioning) -> DeviceResult<()> {
        self.confirmed(|c| c.move_immediate(p))
    }

    fn delete_program(&mut self, program: u8) -> DeviceResult<()> {
        match self.client.delete_program(program) {
            // "No such program" is what we wanted (the client acknowledged the error).
            Err(asea_protocol::Error::Robot { code, .. })
                if code == asea_protocol::RobotError::NoProgram.code() =>
            {
                Ok(())
            }
            r => r.map(|_| ()).map_err(Into::into),
        }
    }

    fn upload(
        &mut self,
        program: u8,
        instructions: &[Instruction],
        progress: &mut dyn FnMut(),
    ) -> DeviceResult<()> {
        self.client
            .upload_verified_reporting(program, instructions, progress)?;
        Ok(())
    }

    fn read_back(
        &mut self,
        program: u8,
        instructions: &[Instruction],
        progress: &mut dyn FnMut(),
    ) -> DeviceResult<()> {
        for (n, want) in (1u16..).zip(instructions) {
            if !self.client.confirm_stored(program, n, want)? {
                return Err(DeviceError::RobotState {
                    what: format!(
                        "program {program} instruction {n} does not read back as uploaded"
                    ),
                });
            }
            progress();
        }
        Ok(())
    }

    fn run_program(&mut self, program: u8) -> DeviceResult<()> {
        self.confirmed(|c| c.run_program(program))
    }

    fn stop(&mut self) -> DeviceResult<()> {
        // STOP first, then its confirmation: no status exchange delays it.
        self.client.stop_at_once()?;
        Ok(())
    }

    fn interrupter(&self) -> Option<Arc<dyn Interrupt>> {
        Some(Arc::new(self.client.cancel_token()))
    }
}

/// The indexer over its X-language link ([`mandrel_drive::XClient`]); commands built by
/// [`crate::run::transfer::indexer_move`].
#[derive(Debug)]
pub struct XIndexer<L: Link, C = WallClock> {
    client: XClient<L, C>,
    setup: IndexerSetup,
}

impl<L: Link, C: Clock> XIndexer<L, C> {
    /// Drives the indexer through `client` with the drive of `setup`.
    pub fn new(client: XClient<L, C>, setup: IndexerSetup) -> Self {
        XIndexer { client, setup }
    }

    fn send(&mut self, cmd: &X) -> DeviceResult<Option<XReply>> {
        Ok(self.client.send(cmd)?)
    }
}

impl<L: Link, C: Clock> MandrelDevice for XIndexer<L, C> {
    fn attach(&mut self) -> DeviceResult<i64> {
        // Not `Z` or `PZ`: a restarted coordinator must find the mandrel where it is. The
        // client's attach waits for a quiet line, recognises the status among stale lines and
        // polls until the card is at rest before it asks the position (`PR`, which a busy card
        // would answer only when its buffer reaches it).
        let s = self.client.attach()?;
        match s.position_steps {
            Some(n) => Ok(n),
            None => self.counter_steps(),
        }
    }

    fn zero(&mut self) -> DeviceResult<()> {
        self.send(&X::Zero)?;
        Ok(())
    }

    fn start_move(&mut self, mv: &MandrelMove, armed: bool) -> DeviceResult<()> {
        let cmds = transfer::indexer_move(mv, &self.setup, None)
            .map_err(|e| DeviceError::Transfer(Box::new(e)))?;
        // No move-complete notification (`CR`): arriving while a command is echoed byte by byte
        // it would split the echo; the coordinator polls `R` instead.
        for cmd in cmds.iter().filter(|c| **c != X::Notify) {
            if armed && *cmd == X::Go {
                // The move waits in the indexer's buffer for the start line (TR1, §2.2).
                self.send(&X::Trigger("1".into()))?;
            }
            self.send(cmd)?;
        }
        Ok(())
    }

    fn busy(&mut self) -> DeviceResult<(bool, bool)> {
        match self.send(&X::Status)? {
            Some(XReply::Status { busy, attention }) => Ok((busy, attention)),
            _ => Err(DeviceError::Indexer(mandrel_drive::Error::BadReply {
                command: "R".into(),
                reply: String::new(),
                reason: "no status",
            })),
        }
    }

    fn counter_steps(&mut self) -> DeviceResult<i64> {
        match self.send(&X::Position)? {
            Some(XReply::Position(n)) => Ok(n),
            _ => Err(DeviceError::Indexer(mandrel_drive::Error::BadReply {
                command: "PR".into(),
                reply: String::new(),
                reason: "no position",
            })),
        }
    }

    fn move_steps(&mut self) -> DeviceResult<i64> {
        Ok(self.client.move_steps()?)
    }

    fn stop(&mut self) -> DeviceResult<()> {
        // The client's stop: stale input of an abandoned exchange dropped, `S` sent while the
        // cancel token is set.
        mandrel_drive::Indexer::stop(&mut self.client, mandrel_drive::StopKind::Decelerate)?;
        Ok(())
    }

    fn stop_on_wire(&mut self) -> DeviceResult<()> {
        Ok(self.client.stop_on_wire()?)
    }

    fn interrupter(&self) -> Option<Arc<dyn Interrupt>> {
        Some(Arc::new(self.client.cancel_token()))
    }
}

/// The indexer as a GRBL 1.1 / grblHAL controller's A axis ([`mandrel_drive::GrblClient`]):
/// each `.IND` move becomes `$113`/`$123` (the profile, sent when it changes) and one incremental
/// `G91 G1 A… F…` line. GRBL always starts a move from rest, so the move's start/stop velocity
/// is dropped (a slower start than the X-language's, never a faster one: no pull-in risk). It has
/// no trigger input, so a move cannot be armed on the start line: discrete mode only (the run
/// refuses program mode before it starts).
#[derive(Debug)]
pub struct GrblIndexer<L: Link, C = WallClock> {
    client: mandrel_drive::GrblClient<L, C>,
    setup: IndexerSetup,
    /// The profile last sent (`$113`, `$123`), so an unchanged one is not written again.
    profile: Option<mandrel_drive::Profile>,
    /// The counter where the current or last move started, steps.
    move_start_steps: i64,
}

/// How long [`GrblIndexer::attach`] waits for a move under way to end.
pub const GRBL_ATTACH_WAIT: Duration = Duration::from_secs(120);

impl<L: Link, C: Clock> GrblIndexer<L, C> {
    /// Drives the controller through `client` with the drive of `setup`.
    pub fn new(client: mandrel_drive::GrblClient<L, C>, setup: IndexerSetup) -> Self {
        GrblIndexer {
            client,
            setup,
            profile: None,
            move_start_steps: 0,
        }
    }

    fn status(&mut self) -> DeviceResult<mandrel_drive::IndexerStatus> {
        Ok(mandrel_drive::Indexer::status(&mut self.client)?)
    }
}

impl<L: Link, C: Clock> MandrelDevice for GrblIndexer<L, C> {
    fn attach(&mut self) -> DeviceResult<i64> {
        use mandrel_drive::Indexer as _;
        // A move under way is waited out (a soft reset during motion loses the position), then
        // the soft reset resynchronises the line (GRBL keeps its position through it at rest),
        // then the steps per degree and the A position as it stands; never `G92 A0`.
        let deadline = self.client.now() + GRBL_ATTACH_WAIT;
        while self.status()?.busy {
            if self.client.now() > deadline {
                return Err(DeviceError::Indexer(mandrel_drive::Error::Timeout {
                    command: "?".into(),
                    waited_ms: GRBL_ATTACH_WAIT.as_millis() as u64,
                }));
            }
            self.client.pause(Duration::from_millis(20))?;
        }
        self.client.stop(mandrel_drive::StopKind::Kill)?;
        self.profile = None;
        let spd = self.setup.drive.steps_per_deg();
        self.client
            .send(&mandrel_drive::grbl::Command::StepsPerDeg(spd))?;
        let steps = self.counter_steps()?;
        self.move_start_steps = steps;
        Ok(steps)
    }

    fn zero(&mut self) -> DeviceResult<()> {
        self.client.send(&mandrel_drive::grbl::Command::ZeroA)?;
        self.move_start_steps = 0;
        Ok(())
    }

    fn start_move(&mut self, mv: &MandrelMove, armed: bool) -> DeviceResult<()> {
        use mandrel_drive::Indexer as _;
        if armed {
            return Err(DeviceError::Indexer(mandrel_drive::Error::Unsupported {
                dialect: "GRBL",
                feature: "a move armed on the start line (no trigger input)",
            }));
        }
        // The X-language's conversion checks the move's figures against the drive (the same
        // pulse-rate limit); GRBL then takes the profile from rest.
        transfer::indexer_move(mv, &self.setup, None)
            .map_err(|e| DeviceError::Transfer(Box::new(e)))?;
        let profile = mandrel_drive::Profile {
            accel_rps2: mv.accel_rps2,
            start_rps: 0.0,
            max_rps: mv.max_rps,
        };
        if self.profile != Some(profile) {
            self.client.set_profile(profile)?;
            self.profile = Some(profile);
        }
        self.move_start_steps = self.counter_steps()?;
        self.client
            .move_to(mv.steps, mandrel_drive::PosMode::Incremental)?;
        Ok(())
    }

    fn busy(&mut self) -> DeviceResult<(bool, bool)> {
        let s = self.status()?;
        Ok((s.busy, s.fault))
    }

    fn counter_steps(&mut self) -> DeviceResult<i64> {
        self.status()?.position_steps.ok_or_else(|| {
            DeviceError::Indexer(mandrel_drive::Error::BadReply {
                command: "?".into(),
                reply: String::new(),
                reason: "no position",
            })
        })
    }

    fn move_steps(&mut self) -> DeviceResult<i64> {
        Ok(self.counter_steps()? - self.move_start_steps)
    }

    fn stop(&mut self) -> DeviceResult<()> {
        mandrel_drive::Indexer::stop(&mut self.client, mandrel_drive::StopKind::Decelerate)?;
        self.profile = None;
        Ok(())
    }

    fn stop_on_wire(&mut self) -> DeviceResult<()> {
        Ok(self.client.stop_on_wire()?)
    }

    fn interrupter(&self) -> Option<Arc<dyn Interrupt>> {
        Some(Arc::new(self.client.cancel_token()))
    }
}

/// Sync lines made of simulated wires ([`mandrel_drive::sync::Wire`]) or real modem-control
/// pins, plus an e-stop input.
#[derive(Debug)]
pub struct WiredSync {
    /// The PC's start output.
    pub start: Box<dyn SyncOutput>,
    /// The robot's in-position output as the PC sees it.
    pub in_position: Box<dyn SyncInput>,
    /// The e-stop input, if one is wired.
    pub estop: Option<Box<dyn SyncInput>>,
}

impl SyncLines for WiredSync {
    fn set_start(&mut self, on: bool) -> DeviceResult<()> {
        self.start.set(on).map_err(DeviceError::Sync)
    }
    fn in_position(&mut self) -> DeviceResult<bool> {
        self.in_position.level().map_err(DeviceError::Sync)
    }
    fn estop(&mut self) -> DeviceResult<bool> {
        match self.estop.as_mut() {
            Some(e) => e.level().map_err(DeviceError::Sync),
            None => Ok(false),
        }
    }
}

/// The sync lines of `windcell sim-cell`, offered on a local socket (one line each way: `start 1`,
/// `start 0` → `ok`; `lines` → `in_position <0|1> estop <0|1>`).
#[derive(Debug)]
pub struct SocketSync {
    reader: std::io::BufReader<std::os::unix::net::UnixStream>,
    writer: std::os::unix::net::UnixStream,
}

impl SocketSync {
    /// Connects to the socket at `path`.
    pub fn connect(path: &std::path::Path) -> std::io::Result<Self> {
        let writer = std::os::unix::net::UnixStream::connect(path)?;
        writer.set_read_timeout(Some(Duration::from_secs(2)))?;
        let reader = std::io::BufReader::new(writer.try_clone()?);
        Ok(SocketSync { reader, writer })
    }

    fn ask(&mut self, line: &str) -> DeviceResult<String> {
        use std::io::{BufRead, Write};
        writeln!(self.writer, "{line}").map_err(DeviceError::Sync)?;
        let mut answer = String::new();
        self.reader
            .read_line(&mut answer)
            .map_err(DeviceError::Sync)?;
        let answer = answer.trim().to_string();
        if answer.starts_with('?') || answer.is_empty() {
            return Err(DeviceError::Sync(std::io::Error::other(format!(
                "sync socket: `{line}` answered `{answer}`"
            ))));
        }
        Ok(answer)
    }

    fn lines(&mut self) -> DeviceResult<(bool, bool)> {
        let a = self.ask("lines")?;
        let f: Vec<&str> = a.split_whitespace().collect();
        match f.as_slice() {
            ["in_position", i, "estop", e] => Ok((*i == "1", *e == "1")),
            _ => Err(DeviceError::Sync(std::io::Error::other(format!(
                "sync socket: `lines` answered `{a}`"
            )))),
        }
    }
}

impl SyncLines for SocketSync {
    fn set_start(&mut self, on: bool) -> DeviceResult<()> {
        self.ask(if on { "start 1" } else { "start 0" }).map(|_| ())
    }
    fn in_position(&mut self) -> DeviceResult<bool> {
        Ok(self.lines()?.0)
    }
    fn estop(&mut self) -> DeviceResult<bool> {
        Ok(self.lines()?.1)
    }
}

/// An e-stop input that software can press (the simulated cell's button, tests).
#[derive(Debug, Clone, Default)]
pub struct EstopButton(pub Arc<AtomicBool>);

impl SyncInput for EstopButton {
    fn level(&mut self) -> std::io::Result<bool> {
        Ok(self.0.load(Ordering::Relaxed))
    }
}
