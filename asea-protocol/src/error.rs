//! The crate's error types: one enum for the crate ([`Error`]) and small enums a caller matches on
//! ([`EncodeError`], [`FrameError`], [`LinkError`]).

/// A value that cannot be put on the wire. Out-of-range values are refused, never clamped.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum EncodeError {
    /// A number outside its wire range (or not finite).
    #[error("{name} = {} out of range ({expected})", paths::limits::shown(*value))]
    OutOfRange {
        /// The field.
        name: &'static str,
        /// The value given.
        value: f64,
        /// The accepted range.
        expected: &'static str,
    },
    /// A quaternion that cannot be normalised (zero or not finite).
    #[error("quaternion ({0}, {1}, {2}, {3}) has no direction")]
    DegenerateQuaternion(f64, f64, f64, f64),
    /// More data than the one-byte LEN field can carry.
    #[error("telegram data of {len} bytes exceeds the limit of {max}")]
    TooLong {
        /// The data length.
        len: usize,
        /// The limit.
        max: usize,
    },
}

/// A frame the decoder refuses (a link error: the receiver answers NAK).
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum FrameError {
    /// The byte at the ETX position is something else.
    #[error("expected ETX after {len} data bytes, got 0x{got:02X}")]
    MissingEtx {
        /// LEN of the frame.
        len: u8,
        /// The byte found.
        got: u8,
    },
    /// The check value does not match.
    #[error("checksum mismatch: computed 0x{computed:04X}, received 0x{received:04X}")]
    Checksum {
        /// Computed over the received bytes.
        computed: u16,
        /// As received.
        received: u16,
    },
    /// LEN above the configured maximum.
    #[error("LEN {len} exceeds the configured maximum {max}")]
    TooLong {
        /// LEN received.
        len: u8,
        /// The limit.
        max: u8,
    },
}

/// A telegram that frames correctly but does not parse as a command or reply.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum ParseError {
    /// An unknown command or reply code.
    #[error("unknown code 0x{0:02X}")]
    UnknownCode(u8),
    /// LEN does not match what the code requires.
    #[error("code 0x{code:02X} takes {expected} data bytes, got {got}")]
    Length {
        /// The code.
        code: u8,
        /// Required length.
        expected: usize,
        /// Received length.
        got: usize,
    },
    /// A field with an invalid value (reserved bits, zero program number, bad selector, …).
    #[error("invalid {0}")]
    Field(&'static str),
    /// A status reply whose `last_error` is no code of [`crate::RobotError`].
    #[error("unknown robot error code {0}")]
    UnknownErrorCode(u8),
}

/// How a link session failed (docs/protocol.md §6).
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum LinkError {
    /// No answer to ENQ after `attempts` tries (`N_ENQ`).
    #[error("no response to ENQ after {attempts} attempts")]
    NoResponse {
        /// ENQ attempts made.
        attempts: u32,
    },
    /// The robot stayed busy (NAK to ENQ) through `attempts` tries.
    #[error("robot busy: NAK to ENQ {attempts} times")]
    Busy {
        /// ENQ attempts made.
        attempts: u32,
    },
    /// The telegram was refused or unacknowledged `attempts` times (`N_TX`); it may or may not have
    /// been executed once, never twice.
    #[error("telegram not acknowledged after {attempts} transmissions")]
    Retries {
        /// Transmissions made.
        attempts: u32,
    },
    /// The other side sent EOT in the middle of a session.
    #[error("session interrupted by EOT")]
    Interrupted,
    /// The telegram was delivered but no reply session followed (`T_REPLY`).
    #[error("no reply session within the reply timeout")]
    NoReply,
}

/// Everything that can go wrong in this crate.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A value cannot be encoded.
    #[error("encode: {0}")]
    Encode(#[from] EncodeError),
    /// A received telegram does not parse.
    #[error("parse: {0}")]
    Parse(#[from] ParseError),
    /// The link session failed.
    #[error("link: {0}")]
    Link(#[from] LinkError),
    /// The byte link failed.
    #[error("link i/o: {0}")]
    Io(#[from] std::io::Error),
    /// The serial port could not be opened or configured.
    #[error("serial port: {0}")]
    Serial(#[from] serialport::Error),
    /// A reply of the wrong kind.
    #[error("unexpected reply: {0}")]
    UnexpectedReply(&'static str),
    /// The robot reported an error through ENQUIRE STATUS (and the client acknowledged it).
    #[error(
        "robot error {code}: {message} (program {program}, instruction {instruction}; {count} new error(s))"
    )]
    Robot {
        /// The `last_error` code.
        code: u8,
        /// Its meaning.
        message: &'static str,
        /// The program the robot was at (0 if none).
        program: u8,
        /// The instruction the robot was at: for a program check, the instruction it refused.
        instruction: u16,
        /// Errors raised since the last one reported ([`crate::Status::error_seq`] advanced by this
        /// much); more than 1 means earlier codes were overwritten by this one.
        count: u8,
    },
    /// A reply telegram that passed the check value but does not parse, named.
    #[error("bad {telegram} reply: {source}")]
    Reply {
        /// The request it answered.
        telegram: &'static str,
        /// Why it does not parse.
        source: ParseError,
    },
    /// The exchange was cancelled through the client's [`crate::client::Cancel`] token.
    #[error("cancelled")]
    Cancelled,
    /// A re-attach found the line talking without pause for its whole wait
    /// ([`crate::Client::attach`]).
    #[error("the line did not go quiet within {waited_ms} ms: something on it keeps sending")]
    LineNotQuiet {
        /// How long the client waited.
        waited_ms: u64,
    },
    /// The robot's execution count shows that a command was not executed exactly once: a
    /// corrupted twin or an unsent telegram was executed (or the command twice). Reported, never
    /// repaired by sending again.
    #[error(
        "{command}: the robot executed {executed} telegram(s) with an effect where 1 was sent (last digest {digest:04X}, sent {sent:04X})"
    )]
    Foreign {
        /// The command sent.
        command: &'static str,
        /// Telegrams with an effect executed meanwhile.
        executed: u16,
        /// Digest of the last executed telegram.
        digest: u16,
        /// Digest of the telegram sent.
        sent: u16,
    },
    /// A command was executed once but its effect is not what it should be.
    #[error("{command}: executed, but {expected} is not so ({found})")]
    Effect {
        /// The command sent.
        command: &'static str,
        /// The effect looked for.
        expected: &'static str,
        /// What the robot reports.
        found: String,
    },
    /// A program of a batch upload holds more instructions than were uploaded, after every
    /// re-upload the policy allows.
    #[error("program {program} holds {count} instructions, {expected} uploaded")]
    ExtraSlots {
        /// Program number.
        program: u8,
        /// Instructions it holds.
        count: u16,
        /// Instructions uploaded.
        expected: u16,
    },
    /// The memory holds instructions that neither the batch nor the memory's earlier contents
    /// account for: a corrupted twin stored into a program outside the batch.
    #[error(
        "memory holds {total} instructions, {expected} expected: a store landed outside the batch"
    )]
    ForeignStore {
        /// Instructions in memory.
        total: u16,
        /// Instructions accounted for.
        expected: u16,
    },
    /// A command was not executed after every attempt the policy allows (each attempt proven
    /// not executed before the next).
    #[error("{command}: not executed after {attempts} attempts")]
    NotExecuted {
        /// The command sent.
        command: &'static str,
        /// Attempts made.
        attempts: u32,
    },
    /// A read-back differs from what was stored, after every re-store.
    #[error("program {program} instruction {instruction} does not read back as stored")]
    Verify {
        /// Program number.
        program: u8,
        /// Instruction number.
        instruction: u16,
    },
}

/// Result with this crate's [`Error`].
pub type Result<T> = std::result::Result<T, Error>;
