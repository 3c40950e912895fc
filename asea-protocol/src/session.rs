//! The session state machines, without I/O: bytes and the time come in, bytes and a deadline come
//! out (docs/protocol.md §6; seed 001 §5.2's four phases: establish, transfer, verify,
//! terminate).
//!
//! ```text
//! host: ENQ            robot: ACK | NAK (busy) | silence
//! host: STX…ETX CS     robot: ACK | NAK
//! host: EOT
//! ```
//!
//! ENQUIRE and READ_BACK are answered in a reverse session with the roles swapped. Time is a
//! [`Duration`] since any epoch the caller likes; the caller feeds received bytes with
//! `on_bytes`, calls `on_time` when [`Host::deadline`] passes, and sends what `take_output`
//! returns.
//!
//! **Exactly once** (spec §5.5): inside one session, a telegram byte-identical to the one already
//! acknowledged is a retransmission after a lost ACK: the robot acknowledges it again and does not
//! deliver it. A different telegram in the same session is refused with NAK. EOT, a new ENQ or
//! `T_IDLE` of silence ends the session.

use std::time::Duration;

use crate::decoder::{Decoder, Token};
use crate::frame::{ACK, ENQ, EOT, Frame, FrameConfig, NAK};

/// Wait for an answer to ENQ (3964R acknowledgement delay).
pub const T_ENQ: Duration = Duration::from_millis(2000);
/// ENQ attempts before `NoResponse` (3964R, ASTM: 6).
pub const N_ENQ: u32 = 6;
/// Pause after NAK to ENQ before asking again.
pub const T_BUSY: Duration = Duration::from_millis(500);
/// Longest gap between two bytes of one telegram (3964R character delay).
pub const T_CHAR: Duration = Duration::from_millis(220);
/// Wait for ACK or NAK after the check value.
pub const T_ACK: Duration = Duration::from_millis(2000);
/// Transmissions of one telegram before `Retries` (ASTM, 3964R: 6).
pub const N_TX: u32 = 6;
/// Wait for the robot's ENQ after the EOT that closed an ENQUIRE or READ_BACK session.
pub const T_REPLY: Duration = Duration::from_millis(3000);
/// A session with no bytes for this long returns to neutral (ISO 1745 timer D).
pub const T_IDLE: Duration = Duration::from_millis(10_000);
/// Minimum gap between the end of one session and the next ENQ.
pub const T_GAP: Duration = Duration::from_millis(20);
/// How much more silence than the robot's `T_GAP`/2 (docs/protocol.md §6 rule 7) an urgent
/// session (STOP, [`Host::start_urgent`]) keeps after the host's last byte: it covers the time
/// between a byte's end on the line, when the host counts its silence from, and the moment the
/// robot notes the byte (its receive latency: a receive interrupt per character takes well under
/// a millisecond; a FIFO UART that reports a lone byte after a receive timeout of 4 character
/// times needs 4.2 ms at 9600 baud, and a larger margin). A robot that noted the byte later and
/// took the ENQ for data answers the urgent ENQ's repeat one urgent gap later.
pub const URGENT_MARGIN: Duration = Duration::from_millis(2);
/// After a bad frame the receiver waits for this much line silence before its NAK, so that the
/// rest of the bad frame is not mistaken for the retransmission.
pub const T_FLUSH: Duration = Duration::from_millis(20);

/// How many NAK bytes the robot sends to refuse a telegram. One corrupted NAK can read as ACK
/// (they differ in three bits); the host watches for a NAK during `T_GAP` after an ACK and then
/// reports the telegram as not delivered. A host that reads a single byte sees the first NAK and
/// ignores the second as a stray byte.
pub const NAK_REPEAT: usize = 2;

/// The timers and retry counts of a link (defaults: the constants above).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Timers {
    /// [`T_ENQ`].
    pub t_enq: Duration,
    /// [`N_ENQ`].
    pub n_enq: u32,
    /// [`T_BUSY`].
    pub t_busy: Duration,
    /// [`T_CHAR`].
    pub t_char: Duration,
    /// [`T_ACK`].
    pub t_ack: Duration,
    /// [`N_TX`].
    pub n_tx: u32,
    /// [`T_REPLY`].
    pub t_reply: Duration,
    /// [`T_IDLE`].
    pub t_idle: Duration,
    /// [`T_GAP`].
    pub t_gap: Duration,
    /// [`T_FLUSH`].
    pub t_flush: Duration,
    /// [`URGENT_MARGIN`].
    pub urgent_margin: Duration,
    /// If set, the host takes an ACK to its telegram only within this time after the telegram
    /// has left the line; a later "ACK" is treated as NAK (retransmit, which the robot
    /// re-acknowledges without executing again). A robot answers a good telegram at once and a
    /// bad one only after `T_FLUSH` of silence, so a NAK corrupted into ACK arrives too late to
    /// count. Must exceed the robot's turnaround; off by default because a real controller's
    /// turnaround is unknown.
    pub t_ack_window: Option<Duration>,
}

impl Default for Timers {
    fn default() -> Self {
        Timers {
            t_enq: T_ENQ,
            n_enq: N_ENQ,
            t_busy: T_BUSY,
            t_char: T_CHAR,
            t_ack: T_ACK,
            n_tx: N_TX,
            t_reply: T_REPLY,
            t_idle: T_IDLE,
            t_gap: T_GAP,
            t_flush: T_FLUSH,
            urgent_margin: URGENT_MARGIN,
            t_ack_window: None,
        }
    }
}

impl Timers {
    /// The silence an urgent session (STOP) keeps after the host's last byte before its ENQ:
    /// the `T_GAP`/2 the robot needs (docs/protocol.md §6 rule 7) and
    /// [`Timers::urgent_margin`].
    pub fn urgent_gap(&self) -> Duration {
        self.t_gap / 2 + self.urgent_margin
    }
}

/// Counters of one side of a link.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Stats {
    /// ENQ sent.
    pub enq_sent: u64,
    /// Telegrams sent, first transmissions and retransmissions.
    pub frames_sent: u64,
    /// NAK received.
    pub nak_received: u64,
    /// NAK sent.
    pub nak_sent: u64,
    /// Timer expiries that led to a repeat.
    pub timeouts: u64,
    /// Identical retransmissions acknowledged and not delivered again (robot).
    pub duplicates: u64,
    /// Bad frames received.
    pub bad_frames: u64,
}

use crate::error::LinkError;

/// The outcome of one host session: the reply telegram, if the command has one.
pub type Outcome = Result<Option<Frame>, LinkError>;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum HostState {
    Idle,
    Gap,
    WaitEnqAck,
    Backoff,
    WaitFrameAck,
    Confirm,
    WaitReplyEnq,
    ReceiveReply,
    WaitReplyEot,
}

/// Receive-side helpers shared by both ends: the decoder, the `T_CHAR` gap, the flush before NAK.
#[derive(Debug, Clone)]
struct Rx {
    decoder: Decoder,
    last_rx: Duration,
    /// Nothing received yet.
    fresh: bool,
    flush_until: Option<Duration>,
}

impl Rx {
    fn new(cfg: FrameConfig) -> Self {
        Rx {
            decoder: Decoder::new(cfg),
            last_rx: Duration::ZERO,
            fresh: true,
            flush_until: None,
        }
    }
    /// Takes bytes; while flushing they are dropped and the flush extended.
    fn push(&mut self, bytes: &[u8], now: Duration, t_flush: Duration) {
        if bytes.is_empty() {
            return;
        }
        self.last_rx = now;
        self.fresh = false;
        if self.flush_until.is_some() {
            self.flush_until = Some(now + t_flush);
        } else {
            self.decoder.push(bytes);
        }
    }
    /// True if nothing arrived for `gap` before `now`.
    fn quiet(&self, now: Duration, gap: Duration) -> bool {
        self.fresh || now.saturating_sub(self.last_rx) >= gap
    }
    fn start_flush(&mut self, now: Duration, t_flush: Duration) {
        self.decoder.clear();
        self.flush_until = Some(now + t_flush);
    }
    fn char_deadline(&self, t_char: Duration) -> Option<Duration> {
        self.decoder.in_frame().then_some(self.last_rx + t_char)
    }
    /// Earliest receive-side deadline.
    fn deadline(&self, t_char: Duration) -> Option<Duration> {
        match (self.flush_until, self.char_deadline(t_char)) {
            (Some(a), _) => Some(a),
            (None, b) => b,
        }
    }
    /// True (once) when a flush or `T_CHAR` has expired at `now`: the caller answers NAK.
    fn expired(&mut self, now: Duration, t_char: Duration) -> bool {
        if let Some(t) = self.flush_until {
            if now >= t {
                self.flush_until = None;
                return true;
            }
            return false;
        }
        if self.char_deadline(t_char).is_some_and(|t| now >= t) {
            self.decoder.clear();
            return true;
        }
        false
    }
}

/// The host (PC) side: one session per telegram.
#[derive(Debug, Clone)]
pub struct Host {
    timers: Timers,
    rx: Rx,
    state: HostState,
    deadline: Option<Duration>,
    out: Vec<u8>,
    frame: Vec<u8>,
    expects_reply: bool,
    enq_attempts: u32,
    nak_to_enq: bool,
    tx: u32,
    /// Nothing but silence since the telegram went out.
    clean: bool,
    reply: Option<Frame>,
    outcome: Option<Outcome>,
    ready_at: Duration,
    line_free: Duration,
    /// The session was started by [`Host::start_urgent`].
    urgent: bool,
    stats: Stats,
}

impl Host {
    /// A host with framing `cfg` and `timers`.
    pub fn new(cfg: FrameConfig, timers: Timers) -> Self {
        Host {
            timers,
            rx: Rx::new(cfg),
            state: HostState::Idle,
            deadline: None,
            out: Vec::new(),
            frame: Vec::new(),
            expects_reply: false,
            enq_attempts: 0,
            nak_to_enq: false,
            tx: 0,
            clean: true,
            reply: None,
            outcome: None,
            ready_at: Duration::ZERO,
            line_free: Duration::ZERO,
            urgent: false,
            stats: Stats::default(),
        }
    }

    /// Counters since creation.
    pub fn stats(&self) -> Stats {
        self.stats
    }

    /// True while a session is under way.
    pub fn is_active(&self) -> bool {
        self.state != HostState::Idle
    }

    /// Starts a session for the framed telegram `frame`; `expects_reply` waits for a reverse
    /// session after EOT. The ENQ goes out at once, or when `T_GAP` after the last session ends.
    pub fn start(&mut self, frame: Vec<u8>, expects_reply: bool, now: Duration) {
        self.urgent = false;
        self.begin(frame, expects_reply, now);
    }

    fn begin(&mut self, frame: Vec<u8>, expects_reply: bool, now: Duration) {
        self.frame = frame;
        self.expects_reply = expects_reply;
        self.enq_attempts = 0;
        self.nak_to_enq = false;
        self.tx = 0;
        self.reply = None;
        self.outcome = None;
        self.rx.decoder.clear();
        self.rx.flush_until = None;
        if now < self.ready_at {
            self.state = HostState::Gap;
            self.deadline = Some(self.ready_at);
        } else {
            self.send_enq(now);
        }
    }

    /// Starts a session like [`Host::start`] for a command that cannot wait (STOP): its ENQ
    /// keeps the urgent gap ([`Timers::urgent_gap`]) of silence after the host's last byte, which is
    /// more than the `T_GAP`/2 the robot needs before it takes an ENQ (docs/protocol.md §6,
    /// rule 7), instead of the whole `T_GAP`. If that ENQ is not answered within another
    /// urgent gap (a robot that noted the host's last byte late and took the ENQ for data),
    /// the ENQ is repeated then, once, rather than after `T_ENQ`; the repeat counts toward
    /// `N_ENQ`, and later ones wait `T_ENQ` as usual.
    pub fn start_urgent(&mut self, frame: Vec<u8>, expects_reply: bool, now: Duration) {
        let urgent = self.line_free + self.timers.urgent_gap();
        self.ready_at = self.ready_at.min(urgent);
        self.urgent = true;
        self.begin(frame, expects_reply, now);
    }

    /// Bytes to send now.
    pub fn take_output(&mut self) -> Vec<u8> {
        std::mem::take(&mut self.out)
    }

    /// Abandons the session under way at `now` (a cancelled exchange); what is still to be sent
    /// is dropped, but for the EOT that ends the host's session. While the host's own session is
    /// open on the line (its ENQ out, its EOT not), an EOT ends it (ISO 1745: the master's EOT at
    /// any time but the end of a message is an abort), so that the robot returns to neutral; the
    /// gap then runs from that EOT. Otherwise nothing more is sent: a session still in its gap,
    /// or whose first ENQ has not left, has sent nothing; one that has sent its EOT (watching
    /// for a late NAK, or in the robot's reply session) is over on the host's side, the robot's
    /// reply session yields to the host's next ENQ (docs/protocol.md §6 rule 8), and the gap
    /// runs from the host's last byte.
    pub fn abort(&mut self, now: Duration) {
        let end_pending = self.out == [EOT];
        let nothing_on_line = self.enq_unsent();
        self.out.clear();
        match self.state {
            HostState::WaitEnqAck if nothing_on_line => {}
            HostState::WaitEnqAck | HostState::Backoff | HostState::WaitFrameAck => {
                self.out.push(EOT);
                self.ready_at = now + self.timers.t_gap;
            }
            HostState::Idle
            | HostState::Gap
            | HostState::Confirm
            | HostState::WaitReplyEnq
            | HostState::ReceiveReply
            | HostState::WaitReplyEot => {
                if end_pending {
                    self.out.push(EOT);
                }
                self.ready_at = self.ready_at.max(self.line_free + self.timers.t_gap);
            }
        }
        self.state = HostState::Idle;
        self.deadline = None;
        self.outcome = None;
    }

    /// The session's first ENQ is queued and has not been taken for the line.
    fn enq_unsent(&self) -> bool {
        self.state == HostState::WaitEnqAck && self.enq_attempts == 1 && self.out == [ENQ]
    }

    /// The first transmission of the telegram is queued and has not been taken for the line.
    fn frame_unsent(&self) -> bool {
        self.state == HostState::WaitFrameAck && self.tx == 1 && self.out == self.frame
    }

    /// True while the robot has seen no telegram of this session: its ENQ awaits an answer, or
    /// the robot has acknowledged it and the telegram has not been taken for the line. Another
    /// telegram can then take the session's place ([`Host::take_over`]).
    pub fn can_take_over(&self) -> bool {
        self.state == HostState::WaitEnqAck || self.frame_unsent()
    }

    /// Puts `frame` in place of the telegram of a session the robot has seen no telegram of
    /// ([`Host::can_take_over`]): it goes out once the robot acknowledges the ENQ (at once if it
    /// has), and it is the session's one telegram (the exactly-once rule, spec §5.5, holds).
    /// Returns false, changing nothing, in any other state.
    pub fn take_over(&mut self, frame: Vec<u8>, expects_reply: bool, now: Duration) -> bool {
        if !self.can_take_over() {
            return false;
        }
        let acknowledged = self.frame_unsent();
        self.frame = frame;
        self.expects_reply = expects_reply;
        self.tx = 0;
        self.reply = None;
        self.outcome = None;
        if acknowledged {
            self.out.clear();
            self.stats.frames_sent = self.stats.frames_sent.saturating_sub(1);
            self.send_frame(now);
        }
        true
    }

    /// Tells the host that what [`Host::take_output`] returned has left the line at `now`, so
    /// that `T_GAP` is counted from the end of the EOT.
    pub fn on_sent(&mut self, now: Duration) {
        self.line_free = now;
        if self.state == HostState::Idle {
            self.ready_at = self.ready_at.max(now + self.timers.t_gap);
        }
    }

    /// The session's result, once it has one.
    pub fn take_outcome(&mut self) -> Option<Outcome> {
        self.outcome.take()
    }

    /// When [`Host::on_time`] must be called next.
    pub fn deadline(&self) -> Option<Duration> {
        let rx = match self.state {
            HostState::ReceiveReply | HostState::WaitReplyEot => {
                self.rx.deadline(self.timers.t_char)
            }
            _ => None,
        };
        match (self.deadline, rx) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }

    fn send_enq(&mut self, now: Duration) {
        self.enq_attempts += 1;
        self.stats.enq_sent += 1;
        self.out.push(ENQ);
        self.state = HostState::WaitEnqAck;
        let wait = if self.urgent && self.enq_attempts == 1 {
            self.timers.urgent_gap()
        } else {
            self.timers.t_enq
        };
        self.deadline = Some(now + wait);
    }

    fn send_frame(&mut self, now: Duration) {
        self.tx += 1;
        self.stats.frames_sent += 1;
        self.out.extend_from_slice(&self.frame);
        self.clean = true;
        self.state = HostState::WaitFrameAck;
        self.deadline = Some(now + self.timers.t_ack);
    }

    fn finish(&mut self, outcome: Outcome, now: Duration) {
        self.outcome = Some(outcome);
        self.state = HostState::Idle;
        self.deadline = None;
        self.ready_at = now + self.timers.t_gap;
    }

    fn fail(&mut self, e: LinkError, now: Duration) {
        self.out.push(EOT);
        self.finish(Err(e), now);
    }

    fn retransmit_or_fail(&mut self, now: Duration) {
        if self.tx >= self.timers.n_tx {
            self.fail(LinkError::Retries { attempts: self.tx }, now);
        } else {
            self.send_frame(now);
        }
    }

    fn uses_decoder(&self) -> bool {
        matches!(
            self.state,
            HostState::ReceiveReply | HostState::WaitReplyEot
        )
    }

    /// Takes received bytes. While waiting for a single control byte, bytes are read one by one
    /// (noise that looks like STX cannot swallow an ACK); frames are decoded only where a reply
    /// telegram is expected.
    pub fn on_bytes(&mut self, bytes: &[u8], now: Duration) {
        for (i, &b) in bytes.iter().enumerate() {
            match self.state {
                HostState::Idle | HostState::Gap | HostState::Backoff => return,
                _ if self.uses_decoder() => {
                    self.rx
                        .push(bytes.get(i..).unwrap_or_default(), now, self.timers.t_flush);
                    while self.uses_decoder() {
                        let Some(token) = self.rx.decoder.next_token() else {
                            return;
                        };
                        self.on_token(token, now);
                    }
                    self.rx.decoder.clear();
                    return;
                }
                HostState::WaitFrameAck
                    if b == ACK
                        && (!self.clean
                            || self
                                .timers
                                .t_ack_window
                                .is_some_and(|w| now > self.line_free + w)) =>
                {
                    // An ACK behind noise may be a corrupted NAK: ask again (a retransmission is
                    // re-acknowledged, never executed twice).
                    self.rx.last_rx = now;
                    self.on_token(Token::Control(NAK), now);
                }
                _ => {
                    self.rx.last_rx = now;
                    if self.state == HostState::WaitFrameAck && b != NAK {
                        self.clean = false;
                    }
                    if matches!(b, ENQ | ACK | NAK | EOT) {
                        self.on_token(Token::Control(b), now);
                    }
                }
            }
        }
    }

    fn on_token(&mut self, token: Token, now: Duration) {
        use HostState as S;
        match (self.state, token) {
            (S::WaitEnqAck, Token::Control(ACK)) => self.send_frame(now),
            (S::WaitEnqAck, Token::Control(NAK)) => {
                self.stats.nak_received += 1;
                self.nak_to_enq = true;
                if self.enq_attempts >= self.timers.n_enq {
                    self.fail(
                        LinkError::Busy {
                            attempts: self.enq_attempts,
                        },
                        now,
                    );
                } else {
                    self.state = S::Backoff;
                    self.deadline = Some(now + self.timers.t_busy);
                }
            }
            (S::WaitFrameAck, Token::Control(ACK)) => {
                self.out.push(EOT);
                if self.expects_reply {
                    self.state = S::WaitReplyEnq;
                    self.deadline = Some(now + self.timers.t_reply);
                } else {
                    // Watch the line through T_GAP: a NAK now means the "ACK" was a corrupted
                    // NAK and the robot did not take the telegram.
                    self.state = S::Confirm;
                    self.deadline = Some(now + self.timers.t_gap);
                }
            }
            (S::Confirm | S::WaitReplyEnq, Token::Control(NAK)) => {
                self.stats.nak_received += 1;
                self.deadline = None;
                self.finish(Err(LinkError::Retries { attempts: self.tx }), now);
            }
            (S::WaitFrameAck, Token::Control(NAK)) => {
                self.stats.nak_received += 1;
                self.retransmit_or_fail(now);
            }
            (S::WaitFrameAck, Token::Control(EOT)) => self.finish(Err(LinkError::Interrupted), now),
            (S::WaitReplyEnq | S::ReceiveReply, Token::Control(ENQ)) => {
                // The robot opens (or, having lost our ACK, re-opens) its reply session. Wait
                // long enough for its repeated ENQ if this ACK is lost.
                self.out.push(ACK);
                self.state = S::ReceiveReply;
                self.deadline = Some(now + self.timers.t_enq + self.timers.t_flush);
            }
            (S::ReceiveReply, Token::Frame(f)) => {
                self.out.push(ACK);
                self.reply = Some(f);
                self.state = S::WaitReplyEot;
                self.deadline = Some(now + self.timers.t_ack + self.timers.t_flush);
            }
            (S::WaitReplyEot, Token::Frame(f)) => {
                // Our ACK was lost: the robot repeats; the same reply is acknowledged again.
                if self.reply.as_ref() == Some(&f) {
                    self.stats.duplicates += 1;
                    self.out.push(ACK);
                } else {
                    self.out.push(NAK);
                    self.stats.nak_sent += 1;
                }
            }
            (S::ReceiveReply | S::WaitReplyEot, Token::Bad(_)) => {
                self.stats.bad_frames += 1;
                self.rx.start_flush(now, self.timers.t_flush);
            }
            (S::ReceiveReply, Token::Control(EOT)) => self.finish(Err(LinkError::Interrupted), now),
            (S::WaitReplyEot, Token::Control(EOT)) => {
                let reply = self.reply.take();
                self.finish(Ok(reply), now);
            }
            // Noise, stray bytes and the robot's ENQ while we hold the line (host wins).
            _ => {}
        }
    }

    /// Lets time run to `now`: expired timers act.
    pub fn on_time(&mut self, now: Duration) {
        use HostState as S;
        if matches!(self.state, S::ReceiveReply | S::WaitReplyEot)
            && self.rx.expired(now, self.timers.t_char)
        {
            self.stats.nak_sent += 1;
            self.out.push(NAK);
            self.deadline = Some(now + self.timers.t_ack);
            return;
        }
        if self.deadline.is_none_or(|d| now < d) {
            return;
        }
        match self.state {
            S::Idle => self.deadline = None,
            S::Gap | S::Backoff => self.send_enq(now),
            S::WaitEnqAck => {
                self.stats.timeouts += 1;
                if self.enq_attempts >= self.timers.n_enq {
                    let attempts = self.enq_attempts;
                    let e = if self.nak_to_enq {
                        LinkError::Busy { attempts }
                    } else {
                        LinkError::NoResponse { attempts }
                    };
                    self.fail(e, now);
                } else {
                    self.send_enq(now);
                }
            }
            S::WaitFrameAck => {
                self.stats.timeouts += 1;
                self.retransmit_or_fail(now);
            }
            S::Confirm => {
                // The gap before the next session has been served here.
                self.finish(Ok(None), now);
                self.ready_at = now.max(self.line_free + self.timers.t_gap);
            }
            S::WaitReplyEnq | S::ReceiveReply => self.finish(Err(LinkError::NoReply), now),
            S::WaitReplyEot => {
                // The robot's EOT was lost; the reply was good and acknowledged.
                let reply = self.reply.take();
                self.finish(Ok(reply), now);
            }
        }
    }
}

#[derive(Debug, Clone, PartialEq, Eq)]
enum RobotState {
    Idle,
    InSession { last: Option<Frame> },
    ReplyWaitEnqAck,
    ReplyBackoff,
    ReplyWaitAck,
}

/// The robot-computer side: acknowledges telegrams, delivers each once, sends replies.
#[derive(Debug, Clone)]
pub struct RobotSession {
    timers: Timers,
    rx: Rx,
    state: RobotState,
    deadline: Option<Duration>,
    out: Vec<u8>,
    pending_reply: Option<Vec<u8>>,
    enq_attempts: u32,
    tx: u32,
    /// When true the robot answers ENQ with NAK (busy).
    pub busy: bool,
    /// A check a framed telegram must pass to be acknowledged; a telegram that fails it is
    /// treated as a transmission error (NAK). `None` acknowledges every well-framed telegram.
    pub validate: Option<fn(&Frame) -> bool>,
    stats: Stats,
}

impl RobotSession {
    /// A robot side with framing `cfg` and `timers`.
    pub fn new(cfg: FrameConfig, timers: Timers) -> Self {
        RobotSession {
            timers,
            rx: Rx::new(cfg),
            state: RobotState::Idle,
            deadline: None,
            out: Vec::new(),
            pending_reply: None,
            enq_attempts: 0,
            tx: 0,
            busy: false,
            validate: None,
            stats: Stats::default(),
        }
    }

    /// Counters since creation.
    pub fn stats(&self) -> Stats {
        self.stats
    }

    /// True from the ENQ that opens a session (either way) to the EOT or timeout that ends it:
    /// the time the robot computer spends on the link.
    pub fn in_session(&self) -> bool {
        self.state != RobotState::Idle
    }

    /// Bytes to send now.
    pub fn take_output(&mut self) -> Vec<u8> {
        std::mem::take(&mut self.out)
    }

    /// The framed reply to send in a reverse session once the host's EOT ends this session.
    pub fn queue_reply(&mut self, frame: Vec<u8>) {
        self.pending_reply = Some(frame);
    }

    /// When [`RobotSession::on_time`] must be called next.
    pub fn deadline(&self) -> Option<Duration> {
        let rx = match self.state {
            RobotState::InSession { .. } => self.rx.deadline(self.timers.t_char),
            _ => None,
        };
        match (self.deadline, rx) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }

    fn open_session(&mut self, now: Duration) {
        if self.busy {
            self.out.push(NAK);
            self.stats.nak_sent += 1;
            self.state = RobotState::Idle;
            self.deadline = None;
        } else {
            self.out.push(ACK);
            self.pending_reply = None;
            self.state = RobotState::InSession { last: None };
            self.deadline = Some(now + self.timers.t_idle);
        }
    }

    fn close_session(&mut self, now: Duration) {
        self.rx.decoder.clear();
        self.rx.flush_until = None;
        if self.pending_reply.is_some() {
            self.enq_attempts = 0;
            self.send_enq(now);
        } else {
            self.state = RobotState::Idle;
            self.deadline = None;
        }
    }

    fn send_enq(&mut self, now: Duration) {
        self.enq_attempts += 1;
        self.stats.enq_sent += 1;
        self.out.push(ENQ);
        self.state = RobotState::ReplyWaitEnqAck;
        self.deadline = Some(now + self.timers.t_enq);
    }

    fn send_reply(&mut self, now: Duration) {
        self.tx += 1;
        self.stats.frames_sent += 1;
        if let Some(f) = &self.pending_reply {
            self.out.extend_from_slice(f);
        }
        self.state = RobotState::ReplyWaitAck;
        self.deadline = Some(now + self.timers.t_ack);
    }

    fn give_up_reply(&mut self) {
        self.pending_reply = None;
        self.state = RobotState::Idle;
        self.deadline = None;
    }

    /// Takes received bytes; returns the telegrams to execute (each delivered exactly once).
    /// Outside a session bytes are read one by one for ENQ, ACK, NAK and EOT; inside one the
    /// decoder frames telegrams.
    pub fn on_bytes(&mut self, bytes: &[u8], now: Duration) -> Vec<Frame> {
        let mut delivered = Vec::new();
        for (i, &b) in bytes.iter().enumerate() {
            if let RobotState::InSession { .. } = self.state {
                self.deadline = Some(now + self.timers.t_idle);
                // Inside a session the host repeats ENQ only after T_ENQ of waiting; a 0x05
                // after a shorter pause is telegram data whose STX was lost (or a stalled check
                // byte), and must not be acknowledged as an ENQ. A host that lost our ACK to its
                // ENQ, or whose EOT was lost, is answered at its next ENQ.
                let mut quiet =
                    self.rx.quiet(now, self.timers.t_enq / 2) && self.rx.decoder.pending() == 0;
                self.rx
                    .push(bytes.get(i..).unwrap_or_default(), now, self.timers.t_flush);
                while let RobotState::InSession { .. } = self.state {
                    let Some(token) = self.rx.decoder.next_token() else {
                        return delivered;
                    };
                    if token == Token::Control(ENQ) && !quiet {
                        continue;
                    }
                    quiet = false;
                    if let Some(f) = self.on_token(token, now) {
                        delivered.push(f);
                    }
                }
                // The session closed (its EOT ends the host's transmission).
                self.rx.decoder.clear();
                return delivered;
            }
            // Outside a session the host's ENQ follows at least T_GAP of silence; a 0x05
            // straight behind other bytes is data of a telegram the robot is not waiting for.
            let quiet = self.rx.quiet(now, self.timers.t_gap / 2);
            self.rx.last_rx = now;
            self.rx.fresh = false;
            match b {
                ENQ if !quiet => {}
                ENQ | ACK | NAK | EOT => {
                    self.on_token(Token::Control(b), now);
                }
                _ => {}
            }
        }
        delivered
    }

    fn on_token(&mut self, token: Token, now: Duration) -> Option<Frame> {
        use RobotState as S;
        match (&mut self.state, token) {
            // A new ENQ opens a session; from any state the host wins.
            (_, Token::Control(ENQ)) => self.open_session(now),
            (S::InSession { last }, Token::Frame(f))
                if last.as_ref() != Some(&f) && self.validate.is_some_and(|ok| !ok(&f)) =>
            {
                self.stats.bad_frames += 1;
                self.rx.start_flush(now, self.timers.t_flush);
            }
            (S::InSession { last }, Token::Frame(f)) => match last {
                Some(prev) if *prev == f => {
                    self.stats.duplicates += 1;
                    self.out.push(ACK);
                }
                Some(_) => {
                    // One telegram per session (spec §5.5): a different one is refused.
                    self.stats.nak_sent += 1;
                    self.out.extend_from_slice(&[NAK; NAK_REPEAT]);
                }
                None => {
                    *last = Some(f.clone());
                    self.out.push(ACK);
                    return Some(f);
                }
            },
            (S::InSession { .. }, Token::Bad(_)) => {
                self.stats.bad_frames += 1;
                self.rx.start_flush(now, self.timers.t_flush);
            }
            (S::InSession { .. }, Token::Control(EOT)) => self.close_session(now),
            (S::ReplyWaitEnqAck, Token::Control(ACK)) => {
                self.tx = 0;
                self.send_reply(now);
            }
            (S::ReplyWaitEnqAck, Token::Control(NAK)) => {
                self.stats.nak_received += 1;
                if self.enq_attempts >= self.timers.n_enq {
                    self.give_up_reply();
                } else {
                    self.state = S::ReplyBackoff;
                    self.deadline = Some(now + self.timers.t_busy);
                }
            }
            (S::ReplyWaitAck, Token::Control(ACK)) => {
                self.out.push(EOT);
                self.give_up_reply();
            }
            (S::ReplyWaitAck, Token::Control(NAK)) => {
                self.stats.nak_received += 1;
                if self.tx >= self.timers.n_tx {
                    self.out.push(EOT);
                    self.give_up_reply();
                } else {
                    self.send_reply(now);
                }
            }
            (S::ReplyWaitEnqAck | S::ReplyWaitAck, Token::Control(EOT)) => self.give_up_reply(),
            _ => {}
        }
        None
    }

    /// Lets time run to `now`: expired timers act.
    pub fn on_time(&mut self, now: Duration) {
        use RobotState as S;
        if matches!(self.state, S::InSession { .. }) && self.rx.expired(now, self.timers.t_char) {
            self.stats.nak_sent += 1;
            self.out.extend_from_slice(&[NAK; NAK_REPEAT]);
            return;
        }
        if self.deadline.is_none_or(|d| now < d) {
            return;
        }
        match self.state {
            S::Idle => self.deadline = None,
            S::InSession { .. } => {
                // T_IDLE: the host went away; back to neutral.
                self.rx.decoder.clear();
                self.pending_reply = None;
                self.state = S::Idle;
                self.deadline = None;
            }
            S::ReplyWaitEnqAck => {
                self.stats.timeouts += 1;
                if self.enq_attempts >= self.timers.n_enq {
                    self.give_up_reply();
                } else {
                    self.send_enq(now);
                }
            }
            S::ReplyBackoff => self.send_enq(now),
            S::ReplyWaitAck => {
                self.stats.timeouts += 1;
                if self.tx >= self.timers.n_tx {
                    self.out.push(EOT);
                    self.give_up_reply();
                } else {
                    self.send_reply(now);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::{STX, encode};

    fn ms(n: u64) -> Duration {
        Duration::from_millis(n)
    }

    fn cfg() -> FrameConfig {
        FrameConfig::default()
    }

    /// RUN_PROGRAM 3 (spec §5.3 golden vector).
    const RUN3: [u8; 6] = [0x02, 0x02, 0x01, 0x03, 0x03, 0x09];

    fn host() -> Host {
        Host::new(cfg(), Timers::default())
    }

    #[test]
    fn happy_path_bytes() {
        let mut h = host();
        assert!(!h.is_active());
        h.start(RUN3.to_vec(), false, ms(0));
        assert_eq!(h.take_output(), [ENQ]);
        assert!(h.is_active());
        assert_eq!(h.deadline(), Some(T_ENQ));
        h.on_bytes(&[ACK], ms(5));
        assert_eq!(h.take_output(), RUN3);
        assert_eq!(h.deadline(), Some(ms(5) + T_ACK));
        h.on_bytes(&[ACK], ms(20));
        assert_eq!(h.take_output(), [EOT]);
        // The EOT has left the line one millisecond later.
        h.on_sent(ms(21));
        // Confirmed once T_GAP has passed without a NAK; the next ENQ follows T_GAP after the
        // end of the EOT.
        assert_eq!(h.take_outcome(), None);
        assert_eq!(h.deadline(), Some(ms(20) + T_GAP));
        h.on_time(ms(20) + T_GAP);
        assert_eq!(h.take_outcome(), Some(Ok(None)));
        assert!(!h.is_active());
        h.start(RUN3.to_vec(), false, ms(20) + T_GAP);
        assert!(h.take_output().is_empty());
        assert_eq!(h.deadline(), Some(ms(21) + T_GAP));
        h.on_time(ms(21) + T_GAP);
        assert_eq!(h.take_output(), [ENQ]);
    }

    /// Every counter of the host's [`Stats`] follows the bytes: a NAK to the ENQ (backoff, ENQ
    /// again), an ENQ unanswered (timeout, ENQ again), the telegram refused once (NAK) and once
    /// unacknowledged (timeout), then taken: 3 ENQs, 3 telegrams, 2 NAKs received, 2 timeouts.
    #[test]
    fn host_counts_every_event_of_a_session() {
        let t = Timers::default();
        let mut h = host();
        h.start(RUN3.to_vec(), false, ms(0));
        assert_eq!(h.take_output(), [ENQ]);
        h.on_bytes(&[NAK], ms(5));
        assert_eq!(h.deadline(), Some(ms(5) + t.t_busy));
        let t1 = ms(5) + t.t_busy;
        h.on_time(t1);
        assert_eq!(h.take_output(), [ENQ]);
        h.on_time(t1 + t.t_enq);
        assert_eq!(h.take_output(), [ENQ]);
        let t2 = t1 + t.t_enq;
        h.on_bytes(&[ACK], t2 + ms(5));
        assert_eq!(h.take_output(), RUN3);
        h.on_bytes(&[NAK], t2 + ms(10));
        assert_eq!(h.take_output(), RUN3);
        h.on_time(t2 + ms(10) + t.t_ack);
        assert_eq!(h.take_output(), RUN3);
        let t3 = t2 + ms(10) + t.t_ack;
        h.on_bytes(&[ACK], t3 + ms(5));
        assert_eq!(h.take_output(), [EOT]);
        h.on_time(t3 + ms(5) + t.t_gap);
        assert_eq!(h.take_outcome(), Some(Ok(None)));
        assert_eq!(
            h.stats(),
            Stats {
                enq_sent: 3,
                frames_sent: 3,
                nak_received: 2,
                nak_sent: 0,
                timeouts: 2,
                duplicates: 0,
                bad_frames: 0,
            }
        );
    }

    /// A NAK within `T_GAP` after the host's EOT means its "ACK" was a corrupted NAK: the
    /// session fails as not taken, and the NAK is counted.
    #[test]
    fn a_nak_after_the_eot_refuses_the_telegram_and_is_counted() {
        let mut h = host();
        h.start(RUN3.to_vec(), false, ms(0));
        h.on_bytes(&[ACK], ms(5));
        h.on_bytes(&[ACK], ms(10));
        assert_eq!(h.take_output().last(), Some(&EOT));
        h.on_bytes(&[NAK], ms(15));
        assert_eq!(
            h.take_outcome(),
            Some(Err(LinkError::Retries { attempts: 1 }))
        );
        assert_eq!(h.stats().nak_received, 1);
    }

    /// A robot that never answers is reported after exactly `N_ENQ` ENQs, `T_ENQ` apart.
    #[test]
    fn host_reports_no_response_after_n_enq() {
        let t = Timers::default();
        let mut h = host();
        h.start(RUN3.to_vec(), false, ms(0));
        let mut now = ms(0);
        let mut enqs = h.take_output().len();
        while h.take_outcome().is_none() {
            now += t.t_enq;
            h.on_time(now);
            enqs += h.take_output().iter().filter(|b| **b == ENQ).count();
            assert!(now <= t.t_enq * (t.n_enq + 1), "no outcome");
        }
        assert_eq!(enqs, t.n_enq as usize);
        assert_eq!(now, t.t_enq * t.n_enq);
    }

    /// The robot's EOT while the host waits for its telegram's ACK, or before its reply
    /// telegram, interrupts the session.
    #[test]
    fn an_eot_in_place_of_an_ack_or_a_reply_interrupts() {
        let mut h = host();
        h.start(RUN3.to_vec(), false, ms(0));
        h.on_bytes(&[ACK], ms(5));
        h.on_bytes(&[EOT], ms(10));
        assert_eq!(h.take_outcome(), Some(Err(LinkError::Interrupted)));
        let mut h = host();
        h.start(RUN3.to_vec(), true, ms(0));
        h.on_bytes(&[ACK], ms(5));
        h.on_bytes(&[ACK], ms(10));
        h.on_bytes(&[ENQ], ms(20));
        h.on_bytes(&[EOT], ms(30));
        assert_eq!(h.take_outcome(), Some(Err(LinkError::Interrupted)));
    }

    /// A reply session as the host receives it: the robot's ENQ answered (deadline `T_ENQ +
    /// T_FLUSH` for its repeat), half a telegram (the `T_CHAR` deadline comes first), the whole
    /// reply acknowledged (deadline `T_ACK + T_FLUSH` for the EOT), the same reply again (our ACK
    /// lost: acknowledged again, a duplicate), another telegram (refused with NAK), a bad one
    /// (counted and flushed; the flush's end is a NAK), then EOT: the first reply is the outcome.
    #[test]
    fn host_receives_a_reply_session() {
        let t = Timers::default();
        let reply = encode(&cfg(), 0x86, &[1, 2, 3]).unwrap();
        let other = encode(&cfg(), 0x86, &[1, 2, 4]).unwrap();
        let mut h = host();
        h.start(RUN3.to_vec(), true, ms(0));
        h.on_bytes(&[ACK], ms(5));
        h.on_bytes(&[ACK], ms(10));
        assert_eq!(
            h.take_output(),
            [
                ENQ, RUN3[0], RUN3[1], RUN3[2], RUN3[3], RUN3[4], RUN3[5], EOT
            ]
        );
        h.on_bytes(&[ENQ], ms(100));
        assert_eq!(h.take_output(), [ACK]);
        assert_eq!(h.deadline(), Some(ms(100) + t.t_enq + t.t_flush));
        h.on_bytes(&reply[..3], ms(110));
        assert_eq!(h.deadline(), Some(ms(110) + t.t_char));
        h.on_bytes(&reply[3..], ms(120));
        assert_eq!(h.take_output(), [ACK]);
        assert_eq!(h.deadline(), Some(ms(120) + t.t_ack + t.t_flush));
        h.on_bytes(&reply, ms(200));
        assert_eq!(h.take_output(), [ACK]);
        h.on_bytes(&other, ms(300));
        assert_eq!(h.take_output(), [NAK]);
        let mut bad = reply.clone();
        *bad.last_mut().unwrap() ^= 0x10;
        h.on_bytes(&bad, ms(400));
        assert!(h.take_output().is_empty());
        h.on_time(ms(400) + t.t_flush);
        assert_eq!(h.take_output(), [NAK]);
        assert_eq!(h.deadline(), Some(ms(400) + t.t_flush + t.t_ack));
        h.on_bytes(&[EOT], ms(500));
        let Some(Ok(Some(f))) = h.take_outcome() else {
            panic!("no reply")
        };
        assert_eq!((f.code, f.data), (0x86, vec![1, 2, 3]));
        let s = h.stats();
        assert_eq!((s.duplicates, s.nak_sent, s.bad_frames), (1, 2, 1));
    }

    /// After noise while the host waits for its telegram's ACK, an ACK may be a corrupted NAK:
    /// the host sends the telegram again. With an ACK window, an ACK later than the window after
    /// the line fell free is treated the same; one at the window's end is taken.
    #[test]
    fn an_ack_behind_noise_or_after_the_window_is_asked_again() {
        // Noise, then ACK: sent again.
        let mut h = host();
        h.start(RUN3.to_vec(), false, ms(0));
        h.on_bytes(&[ACK], ms(5));
        h.take_output();
        h.on_bytes(&[0x55, ACK], ms(20));
        assert_eq!(h.take_output(), RUN3);
        // A NAK is no noise: the ACK after it is taken.
        let mut h = host();
        h.start(RUN3.to_vec(), false, ms(0));
        h.on_bytes(&[ACK], ms(5));
        h.take_output();
        h.on_bytes(&[NAK], ms(20));
        assert_eq!(h.take_output(), RUN3);
        h.on_bytes(&[ACK], ms(40));
        assert_eq!(h.take_output(), [EOT]);
        // The ACK window, counted from the end of the telegram on the line.
        let window = ms(30);
        for (at, taken) in [(ms(30), true), (ms(31), false)] {
            let mut h = Host::new(
                cfg(),
                Timers {
                    t_ack_window: Some(window),
                    ..Timers::default()
                },
            );
            h.start(RUN3.to_vec(), false, ms(0));
            h.on_bytes(&[ACK], ms(5));
            h.take_output();
            h.on_sent(ms(10));
            h.on_bytes(&[ACK], ms(10) + at);
            let out = h.take_output();
            assert_eq!(
                out == [EOT],
                taken,
                "ACK {at:?} after the line fell free: {out:?}"
            );
        }
    }

    #[test]
    fn nak_twice_then_ack_is_three_transmissions() {
        let mut h = host();
        h.start(RUN3.to_vec(), false, ms(0));
        assert_eq!(h.take_output(), [ENQ]);
        h.on_bytes(&[ACK], ms(1));
        for _ in 0..2 {
            assert_eq!(h.take_output(), RUN3);
            h.on_bytes(&[NAK], ms(2));
        }
        assert_eq!(h.take_output(), RUN3);
        h.on_bytes(&[ACK], ms(3));
        assert_eq!(h.take_output(), [EOT]);
        h.on_time(ms(3) + T_GAP);
        assert_eq!(h.take_outcome(), Some(Ok(None)));
        assert_eq!(h.stats().frames_sent, 3);
    }

    #[test]
    fn nak_corrupted_into_ack_is_caught_by_the_repeat() {
        let mut h = host();
        h.start(RUN3.to_vec(), false, ms(0));
        h.take_output();
        h.on_bytes(&[ACK], ms(1));
        h.take_output();
        // The robot's NAK NAK arrives as ACK NAK.
        h.on_bytes(&[ACK], ms(10));
        assert_eq!(h.take_output(), [EOT]);
        h.on_bytes(&[NAK], ms(11));
        assert_eq!(
            h.take_outcome(),
            Some(Err(LinkError::Retries { attempts: 1 }))
        );
    }

    #[test]
    fn nak_storm_is_retries_error() {
        let mut h = host();
        h.start(RUN3.to_vec(), false, ms(0));
        assert_eq!(h.take_output(), [ENQ]);
        h.on_bytes(&[ACK], ms(1));
        let mut sent = 0;
        for k in 0..20 {
            let out = h.take_output();
            if out == RUN3 {
                sent += 1;
            }
            if let Some(o) = h.take_outcome() {
                assert_eq!(out, [EOT]);
                assert_eq!(o, Err(LinkError::Retries { attempts: N_TX }));
                assert_eq!(sent, N_TX);
                return;
            }
            h.on_bytes(&[NAK], ms(2 + k));
        }
        panic!("no outcome");
    }

    #[test]
    fn silence_is_no_response_after_n_enq() {
        let mut h = host();
        h.start(RUN3.to_vec(), false, ms(0));
        let mut enqs = 0;
        let mut now = ms(0);
        loop {
            for b in h.take_output() {
                if b == ENQ {
                    enqs += 1;
                }
            }
            if let Some(o) = h.take_outcome() {
                assert_eq!(o, Err(LinkError::NoResponse { attempts: N_ENQ }));
                break;
            }
            now = h.deadline().expect("a deadline while active");
            h.on_time(now);
        }
        assert_eq!(enqs, N_ENQ);
        assert_eq!(now, T_ENQ * N_ENQ);
    }

    #[test]
    fn busy_nak_backs_off() {
        let mut h = host();
        h.start(RUN3.to_vec(), false, ms(0));
        h.take_output();
        h.on_bytes(&[NAK], ms(3));
        assert!(h.take_output().is_empty());
        assert_eq!(h.deadline(), Some(ms(3) + T_BUSY));
        h.on_time(ms(3) + T_BUSY);
        assert_eq!(h.take_output(), [ENQ]);
    }

    #[test]
    fn noise_stx_cannot_swallow_the_ack() {
        let mut h = host();
        h.start(RUN3.to_vec(), false, ms(0));
        h.take_output();
        h.on_bytes(&[STX, 0x40, ACK], ms(1));
        assert_eq!(h.take_output(), RUN3);
    }

    fn robot() -> RobotSession {
        RobotSession::new(cfg(), Timers::default())
    }

    #[test]
    fn robot_reacks_identical_retransmission_once_executed() {
        let mut r = robot();
        assert!(r.on_bytes(&[ENQ], ms(0)).is_empty());
        assert_eq!(r.take_output(), [ACK]);
        let got = r.on_bytes(&RUN3, ms(10));
        assert_eq!(got.len(), 1);
        assert_eq!(r.take_output(), [ACK]);
        // The ACK was lost; the host sends the same telegram again.
        assert!(r.on_bytes(&RUN3, ms(2100)).is_empty());
        assert_eq!(r.take_output(), [ACK]);
        assert_eq!(r.stats().duplicates, 1);
        // A different telegram in the same session is refused.
        let other = encode(&cfg(), 0x02, &[4]).unwrap();
        assert!(r.on_bytes(&other, ms(2200)).is_empty());
        assert_eq!(r.take_output(), [NAK, NAK]);
        // EOT ends the session; a new session delivers the same telegram again.
        r.on_bytes(&[EOT], ms(2300));
        r.on_bytes(&[ENQ], ms(2400));
        assert_eq!(r.take_output(), [ACK]);
        assert_eq!(r.on_bytes(&RUN3, ms(2410)).len(), 1);
    }

    #[test]
    fn robot_naks_bad_checksum_after_flush_and_char_gap() {
        let mut r = robot();
        r.on_bytes(&[ENQ], ms(0));
        r.take_output();
        let mut bad = RUN3;
        bad[5] ^= 0x10;
        assert!(r.on_bytes(&bad, ms(5)).is_empty());
        assert!(r.take_output().is_empty());
        assert_eq!(r.deadline(), Some(ms(5) + T_FLUSH));
        r.on_time(ms(5) + T_FLUSH);
        assert_eq!(r.take_output(), [NAK, NAK]);
        // Bytes arriving during a flush extend it to T_FLUSH after the last of them.
        let mut bad = RUN3;
        bad[5] ^= 0x10;
        assert!(r.on_bytes(&bad, ms(40)).is_empty());
        assert!(r.on_bytes(&[0x55], ms(55)).is_empty());
        assert_eq!(r.deadline(), Some(ms(55) + T_FLUSH));
        r.on_time(ms(45) + T_FLUSH);
        assert!(r.take_output().is_empty(), "the flush still runs");
        r.on_time(ms(55) + T_FLUSH);
        assert_eq!(r.take_output(), [NAK, NAK]);
        // Half a telegram, then silence beyond T_CHAR.
        r.on_bytes(&RUN3[..3], ms(100));
        assert_eq!(r.deadline(), Some(ms(100) + T_CHAR));
        r.on_time(ms(100) + T_CHAR);
        assert_eq!(r.take_output(), [NAK, NAK]);
        // The retransmission goes through.
        assert_eq!(r.on_bytes(&RUN3, ms(400)).len(), 1);
        assert_eq!(r.take_output(), [ACK]);
        // Two bad telegrams counted; three NAK pairs (two flushes, one T_CHAR gap).
        assert_eq!((r.stats().bad_frames, r.stats().nak_sent), (2, 3));
    }

    #[test]
    fn busy_robot_naks_enq() {
        let mut r = robot();
        r.busy = true;
        r.on_bytes(&[ENQ], ms(0));
        assert_eq!(r.take_output(), [NAK]);
        assert_eq!(r.stats().nak_sent, 1);
    }

    /// Accepts RUN_PROGRAM 3 only (a robot's strict check, [`RobotSession::validate`]).
    fn only_run3(f: &Frame) -> bool {
        f.code == 0x02 && f.data == [3]
    }

    /// A robot that validates telegrams takes a telegram that fails the check as bad (counted,
    /// flushed, then NAK) and passes a good one and its repetition.
    #[test]
    fn a_validating_robot_refuses_a_telegram_that_fails_its_check() {
        let mut r = robot();
        r.validate = Some(only_run3);
        r.on_bytes(&[ENQ], ms(0));
        assert_eq!(r.take_output(), [ACK]);
        let other = encode(&cfg(), 0x02, &[4]).unwrap();
        assert!(r.on_bytes(&other, ms(5)).is_empty());
        assert!(r.take_output().is_empty());
        assert_eq!(r.stats().bad_frames, 1);
        r.on_time(ms(5) + T_FLUSH);
        assert_eq!(r.take_output(), [NAK, NAK]);
        assert_eq!(r.on_bytes(&RUN3, ms(100)).len(), 1);
        assert_eq!(r.take_output(), [ACK]);
        assert!(r.on_bytes(&RUN3, ms(200)).is_empty());
        assert_eq!(r.take_output(), [ACK]);
        // Another (valid) telegram in the same session is refused: one per session.
        r.validate = None;
        assert!(r.on_bytes(&other, ms(300)).is_empty());
        assert_eq!(r.take_output(), [NAK, NAK]);
        let s = r.stats();
        assert_eq!((s.bad_frames, s.duplicates, s.nak_sent), (1, 1, 2));
    }

    /// The robot's reply session, counted: after the host's ENQUIRE session it sends ENQ; a
    /// host that never answers gets exactly `N_ENQ` of them, `T_ENQ` apart, and then none; one
    /// that answers gets the reply telegram, sent again after a NAK, then EOT.
    #[test]
    fn robot_reply_session_counts_its_enqs_and_telegrams() {
        let t = Timers::default();
        let reply = encode(&cfg(), 0x86, &[1, 2, 3]).unwrap();
        let enquired = |r: &mut RobotSession, at: Duration| {
            r.on_bytes(&[ENQ], at);
            assert_eq!(r.on_bytes(&ENQUIRE, at + ms(5)).len(), 1);
            r.queue_reply(reply.clone());
            r.on_bytes(&[EOT], at + ms(10));
            assert_eq!(r.take_output(), [ACK, ACK, ENQ]);
        };
        // Unanswered.
        let mut r = robot();
        enquired(&mut r, ms(0));
        let mut now = ms(10);
        let mut enqs = 1;
        for _ in 0..2 * t.n_enq {
            now += t.t_enq;
            r.on_time(now);
            enqs += r.take_output().iter().filter(|b| **b == ENQ).count();
        }
        assert_eq!(enqs, t.n_enq as usize);
        assert_eq!(r.stats().enq_sent, u64::from(t.n_enq));
        assert_eq!(r.stats().timeouts, u64::from(t.n_enq));
        // Every ENQ refused: it gives up after N_ENQ of them.
        let mut r = robot();
        enquired(&mut r, ms(0));
        let (mut now, mut enqs) = (ms(20), 1);
        for _ in 0..2 * t.n_enq {
            r.on_bytes(&[NAK], now);
            now += t.t_busy;
            r.on_time(now);
            enqs += r.take_output().iter().filter(|b| **b == ENQ).count();
        }
        assert_eq!(enqs, t.n_enq as usize);
        assert_eq!(r.deadline(), None);
        // Its ENQ taken, its telegram never acknowledged: N_TX transmissions, T_ACK apart, then
        // EOT.
        let mut r = robot();
        enquired(&mut r, ms(0));
        r.on_bytes(&[ACK], ms(20));
        let (mut now, mut out) = (ms(20), r.take_output());
        for _ in 0..2 * t.n_tx {
            now += t.t_ack;
            r.on_time(now);
            out.extend(r.take_output());
        }
        assert_eq!(out.len(), t.n_tx as usize * reply.len() + 1);
        assert_eq!(out.last(), Some(&EOT));
        assert_eq!(r.stats().timeouts, u64::from(t.n_tx));
        // Answered, the telegram refused once.
        let mut r = robot();
        enquired(&mut r, ms(0));
        r.on_bytes(&[ACK], ms(20));
        assert_eq!(r.take_output(), reply);
        r.on_bytes(&[NAK], ms(30));
        assert_eq!(r.take_output(), reply);
        r.on_bytes(&[ACK], ms(40));
        assert_eq!(r.take_output(), [EOT]);
        let s = r.stats();
        assert_eq!((s.enq_sent, s.frames_sent, s.nak_received), (1, 2, 1));
        // Its ENQ refused (the host is busy): ENQ again after T_BUSY, the NAK counted.
        let mut r = robot();
        enquired(&mut r, ms(0));
        r.on_bytes(&[NAK], ms(20));
        assert!(r.take_output().is_empty());
        assert_eq!(r.deadline(), Some(ms(20) + t.t_busy));
        r.on_time(ms(20) + t.t_busy);
        assert_eq!(r.take_output(), [ENQ]);
        assert_eq!(r.stats().nak_received, 1);
        // The host's EOT ends the reply session: no ENQ follows.
        let mut r = robot();
        enquired(&mut r, ms(0));
        r.on_bytes(&[EOT], ms(20));
        r.on_time(ms(20) + t.t_enq);
        assert!(r.take_output().is_empty());
        assert_eq!(r.deadline(), None);
    }

    /// Host and robot wired back to back with no delay; the robot answers ENQUIRE with `reply`.
    fn converse(frame: Vec<u8>, reply: Option<Vec<u8>>) -> (Outcome, usize) {
        let mut h = host();
        let mut r = robot();
        let mut now = ms(0);
        let mut delivered = 0;
        h.start(frame, reply.is_some(), now);
        for _ in 0..1000 {
            let to_robot = h.take_output();
            for f in r.on_bytes(&to_robot, now) {
                delivered += 1;
                let _ = f;
                if let Some(rep) = &reply {
                    r.queue_reply(rep.clone());
                }
            }
            let to_host = r.take_output();
            h.on_bytes(&to_host, now);
            if let Some(o) = h.take_outcome() {
                // Let the robot see the final EOT.
                r.on_bytes(&h.take_output(), now);
                return (o, delivered);
            }
            if to_robot.is_empty() && to_host.is_empty() {
                now = [h.deadline(), r.deadline()]
                    .into_iter()
                    .flatten()
                    .min()
                    .expect("someone waits");
                h.on_time(now);
                r.on_time(now);
            }
        }
        panic!("no outcome");
    }

    #[test]
    fn busy_robot_through_n_enq_is_busy_error() {
        let mut h = host();
        let mut now = ms(0);
        h.start(RUN3.to_vec(), false, now);
        let mut enqs = 0;
        loop {
            let out = h.take_output();
            if out.contains(&ENQ) {
                enqs += 1;
                h.on_bytes(&[NAK], now + ms(1));
            }
            if let Some(o) = h.take_outcome() {
                assert_eq!(o, Err(LinkError::Busy { attempts: N_ENQ }));
                break;
            }
            now = h.deadline().expect("deadline");
            h.on_time(now);
        }
        assert_eq!(enqs, N_ENQ);
        // Five back-offs of T_BUSY between six ENQs.
        assert_eq!(now, T_BUSY * (N_ENQ - 1) + ms(N_ENQ as u64 - 1));
    }

    #[test]
    fn robot_session_times_out_to_neutral() {
        let mut r = robot();
        r.on_bytes(&[ENQ], ms(0));
        assert_eq!(r.take_output(), [ACK]);
        assert_eq!(r.deadline(), Some(T_IDLE));
        r.on_time(T_IDLE);
        assert_eq!(r.deadline(), None);
        // A telegram now is ignored (no session); the next ENQ opens one.
        assert!(r.on_bytes(&RUN3, T_IDLE + ms(100)).is_empty());
        assert!(r.take_output().is_empty());
        r.on_bytes(&[ENQ], T_IDLE + ms(200));
        assert_eq!(r.take_output(), [ACK]);
        assert_eq!(r.on_bytes(&RUN3, T_IDLE + ms(210)).len(), 1);
    }

    #[test]
    fn host_wins_contention_and_stray_enq_in_data_is_ignored() {
        let mut r = robot();
        r.on_bytes(&[ENQ], ms(0));
        r.take_output();
        // ENQUIRE accepted; the robot will reply after EOT.
        let enquire = [0x02, 0x06, 0x01, 0x00, 0x03, 0x0A];
        assert_eq!(r.on_bytes(&enquire, ms(10)).len(), 1);
        r.queue_reply(encode(&cfg(), 0x86, &[1; 15]).unwrap());
        r.on_bytes(&[EOT], ms(20));
        assert_eq!(r.take_output(), [ACK, ENQ]);
        // The host starts a new session instead: it wins, the reply is dropped.
        r.on_bytes(&[ENQ], ms(100));
        assert_eq!(r.take_output(), [ACK]);
        // Inside the session, a 0x05 right behind other bytes is data, not ENQ.
        assert!(r.on_bytes(&[0x41, ENQ], ms(110)).is_empty());
        assert!(r.take_output().is_empty());
        r.on_bytes(&[EOT], ms(120));
        r.on_time(ms(5000));
        assert!(
            r.take_output().is_empty(),
            "no reply session after contention"
        );
    }

    #[test]
    fn enquire_reply_in_reverse_session() {
        // ENQUIRE status (spec §5.3: 02 06 01 00 03 0A).
        let enquire = vec![0x02, 0x06, 0x01, 0x00, 0x03, 0x0A];
        let reply = encode(&cfg(), 0x86, &[0, 1, 0, 0, 0, 0, 0, 1]).unwrap();
        let (o, n) = converse(enquire, Some(reply));
        assert_eq!(n, 1);
        let f = o.unwrap().unwrap();
        assert_eq!(f.code, 0x86);
        assert_eq!(f.data, [0, 1, 0, 0, 0, 0, 0, 1]);
        let (o, n) = converse(RUN3.to_vec(), None);
        assert_eq!((o, n), (Ok(None), 1));
    }

    #[test]
    fn an_urgent_session_keeps_half_the_gap_and_its_margin_and_an_abort_in_the_gap_sends_nothing() {
        let mut h = Host::new(FrameConfig::default(), Timers::default());
        // The host's last byte left the line at 100 ms: the next ENQ waits until 120 ms.
        h.on_sent(ms(100));
        h.start(RUN3.to_vec(), false, ms(105));
        assert!(h.take_output().is_empty());
        assert_eq!(h.deadline(), Some(ms(120)));
        // Abandoned in its gap: nothing was on the line, so no EOT, and the gap is not restarted.
        h.abort(ms(106));
        assert!(h.take_output().is_empty());
        // STOP: its ENQ after 12 ms of silence (the robot needs 10 ms, the margin is 2 ms), not
        // 20 ms.
        h.start_urgent(RUN3.to_vec(), false, ms(106));
        assert_eq!(h.deadline(), Some(ms(112)));
        h.on_time(ms(112));
        assert_eq!(h.take_output(), vec![ENQ]);
        // A session abandoned on the line ends with EOT and a whole gap.
        h.abort(ms(116));
        assert_eq!(h.take_output(), vec![EOT]);
        h.start(RUN3.to_vec(), false, ms(117));
        assert_eq!(h.deadline(), Some(ms(136)));
    }

    /// ENQUIRE status (spec §5.3: 02 06 01 00 03 0A).
    const ENQUIRE: [u8; 6] = [0x02, 0x06, 0x01, 0x00, 0x03, 0x0A];
    /// STOP (docs/protocol.md §3: 02 0C 00 03 0F).
    const STOP: [u8; 5] = [0x02, 0x0C, 0x00, 0x03, 0x0F];

    #[test]
    fn an_abort_sends_eot_only_while_the_hosts_own_session_is_open() {
        // The ENQ out, unanswered: EOT, and the gap from it.
        let mut h = host();
        h.start(ENQUIRE.to_vec(), true, ms(0));
        assert_eq!(h.take_output(), [ENQ]);
        h.on_sent(ms(1));
        h.abort(ms(2));
        assert_eq!(h.take_output(), [EOT]);
        h.on_sent(ms(3));
        h.start(ENQUIRE.to_vec(), true, ms(3));
        assert_eq!(h.deadline(), Some(ms(3) + T_GAP));
        // The telegram out, unacknowledged: EOT.
        let mut h = host();
        h.start(ENQUIRE.to_vec(), true, ms(0));
        h.take_output();
        h.on_bytes(&[ACK], ms(2));
        assert_eq!(h.take_output(), ENQUIRE);
        h.on_sent(ms(8));
        h.abort(ms(9));
        assert_eq!(h.take_output(), [EOT]);
        // The first ENQ queued and not yet taken: nothing reached the line, nothing is sent.
        let mut h = host();
        h.start(ENQUIRE.to_vec(), true, ms(0));
        h.abort(ms(0));
        assert!(h.take_output().is_empty());
        // In the robot's reply session (the host's EOT out): nothing more is sent, and the gap
        // runs from the host's last byte, its ACK to the robot's ENQ.
        let mut h = host();
        h.start(ENQUIRE.to_vec(), true, ms(0));
        h.take_output();
        h.on_bytes(&[ACK], ms(2));
        h.take_output();
        h.on_bytes(&[ACK], ms(9));
        assert_eq!(h.take_output(), [EOT]);
        h.on_sent(ms(10));
        h.on_bytes(&[ENQ], ms(12));
        assert_eq!(h.take_output(), [ACK]);
        h.on_sent(ms(13));
        h.abort(ms(20));
        assert!(h.take_output().is_empty());
        h.start(ENQUIRE.to_vec(), true, ms(20));
        assert_eq!(h.deadline(), Some(ms(13) + T_GAP));
        // The session's EOT queued when the request came: it still goes out.
        let mut h = host();
        h.start(RUN3.to_vec(), false, ms(0));
        h.take_output();
        h.on_bytes(&[ACK], ms(2));
        h.take_output();
        h.on_bytes(&[ACK], ms(9));
        h.abort(ms(9));
        assert_eq!(h.take_output(), [EOT]);
    }

    #[test]
    fn stop_takes_over_a_session_whose_robot_has_seen_no_telegram() {
        // The ENQ awaits its answer: STOP goes out when the ACK comes, in that session.
        let mut h = host();
        h.start(ENQUIRE.to_vec(), true, ms(0));
        h.take_output();
        assert!(h.can_take_over());
        assert!(h.take_over(STOP.to_vec(), false, ms(1)));
        assert!(h.take_output().is_empty());
        h.on_bytes(&[ACK], ms(2));
        assert_eq!(h.take_output(), STOP);
        h.on_bytes(&[ACK], ms(8));
        assert_eq!(h.take_output(), [EOT]);
        h.on_time(ms(8) + T_GAP);
        assert_eq!(h.take_outcome(), Some(Ok(None)));
        assert_eq!(h.stats().frames_sent, 1);
        // The ACK is in and the ENQUIRE queued, not yet taken: STOP goes in its place.
        let mut h = host();
        h.start(ENQUIRE.to_vec(), true, ms(0));
        h.take_output();
        h.on_bytes(&[ACK], ms(2));
        assert!(h.can_take_over());
        assert!(h.take_over(STOP.to_vec(), false, ms(2)));
        assert_eq!(h.take_output(), STOP);
        assert_eq!(h.stats().frames_sent, 1);
        // The ENQUIRE has left: the robot may have it, the session is not taken over.
        assert!(!h.can_take_over());
        assert!(!h.take_over(ENQUIRE.to_vec(), true, ms(3)));
        assert!(h.take_output().is_empty());
        // Nor in the gap, where nothing is on the line.
        let mut h = host();
        h.on_sent(ms(0));
        h.start(ENQUIRE.to_vec(), true, ms(1));
        assert!(!h.can_take_over());
        assert!(!h.take_over(STOP.to_vec(), false, ms(1)));
    }

    #[test]
    fn an_urgent_enq_unanswered_is_repeated_after_one_urgent_gap_once() {
        let g = Timers::default().urgent_gap();
        let mut h = host();
        h.on_sent(ms(100));
        h.start_urgent(STOP.to_vec(), false, ms(100));
        h.on_time(ms(100) + g);
        assert_eq!(h.take_output(), [ENQ]);
        // No answer: the ENQ again one urgent gap later, then T_ENQ apart as usual.
        assert_eq!(h.deadline(), Some(ms(100) + g * 2));
        h.on_time(ms(100) + g * 2);
        assert_eq!(h.take_output(), [ENQ]);
        assert_eq!(h.deadline(), Some(ms(100) + g * 2 + T_ENQ));
        // A session not urgent waits T_ENQ for its first answer.
        let mut h = host();
        h.start(STOP.to_vec(), false, ms(0));
        assert_eq!(h.deadline(), Some(T_ENQ));
        // An urgent session's repeat counts toward N_ENQ: silence fails after N_ENQ ENQs.
        let mut h = host();
        h.start_urgent(STOP.to_vec(), false, ms(0));
        let mut enqs = 0;
        loop {
            enqs += h.take_output().iter().filter(|b| **b == ENQ).count();
            if let Some(o) = h.take_outcome() {
                assert_eq!(o, Err(LinkError::NoResponse { attempts: N_ENQ }));
                break;
            }
            let t = h.deadline().expect("a deadline");
            h.on_time(t);
        }
        assert_eq!(enqs, N_ENQ as usize);
    }
}
