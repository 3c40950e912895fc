//! The robot control file `NAME_<prog>.ROB` (seed 001 §5.6.1): a header (base velocity, maximum
//! velocity, synchronise the mandrel to the robot), one instruction per segment end (speed, next
//! position, wrist quaternion, coordinate type, absolute/relative, and the mandrel instruction),
//! and a trailer that ends the link. Alone it drives discrete mode.
//!
//! ```text
//! rob 1
//! program 1
//! base_speed_mm_s 1000
//! max_speed_mm_s 2000
//! movement fine
//! sync_mandrel_deg 91.2
//! instr 1 speed_pct=10 pos_mm=768.3,31.7,478 q=0.5,0.5,0.5,-0.5 move=rect ref=abs accel_rps2=1 start_rps=0.05 max_rps=0.1 steps=0
//! end
//! ```
//! The full grammar is in `docs/file-formats.md`.

use std::fmt::Write as _;

use crate::syntax::{Places, Record, Token, number, records};
use crate::{Error, MandrelMove};

/// The format version written on the first line.
pub const VERSION: i64 = 1;

/// How the robot moves between points (seed 001 §5.3.2, §5.4.2; docs/protocol.md).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Movement {
    /// Positions sent one at a time, executed at once without storing; robot and mandrel stop at
    /// every point (§5.4.1).
    Discrete,
    /// Stored program; the robot passes within a 1 mm zone of each point (§5.4.2).
    Fine,
    /// Stored program; 10 mm zone.
    Medium,
    /// Stored program in the medium zone, kept in step with the mandrel (ours, beyond the
    /// thesis; docs/continuous.md): the program starts at the path's second point (the eye is
    /// at the first from the approach), and every segment lasts at least the robot's time per
    /// instruction.
    Continuous,
}

impl Movement {
    /// The file keyword.
    pub fn keyword(self) -> &'static str {
        match self {
            Movement::Discrete => "discrete",
            Movement::Fine => "fine",
            Movement::Medium => "medium",
            Movement::Continuous => "continuous",
        }
    }

    /// Parses the file keyword.
    pub fn from_keyword(word: &str) -> Option<Self> {
        match word {
            "discrete" => Some(Movement::Discrete),
            "fine" => Some(Movement::Fine),
            "medium" => Some(Movement::Medium),
            "continuous" => Some(Movement::Continuous),
            _ => None,
        }
    }
}

/// Rectangular (straight-line TCP) or robot (joint) interpolation (§5.3.2).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Interpolation {
    /// Straight line from point to point.
    Rectangular,
    /// Shortest path in joint space.
    Joint,
}

/// Absolute or relative coordinates (§5.3.2).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reference {
    /// Absolute cell coordinates.
    Absolute,
    /// Relative to the previous position.
    Relative,
}

/// The header of a robot control file.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Header {
    /// Program number 1–255.
    pub program: u8,
    /// Base speed, mm/s.
    pub base_speed_mm_s: f64,
    /// Maximum speed, mm/s.
    pub max_speed_mm_s: f64,
    /// Movement type.
    pub movement: Movement,
    /// The mandrel angle to synchronise to before the first instruction, degrees.
    pub sync_mandrel_deg: f64,
}

/// One robot instruction with its mandrel instruction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Instruction {
    /// Instruction number, 1-based, consecutive.
    pub number: u16,
    /// Speed as a percentage of the base speed.
    pub speed_pct: f64,
    /// Next eye position, mm, cell frame.
    pub position_mm: [f64; 3],
    /// Wrist quaternion, scalar first (App. A).
    pub q: [f64; 4],
    /// Interpolation.
    pub interpolation: Interpolation,
    /// Absolute or relative.
    pub reference: Reference,
    /// The mandrel's move for this segment.
    pub mandrel: MandrelMove,
}

/// A whole robot control file.
#[derive(Debug, Clone, PartialEq)]
pub struct RobotFile {
    /// The header.
    pub header: Header,
    /// The instructions in order.
    pub instructions: Vec<Instruction>,
}

impl RobotFile {
    /// Parses the text of a .ROB file.
    pub fn parse(text: &str) -> Result<Self, Error> {
        Self::read(text, None)
    }

    /// [`RobotFile::parse`], keeping where each value was read: the header's by keyword
    /// (`program`, `base_speed_mm_s`, `max_speed_mm_s`, `movement`, `sync_mandrel_deg`) and each
    /// instruction's by field (`speed_pct`, `pos_mm`, `q`, `move`, `ref`, `accel_rps2`,
    /// `start_rps`, `max_rps`, `steps`).
    pub fn parse_placed(text: &str) -> Result<(Self, Places), Error> {
        let mut places = Places::default();
        let file = Self::read(text, Some(&mut places))?;
        Ok((file, places))
    }

    fn read(text: &str, mut places: Option<&mut Places>) -> Result<Self, Error> {
        let recs = records(text);
        let mut it = recs.iter().peekable();
        let first = it
            .next()
            .ok_or_else(|| Error::at(1, 1, "empty robot control file"))?;
        expect_keyword(first, "rob")?;
        first.expect_len(2, "format version")?;
        let version = first.tokens[1].i64()?;
        if version != VERSION {
            return Err(first.tokens[1].error(format!("unsupported .ROB version {version}")));
        }
        let program_token = header_value(it.next(), first, "program")?;
        let program = program_token.int_in(1..=255)? as u8;
        let base = header_value(it.next(), first, "base_speed_mm_s")?;
        let base_speed_mm_s = positive(&base)?;
        let max = header_value(it.next(), first, "max_speed_mm_s")?;
        let max_speed_mm_s = positive(&max)?;
        if max_speed_mm_s < base_speed_mm_s {
            return Err(max.error("max_speed_mm_s is below base_speed_mm_s"));
        }
        let movement_token = header_value(it.next(), first, "movement")?;
        let movement = Movement::from_keyword(movement_token.text).ok_or_else(|| {
            movement_token.error(format!(
                "unknown movement `{}` (discrete, fine or medium)",
                movement_token.text
            ))
        })?;
        let sync = header_value(it.next(), first, "sync_mandrel_deg")?;
        let sync_mandrel_deg = sync.f64()?;
        if let Some(p) = places.as_deref_mut() {
            for (name, token) in [
                ("program", &program_token),
                ("base_speed_mm_s", &base),
                ("max_speed_mm_s", &max),
                ("movement", &movement_token),
                ("sync_mandrel_deg", &sync),
            ] {
                p.add_field(name, token);
            }
        }
        let header = Header {
            program,
            base_speed_mm_s,
            max_speed_mm_s,
            movement,
            sync_mandrel_deg,
        };

        let mut instructions = Vec::new();
        let mut last_line = first;
        for rec in it {
            last_line = rec;
            match rec.head().text {
                "instr" => {
                    let instruction = parse_instruction(
                        rec,
                        max_speed_mm_s / base_speed_mm_s,
                        places.as_deref_mut(),
                    )?;
                    let expected = instructions.len() + 1;
                    if instruction.number as usize != expected {
                        return Err(rec.tokens[1].error(format!(
                            "instruction number {} out of order (expected {expected})",
                            instruction.number
                        )));
                    }
                    instructions.push(instruction);
                }
                "end" => {
                    rec.expect_len(1, "")?;
                    let trailing = recs.iter().find(|r| r.line > rec.line);
                    if let Some(extra) = trailing {
                        return Err(extra.head().error("text after `end`"));
                    }
                    if instructions.is_empty() {
                        return Err(rec.head().error("no instructions before `end`"));
                    }
                    return Ok(RobotFile {
                        header,
                        instructions,
                    });
                }
                other => {
                    return Err(rec
                        .head()
                        .error(format!("expected `instr` or `end`, found `{other}`")));
                }
            }
        }
        Err(last_line.missing("`end` trailer"))
    }

    /// Writes the canonical text. Refuses ([`Error::Unwritable`]) a file that
    /// [`RobotFile::parse`] would refuse or read back differently: no instructions, numbers not
    /// 1, 2, 3, …, a speed not above 0 or above the maximum, a quaternion whose norm is not 1, a
    /// non-finite number, program 0.
    pub fn write(&self) -> Result<String, Error> {
        crate::error::written("robot control file", self, self.text(), RobotFile::parse)
    }

    fn text(&self) -> String {
        let h = &self.header;
        let mut out = String::new();
        let _ = writeln!(out, "# windcell robot control file (seed 001 §5.6.1)");
        let _ = writeln!(out, "rob {VERSION}");
        let _ = writeln!(out, "program {}", h.program);
        let _ = writeln!(out, "base_speed_mm_s {}", number(h.base_speed_mm_s));
        let _ = writeln!(out, "max_speed_mm_s {}", number(h.max_speed_mm_s));
        let _ = writeln!(out, "movement {}", h.movement.keyword());
        let _ = writeln!(out, "sync_mandrel_deg {}", number(h.sync_mandrel_deg));
        for i in &self.instructions {
            let [x, y, z] = i.position_mm;
            let [q1, q2, q3, q4] = i.q;
            let _ = writeln!(
                out,
                "instr {} speed_pct={} pos_mm={},{},{} q={},{},{},{} move={} ref={} {}",
                i.number,
                number(i.speed_pct),
                number(x),
                number(y),
                number(z),
                number(q1),
                number(q2),
                number(q3),
                number(q4),
                match i.interpolation {
                    Interpolation::Rectangular => "rect",
                    Interpolation::Joint => "joint",
                },
                match i.reference {
                    Reference::Absolute => "abs",
                    Reference::Relative => "rel",
                },
                i.mandrel.fields(),
            );
        }
        out.push_str("end\n");
        out
    }
}

fn expect_keyword(rec: &Record<'_>, keyword: &str) -> Result<(), Error> {
    if rec.head().text == keyword {
        Ok(())
    } else {
        Err(rec
            .head()
            .error(format!("expected `{keyword}`, found `{}`", rec.head().text)))
    }
}

fn header_value<'a>(
    rec: Option<&Record<'a>>,
    previous: &Record<'a>,
    keyword: &str,
) -> Result<Token<'a>, Error> {
    let rec = rec.ok_or_else(|| previous.missing(&format!("header line `{keyword}`")))?;
    expect_keyword(rec, keyword)?;
    rec.expect_len(2, &format!("value of `{keyword}`"))?;
    Ok(rec.tokens[1])
}

fn positive(token: &Token<'_>) -> Result<f64, Error> {
    let v = token.f64()?;
    if v > 0.0 {
        Ok(v)
    } else {
        Err(token.error(format!("{v} must be > 0")))
    }
}

/// The fields of an `instr` record, in the order they are written.
const INSTRUCTION_FIELDS: [&str; 9] = [
    "speed_pct",
    "pos_mm",
    "q",
    "move",
    "ref",
    "accel_rps2",
    "start_rps",
    "max_rps",
    "steps",
];

fn parse_instruction(
    rec: &Record<'_>,
    max_ratio: f64,
    places: Option<&mut Places>,
) -> Result<Instruction, Error> {
    if rec.tokens.len() < 2 {
        return Err(rec.missing("instruction number"));
    }
    let number = rec.tokens[1].int_in(1..=65535)? as u16;
    let tokens = rec.fields(1, INSTRUCTION_FIELDS)?;
    if let Some(p) = places {
        p.add_instruction(&INSTRUCTION_FIELDS, &tokens);
    }
    let [speed, pos, q, mv, reference, accel, start, max, steps] = tokens;
    let speed_pct = positive(&speed)?;
    if speed_pct > 100.0 * max_ratio * (1.0 + 1e-12) {
        return Err(speed.error(format!("speed {speed_pct}% exceeds the maximum speed")));
    }
    let q_values = q.f64s::<4>()?;
    let norm = q_values.iter().map(|c| c * c).sum::<f64>().sqrt();
    if (norm - 1.0).abs() > 0.01 {
        return Err(q.error(format!("quaternion norm {norm:.4} is not 1")));
    }
    let interpolation = match mv.text {
        "rect" => Interpolation::Rectangular,
        "joint" => Interpolation::Joint,
        other => return Err(mv.error(format!("unknown move `{other}` (rect or joint)"))),
    };
    let reference = match reference.text {
        "abs" => Reference::Absolute,
        "rel" => Reference::Relative,
        other => return Err(reference.error(format!("unknown ref `{other}` (abs or rel)"))),
    };
    Ok(Instruction {
        number,
        speed_pct,
        position_mm: pos.f64s::<3>()?,
        q: q_values,
        interpolation,
        reference,
        mandrel: MandrelMove::from_tokens(accel, start, max, steps)?,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    pub(crate) fn sample() -> RobotFile {
        RobotFile {
            header: Header {
                program: 2,
                base_speed_mm_s: 1000.0,
                max_speed_mm_s: 2000.0,
                movement: Movement::Fine,
                sync_mandrel_deg: 91.25,
            },
            instructions: (1..=3)
                .map(|n| Instruction {
                    number: n,
                    speed_pct: 10.0 + n as f64 * 0.125,
                    position_mm: [768.3, -31.7 * n as f64, 478.0],
                    q: [0.5, 0.5, 0.5, -0.5],
                    interpolation: Interpolation::Rectangular,
                    reference: Reference::Absolute,
                    mandrel: MandrelMove {
                        accel_rps2: 1.0,
                        start_stop_rps: 0.05,
                        max_rps: 0.1,
                        steps: -37 + n as i64,
                    },
                })
                .collect(),
        }
    }

    #[test]
    fn round_trips_exactly() {
        let file = sample();
        let text = file.write().unwrap();
        let parsed = RobotFile::parse(&text).unwrap();
        assert_eq!(parsed, file);
        assert_eq!(parsed.write().unwrap(), text);
    }

    #[test]
    fn errors_name_line_and_column() {
        let text = sample().write().unwrap();
        let bad = text.replace("q=0.5,0.5,0.5,-0.5 move=rect ref=abs accel_rps2=1 start_rps=0.05 max_rps=0.1 steps=-35", "q=0.5,0.5,0.5,-0.5 move=rect ref=abs accel_rps2=1 start_rps=0.05 max_rps=0.1 steps=x");
        let err = RobotFile::parse(&bad).unwrap_err().to_string();
        assert!(err.starts_with("9:131:"), "{err}");
        assert!(err.contains("expected an integer"), "{err}");
        let cases = [
            (text.replace("movement fine", "movement coarse"), "6:10:"),
            (text.replace("program 2", "program 0"), "3:9:"),
            (text.replace("end\n", ""), "missing `end`"),
            (text.replace("instr 2 ", "instr 5 "), "out of order"),
            (
                text.replace("q=0.5,0.5,0.5,-0.5", "q=0.5,0.5,0.5"),
                "4 comma-separated",
            ),
            (
                text.replace("speed_pct=10.25", "speed_pct=250"),
                "exceeds the maximum",
            ),
            (
                text.replace("move=rect", "move=rect colour=red"),
                "unknown field `colour`",
            ),
            (String::new(), "1:1: empty"),
        ];
        for (bad, expected) in cases {
            let err = RobotFile::parse(&bad).unwrap_err().to_string();
            assert!(err.contains(expected), "{err} should contain {expected}");
        }
    }

    /// Every value's place as a reader counts it by hand: lines from 1, columns in characters
    /// from 1 (the `é` of the comment is one character, not two bytes), each part of a list
    /// after its comma; the values are those `parse` reads.
    #[test]
    fn parse_placed_keeps_every_values_line_and_column() {
        let text = "# é\nrob 1\nprogram 7\nbase_speed_mm_s 1000\nmax_speed_mm_s  2000\n\
movement fine\nsync_mandrel_deg 1.5\n\
instr 1 speed_pct=10 pos_mm=1,22,333 q=1,0,0,0 move=rect ref=abs accel_rps2=1 start_rps=0 max_rps=0.1 steps=0\n\
\x20\x20instr 2 steps=5 speed_pct=20 pos_mm=-4.5,6,7 q=1,0,0,0 move=joint ref=abs accel_rps2=2 start_rps=0 max_rps=0.1\n\
end\n";
        let (file, places) = RobotFile::parse_placed(text).unwrap();
        assert_eq!(file, RobotFile::parse(text).unwrap());
        assert_eq!(places.field("program"), Some((3, 9)));
        assert_eq!(places.field("base_speed_mm_s"), Some((4, 17)));
        assert_eq!(places.field("max_speed_mm_s"), Some((5, 17)));
        assert_eq!(places.field("movement"), Some((6, 10)));
        assert_eq!(places.field("sync_mandrel_deg"), Some((7, 18)));
        // "instr 1 speed_pct=" is 18 characters; "pos_mm=" starts at 22, its value at 29.
        assert_eq!(places.instruction(1, "speed_pct", 0), Some((8, 19)));
        assert_eq!(places.instruction(1, "pos_mm", 0), Some((8, 29)));
        assert_eq!(places.instruction(1, "pos_mm", 1), Some((8, 31)));
        assert_eq!(places.instruction(1, "pos_mm", 2), Some((8, 34)));
        assert_eq!(places.instruction(1, "pos_mm", 3), None);
        // Fields in another order, the line indented by two.
        assert_eq!(places.instruction(2, "steps", 0), Some((9, 17)));
        assert_eq!(places.instruction(2, "speed_pct", 0), Some((9, 29)));
        assert_eq!(places.instruction(2, "pos_mm", 2), Some((9, 46)));
        assert_eq!(places.instruction(2, "move", 0), Some((9, 63)));
        assert_eq!(places.instruction(3, "steps", 0), None);
        assert_eq!(places.instruction(0, "steps", 0), None);
        assert_eq!(places.field("steps"), None);
    }
}
