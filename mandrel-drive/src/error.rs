//! The crate's error type.

/// Everything that can go wrong talking to, or simulating, an indexer.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// The byte link failed.
    #[error("link i/o: {0}")]
    Io(#[from] std::io::Error),
    /// The serial port could not be opened or configured.
    #[error("serial port: {0}")]
    Serial(#[from] serialport::Error),
    /// No complete reply within the timeout.
    #[error("no reply to {command:?} within {waited_ms} ms")]
    Timeout {
        /// The command that went unanswered.
        command: String,
        /// How long the client waited.
        waited_ms: u64,
    },
    /// A reply that does not follow the dialect's grammar.
    #[error("bad reply to {command:?}: {reply:?} ({reason})")]
    BadReply {
        /// The command that was answered.
        command: String,
        /// The reply text as received (lossy UTF-8).
        reply: String,
        /// What is wrong with it.
        reason: &'static str,
    },
    /// A reply from another device on the daisy chain.
    #[error("reply from device {got}, expected device {expected}")]
    WrongAddress {
        /// The address the command went to.
        expected: u8,
        /// The address in the reply.
        got: u16,
    },
    /// The echo did not match the command sent.
    #[error("echo {echo:?} does not match command {command:?}")]
    Echo {
        /// The command sent.
        command: String,
        /// What came back.
        echo: String,
    },
    /// The controller answered with an error (GRBL `error:N`, simulator `?`).
    #[error("controller refused {command:?}: {message}")]
    Refused {
        /// The refused command.
        command: String,
        /// The controller's code or message.
        message: String,
    },
    /// A step rate above the translator's pulse limit (seed 001 §4.1.5).
    #[error("{requested_pps:.0} pulses/s exceeds the translator limit of {limit_pps:.0} pulses/s")]
    PulseRate {
        /// The requested pulse rate.
        requested_pps: f64,
        /// The translator's limit.
        limit_pps: f64,
    },
    /// The motor stalled: it fell out of step, from a start velocity above its pull-in rate
    /// (seed 001 §5.3.2) or a ramp or speed that asked for more than its pull-out torque
    /// (`sim::motor`). The indexer's attention flag does not say which.
    #[error(
        "the mandrel motor stalled (out of step: a start velocity above its pull-in rate, or a ramp or speed beyond its pull-out torque); the move failed"
    )]
    Stalled,
    /// The controller raised an alarm.
    #[error("controller alarm: {0}")]
    Alarm(String),
    /// A function the dialect does not have.
    #[error("{dialect} has no {feature}")]
    Unsupported {
        /// The dialect.
        dialect: &'static str,
        /// The missing function.
        feature: &'static str,
    },
    /// A value outside what the dialect or the drive accepts.
    #[error("{name} = {} out of range ({expected})", paths::limits::shown(*value))]
    OutOfRange {
        /// The parameter.
        name: &'static str,
        /// The value given.
        value: f64,
        /// The accepted range.
        expected: &'static str,
    },
    /// The move did not finish in time.
    #[error("move not finished within {waited_ms} ms")]
    MoveTimeout {
        /// How long the client waited.
        waited_ms: u64,
    },
    /// A re-attach found the line talking without pause for its whole wait: not an indexer
    /// that answers (or one that keeps sending).
    #[error("the line did not go quiet within {waited_ms} ms: something on it keeps sending")]
    LineNotQuiet {
        /// How long the client waited.
        waited_ms: u64,
    },
    /// A re-attach found the card still moving at the end of its wait (a move of the run before
    /// that does not end).
    #[error(
        "still moving after {waited_ms} ms of waiting for the move under way to end; stop the mandrel and re-reference it"
    )]
    StillMoving {
        /// How long the client waited.
        waited_ms: u64,
    },
    /// A lathe axis ran onto a hardware limit switch; the drives were stopped (seed 000 §9.11).
    #[error("axis {axis} hit its {side} limit switch at {position_counts} counts; drives stopped")]
    LimitTripped {
        /// The axis letter.
        axis: char,
        /// `low` or `high`.
        side: &'static str,
        /// Where it was, counts from machine zero.
        position_counts: i64,
    },
    /// Machine-zero search found no home switch within the travel searched (seed 003 §4.2).
    #[error("axis {axis}: no home switch within {searched_counts} counts")]
    HomeNotFound {
        /// The axis letter.
        axis: char,
        /// How far it moved looking for it.
        searched_counts: i64,
    },
    /// The exchange was cancelled through the client's [`crate::client::Cancel`] token.
    #[error("cancelled")]
    Cancelled,
    /// The gearing is invalid.
    #[error("gearing: {0}")]
    Gearing(#[from] paths::Error),
}

/// Result with this crate's [`Error`].
pub type Result<T> = std::result::Result<T, Error>;
