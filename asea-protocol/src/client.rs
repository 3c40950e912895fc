//! The blocking client: one host session per telegram over any [`Link`], with a retry policy
//! (docs/protocol.md §6).
//!
//! Within a session the [`Host`] state machine retries by itself (ENQ up to `N_ENQ`, the telegram
//! up to `N_TX`). A whole new session is started again only for requests without side effects
//! (ENQUIRE, READ_BACK, PROGRAM_INFO), and never after a session in which the robot answered none
//! of its `N_ENQ` ENQs ([`crate::error::LinkError::NoResponse`]): that is a silent robot, not
//! noise, and is reported at once (within `N_ENQ × T_ENQ`, 12 s by default). A robot that refused
//! every ENQ of a session as busy ([`crate::error::LinkError::Busy`]) is asked again in new
//! sessions by the request, but the layers above (agreeing status reads, read-backs, command
//! confirmation, STOP's confirmation) do not repeat that: either is reported rather than retried
//! by every layer, which multiplied a hung robot into minutes. A command is sent again only once the robot's status proves
//! that it was not executed ([`Client::command_confirmed`]); stored instructions are proven by
//! reading them back ([`Client::store_verified`]). The guarantee of each command class is the
//! table in docs/protocol.md §7.
//!
//! Every exchange can be cancelled from another thread with the [`Cancel`] token
//! ([`Client::cancel_token`]): the exchange under way ends with an EOT and [`Error::Cancelled`]
//! within [`POLL_PERIOD`], and [`Client::stop`] still goes through while the token is set.

use std::time::Duration;

use crate::clock::{Clock, WallClock};
use crate::command::{
    Command, Control, Instruction, Pose, Positioning, Reply, RobotError, Selector, Speed, Status,
};
use crate::error::{Error, Result};
use crate::frame::{Frame, FrameConfig};
use crate::link::{Link, SerialLink};
use crate::session::{Host, Stats, Timers};

/// How often to start a request session again after a link failure, and how often to re-store
/// an instruction whose read-back differs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RetryPolicy {
    /// Sessions tried for ENQUIRE and READ_BACK (at least 1).
    pub request_sessions: u32,
    /// Re-stores of one instruction during [`Client::verify`].
    pub restores: u32,
    /// Attempts of one confirmed command ([`Client::command_confirmed`]); each attempt after the
    /// first follows a status that proves the previous one was not executed.
    pub command_attempts: u32,
    /// Uploads of one program of a batch ([`Client::upload_batch`]) when its program information
    /// shows instructions the upload did not write.
    pub program_uploads: u32,
}

impl Default for RetryPolicy {
    fn default() -> Self {
        RetryPolicy {
            request_sessions: 3,
            restores: 3,
            command_attempts: 3,
            program_uploads: 3,
        }
    }
}

/// Longest wait of one read: a cancelled exchange ends within this (plus one byte write). It
/// bounds how late a stop request is seen while the host waits out a gap or a silent robot, so
/// it is small beside the urgent gap ([`crate::session::Timers::urgent_gap`]). The one poll
/// period of the shared plumbing ([`paths::link::POLL_PERIOD`]).
pub use paths::link::POLL_PERIOD;

/// The token that cancels the client's exchanges from another thread or task
/// ([`paths::link::Cancel`], the same for both devices).
pub use paths::link::Cancel;

/// Status replies in a row that must agree (on every field but state and instruction, which
/// move while the arm runs) before the client acts on them: one corrupted reply that a one-byte
/// sum lets through cannot make a command look unexecuted (and be sent twice) or hide an error.
pub const AGREE_STATUS: u32 = 2;

/// Set-up of a [`Client`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ClientConfig {
    /// Framing (check value, span, max LEN); must match the robot's.
    pub frame: FrameConfig,
    /// Timers and retry counts.
    pub timers: Timers,
    /// Session-level retries.
    pub retry: RetryPolicy,
}

/// Read-backs [`Client::confirm_stored`] makes at most before giving up.
pub const CONFIRMING_READS: u32 = 8;
/// Answers in a row equal to the wanted instruction that prove it stored.
pub const AGREE_STORED: u32 = 2;
/// Answers in a row agreeing on something else that prove it not stored.
pub const AGREE_DIFFERENT: u32 = 3;

/// Result of [`Client::verify`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct VerifyReport {
    /// Instructions read back.
    pub checked: usize,
    /// Instructions stored again because they read back differently.
    pub restored: usize,
    /// Errors the robot raised during the upload that belong to no instruction of it (corrupted
    /// twins it refused), acknowledged.
    pub refused_twins: u64,
}

/// The blocking robot client.
#[derive(Debug)]
pub struct Client<L, C = WallClock> {
    link: L,
    clock: C,
    host: Host,
    cfg: ClientConfig,
    buf: Vec<u8>,
    cancel: Cancel,
    /// While true the cancel token is ignored (STOP).
    uncancellable: bool,
    /// While true a session starts after the urgent gap (STOP, [`Host::start_urgent`]).
    urgent: bool,
    /// A cancelled session of which the robot has seen no telegram was left open: STOP takes it
    /// over
    /// ([`Host::take_over`]), any other session ends it with EOT first.
    held: bool,
    /// The robot's error sequence number as last accounted for: errors up to it are reported.
    seen_error_seq: Option<u8>,
    /// Errors the robot raised that this client has seen (reported or acknowledged), counted by
    /// sequence number.
    errors_seen: u64,
    /// The robot's execution count after the last confirmed command, while nothing else with an
    /// effect was sent since (stores make it unknown).
    last_executed: Option<u16>,
}

/// How long the line must say nothing before [`Client::attach`] starts its first session: longer
/// than the robot's gaps inside a session it answers (a byte at 9600 baud is about 1 ms).
pub const ATTACH_QUIET: Duration = Duration::from_millis(100);

/// Longest [`Client::attach`] waits for the line to go quiet.
pub const ATTACH_QUIET_LIMIT: Duration = Duration::from_secs(5);

impl<L: Link> Client<L, WallClock> {
    /// A client on `link` in wall time.
    pub fn new(link: L, cfg: ClientConfig) -> Self {
        Client::with_clock(link, WallClock::new(), cfg)
    }
}

impl Client<SerialLink<Box<dyn serialport::SerialPort>>, WallClock> {
    /// A client on the serial port at `path`, 9600 baud 8N1 (docs/protocol.md §1; see
    /// [`crate::link::open_serial`] for other settings).
    pub fn open(path: &str, cfg: ClientConfig) -> Result<Self> {
        let port = crate::link::open_serial(
            path,
            crate::link::DEFAULT_BAUD,
            crate::link::DEFAULT_CHAR_FORMAT,
        )?;
        Ok(Client::new(port, cfg))
    }
}

impl<L: Link, C: Clock> Client<L, C> {
    /// A client on `link` timed by `clock` (a virtual clock for a paced wire).
    pub fn with_clock(link: L, clock: C, cfg: ClientConfig) -> Self {
        Client {
            link,
            clock,
            host: Host::new(cfg.frame, cfg.timers),
            cfg,
            buf: vec![0u8; 256],
            cancel: Cancel::new(),
            uncancellable: false,
            urgent: false,
            held: false,
            seen_error_seq: None,
            errors_seen: 0,
            last_executed: None,
        }
    }

    /// Errors the robot raised that this client has seen since it was made (by the robot's error
    /// sequence number, so errors that overwrote each other between two reads count each).
    pub fn errors_seen(&self) -> u64 {
        self.errors_seen
    }

    /// The token that cancels this client's exchanges (clone it into another thread).
    pub fn cancel_token(&self) -> Cancel {
        self.cancel.clone()
    }

    /// Link counters.
    pub fn stats(&self) -> Stats {
        self.host.stats()
    }

    /// The link.
    pub fn link(&self) -> &L {
        &self.link
    }

    /// The link, mutably.
    pub fn link_mut(&mut self) -> &mut L {
        &mut self.link
    }

    /// Gives the link back.
    pub fn into_link(self) -> L {
        self.link
    }

    fn session(&mut self, cmd: &Command) -> Result<Option<Frame>> {
        let bytes = cmd.encode(&self.cfg.frame)?;
        let held = std::mem::take(&mut self.held);
        if held
            && self.urgent
            && self
                .host
                .take_over(bytes.clone(), cmd.expects_reply(), self.clock.now())
        {
            // The cancelled session's robot has seen no telegram of it: STOP goes in that
            // session (the ACK to its ENQ may be waiting in the input: nothing is discarded).
        } else {
            if held {
                // A session left open for STOP and not taken over: its EOT ends it.
                self.host.abort(self.clock.now());
                self.write_out()?;
            }
            self.link.discard_input()?;
            if self.urgent {
                self.host
                    .start_urgent(bytes, cmd.expects_reply(), self.clock.now());
            } else {
                self.host
                    .start(bytes, cmd.expects_reply(), self.clock.now());
            }
        }
        loop {
            // Before anything more goes out: a cancelled session is held for STOP while the
            // robot has seen no telegram of it, else abandoned.
            if !self.uncancellable && self.cancel.is_cancelled() {
                if self.host.can_take_over() {
                    // Left open: a STOP that follows takes this session over
                    // ([`Client::stop_at_once`]); any other session ends it first.
                    self.held = true;
                } else {
                    self.host.abort(self.clock.now());
                    self.write_out()?;
                }
                return Err(Error::Cancelled);
            }
            let out = self.host.take_output();
            if !out.is_empty() {
                self.link.write_all(&out)?;
                self.host.on_sent(self.clock.now());
                // Half duplex: nothing the robot sent while we were sending an ENQ or a telegram
                // answers it (a duplicated or stale ACK must not acknowledge a telegram the
                // robot never saw).
                if matches!(out.first(), Some(&crate::frame::ENQ | &crate::frame::STX)) {
                    self.link.discard_input()?;
                }
            }
            if let Some(outcome) = self.host.take_outcome() {
                return outcome.map_err(Error::from);
            }
            if !self.uncancellable && self.cancel.is_cancelled() {
                continue;
            }
            let now = self.clock.now();
            let wait = match self.host.deadline() {
                Some(d) => d.saturating_sub(now),
                None => POLL_PERIOD,
            }
            .min(POLL_PERIOD);
            if wait.is_zero() {
                self.host.on_time(now);
                continue;
            }
            let n = self.link.read_timeout(&mut self.buf, wait)?;
            let now = self.clock.now();
            if let Some(bytes) = self.buf.get(..n)
                && n > 0
            {
                self.host.on_bytes(bytes, now);
            }
            self.host.on_time(now);
        }
    }

    /// Writes what the host has to send after an abort.
    fn write_out(&mut self) -> Result<()> {
        let out = self.host.take_output();
        if !out.is_empty() {
            self.link.write_all(&out)?;
            self.host.on_sent(self.clock.now());
        }
        Ok(())
    }

    /// Sends `cmd` in one session, once. `Ok` means the robot acknowledged a telegram: on a CRC-16
    /// link with the ACK window that is `cmd`, executed once; on the thesis's one-byte sum it may
    /// have been a corrupted twin (docs/protocol.md §7). An error means it was not acknowledged:
    /// it may have been executed once, never twice by this call. Semantic errors are latched by
    /// the robot and read with [`Client::check_status`]. [`Client::command_confirmed`] and
    /// [`Client::store_verified`] prove what was executed.
    pub fn send(&mut self, cmd: &Command) -> Result<()> {
        self.session(cmd).map(|_| ())
    }

    /// Sends a request (ENQUIRE, READ_BACK) and returns its reply, starting new sessions on link
    /// errors up to [`RetryPolicy::request_sessions`].
    pub fn request(&mut self, cmd: &Command) -> Result<Reply> {
        if !cmd.expects_reply() {
            return Err(Error::UnexpectedReply("request: the command has no reply"));
        }
        let mut last = None;
        for _ in 0..self.cfg.retry.request_sessions.max(1) {
            match self.session(cmd) {
                Ok(Some(frame)) => match Reply::from_frame(&frame) {
                    Ok(reply) => return Ok(reply),
                    // A reply that passed the check value but does not parse was corrupted.
                    Err(source) => {
                        last = Some(Error::Reply {
                            telegram: request_name(cmd),
                            source,
                        })
                    }
                },
                Ok(None) => last = Some(Error::UnexpectedReply("no reply telegram")),
                Err(e) if is_silent(&e) => return Err(e),
                Err(Error::Link(e)) => last = Some(Error::Link(e)),
                Err(e) => return Err(e),
            }
        }
        Err(last.unwrap_or(Error::UnexpectedReply("no reply")))
    }

    /// Attaches to a robot computer that may have been talking to a run that was killed: waits
    /// until the line has been quiet for [`ATTACH_QUIET`] (dropping what comes: the end of a
    /// session the killed run left, the robot's retransmissions), at most [`ATTACH_QUIET_LIMIT`]
    /// ([`Error::LineNotQuiet`]), then starts a session of its own with ENQUIRE status: its answer
    /// is the status reply telegram, recognised by its code and check value, never a stray byte
    /// (docs/protocol.md §6). Reading the status does not clear a latched error.
    pub fn attach(&mut self) -> Result<Status> {
        let d = paths::link::drain_until_quiet(
            &mut self.link,
            &self.clock,
            ATTACH_QUIET,
            ATTACH_QUIET_LIMIT,
        )?;
        if !d.quiet {
            return Err(Error::LineNotQuiet {
                waited_ms: ATTACH_QUIET_LIMIT.as_millis() as u64,
            });
        }
        self.status()
    }

    /// ENQUIRE status, one reply (reading it does not clear the robot's latched error).
    pub fn status(&mut self) -> Result<Status> {
        match self.request(&Command::Enquire(Selector::Status))? {
            Reply::Status(s) => Ok(s),
            _ => Err(Error::UnexpectedReply(
                "enquire status answered with another reply",
            )),
        }
    }

    /// ENQUIRE status until [`AGREE_STATUS`] replies in a row agree on everything but the state
    /// and the instruction (at most [`CONFIRMING_READS`] reads).
    pub fn status_agreed(&mut self) -> Result<Status> {
        let key = |s: &Status| {
            (
                s.mode,
                s.program,
                s.last_error,
                s.homed,
                s.error_seq,
                s.executed,
                s.last_digest,
            )
        };
        let mut run: Option<(Status, u32)> = None;
        let mut last_error = None;
        for _ in 0..CONFIRMING_READS {
            match self.status() {
                Ok(s) => {
                    let n = match &run {
                        Some((prev, n)) if key(prev) == key(&s) => n + 1,
                        _ => 1,
                    };
                    if n >= AGREE_STATUS {
                        return Ok(s);
                    }
                    run = Some((s, n));
                }
                Err(e) if is_link_noise(&e) => last_error = Some(e),
                Err(e) => return Err(e),
            }
        }
        Err(last_error.unwrap_or(Error::UnexpectedReply("status replies never agreed")))
    }

    /// Reads the status ([`Client::status_agreed`]) and reports a latched error the client has
    /// not reported yet as [`Error::Robot`], after acknowledging it (ACK_ERROR with its sequence
    /// number). The robot keeps an error latched until acknowledged, so a lost, corrupted or
    /// duplicated status reply cannot erase it: it is reported at the next check. An error
    /// already reported whose acknowledgement was lost is acknowledged again, not reported twice.
    pub fn check_status(&mut self) -> Result<Status> {
        let s = self.status_agreed()?;
        self.account_errors(&s).map(|()| s)
    }

    /// Reads the robot's error sequence number once, before this client's first command with an
    /// effect, so that every error raised afterwards is counted by its number: without it, two
    /// errors raised before the first status read (two refused twins of one upload) would count
    /// as one, the latched one. An error still latched at this read is left to the next check,
    /// which reports it.
    fn error_baseline(&mut self) -> Result<()> {
        if self.seen_error_seq.is_none() {
            let s = self.status_agreed()?;
            self.seen_error_seq = Some(s.error_seq.wrapping_sub(u8::from(s.last_error != 0)));
        }
        Ok(())
    }

    /// Reports and acknowledges the errors `s` shows beyond those already accounted for.
    fn account_errors(&mut self, s: &Status) -> Result<()> {
        let new = self
            .seen_error_seq
            .map_or(s.last_error != 0, |seen| seen != s.error_seq);
        if new && s.last_error == 0 {
            // Only this client acknowledges errors, so a new error number without its code is a
            // corrupted reply (or another host's doing): the error, if there is one, is still
            // latched and the next read reports it.
            return Ok(());
        }
        let count = self
            .seen_error_seq
            .map_or(u8::from(s.last_error != 0), |seen| {
                s.error_seq.wrapping_sub(seen)
            });
        self.errors_seen += u64::from(count);
        self.seen_error_seq = Some(s.error_seq);
        if s.last_error != 0 {
            // Idempotent: it clears only the error with this number; if it is lost the error stays
            // latched and the next check acknowledges it again.
            let _ = self.send(&Command::AckError { seq: s.error_seq });
        }
        if !new {
            return Ok(());
        }
        let code = s.last_error;
        let message = RobotError::from_code(code).map_or("unknown", RobotError::message);
        Err(Error::Robot {
            code,
            message,
            program: s.program,
            instruction: s.instruction,
            count,
        })
    }

    /// Sends a command with an effect and proves what the robot did by its status (seed 001
    /// §5.3.1: "a continuous check of the communication link is possible with the ENQUIRE
    /// command"): the execution count must have advanced by exactly one, with the digest of the
    /// telegram sent, and `effect` must hold for the status after it. A count that did not move
    /// proves the command not executed; only then is it sent again (at most
    /// [`RetryPolicy::command_attempts`] times in all). A count that moved by more than one, or
    /// the digest of another telegram, is [`Error::Foreign`]; an error the robot raised is
    /// [`Error::Robot`] (acknowledged); a wrong effect is [`Error::Effect`]. Never sent blindly.
    /// An error latched before the command and not reported yet is reported before it is sent,
    /// except before STOP, which goes out first; the error is then reported after it.
    pub fn command_confirmed(
        &mut self,
        cmd: &Command,
        effect: fn(&Command, &Status) -> std::result::Result<(), &'static str>,
    ) -> Result<Status> {
        let bytes = cmd.encode(&self.cfg.frame)?;
        let data = bytes
            .get(3..3 + usize::from(bytes.get(2).copied().unwrap_or(0)))
            .unwrap_or_default();
        let sent = crate::frame::telegram_digest(cmd.code(), data);
        let name = command_name(cmd);
        let mut before = self.status_agreed()?;
        // Errors from before this command are not its errors: report them first. Not before a
        // STOP, which must not be held back: they stay latched and are reported once it has
        // been executed (by the check of the status after it).
        if !matches!(cmd, Command::Stop) {
            self.account_errors(&before)?;
        }
        // Anything executed since the last confirmed command that this client did not send.
        if let Some(last) = self.last_executed.take()
            && last != before.executed
        {
            return Err(Error::Foreign {
                command: "(between commands)",
                executed: before.executed.wrapping_sub(last),
                digest: before.last_digest,
                sent: 0,
            });
        }
        let attempts = self.cfg.retry.command_attempts.max(1);
        for _ in 0..attempts {
            match self.send(cmd) {
                Err(Error::Cancelled) => return Err(Error::Cancelled),
                Err(Error::Io(e)) => return Err(Error::Io(e)),
                // Not one ENQ taken: the telegram never went out, and no status read would be
                // taken either (docs/protocol.md §6 rule 3).
                Err(e) if is_unanswered(&e) => return Err(e),
                // A link failure leaves the command's fate unknown: the status decides.
                _ => {}
            }
            let after = self.status_agreed()?;
            let executed = after.executed.wrapping_sub(before.executed);
            match executed {
                0 => {
                    before = after;
                    continue;
                }
                1 if after.last_digest == sent => {
                    self.last_executed = Some(after.executed);
                    self.account_errors(&after)?;
                    return match effect(cmd, &after) {
                        Ok(()) => Ok(after),
                        Err(expected) => Err(Error::Effect {
                            command: name,
                            expected,
                            found: after.to_string(),
                        }),
                    };
                }
                _ => {
                    // Errors stay latched for the next check to report.
                    return Err(Error::Foreign {
                        command: name,
                        executed,
                        digest: after.last_digest,
                        sent,
                    });
                }
            }
        }
        Err(Error::NotExecuted {
            command: name,
            attempts,
        })
    }

    /// ENQUIRE position.
    pub fn position(&mut self) -> Result<Pose> {
        match self.request(&Command::Enquire(Selector::Position))? {
            Reply::Position(p) => Ok(p),
            _ => Err(Error::UnexpectedReply(
                "enquire position answered with another reply",
            )),
        }
    }

    /// Reads instruction `instruction` of `program` back (`None`: nothing stored).
    pub fn read_back(&mut self, program: u8, instruction: u16) -> Result<Option<Instruction>> {
        match self.request(&Command::ReadBack {
            program,
            instruction,
        })? {
            Reply::ReadBack {
                program: p,
                instruction: i,
                stored,
            } if p == program && i == instruction => Ok(stored),
            _ => Err(Error::UnexpectedReply("read-back of another instruction")),
        }
    }

    /// Standby mode, confirmed ([`Client::command_confirmed`]: the status shows STANDBY).
    pub fn standby(&mut self) -> Result<Status> {
        self.command_confirmed(&Command::Standby, effect_of)
    }

    /// Operate mode, confirmed (the status shows OPERATE).
    pub fn operate(&mut self) -> Result<Status> {
        self.command_confirmed(&Command::Operate, effect_of)
    }

    /// Home synchronisation, confirmed (homing under way, or homed).
    pub fn sync_home(&mut self) -> Result<Status> {
        self.command_confirmed(&Command::SyncHome, effect_of)
    }

    /// Runs a stored program, confirmed (running it, or idle after a standby dry run). A program
    /// the robot refuses is [`Error::Robot`] with the instruction it stopped at (a pose the arm
    /// cannot take: code 9).
    pub fn run_program(&mut self, program: u8) -> Result<Status> {
        self.command_confirmed(&Command::RunProgram { program }, effect_of)
    }

    /// Stops motion, confirmed (the state is STOPPED). It goes through while the cancel token is
    /// set: this is what a cancelled coordinator sends.
    pub fn stop(&mut self) -> Result<Status> {
        self.uncancellable = true;
        let r = self.command_confirmed(&Command::Stop, effect_of);
        self.uncancellable = false;
        r
    }

    /// Stops motion with the least delay: STOP goes out in the first session, before any status
    /// is read (a STOP executed twice is still one stop, so it needs no proof that it was not
    /// executed before it is sent), then the status must show STOPPED; if it does not (the session
    /// failed), [`Client::stop`] sends it again, confirmed. Like [`Client::stop`] it goes through
    /// while the cancel token is set. The execution count is unknown afterwards, as after a store.
    pub fn stop_at_once(&mut self) -> Result<Status> {
        self.uncancellable = true;
        self.urgent = true;
        let sent = self.send(&Command::Stop);
        self.urgent = false;
        self.last_executed = None;
        let r = match sent {
            Err(Error::Io(e)) => Err(Error::Io(e)),
            // Not one ENQ taken: no status will be either.
            Err(e) if is_unanswered(&e) => Err(e),
            _ => match self.status_agreed() {
                Ok(s) if s.state == crate::command::State::Stopped => Ok(s),
                Err(e) if is_unanswered(&e) => Err(e),
                Ok(_) | Err(Error::Link(_)) => self.command_confirmed(&Command::Stop, effect_of),
                Err(e) => Err(e),
            },
        };
        self.uncancellable = false;
        r
    }

    /// Deletes a program, confirmed (executed once; a program that did not exist is error 5).
    pub fn delete_program(&mut self, program: u8) -> Result<Status> {
        self.command_confirmed(&Command::DeleteProgram { program }, effect_of)
    }

    /// A discrete-mode move, executed at once, confirmed (the arm is moving, or idle in
    /// standby). A robot busy with another move or program refuses it: [`Error::Robot`] code 7.
    pub fn move_immediate(&mut self, p: Positioning) -> Result<Status> {
        self.command_confirmed(&Command::MoveImmediate(p), effect_of)
    }

    /// Base speed, m/s, confirmed (executed once).
    pub fn set_base_speed(&mut self, speed: Speed) -> Result<Status> {
        self.command_confirmed(&Command::SetBaseSpeed(speed), effect_of)
    }

    /// Maximum speed, m/s, confirmed (executed once).
    pub fn set_max_speed(&mut self, speed: Speed) -> Result<Status> {
        self.command_confirmed(&Command::SetMaxSpeed(speed), effect_of)
    }

    /// PROGRAM_INFO until [`AGREE_STORED`] answers in a row agree: (instructions in `program`,
    /// its highest instruction number, instructions in the whole memory).
    pub fn program_info(&mut self, program: u8) -> Result<(u16, u16, u16)> {
        let mut run: Option<((u16, u16, u16), u32)> = None;
        let mut last_error = None;
        for _ in 0..CONFIRMING_READS {
            match self.request(&Command::ProgramInfo { program }) {
                Ok(Reply::ProgramInfo {
                    program: p,
                    count,
                    highest,
                    total,
                }) if p == program => {
                    let info = (count, highest, total);
                    let n = match &run {
                        Some((prev, n)) if *prev == info => n + 1,
                        _ => 1,
                    };
                    if n >= AGREE_STORED {
                        return Ok(info);
                    }
                    run = Some((info, n));
                }
                Ok(_) => {
                    last_error = Some(Error::UnexpectedReply("program info of another program"))
                }
                Err(e) if is_link_noise(&e) => last_error = Some(e),
                Err(e) => return Err(e),
            }
        }
        Err(last_error.unwrap_or(Error::UnexpectedReply("program info never agreed")))
    }

    /// Uploads a batch of programs (seed 001 §5.6.4: every control file of the sequence file into
    /// memory before the run file starts): each with [`Client::upload_verified`], then every
    /// program of the batch read back once more (a corrupted twin stored for one program can
    /// overwrite another), then PROGRAM_INFO for each: a program holding more than its
    /// instructions (a twin with a corrupted instruction number) is deleted and uploaded again,
    /// and a memory total above what the batch and the memory's earlier contents account for (a
    /// twin with a corrupted program number) is [`Error::ForeignStore`]. On `Ok` every program of
    /// the batch holds exactly its instructions and nothing else was stored.
    pub fn upload_batch(&mut self, batch: &[(u8, &[Instruction])]) -> Result<VerifyReport> {
        self.error_baseline()?;
        let mut report = VerifyReport::default();
        // Clear the batch's programs; what the memory holds then is outside the batch.
        let mut programs: Vec<u8> = batch.iter().map(|(p, _)| *p).collect();
        programs.sort_unstable();
        programs.dedup();
        let mut outside = 0;
        for program in &programs {
            let (count, _, total) = self.program_info(*program)?;
            if count > 0 {
                self.delete_quietly(*program)?;
            }
            outside = total.saturating_sub(count);
        }
        for (program, instructions) in batch {
            let r = self.upload_verified(*program, instructions)?;
            report.checked += r.checked;
            report.restored += r.restored;
            report.refused_twins += r.refused_twins;
        }
        for (program, instructions) in batch {
            for (n, i) in (1u16..).zip(instructions.iter()) {
                report.checked += 1;
                report.restored += self.settle(*program, n, i)?;
            }
        }
        let expected: u16 = batch
            .iter()
            .map(|(_, i)| u16::try_from(i.len()).unwrap_or(u16::MAX))
            .fold(0, u16::saturating_add);
        for (program, instructions) in batch {
            let len = u16::try_from(instructions.len()).unwrap_or(u16::MAX);
            let mut uploads = 1;
            loop {
                // After the read-backs every slot 1..=len holds its instruction, so the two
                // conditions agree; together they say what is meant: exactly those slots.
                let (count, highest, _) = self.program_info(*program)?;
                if count == len && highest == len {
                    break;
                }
                if uploads >= self.cfg.retry.program_uploads {
                    return Err(Error::ExtraSlots {
                        program: *program,
                        count,
                        expected: len,
                    });
                }
                uploads += 1;
                self.delete_quietly(*program)?;
                let r = self.upload_verified(*program, instructions)?;
                report.checked += r.checked;
                report.restored += r.restored;
                report.refused_twins += r.refused_twins;
            }
        }
        let (_, _, total) = self.program_info(batch.first().map_or(1, |(p, _)| *p))?;
        if total != expected.saturating_add(outside) {
            return Err(Error::ForeignStore {
                total,
                expected: expected.saturating_add(outside),
            });
        }
        Ok(report)
    }

    /// Deletes `program`, confirmed; a program that was already gone is no error here.
    fn delete_quietly(&mut self, program: u8) -> Result<()> {
        match self.delete_program(program) {
            Ok(_) => Ok(()),
            Err(Error::Robot { code, .. }) if code == RobotError::NoProgram.code() => Ok(()),
            Err(e) => Err(e),
        }
    }

    /// Stores one instruction (positioning or control) as `instruction` of `program`, sent once
    /// ([`Client::send`]); [`Client::store_verified`] proves it.
    pub fn store(&mut self, program: u8, instruction: u16, i: &Instruction) -> Result<()> {
        self.last_executed = None;
        self.send(&store_command(program, instruction, i))
    }

    /// Stores `instructions` as instructions 1, 2, … of `program`, then checks `last_error`.
    pub fn upload(&mut self, program: u8, instructions: &[Instruction]) -> Result<()> {
        self.error_baseline()?;
        for (n, i) in (1u16..).zip(instructions) {
            self.store(program, n, i)?;
        }
        self.check_status().map(|_| ())
    }

    /// Uploads `instructions` as instructions 1, 2, … of `program` with verified stores
    /// ([`Client::store_verified`]), then reads the whole program back once more and stores again
    /// any instruction a corrupted twin overwrote meanwhile (as [`Client::verify`] does, each
    /// instruction started again after link failures), and finally reads the status to clear the
    /// error a refused twin may have left. This is the upload for a link whose check value can be
    /// fooled (the thesis's one-byte sum, docs/protocol.md §7.1): on success the robot holds
    /// exactly `instructions`; a store the robot refuses fails with its `last_error`.
    ///
    /// A twin with a corrupted instruction number can also land beyond the program's end; the
    /// robot never runs past `Control::End`, and deleting the program before the upload clears
    /// such leftovers.
    pub fn upload_verified(
        &mut self,
        program: u8,
        instructions: &[Instruction],
    ) -> Result<VerifyReport> {
        self.upload_verified_reporting(program, instructions, &mut || {})
    }

    /// [`Client::upload_verified`], calling `progress` after each instruction is stored and
    /// after each is verified (twice per instruction in all).
    pub fn upload_verified_reporting(
        &mut self,
        program: u8,
        instructions: &[Instruction],
        progress: &mut dyn FnMut(),
    ) -> Result<VerifyReport> {
        self.error_baseline()?;
        let mut report = VerifyReport::default();
        for (n, i) in (1u16..).zip(instructions) {
            report.restored += match self.store_verified(program, n, i) {
                Ok(stores) => stores - 1,
                // A robot that took no ENQ is reported at once (docs/protocol.md §6 rule 3).
                Err(e) if is_unanswered(&e) => return Err(e),
                // The store's fate is unknown: settle it by reading back, never by a blind store.
                Err(_) => self.settle(program, n, i)?,
            };
            progress();
        }
        for (n, i) in (1u16..).zip(instructions) {
            report.checked += 1;
            report.restored += self.settle(program, n, i)?;
            progress();
        }
        // Every instruction is confirmed, so a new latched error now can only come from a
        // corrupted twin the robot refused: acknowledge it and count it in the report (a twin
        // that was stored is found by [`Client::upload_batch`]).
        let seen = self.errors_seen;
        match self.check_status() {
            Ok(_) | Err(Error::Robot { .. }) => {}
            Err(e) if is_link_noise(&e) => {}
            Err(e) => return Err(e),
        }
        report.refused_twins += self.errors_seen - seen;
        Ok(report)
    }

    /// [`Client::ensure_stored`], started again after link failures up to
    /// [`RetryPolicy::request_sessions`] times in all. Returns the stores sent.
    fn settle(&mut self, program: u8, instruction: u16, want: &Instruction) -> Result<usize> {
        let mut last = None;
        for _ in 0..self.cfg.retry.request_sessions.max(1) {
            match self.ensure_stored(program, instruction, want) {
                Ok(stores) => return Ok(stores),
                Err(e) if is_link_noise(&e) || matches!(e, Error::Verify { .. }) => last = Some(e),
                Err(e) => return Err(e),
            }
        }
        // A store the robot keeps refusing (memory full, a value out of range) reads back
        // differently every time: name the robot's reason when it gives one.
        if matches!(last, Some(Error::Verify { .. })) {
            match self.check_status() {
                Err(robot @ Error::Robot { .. }) => return Err(robot),
                // Reported earlier (a failed store's error): name it again here.
                Ok(s) if s.last_error != 0 => {
                    return Err(Error::Robot {
                        code: s.last_error,
                        message: RobotError::from_code(s.last_error)
                            .map_or("unknown", RobotError::message),
                        program,
                        instruction,
                        count: 0,
                    });
                }
                _ => {}
            }
        }
        Err(last.unwrap_or(Error::Verify {
            program,
            instruction,
        }))
    }

    /// Reads every instruction of an uploaded program back and stores again any that differ (a
    /// store overwrites, so this is idempotent).
    pub fn verify(&mut self, program: u8, instructions: &[Instruction]) -> Result<VerifyReport> {
        let mut report = VerifyReport::default();
        for (n, want) in (1u16..).zip(instructions) {
            report.checked += 1;
            report.restored += self.ensure_stored(program, n, want)?;
        }
        Ok(report)
    }

    /// Decides by reading back whether `instruction` of `program` holds `want`: `true` once
    /// [`AGREE_STORED`] answers in a row equal `want`, `false` once [`AGREE_DIFFERENT`] answers in a
    /// row agree on something else, an error after [`CONFIRMING_READS`] reads without either.
    ///
    /// A one-byte sum lets some corrupted replies through (a duplicated and a dropped byte of equal
    /// value cancel), so one answer proves nothing on a noisy `Sum8` link. "Different" needs more
    /// agreeing answers than "stored" because it leads to a store, the only step that could
    /// execute a telegram twice.
    pub fn confirm_stored(
        &mut self,
        program: u8,
        instruction: u16,
        want: &Instruction,
    ) -> Result<bool> {
        let mut run: Option<(Option<Instruction>, u32)> = None;
        let mut last_error = None;
        for _ in 0..CONFIRMING_READS {
            match self.read_back(program, instruction) {
                Ok(answer) => {
                    let count = match &run {
                        Some((previous, n)) if *previous == answer => n + 1,
                        _ => 1,
                    };
                    let stored = answer.as_ref() == Some(want);
                    if stored && count >= AGREE_STORED {
                        return Ok(true);
                    }
                    if !stored && count >= AGREE_DIFFERENT {
                        return Ok(false);
                    }
                    run = Some((answer, count));
                }
                Err(e) if is_link_noise(&e) => last_error = Some(e),
                Err(e) => return Err(e),
            }
        }
        Err(last_error.unwrap_or(Error::Verify {
            program,
            instruction,
        }))
    }

    /// Stores `i` as `instruction` of `program` and confirms it by reading it back
    /// ([`Client::confirm_stored`]): `Ok` means the
    /// robot's memory holds exactly `i` there, stored once by this call (or already there).
    ///
    /// This is the exactly-once delivery of stored instructions on a link whose check value can be
    /// fooled (the thesis's one-byte sum, docs/protocol.md §7): a corrupted twin that the sum let
    /// through is found by the read-back and overwritten, and a store whose acknowledgement was
    /// lost is found stored and not sent again. Returns the number of stores sent.
    pub fn store_verified(
        &mut self,
        program: u8,
        instruction: u16,
        i: &Instruction,
    ) -> Result<usize> {
        // A failed send may still have stored the instruction; the read-back decides. A robot
        // that took no ENQ is reported at once (docs/protocol.md §6 rule 3).
        if let Err(e) = self.store(program, instruction, i)
            && is_unanswered(&e)
        {
            return Err(e);
        }
        Ok(1 + self.ensure_stored(program, instruction, i)?)
    }

    /// Confirms `want` at `instruction` of `program`, storing it again while the confirmed
    /// read-back differs (at most [`RetryPolicy::restores`] times). Returns the stores sent (0 when
    /// it was already there).
    pub fn ensure_stored(
        &mut self,
        program: u8,
        instruction: u16,
        want: &Instruction,
    ) -> Result<usize> {
        let mut stores = 0;
        while !self.confirm_stored(program, instruction, want)? {
            if stores >= self.cfg.retry.restores as usize {
                return Err(Error::Verify {
                    program,
                    instruction,
                });
            }
            stores += 1;
            // As in `store_verified`: a failed send is settled by the next read-back.
            if let Err(e) = self.store(program, instruction, want)
                && is_unanswered(&e)
            {
                return Err(e);
            }
        }
        Ok(stores)
    }
}

/// A failure that another read-back may not repeat: the link, or a reply that passed the check
/// value but was corrupted (does not parse, or answers another request).
fn is_link_noise(e: &Error) -> bool {
    matches!(
        e,
        Error::Link(_) | Error::Parse(_) | Error::Reply { .. } | Error::UnexpectedReply(_)
    ) && !is_unanswered(e)
}

/// A session in which the robot took none of its ENQs: silent, or busy every time.
fn is_unanswered(e: &Error) -> bool {
    is_silent(e) || matches!(e, Error::Link(crate::error::LinkError::Busy { .. }))
}

/// A session in which the robot answered none of its ENQs: the robot (or its line) is silent.
/// Noise that loses all `N_ENQ` ENQs or their answers in a row is as rare as the noise rate to
/// the twelfth power; retrying it would only multiply the silence.
fn is_silent(e: &Error) -> bool {
    matches!(e, Error::Link(crate::error::LinkError::NoResponse { .. }))
}

/// The name of a request telegram in errors.
fn request_name(cmd: &Command) -> &'static str {
    match cmd {
        Command::Enquire(Selector::Status) => "ENQUIRE status",
        Command::Enquire(Selector::Position) => "ENQUIRE position",
        Command::ReadBack { .. } => "READ_BACK",
        Command::ProgramInfo { .. } => "PROGRAM_INFO",
        other => command_name(other),
    }
}

/// The name of a command (docs/protocol.md §5).
pub fn command_name(cmd: &Command) -> &'static str {
    crate::command::COMMANDS
        .iter()
        .find(|c| c.code == cmd.code())
        .map_or("?", |c| c.name)
}

/// The observable effect each command class must show in the status after it was executed once
/// (docs/protocol.md §7): `Err` names what is missing.
pub fn effect_of(cmd: &Command, s: &Status) -> std::result::Result<(), &'static str> {
    use crate::command::{Mode, State};
    let ok = match cmd {
        Command::Standby => s.mode == Mode::Standby,
        Command::Operate => s.mode == Mode::Operate,
        Command::SyncHome => s.state == State::Homing || (s.homed && s.state == State::Idle),
        Command::RunProgram { program } => match s.mode {
            Mode::Operate => {
                s.program == *program && s.state == State::Running || s.state == State::Idle
            }
            Mode::Standby => s.state == State::Idle,
        },
        Command::Stop => s.state == State::Stopped,
        Command::MoveImmediate(_) => match s.mode {
            Mode::Operate => matches!(s.state, State::Running | State::Idle),
            Mode::Standby => s.state == State::Idle,
        },
        _ => true,
    };
    if ok {
        Ok(())
    } else {
        Err(match cmd {
            Command::Standby => "mode STANDBY",
            Command::Operate => "mode OPERATE",
            Command::SyncHome => "homing or homed",
            Command::RunProgram { .. } => "the program running",
            Command::Stop => "state STOPPED",
            Command::MoveImmediate(_) => "the arm moving or at rest",
            _ => "its effect",
        })
    }
}

/// The telegram that stores `i` as `instruction` of `program`.
pub fn store_command(program: u8, instruction: u16, i: &Instruction) -> Command {
    match *i {
        Instruction::Position(positioning) => Command::StorePos {
            program,
            instruction,
            positioning,
        },
        Instruction::Control(control) => Command::StoreControl {
            program,
            instruction,
            control,
        },
    }
}

impl From<Control> for Instruction {
    fn from(c: Control) -> Self {
        Instruction::Control(c)
    }
}

impl From<Positioning> for Instruction {
    fn from(p: Positioning) -> Self {
        Instruction::Position(p)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::command::{Mode, Positioning, Selector, State};

    fn status(mode: Mode, state: State, program: u8, homed: bool) -> Status {
        Status {
            mode,
            state,
            program,
            homed,
            ..Status::default()
        }
    }

    /// Each command class's effect in the status (docs/protocol.md §7, the table's motion and mode
    /// row): the mode; homing, or homed and at rest; the program running (or already finished,
    /// at rest) in OPERATE, at rest in STANDBY; STOPPED; the arm moving or at rest. Every other
    /// command has no effect to see. A missing effect is named.
    #[test]
    fn each_command_class_is_judged_by_its_own_effect() {
        use Mode::{Operate, Standby};
        use State::{Homing, Idle, Running, Stopped};
        let ok = |c: &Command, s: Status| effect_of(c, &s).is_ok();
        let why = |c: &Command, s: Status| effect_of(c, &s).unwrap_err();

        assert!(ok(&Command::Standby, status(Standby, Idle, 0, true)));
        assert_eq!(
            why(&Command::Standby, status(Operate, Idle, 0, true)),
            "mode STANDBY"
        );
        assert!(ok(&Command::Operate, status(Operate, Idle, 0, true)));
        assert_eq!(
            why(&Command::Operate, status(Standby, Idle, 0, true)),
            "mode OPERATE"
        );

        assert!(ok(&Command::SyncHome, status(Operate, Homing, 0, false)));
        assert!(ok(&Command::SyncHome, status(Operate, Idle, 0, true)));
        assert_eq!(
            why(&Command::SyncHome, status(Operate, Idle, 0, false)),
            "homing or homed"
        );
        assert!(!ok(&Command::SyncHome, status(Operate, Stopped, 0, true)));

        let run = Command::RunProgram { program: 2 };
        assert!(ok(&run, status(Operate, Running, 2, true)));
        assert!(ok(&run, status(Operate, Idle, 3, true)), "already finished");
        assert_eq!(
            why(&run, status(Operate, Running, 3, true)),
            "the program running"
        );
        assert!(!ok(&run, status(Operate, Stopped, 2, true)));
        assert!(ok(&run, status(Standby, Idle, 2, true)));
        assert!(!ok(&run, status(Standby, Running, 2, true)));

        assert!(ok(&Command::Stop, status(Operate, Stopped, 2, true)));
        assert_eq!(
            why(&Command::Stop, status(Operate, Running, 2, true)),
            "state STOPPED"
        );

        let mv = Command::MoveImmediate(Positioning::default());
        assert!(ok(&mv, status(Operate, Running, 0, true)));
        assert!(ok(&mv, status(Operate, Idle, 0, true)));
        assert_eq!(
            why(&mv, status(Operate, Stopped, 0, true)),
            "the arm moving or at rest"
        );
        assert!(ok(&mv, status(Standby, Idle, 0, true)));
        assert!(!ok(&mv, status(Standby, Running, 0, true)));

        // No effect to see: judged by the execution count alone.
        assert!(ok(
            &Command::DeleteProgram { program: 1 },
            status(Standby, Stopped, 0, false)
        ));
    }

    /// The names errors give (docs/protocol.md §5's table; a request's selector is named).
    #[test]
    fn commands_and_requests_are_named_as_the_protocol_names_them() {
        assert_eq!(command_name(&Command::Stop), "STOP");
        assert_eq!(
            command_name(&Command::MoveImmediate(Positioning::default())),
            "MOVE_IMMEDIATE"
        );
        assert_eq!(
            command_name(&Command::DeleteProgram { program: 1 }),
            "DELETE_PROGRAM"
        );
        assert_eq!(
            request_name(&Command::Enquire(Selector::Status)),
            "ENQUIRE status"
        );
        assert_eq!(
            request_name(&Command::Enquire(Selector::Position)),
            "ENQUIRE position"
        );
        assert_eq!(
            request_name(&Command::ReadBack {
                program: 1,
                instruction: 1
            }),
            "READ_BACK"
        );
        assert_eq!(
            request_name(&Command::ProgramInfo { program: 1 }),
            "PROGRAM_INFO"
        );
        assert_eq!(request_name(&Command::Stop), "STOP");
    }
}
