//! The indexer seam the coordinator drives (docs/mandrel-drive.md), for both dialects over a
//! [`Link`]: commands built from physical units at the mandrel through [`Drive`], replies checked,
//! timeouts and typed errors.

use std::time::Duration;

use paths::link::{Wait, read_within};

use crate::error::{Error, Result};
use crate::grbl;
use crate::link::{Clock, Link, WallClock};
use crate::profile::Profile;
use crate::units::Drive;
use crate::xlang::{self, Command, Reply, ReplyError};

/// How `move_to` reads its step count.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PosMode {
    /// Absolute position since init (X `MPA`, GRBL `G90`).
    Absolute,
    /// Relative to the current position (X `MPI`, GRBL `G91`).
    Incremental,
}

/// Direction of a constant-velocity run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Direction {
    /// Positive step count (X `H+`).
    Positive,
    /// Negative step count (X `H-`).
    Negative,
}

/// How to stop.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StopKind {
    /// Decelerate at the profile's acceleration (X `S`, GRBL feed hold / jog cancel).
    Decelerate,
    /// Stop at once (X `K`, GRBL soft reset).
    Kill,
}

/// Set-up of an indexer client.
#[derive(Debug, Clone, PartialEq)]
pub struct IndexerConfig {
    /// Motor, belt and translator.
    pub drive: Drive,
    /// X-language device address (1–255).
    pub address: u8,
    /// Wait after a reset (X `Z`: 1000 ms; GRBL: until the banner).
    pub reset_wait: Duration,
    /// Longest wait for one reply line.
    pub reply_timeout: Duration,
    /// X-language: the backend has a start/stop velocity command (`VS`, our simulator). Without
    /// it a profile with a start velocity is refused as [`Error::Unsupported`].
    pub start_velocity_command: bool,
    /// X-language: ask for the device-ID prefix on replies (`SSD1`) and check it.
    pub device_id: bool,
    /// X-language: no limit switches fitted (`LD3`).
    pub no_limit_switches: bool,
    /// GRBL: grblHAL rotary-axis mask to send as `$376` (`None` for classic GRBL).
    pub rotary_mask: Option<u8>,
    /// Longest [`XClient::attach`] waits for a move it finds under way (the move a killed run
    /// left the card finishing) before it fails with [`Error::StillMoving`].
    pub attach_wait: Duration,
}

impl Default for IndexerConfig {
    fn default() -> Self {
        IndexerConfig {
            drive: Drive::default(),
            address: 1,
            reset_wait: Duration::from_millis(1000),
            reply_timeout: Duration::from_millis(500),
            start_velocity_command: false,
            device_id: true,
            no_limit_switches: true,
            rotary_mask: None,
            attach_wait: Duration::from_secs(60),
        }
    }
}

/// What `status` reports.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IndexerStatus {
    /// Moving or resetting.
    pub busy: bool,
    /// A fault: our simulator's stall flag or a refused move (X attention), GRBL alarm.
    pub fault: bool,
    /// Absolute position in motor steps, where the dialect reports it while in this state.
    pub position_steps: Option<i64>,
}

/// The device-level seam the coordinator drives (docs/mandrel-drive.md).
pub trait Indexer {
    /// Resets the controller and sets resolution, limits and reply format.
    fn init(&mut self) -> Result<()>;
    /// Sets acceleration, start/stop velocity and maximum velocity (seed 001 §5.3.2).
    fn set_profile(&mut self, profile: Profile) -> Result<()>;
    /// Starts a preset move and returns once it is accepted.
    fn move_to(&mut self, steps: i64, mode: PosMode) -> Result<()>;
    /// Turns at constant velocity (mandrel rev/s) until stopped or re-speeded.
    fn run_constant(&mut self, mandrel_rps: f64, dir: Direction) -> Result<()>;
    /// Alternates between absolute positions `a` and `b`, `cycles` times (`None` = until stopped).
    fn alternate(&mut self, a: i64, b: i64, cycles: Option<u16>) -> Result<()>;
    /// Stops.
    fn stop(&mut self, kind: StopKind) -> Result<()>;
    /// Reads busy, fault and position.
    fn status(&mut self) -> Result<IndexerStatus>;
    /// The client's time: its clock's (wall time, or the virtual clock of a simulated link).
    fn now(&self) -> Duration;
    /// Lets `dt` of the client's time pass, reading the link meanwhile (what comes is kept for
    /// the next reply): on a simulated link the device runs meanwhile.
    fn pause(&mut self, dt: Duration) -> Result<()>;

    /// Polls [`Indexer::status`] until the drive is at rest; a fault is [`Error::Stalled`].
    fn wait_idle(&mut self, timeout: Duration) -> Result<IndexerStatus> {
        let deadline = self.now() + timeout;
        loop {
            let s = self.status()?;
            if s.fault {
                return Err(Error::Stalled);
            }
            if !s.busy {
                return Ok(s);
            }
            if self.now() >= deadline {
                return Err(Error::MoveTimeout {
                    waited_ms: timeout.as_millis() as u64,
                });
            }
            self.pause(Duration::from_millis(5))?;
        }
    }
}

/// Longest wait of one read: a cancelled exchange ends within this (of the client's time). The
/// one poll period of the shared plumbing ([`paths::link::POLL_PERIOD`]).
pub use paths::link::POLL_PERIOD;

/// A token that cancels a client's blocking exchanges from another thread or task: the read
/// under way returns [`Error::Cancelled`] within [`POLL_PERIOD`]. The stop commands (`S`, `K`) are
/// written without waiting and go through while it is set. The same token as the robot's
/// ([`paths::link::Cancel`]).
pub use paths::link::Cancel;

/// How often a card busy after its reset (`Z`) is asked for its status (`R`).
pub const RESET_POLL_PERIOD: Duration = Duration::from_millis(50);

/// How long the line must say nothing before [`XClient::attach`] asks its first question: a
/// stale line of the run before (an echo, a reply to a command the card had buffered) is a few
/// bytes at most 1 ms apart at 9600 baud; 100 ms of silence means its burst is over.
pub const ATTACH_QUIET: Duration = Duration::from_millis(100);

/// Longest [`XClient::attach`] waits for the line to go quiet before it fails with
/// [`Error::LineNotQuiet`] (something on the line keeps talking: not an indexer that answers).
pub const ATTACH_QUIET_LIMIT: Duration = Duration::from_secs(5);

/// A busy card whose step count (`W3`) has not moved for this long is not turning: a move armed
/// on the start line (`TR1`) that never saw its edge. [`XClient::attach`] stops it (`S`, which
/// also empties the card's buffer), as nobody will raise that edge for it.
pub const ARMED_STILL: Duration = Duration::from_millis(500);

/// How often [`XClient::attach`] asks a query that got no recognised answer within the reply
/// timeout before it gives up.
pub const RECOGNISED_ASKS: u32 = 3;

/// Reads lines ending in `end` (other line-end bytes dropped) from a link with a deadline.
#[derive(Debug, Default)]
struct LineReader {
    pending: Vec<u8>,
    cancel: Cancel,
    /// Set while a stop is exchanged: it goes through a cancelled client.
    ignore_cancel: bool,
}

/// Longest line we accept before calling it garbage.
const MAX_LINE: usize = 256;

impl LineReader {
    #[allow(clippy::too_many_arguments)]
    fn next_line<L: Link, C: Clock>(
        &mut self,
        link: &mut L,
        clock: &C,
        end: u8,
        drop: u8,
        timeout: Duration,
        command: &str,
    ) -> Result<Vec<u8>> {
        let deadline = clock.now() + timeout;
        loop {
            if let Some(i) = self.pending.iter().position(|b| *b == end) {
                let mut line: Vec<u8> = self.pending.drain(..=i).collect();
                line.pop();
                line.retain(|b| *b != drop);
                return Ok(line);
            }
            if self.pending.len() > MAX_LINE {
                let junk = std::mem::take(&mut self.pending);
                return Err(Error::BadReply {
                    command: command.to_string(),
                    reply: String::from_utf8_lossy(&junk).into_owned(),
                    reason: "line too long",
                });
            }
            let cancel = (!self.ignore_cancel).then_some(&self.cancel);
            let left = deadline.saturating_sub(clock.now());
            let mut buf = [0u8; 128];
            match read_within(link, clock, cancel, &mut buf, left)? {
                Wait::Bytes(n) => self.pending.extend_from_slice(buf.get(..n).unwrap_or(&[])),
                Wait::Cancelled => return Err(Error::Cancelled),
                Wait::TimedOut => {
                    return Err(Error::Timeout {
                        command: command.to_string(),
                        waited_ms: timeout.as_millis() as u64,
                    });
                }
            }
        }
    }

    /// Lets `dt` of `clock` pass reading `link`; what comes is kept for the next line.
    fn pause<L: Link, C: Clock>(&mut self, link: &mut L, clock: &C, dt: Duration) -> Result<()> {
        let deadline = clock.now() + dt;
        let mut buf = [0u8; 128];
        loop {
            let left = deadline.saturating_sub(clock.now());
            if left.is_zero() {
                return Ok(());
            }
            match read_within(link, clock, None, &mut buf, left)? {
                Wait::Bytes(n) => self.pending.extend_from_slice(buf.get(..n).unwrap_or(&[])),
                Wait::TimedOut | Wait::Cancelled => return Ok(()),
            }
        }
    }
}

/// Longest wait for an X-language card to come back from a reset (`Z`) after the client's
/// [`IndexerConfig::reset_wait`]: five times the OEM guide's 1000 ms, so that only a card that is
/// not there (or not answering) fails [`Indexer::init`].
pub const RESET_LIMIT: Duration = Duration::from_secs(5);

/// An X-language indexer (Compumotor 2100 / PC21 / OEM family) over a serial link.
#[derive(Debug)]
pub struct XClient<L: Link, C = WallClock> {
    link: L,
    clock: C,
    cfg: IndexerConfig,
    reader: LineReader,
    echo: bool,
    device_id: bool,
    profile: Option<Profile>,
    completions: u32,
}

impl<L: Link> XClient<L, WallClock> {
    /// A client on `link` in wall time; call [`Indexer::init`] before anything else.
    pub fn new(link: L, cfg: IndexerConfig) -> Self {
        XClient::with_clock(link, WallClock::new(), cfg)
    }
}

impl<L: Link, C: Clock> XClient<L, C> {
    /// A client on `link` timed by `clock` (the link's time: the virtual clock of a simulated
    /// link, whose reads move it); call [`Indexer::init`] before anything else.
    pub fn with_clock(link: L, clock: C, cfg: IndexerConfig) -> Self {
        XClient {
            link,
            clock,
            cfg,
            reader: LineReader::default(),
            echo: true,
            device_id: false,
            profile: None,
            completions: 0,
        }
    }

    /// The configuration.
    pub fn config(&self) -> &IndexerConfig {
        &self.cfg
    }

    /// The token that cancels this client's exchanges (clone it into another thread).
    pub fn cancel_token(&self) -> Cancel {
        self.reader.cancel.clone()
    }

    /// Attaches to an indexer that may have been running (a restarted coordinator, a resume
    /// after `kill -9`): no reset (`Z`) and no zeroing (`PZ`), so the step counter keeps the
    /// mandrel's position.
    ///
    /// The card may still be finishing what the run before left it: a move under way, with
    /// that run's later commands in its buffer (their replies, `PR`'s position and `CR`'s
    /// completion, come when the move ends), its echo and device-ID settings unknown. So the
    /// client first waits for the line to go quiet ([`ATTACH_QUIET`]), dropping what comes, then
    /// asks the immediate status (`R`) and takes as its answer only a line that is a status reply
    /// (`*R`, `*B`, `*S`, `*C`, with or without the device-ID prefix): an echo of that run's
    /// commands (`1G`, `1R`), a position or a completion is skipped. While the card is busy it is
    /// polled until at rest ([`IndexerConfig::attach_wait`], else [`Error::StillMoving`]); a busy
    /// card whose step count does not move for [`ARMED_STILL`] holds an armed move that never saw
    /// its start edge, and is stopped. Once at rest the line is drained again (the buffered
    /// replies), then echo and the device-ID prefix are set to what this client expects and the
    /// state and position read.
    pub fn attach(&mut self) -> Result<IndexerStatus> {
        self.quiet_line()?;
        let t0 = self.clock.now();
        let mut steps: Option<(i64, Duration)> = None;
        loop {
            let (busy, _) = self.recognised_status()?;
            if !busy {
                break;
            }
            let now = self.clock.now();
            if now.saturating_sub(t0) >= self.cfg.attach_wait {
                return Err(Error::StillMoving {
                    waited_ms: self.cfg.attach_wait.as_millis() as u64,
                });
            }
            let w3 = self.recognised_move_steps()?;
            match steps {
                Some((n, since)) if n == w3 => {
                    if now.saturating_sub(since) >= ARMED_STILL {
                        let stop = xlang::encode(Some(self.cfg.address), &Command::Stop);
                        self.link.write_all(format!("{stop}\r").as_bytes())?;
                        steps = None;
                    }
                }
                _ => steps = Some((w3, now)),
            }
            self.reader
                .pause(&mut self.link, &self.clock, RESET_POLL_PERIOD)?;
        }
        // The card at rest has run what its buffer held: its replies are stale. A reply that
        // comes later than the waits allowed (a loaded host) puts the set-up's echoes out of
        // step: the set-up is then done again from a quiet line.
        let mut tries = 0;
        loop {
            tries += 1;
            match self.set_up_attached() {
                Err(Error::Echo { .. } | Error::BadReply { .. } | Error::Timeout { .. })
                    if tries < RECOGNISED_ASKS => {}
                r => return r,
            }
        }
    }

    /// The set-up of [`XClient::attach`] once the card is at rest: a quiet line, echo off (its
    /// echo read past), the device-ID prefix off, echo on, the configured prefix and resolution,
    /// then the state and position.
    fn set_up_attached(&mut self) -> Result<IndexerStatus> {
        self.quiet_line()?;
        // Echo off first: whatever the echo state was, the next commands' echo is known.
        let off = xlang::encode(Some(self.cfg.address), &Command::Echo(false));
        self.link.write_all(format!("{off}\r").as_bytes())?;
        // Its echo, if echo was on, comes before the answer to a status asked after it (the
        // card answers in order): the status is recognised past it, however late it comes.
        self.recognised_status()?;
        self.echo = false;
        self.device_id = false;
        self.completions = 0;
        self.send(&Command::DeviceId(false))?;
        self.send(&Command::Echo(true))?;
        self.echo = true;
        if self.cfg.device_id {
            self.send(&Command::DeviceId(true))?;
        }
        self.send(&Command::Resolution(
            self.cfg.drive.gearing.steps_per_motor_rev,
        ))?;
        self.status()
    }

    /// Drops what comes until the line has been quiet for [`ATTACH_QUIET`]
    /// ([`paths::link::drain_until_quiet`]).
    fn quiet_line(&mut self) -> Result<()> {
        let d = paths::link::drain_until_quiet(
            &mut self.link,
            &self.clock,
            ATTACH_QUIET,
            ATTACH_QUIET_LIMIT,
        )?;
        self.reader.pending.clear();
        if !d.quiet {
            return Err(Error::LineNotQuiet {
                waited_ms: ATTACH_QUIET_LIMIT.as_millis() as u64,
            });
        }
        Ok(())
    }

    /// Asks an immediate query (`R`, `W3`) in whatever echo and device-ID state the card is in,
    /// and returns the first line that `parse` recognises as its answer; every other line (an
    /// echo, a stale reply of another kind, a completion) is skipped.
    fn recognised<T>(&mut self, cmd: &Command, parse: impl Fn(&Reply) -> Option<T>) -> Result<T> {
        let text = xlang::encode(Some(self.cfg.address), cmd);
        // Asked again after a reply timeout (a loaded host, a card slow to come back): a late
        // answer to the first ask is as good an answer as the second's.
        for _ in 0..RECOGNISED_ASKS {
            self.link.write_all(format!("{text}\r").as_bytes())?;
            let deadline = self.clock.now() + self.cfg.reply_timeout;
            loop {
                let left = deadline.saturating_sub(self.clock.now());
                let line = match self.reader.next_line(
                    &mut self.link,
                    &self.clock,
                    b'\r',
                    b'\n',
                    left,
                    &text,
                ) {
                    Err(Error::Timeout { .. }) => break,
                    r => r?,
                };
                let reply = xlang::parse_reply(cmd, &line, None)
                    .or_else(|_| xlang::parse_reply(cmd, &line, Some(self.cfg.address)));
                if let Some(t) = reply.ok().as_ref().and_then(&parse) {
                    return Ok(t);
                }
            }
        }
        Err(Error::Timeout {
            command: text,
            waited_ms: (self.cfg.reply_timeout * RECOGNISED_ASKS).as_millis() as u64,
        })
    }

    /// The immediate status (busy, attention), recognised among stale lines.
    fn recognised_status(&mut self) -> Result<(bool, bool)> {
        self.recognised(&Command::Status, |r| match r {
            Reply::Status { busy, attention } => Some((*busy, *attention)),
            _ => None,
        })
    }

    /// The steps of the current or last move (`W3`), recognised among stale lines.
    fn recognised_move_steps(&mut self) -> Result<i64> {
        self.recognised(&Command::MoveSteps, |r| match r {
            Reply::MoveSteps(n) => Some(*n),
            _ => None,
        })
    }

    /// Arms a preset move on the trigger input (X-language `TR1` before `G`): the move waits in
    /// the indexer's buffer until the start line is high, so that robot and mandrel start on the
    /// same edge (seed 001 §5.6.4 step 10, App. D). The start line must be low when it is armed.
    /// No `CR` notification follows (poll [`Indexer::status`]).
    pub fn arm_move(&mut self, steps: i64, mode: PosMode) -> Result<()> {
        self.completions = 0;
        self.send(&Command::Preset)?;
        self.send(&match mode {
            PosMode::Absolute => Command::Absolute,
            PosMode::Incremental => Command::Incremental,
        })?;
        self.send(&Command::Distance(steps))?;
        self.send(&Command::Trigger("1".into()))?;
        self.send(&Command::Go)?;
        let (busy, attention) = self.ready_status()?;
        if attention {
            return Err(Error::Stalled);
        }
        if !busy {
            return Err(Error::BadReply {
                command: "TR1 G".into(),
                reply: "*R".into(),
                reason: "the armed move is not waiting for its trigger",
            });
        }
        Ok(())
    }

    fn line(&mut self, command: &str) -> Result<Vec<u8>> {
        self.reader.next_line(
            &mut self.link,
            &self.clock,
            b'\r',
            b'\n',
            self.cfg.reply_timeout,
            command,
        )
    }

    /// Sends one command, swallows and checks its echo, and returns its reply if it has one.
    pub fn send(&mut self, cmd: &Command) -> Result<Option<Reply>> {
        if !self.reader.ignore_cancel && self.reader.cancel.is_cancelled() {
            return Err(Error::Cancelled);
        }
        let text = xlang::encode(Some(self.cfg.address), cmd);
        let mut wire = text.clone().into_bytes();
        wire.push(b'\r');
        self.link.write_all(&wire)?;
        // A refusal of an earlier buffered command may arrive first; the exchange is finished
        // before it is reported, so that the stream stays in step.
        let mut earlier: Option<Error> = None;
        if self.echo {
            loop {
                let line = self.line(&text)?;
                if line.is_empty() {
                    self.completions += 1;
                } else if line == text.as_bytes() {
                    break;
                } else if let Some(reason) = line.strip_prefix(b"?") {
                    earlier = Some(refused("G", reason));
                } else {
                    return Err(Error::Echo {
                        command: text,
                        echo: String::from_utf8_lossy(&line).into_owned(),
                    });
                }
            }
        }
        match cmd {
            Command::Echo(on) => self.echo = *on,
            Command::DeviceId(on) => self.device_id = *on,
            _ => {}
        }
        if !cmd.expects_reply() {
            return earlier.map_or(Ok(None), Err);
        }
        let id = self.device_id.then_some(self.cfg.address);
        loop {
            let line = self.line(&text)?;
            if line.is_empty() {
                self.completions += 1;
                continue;
            }
            if let Some(reason) = line.strip_prefix(b"?") {
                earlier = Some(refused("G", reason));
                continue;
            }
            if let Some(e) = earlier {
                return Err(e);
            }
            return match xlang::parse_reply(cmd, &line, id) {
                Ok(r) => Ok(Some(r)),
                Err(ReplyError::WrongAddress { expected, got }) => {
                    Err(Error::WrongAddress { expected, got })
                }
                Err(ReplyError::Refused(reason)) => Err(refused(&text, reason.as_bytes())),
                Err(ReplyError::Malformed(reason)) => Err(Error::BadReply {
                    command: text,
                    reply: String::from_utf8_lossy(&line).into_owned(),
                    reason,
                }),
            };
        }
    }

    /// Polls the immediate status (`R`) until the card reports ready after a reset (`Z`): the
    /// card buffers the commands that arrive while it resets and runs them only afterwards, so a
    /// set-up command sent early (`SSD1`) would take effect after the replies that depend on it.
    /// The `Z` may reach the card later than the client's wait assumed (a loaded host, a slow
    /// link), so the client waits for the card's word, not for the clock. A line that is not a
    /// status reply (the late echo of `Z`, a partial line cut by the reset) is skipped.
    fn wait_reset_done(&mut self) -> Result<()> {
        let limit = RESET_LIMIT + self.cfg.reply_timeout;
        let deadline = self.clock.now() + limit;
        let status = xlang::encode(Some(self.cfg.address), &Command::Status);
        // Polls sent and replies read: a reply that comes after its poll timed out belongs to
        // an earlier poll and is consumed before the set-up goes on.
        let (mut sent, mut answered) = (0u32, 0u32);
        let mut ready = false;
        loop {
            if !ready {
                self.link.write_all(format!("{status}\r").as_bytes())?;
                sent += 1;
            }
            let mut got = None;
            while got.is_none() {
                let line = match self.line(&status) {
                    Ok(line) => line,
                    Err(Error::Timeout { .. }) => break,
                    Err(e) => return Err(e),
                };
                if let Ok(Reply::Status { busy, .. }) =
                    xlang::parse_reply(&Command::Status, &line, None)
                {
                    answered += 1;
                    got = Some(busy);
                }
            }
            ready |= got == Some(false);
            if ready && (answered >= sent || got.is_none()) {
                return Ok(());
            }
            if self.clock.now() >= deadline {
                return Err(Error::MoveTimeout {
                    waited_ms: limit.as_millis() as u64,
                });
            }
            if !ready {
                let poll = RESET_POLL_PERIOD.min(self.cfg.reply_timeout);
                self.reader.pause(&mut self.link, &self.clock, poll)?;
            }
        }
    }

    fn ready_status(&mut self) -> Result<(bool, bool)> {
        match self.send(&Command::Status)? {
            Some(Reply::Status { busy, attention }) => Ok((busy, attention)),
            _ => Err(Error::BadReply {
                command: "R".into(),
                reply: String::new(),
                reason: "no status",
            }),
        }
    }

    /// Waits for the `CR` move-complete notification of the last preset move.
    pub fn wait_complete(&mut self, timeout: Duration) -> Result<()> {
        let deadline = self.clock.now() + timeout;
        while self.completions == 0 {
            let now = self.clock.now();
            if now >= deadline {
                return Err(Error::MoveTimeout {
                    waited_ms: timeout.as_millis() as u64,
                });
            }
            match self.reader.next_line(
                &mut self.link,
                &self.clock,
                b'\r',
                b'\n',
                deadline - now,
                "CR",
            ) {
                Ok(line) if line.is_empty() => self.completions += 1,
                Ok(line) if line.starts_with(b"?") => {
                    return Err(refused("G", line.get(1..).unwrap_or(&[])));
                }
                Ok(_) => {}
                Err(Error::Timeout { .. }) => {}
                Err(e) => return Err(e),
            }
        }
        self.completions -= 1;
        let (_, attention) = self.ready_status()?;
        if attention {
            return Err(Error::Stalled);
        }
        Ok(())
    }

    /// Puts `S` on the wire at once, without waiting for its echo: the first thing a coordinator
    /// sends when both devices must stop (it goes through a cancelled client). [`Indexer::stop`]
    /// must follow: it drops what is on the line and sends `S` again, confirmed by its echo (a
    /// second `S` stops nothing more).
    pub fn stop_on_wire(&mut self) -> Result<()> {
        let text = xlang::encode(Some(self.cfg.address), &Command::Stop);
        self.link.write_all(format!("{text}\r").as_bytes())?;
        Ok(())
    }

    /// Reads `W3`: steps since the start of the current or last move.
    pub fn move_steps(&mut self) -> Result<i64> {
        match self.send(&Command::MoveSteps)? {
            Some(Reply::MoveSteps(n)) => Ok(n),
            _ => Err(Error::BadReply {
                command: "W3".into(),
                reply: String::new(),
                reason: "no step count",
            }),
        }
    }

    /// Sends `G` and surfaces a refusal of the move at once.
    fn go(&mut self) -> Result<()> {
        self.send(&Command::Go)?;
        let (_, attention) = self.ready_status()?;
        if attention {
            return Err(Error::Stalled);
        }
        Ok(())
    }
}

fn refused(command: &str, reason: &[u8]) -> Error {
    Error::Refused {
        command: command.to_string(),
        message: String::from_utf8_lossy(reason).into_owned(),
    }
}

impl<L: Link, C: Clock> Indexer for XClient<L, C> {
    fn now(&self) -> Duration {
        self.clock.now()
    }

    fn pause(&mut self, dt: Duration) -> Result<()> {
        self.reader.pause(&mut self.link, &self.clock, dt)
    }

    fn init(&mut self) -> Result<()> {
        self.link.discard_input()?;
        let z = xlang::encode(Some(self.cfg.address), &Command::Reset);
        self.link.write_all(format!("{z}\r").as_bytes())?;
        self.pause(self.cfg.reset_wait)?;
        self.link.discard_input()?;
        self.reader.pending.clear();
        self.echo = true;
        self.device_id = false;
        self.completions = 0;
        self.profile = None;
        self.wait_reset_done()?;
        if self.cfg.device_id {
            self.send(&Command::DeviceId(true))?;
        }
        let res = self.cfg.drive.gearing.steps_per_motor_rev;
        self.send(&Command::Resolution(res))?;
        if self.cfg.no_limit_switches {
            self.send(&Command::LimitDisable(3))?;
        }
        self.send(&Command::Zero)?;
        let deadline = self.clock.now() + self.cfg.reset_wait + self.cfg.reply_timeout;
        while self.ready_status()?.0 {
            if self.clock.now() > deadline {
                return Err(Error::MoveTimeout {
                    waited_ms: (self.cfg.reset_wait + self.cfg.reply_timeout).as_millis() as u64,
                });
            }
            self.pause(Duration::from_millis(10))?;
        }
        Ok(())
    }

    fn set_profile(&mut self, p: Profile) -> Result<()> {
        let drive = self.cfg.drive;
        let (a, v) = xlang::accel_and_velocity(&p, &drive)?;
        if p.start_rps > 0.0 && !self.cfg.start_velocity_command {
            return Err(Error::Unsupported {
                dialect: "the X-language",
                feature: "start/stop velocity command",
            });
        }
        self.send(&Command::Accel(a))?;
        self.send(&Command::Velocity(v))?;
        if self.cfg.start_velocity_command {
            self.send(&Command::StartVelocity(drive.motor_rps(p.start_rps)))?;
        }
        self.profile = Some(p);
        Ok(())
    }

    fn move_to(&mut self, steps: i64, mode: PosMode) -> Result<()> {
        self.completions = 0;
        self.send(&Command::Preset)?;
        self.send(&match mode {
            PosMode::Absolute => Command::Absolute,
            PosMode::Incremental => Command::Incremental,
        })?;
        self.send(&Command::Distance(steps))?;
        self.go()?;
        self.send(&Command::Notify)?;
        Ok(())
    }

    fn run_constant(&mut self, mandrel_rps: f64, dir: Direction) -> Result<()> {
        let drive = self.cfg.drive;
        drive.check_pulse_rate(mandrel_rps)?;
        let v = xlang::in_range(
            "velocity (motor rev/s)",
            drive.motor_rps(mandrel_rps),
            (0.0, xlang::VELOCITY_RANGE_MOTOR_RPS.1),
            "0–50.00",
        )?;
        self.send(&Command::Continuous)?;
        self.send(&Command::Direction(Some(dir == Direction::Positive)))?;
        self.send(&Command::Velocity(v))?;
        self.go()
    }

    fn alternate(&mut self, a: i64, b: i64, cycles: Option<u16>) -> Result<()> {
        self.send(&Command::Preset)?;
        self.send(&Command::Absolute)?;
        self.send(&Command::Loop(cycles.unwrap_or(0)))?;
        self.send(&Command::Distance(a))?;
        self.send(&Command::Go)?;
        self.send(&Command::Distance(b))?;
        self.send(&Command::Go)?;
        self.send(&Command::EndLoop)?;
        Ok(())
    }

    fn stop(&mut self, kind: StopKind) -> Result<()> {
        // What a cancelled exchange left on the line is stale.
        self.link.discard_input()?;
        self.reader.pending.clear();
        self.reader.ignore_cancel = true;
        let r = self.send(&match kind {
            StopKind::Decelerate => Command::Stop,
            StopKind::Kill => Command::Kill,
        });
        self.reader.ignore_cancel = false;
        r.map(|_| ())
    }

    fn status(&mut self) -> Result<IndexerStatus> {
        let (busy, attention) = self.ready_status()?;
        let position_steps = if busy {
            None
        } else {
            match self.send(&Command::Position)? {
                Some(Reply::Position(n)) => Some(n),
                _ => None,
            }
        };
        Ok(IndexerStatus {
            busy,
            fault: attention,
            position_steps,
        })
    }
}

/// A GRBL 1.1 / grblHAL controller turning the mandrel as its A axis.
#[derive(Debug)]
pub struct GrblClient<L: Link, C = WallClock> {
    link: L,
    clock: C,
    cfg: IndexerConfig,
    reader: LineReader,
    feed_deg_per_min: f64,
    stop_wait: Duration,
}

/// The longest a decelerating stop waits for the controller to come to rest (a jog cancelled, a
/// feed hold complete) before it resets the controller anyway: a full-speed move of the slowest
/// profile ends well within it.
pub const GRBL_STOP_WAIT: Duration = Duration::from_secs(60);

impl<L: Link> GrblClient<L, WallClock> {
    /// A client on `link` in wall time; call [`Indexer::init`] before anything else.
    pub fn new(link: L, cfg: IndexerConfig) -> Self {
        GrblClient::with_clock(link, WallClock::new(), cfg)
    }
}

impl<L: Link, C: Clock> GrblClient<L, C> {
    /// A client on `link` timed by `clock` (the link's time); call [`Indexer::init`] before
    /// anything else.
    pub fn with_clock(link: L, clock: C, cfg: IndexerConfig) -> Self {
        GrblClient {
            link,
            clock,
            cfg,
            reader: LineReader::default(),
            feed_deg_per_min: 360.0,
            stop_wait: GRBL_STOP_WAIT,
        }
    }

    /// The same client with another wait for a decelerating stop ([`GRBL_STOP_WAIT`]).
    pub fn with_stop_wait(mut self, wait: Duration) -> Self {
        self.stop_wait = wait;
        self
    }

    /// The token that cancels this client's exchanges (clone it into another thread); a stop
    /// ([`Indexer::stop`]) still goes through a cancelled client.
    pub fn cancel_token(&self) -> Cancel {
        self.reader.cancel.clone()
    }

    /// Puts the feed hold on the wire at once, without waiting for an answer: the first thing a
    /// coordinator sends when both devices must stop. [`Indexer::stop`] must follow.
    pub fn stop_on_wire(&mut self) -> Result<()> {
        self.link.write_all(&[grbl::FEED_HOLD])?;
        Ok(())
    }

    fn line(&mut self, command: &str, timeout: Duration) -> Result<grbl::Line> {
        let mut raw = Vec::new();
        while raw.is_empty() {
            raw = self.reader.next_line(
                &mut self.link,
                &self.clock,
                b'\n',
                b'\r',
                timeout,
                command,
            )?;
        }
        grbl::parse_line(&raw).map_err(|e| Error::BadReply {
            command: command.to_string(),
            reply: String::from_utf8_lossy(&raw).into_owned(),
            reason: match e {
                grbl::LineError::Malformed(r) => r,
            },
        })
    }

    /// Sends one line and waits for its `ok`.
    pub fn send(&mut self, cmd: &grbl::Command) -> Result<()> {
        let text = cmd.to_string();
        self.link.write_all(format!("{text}\n").as_bytes())?;
        let mut messages = Vec::new();
        loop {
            match self.line(&text, self.cfg.reply_timeout)? {
                grbl::Line::Ok => return Ok(()),
                grbl::Line::Error(code) => {
                    messages.push(format!("error:{code}"));
                    return Err(Error::Refused {
                        command: text,
                        message: messages.join(" "),
                    });
                }
                grbl::Line::Alarm(code) => return Err(Error::Alarm(format!("ALARM:{code}"))),
                grbl::Line::Message(m) => messages.push(m),
                _ => {}
            }
        }
    }

    fn reset(&mut self) -> Result<()> {
        self.link.write_all(&[grbl::SOFT_RESET])?;
        let wait = self.cfg.reset_wait.max(self.cfg.reply_timeout);
        loop {
            match self.line("0x18", wait)? {
                grbl::Line::Banner => break,
                _ => continue,
            }
        }
        self.link.discard_input()?;
        self.reader.pending.clear();
        Ok(())
    }

    fn report(&mut self) -> Result<(grbl::State, f64)> {
        self.link.write_all(&[grbl::STATUS])?;
        loop {
            match self.line("?", self.cfg.reply_timeout)? {
                grbl::Line::Status { state, a_deg } => return Ok((state, a_deg)),
                grbl::Line::Alarm(code) => return Err(Error::Alarm(format!("ALARM:{code}"))),
                _ => continue,
            }
        }
    }

    /// [`Indexer::stop`]'s work: a feed hold (or jog cancel) waited out, then a soft reset.
    fn stop_now(&mut self, kind: StopKind) -> Result<()> {
        if kind == StopKind::Decelerate {
            let (state, _) = self.report()?;
            if state == grbl::State::Jog {
                self.link.write_all(&[grbl::JOG_CANCEL])?;
                self.wait_idle(self.stop_wait)?;
                return Ok(());
            }
            self.link.write_all(&[grbl::FEED_HOLD])?;
            let deadline = self.clock.now() + self.stop_wait;
            loop {
                self.link.write_all(&[grbl::STATUS])?;
                let raw = self.reader.next_line(
                    &mut self.link,
                    &self.clock,
                    b'\n',
                    b'\r',
                    self.cfg.reply_timeout,
                    "?",
                )?;
                if raw.starts_with(b"<Hold:0") && raw.windows(5).any(|w| w == b"|FS:0") {
                    break;
                }
                if raw.starts_with(b"<Idle") || self.clock.now() > deadline {
                    break;
                }
                self.pause(Duration::from_millis(5))?;
            }
        }
        self.reset()
    }

    fn feed_for(&self, mandrel_rps: f64) -> f64 {
        mandrel_rps * 21_600.0
    }
}

impl<L: Link, C: Clock> Indexer for GrblClient<L, C> {
    fn now(&self) -> Duration {
        self.clock.now()
    }

    fn pause(&mut self, dt: Duration) -> Result<()> {
        self.reader.pause(&mut self.link, &self.clock, dt)
    }

    fn init(&mut self) -> Result<()> {
        self.link.discard_input()?;
        self.reader.pending.clear();
        self.reset()?;
        let spd = self.cfg.drive.steps_per_deg();
        self.send(&grbl::Command::StepsPerDeg(spd))?;
        if let Some(mask) = self.cfg.rotary_mask {
            self.send(&grbl::Command::RotaryMask(mask))?;
            self.send(&grbl::Command::MaxTravel(0.0))?;
        }
        self.send(&grbl::Command::ZeroA)
    }

    fn set_profile(&mut self, p: Profile) -> Result<()> {
        p.validate(&self.cfg.drive)?;
        if p.start_rps > 0.0 {
            return Err(Error::Unsupported {
                dialect: "GRBL",
                feature: "start/stop velocity (it always starts from rest)",
            });
        }
        let feed = self.feed_for(p.max_rps);
        self.send(&grbl::Command::MaxRate(feed))?;
        self.send(&grbl::Command::Accel(p.accel_rps2 * 360.0))?;
        self.feed_deg_per_min = feed;
        Ok(())
    }

    fn move_to(&mut self, steps: i64, mode: PosMode) -> Result<()> {
        let a_deg = steps as f64 / self.cfg.drive.steps_per_deg();
        self.send(&grbl::Command::Move {
            absolute: mode == PosMode::Absolute,
            a_deg,
            feed_deg_per_min: self.feed_deg_per_min,
        })
    }

    fn run_constant(&mut self, mandrel_rps: f64, dir: Direction) -> Result<()> {
        self.cfg.drive.check_pulse_rate(mandrel_rps)?;
        let (state, _) = self.report()?;
        if state == grbl::State::Jog {
            self.link.write_all(&[grbl::JOG_CANCEL])?;
            self.wait_idle(Duration::from_secs(60))?;
        }
        let feed = self.feed_for(mandrel_rps);
        // A day of turning: the jog is cancelled long before.
        let span = mandrel_rps * 360.0 * 86_400.0;
        self.send(&grbl::Command::Jog {
            a_deg: if dir == Direction::Positive {
                span
            } else {
                -span
            },
            feed_deg_per_min: feed,
        })
    }

    fn alternate(&mut self, a: i64, b: i64, cycles: Option<u16>) -> Result<()> {
        let Some(n) = cycles else {
            return Err(Error::Unsupported {
                dialect: "GRBL",
                feature: "endless alternating mode (the host drives a counted one)",
            });
        };
        for _ in 0..n {
            self.move_to(a, PosMode::Absolute)?;
            self.move_to(b, PosMode::Absolute)?;
        }
        Ok(())
    }

    fn stop(&mut self, kind: StopKind) -> Result<()> {
        // A stop goes through a cancelled client; what the cancelled exchange left is stale.
        self.reader.ignore_cancel = true;
        let r = self.stop_now(kind);
        self.reader.ignore_cancel = false;
        r
    }

    fn status(&mut self) -> Result<IndexerStatus> {
        let (state, a_deg) = self.report()?;
        Ok(IndexerStatus {
            busy: !matches!(state, grbl::State::Idle),
            fault: state == grbl::State::Alarm,
            position_steps: Some((a_deg * self.cfg.drive.steps_per_deg()).round() as i64),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::Pipe;
    use std::time::Instant;

    /// A line may hold up to [`MAX_LINE`] bytes before its end: that many without an end is
    /// still waited for (here until the deadline), one more is refused as too long at once.
    #[test]
    fn a_line_is_refused_only_beyond_max_line_bytes() {
        let wait = Duration::from_millis(120);
        let (mut host, mut device) = Pipe::pair();
        device.write_all(&[b'X'; MAX_LINE]).unwrap();
        let e = LineReader::default()
            .next_line(&mut host, &WallClock::new(), b'\r', b'\n', wait, "R")
            .unwrap_err();
        assert!(matches!(e, Error::Timeout { .. }), "{e:?}");
        let (mut host, mut device) = Pipe::pair();
        device.write_all(&[b'X'; MAX_LINE + 1]).unwrap();
        let e = LineReader::default()
            .next_line(&mut host, &WallClock::new(), b'\r', b'\n', wait, "R")
            .unwrap_err();
        assert!(
            matches!(
                e,
                Error::BadReply {
                    reason: "line too long",
                    ..
                }
            ),
            "{e:?}"
        );
    }

    /// A client on a pipe whose card end has already written `card` (CR-ended lines).
    fn answered(card: &str) -> XClient<Pipe> {
        let (host, device) = Pipe::pair();
        // The card end stays open (leaked): a card that says nothing more, not one that is gone.
        Box::leak(Box::new(device))
            .write_all(card.as_bytes())
            .unwrap();
        XClient::new(
            host,
            IndexerConfig {
                reply_timeout: Duration::from_millis(150),
                ..IndexerConfig::default()
            },
        )
    }

    /// A move's completion (an empty line) that arrives among another command's echo or reply
    /// lines is counted, so that the wait for it ends at once: here before `G`'s echo, and
    /// between `R`'s echo and its status reply.
    #[test]
    fn completions_among_other_lines_are_counted() {
        let mut c = answered("\r1G\r1R\r*R\r");
        assert_eq!(c.send(&Command::Go).unwrap(), None);
        c.wait_complete(Duration::from_millis(100)).unwrap();
        let mut c = answered("1R\r\r*R\r1R\r*R\r");
        c.send(&Command::Status).unwrap();
        c.wait_complete(Duration::from_millis(100)).unwrap();
    }

    /// With echo turned off (`SSA1`, whose own echo still comes) the client reads a reply with
    /// no echo before it.
    #[test]
    fn echo_off_is_followed() {
        let mut c = answered("1SSA1\r*R\r");
        c.send(&Command::Echo(false)).unwrap();
        assert!(matches!(
            c.send(&Command::Status).unwrap(),
            Some(Reply::Status { busy: false, .. })
        ));
    }

    /// `range` passes a finite value inside its bounds unchanged and refuses one outside or
    /// not finite.
    #[test]
    fn range_passes_only_finite_values_inside_the_bounds() {
        assert_eq!(xlang::in_range("v", 2.5, (0.01, 50.0), "").unwrap(), 2.5);
        assert_eq!(xlang::in_range("v", 0.01, (0.01, 50.0), "").unwrap(), 0.01);
        for bad in [0.005, 50.5, f64::NAN, f64::INFINITY] {
            assert!(
                xlang::in_range("v", bad, (0.01, 50.0), "").is_err(),
                "{bad}"
            );
        }
    }

    /// A start velocity needs the backend's `VS` command: refused without it, and a profile
    /// that starts from rest needs nothing of the kind (its `A` and `V` go out, echoed).
    #[test]
    fn a_start_velocity_needs_the_start_velocity_command() {
        let drive = Drive::default();
        let cfg = IndexerConfig {
            start_velocity_command: false,
            reply_timeout: Duration::from_millis(150),
            ..IndexerConfig::default()
        };
        let profile = |start_rps| Profile {
            accel_rps2: 1.0,
            start_rps,
            max_rps: 0.5,
        };
        let (host, mut card) = Pipe::pair();
        let mut c = XClient::new(host, cfg.clone());
        let a = xlang::encode(Some(1), &Command::Accel(drive.motor_rps(1.0)));
        let v = xlang::encode(Some(1), &Command::Velocity(drive.motor_rps(0.5)));
        card.write_all(format!("{a}\r{v}\r").as_bytes()).unwrap();
        c.set_profile(profile(0.0)).unwrap();
        let e = c.set_profile(profile(0.05)).unwrap_err();
        assert!(matches!(e, Error::Unsupported { .. }), "{e:?}");
    }

    /// The stop that goes on the wire at once is the unit's `S`.
    #[test]
    fn stop_on_wire_writes_the_stop_command() {
        let (host, mut card) = Pipe::pair();
        XClient::new(host, IndexerConfig::default())
            .stop_on_wire()
            .unwrap();
        let mut buf = [0u8; 16];
        let n = card
            .read_timeout(&mut buf, Duration::from_millis(50))
            .unwrap();
        assert_eq!(&buf[..n], b"1S\r");
    }

    /// The wait for a move's completion skips a stray line, ends at the empty line (then reads
    /// the status), uses each completion once (a second wait waits again), and reports a
    /// refusal (`?`) that comes instead.
    #[test]
    fn the_wait_for_completion_takes_each_completion_once_and_reports_a_refusal() {
        let short = Duration::from_millis(100);
        let mut c = answered("stray\r\r1R\r*R\r");
        c.wait_complete(short).unwrap();
        let e = c.wait_complete(short).unwrap_err();
        assert!(matches!(e, Error::MoveTimeout { .. }), "{e:?}");
        let mut c = answered("?X\r");
        let e = c.wait_complete(short).unwrap_err();
        assert!(matches!(e, Error::Refused { .. }), "{e:?}");
    }

    /// The client keeps the configuration it was made with.
    #[test]
    fn the_client_reports_its_configuration() {
        let cfg = IndexerConfig {
            address: 7,
            ..IndexerConfig::default()
        };
        let (host, _device) = Pipe::pair();
        assert_eq!(XClient::new(host, cfg.clone()).config(), &cfg);
    }

    /// How long a test card waits for the client's next command before it ends.
    const CARD_IDLE: Duration = Duration::from_secs(1);

    /// An X-language card on the far end of a pipe, on a thread of its own: for each CR-ended
    /// command line it receives (`1R`, `1PZ`), `answer` gives a pause and the bytes to write back
    /// (echo and reply), or `None` to fall silent. It ends then, or when no command has come for
    /// [`CARD_IDLE`], and returns the lines it received.
    fn x_card<F>(mut card: Pipe, mut answer: F) -> std::thread::JoinHandle<Vec<String>>
    where
        F: FnMut(&str) -> Option<(Duration, String)> + Send + 'static,
    {
        std::thread::spawn(move || {
            let (mut got, mut pending, mut buf) = (Vec::new(), Vec::new(), [0u8; 64]);
            loop {
                while let Some(i) = pending.iter().position(|b| *b == b'\r') {
                    let raw: Vec<u8> = pending.drain(..=i).collect();
                    let line = String::from_utf8_lossy(&raw[..i]).into_owned();
                    let Some((pause, bytes)) = answer(&line) else {
                        return got;
                    };
                    got.push(line);
                    std::thread::sleep(pause);
                    if card.write_all(bytes.as_bytes()).is_err() {
                        return got;
                    }
                }
                // A client gone (its end dropped) ends the card as silence does.
                let n = card.read_timeout(&mut buf, CARD_IDLE).unwrap_or(0);
                if n == 0 {
                    return got;
                }
                pending.extend_from_slice(&buf[..n]);
            }
        })
    }

    /// What a card with echo on writes back for `line`: nothing for the reset (`Z`), else the
    /// echo, and for the status request (`R`) the status `status` after it (`R` ready, `B` busy).
    fn echoed(line: &str, status: char) -> String {
        match line {
            "1Z" => String::new(),
            "1R" => format!("1R\r*{status}\r"),
            _ => format!("{line}\r"),
        }
    }

    /// An X client at address 1 without the device-ID prefix, so that `init` sends `Z`, polls
    /// `R`, then `MR400`, `LD3`, `PZ` and polls `R` again.
    fn x_client(host: Pipe, reset_wait: Duration, reply_timeout: Duration) -> XClient<Pipe> {
        XClient::new(
            host,
            IndexerConfig {
                reset_wait,
                reply_timeout,
                device_id: false,
                ..IndexerConfig::default()
            },
        )
    }

    /// The `R` polls among the lines a card received before the first set-up command (`MR`).
    fn reset_polls(lines: &[String]) -> usize {
        lines
            .iter()
            .take_while(|l| !l.starts_with("1MR"))
            .filter(|l| *l == "1R")
            .count()
    }

    /// A card that stays busy after its reset fails `init` once `RESET_LIMIT` and one reply
    /// timeout (the last poll's full wait for its reply) have passed, and that is the wait it
    /// reports.
    #[test]
    fn init_gives_up_on_a_card_busy_beyond_the_reset_limit() {
        let reply = Duration::from_millis(100);
        let (host, card) = Pipe::pair();
        let _card = x_card(card, |line| Some((Duration::ZERO, echoed(line, 'B'))));
        let mut c = x_client(host, Duration::from_millis(10), reply);
        let t0 = Instant::now();
        let e = c.init().unwrap_err();
        let limit = RESET_LIMIT + reply;
        assert!(t0.elapsed() >= limit, "{:?}", t0.elapsed());
        assert!(
            matches!(e, Error::MoveTimeout { waited_ms } if u128::from(waited_ms) == limit.as_millis()),
            "{e:?}"
        );
    }

    /// A ready reply that comes after its poll timed out is the answer to that poll: the wait
    /// goes on until the later polls are answered too, so that their replies do not come in
    /// front of the echo of the first set-up command (`MR400`). Here the first reply comes
    /// three reply timeouts late.
    #[test]
    fn init_reads_the_replies_of_polls_that_timed_out() {
        let reply = Duration::from_millis(100);
        let (host, card) = Pipe::pair();
        let mut first = true;
        let card = x_card(card, move |line| {
            let late = line == "1R" && std::mem::take(&mut first);
            let pause = if late { 3 * reply } else { Duration::ZERO };
            Some((pause, echoed(line, 'R')))
        });
        let mut c = x_client(host, Duration::ZERO, reply);
        c.init().unwrap();
        let lines = card.join().unwrap();
        assert!(reset_polls(&lines) >= 2, "{lines:?}");
    }

    /// The wait ends at the ready reply to the last poll, not one reply timeout later.
    #[test]
    fn init_goes_on_at_the_ready_reply() {
        let reply = Duration::from_secs(2);
        let (host, card) = Pipe::pair();
        let _card = x_card(card, |line| Some((Duration::ZERO, echoed(line, 'R'))));
        let mut c = x_client(host, Duration::ZERO, reply);
        let t0 = Instant::now();
        c.init().unwrap();
        assert!(t0.elapsed() < reply / 2, "{:?}", t0.elapsed());
    }

    /// While the card is busy after its reset it is polled once per `RESET_POLL_PERIOD`, not as fast
    /// as it answers: a card busy for six poll periods from the first poll gets at most eight
    /// polls (one at the start, six more a period apart, one of slack for the card's own clock).
    #[test]
    fn a_card_busy_resetting_is_polled_once_per_poll_period() {
        let busy_for = 6 * RESET_POLL_PERIOD;
        let (host, card) = Pipe::pair();
        let mut first_poll: Option<Instant> = None;
        let card = x_card(card, move |line| {
            let busy =
                line == "1R" && first_poll.get_or_insert_with(Instant::now).elapsed() < busy_for;
            Some((Duration::ZERO, echoed(line, if busy { 'B' } else { 'R' })))
        });
        let mut c = x_client(host, Duration::ZERO, Duration::from_millis(150));
        c.init().unwrap();
        let lines = card.join().unwrap();
        let polls = reset_polls(&lines);
        assert!((2..=8).contains(&polls), "{polls} polls");
    }

    /// A re-attach to a card a killed run left finishing its move: the card answers the first
    /// three status polls busy, each behind the stale echoes `1G` and `1R` of that run's last
    /// commands (the issue's "echo \"1G\" does not match command \"1R\""), its step count
    /// moving; then ready, with that run's buffered `PR` reply and completion coming after. The
    /// client skips every stale line, polls until the card is at rest, asks `PR` only then (a
    /// `PR` sent while busy would wait in the card's buffer), and reads the counter the card
    /// reports (+66), not the stale one (+12).
    #[test]
    fn attach_skips_stale_echoes_and_waits_out_the_move_before_asking_the_position() {
        let (host, card) = Pipe::pair();
        let mut polls = 0u32;
        let mut echo = true;
        let mut w3 = 0u32;
        let card = x_card(card, move |line| {
            let echoed = |l: &str| {
                if echo {
                    format!("{l}\r")
                } else {
                    String::new()
                }
            };
            let out = match line {
                "1R" => {
                    polls += 1;
                    if polls <= 3 {
                        "1G\r1R\r*B\r".to_string()
                    } else if polls == 4 {
                        "1R\r*R\r\r\n*+0000000012\r".to_string()
                    } else {
                        format!("{}*R\r", echoed(line))
                    }
                }
                "1W3" => {
                    w3 += 25;
                    format!("{}*{w3:08X}\r", echoed(line))
                }
                "1SSA1" => {
                    let e = echoed(line);
                    echo = false;
                    e
                }
                "1SSA0" => {
                    echo = true;
                    String::new()
                }
                "1PR" => format!("{}*+0000000066\r", echoed(line)),
                _ => echoed(line),
            };
            Some((Duration::ZERO, out))
        });
        let mut c = x_client(host, Duration::ZERO, Duration::from_millis(300));
        let s = c.attach().unwrap();
        assert_eq!(
            s,
            IndexerStatus {
                busy: false,
                fault: false,
                position_steps: Some(66)
            }
        );
        drop(c);
        let lines = card.join().unwrap();
        let first_pr = lines.iter().position(|l| l == "1PR").unwrap();
        let ready_poll = lines
            .iter()
            .enumerate()
            .filter(|(_, l)| *l == "1R")
            .nth(3)
            .unwrap()
            .0;
        assert!(first_pr > ready_poll, "{lines:?}");
        // No reset, no zeroing, no stop of a move that was turning.
        for never in ["1Z", "1PZ", "1S"] {
            assert!(!lines.iter().any(|l| l == never), "{lines:?}");
        }
    }

    /// A card busy with a step count that does not move holds an armed move that never saw its
    /// start edge: the re-attach stops it (`S`) once it has stood still for `ARMED_STILL`, and
    /// one still busy past the attach wait fails naming the wait.
    #[test]
    fn attach_stops_an_armed_move_and_gives_up_on_a_move_that_does_not_end() {
        for stops in [true, false] {
            let (host, card) = Pipe::pair();
            let mut stopped = false;
            let mut echo = true;
            let mut w3 = 0u32;
            let card = x_card(card, move |line| {
                let e = if echo {
                    format!("{line}\r")
                } else {
                    String::new()
                };
                let out = match line {
                    "1S" => {
                        stopped = stops;
                        e
                    }
                    "1R" if !stopped => format!("{e}*B\r"),
                    "1W3" => {
                        // Without the stop taking effect the count moves: a move that turns
                        // but never ends.
                        if !stops {
                            w3 += 1;
                        }
                        format!("{e}*{w3:08X}\r")
                    }
                    "1PR" => format!("{e}*-0000000040\r"),
                    "1R" => format!("{e}*R\r"),
                    "1SSA1" => {
                        echo = false;
                        e
                    }
                    "1SSA0" => {
                        echo = true;
                        e
                    }
                    _ => e,
                };
                Some((Duration::ZERO, out))
            });
            let mut c = x_client(host, Duration::ZERO, Duration::from_millis(300));
            c.cfg.attach_wait = Duration::from_millis(1500);
            let r = c.attach();
            drop(c);
            let lines = card.join().unwrap();
            if stops {
                assert_eq!(r.unwrap().position_steps, Some(-40));
                assert!(lines.iter().any(|l| l == "1S"), "{lines:?}");
            } else {
                let e = r.unwrap_err();
                assert!(matches!(e, Error::StillMoving { waited_ms: 1500 }), "{e:?}");
                assert!(!lines.iter().any(|l| l == "1S"), "{lines:?}");
            }
        }
    }

    /// A card busy for `busy_after_zero` after `PZ` and silent `silent_after_zero` after it.
    fn zeroing_card(
        card: Pipe,
        busy_after_zero: Duration,
        silent_after_zero: Duration,
    ) -> std::thread::JoinHandle<Vec<String>> {
        let mut zeroed: Option<Instant> = None;
        x_card(card, move |line| {
            if line == "1PZ" {
                zeroed = Some(Instant::now());
            }
            let since = zeroed.map(|t| t.elapsed());
            if since.is_some_and(|t| t >= silent_after_zero) {
                return None;
            }
            let busy = since.is_some_and(|t| t < busy_after_zero);
            Some((Duration::ZERO, echoed(line, if busy { 'B' } else { 'R' })))
        })
    }

    /// After `PZ` the card may stay busy for up to the reset wait plus one reply timeout (here
    /// 200 + 1000 ms): one busy for 400 ms is waited for (with 800 ms to spare for a loaded
    /// machine's thread scheduling).
    #[test]
    fn init_waits_for_the_zeroing_within_its_deadline() {
        let (host, card) = Pipe::pair();
        let card = zeroing_card(card, Duration::from_millis(400), Duration::from_secs(3));
        let mut c = x_client(
            host,
            Duration::from_millis(200),
            Duration::from_millis(1000),
        );
        c.init().unwrap();
        let lines = card.join().unwrap();
        let after_zero = lines
            .iter()
            .skip_while(|l| *l != "1PZ")
            .filter(|l| *l == "1R");
        assert!(after_zero.count() >= 2, "{lines:?}");
    }

    /// A card still busy after `PZ` once the reset wait and one reply timeout (200 + 400 ms)
    /// have passed fails `init`, and that is the wait it reports.
    #[test]
    fn init_gives_up_on_a_zeroing_that_does_not_end() {
        let (host, card) = Pipe::pair();
        let _card = zeroing_card(card, Duration::from_secs(3), Duration::from_secs(3));
        let mut c = x_client(host, Duration::from_millis(200), Duration::from_millis(400));
        let e = c.init().unwrap_err();
        assert!(matches!(e, Error::MoveTimeout { waited_ms: 600 }), "{e:?}");
    }

    /// GRBL's start-up banner, as it comes after a soft reset.
    const BANNER: &str = "\r\nGrbl 1.1h ['$' for help]\r\n";

    /// A GRBL client on a pipe whose controller end has already written `lines` (CRLF-ended);
    /// the controller end comes back to read what the client wrote.
    fn grbl_answered(lines: &str) -> (GrblClient<Pipe>, Pipe) {
        let (host, mut card) = Pipe::pair();
        card.write_all(lines.as_bytes()).unwrap();
        let cfg = IndexerConfig {
            reset_wait: Duration::from_millis(150),
            reply_timeout: Duration::from_millis(150),
            ..IndexerConfig::default()
        };
        (GrblClient::new(host, cfg), card)
    }

    /// Everything the client has written to the controller end so far.
    fn written(card: &mut Pipe) -> Vec<u8> {
        let (mut all, mut buf) = (Vec::new(), [0u8; 256]);
        loop {
            let n = card
                .read_timeout(&mut buf, Duration::from_millis(20))
                .unwrap();
            if n == 0 {
                return all;
            }
            all.extend_from_slice(&buf[..n]);
        }
    }

    /// A GRBL 1.1 status report with the A axis (the fourth `MPos` field) at 12.5°.
    fn report(state: &str, feed: u32) -> String {
        format!("<{state}|MPos:0.000,0.000,0.000,12.500|FS:{feed},0>\r\n")
    }

    /// `init` soft-resets the controller (0x18) and waits for its banner, then sets the A axis'
    /// steps per degree (400 steps per motor turn × 60/13 belt / 360° = 5.1282) and zeroes A.
    #[test]
    fn grbl_init_resets_and_sets_up_the_a_axis() {
        let (host, mut card) = Pipe::pair();
        let controller = std::thread::spawn(move || {
            let (mut got, mut buf) = (Vec::new(), [0u8; 64]);
            loop {
                let n = card.read_timeout(&mut buf, CARD_IDLE).unwrap();
                if n == 0 {
                    return got;
                }
                for &b in &buf[..n] {
                    got.push(b);
                    match b {
                        grbl::SOFT_RESET => card.write_all(BANNER.as_bytes()).unwrap(),
                        b'\n' => card.write_all(b"ok\r\n").unwrap(),
                        _ => {}
                    }
                }
            }
        });
        let cfg = IndexerConfig {
            reply_timeout: Duration::from_millis(150),
            ..IndexerConfig::default()
        };
        let mut client = GrblClient::new(host, cfg);
        client.init().unwrap();
        assert_eq!(
            String::from_utf8(controller.join().unwrap()).unwrap(),
            "\u{18}$103=5.1282\nG92 A0\n"
        );
    }

    /// An `ALARM:N` in place of a line's `ok`, or in front of a status report, is reported as
    /// that alarm.
    #[test]
    fn grbl_alarms_are_reported() {
        let (mut c, _card) = grbl_answered("ALARM:1\r\n");
        let e = c.send(&grbl::Command::ZeroA).unwrap_err();
        assert!(matches!(&e, Error::Alarm(m) if m == "ALARM:1"), "{e:?}");
        let (mut c, _card) = grbl_answered(&format!("ALARM:1\r\n{}", report("Alarm", 0)));
        let e = c.status().unwrap_err();
        assert!(matches!(&e, Error::Alarm(m) if m == "ALARM:1"), "{e:?}");
    }

    /// A profile goes out in degrees at the mandrel: 0.5 rev/s × 360° × 60 s = 10 800 deg/min
    /// as the A axis' maximum rate (`$113`), 2 rev/s² × 360° = 720 deg/s² as its acceleration
    /// (`$123`).
    #[test]
    fn grbl_profile_goes_out_in_degrees() {
        let (mut c, mut card) = grbl_answered("ok\r\nok\r\n");
        c.set_profile(Profile {
            accel_rps2: 2.0,
            start_rps: 0.0,
            max_rps: 0.5,
        })
        .unwrap();
        assert_eq!(written(&mut card), b"$113=10800.000\n$123=720.000\n");
    }

    /// Constant velocity is a jog of a day's turning at the feed: 0.5 rev/s is 10 800 deg/min
    /// and 0.5 × 360° × 86 400 s = 15 552 000°, negative for the negative direction. From rest
    /// the jog goes out after the status request (`?`); a jog under way is cancelled first
    /// (0x85) and the drive waited for until idle.
    #[test]
    fn grbl_constant_velocity_is_a_day_long_jog_at_the_feed() {
        let idle = report("Idle", 0);
        let (mut c, mut card) = grbl_answered(&format!("{idle}ok\r\n"));
        c.run_constant(0.5, Direction::Positive).unwrap();
        assert_eq!(written(&mut card), b"?$J=G91 A15552000.0000 F10800.000\n");
        let (mut c, mut card) = grbl_answered(&format!("{idle}ok\r\n"));
        c.run_constant(0.5, Direction::Negative).unwrap();
        assert_eq!(written(&mut card), b"?$J=G91 A-15552000.0000 F10800.000\n");
        let jog = report("Jog", 10_800);
        let (mut c, mut card) = grbl_answered(&format!("{jog}{idle}ok\r\n"));
        c.run_constant(0.25, Direction::Positive).unwrap();
        assert_eq!(
            written(&mut card),
            b"?\x85?$J=G91 A7776000.0000 F5400.000\n"
        );
    }

    /// A kill is a soft reset (0x18) and nothing else; the client waits for the banner.
    #[test]
    fn grbl_kill_is_a_soft_reset() {
        let (mut c, mut card) = grbl_answered(BANNER);
        c.stop(StopKind::Kill).unwrap();
        assert_eq!(written(&mut card), [grbl::SOFT_RESET]);
    }

    /// A decelerating stop of a jog is a jog cancel (0x85), waited for until idle, without a
    /// reset. Of a motion line it is a feed hold (`!`), then status requests (`?`) until the hold
    /// is complete, `Hold:0` with the feed at 0 (either alone is waited past) or the drive idle,
    /// then a soft reset (0x18) to drop the rest of the motion.
    #[test]
    fn grbl_decelerating_stop_holds_until_at_rest_then_resets() {
        let (mut c, mut card) =
            grbl_answered(&format!("{}{}", report("Jog", 10_800), report("Idle", 0)));
        c.stop(StopKind::Decelerate).unwrap();
        assert_eq!(written(&mut card), b"?\x85?");

        let run = report("Run", 10_800);
        let hold = |holding: &[(&str, u32)]| {
            let mut lines = run.clone();
            for (state, feed) in holding {
                lines += &report(state, *feed);
            }
            lines + BANNER
        };
        // Decelerating, at feed 0 but the hold not yet complete, complete.
        let (mut c, mut card) =
            grbl_answered(&hold(&[("Hold:1", 2_400), ("Hold:1", 0), ("Hold:0", 0)]));
        c.stop(StopKind::Decelerate).unwrap();
        assert_eq!(written(&mut card), b"?!???\x18");
        // Reported complete while the feed is not yet 0, then complete.
        let (mut c, mut card) = grbl_answered(&hold(&[("Hold:0", 120), ("Hold:0", 0)]));
        c.stop(StopKind::Decelerate).unwrap();
        assert_eq!(written(&mut card), b"?!??\x18");
        // The motion ended before the hold: idle.
        let (mut c, mut card) = grbl_answered(&hold(&[("Idle", 0)]));
        c.stop(StopKind::Decelerate).unwrap();
        assert_eq!(written(&mut card), b"?!?\x18");
        // A hold that does not complete within the stop's wait: reset anyway, at the first
        // report past the wait (here none is allowed), the later reports left unread.
        let (c, mut card) = grbl_answered(&hold(&[("Hold:1", 2_400), ("Hold:1", 2_400)]));
        let mut c = c.with_stop_wait(Duration::ZERO);
        c.stop(StopKind::Decelerate).unwrap();
        assert_eq!(written(&mut card), b"?!?\x18");
    }
}
