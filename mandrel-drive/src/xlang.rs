//! The Compumotor X-language subset (docs/mandrel-drive.md; OEM Series Software Reference
//! Guide, 88-013785-01 C): typed commands, their text, and reply parsing.
//!
//! A command is `<a>CMD<args>` ended by CR, `a` the device address 1–255 (absent = every unit).
//! With echo on, the unit echoes each byte; status replies are `*payload` CR, with a 3-digit
//! device ID after the `*` when `SSD1` is set.

use std::fmt;

use crate::error::Error;
use crate::profile::Profile;
use crate::units::Drive;

/// `A`'s range, motor rev/s² (OEM guide: 0.01–999.00).
pub const ACCEL_RANGE_MOTOR_RPS2: (f64, f64) = (0.01, 999.0);
/// `V`'s range for a preset move, motor rev/s (OEM guide: 0.01–50.00).
pub const VELOCITY_RANGE_MOTOR_RPS: (f64, f64) = (0.01, 50.0);

/// The `A` and `V` a mandrel profile is sent as on `drive` (motor rev/s², motor rev/s): the
/// profile's own checks ([`Profile::validate`]: signs, order, the translator's pulse limit), then
/// the guide's ranges. Every place that sends or admits a profile asks this one function, so what
/// the pre-run check passes is what the indexer takes.
pub fn accel_and_velocity(p: &Profile, drive: &Drive) -> crate::error::Result<(f64, f64)> {
    p.validate(drive)?;
    let accel = in_range(
        "accel (motor rev/s²)",
        drive.motor_rps(p.accel_rps2),
        ACCEL_RANGE_MOTOR_RPS2,
        "0.01–999.00",
    )?;
    let velocity = in_range(
        "velocity (motor rev/s)",
        drive.motor_rps(p.max_rps),
        VELOCITY_RANGE_MOTOR_RPS,
        "0.01–50.00",
    )?;
    Ok((accel, velocity))
}

/// `value` if finite and within `lo..=hi`, else [`Error::OutOfRange`] naming it.
pub fn in_range(
    name: &'static str,
    value: f64,
    (lo, hi): (f64, f64),
    expected: &'static str,
) -> crate::error::Result<f64> {
    if value.is_finite() && (lo..=hi).contains(&value) {
        Ok(value)
    } else {
        Err(Error::OutOfRange {
            name,
            value,
            expected,
        })
    }
}

/// One X-language command.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum Command {
    /// `A`: acceleration, motor rev/s² (0.01–999.00).
    Accel(f64),
    /// `V`: velocity, motor rev/s (0.01–50.00; `V0` stops a continuous run).
    Velocity(f64),
    /// `VS`: start/stop velocity, motor rev/s. **Simulator extension**, not in the OEM guide;
    /// the client sends it only when the configuration says the backend has it.
    StartVelocity(f64),
    /// `D`: distance (MPI) or absolute target (MPA), steps.
    Distance(i64),
    /// `G`: execute the move.
    Go,
    /// `MN`: preset (normal) mode.
    Preset,
    /// `MC`: continuous mode.
    Continuous,
    /// `MPA`: absolute positioning.
    Absolute,
    /// `MPI`: incremental positioning.
    Incremental,
    /// `H+` (`Some(true)`), `H-` (`Some(false)`), `H` (toggle, `None`): direction.
    Direction(Option<bool>),
    /// `MR`: motor resolution, steps/rev.
    Resolution(u32),
    /// `L`: loop start, count (0 = forever).
    Loop(u16),
    /// `N`: loop end.
    EndLoop,
    /// `S`: stop with deceleration (immediate).
    Stop,
    /// `K`: kill, no deceleration (immediate).
    Kill,
    /// `Z`: reset to power-up, busy for 1000 ms (immediate).
    Reset,
    /// `R`: ready/busy status (immediate).
    Status,
    /// `RA`: limit status (immediate).
    LimitStatus,
    /// `PR`: absolute position, reported when the buffer reaches it.
    Position,
    /// `W3`: steps since the start of the move, hex two's complement (immediate).
    MoveSteps,
    /// `PZ`: zero the absolute counter.
    Zero,
    /// `CR`: send CR LF when reached (the move-complete notification after `G`).
    Notify,
    /// `LD`: limit-switch disable (0 both enabled … 3 both disabled).
    LimitDisable(u8),
    /// `SSA0`/`SSA1`: echo on/off.
    Echo(bool),
    /// `SSD0`/`SSD1`: device-ID prefix on replies off/on.
    DeviceId(bool),
    /// `TR`: wait for a trigger pattern (`1`, `0`, `X` per trigger).
    Trigger(String),
}

impl Command {
    /// True when the unit answers with a `*` line.
    pub fn expects_reply(&self) -> bool {
        matches!(
            self,
            Command::Status | Command::LimitStatus | Command::Position | Command::MoveSteps
        )
    }

    /// True for commands the unit executes at once instead of buffering.
    pub fn is_immediate(&self) -> bool {
        matches!(
            self,
            Command::Stop
                | Command::Kill
                | Command::Reset
                | Command::Status
                | Command::LimitStatus
                | Command::MoveSteps
        )
    }
}

impl fmt::Display for Command {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Command::Accel(v) => write!(f, "A{v:.2}"),
            Command::Velocity(v) => write!(f, "V{v:.2}"),
            Command::StartVelocity(v) => write!(f, "VS{v:.2}"),
            Command::Distance(d) => write!(f, "D{d}"),
            Command::Go => f.write_str("G"),
            Command::Preset => f.write_str("MN"),
            Command::Continuous => f.write_str("MC"),
            Command::Absolute => f.write_str("MPA"),
            Command::Incremental => f.write_str("MPI"),
            Command::Direction(Some(true)) => f.write_str("H+"),
            Command::Direction(Some(false)) => f.write_str("H-"),
            Command::Direction(None) => f.write_str("H"),
            Command::Resolution(r) => write!(f, "MR{r}"),
            Command::Loop(n) => write!(f, "L{n}"),
            Command::EndLoop => f.write_str("N"),
            Command::Stop => f.write_str("S"),
            Command::Kill => f.write_str("K"),
            Command::Reset => f.write_str("Z"),
            Command::Status => f.write_str("R"),
            Command::LimitStatus => f.write_str("RA"),
            Command::Position => f.write_str("PR"),
            Command::MoveSteps => f.write_str("W3"),
            Command::Zero => f.write_str("PZ"),
            Command::Notify => f.write_str("CR"),
            Command::LimitDisable(n) => write!(f, "LD{n}"),
            Command::Echo(on) => write!(f, "SSA{}", if *on { 0 } else { 1 }),
            Command::DeviceId(on) => write!(f, "SSD{}", u8::from(*on)),
            Command::Trigger(p) => write!(f, "TR{p}"),
        }
    }
}

/// The wire text of `cmd` to device `address` (without the CR).
pub fn encode(address: Option<u8>, cmd: &Command) -> String {
    match address {
        Some(a) => format!("{a}{cmd}"),
        None => cmd.to_string(),
    }
}

/// Parses one command token (as the simulator receives it): address digits, then the command.
/// `None` for anything not in the subset.
pub fn parse_command(token: &str) -> Option<(Option<u8>, Command)> {
    let digits = token.bytes().take_while(u8::is_ascii_digit).count();
    let (addr, body) = token.split_at(digits);
    let address = if addr.is_empty() {
        None
    } else {
        Some(addr.parse::<u8>().ok()?)
    };
    let num = |s: &str| s.parse::<f64>().ok().filter(|v| v.is_finite());
    let cmd = match body {
        "G" => Command::Go,
        "MN" => Command::Preset,
        "MC" => Command::Continuous,
        "MPA" => Command::Absolute,
        "MPI" => Command::Incremental,
        "H+" => Command::Direction(Some(true)),
        "H-" => Command::Direction(Some(false)),
        "H" => Command::Direction(None),
        "N" => Command::EndLoop,
        "L" => Command::Loop(0),
        "S" => Command::Stop,
        "K" => Command::Kill,
        "Z" => Command::Reset,
        "R" => Command::Status,
        "RA" => Command::LimitStatus,
        "PR" => Command::Position,
        "W3" => Command::MoveSteps,
        "PZ" => Command::Zero,
        "CR" => Command::Notify,
        "SSA0" => Command::Echo(true),
        "SSA1" => Command::Echo(false),
        "SSD0" => Command::DeviceId(false),
        "SSD1" => Command::DeviceId(true),
        _ => {
            if let Some(v) = body.strip_prefix("VS") {
                Command::StartVelocity(num(v)?)
            } else if let Some(v) = body.strip_prefix('V') {
                Command::Velocity(num(v)?)
            } else if let Some(v) = body.strip_prefix('A') {
                Command::Accel(num(v)?)
            } else if let Some(v) = body.strip_prefix('D') {
                Command::Distance(v.parse().ok()?)
            } else if let Some(v) = body.strip_prefix("MR") {
                Command::Resolution(v.parse().ok()?)
            } else if let Some(v) = body.strip_prefix("LD") {
                Command::LimitDisable(v.parse().ok().filter(|n| *n <= 3)?)
            } else if let Some(v) = body.strip_prefix("TR") {
                if v.is_empty() || !v.bytes().all(|b| matches!(b, b'0' | b'1' | b'X' | b'x')) {
                    return None;
                }
                Command::Trigger(v.to_string())
            } else if let Some(v) = body.strip_prefix('L') {
                Command::Loop(v.parse().ok()?)
            } else {
                return None;
            }
        }
    };
    Some((address, cmd))
}

/// A parsed status reply.
#[derive(Debug, Clone, PartialEq, Eq)]
#[non_exhaustive]
pub enum Reply {
    /// `R`: `*R` ready, `*S` ready + attention, `*B` busy, `*C` busy + attention.
    Status {
        /// Busy (moving, or resetting).
        busy: bool,
        /// Attention: a fault (our simulator: a stall, or a refused move).
        attention: bool,
    },
    /// `RA`: the limit character (`@` = none).
    Limits(char),
    /// `PR`: absolute position, steps.
    Position(i64),
    /// `W3`: steps since the start of the move (hex two's complement on the wire).
    MoveSteps(i64),
}

/// Why a reply line was rejected.
#[derive(Debug, Clone, PartialEq, Eq)]
#[non_exhaustive]
pub enum ReplyError {
    /// Not of the form the command expects.
    Malformed(&'static str),
    /// The device-ID prefix names another device.
    WrongAddress {
        /// Expected device.
        expected: u8,
        /// Device in the reply.
        got: u16,
    },
    /// The controller refused the command (`?…`, our simulator's convention).
    Refused(String),
}

/// Parses a reply line (without its CR) to `cmd`. With `device_id` set, the payload must start
/// with that 3-digit device ID (`SSD1`).
pub fn parse_reply(cmd: &Command, line: &[u8], device_id: Option<u8>) -> Result<Reply, ReplyError> {
    if let Some(rest) = line.strip_prefix(b"?") {
        return Err(ReplyError::Refused(
            String::from_utf8_lossy(rest).into_owned(),
        ));
    }
    let mut payload = line
        .strip_prefix(b"*")
        .ok_or(ReplyError::Malformed("reply does not start with '*'"))?;
    if let Some(expected) = device_id {
        let (id, rest) = payload
            .split_at_checked(3)
            .ok_or(ReplyError::Malformed("truncated device id"))?;
        if !id.iter().all(u8::is_ascii_digit) {
            return Err(ReplyError::Malformed("device id is not 3 digits"));
        }
        let got = id.iter().fold(0u16, |n, d| n * 10 + u16::from(d - b'0'));
        if got != u16::from(expected) {
            return Err(ReplyError::WrongAddress { expected, got });
        }
        payload = rest;
    }
    match cmd {
        Command::Status => match payload {
            b"R" => Ok(Reply::Status {
                busy: false,
                attention: false,
            }),
            b"S" => Ok(Reply::Status {
                busy: false,
                attention: true,
            }),
            b"B" => Ok(Reply::Status {
                busy: true,
                attention: false,
            }),
            b"C" => Ok(Reply::Status {
                busy: true,
                attention: true,
            }),
            _ => Err(ReplyError::Malformed("status is not one of R, S, B, C")),
        },
        Command::LimitStatus => match payload {
            [c] if c.is_ascii_graphic() => Ok(Reply::Limits(char::from(*c))),
            _ => Err(ReplyError::Malformed("limit status is not one character")),
        },
        Command::Position => {
            let (sign, digits) = match payload {
                [b'+', d @ ..] => (1i64, d),
                [b'-', d @ ..] => (-1i64, d),
                _ => return Err(ReplyError::Malformed("position has no sign")),
            };
            if digits.len() != 10 || !digits.iter().all(u8::is_ascii_digit) {
                return Err(ReplyError::Malformed("position is not 10 digits"));
            }
            let n = digits
                .iter()
                .fold(0i64, |n, d| n * 10 + i64::from(d - b'0'));
            Ok(Reply::Position(sign * n))
        }
        Command::MoveSteps => {
            if payload.len() != 8 || !payload.iter().all(u8::is_ascii_hexdigit) {
                return Err(ReplyError::Malformed("W3 is not 8 hex digits"));
            }
            let text = std::str::from_utf8(payload)
                .map_err(|_| ReplyError::Malformed("W3 is not ASCII"))?;
            let raw = u32::from_str_radix(text, 16)
                .map_err(|_| ReplyError::Malformed("W3 is not hex"))?;
            Ok(Reply::MoveSteps(i64::from(raw as i32)))
        }
        _ => Err(ReplyError::Malformed("command has no reply")),
    }
}

/// Formats a `PR` payload (`+0000002000`).
pub fn format_position(steps: i64) -> String {
    let sign = if steps < 0 { '-' } else { '+' };
    format!("{sign}{:010}", steps.unsigned_abs().min(9_999_999_999))
}

/// Formats a `W3` payload (`FFFF9E58` for −25 000).
pub fn format_move_steps(steps: i64) -> String {
    format!("{:08X}", steps as i32 as u32)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Commands of the subset the language spells without a number (docs: spec's X-language
    /// table): a bare `L` loops forever like `L0`, `SSD0` turns the device-ID prefix off, and a
    /// `TR` without its pattern of 0, 1 and X is not a command.
    #[test]
    fn bare_and_switch_commands_parse() {
        assert_eq!(parse_command("L"), Some((None, Command::Loop(0))));
        assert_eq!(parse_command("1L"), Some((Some(1), Command::Loop(0))));
        assert_eq!(parse_command("L0"), Some((None, Command::Loop(0))));
        assert_eq!(
            parse_command("SSD0"),
            Some((None, Command::DeviceId(false)))
        );
        assert_eq!(parse_command("SSD1"), Some((None, Command::DeviceId(true))));
        assert_eq!(parse_command("TR"), None);
        assert_eq!(parse_command("TR12"), None);
        assert_eq!(
            parse_command("1TR1X"),
            Some((Some(1), Command::Trigger("1X".into())))
        );
    }

    /// `*S` is ready with attention; a device ID is read as a decimal number of three digits;
    /// a limit status is one printable character, not a control character or a space.
    #[test]
    fn attention_device_ids_and_limit_characters() {
        assert_eq!(
            parse_reply(&Command::Status, b"*S", None),
            Ok(Reply::Status {
                busy: false,
                attention: true
            })
        );
        assert_eq!(
            parse_reply(&Command::Status, b"*C", None),
            Ok(Reply::Status {
                busy: true,
                attention: true
            })
        );
        assert_eq!(
            parse_reply(&Command::Status, b"*123R", Some(123)),
            Ok(Reply::Status {
                busy: false,
                attention: false
            })
        );
        assert_eq!(
            parse_reply(&Command::Status, b"*012R", Some(13)),
            Err(ReplyError::WrongAddress {
                expected: 13,
                got: 12
            })
        );
        // W3 is exactly eight hex digits: fewer or more is not a count.
        for bad in [&b"*FFFF"[..], b"*0FFFF9E58"] {
            assert_eq!(
                parse_reply(&Command::MoveSteps, bad, None),
                Err(ReplyError::Malformed("W3 is not 8 hex digits"))
            );
        }
        for bad in [&b"* "[..], b"*\x07", b"*\x7F"] {
            assert!(
                matches!(
                    parse_reply(&Command::LimitStatus, bad, None),
                    Err(ReplyError::Malformed(_))
                ),
                "{bad:?}"
            );
        }
    }

    #[test]
    fn golden_replies() {
        assert_eq!(
            parse_reply(&Command::Status, b"*R", None),
            Ok(Reply::Status {
                busy: false,
                attention: false
            })
        );
        assert_eq!(
            parse_reply(&Command::Status, b"*B", None),
            Ok(Reply::Status {
                busy: true,
                attention: false
            })
        );
        // '*' '+' then ten digits 0000002000
        assert_eq!(
            parse_reply(&Command::Position, b"*+0000002000", None),
            Ok(Reply::Position(2000))
        );
        // 0xFFFF9E58 as i32 = -25 000
        assert_eq!(
            parse_reply(&Command::MoveSteps, b"*FFFF9E58", None),
            Ok(Reply::MoveSteps(-25_000))
        );
        assert_eq!(
            parse_reply(&Command::LimitStatus, b"*@", None),
            Ok(Reply::Limits('@'))
        );
        // SSD1: '*' then device id 001 then 'R'
        assert_eq!(
            parse_reply(&Command::Status, b"*001R", Some(1)),
            Ok(Reply::Status {
                busy: false,
                attention: false
            })
        );
        assert_eq!(format_position(2000), "+0000002000");
        assert_eq!(format_move_steps(-25_000), "FFFF9E58");
    }

    #[test]
    fn bad_replies() {
        assert_eq!(
            parse_reply(&Command::Status, b"*002R", Some(1)),
            Err(ReplyError::WrongAddress {
                expected: 1,
                got: 2
            })
        );
        assert!(matches!(
            parse_reply(&Command::Status, b"*00", Some(1)),
            Err(ReplyError::Malformed(_))
        ));
        assert!(matches!(
            parse_reply(&Command::Position, b"*+00002", None),
            Err(ReplyError::Malformed(_))
        ));
        assert!(matches!(
            parse_reply(&Command::MoveSteps, b"*FFFF9E5G", None),
            Err(ReplyError::Malformed(_))
        ));
        assert!(matches!(
            parse_reply(&Command::Status, b"\xff\x00", None),
            Err(ReplyError::Malformed(_))
        ));
        assert!(matches!(
            parse_reply(&Command::Status, b"?limit", None),
            Err(ReplyError::Refused(_))
        ));
    }

    #[test]
    fn command_text_round_trips() {
        for c in [
            Command::Accel(12.5),
            Command::Velocity(4.62),
            Command::StartVelocity(0.5),
            Command::Distance(-1846),
            Command::Go,
            Command::Preset,
            Command::Continuous,
            Command::Absolute,
            Command::Incremental,
            Command::Direction(Some(true)),
            Command::Direction(Some(false)),
            Command::Direction(None),
            Command::Resolution(400),
            Command::Loop(3),
            Command::EndLoop,
            Command::Stop,
            Command::Kill,
            Command::Reset,
            Command::Status,
            Command::LimitStatus,
            Command::Position,
            Command::MoveSteps,
            Command::Zero,
            Command::Notify,
            Command::LimitDisable(3),
            Command::Echo(false),
            Command::DeviceId(true),
            Command::Trigger("1XX".into()),
        ] {
            let text = encode(Some(1), &c);
            assert_eq!(parse_command(&text), Some((Some(1), c.clone())), "{text}");
        }
        assert_eq!(encode(Some(1), &Command::Distance(1846)), "1D1846");
        assert_eq!(parse_command("1Q"), None);
    }

    proptest! {
        #[test]
        fn reply_parser_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..24), id in proptest::option::of(any::<u8>())) {
            for cmd in [Command::Status, Command::LimitStatus, Command::Position, Command::MoveSteps, Command::Go] {
                let _ = parse_reply(&cmd, &bytes, id);
            }
        }

        #[test]
        fn command_parser_never_panics(s in "\\PC{0,12}") {
            let _ = parse_command(&s);
        }

        #[test]
        fn position_round_trips(n in -9_999_999_999i64..=9_999_999_999) {
            let line = format!("*{}", format_position(n));
            prop_assert_eq!(parse_reply(&Command::Position, line.as_bytes(), None), Ok(Reply::Position(n)));
        }

        #[test]
        fn move_steps_round_trips(n in any::<i32>()) {
            let line = format!("*{}", format_move_steps(i64::from(n)));
            prop_assert_eq!(parse_reply(&Command::MoveSteps, line.as_bytes(), None), Ok(Reply::MoveSteps(i64::from(n))));
        }
    }
}
