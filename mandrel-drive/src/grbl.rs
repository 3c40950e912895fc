//! A GRBL 1.1 / grblHAL class controller turning the mandrel as its A axis (docs/mandrel-drive.md).
//!
//! Lines end in LF and get `ok` or `error:N`; real-time bytes (`?`, `!`, `~`, `0x18`, `0x85`) are
//! never acknowledged. The A axis is set up in degrees at the mandrel: `$103` steps/deg,
//! `$113` deg/min, `$123` deg/s². GRBL has no start/stop velocity: it starts from rest.

use std::fmt;

/// Real-time status request.
pub const STATUS: u8 = b'?';
/// Real-time feed hold.
pub const FEED_HOLD: u8 = b'!';
/// Real-time cycle start / resume.
pub const CYCLE_START: u8 = b'~';
/// Real-time soft reset (Ctrl-X).
pub const SOFT_RESET: u8 = 0x18;
/// Real-time jog cancel (grbl 1.1).
pub const JOG_CANCEL: u8 = 0x85;

/// One line command.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum Command {
    /// `$103=`: A-axis steps per degree.
    StepsPerDeg(f64),
    /// `$113=`: A-axis maximum rate, deg/min.
    MaxRate(f64),
    /// `$123=`: A-axis acceleration, deg/s².
    Accel(f64),
    /// `$376=`: grblHAL rotary-axis mask (A = 1 … bit 3 on a 4-axis build; we send the A bit).
    RotaryMask(u8),
    /// `$133=`: A-axis maximum travel (0 = no soft limit).
    MaxTravel(f64),
    /// `G90 G1 A… F…` (absolute) or `G91 G1 A… F…` (incremental): position move.
    Move {
        /// Absolute (`G90`) or incremental (`G91`).
        absolute: bool,
        /// Mandrel angle, degrees.
        a_deg: f64,
        /// Feed, deg/min.
        feed_deg_per_min: f64,
    },
    /// `$J=G91 A… F…`: jog, used for constant velocity.
    Jog {
        /// Incremental angle, degrees.
        a_deg: f64,
        /// Feed, deg/min.
        feed_deg_per_min: f64,
    },
    /// `G92 A0`: zero the A position.
    ZeroA,
}

impl fmt::Display for Command {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Command::StepsPerDeg(v) => write!(f, "$103={v:.4}"),
            Command::MaxRate(v) => write!(f, "$113={v:.3}"),
            Command::Accel(v) => write!(f, "$123={v:.3}"),
            Command::RotaryMask(m) => write!(f, "$376={m}"),
            Command::MaxTravel(v) => write!(f, "$133={v:.3}"),
            Command::Move {
                absolute,
                a_deg,
                feed_deg_per_min,
            } => write!(
                f,
                "{} G1 A{a_deg:.4} F{feed_deg_per_min:.3}",
                if *absolute { "G90" } else { "G91" }
            ),
            Command::Jog {
                a_deg,
                feed_deg_per_min,
            } => write!(f, "$J=G91 A{a_deg:.4} F{feed_deg_per_min:.3}"),
            Command::ZeroA => f.write_str("G92 A0"),
        }
    }
}

/// Parses a line as the simulator receives it. `None` when outside the subset.
pub fn parse_command(line: &str) -> Option<Command> {
    let line = line.trim();
    let num = |s: &str| s.parse::<f64>().ok().filter(|v| v.is_finite());
    if let Some((key, value)) = line.strip_prefix('$').and_then(|s| s.split_once('=')) {
        return match key {
            "103" => Some(Command::StepsPerDeg(num(value)?)),
            "113" => Some(Command::MaxRate(num(value)?)),
            "123" => Some(Command::Accel(num(value)?)),
            "133" => Some(Command::MaxTravel(num(value)?)),
            "376" => Some(Command::RotaryMask(value.parse().ok()?)),
            "J" => {
                let (absolute, a, f) = words(value)?;
                if absolute != Some(false) {
                    return None;
                }
                Some(Command::Jog {
                    a_deg: a?,
                    feed_deg_per_min: f?,
                })
            }
            _ => None,
        };
    }
    if line == "G92 A0" {
        return Some(Command::ZeroA);
    }
    let (absolute, a, f) = words(line)?;
    Some(Command::Move {
        absolute: absolute.unwrap_or(true),
        a_deg: a?,
        feed_deg_per_min: f?,
    })
}

/// The G90/G91 mode, A word and F word of a motion line; `None` on any other word.
fn words(text: &str) -> Option<(Option<bool>, Option<f64>, Option<f64>)> {
    let (mut absolute, mut a, mut f) = (None, None, None);
    for w in text.split_whitespace() {
        let num = |s: &str| s.parse::<f64>().ok().filter(|v| v.is_finite());
        match w {
            "G90" => absolute = Some(true),
            "G91" => absolute = Some(false),
            "G1" | "G01" => {}
            _ => {
                if let Some(v) = w.strip_prefix('A') {
                    a = Some(num(v)?);
                } else if let Some(v) = w.strip_prefix('F') {
                    f = Some(num(v)?);
                } else {
                    return None;
                }
            }
        }
    }
    Some((absolute, a, f))
}

/// Machine state in a status report.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum State {
    /// At rest.
    Idle,
    /// Executing a motion line.
    Run,
    /// Jogging.
    Jog,
    /// Feed hold.
    Hold,
    /// Alarm.
    Alarm,
    /// Any other state (`Door`, `Check`, `Home`, `Sleep`).
    Other,
}

/// A parsed line from the controller.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum Line {
    /// `ok`.
    Ok,
    /// `error:N`.
    Error(u16),
    /// `ALARM:N`.
    Alarm(u16),
    /// `<State|MPos:…|…>`.
    Status {
        /// The state.
        state: State,
        /// A-axis machine position, degrees (the fourth MPos field).
        a_deg: f64,
    },
    /// `[MSG:…]` and other bracketed push messages.
    Message(String),
    /// The start-up banner (`Grbl 1.1h ['$' for help]`).
    Banner,
}

/// Why a controller line was rejected.
#[derive(Debug, Clone, PartialEq, Eq)]
#[non_exhaustive]
pub enum LineError {
    /// Does not follow the grammar.
    Malformed(&'static str),
}

/// Parses one line (without its line end).
pub fn parse_line(line: &[u8]) -> Result<Line, LineError> {
    let text = std::str::from_utf8(line).map_err(|_| LineError::Malformed("not UTF-8"))?;
    let text = text.trim();
    if text == "ok" {
        return Ok(Line::Ok);
    }
    if let Some(n) = text.strip_prefix("error:") {
        return n
            .parse()
            .map(Line::Error)
            .map_err(|_| LineError::Malformed("error code is not a number"));
    }
    if let Some(n) = text.strip_prefix("ALARM:") {
        return n
            .parse()
            .map(Line::Alarm)
            .map_err(|_| LineError::Malformed("alarm code is not a number"));
    }
    if text.starts_with("Grbl ") || text.starts_with("GrblHAL ") {
        return Ok(Line::Banner);
    }
    if let Some(inner) = text.strip_prefix('[').and_then(|t| t.strip_suffix(']')) {
        return Ok(Line::Message(inner.to_string()));
    }
    let inner = text
        .strip_prefix('<')
        .and_then(|t| t.strip_suffix('>'))
        .ok_or(LineError::Malformed("unknown line"))?;
    let mut fields = inner.split('|');
    let state = match fields.next().and_then(|s| s.split(':').next()) {
        Some("Idle") => State::Idle,
        Some("Run") => State::Run,
        Some("Jog") => State::Jog,
        Some("Hold") => State::Hold,
        Some("Alarm") => State::Alarm,
        Some("Door" | "Check" | "Home" | "Sleep") => State::Other,
        _ => return Err(LineError::Malformed("unknown state")),
    };
    let mpos = fields
        .find_map(|f| f.strip_prefix("MPos:"))
        .ok_or(LineError::Malformed("no MPos field"))?;
    let a_deg = mpos
        .split(',')
        .nth(3)
        .ok_or(LineError::Malformed("MPos has no A axis"))?
        .parse::<f64>()
        .ok()
        .filter(|v| v.is_finite())
        .ok_or(LineError::Malformed("A position is not a number"))?;
    Ok(Line::Status { state, a_deg })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn lines() {
        assert_eq!(parse_line(b"ok"), Ok(Line::Ok));
        assert_eq!(parse_line(b"error:20"), Ok(Line::Error(20)));
        assert_eq!(parse_line(b"ALARM:1"), Ok(Line::Alarm(1)));
        assert_eq!(
            parse_line(b"<Run|MPos:0.000,0.000,0.000,90.250|FS:500,0>"),
            Ok(Line::Status {
                state: State::Run,
                a_deg: 90.25
            })
        );
        // GRBL 1.1's other machine states (its interface document): Alarm is its own, the
        // door, check mode, homing and sleep are "other"; sub-states after ':' are ignored.
        assert_eq!(
            parse_line(b"<Alarm|MPos:0.000,0.000,0.000,-12.500|FS:0,0>"),
            Ok(Line::Status {
                state: State::Alarm,
                a_deg: -12.5
            })
        );
        for other in ["Door:1", "Check", "Home", "Sleep"] {
            let line = format!("<{other}|MPos:0.000,0.000,0.000,1.000|FS:0,0>");
            assert_eq!(
                parse_line(line.as_bytes()),
                Ok(Line::Status {
                    state: State::Other,
                    a_deg: 1.0
                }),
                "{line}"
            );
        }
        assert!(parse_line(b"<Tool|MPos:0,0,0,0>").is_err());
        assert_eq!(parse_line(b"Grbl 1.1h ['$' for help]"), Ok(Line::Banner));
        assert!(parse_line(b"<Idle|MPos:0,0,0>").is_err());
        assert!(parse_line(b"<Idle|MPos:0,0,0,nan>").is_err());
        assert!(parse_line(b"okay").is_err());
    }

    #[test]
    fn commands_round_trip() {
        for c in [
            Command::StepsPerDeg(5.1282),
            Command::MaxRate(21600.0),
            Command::Accel(360.0),
            Command::RotaryMask(8),
            Command::MaxTravel(0.0),
            Command::Move {
                absolute: true,
                a_deg: 360.0,
                feed_deg_per_min: 10800.0,
            },
            Command::Move {
                absolute: false,
                a_deg: -12.5,
                feed_deg_per_min: 600.0,
            },
            Command::Jog {
                a_deg: 1.0e6,
                feed_deg_per_min: 3600.0,
            },
            Command::ZeroA,
        ] {
            assert_eq!(parse_command(&c.to_string()), Some(c.clone()), "{c}");
        }
        assert_eq!(
            Command::Move {
                absolute: true,
                a_deg: 360.0,
                feed_deg_per_min: 21600.0
            }
            .to_string(),
            "G90 G1 A360.0000 F21600.000"
        );
        assert_eq!(parse_command("G1 X10"), None);
    }

    proptest! {
        #[test]
        fn line_parser_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..64)) {
            let _ = parse_line(&bytes);
        }

        #[test]
        fn command_parser_never_panics(s in "\\PC{0,32}") {
            let _ = parse_command(&s);
        }
    }
}
