//! Typed telegrams and their scales (seed 001 §5.2, §5.4; docs/protocol.md §4, §5 with the
//! corrections in its header).
//!
//! Codes 0x01–0x07 are those of spec §5.7. Codes 0x08–0x0D add what the thesis names and §5.7
//! lacks: immediate (discrete-mode) positioning, stored control instructions, base and maximum
//! speed, stop, and reading a stored instruction back. Codes 0x10–0x2F are reserved for the rest
//! of the thesis' 26 commands. Replies set bit 7 of the command code. The thesis does not number
//! its commands, so [`CommandInfo::thesis_command_no`] is `None` throughout until a source does.

use crate::error::{EncodeError, ParseError};
use crate::frame::{self, Frame, FrameConfig};

/// Millimetres per LSB of x, y, z (seed 001 §5.4.1: "a scale factor of 0.0625").
pub const LENGTH_MM_PER_LSB: f64 = 0.0625;
/// Speed units per LSB (seed 001 §5.4.1: "a scale factor of 1/8192 for the speed input values").
pub const SPEED_PER_LSB: f64 = 1.0 / 8192.0;
/// Quaternion component per LSB: Q1.14 (ours; the thesis gives no scale).
pub const QUATERNION_PER_LSB: f64 = 1.0 / 16384.0;
/// The robot refuses a stored quaternion whose norm differs from 1 by more than this.
pub const QUATERNION_NORM_TOLERANCE: f64 = 0.01;
/// Number of robot output lines and input lines (seed 001 §4.1.2: "six inputs/outputs").
pub const IO_LINES: u8 = 6;

// The robot computer's facts that a host program must respect (its memory and its I/O
// assignment, seed 001 §4.1.2, App. D): the simulator in `crate::sim` models them, and the host
// side (transfer, coordinator) plans against them, both from here.

/// Memory units of the robot computer's program store. With [`POSITION_UNITS`] and
/// [`CONTROL_UNITS`] it holds exactly 470 positioning instructions, or 300 positioning and 200
/// control instructions (seed 001 §4.1.2: 6 KB).
pub const MEMORY_UNITS: u32 = 9400;
/// Memory units of one positioning instruction.
pub const POSITION_UNITS: u32 = 20;
/// Memory units of one control instruction.
pub const CONTROL_UNITS: u32 = 17;
/// The output line that tells the PC "in position" (seed 001 App. D, §5.6.4 steps 10–11): raised at
/// the end of a discrete move, and by a winding program only at its last point. A program run
/// lowers it first; STOP leaves it low.
pub const IN_POSITION_OUTPUT: u8 = 1;
/// The input line on which the PC's "start" reaches the robot (seed 001 App. D: one opto-isolated
/// signal to the robot computer and the mandrel driver together). A winding program waits on it.
pub const START_INPUT: u8 = 1;
/// Interpretation time of a flying move of a stored program, per zone (fine, medium, coarse), s.
/// Seed 001 App. B: the fastest windings of the 50-segment cylinder paths that still kept the
/// path ran fine at 0.20 rev/s (10.0 s, 0.20 s per instruction) and medium at 0.30 rev/s (6.7 s,
/// 0.134 s per instruction); fine asks the servos to come within 1 mm before the next instruction
/// is taken, so it needs more time per instruction. Coarse is not used for winding (§5.4.2); ours.
pub const INTERPRETATION_S: [f64; 3] = [0.20, 0.13, 0.10];

fn out_of_range(name: &'static str, value: f64, expected: &'static str) -> EncodeError {
    EncodeError::OutOfRange {
        name,
        value,
        expected,
    }
}

/// A Cartesian coordinate on the wire: i16 at 0.0625 mm per LSB, ±2047.9375 mm (`docs/protocol.md` §4
/// "Field encodings": the range is symmetric, so the raw value −32768 is refused).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct Length(pub i16);

impl Length {
    /// Rounds `mm` to the nearest LSB; outside the range (or not finite) is an error.
    pub fn from_mm(name: &'static str, mm: f64) -> Result<Self, EncodeError> {
        let raw = (mm / LENGTH_MM_PER_LSB).round();
        if !(-f64::from(i16::MAX)..=f64::from(i16::MAX)).contains(&raw) {
            return Err(out_of_range(name, mm, "-2047.9375 to 2047.9375 mm"));
        }
        Ok(Length(raw as i16))
    }
    /// True when the raw value lies in the wire range ±2047.9375 mm (`docs/protocol.md` §4 "Field encodings");
    /// −32768 (−2048.0 mm) is outside it.
    pub fn in_range(self) -> bool {
        self.0 != i16::MIN
    }
    /// Millimetres.
    pub fn mm(self) -> f64 {
        f64::from(self.0) * LENGTH_MM_PER_LSB
    }
}

/// A speed value on the wire: u16 at 1/8192 per LSB (0 to 7.99988).
///
/// In a positioning instruction it is the fraction of the base speed (seed 001 §5.4.1: "given as
/// a percentage of the specified base velocity"; 8192 = 100 %). Base and maximum speed are in m/s
/// (our reading; the thesis names no unit), so 8192 = 1 m/s.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct Speed(pub u16);

impl Speed {
    /// Rounds `value` to the nearest LSB; negative, too large or not finite is an error.
    pub fn from_value(name: &'static str, value: f64) -> Result<Self, EncodeError> {
        let raw = (value / SPEED_PER_LSB).round();
        if !(0.0..=f64::from(u16::MAX)).contains(&raw) {
            return Err(out_of_range(name, value, "0 to 7.99988 (1/8192 per LSB)"));
        }
        Ok(Speed(raw as u16))
    }
    /// The value (raw / 8192).
    pub fn value(self) -> f64 {
        f64::from(self.0) * SPEED_PER_LSB
    }
}

/// A wrist orientation quaternion on the wire, scalar first (q1 = w, then x, y, z; the ABB
/// convention), each component i16 Q1.14.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Quaternion(pub [i16; 4]);

impl Default for Quaternion {
    fn default() -> Self {
        Quaternion::IDENTITY
    }
}

impl Quaternion {
    /// No rotation.
    pub const IDENTITY: Quaternion = Quaternion([16384, 0, 0, 0]);

    /// Normalises (w, x, y, z), chooses the sign with w ≥ 0 (determinism), and quantises.
    pub fn from_wxyz(w: f64, x: f64, y: f64, z: f64) -> Result<Self, EncodeError> {
        let n = (w * w + x * x + y * y + z * z).sqrt();
        if !n.is_finite() || n < 1e-9 {
            return Err(EncodeError::DegenerateQuaternion(w, x, y, z));
        }
        let s = if w < 0.0 { -1.0 / n } else { 1.0 / n };
        let q = |v: f64| {
            ((v * s) / QUATERNION_PER_LSB)
                .round()
                .clamp(-16384.0, 16384.0) as i16
        };
        Ok(Quaternion([q(w), q(x), q(y), q(z)]))
    }
    /// Components (w, x, y, z) as numbers.
    pub fn wxyz(self) -> [f64; 4] {
        self.0.map(|c| f64::from(c) * QUATERNION_PER_LSB)
    }
    /// |‖q‖ − 1|.
    pub fn norm_error(self) -> f64 {
        let n2: f64 = self.wxyz().iter().map(|c| c * c).sum();
        (n2.sqrt() - 1.0).abs()
    }
}

/// Path interpolation (seed 001 §5.4, spec §5.6 flags bit 0).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Interpolation {
    /// A straight tool-centre-point path ("rectangular").
    #[default]
    Rectangular,
    /// Joint ("robot") interpolation.
    Joint,
}

/// How coordinates are read (flags bit 1; seed 001 §5.3.2 "absolute or relative terms").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Reference {
    /// Absolute, in the robot base frame.
    #[default]
    Absolute,
    /// Relative to the previous point.
    Relative,
}

/// Accuracy zone (seed 001 §5.4.2; flags bits 2–3 in the thesis meaning of the corrections).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Zone {
    /// Pass within 1 mm of the point.
    #[default]
    Fine,
    /// Pass within 10 mm of the point.
    Medium,
    /// Beyond 10 mm (not used for winding); the simulator uses 25 mm.
    Coarse,
}

impl Zone {
    /// Zone radius in millimetres.
    pub fn radius_mm(self) -> f64 {
        match self {
            Zone::Fine => 1.0,
            Zone::Medium => 10.0,
            Zone::Coarse => 25.0,
        }
    }
}

/// The flags byte of a positioning telegram. Bits 4–7 must be zero; zone 3 is reserved.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct Flags {
    /// Bit 0.
    pub interpolation: Interpolation,
    /// Bit 1.
    pub reference: Reference,
    /// Bits 2–3.
    pub zone: Zone,
}

impl Flags {
    /// The wire byte.
    pub fn to_byte(self) -> u8 {
        let i = u8::from(self.interpolation == Interpolation::Joint);
        let r = u8::from(self.reference == Reference::Relative) << 1;
        let z = match self.zone {
            Zone::Fine => 0,
            Zone::Medium => 1,
            Zone::Coarse => 2,
        } << 2;
        i | r | z
    }
    /// Parses the wire byte.
    pub fn from_byte(b: u8) -> Result<Self, ParseError> {
        if b & 0xF0 != 0 {
            return Err(ParseError::Field("flags: bits 4-7 must be zero"));
        }
        let zone = match (b >> 2) & 3 {
            0 => Zone::Fine,
            1 => Zone::Medium,
            2 => Zone::Coarse,
            _ => return Err(ParseError::Field("flags: zone 3 is reserved")),
        };
        Ok(Flags {
            interpolation: if b & 1 != 0 {
                Interpolation::Joint
            } else {
                Interpolation::Rectangular
            },
            reference: if b & 2 != 0 {
                Reference::Relative
            } else {
                Reference::Absolute
            },
            zone,
        })
    }
}

/// A payout-eye pose: x, y, z and the wrist quaternion.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct Pose {
    /// x.
    pub x: Length,
    /// y.
    pub y: Length,
    /// z.
    pub z: Length,
    /// Wrist orientation.
    pub q: Quaternion,
}

impl Pose {
    /// A pose from millimetres and a (w, x, y, z) quaternion; every field range-checked.
    pub fn from_mm(xyz_mm: [f64; 3], q_wxyz: [f64; 4]) -> Result<Self, EncodeError> {
        Ok(Pose {
            x: Length::from_mm("x", xyz_mm[0])?,
            y: Length::from_mm("y", xyz_mm[1])?,
            z: Length::from_mm("z", xyz_mm[2])?,
            q: Quaternion::from_wxyz(q_wxyz[0], q_wxyz[1], q_wxyz[2], q_wxyz[3])?,
        })
    }
    /// (x, y, z) in millimetres.
    pub fn xyz_mm(&self) -> [f64; 3] {
        [self.x.mm(), self.y.mm(), self.z.mm()]
    }
    fn write(&self, out: &mut Vec<u8>) {
        for v in [self.x.0, self.y.0, self.z.0] {
            out.extend_from_slice(&v.to_be_bytes());
        }
        for c in self.q.0 {
            out.extend_from_slice(&c.to_be_bytes());
        }
    }
    fn read(d: &[u8]) -> Result<Pose, ParseError> {
        let w = |i: usize| i16::from_be_bytes([d[2 * i], d[2 * i + 1]]);
        let p = Pose {
            x: Length(w(0)),
            y: Length(w(1)),
            z: Length(w(2)),
            q: Quaternion([w(3), w(4), w(5), w(6)]),
        };
        if ![p.x, p.y, p.z].iter().all(|l| l.in_range()) {
            return Err(ParseError::Field("position outside ±2047.9375 mm"));
        }
        Ok(p)
    }
}

/// A positioning instruction: flags, pose, speed (17 bytes on the wire).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct Positioning {
    /// Interpolation, reference, zone.
    pub flags: Flags,
    /// Target.
    pub pose: Pose,
    /// Fraction of the base speed (1/8192 per LSB).
    pub speed: Speed,
}

const POSITIONING_LEN: usize = 17;

impl Positioning {
    fn write(&self, out: &mut Vec<u8>) {
        out.push(self.flags.to_byte());
        self.pose.write(out);
        out.extend_from_slice(&self.speed.0.to_be_bytes());
    }
    fn read(d: &[u8]) -> Result<Self, ParseError> {
        Ok(Positioning {
            flags: Flags::from_byte(d[0])?,
            pose: Pose::read(&d[1..15])?,
            speed: Speed(u16::from_be_bytes([d[15], d[16]])),
        })
    }
}

/// A control instruction stored in a program (seed 001 §4.1.2, §5.4, App. D).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Control {
    /// Drive output `line` (1–6) to `on`; output 1 tells the PC "in position".
    SetOutput {
        /// Output line, 1–6.
        line: u8,
        /// Level.
        on: bool,
    },
    /// Wait until input `line` (1–6) is `on`; input 1 is the PC's "start".
    WaitInput {
        /// Input line, 1–6.
        line: u8,
        /// Level awaited.
        on: bool,
    },
    /// End of program.
    End,
}

const CONTROL_LEN: usize = 3;

impl Control {
    fn write(&self, out: &mut Vec<u8>) {
        let (op, line, on) = match *self {
            Control::SetOutput { line, on } => (1, line, on),
            Control::WaitInput { line, on } => (2, line, on),
            Control::End => (3, 0, false),
        };
        out.extend_from_slice(&[op, line, u8::from(on)]);
    }
    fn read(d: &[u8]) -> Result<Self, ParseError> {
        let (op, line, level) = (d[0], d[1], d[2]);
        let on = match level {
            0 => false,
            1 => true,
            _ => return Err(ParseError::Field("control: level must be 0 or 1")),
        };
        let line_ok = (1..=IO_LINES).contains(&line);
        match op {
            1 if line_ok => Ok(Control::SetOutput { line, on }),
            2 if line_ok => Ok(Control::WaitInput { line, on }),
            3 if line == 0 && !on => Ok(Control::End),
            1..=3 => Err(ParseError::Field("control: line")),
            _ => Err(ParseError::Field("control: operation")),
        }
    }
}

/// One stored program instruction.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Instruction {
    /// Move.
    Position(Positioning),
    /// Output, input or end.
    Control(Control),
}

/// What ENQUIRE asks for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Selector {
    /// Mode, state, program, instruction, last error, homed.
    Status,
    /// The current pose.
    Position,
}

/// A telegram from the PC to the robot computer.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Command {
    /// 0x01: store positioning instruction `instruction` of `program` (overwrite).
    StorePos {
        /// Program number, 1–255.
        program: u8,
        /// Instruction number, 1–65535.
        instruction: u16,
        /// The instruction.
        positioning: Positioning,
    },
    /// 0x02: run a stored program (OPERATE and homed, or STANDBY for a dry run).
    RunProgram {
        /// Program number.
        program: u8,
    },
    /// 0x03: standby mode (execute without moving the arm: syntax and range check).
    Standby,
    /// 0x04: operate mode.
    Operate,
    /// 0x05: synchronise to the home position.
    SyncHome,
    /// 0x06: ask for status or position; answered in a reverse session (0x86).
    Enquire(Selector),
    /// 0x07: delete a stored program.
    DeleteProgram {
        /// Program number.
        program: u8,
    },
    /// 0x08: discrete-mode positioning, executed at once without storing; stops at the point
    /// (seed 001 §5.4.1). The zone bits must be fine.
    MoveImmediate(Positioning),
    /// 0x09: store a control instruction in a program.
    StoreControl {
        /// Program number.
        program: u8,
        /// Instruction number.
        instruction: u16,
        /// The instruction.
        control: Control,
    },
    /// 0x0A: base speed in m/s (1/8192 per LSB; seed 001 §5.4.1).
    SetBaseSpeed(Speed),
    /// 0x0B: maximum speed in m/s.
    SetMaxSpeed(Speed),
    /// 0x0C: stop motion and any running program.
    Stop,
    /// 0x0D: read a stored instruction back; answered in a reverse session (0x8D).
    ReadBack {
        /// Program number.
        program: u8,
        /// Instruction number.
        instruction: u16,
    },
    /// 0x0E: acknowledge the latched error whose sequence number is `seq` (from the status
    /// reply); the robot clears `last_error` only if `seq` is still the latest error's number,
    /// so a repeated or late acknowledgement never clears a newer error.
    AckError {
        /// [`Status::error_seq`] of the error being acknowledged.
        seq: u8,
    },
    /// 0x0F: how many instructions `program` holds and its highest instruction number, and how
    /// many the whole memory holds; answered in a reverse session (0x8F). After an upload it
    /// shows whether a corrupted twin left an instruction in a slot the upload never wrote.
    ProgramInfo {
        /// Program number.
        program: u8,
    },
}

/// A table row: the code, name, data length and reply of one command.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CommandInfo {
    /// Command code.
    pub code: u8,
    /// Name in docs/protocol.md.
    pub name: &'static str,
    /// LEN.
    pub len: usize,
    /// The reply code, for commands answered in a reverse session.
    pub reply: Option<u8>,
    /// The number in the thesis' list of 26 commands, where known (none is yet).
    pub thesis_command_no: Option<u8>,
}

const fn info(code: u8, name: &'static str, len: usize, reply: Option<u8>) -> CommandInfo {
    CommandInfo {
        code,
        name,
        len,
        reply,
        thesis_command_no: None,
    }
}

/// Every command code.
pub const COMMANDS: [CommandInfo; 15] = [
    info(0x01, "STORE_POS", 20, None),
    info(0x02, "RUN_PROGRAM", 1, None),
    info(0x03, "MODE_STANDBY", 0, None),
    info(0x04, "MODE_OPERATE", 0, None),
    info(0x05, "SYNC_HOME", 0, None),
    info(0x06, "ENQUIRE", 1, Some(REPLY_ENQUIRE)),
    info(0x07, "DELETE_PROGRAM", 1, None),
    info(0x08, "MOVE_IMMEDIATE", 17, None),
    info(0x09, "STORE_CONTROL", 6, None),
    info(0x0A, "SET_BASE_SPEED", 2, None),
    info(0x0B, "SET_MAX_SPEED", 2, None),
    info(0x0C, "STOP", 0, None),
    info(0x0D, "READ_BACK", 3, Some(REPLY_READ_BACK)),
    info(0x0E, "ACK_ERROR", 1, None),
    info(0x0F, "PROGRAM_INFO", 1, Some(REPLY_PROGRAM_INFO)),
];

/// Codes reserved for the thesis commands not yet transcribed.
pub const RESERVED_CODES: std::ops::RangeInclusive<u8> = 0x10..=0x2F;
/// Reply code to ENQUIRE.
pub const REPLY_ENQUIRE: u8 = 0x86;
/// Reply code to READ_BACK.
pub const REPLY_READ_BACK: u8 = 0x8D;
/// Reply code to PROGRAM_INFO.
pub const REPLY_PROGRAM_INFO: u8 = 0x8F;

fn check_prog(p: u8) -> Result<u8, ParseError> {
    if p == 0 {
        Err(ParseError::Field("program number 0"))
    } else {
        Ok(p)
    }
}

fn check_instr(i: u16) -> Result<u16, ParseError> {
    if i == 0 {
        Err(ParseError::Field("instruction number 0"))
    } else {
        Ok(i)
    }
}

impl Command {
    /// The command code.
    pub fn code(&self) -> u8 {
        match self {
            Command::StorePos { .. } => 0x01,
            Command::RunProgram { .. } => 0x02,
            Command::Standby => 0x03,
            Command::Operate => 0x04,
            Command::SyncHome => 0x05,
            Command::Enquire(_) => 0x06,
            Command::DeleteProgram { .. } => 0x07,
            Command::MoveImmediate(_) => 0x08,
            Command::StoreControl { .. } => 0x09,
            Command::SetBaseSpeed(_) => 0x0A,
            Command::SetMaxSpeed(_) => 0x0B,
            Command::Stop => 0x0C,
            Command::ReadBack { .. } => 0x0D,
            Command::AckError { .. } => 0x0E,
            Command::ProgramInfo { .. } => 0x0F,
        }
    }

    /// True if the robot answers in a reverse session.
    pub fn expects_reply(&self) -> bool {
        matches!(
            self,
            Command::Enquire(_) | Command::ReadBack { .. } | Command::ProgramInfo { .. }
        )
    }

    /// Appends the DATA bytes.
    pub fn write_data(&self, out: &mut Vec<u8>) {
        match self {
            Command::StorePos {
                program,
                instruction,
                positioning,
            } => {
                out.push(*program);
                out.extend_from_slice(&instruction.to_be_bytes());
                positioning.write(out);
            }
            Command::RunProgram { program } | Command::DeleteProgram { program } => {
                out.push(*program)
            }
            Command::AckError { seq } => out.push(*seq),
            Command::ProgramInfo { program } => out.push(*program),
            Command::Standby | Command::Operate | Command::SyncHome | Command::Stop => {}
            Command::Enquire(s) => out.push(match s {
                Selector::Status => 0,
                Selector::Position => 1,
            }),
            Command::MoveImmediate(p) => p.write(out),
            Command::StoreControl {
                program,
                instruction,
                control,
            } => {
                out.push(*program);
                out.extend_from_slice(&instruction.to_be_bytes());
                control.write(out);
            }
            Command::SetBaseSpeed(s) | Command::SetMaxSpeed(s) => {
                out.extend_from_slice(&s.0.to_be_bytes())
            }
            Command::ReadBack {
                program,
                instruction,
            } => {
                out.push(*program);
                out.extend_from_slice(&instruction.to_be_bytes());
            }
        }
    }

    /// The framed telegram.
    pub fn encode(&self, cfg: &FrameConfig) -> Result<Vec<u8>, EncodeError> {
        let mut out = Vec::with_capacity(32);
        self.encode_into(cfg, &mut out)?;
        Ok(out)
    }

    /// The telegram before framing: its code and data (the inverse of [`Command::from_frame`]).
    pub fn to_frame(&self) -> Frame {
        let mut data = Vec::with_capacity(24);
        self.write_data(&mut data);
        Frame {
            code: self.code(),
            data,
        }
    }

    /// Appends the framed telegram to `out`.
    pub fn encode_into(&self, cfg: &FrameConfig, out: &mut Vec<u8>) -> Result<(), EncodeError> {
        let mut data = Vec::with_capacity(24);
        self.write_data(&mut data);
        frame::encode_into(cfg, self.code(), &data, out)
    }

    /// Types a received frame.
    pub fn from_frame(f: &Frame) -> Result<Command, ParseError> {
        let d = f.data.as_slice();
        let want = COMMANDS
            .iter()
            .find(|c| c.code == f.code)
            .ok_or(ParseError::UnknownCode(f.code))?
            .len;
        if d.len() != want {
            return Err(ParseError::Length {
                code: f.code,
                expected: want,
                got: d.len(),
            });
        }
        let u16_at = |i: usize| u16::from_be_bytes([d[i], d[i + 1]]);
        Ok(match f.code {
            0x01 => Command::StorePos {
                program: check_prog(d[0])?,
                instruction: check_instr(u16_at(1))?,
                positioning: Positioning::read(&d[3..])?,
            },
            0x02 => Command::RunProgram {
                program: check_prog(d[0])?,
            },
            0x03 => Command::Standby,
            0x04 => Command::Operate,
            0x05 => Command::SyncHome,
            0x06 => Command::Enquire(match d[0] {
                0 => Selector::Status,
                1 => Selector::Position,
                _ => return Err(ParseError::Field("enquire selector")),
            }),
            0x07 => Command::DeleteProgram {
                program: check_prog(d[0])?,
            },
            0x08 => {
                let p = Positioning::read(d)?;
                if p.flags.zone != Zone::Fine {
                    return Err(ParseError::Field("immediate positioning: zone must be 0"));
                }
                Command::MoveImmediate(p)
            }
            0x09 => Command::StoreControl {
                program: check_prog(d[0])?,
                instruction: check_instr(u16_at(1))?,
                control: Control::read(&d[3..])?,
            },
            0x0A => Command::SetBaseSpeed(Speed(u16_at(0))),
            0x0B => Command::SetMaxSpeed(Speed(u16_at(0))),
            0x0C => Command::Stop,
            0x0E => Command::AckError { seq: d[0] },
            0x0F => Command::ProgramInfo {
                program: check_prog(d[0])?,
            },
            _ => Command::ReadBack {
                program: check_prog(d[0])?,
                instruction: check_instr(u16_at(1))?,
            },
        })
    }
}

/// True if `f` parses as a command and every quaternion in it has unit norm within
/// [`QUATERNION_NORM_TOLERANCE`]: the strict check a robot may apply before acknowledging.
pub fn well_formed(f: &Frame) -> bool {
    match Command::from_frame(f) {
        Ok(Command::StorePos { positioning: p, .. } | Command::MoveImmediate(p)) => {
            p.pose.q.norm_error() <= QUATERNION_NORM_TOLERANCE
        }
        Ok(_) => true,
        Err(_) => false,
    }
}

/// The robot's mode (seed 001 §5.3.1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Mode {
    /// Execute without moving the arm.
    #[default]
    Standby,
    /// Execute with the arm.
    Operate,
}

/// What the robot computer is doing.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum State {
    /// Nothing.
    #[default]
    Idle,
    /// A program or an immediate move.
    Running,
    /// Synchronising to home.
    Homing,
    /// Stopped on an error.
    Error,
    /// Halted by STOP: the arm has decelerated (or is decelerating) to rest where it was and the
    /// program has ended; "in position" stays low.
    Stopped,
}

/// ENQUIRE status reply.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct Status {
    /// Mode.
    pub mode: Mode,
    /// State.
    pub state: State,
    /// Current (or last) program, 0 if none.
    pub program: u8,
    /// Current instruction, 0 if none.
    pub instruction: u16,
    /// The latched error code ([`crate::RobotError`]), 0 if none. It stays until the host
    /// acknowledges it with [`Command::AckError`] (reading the status does not clear it).
    pub last_error: u8,
    /// Homed since power-up.
    pub homed: bool,
    /// Sequence number of the latest error (wraps at 256): it changes with every error the robot
    /// raises, so the host tells a new error from one it has already seen.
    pub error_seq: u8,
    /// Count of telegrams with an effect (every command but ENQUIRE, READ_BACK, PROGRAM_INFO and
    /// ACK_ERROR, which only clears the error latch) the robot has
    /// executed since power-up, wrapping at 65 536: the host compares it before and after a
    /// command to see whether the command was executed, and how often.
    pub executed: u16,
    /// CRC-16/CCITT-FALSE of the last such telegram's CMD, LEN and DATA
    /// ([`crate::frame::telegram_digest`]): which telegram the robot executed last.
    pub last_digest: u16,
}

impl std::fmt::Display for Status {
    /// The status in the protocol's words (docs/protocol.md, ENQUIRE): `mode OPERATE, state
    /// ERROR, program 1, instruction 53, last error 9`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mode = match self.mode {
            Mode::Standby => "STANDBY",
            Mode::Operate => "OPERATE",
        };
        let state = match self.state {
            State::Idle => "IDLE",
            State::Running => "RUNNING",
            State::Homing => "HOMING",
            State::Error => "ERROR",
            State::Stopped => "STOPPED",
        };
        write!(
            f,
            "mode {mode}, state {state}, program {}, instruction {}, last error {}",
            self.program, self.instruction, self.last_error
        )
    }
}

/// DATA length of the ENQUIRE status reply.
pub const STATUS_REPLY_LEN: usize = 13;

/// A telegram from the robot computer to the PC (in a reverse session).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Reply {
    /// 0x86, selector 0.
    Status(Status),
    /// 0x86, selector 1.
    Position(Pose),
    /// 0x8F: what a program and the memory hold.
    ProgramInfo {
        /// Program.
        program: u8,
        /// Instructions stored in it.
        count: u16,
        /// Its highest instruction number (0 if empty).
        highest: u16,
        /// Instructions stored in all programs.
        total: u16,
    },
    /// 0x8D: the stored instruction, `None` if there is none.
    ReadBack {
        /// Program.
        program: u8,
        /// Instruction number.
        instruction: u16,
        /// What is stored there.
        stored: Option<Instruction>,
    },
}

impl Reply {
    /// The reply code.
    pub fn code(&self) -> u8 {
        match self {
            Reply::Status(_) | Reply::Position(_) => REPLY_ENQUIRE,
            Reply::ReadBack { .. } => REPLY_READ_BACK,
            Reply::ProgramInfo { .. } => REPLY_PROGRAM_INFO,
        }
    }

    /// The DATA bytes.
    pub fn data(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(24);
        match self {
            Reply::Status(s) => {
                out.push(0);
                out.push(match s.mode {
                    Mode::Standby => 0,
                    Mode::Operate => 1,
                });
                out.push(match s.state {
                    State::Idle => 0,
                    State::Running => 1,
                    State::Homing => 2,
                    State::Error => 3,
                    State::Stopped => 4,
                });
                out.push(s.program);
                out.extend_from_slice(&s.instruction.to_be_bytes());
                out.push(s.last_error);
                out.push(u8::from(s.homed));
                out.push(s.error_seq);
                out.extend_from_slice(&s.executed.to_be_bytes());
                out.extend_from_slice(&s.last_digest.to_be_bytes());
            }
            Reply::Position(p) => {
                out.push(1);
                p.write(&mut out);
            }
            Reply::ProgramInfo {
                program,
                count,
                highest,
                total,
            } => {
                out.push(*program);
                for v in [count, highest, total] {
                    out.extend_from_slice(&v.to_be_bytes());
                }
            }
            Reply::ReadBack {
                program,
                instruction,
                stored,
            } => {
                out.push(*program);
                out.extend_from_slice(&instruction.to_be_bytes());
                match stored {
                    None => out.push(0),
                    Some(Instruction::Position(p)) => {
                        out.push(0x01);
                        p.write(&mut out);
                    }
                    Some(Instruction::Control(c)) => {
                        out.push(0x09);
                        c.write(&mut out);
                    }
                }
            }
        }
        out
    }

    /// The framed telegram.
    pub fn encode(&self, cfg: &FrameConfig) -> Result<Vec<u8>, EncodeError> {
        frame::encode(cfg, self.code(), &self.data())
    }

    /// Types a received frame.
    pub fn from_frame(f: &Frame) -> Result<Reply, ParseError> {
        let d = f.data.as_slice();
        let len_err = |expected| ParseError::Length {
            code: f.code,
            expected,
            got: d.len(),
        };
        match (f.code, d.first()) {
            (REPLY_ENQUIRE, Some(0)) => {
                if d.len() != STATUS_REPLY_LEN {
                    return Err(len_err(STATUS_REPLY_LEN));
                }
                if d[6] != 0 && RobotError::from_code(d[6]).is_none() {
                    return Err(ParseError::UnknownErrorCode(d[6]));
                }
                Ok(Reply::Status(Status {
                    mode: match d[1] {
                        0 => Mode::Standby,
                        1 => Mode::Operate,
                        _ => return Err(ParseError::Field("status mode")),
                    },
                    state: match d[2] {
                        0 => State::Idle,
                        1 => State::Running,
                        2 => State::Homing,
                        3 => State::Error,
                        4 => State::Stopped,
                        _ => return Err(ParseError::Field("status state")),
                    },
                    program: d[3],
                    instruction: u16::from_be_bytes([d[4], d[5]]),
                    last_error: d[6],
                    homed: match d[7] {
                        0 => false,
                        1 => true,
                        _ => return Err(ParseError::Field("status homed")),
                    },
                    error_seq: d[8],
                    executed: u16::from_be_bytes([d[9], d[10]]),
                    last_digest: u16::from_be_bytes([d[11], d[12]]),
                }))
            }
            (REPLY_ENQUIRE, Some(1)) => {
                if d.len() != 15 {
                    return Err(len_err(15));
                }
                Ok(Reply::Position(Pose::read(&d[1..])?))
            }
            (REPLY_ENQUIRE, _) => Err(ParseError::Field("enquire reply selector")),
            (REPLY_READ_BACK, _) => {
                if d.len() < 4 {
                    return Err(len_err(4));
                }
                let program = check_prog(d[0])?;
                let instruction = check_instr(u16::from_be_bytes([d[1], d[2]]))?;
                let body = &d[4..];
                let stored = match (d[3], body.len()) {
                    (0, 0) => None,
                    (0x01, POSITIONING_LEN) => {
                        Some(Instruction::Position(Positioning::read(body)?))
                    }
                    (0x09, CONTROL_LEN) => Some(Instruction::Control(Control::read(body)?)),
                    (0 | 0x01 | 0x09, _) => return Err(ParseError::Field("read-back length")),
                    _ => return Err(ParseError::Field("read-back kind")),
                };
                Ok(Reply::ReadBack {
                    program,
                    instruction,
                    stored,
                })
            }
            (REPLY_PROGRAM_INFO, _) => {
                if d.len() != 7 {
                    return Err(len_err(7));
                }
                let at = |i: usize| u16::from_be_bytes([d[i], d[i + 1]]);
                Ok(Reply::ProgramInfo {
                    program: check_prog(d[0])?,
                    count: at(1),
                    highest: at(3),
                    total: at(5),
                })
            }
            (code, _) => Err(ParseError::UnknownCode(code)),
        }
    }
}

/// The robot's `last_error` codes (docs/protocol.md §5, plus 8: memory full).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum RobotError {
    /// 1: unknown CMD.
    UnknownCommand = 1,
    /// 2: LEN does not match CMD.
    Length = 2,
    /// 3: value out of range, reserved bits set, bad quaternion.
    Range = 3,
    /// 4: not in OPERATE (a move was asked for in STANDBY).
    NotOperate = 4,
    /// 5: program empty or unknown.
    NoProgram = 5,
    /// 6: not homed.
    NotHomed = 6,
    /// 7: busy (program running).
    Busy = 7,
    /// 8: memory full (seed 001 §4.1.2: 470 positioning, or 300 positioning + 200 control).
    MemoryFull = 8,
    /// 9: a pose the arm cannot take (outside its reach or joint limits, or needing a wrist yaw
    /// the 5-axis IRB 6/2 does not have: seed 001 §4.1.1).
    Kinematics = 9,
}

impl RobotError {
    /// Every code.
    pub const ALL: [RobotError; 9] = [
        RobotError::UnknownCommand,
        RobotError::Length,
        RobotError::Range,
        RobotError::NotOperate,
        RobotError::NoProgram,
        RobotError::NotHomed,
        RobotError::Busy,
        RobotError::MemoryFull,
        RobotError::Kinematics,
    ];
    /// The wire code.
    pub fn code(self) -> u8 {
        self as u8
    }
    /// The error of a wire code (0 = none).
    pub fn from_code(code: u8) -> Option<Self> {
        Self::ALL.into_iter().find(|e| e.code() == code)
    }
    /// A short description.
    pub fn message(self) -> &'static str {
        match self {
            RobotError::UnknownCommand => "unknown command",
            RobotError::Length => "telegram length does not match the command",
            RobotError::Range => "value out of range or bad quaternion",
            RobotError::NotOperate => "not in operate mode",
            RobotError::NoProgram => "program empty or unknown",
            RobotError::NotHomed => "not synchronised to home",
            RobotError::Busy => "busy: a program or move is running",
            RobotError::MemoryFull => "program memory full",
            RobotError::Kinematics => "pose outside the arm's reach or joint limits",
        }
    }
    /// The error a parse failure maps to.
    pub fn from_parse(e: &ParseError) -> Self {
        match e {
            ParseError::UnknownCode(_) => RobotError::UnknownCommand,
            ParseError::Length { .. } => RobotError::Length,
            ParseError::Field(_) | ParseError::UnknownErrorCode(_) => RobotError::Range,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::decoder::{Decoder, Token};
    use proptest::prelude::*;

    /// A status in an operator's message reads in the protocol's words (docs/protocol.md: state
    /// 3 error, mode 1 operate), not as a Rust structure.
    #[test]
    fn a_status_reads_in_the_protocols_words() {
        let s = Status {
            mode: Mode::Operate,
            state: State::Error,
            program: 1,
            instruction: 53,
            last_error: 9,
            ..Status::default()
        };
        assert_eq!(
            s.to_string(),
            "mode OPERATE, state ERROR, program 1, instruction 53, last error 9"
        );
        let idle = Status::default().to_string();
        assert_eq!(
            idle,
            "mode STANDBY, state IDLE, program 0, instruction 0, last error 0"
        );
    }

    /// The wire range is symmetric: ±2047.9375 mm lie in it, the raw −32768 (−2048.0 mm) does
    /// not (docs/protocol.md §4).
    #[test]
    fn the_length_range_is_symmetric() {
        assert!(Length(i16::MAX).in_range());
        assert!(Length(-i16::MAX).in_range());
        assert!(!Length(i16::MIN).in_range());
    }

    /// `from_wxyz` divides by the norm over all four components and keeps w ≥ 0: (3, 3, 3, 3)
    /// has norm 6, so every component is 0.5 (8192 in Q1.14); with w negative the whole
    /// quaternion changes sign (the same rotation). A norm of exactly the 1e-9 guard is still
    /// normalised; zero is degenerate.
    #[test]
    fn quaternions_are_normalised_over_all_four_components() {
        assert_eq!(
            Quaternion::from_wxyz(3.0, 3.0, 3.0, 3.0).unwrap().0,
            [8192; 4]
        );
        assert_eq!(
            Quaternion::from_wxyz(-3.0, 3.0, 3.0, 3.0).unwrap().0,
            [8192, -8192, -8192, -8192]
        );
        assert_eq!(
            Quaternion::from_wxyz(0.0, 0.0, 3.0, 4.0).unwrap().0,
            [0, 0, 9830, 13107]
        );
        assert_eq!(
            Quaternion::from_wxyz(1e-9, 0.0, 0.0, 0.0).unwrap(),
            Quaternion::IDENTITY
        );
        assert!(Quaternion::from_wxyz(0.0, 0.0, 0.0, 0.0).is_err());
    }

    /// A control instruction's line must be 1–6 for SET_OUTPUT and WAIT_INPUT, and `End` carries
    /// line 0 and level 0; anything else of operations 1–3 is a bad line, not a bad operation.
    #[test]
    fn control_instructions_check_their_line_and_level() {
        let read = |d: [u8; 3]| Control::read(&d);
        let bad_line = Err(ParseError::Field("control: line"));
        assert_eq!(
            read([1, 6, 1]),
            Ok(Control::SetOutput { line: 6, on: true })
        );
        assert_eq!(read([1, 0, 1]), bad_line);
        assert_eq!(read([1, IO_LINES + 1, 1]), bad_line);
        assert_eq!(read([2, 0, 0]), bad_line);
        assert_eq!(read([3, 0, 0]), Ok(Control::End));
        assert_eq!(read([3, 1, 0]), bad_line);
        assert_eq!(read([3, 0, 1]), bad_line);
        assert_eq!(
            read([4, 1, 0]),
            Err(ParseError::Field("control: operation"))
        );
    }

    /// `well_formed` refuses a positioning whose quaternion is off unit norm and a frame that
    /// does not parse, and passes a good one.
    #[test]
    fn well_formed_checks_the_quaternion_norm() {
        let good = golden_positioning();
        assert!(well_formed(&Command::MoveImmediate(good).to_frame()));
        let mut off = good;
        off.pose.q = Quaternion([16384, 16384, 0, 0]);
        assert!(!well_formed(&Command::MoveImmediate(off).to_frame()));
        assert!(well_formed(&Command::Stop.to_frame()));
        assert!(!well_formed(&Frame {
            code: 0x7F,
            data: vec![],
        }));
    }

    /// A read-back reply of a known kind with a body of the wrong length is refused for its
    /// length; an unknown kind for its kind.
    #[test]
    fn read_back_replies_name_a_wrong_length_and_a_wrong_kind() {
        let reply = |kind: u8, body: &[u8]| {
            let mut data = vec![1, 0, 1, kind];
            data.extend_from_slice(body);
            Reply::from_frame(&Frame { code: 0x8D, data })
        };
        assert_eq!(
            reply(0x01, &[1, 0, 0]),
            Err(ParseError::Field("read-back length"))
        );
        assert_eq!(
            reply(0x05, &[1, 0, 0]),
            Err(ParseError::Field("read-back kind"))
        );
    }

    /// Every robot error code maps back to its error, 0 and unknown codes to none, and each error
    /// has a description of its own.
    #[test]
    fn robot_error_codes_and_messages() {
        for e in RobotError::ALL {
            assert_eq!(RobotError::from_code(e.code()), Some(e));
        }
        assert_eq!(RobotError::from_code(0), None);
        assert_eq!(RobotError::from_code(200), None);
        let messages: std::collections::BTreeSet<&str> =
            RobotError::ALL.iter().map(|e| e.message()).collect();
        assert_eq!(messages.len(), RobotError::ALL.len());
        assert!(messages.iter().all(|m| !m.is_empty()));
        assert!(RobotError::MemoryFull.message().contains("memory"));
    }

    fn golden_positioning() -> Positioning {
        Positioning {
            flags: Flags::default(),
            pose: Pose::from_mm([500.0, -250.5, 800.0], [0.0, 0.0, 1.0, 0.0]).unwrap(),
            speed: Speed::from_value("speed", 0.25).unwrap(),
        }
    }

    /// docs/protocol.md §3: the typed STORE_POS gives the golden bytes, CS 0x3F.
    #[test]
    fn typed_golden_store_pos() {
        let cmd = Command::StorePos {
            program: 1,
            instruction: 5,
            positioning: golden_positioning(),
        };
        let bytes = cmd.encode(&FrameConfig::default()).unwrap();
        assert_eq!(
            bytes,
            [
                0x02, // STX
                0x01, 0x14, // STORE_POS, LEN 20
                0x01, 0x00, 0x05, // program 1, instruction 5
                0x00, // flags: rectangular, absolute, fine
                0x1F, 0x40, 0xF0, 0x58, 0x32, 0x00, // x 500.0, y -250.5, z 800.0 mm
                0x00, 0x00, 0x00, 0x00, 0x40, 0x00, 0x00, 0x00, // q = (0, 0, 1, 0)
                0x08, 0x00, // speed 0.25
                0x03, 0x3F, // ETX, CS
            ]
        );
    }

    #[test]
    fn typed_golden_others() {
        let c = FrameConfig::default();
        // MOVE_IMMEDIATE: flags 0x03 (joint, relative, fine), x 1 mm (0x0010), y 0, z -1 mm
        // (0xFFF0), identity quaternion (0x4000 0 0 0), speed 1.0 (0x2000).
        let p = Positioning {
            flags: Flags {
                interpolation: Interpolation::Joint,
                reference: Reference::Relative,
                zone: Zone::Fine,
            },
            pose: Pose::from_mm([1.0, 0.0, -1.0], [1.0, 0.0, 0.0, 0.0]).unwrap(),
            speed: Speed(0x2000),
        };
        let b = Command::MoveImmediate(p).encode(&c).unwrap();
        // All 22 bytes: ETX, and CS = (0x08 + 0x11 + 0x03 + 0x10 + 0xFF + 0xF0 + 0x40 + 0x20 +
        // 0x03) mod 256 = 0x27E mod 256 = 0x7E.
        assert_eq!(
            b,
            [
                0x02, 0x08, 0x11, 0x03, 0x00, 0x10, 0x00, 0x00, 0xFF, 0xF0, 0x40, 0x00, 0x00, 0x00,
                0x00, 0x00, 0x00, 0x00, 0x20, 0x00, 0x03, 0x7E
            ]
        );
        // ACK_ERROR 5: 02 0E 01 05 03 CS = 0x0E + 0x01 + 0x05 + 0x03 = 0x17.
        assert_eq!(
            Command::AckError { seq: 5 }.encode(&c).unwrap(),
            [0x02, 0x0E, 0x01, 0x05, 0x03, 0x17]
        );
        // STORE_CONTROL program 2, instruction 7, set output 1 on: 02 09 06 02 00 07 01 01 01 03 CS
        let b = Command::StoreControl {
            program: 2,
            instruction: 7,
            control: Control::SetOutput { line: 1, on: true },
        }
        .encode(&c)
        .unwrap();
        let cs = (0x09u32 + 6 + 2 + 7 + 1 + 1 + 1 + 3) as u8;
        assert_eq!(
            b,
            [
                0x02, 0x09, 0x06, 0x02, 0x00, 0x07, 0x01, 0x01, 0x01, 0x03, cs
            ]
        );
        // SET_BASE_SPEED 1.0 m/s: 02 0A 02 20 00 03 2F
        let b = Command::SetBaseSpeed(Speed::from_value("base", 1.0).unwrap())
            .encode(&c)
            .unwrap();
        assert_eq!(b, [0x02, 0x0A, 0x02, 0x20, 0x00, 0x03, 0x2F]);
        // STOP: 02 0C 00 03 0F
        assert_eq!(
            Command::Stop.encode(&c).unwrap(),
            [0x02, 0x0C, 0x00, 0x03, 0x0F]
        );
    }

    #[test]
    fn out_of_range_is_an_error_not_a_clamp() {
        assert!(Length::from_mm("x", 2048.0).is_err());
        assert!(Length::from_mm("x", -2048.05).is_err());
        // `docs/protocol.md` §4 "Field encodings": the range is ±2047.9375 mm, so −2048.0 is refused.
        assert!(Length::from_mm("x", -2048.0).is_err());
        assert_eq!(Length::from_mm("x", -2047.9375).unwrap(), Length(-i16::MAX));
        assert_eq!(Length::from_mm("x", 2047.9375).unwrap(), Length(i16::MAX));
        assert!(Length::from_mm("x", f64::NAN).is_err());
        assert!(Speed::from_value("s", -0.001).is_err());
        assert!(Speed::from_value("s", 8.0).is_err());
        assert!(Quaternion::from_wxyz(0.0, 0.0, 0.0, 0.0).is_err());
        // Sign canonicalisation: w ≥ 0.
        assert_eq!(
            Quaternion::from_wxyz(-1.0, 0.0, 0.0, 0.0).unwrap(),
            Quaternion::IDENTITY
        );
        // Quantisation: |decode(encode(x)) - x| ≤ 1/32 mm.
        for mm in [0.01, 1.03125, -250.51, 2047.9] {
            assert!((Length::from_mm("x", mm).unwrap().mm() - mm).abs() <= 0.03125);
        }
    }

    #[test]
    fn bad_fields_are_parse_errors() {
        let f = |code: u8, data: &[u8]| Frame {
            code,
            data: data.to_vec(),
        };
        assert_eq!(
            Command::from_frame(&f(0x42, &[])),
            Err(ParseError::UnknownCode(0x42))
        );
        assert!(matches!(
            Command::from_frame(&f(0x02, &[])),
            Err(ParseError::Length { .. })
        ));
        assert!(Command::from_frame(&f(0x02, &[0])).is_err());
        let mut store = vec![1, 0, 1, 0x10];
        store.extend_from_slice(&[0; 16]);
        assert!(Command::from_frame(&f(0x01, &store)).is_err());
        store[3] = 0x0C; // zone 3 reserved
        assert!(Command::from_frame(&f(0x01, &store)).is_err());
        assert!(Command::from_frame(&f(0x09, &[1, 0, 1, 1, 7, 1])).is_err());
        assert!(Command::from_frame(&f(0x06, &[2])).is_err());
        for info in COMMANDS {
            assert!(!RESERVED_CODES.contains(&info.code));
            assert_eq!(info.thesis_command_no, None);
        }
    }

    fn arb_positioning() -> impl Strategy<Value = Positioning> {
        (
            0u8..2,
            0u8..2,
            0u8..3,
            proptest::array::uniform3(-i16::MAX..=i16::MAX),
            any::<[i16; 4]>(),
            any::<u16>(),
        )
            .prop_map(|(i, r, z, xyz, q, s)| Positioning {
                flags: Flags::from_byte(i | r << 1 | z << 2).unwrap(),
                pose: Pose {
                    x: Length(xyz[0]),
                    y: Length(xyz[1]),
                    z: Length(xyz[2]),
                    q: Quaternion(q),
                },
                speed: Speed(s),
            })
    }

    fn arb_control() -> impl Strategy<Value = Control> {
        prop_oneof![
            (1u8..=6, any::<bool>()).prop_map(|(line, on)| Control::SetOutput { line, on }),
            (1u8..=6, any::<bool>()).prop_map(|(line, on)| Control::WaitInput { line, on }),
            Just(Control::End),
        ]
    }

    fn arb_command() -> impl Strategy<Value = Command> {
        prop_oneof![
            (1u8.., 1u16.., arb_positioning()).prop_map(|(program, instruction, positioning)| {
                Command::StorePos {
                    program,
                    instruction,
                    positioning,
                }
            }),
            (1u8..).prop_map(|program| Command::RunProgram { program }),
            Just(Command::Standby),
            Just(Command::Operate),
            Just(Command::SyncHome),
            Just(Command::Enquire(Selector::Status)),
            Just(Command::Enquire(Selector::Position)),
            (1u8..).prop_map(|program| Command::DeleteProgram { program }),
            arb_positioning().prop_map(|mut p| {
                p.flags.zone = Zone::Fine;
                Command::MoveImmediate(p)
            }),
            (1u8.., 1u16.., arb_control()).prop_map(|(program, instruction, control)| {
                Command::StoreControl {
                    program,
                    instruction,
                    control,
                }
            }),
            any::<u16>().prop_map(|s| Command::SetBaseSpeed(Speed(s))),
            any::<u16>().prop_map(|s| Command::SetMaxSpeed(Speed(s))),
            Just(Command::Stop),
            any::<u8>().prop_map(|seq| Command::AckError { seq }),
            (1u8..).prop_map(|program| Command::ProgramInfo { program }),
            (1u8.., 1u16..).prop_map(|(program, instruction)| Command::ReadBack {
                program,
                instruction
            }),
        ]
    }

    fn arb_reply() -> impl Strategy<Value = Reply> {
        prop_oneof![
            (
                (any::<bool>(), 0u8..5, any::<u8>(), any::<u16>()),
                (
                    0u8..10,
                    any::<bool>(),
                    any::<u8>(),
                    any::<u16>(),
                    any::<u16>()
                ),
            )
                .prop_map(
                    |(
                        (op, st, program, instruction),
                        (last_error, homed, error_seq, executed, last_digest),
                    )| {
                        Reply::Status(Status {
                            mode: if op { Mode::Operate } else { Mode::Standby },
                            state: [
                                State::Idle,
                                State::Running,
                                State::Homing,
                                State::Error,
                                State::Stopped,
                            ][usize::from(st)],
                            program,
                            instruction,
                            last_error,
                            homed,
                            error_seq,
                            executed,
                            last_digest,
                        })
                    }
                ),
            (1u8.., any::<u16>(), any::<u16>(), any::<u16>()).prop_map(
                |(program, count, highest, total)| Reply::ProgramInfo {
                    program,
                    count,
                    highest,
                    total
                }
            ),
            arb_positioning().prop_map(|p| Reply::Position(p.pose)),
            (
                1u8..,
                1u16..,
                prop_oneof![
                    Just(None),
                    arb_positioning().prop_map(|p| Some(Instruction::Position(p))),
                    arb_control().prop_map(|c| Some(Instruction::Control(c))),
                ]
            )
                .prop_map(|(program, instruction, stored)| Reply::ReadBack {
                    program,
                    instruction,
                    stored
                }),
        ]
    }

    fn configs() -> impl Strategy<Value = FrameConfig> {
        (any::<bool>(), 0u8..3).prop_map(|(crc, span)| FrameConfig {
            checksum: if crc {
                crate::frame::Checksum::Crc16
            } else {
                crate::frame::Checksum::Sum8
            },
            span: [
                crate::frame::ChecksumSpan::AfterStxThroughEtx,
                crate::frame::ChecksumSpan::StxThroughEtx,
                crate::frame::ChecksumSpan::TelegramOnly,
            ][usize::from(span)],
            ..FrameConfig::default()
        })
    }

    fn decode_one(cfg: FrameConfig, bytes: &[u8]) -> Frame {
        let mut d = Decoder::new(cfg);
        d.push(bytes);
        match d.next_token() {
            Some(Token::Frame(f)) => f,
            other => panic!("{other:?}"),
        }
    }

    proptest! {
        #[test]
        fn command_round_trip(cmd in arb_command(), cfg in configs()) {
            let bytes = cmd.encode(&cfg).unwrap();
            let f = decode_one(cfg, &bytes);
            prop_assert_eq!(Command::from_frame(&f), Ok(cmd));
        }

        #[test]
        fn reply_round_trip(reply in arb_reply(), cfg in configs()) {
            let bytes = reply.encode(&cfg).unwrap();
            let f = decode_one(cfg, &bytes);
            prop_assert_eq!(Reply::from_frame(&f), Ok(reply));
        }

        #[test]
        fn decoder_never_panics_and_recovers(
            garbage in proptest::collection::vec(any::<u8>(), 0..200),
            cmd in arb_command(),
            cfg in configs(),
        ) {
            let mut d = Decoder::new(cfg);
            d.push(&garbage);
            while d.next_token().is_some() {}
            // Arbitrary bytes decode without panic; a clean decoder recovers after a garbage
            // prefix without STX (an STX would open a frame that may swallow the next one).
            let clean: Vec<u8> = garbage.iter().copied().filter(|&b| b != crate::frame::STX).collect();
            let mut d = Decoder::new(cfg);
            d.push(&clean);
            let bytes = cmd.encode(&cfg).unwrap();
            d.push(&bytes);
            let mut found = false;
            while let Some(t) = d.next_token() {
                if let Token::Frame(f) = t {
                    found = Command::from_frame(&f) == Ok(cmd);
                }
            }
            prop_assert!(found);
        }

        #[test]
        fn parsers_never_panic(code in any::<u8>(), data in proptest::collection::vec(any::<u8>(), 0..64)) {
            let f = Frame { code, data };
            let _ = Command::from_frame(&f);
            let _ = Reply::from_frame(&f);
        }
    }
}
