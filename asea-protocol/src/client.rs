//! The blocking client: one host session per telegram over any [`Link`], with a retry policy
//! (docs/protocol.md §6).
//!
//! Within a session the [`Host`] state machine retries by itself (ENQ up to `N_ENQ`, the telegram
//! up to `N_TX`). A whole new session is started again only for requests without side effects
//! (ENQUIRE, READ_BACK): re-sending a command in a new session after an unacknowledged one could
//! execute it twice, so commands are sent once and a failure is reported to the caller.

use std::time::Duration;

use crate::clock::{Clock, RealClock};
use crate::command::{
    Command, Control, Instruction, Pose, Positioning, Reply, RobotError, Selector, Speed, Status,
};
use crate::error::{Error, Result};
use crate::frame::{Frame, FrameConfig};
use crate::link::Link;
use crate::session::{Host, Stats, Timers};

/// How often to start a request session again after a link failure, and how often to re-store
/// an instruction whose read-back differs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RetryPolicy {
    /// Sessions tried for ENQUIRE and READ_BACK (at least 1).
    pub request_sessions: u32,
    /// Re-stores of one instruction during [`Client::verify`].
    pub restores: u32,
}

impl Default for RetryPolicy {
    fn default() -> Self {
        RetryPolicy {
            request_sessions: 3,
            restores: 3,
        }
    }
}

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
}

/// The blocking robot client.
#[derive(Debug)]
pub struct Client<L, C = RealClock> {
    link: L,
    clock: C,
    host: Host,
    cfg: ClientConfig,
    buf: Vec<u8>,
}

impl<L: Link> Client<L, RealClock> {
    /// A client on `link` in real time.
    pub fn new(link: L, cfg: ClientConfig) -> Self {
        Client::with_clock(link, RealClock::new(), cfg)
    }
}

impl Client<Box<dyn serialport::SerialPort>, RealClock> {
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
        }
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
        self.link.discard_input()?;
        self.host
            .start(bytes, cmd.expects_reply(), self.clock.now());
        loop {
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
            let now = self.clock.now();
            let wait = match self.host.deadline() {
                Some(d) => d.saturating_sub(now),
                None => Duration::from_millis(50),
            };
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

    /// Sends `cmd` in one session. `Ok` means the robot acknowledged it: it is executed exactly
    /// once. An error means it was not acknowledged: it may have been executed once, never twice.
    /// Semantic errors are the robot's `last_error`, read with [`Client::check_status`].
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
                    Err(e) => last = Some(Error::Parse(e)),
                },
                Ok(None) => last = Some(Error::UnexpectedReply("no reply telegram")),
                Err(Error::Link(e)) => last = Some(Error::Link(e)),
                Err(e) => return Err(e),
            }
        }
        Err(last.unwrap_or(Error::UnexpectedReply("no reply")))
    }

    /// ENQUIRE status (reading it clears the robot's `last_error`).
    pub fn status(&mut self) -> Result<Status> {
        match self.request(&Command::Enquire(Selector::Status))? {
            Reply::Status(s) => Ok(s),
            _ => Err(Error::UnexpectedReply(
                "enquire status answered with another reply",
            )),
        }
    }

    /// ENQUIRE status and turn a nonzero `last_error` into [`Error::Robot`].
    pub fn check_status(&mut self) -> Result<Status> {
        let s = self.status()?;
        match RobotError::from_code(s.last_error) {
            None if s.last_error == 0 => Ok(s),
            None => Err(Error::Robot {
                code: s.last_error,
                message: "unknown error code",
            }),
            Some(e) => Err(Error::Robot {
                code: e.code(),
                message: e.message(),
            }),
        }
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

    /// Standby mode.
    pub fn standby(&mut self) -> Result<()> {
        self.send(&Command::Standby)
    }

    /// Operate mode.
    pub fn operate(&mut self) -> Result<()> {
        self.send(&Command::Operate)
    }

    /// Home synchronisation.
    pub fn sync_home(&mut self) -> Result<()> {
        self.send(&Command::SyncHome)
    }

    /// Runs a stored program.
    pub fn run_program(&mut self, program: u8) -> Result<()> {
        self.send(&Command::RunProgram { program })
    }

    /// Stops motion.
    pub fn stop(&mut self) -> Result<()> {
        self.send(&Command::Stop)
    }

    /// Deletes a program.
    pub fn delete_program(&mut self, program: u8) -> Result<()> {
        self.send(&Command::DeleteProgram { program })
    }

    /// A discrete-mode move, executed at once.
    pub fn move_immediate(&mut self, p: Positioning) -> Result<()> {
        self.send(&Command::MoveImmediate(p))
    }

    /// Base speed, m/s.
    pub fn set_base_speed(&mut self, speed: Speed) -> Result<()> {
        self.send(&Command::SetBaseSpeed(speed))
    }

    /// Maximum speed, m/s.
    pub fn set_max_speed(&mut self, speed: Speed) -> Result<()> {
        self.send(&Command::SetMaxSpeed(speed))
    }

    /// Stores one instruction (positioning or control) as `instruction` of `program`.
    pub fn store(&mut self, program: u8, instruction: u16, i: &Instruction) -> Result<()> {
        self.send(&store_command(program, instruction, i))
    }

    /// Stores `instructions` as instructions 1, 2, … of `program`, then checks `last_error`.
    pub fn upload(&mut self, program: u8, instructions: &[Instruction]) -> Result<()> {
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
        let mut report = VerifyReport::default();
        for (n, i) in (1u16..).zip(instructions) {
            report.restored += match self.store_verified(program, n, i) {
                Ok(stores) => stores - 1,
                // The store's fate is unknown: settle it by reading back, never by a blind store.
                Err(_) => self.settle(program, n, i)?,
            };
        }
        for (n, i) in (1u16..).zip(instructions) {
            report.checked += 1;
            report.restored += self.settle(program, n, i)?;
        }
        // Every instruction is confirmed, so a `last_error` now can only come from a corrupted
        // twin the robot refused; read it to clear it.
        let _ = self.status();
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
        if matches!(last, Some(Error::Verify { .. }))
            && let Err(robot @ Error::Robot { .. }) = self.check_status()
        {
            return Err(robot);
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
        // A failed send may still have stored the instruction; the read-back decides.
        let _ = self.store(program, instruction, i);
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
            let _ = self.store(program, instruction, want);
        }
        Ok(stores)
    }
}

/// A failure that another read-back may not repeat: the link, or a reply that passed the check
/// value but was corrupted (does not parse, or answers another request).
fn is_link_noise(e: &Error) -> bool {
    matches!(
        e,
        Error::Link(_) | Error::Parse(_) | Error::UnexpectedReply(_)
    )
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
