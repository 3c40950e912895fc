//! Lathe-winder part programs in the NC format of seed 000 Fig 9-1 (Haq 1994 §9.4), and the
//! FW-CNC.PAR machine parameter file (App. A, §9.4; `docs/seed-readings.md` V000-7, V000-8).
//!
//! A part program is one or more programs (`O` numbers) of blocks ended by `;` or a line end.
//! Words: `N` sequence, `G01` linear feed, `G90` absolute, `G91` incremental, `F` feed, axes
//! `A` (mandrel, degrees), `X` (carriage, mm), `Y` (cross-feed, mm), `M98 P… L…` call a
//! subprogram `L` times, `M99` return, `M00` stop, `M30` end; `(…)` is a comment and `%` marks the
//! tape start and end. Spaces between a word's letter and its value are optional (`F12000`,
//! `F 2000`). Subprograms end with `M99`; the one program that does not is the main program.
//!
//! [`PartProgram::parse`] keeps every block's line and column; [`PartProgram::expand`] follows the
//! calls and repeat counts from the main program and returns absolute targets, each naming the
//! block it came from, so the controller can reject a move before any motion with `FILE:LINE:COL`.
//! `to_string()` writes the Fig 9-1 layout back; parsing it gives the same blocks.

use std::fmt;
use std::path::Path;

use crate::Error;

/// The deepest subprogram nesting accepted (calls within calls).
pub const MAX_CALL_DEPTH: usize = 8;
/// The most moves an expansion may produce (bounded memory for any input).
pub const MAX_EXPANDED_MOVES: usize = 1_000_000;

/// Where a block or word starts in the text (1-based line, column in characters).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Location {
    /// 1-based line.
    pub line: usize,
    /// 1-based column.
    pub column: usize,
}

impl Location {
    /// A parse error at this location.
    pub fn error(self, message: impl Into<String>) -> Error {
        Error::at(self.line, self.column, message)
    }
}

/// Coordinates of the following axis words (G90 / G91).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Distance {
    /// G90: axis words are positions from part zero.
    Absolute,
    /// G91: axis words are increments from the previous position.
    Incremental,
}

/// A block's M function.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Function {
    /// M00: program stop; the operator resumes.
    Stop,
    /// M30: end of program.
    End,
    /// M98 P… L…: run subprogram `program` `repeats` times.
    Call {
        /// The `O` number called.
        program: u32,
        /// How many times (L, 1 when absent).
        repeats: u32,
    },
    /// M99: return from a subprogram.
    Return,
}

/// One block (one `;`-terminated statement).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Block {
    /// Where the block's first word is.
    pub at: Location,
    /// `N` sequence number.
    pub sequence: Option<u32>,
    /// `G01` present (linear feed; the only motion mode, so it is informational).
    pub linear: bool,
    /// `G90` / `G91`.
    pub distance: Option<Distance>,
    /// `F` word, as written (its unit is not defined by the seed; the controller's feed is the
    /// FW-CNC.PAR value in counts per interrupt, `docs/seed-readings.md` R000-4).
    pub feed: Option<f64>,
    /// `A` word: mandrel rotation in degrees.
    pub a_deg: Option<f64>,
    /// `X` word: carriage along the mandrel axis, mm.
    pub x_mm: Option<f64>,
    /// `Y` word: cross-feed, mm.
    pub y_mm: Option<f64>,
    /// `M` function.
    pub function: Option<Function>,
    /// Text of a `( … )` comment in the block, without the parentheses.
    pub comment: Option<String>,
}

impl Block {
    /// A motion block with the three axis words (an axis of `0.0` is still written).
    pub fn motion(a_deg: f64, x_mm: f64, y_mm: f64) -> Self {
        Block {
            a_deg: Some(a_deg),
            x_mm: Some(x_mm),
            y_mm: Some(y_mm),
            ..Block::default()
        }
    }

    /// Whether the block carries an axis word.
    pub fn moves(&self) -> bool {
        self.a_deg.is_some() || self.x_mm.is_some() || self.y_mm.is_some()
    }
}

/// One program: an `O` number and its blocks.
#[derive(Debug, Clone, PartialEq)]
pub struct Program {
    /// The `O` number.
    pub number: u32,
    /// Where the `O` word is.
    pub at: Location,
    /// The blocks, in order (the `O` word's own block included when it has other words).
    pub blocks: Vec<Block>,
}

impl Program {
    /// Whether the program ends with `M99` (a subprogram).
    pub fn is_subprogram(&self) -> bool {
        self.blocks
            .last()
            .is_some_and(|b| b.function == Some(Function::Return))
    }
}

/// A parsed part program: the programs in file order.
#[derive(Debug, Clone, PartialEq)]
pub struct PartProgram {
    /// The programs, subprograms usually first (Fig 9-1).
    pub programs: Vec<Program>,
}

/// A machine position: mandrel angle and carriage and cross-feed positions from part zero.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Position {
    /// A, degrees.
    pub a_deg: f64,
    /// X, mm.
    pub x_mm: f64,
    /// Y, mm.
    pub y_mm: f64,
}

/// One absolute target of an expanded program.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Target {
    /// Where to go, from part zero.
    pub position: Position,
    /// The block that asked for it.
    pub at: Location,
    /// Which top-level subprogram call (0-based over all `M98` repeats of the main program)
    /// this move belongs to: a fibre circuit, counted for the layer display. `None` for moves
    /// of the main program itself.
    pub circuit: Option<usize>,
}

/// A step of an expanded program.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Step {
    /// Move to a target.
    Move(Target),
    /// M00: stop until the operator resumes.
    Stop(Location),
}

/// A part program followed through its calls from the main program.
#[derive(Debug, Clone, PartialEq)]
pub struct Expanded {
    /// The start position (part zero unless given).
    pub start: Position,
    /// The steps in execution order.
    pub steps: Vec<Step>,
    /// Number of fibre circuits (top-level subprogram runs).
    pub circuits: usize,
}

impl Expanded {
    /// The move targets only.
    pub fn targets(&self) -> impl Iterator<Item = &Target> {
        self.steps.iter().filter_map(|s| match s {
            Step::Move(t) => Some(t),
            Step::Stop(_) => None,
        })
    }

    /// The start and every target, in order.
    pub fn positions(&self) -> Vec<Position> {
        std::iter::once(self.start)
            .chain(self.targets().map(|t| t.position))
            .collect()
    }
}

impl PartProgram {
    /// Parses a part program (see the module documentation).
    pub fn parse(text: &str) -> Result<Self, Error> {
        parse(text)
    }

    /// Reads and parses a file; errors name it.
    pub fn load(path: &Path) -> Result<Self, Error> {
        let text = crate::source::read_text(path, crate::source::MAX_PROGRAM_BYTES)?;
        PartProgram::parse(&text).map_err(|e| e.in_file(path))
    }

    /// The program with `O` number `number`.
    pub fn program(&self, number: u32) -> Option<&Program> {
        self.programs.iter().find(|p| p.number == number)
    }

    /// The main program: the one that does not end with `M99`.
    /// When several programs lack `M99`, the main program is the one that ends with `M30`.
    pub fn main(&self) -> Result<&Program, Error> {
        let mains: Vec<&Program> = self
            .programs
            .iter()
            .filter(|p| !p.is_subprogram())
            .collect();
        let ends = |p: &&&Program| {
            p.blocks
                .last()
                .is_some_and(|b| b.function == Some(Function::End))
        };
        match mains.as_slice() {
            [] => Err(Error::at(
                1,
                1,
                "no main program (every program ends with M99)",
            )),
            [main] => Ok(main),
            _ => {
                let mut with_end = mains.iter().filter(ends).copied();
                match (with_end.next(), with_end.next()) {
                    (Some(main), None) => Ok(main),
                    _ => Err(mains[1].at.error(format!(
                        "programs O{} and O{} both lack M99: which one is the main program?",
                        mains[0].number, mains[1].number
                    ))),
                }
            }
        }
    }

    /// Follows the main program's calls and repeats from part zero, in absolute targets.
    /// Distance mode starts as G90 (absolute) and is modal across calls; an axis absent from a
    /// block keeps its position.
    pub fn expand(&self) -> Result<Expanded, Error> {
        self.expand_from(Position::default())
    }

    /// As [`PartProgram::expand`], starting at `start`.
    pub fn expand_from(&self, start: Position) -> Result<Expanded, Error> {
        let main = self.main()?;
        let mut run = Expansion {
            part: self,
            position: start,
            distance: Distance::Absolute,
            steps: Vec::new(),
            circuits: 0,
            stack: vec![main.number],
        };
        run.program(main, None)?;
        Ok(Expanded {
            start,
            steps: run.steps,
            circuits: run.circuits,
        })
    }
}

struct Expansion<'a> {
    part: &'a PartProgram,
    position: Position,
    distance: Distance,
    steps: Vec<Step>,
    circuits: usize,
    stack: Vec<u32>,
}

impl Expansion<'_> {
    fn program(&mut self, program: &Program, circuit: Option<usize>) -> Result<(), Error> {
        let top = self.stack.len() == 1;
        for block in &program.blocks {
            if let Some(d) = block.distance {
                self.distance = d;
            }
            if block.moves() {
                let p = &mut self.position;
                match self.distance {
                    Distance::Absolute => {
                        p.a_deg = block.a_deg.unwrap_or(p.a_deg);
                        p.x_mm = block.x_mm.unwrap_or(p.x_mm);
                        p.y_mm = block.y_mm.unwrap_or(p.y_mm);
                    }
                    Distance::Incremental => {
                        p.a_deg += block.a_deg.unwrap_or(0.0);
                        p.x_mm += block.x_mm.unwrap_or(0.0);
                        p.y_mm += block.y_mm.unwrap_or(0.0);
                    }
                }
                if self.steps.len() >= MAX_EXPANDED_MOVES {
                    return Err(block.at.error(format!(
                        "the program expands to more than {MAX_EXPANDED_MOVES} moves"
                    )));
                }
                self.steps.push(Step::Move(Target {
                    position: self.position,
                    at: block.at,
                    circuit,
                }));
            }
            match block.function {
                Some(Function::Stop) => self.steps.push(Step::Stop(block.at)),
                Some(Function::End) | Some(Function::Return) => return Ok(()),
                Some(Function::Call {
                    program: number,
                    repeats,
                }) => {
                    let called = self.part.program(number).ok_or_else(|| {
                        block
                            .at
                            .error(format!("M98 calls O{number}, which is not in the file"))
                    })?;
                    if self.stack.contains(&number) {
                        return Err(block.at.error(format!(
                            "M98 calls O{number} recursively (call chain O{} → O{number})",
                            self.stack
                                .iter()
                                .map(u32::to_string)
                                .collect::<Vec<_>>()
                                .join(" → O")
                        )));
                    }
                    if !called.is_subprogram() {
                        return Err(called
                            .at
                            .error(format!("subprogram O{number} does not end with M99")));
                    }
                    if self.stack.len() > MAX_CALL_DEPTH {
                        return Err(block.at.error(format!(
                            "subprogram calls nest deeper than {MAX_CALL_DEPTH}"
                        )));
                    }
                    self.stack.push(number);
                    for _ in 0..repeats {
                        let c = if top {
                            self.circuits += 1;
                            Some(self.circuits - 1)
                        } else {
                            circuit
                        };
                        self.program(called, c)?;
                    }
                    self.stack.pop();
                }
                None => {}
            }
        }
        Ok(())
    }
}

/// Raw word of the text: letter, value text, location.
struct Word<'a> {
    letter: char,
    value: &'a str,
    at: Location,
}

impl Word<'_> {
    fn number(&self) -> Result<f64, Error> {
        let v: f64 = self.value.parse().map_err(|_| {
            self.at
                .error(format!("{}: '{}' is not a number", self.letter, self.value))
        })?;
        if !v.is_finite() {
            return Err(self
                .at
                .error(format!("{}: value is not finite", self.letter)));
        }
        Ok(v)
    }

    fn integer(&self, max: u32) -> Result<u32, Error> {
        let ok = !self.value.is_empty()
            && self.value.bytes().all(|b| b.is_ascii_digit())
            && self.value.len() <= 10;
        let v = ok.then(|| self.value.parse::<u64>().ok()).flatten();
        match v {
            Some(v) if v <= u64::from(max) => Ok(v as u32),
            _ => Err(self.at.error(format!(
                "{}: '{}' is not a whole number from 0 to {max}",
                self.letter, self.value
            ))),
        }
    }
}

fn parse(text: &str) -> Result<PartProgram, Error> {
    let mut programs: Vec<Program> = Vec::new();
    let mut percent_seen = 0usize;
    let mut words: Vec<Word<'_>> = Vec::new();
    let mut comment: Option<String> = None;
    let mut line = 1usize;
    let mut line_start = 0usize;
    let bytes = text.as_bytes();
    let mut i = 0usize;
    let col = |offset: usize, line_start: usize| text[line_start..offset].chars().count() + 1;
    while i <= bytes.len() {
        let c = if i < bytes.len() { bytes[i] } else { b'\n' };
        let at = Location {
            line,
            column: col(i.min(text.len()), line_start),
        };
        match c {
            b';' | b'\n' => {
                if !words.is_empty() || comment.is_some() {
                    if percent_seen >= 2 {
                        return Err(at.error("text after the closing %"));
                    }
                    block(&mut programs, std::mem::take(&mut words), comment.take())?;
                }
                if c == b'\n' {
                    line += 1;
                    line_start = i + 1;
                }
                i += 1;
            }
            b'\r' | b' ' | b'\t' => i += 1,
            b'%' => {
                if !words.is_empty() {
                    return Err(at.error("% inside a block"));
                }
                percent_seen += 1;
                if percent_seen > 2 {
                    return Err(at.error("a third %"));
                }
                i += 1;
            }
            b'(' => {
                let close = text[i..]
                    .find([')', '\n'])
                    .filter(|&k| bytes[i + k] == b')')
                    .ok_or_else(|| at.error("comment '(' is not closed on its line"))?;
                let body = text[i + 1..i + close].trim().to_string();
                comment = Some(match comment.take() {
                    Some(prev) => format!("{prev} {body}"),
                    None => body,
                });
                i += close + 1;
            }
            c if c.is_ascii_alphabetic() => {
                let letter = c.to_ascii_uppercase() as char;
                let mut j = i + 1;
                while j < bytes.len() && (bytes[j] == b' ' || bytes[j] == b'\t') {
                    j += 1;
                }
                let start = j;
                while j < bytes.len() && matches!(bytes[j], b'0'..=b'9' | b'.' | b'-' | b'+') {
                    j += 1;
                }
                if percent_seen >= 2 {
                    return Err(at.error("text after the closing %"));
                }
                words.push(Word {
                    letter,
                    value: &text[start..j],
                    at,
                });
                i = j;
            }
            _ => {
                let ch = text[i..].chars().next().unwrap_or('?');
                return Err(at.error(format!("unexpected character '{ch}'")));
            }
        }
    }
    if programs.is_empty() {
        return Err(Error::at(1, 1, "no blocks in the part program"));
    }
    for p in &programs {
        for (k, b) in p.blocks.iter().enumerate() {
            let last = k + 1 == p.blocks.len();
            if matches!(b.function, Some(Function::Return) | Some(Function::End)) && !last {
                return Err(p.blocks[k + 1]
                    .at
                    .error("block after the program's M99 or M30"));
            }
        }
        if let Some(dup) = programs
            .iter()
            .find(|q| q.number == p.number && q.at != p.at)
        {
            return Err(dup
                .at
                .error(format!("program O{} is defined twice", p.number)));
        }
    }
    Ok(PartProgram { programs })
}

fn block(
    programs: &mut Vec<Program>,
    words: Vec<Word<'_>>,
    comment: Option<String>,
) -> Result<(), Error> {
    let mut b = Block {
        at: words.first().map(|w| w.at).unwrap_or_default(),
        comment,
        ..Block::default()
    };
    let mut call: Option<(Location, Option<u32>, Option<u32>)> = None;
    let mut seen = String::new();
    for w in &words {
        if w.letter != 'G' && seen.contains(w.letter) {
            return Err(w
                .at
                .error(format!("{} appears twice in the block", w.letter)));
        }
        seen.push(w.letter);
        match w.letter {
            'O' => {
                if b.at != w.at {
                    return Err(w.at.error("O must start its block"));
                }
                programs.push(Program {
                    number: w.integer(99_999)?,
                    at: w.at,
                    blocks: Vec::new(),
                });
                b.at = Location::default();
            }
            'N' => b.sequence = Some(w.integer(99_999)?),
            'G' => match w.integer(99)? {
                1 => b.linear = true,
                90 => b.distance = Some(Distance::Absolute),
                91 => b.distance = Some(Distance::Incremental),
                g => {
                    return Err(w
                        .at
                        .error(format!("G{g:02} is not supported (G01, G90 and G91 are)")));
                }
            },
            'F' => {
                let f = w.number()?;
                if f <= 0.0 {
                    return Err(w.at.error("F must be > 0"));
                }
                b.feed = Some(f);
            }
            'A' => b.a_deg = Some(w.number()?),
            'X' => b.x_mm = Some(w.number()?),
            'Y' => b.y_mm = Some(w.number()?),
            'M' => {
                b.function = Some(match w.integer(99)? {
                    0 => Function::Stop,
                    30 => Function::End,
                    99 => Function::Return,
                    98 => {
                        call = Some((w.at, None, None));
                        Function::Call {
                            program: 0,
                            repeats: 1,
                        }
                    }
                    m => {
                        return Err(w.at.error(format!(
                            "M{m:02} is not supported (M00, M30, M98 and M99 are)"
                        )));
                    }
                })
            }
            'P' | 'L' => {
                let v = w.integer(if w.letter == 'P' { 99_999 } else { 9_999 })?;
                match call.as_mut() {
                    Some(c) if w.letter == 'P' => c.1 = Some(v),
                    Some(c) => c.2 = Some(v),
                    None => {
                        return Err(w
                            .at
                            .error(format!("{} is only allowed after M98", w.letter)));
                    }
                }
            }
            other => {
                return Err(w.at.error(format!("unknown word '{other}'")));
            }
        }
    }
    if let Some((at, program, repeats)) = call {
        let program = program.ok_or_else(|| at.error("M98 needs P (the subprogram number)"))?;
        let repeats = repeats.unwrap_or(1);
        if repeats == 0 {
            return Err(at.error("L must be ≥ 1"));
        }
        b.function = Some(Function::Call { program, repeats });
    }
    let has_content = b.sequence.is_some()
        || b.linear
        || b.distance.is_some()
        || b.feed.is_some()
        || b.moves()
        || b.function.is_some()
        || b.comment.is_some();
    if b.at == Location::default() {
        // The O word's block: the block starts at its next word.
        b.at = words.get(1).map(|w| w.at).unwrap_or_default();
    }
    if has_content {
        let program = programs.last_mut().ok_or_else(|| {
            let at = words
                .first()
                .map(|w| w.at)
                .unwrap_or(Location { line: 1, column: 1 });
            at.error("block before the first O program number")
        })?;
        program.blocks.push(b);
    }
    Ok(())
}

fn number(v: f64) -> String {
    crate::syntax::number(v)
}

impl fmt::Display for Block {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut parts: Vec<String> = Vec::new();
        if let Some(n) = self.sequence {
            parts.push(format!("N {n}"));
        }
        if self.linear {
            parts.push("G01".into());
        }
        match self.distance {
            Some(Distance::Absolute) => parts.push("G90".into()),
            Some(Distance::Incremental) => parts.push("G91".into()),
            None => {}
        }
        for (letter, v) in [('A', self.a_deg), ('X', self.x_mm), ('Y', self.y_mm)] {
            if let Some(v) = v {
                parts.push(format!("{letter} {}", number(v)));
            }
        }
        if let Some(v) = self.feed {
            parts.push(format!("F {}", number(v)));
        }
        match self.function {
            Some(Function::Stop) => parts.push("M00".into()),
            Some(Function::End) => parts.push("M30".into()),
            Some(Function::Return) => parts.push("M99".into()),
            Some(Function::Call { program, repeats }) => {
                parts.push(format!("M98 P {program} L {repeats}"))
            }
            None => {}
        }
        if let Some(c) = &self.comment {
            parts.push(format!("({})", c.replace([')', '('], "")));
        }
        write!(f, "{};", parts.join(" "))
    }
}

impl fmt::Display for PartProgram {
    /// Writes the Fig 9-1 layout: `%`, each program as `O n;` then one block per line, `%`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "%")?;
        for (i, p) in self.programs.iter().enumerate() {
            if i > 0 {
                writeln!(f)?;
            }
            writeln!(f, "O {};", p.number)?;
            for b in &p.blocks {
                writeln!(f, "{b}")?;
            }
        }
        writeln!(f, "%")
    }
}

/// The FW-CNC.PAR machine parameters (App. A; `docs/seed-readings.md` V000-8): feeds in encoder counts per
/// interrupt of the fastest axis (glossary: "feed rate").
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MachineParameters {
    /// "Initial feed rate for manual control".
    pub manual_feed: u32,
    /// "Normal feed rate".
    pub normal_feed: u32,
    /// "Feed rate limit".
    pub feed_limit: u32,
    /// "Number of interrupts after which actual positions are recorded" (1 … 32 767, §9.9).
    pub record_interval: u32,
    /// "Number of knot points to be interpolated between two points", read as intervals per
    /// segment `N` (`docs/seed-readings.md` R000-5).
    pub knots_per_segment: u32,
}

impl Default for MachineParameters {
    /// The values of the thesis's sample file: 20, 10, 30, 20, 4.
    fn default() -> Self {
        MachineParameters {
            manual_feed: 20,
            normal_feed: 10,
            feed_limit: 30,
            record_interval: 20,
            knots_per_segment: 4,
        }
    }
}

const PARAMETER_NAMES: [&str; 5] = [
    "Initial feed rate for manual control",
    "Normal feed rate",
    "Feed rate limit",
    "Number of interrupts after which actual positions are recorded",
    "Number of knot points to be interpolated between two points",
];

impl MachineParameters {
    /// Parses FW-CNC.PAR: three comment lines, then five lines each holding an integer and an
    /// optional `;` comment, in the order of the fields. Blank lines after the fifth value are
    /// allowed; anything else is an error.
    pub fn parse(text: &str) -> Result<Self, Error> {
        let mut values = Vec::with_capacity(5);
        let mut lines = 0usize;
        for (index, raw) in text.lines().enumerate() {
            lines = index + 1;
            if index < 3 {
                continue;
            }
            let body = raw.split(';').next().unwrap_or("");
            let trimmed = body.trim();
            let column = body.len() - body.trim_start().len() + 1;
            if trimmed.is_empty() {
                if values.len() < 5 && !raw.trim().is_empty() {
                    return Err(Error::at(index + 1, 1, "expected an integer before ';'"));
                }
                continue;
            }
            if values.len() == 5 {
                return Err(Error::at(
                    index + 1,
                    column,
                    "more than five parameter lines",
                ));
            }
            let name = PARAMETER_NAMES[values.len()];
            let (max, min) = if values.len() == 3 {
                (32_767, 1)
            } else {
                (100_000, 1)
            };
            let v = trimmed
                .parse::<u32>()
                .ok()
                .filter(|v| (min..=max).contains(v))
                .ok_or_else(|| {
                    Error::at(
                        index + 1,
                        column,
                        format!("{name}: '{trimmed}' is not a whole number from {min} to {max}"),
                    )
                })?;
            values.push(v);
        }
        if values.len() < 5 {
            return Err(Error::at(
                lines + 1,
                1,
                format!(
                    "missing parameter line: {} (three comment lines, then five values)",
                    PARAMETER_NAMES[values.len()]
                ),
            ));
        }
        Ok(MachineParameters {
            manual_feed: values[0],
            normal_feed: values[1],
            feed_limit: values[2],
            record_interval: values[3],
            knots_per_segment: values[4],
        })
    }

    /// Reads and parses a file; errors name it.
    pub fn load(path: &Path) -> Result<Self, Error> {
        let text = crate::source::read_text(path, crate::source::MAX_JOB_BYTES)?;
        MachineParameters::parse(&text).map_err(|e| e.in_file(path))
    }
}

impl fmt::Display for MachineParameters {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "FW-CNC.PAR  --  CNC filament winding machine parameters file"
        )?;
        writeln!(
            f,
            "First three lines are for comments, all the other lines are also"
        )?;
        writeln!(
            f,
            "formatted bearing an integer and a comment beginning with <;>."
        )?;
        let values = [
            self.manual_feed,
            self.normal_feed,
            self.feed_limit,
            self.record_interval,
            self.knots_per_segment,
        ];
        for (v, name) in values.iter().zip(PARAMETER_NAMES) {
            writeln!(f, "{v:<3} ; {name}")?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;

    /// Seed 000 Fig 9-1, as printed (also `examples/cone-dome-cylinder.prg`).
    const FIG_9_1: &str = "%
O 999 N 10 A 10.13 X 15.79 F12000;
N 15 A 10.64 X 18.01 ;
N 20 A 9.79 X 19.18 ;
N 25 A 17.68 X 42.61 ;
N 30 A 13.03 X 45.36 ;
N 35 A 34.77 X 119.56 ;
N 40 A 18.10 X 54.48 Y 25.70 ;
N 45 A 17.54 X 9.39 Y 28.53 ;
N 50 A 18.98 X 5.77 Y 17.57 ;
N 55 A 26.04 X 1.21 Y 3.64 ;
N 60 A 25.89 X -3.12 Y -9.45 ;
N 65 A 19.66 X -7.55 Y -22.96 ;
N 70 A 16.58 X -21.14 Y -43.03 ;
N 75 A 7.94 X -31.35 ;
N 80 A 8.98 X -39.95 ;
N 85 A 6.69 X -30.29 ;
N 90 A 7.88 X -39.13 ;
N 95 A 14.20 X -58.98 ;
N 100 A 22.65 X -82.27 ;
N 105 A 22.40 X -79.75 ;
N 110 A 57.27 X -39.24 Y 22.44 ;
N 115 A 27.50 X 7.43 Y -22.44 ;
N 120 A 22.46 X 32.53 ;
N 125 A 22.60 X 30.82 ;
N 130 A 11.47 X 15.64 ;
N 135 A 10.11 X 14.99 M99;

O 998;
N 15 G01 F 2000;
N 20 G91;
N 25 M98 P 999 L 3;
N 30 M00;
N 35 M30;
%
";

    fn err(text: &str) -> String {
        PartProgram::parse(text)
            .and_then(|p| p.expand())
            .unwrap_err()
            .to_string()
    }

    #[test]
    fn fig_9_1_circuit_statistics() {
        let p = PartProgram::parse(FIG_9_1).unwrap();
        let sub = p.program(999).unwrap();
        assert!(sub.is_subprogram());
        assert_eq!(sub.blocks.len(), 26);
        let sum = |f: fn(&Block) -> Option<f64>| sub.blocks.iter().filter_map(f).sum::<f64>();
        assert_abs_diff_eq!(sum(|b| b.x_mm), 0.0, epsilon = 1e-9);
        assert_abs_diff_eq!(sum(|b| b.y_mm), 0.0, epsilon = 1e-9);
        assert_abs_diff_eq!(sum(|b| b.a_deg), 480.98, epsilon = 1e-9);
        assert_eq!(sub.blocks[0].feed, Some(12000.0));
        let main = p.main().unwrap();
        assert_eq!(main.number, 998);
        assert_eq!(main.blocks[0].feed, Some(2000.0));
        assert_eq!(
            main.blocks[2].function,
            Some(Function::Call {
                program: 999,
                repeats: 3
            })
        );
        assert_eq!(sub.blocks[0].at, Location { line: 2, column: 7 });
    }

    #[test]
    fn fig_9_1_expands_to_three_circuits() {
        let e = PartProgram::parse(FIG_9_1).unwrap().expand().unwrap();
        assert_eq!(e.circuits, 3);
        let targets: Vec<_> = e.targets().collect();
        assert_eq!(targets.len(), 78);
        let last = targets[77].position;
        assert_abs_diff_eq!(last.a_deg, 1442.94, epsilon = 1e-9);
        assert_abs_diff_eq!(last.x_mm, 0.0, epsilon = 1e-9);
        assert_abs_diff_eq!(last.y_mm, 0.0, epsilon = 1e-9);
        let xs: Vec<f64> = targets.iter().map(|t| t.position.x_mm).collect();
        let min = xs.iter().copied().fold(f64::INFINITY, f64::min);
        let max = xs.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        assert_abs_diff_eq!(min, -101.41, epsilon = 1e-9);
        assert_abs_diff_eq!(max, 331.36, epsilon = 1e-9);
        let ymax = targets.iter().map(|t| t.position.y_mm).fold(0.0, f64::max);
        assert_abs_diff_eq!(ymax, 75.44, epsilon = 1e-9);
        assert_eq!(targets[26].circuit, Some(1));
        assert!(matches!(e.steps.last(), Some(Step::Stop(l)) if l.line == 33));
        assert_eq!(e.positions().len(), 79);
    }

    #[test]
    fn written_program_parses_back_to_the_same_blocks() {
        let p = PartProgram::parse(FIG_9_1).unwrap();
        let text = p.to_string();
        let q = PartProgram::parse(&text).unwrap();
        assert_eq!(q.to_string(), text);
        assert_eq!(
            p.expand().unwrap().positions(),
            q.expand().unwrap().positions()
        );
        let strip = |p: &PartProgram| -> Vec<Vec<Block>> {
            p.programs
                .iter()
                .map(|g| {
                    g.blocks
                        .iter()
                        .map(|b| Block {
                            at: Location::default(),
                            ..b.clone()
                        })
                        .collect()
                })
                .collect()
        };
        assert_eq!(strip(&p), strip(&q));
    }

    #[test]
    fn built_program_writes_and_reads() {
        let p = PartProgram {
            programs: vec![
                Program {
                    number: 1,
                    at: Location::default(),
                    blocks: vec![
                        Block::motion(90.0, 100.5, 0.0),
                        Block {
                            function: Some(Function::Return),
                            comment: Some("end of circuit".into()),
                            ..Block::motion(90.0, -100.5, 0.0)
                        },
                    ],
                },
                Program {
                    number: 2,
                    at: Location::default(),
                    blocks: vec![
                        Block {
                            distance: Some(Distance::Incremental),
                            ..Block::default()
                        },
                        Block {
                            function: Some(Function::Call {
                                program: 1,
                                repeats: 2,
                            }),
                            ..Block::default()
                        },
                        Block {
                            function: Some(Function::End),
                            ..Block::default()
                        },
                    ],
                },
            ],
        };
        let e = PartProgram::parse(&p.to_string())
            .unwrap()
            .expand()
            .unwrap();
        let pos = e.positions();
        assert_eq!(pos.len(), 5);
        assert_abs_diff_eq!(pos[4].a_deg, 360.0);
        assert_abs_diff_eq!(pos[1].x_mm, 100.5);
        assert_eq!(e.circuits, 2);
    }

    #[test]
    fn absolute_mode_and_missing_axes() {
        let e = PartProgram::parse("O 1; G90 X 10; A 5; G91 X 1; Y 2 M30;")
            .unwrap()
            .expand()
            .unwrap();
        let p = e.positions();
        assert_eq!(
            p[4],
            Position {
                a_deg: 5.0,
                x_mm: 11.0,
                y_mm: 2.0
            }
        );
    }

    #[test]
    fn bad_programs_name_line_and_column() {
        assert_eq!(
            err("%\nO 1;\nN 10 Q 5;\nM30;\n%\n"),
            "3:6: unknown word 'Q'"
        );
        assert_eq!(
            err("O 9; X 1;\nO 1; M98 P 9; M30;"),
            "1:1: subprogram O9 does not end with M99"
        );
        assert_eq!(
            err("O 1;\n M98 P 7 L 2;\nM30;"),
            "2:2: M98 calls O7, which is not in the file"
        );
        assert!(
            err("O 5; M98 P 6; M99;\nO 6; M98 P 5; M99;\nO 1; M98 P 5; M30;")
                .starts_with("2:6: M98 calls O5 recursively"),
        );
        assert_eq!(
            err("O 1; M98 P 1; M30;"),
            "1:6: M98 calls O1 recursively (call chain O1 → O1)"
        );
        assert_eq!(err("X 1;"), "1:1: block before the first O program number");
        assert_eq!(
            err("O 1; G02 X 1;"),
            "1:6: G02 is not supported (G01, G90 and G91 are)"
        );
        assert_eq!(err("O 1; X 1 X 2;"), "1:10: X appears twice in the block");
        assert_eq!(err("O 1; X 1.2.3;"), "1:6: X: '1.2.3' is not a number");
        assert_eq!(err("O 1; P 3;"), "1:6: P is only allowed after M98");
        assert_eq!(
            err("O 1; M99; X 1;"),
            "1:11: block after the program's M99 or M30"
        );
        assert_eq!(err("O 1; X 1 # 2;"), "1:10: unexpected character '#'");
        assert_eq!(
            err("%\nO 1; M30;\n%\nX 5\n"),
            "4:1: text after the closing %"
        );
        assert_eq!(
            err("(only a comment"),
            "1:1: comment '(' is not closed on its line"
        );
        assert_eq!(err(""), "1:1: no blocks in the part program");
        assert_eq!(
            err("O 1; M99;"),
            "1:1: no main program (every program ends with M99)"
        );
        assert_eq!(
            err("O 1; M98 L 2;"),
            "1:6: M98 needs P (the subprogram number)"
        );
        assert_eq!(err("O 1; M98 P 2 L 0;"), "1:6: L must be ≥ 1");
        assert_eq!(err("O 1; F 0;"), "1:6: F must be > 0");
        assert_eq!(
            err("O 1; M30;\nO 1; M30;"),
            "2:1: program O1 is defined twice"
        );
    }

    #[test]
    fn comments_and_lowercase_are_accepted() {
        let p = PartProgram::parse("(cylinder) o 1 (start);\nx 5 (out);\nm30;").unwrap();
        let main = p.main().unwrap();
        assert_eq!(main.blocks[0].comment.as_deref(), Some("cylinder start"));
        assert_eq!(main.blocks[1].x_mm, Some(5.0));
        assert_eq!(main.blocks[1].comment.as_deref(), Some("out"));
    }

    /// The written layout: `%`, the first program at once, a blank line before each later one.
    #[test]
    fn written_programs_are_separated_by_one_blank_line() {
        let text = PartProgram::parse(FIG_9_1).unwrap().to_string();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(&lines[..2], &["%", "O 999;"]);
        let second = lines.iter().position(|l| *l == "O 998;").unwrap();
        assert_eq!(lines[second - 1], "");
        assert_eq!(lines.iter().filter(|l| l.is_empty()).count(), 1);
    }

    #[test]
    fn a_motion_block_carries_all_three_axes() {
        let b = Block::motion(1.5, -2.0, 0.0);
        assert_eq!(
            (b.a_deg, b.x_mm, b.y_mm),
            (Some(1.5), Some(-2.0), Some(0.0))
        );
        assert!(b.moves());
    }

    #[test]
    fn a_lone_program_without_m99_or_m30_is_the_main_one() {
        let p = PartProgram::parse("O 5; X 1; Y 2;").unwrap();
        assert_eq!(p.main().unwrap().number, 5);
        assert_eq!(p.expand().unwrap().targets().count(), 2);
    }

    /// `MAX_CALL_DEPTH` calls within calls are accepted, one more is refused.
    #[test]
    fn call_depth_is_accepted_up_to_its_limit() {
        let chain = |depth: usize| {
            let mut text = String::new();
            for k in 1..depth {
                text.push_str(&format!("O {k}; M98 P {}; M99;\n", k + 1));
            }
            text.push_str(&format!("O {depth}; X 1; M99;\nO 100; M98 P 1; M30;\n"));
            PartProgram::parse(&text).unwrap().expand()
        };
        assert!(chain(MAX_CALL_DEPTH).is_ok());
        assert!(chain(MAX_CALL_DEPTH + 1).is_err());
    }

    #[test]
    fn whole_number_words_refuse_fractions_signs_overlong_and_overlarge_values() {
        for text in [
            "O 1; N 1.5 X 1; M30;",
            "O 1; N -5 X 1; M30;",
            "O 1; N 12345678901 X 1; M30;",
            "O 1; N 100000 X 1; M30;",
            "O 1; G 100; M30;",
            "O 1; M98 P 2 L 10000; M30;\nO 2; X 1; M99;",
        ] {
            let e = err(text);
            assert!(e.contains("is not a whole number"), "{text}: {e}");
        }
        assert!(PartProgram::parse("O 1; N 99999 X 1; M30;").is_ok());
    }

    #[test]
    fn deep_or_huge_expansions_are_refused() {
        let mut text = String::new();
        for k in 1..=12 {
            text.push_str(&format!("O {k}; M98 P {} L 2; M99;\n", k + 1));
        }
        text.push_str("O 13; X 1; M99;\nO 100; M98 P 1; M30;\n");
        assert!(err(&text).contains("nest deeper than 8"), "{}", err(&text));
        let huge = "O 2; X 1; M99;\nO 3; M98 P 2 L 9999; M99;\nO 4; M98 P 3 L 9999; M99;\nO 1; M98 P 4 L 9999; M30;";
        assert!(err(huge).contains("more than 1000000 moves"));
    }

    #[test]
    fn fw_cnc_par_reads_the_thesis_file() {
        let text = "FW-CNC.PAR  --  CNC filament winding machine parameters file
First three lines are for comments, all the other lines are also
formatted bearing an integer and a comment beginning with <;>.
20  ; Initial feed rate for manual control
10  ; Normal feed rate
30  ; Feed rate limit
20  ; Number of interrupts after which actual positions are recorded
4   ; Number of knot points to be interpolated between two points
";
        let p = MachineParameters::parse(text).unwrap();
        assert_eq!(p, MachineParameters::default());
        assert_eq!(
            (
                p.manual_feed,
                p.normal_feed,
                p.feed_limit,
                p.record_interval,
                p.knots_per_segment
            ),
            (20, 10, 30, 20, 4)
        );
        assert_eq!(MachineParameters::parse(&p.to_string()).unwrap(), p);
    }

    #[test]
    fn fw_cnc_par_errors_have_line_and_column() {
        let head = "a\nb\nc\n";
        let e = |body: &str| {
            MachineParameters::parse(&format!("{head}{body}"))
                .unwrap_err()
                .to_string()
        };
        assert_eq!(
            e("20\n10\n  x ; feed limit\n"),
            "6:3: Feed rate limit: 'x' is not a whole number from 1 to 100000"
        );
        assert_eq!(
            e("20\n10\n30\n40000\n4\n"),
            "7:1: Number of interrupts after which actual positions are recorded: '40000' is not a whole number from 1 to 32767"
        );
        assert!(e("20\n10\n30\n").starts_with("7:1: missing parameter line: Number of interrupts"));
        assert_eq!(
            e("1\n1\n1\n1\n1\n1\n"),
            "9:1: more than five parameter lines"
        );
        assert_eq!(e("1\n ; nothing\n"), "5:1: expected an integer before ';'");
    }

    proptest::proptest! {
        #[test]
        fn any_text_parses_or_errs_without_panic(text in "[%OoNGFAXYMPL0-9 .;()\n-]{0,120}") {
            if let Ok(p) = PartProgram::parse(&text) {
                let _ = p.expand();
            }
        }
    }
}
