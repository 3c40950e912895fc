//! Lathe-winder G-code in six dialects, written from the one motion representation
//! ([`paths::motion`]) and read back into it.
//!
//! | dialect    | mandrel | carriage | cross-feed | eye | coordinates            | feed                      |
//! |------------|---------|----------|------------|-----|------------------------|---------------------------|
//! | `fw-cnc`   | A       | X        | Y          | —   | G90, unwrapped A       | none (the controller's)   |
//! | `mach3`    | X       | Y        | Z          | A   | G91, increments        | G94, F over all words     |
//! | `grbl`     | A       | X        | Y          | B   | G90, `G92 A` re-zero   | G93 inverse time          |
//! | `linuxcnc` | A       | X        | Y          | B   | G90, unwrapped A       | G93 inverse time          |
//! | `marlin`   | A       | X        | Y          | B   | G90, `G92 A` re-zero   | G94, F over linear words  |
//! | `fanuc`    | A       | X        | Y          | B   | G91, increments        | G93 inverse time          |
//!
//! - `fw-cnc` is the part-program format of seed 000 Fig 9-1 (`;` ends a block, `%` marks the
//!   tape); it has no eye-rotation axis and no rapid word, so a 4-axis plan is refused and the
//!   first positioning is written as a `G01` block. `mach3` follows seed 002's Appendix A (`G91`,
//!   X the mandrel in degrees, F on the vector of all axis words as Mach3 applies it).
//! - Feed moves are `G1` with a feed that makes the move take its planned duration; `G0` appears
//!   only for true rapids (the first positioning before the tow is tied on).
//! - Values are written to 0.001 mm or degree. Incremental dialects write the difference of the
//!   rounded absolute positions, so the rounding never accumulates. GRBL and Marlin parse numbers
//!   as 32-bit floats (about 7 digits): before the written mandrel angle passes
//!   [`REZERO_BEYOND_DEG`] they re-zero it with `G92 A…` by whole turns. LinuxCNC keeps doubles
//!   and takes the unwrapped angle as it is.
//! - Layer boundaries are comments, `(layer N KIND …)` (`; layer N …` in Marlin), which the
//!   reader and the streamer use for pausing at a layer boundary.

use crate::Error;
use crate::machine::{FeedMode as Feed, LinearUnit, MachineProfile};
use paths::motion::{Axes, AxisSet, LayerKind, LayerMark, MotionSink, Move, MoveKind, Recording};
use std::io::{self, Write};

/// Written resolution: thousandths of a millimetre or a degree.
pub const UNITS_PER_LSB: f64 = 0.001;

/// Past this written mandrel angle, GRBL and Marlin programs re-zero it by whole turns.
pub const REZERO_BEYOND_DEG: f64 = 3600.0;

/// A controller's G-code.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dialect {
    /// Seed 000's Fig 9-1 part-program format (our lathe controller).
    FwCnc,
    /// Mach3, as seed 002's Appendix A.
    Mach3,
    /// GRBL 1.1 / grblHAL with A and B axes.
    Grbl,
    /// LinuxCNC.
    LinuxCnc,
    /// Marlin 2.1 with A and B axes.
    Marlin,
    /// FANUC-style (0i/30i class).
    Fanuc,
}

impl Dialect {
    /// Every dialect.
    pub const ALL: [Dialect; 6] = [
        Dialect::FwCnc,
        Dialect::Mach3,
        Dialect::Grbl,
        Dialect::LinuxCnc,
        Dialect::Marlin,
        Dialect::Fanuc,
    ];

    /// The name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Dialect::FwCnc => "fw-cnc",
            Dialect::Mach3 => "mach3",
            Dialect::Grbl => "grbl",
            Dialect::LinuxCnc => "linuxcnc",
            Dialect::Marlin => "marlin",
            Dialect::Fanuc => "fanuc",
        }
    }

    /// From a command-line name.
    pub fn from_name(name: &str) -> Option<Dialect> {
        Dialect::ALL.into_iter().find(|d| d.name() == name)
    }

    /// The usual file extension.
    pub fn extension(self) -> &'static str {
        match self {
            Dialect::FwCnc => "prg",
            Dialect::Mach3 => "tap",
            Dialect::Grbl => "nc",
            Dialect::LinuxCnc => "ngc",
            Dialect::Marlin => "gcode",
            Dialect::Fanuc => "nc",
        }
    }

    /// Axis letters of the dialect's usual winder: mandrel, carriage, cross-feed, eye.
    pub fn letters(self) -> [Option<u8>; 4] {
        match self {
            Dialect::FwCnc => [Some(b'A'), Some(b'X'), Some(b'Y'), None],
            Dialect::Mach3 => [Some(b'X'), Some(b'Y'), Some(b'Z'), Some(b'A')],
            _ => [Some(b'A'), Some(b'X'), Some(b'Y'), Some(b'B')],
        }
    }

    fn incremental(self) -> bool {
        matches!(self, Dialect::Mach3 | Dialect::Fanuc)
    }

    fn rezero(self) -> bool {
        matches!(self, Dialect::Grbl | Dialect::Marlin)
    }

    /// How the dialect's usual controller reads F on a multi-axis move.
    pub fn feed(self) -> Feed {
        match self {
            Dialect::FwCnc => Feed::None,
            Dialect::Mach3 => Feed::AllWords,
            Dialect::Marlin => Feed::LinearWords,
            _ => Feed::InverseTime,
        }
    }

    fn block_end(self) -> &'static str {
        if self == Dialect::FwCnc { ";\n" } else { "\n" }
    }
}

impl std::fmt::Display for Dialect {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

fn quantise(v: f64) -> i64 {
    (v * 1000.0).round() as i64
}

/// Appends `scaled` / 10^`decimals` as a decimal with trailing zeros dropped (`-1.5`, `30.006`,
/// `0`), without going through a formatter.
fn push_scaled(out: &mut Vec<u8>, scaled: i64, decimals: u32) {
    if scaled < 0 {
        out.push(b'-');
    }
    let mut m = scaled.unsigned_abs();
    let mut digits = [0u8; 24];
    let mut n = 0;
    // Fraction digits, least significant first, dropping trailing zeros.
    let mut frac_len = decimals as usize;
    for _ in 0..decimals {
        let d = (m % 10) as u8;
        m /= 10;
        if n == 0 && d == 0 {
            frac_len -= 1;
            continue;
        }
        digits[n] = b'0' + d;
        n += 1;
    }
    if frac_len > 0 {
        digits[n] = b'.';
        n += 1;
    }
    loop {
        digits[n] = b'0' + (m % 10) as u8;
        n += 1;
        m /= 10;
        if m == 0 {
            break;
        }
    }
    out.extend(digits[..n].iter().rev());
}

/// Appends `lsb` thousandths (see [`push_scaled`]).
fn push_fixed(out: &mut Vec<u8>, lsb: i64) {
    push_scaled(out, lsb, 3);
}

/// Appends a feed with six significant digits, trailing zeros dropped.
fn push_feed(out: &mut Vec<u8>, f: f64) {
    let decimals = (5 - f.abs().log10().floor() as i32).clamp(0, 9) as u32;
    push_scaled(
        out,
        (f * 10f64.powi(decimals as i32)).round() as i64,
        decimals,
    );
}

/// A feed word's value for a move of `delta` (axis units, written words only) taking
/// `duration_s`; and back.
fn feed_value(feed: Feed, delta: &[f64; 4], duration_s: f64) -> Option<f64> {
    let minutes = duration_s / 60.0;
    match feed {
        Feed::None => None,
        Feed::InverseTime => Some(1.0 / minutes),
        Feed::AllWords => Some(delta.iter().map(|d| d * d).sum::<f64>().sqrt() / minutes),
        Feed::LinearWords => Some(feed_length(delta) / minutes),
    }
}

/// Marlin's move length: the linear axes' distance, or the rotary axes' when no linear axis moves.
fn feed_length(delta: &[f64; 4]) -> f64 {
    let linear = delta[1].hypot(delta[2]);
    if linear > 0.0 {
        linear
    } else {
        delta[0].hypot(delta[3])
    }
}

fn duration_from(feed: Feed, delta: &[f64; 4], f: f64) -> f64 {
    match feed {
        Feed::None => 0.0,
        Feed::InverseTime => 60.0 / f,
        Feed::AllWords => delta.iter().map(|d| d * d).sum::<f64>().sqrt() / f * 60.0,
        Feed::LinearWords => feed_length(delta) / f * 60.0,
    }
}

/// What the program says about itself in its header.
#[derive(Debug, Clone, Default)]
pub struct Header {
    /// One-line title (the job file's name).
    pub title: String,
    /// The mandrel and tow for FiberPath's `; Parameters` header (written when the machine
    /// asks for it, [`MachineProfile::fiberpath_header`]).
    pub parameters: Option<Parameters>,
}

/// What FiberPath's `; Parameters {…}` header line carries: its reader refuses a program
/// without it (FiberPath 0.11, `fiberpath.gcode.reader`).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Parameters {
    /// The mandrel's diameter at the carriage's start, mm.
    pub diameter_mm: f64,
    /// The wound length, mm.
    pub wind_length_mm: f64,
    /// Tow (band) width, mm.
    pub tow_width_mm: f64,
    /// Tow thickness, mm.
    pub tow_thickness_mm: f64,
}

/// How the planner's frame maps onto a machine's written coordinates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frame {
    /// Axis letters: mandrel, carriage, cross-feed, eye (`None`: not written).
    pub letters: [Option<u8>; 4],
    /// How F is read.
    pub feed: Feed,
    /// Written value = (planner value + offset) / unit, per axis.
    pub offset: [f64; 4],
    /// Planner units (mm or degrees) per written unit, per axis.
    pub unit: [f64; 4],
    /// Linear units (G21 / G20).
    pub units: LinearUnit,
    /// FiberPath's header and no M-codes.
    pub fiberpath: bool,
}

impl Frame {
    /// The dialect's usual winder in the planner's own frame (carriage 0 at the mandrel's
    /// middle, millimetres).
    pub fn of_dialect(dialect: Dialect) -> Frame {
        Frame {
            letters: dialect.letters(),
            feed: dialect.feed(),
            offset: [0.0; 4],
            unit: [1.0; 4],
            units: LinearUnit::Mm,
            fiberpath: false,
        }
    }

    /// A machine profile's frame, the carriage's written zero `carriage_offset_mm` from the
    /// planner's (see [`MachineProfile::carriage_offset_mm`]).
    pub fn of_machine(machine: &MachineProfile, carriage_offset_mm: f64) -> Frame {
        let u = machine.units.mm();
        Frame {
            letters: std::array::from_fn(|i| machine.letter(i)),
            feed: machine.feed,
            offset: [0.0, carriage_offset_mm, 0.0, 0.0],
            unit: [1.0, u, u, 1.0],
            units: machine.units,
            fiberpath: machine.fiberpath_header,
        }
    }

    /// A planner value of axis `i` as written (before rounding).
    pub fn to_machine(&self, i: usize, planner: f64) -> f64 {
        (planner + self.offset[i]) / self.unit[i]
    }

    /// A written value of axis `i` in the planner's frame.
    pub fn to_planner(&self, i: usize, written: f64) -> f64 {
        written * self.unit[i] - self.offset[i]
    }

    fn units_word(&self) -> &'static str {
        match self.units {
            LinearUnit::Mm => "G21",
            LinearUnit::Inch => "G20",
        }
    }
}

/// Writes a plan as G-code while it is being made ([`MotionSink`]): memory stays bounded
/// whatever the plan's size.
#[derive(Debug)]
pub struct Writer<W: Write> {
    out: W,
    dialect: Dialect,
    frame: Frame,
    axes: [bool; 4],
    /// The last written position, in LSB of the machine's (unwrapped) coordinates.
    written: [i64; 4],
    /// The mandrel's written-coordinate offset (G92 re-zero), LSB.
    mandrel_offset: i64,
    line: Vec<u8>,
    lines: u64,
    started: bool,
    incremental_mode: bool,
}

impl<W: Write> Writer<W> {
    /// Starts a program for a machine with `axes`; writes the prologue. A dialect without an
    /// axis the machine uses is refused (`fw-cnc` has no eye rotation).
    pub fn new(out: W, dialect: Dialect, axes: AxisSet, header: &Header) -> Result<Self, Error> {
        let used = [true, true, axes.cross_feed(), axes.eye_rotation()];
        let letters = dialect.letters();
        if let Some(missing) = (0..4).find(|&i| used[i] && letters[i].is_none()) {
            let name = ["mandrel", "carriage", "cross-feed", "eye rotation"][missing];
            return Err(Error::content(format!(
                "the {dialect} dialect has no {name} axis: plan for a machine without it \
                 (axes = 3 or 2)"
            )));
        }
        Writer::in_frame(out, dialect, Frame::of_dialect(dialect), used, header)
    }

    /// Starts a program in a machine's `frame`, writing the axes that are both `used` by the plan
    /// and in the frame (an axis the machine lacks must stay where it is: checked beforehand by
    /// [`crate::machine::Extent`]).
    pub fn in_frame(
        out: W,
        dialect: Dialect,
        frame: Frame,
        used: [bool; 4],
        header: &Header,
    ) -> Result<Self, Error> {
        let mut w = Writer {
            out,
            dialect,
            frame,
            axes: std::array::from_fn(|i| used[i] && frame.letters[i].is_some()),
            written: [0; 4],
            mandrel_offset: 0,
            line: Vec::with_capacity(128),
            lines: 0,
            started: false,
            incremental_mode: false,
        };
        w.prologue(header)
            .map_err(|e| Error::content(e.to_string()))?;
        Ok(w)
    }

    /// Lines written so far.
    pub fn lines(&self) -> u64 {
        self.lines
    }

    fn comment(&mut self, text: &str) -> io::Result<()> {
        let clean: String = text
            .chars()
            .filter(|c| !matches!(c, '(' | ')' | ';' | '\n' | '\r'))
            .collect();
        if self.dialect == Dialect::Marlin {
            self.raw(&format!("; {clean}\n"))
        } else {
            self.raw(&format!("({clean})\n"))
        }
    }

    fn raw(&mut self, text: &str) -> io::Result<()> {
        self.lines += text.matches('\n').count() as u64;
        self.out.write_all(text.as_bytes())
    }

    fn block(&mut self, text: &str) -> io::Result<()> {
        let end = self.dialect.block_end();
        self.raw(&format!("{text}{end}"))
    }

    fn prologue(&mut self, header: &Header) -> io::Result<()> {
        let title = format!("windcell lathe plan: {} ({})", header.title, self.dialect);
        if self.frame.fiberpath {
            self.comment(&title)?;
            let p = header.parameters.unwrap_or_default();
            self.raw(&fiberpath_parameters(&p))?;
            let units = self.frame.units_word();
            return self.raw(&format!("{units}\nG90\nG94\n"));
        }
        let units = self.frame.units_word();
        match self.dialect {
            Dialect::FwCnc => {
                self.raw("%\n")?;
                self.raw("O 1;\n")?;
                self.comment(&title)?;
                self.block("G01 G90")
            }
            Dialect::Mach3 => {
                self.comment(&title)?;
                self.raw(&format!("{units} G19 G94 G90\n"))
            }
            Dialect::Grbl => {
                self.comment(&title)?;
                self.raw(&format!("{units} G90 {}\n", self.feed_mode_word()))
            }
            Dialect::LinuxCnc => {
                self.comment(&title)?;
                self.raw(&format!(
                    "{units} G90 {} G64 P0.01\n",
                    self.feed_mode_word()
                ))
            }
            Dialect::Marlin => {
                self.comment(&title)?;
                self.raw(&format!("{units}\nG90\n{}\n", self.feed_mode_word()))
            }
            Dialect::Fanuc => {
                self.raw("%\nO0001\n")?;
                self.comment(&title)?;
                self.raw(&format!("{units} G90 {}\n", self.feed_mode_word()))
            }
        }
    }

    /// G93 when the machine reads F as an inverse time, else G94.
    fn feed_mode_word(&self) -> &'static str {
        if self.frame.feed == Feed::InverseTime {
            "G93"
        } else {
            "G94"
        }
    }

    /// Writes the epilogue and flushes; returns the output and the number of lines written.
    pub fn finish(mut self) -> io::Result<(W, u64)> {
        if self.frame.fiberpath {
            // FiberPath's reader takes G0, G1, G21, G90, G92 and G94 only: no program end.
            self.out.flush()?;
            return Ok((self.out, self.lines));
        }
        match self.dialect {
            Dialect::FwCnc => {
                self.block("M30")?;
                self.raw("%\n")?;
            }
            Dialect::Mach3 | Dialect::Grbl => self.raw("M30\n")?,
            Dialect::LinuxCnc => self.raw("M2\n")?,
            Dialect::Marlin => self.raw("M400\n")?,
            Dialect::Fanuc => self.raw("M30\n%\n")?,
        }
        self.out.flush()?;
        Ok((self.out, self.lines))
    }
}

impl<W: Write> MotionSink for Writer<W> {
    type Error = io::Error;

    fn layer(&mut self, mark: &LayerMark) -> io::Result<()> {
        let kind = match mark.kind {
            LayerKind::Hoop => "hoop",
            LayerKind::Helical => "helical",
            LayerKind::Skip => "skip",
            LayerKind::Polar => "polar",
        };
        self.comment(&format!(
            "layer {} {kind}: {} circuits, radius {:.3} mm, angle {:.3} deg, tow {:.1} mm",
            mark.number,
            mark.circuits,
            mark.winding_radius_mm,
            mark.wind_angle_deg,
            mark.tow_length_mm
        ))
    }

    fn motion(&mut self, m: &Move) -> io::Result<()> {
        let planned = m.to.to_array();
        let target: [i64; 4] =
            std::array::from_fn(|i| quantise(self.frame.to_machine(i, planned[i])));
        let letters = self.frame.letters;
        let mut line = std::mem::take(&mut self.line);
        line.clear();
        // Mode switches for the incremental dialects: the first (absolute) positioning, then G91.
        let incremental = self.dialect.incremental() && self.started;
        if self.dialect.incremental() && incremental && !self.incremental_mode {
            line.extend_from_slice(b"G91\n");
            self.lines += 1;
            self.incremental_mode = true;
        }
        // GRBL/Marlin: re-zero the mandrel by whole turns before the written angle grows long.
        if self.dialect.rezero() {
            let shown = target[0] - self.mandrel_offset;
            if shown.unsigned_abs() as f64 * UNITS_PER_LSB > REZERO_BEYOND_DEG {
                let turns = (self.written[0] - self.mandrel_offset).div_euclid(360_000);
                self.mandrel_offset += turns * 360_000;
                line.extend_from_slice(b"G92 A");
                push_fixed(&mut line, self.written[0] - self.mandrel_offset);
                line.push(b'\n');
                self.lines += 1;
            }
        }
        let rapid = m.kind == MoveKind::Rapid && self.dialect != Dialect::FwCnc;
        line.extend_from_slice(if rapid {
            b"G0"
        } else if self.dialect == Dialect::FwCnc {
            b"G01"
        } else {
            b"G1"
        });
        let mut delta = [0.0; 4];
        let mut any = false;
        for i in 0..4 {
            if !self.axes[i] {
                continue;
            }
            let changed = target[i] != self.written[i];
            if changed || (!self.started && m.kind == MoveKind::Rapid && i > 0) {
                let Some(letter) = letters[i] else { continue };
                line.push(b' ');
                line.push(letter);
                let value = if incremental {
                    target[i] - self.written[i]
                } else if i == 0 {
                    target[i] - self.mandrel_offset
                } else {
                    target[i]
                };
                push_fixed(&mut line, value);
                delta[i] = (target[i] - self.written[i]) as f64 * UNITS_PER_LSB;
                any = true;
            }
        }
        if !any {
            self.line = line;
            return Ok(());
        }
        if !rapid && m.duration_s > 0.0 {
            let words: [f64; 4] = std::array::from_fn(|i| {
                if letters[i].is_some() && self.axes[i] {
                    delta[i]
                } else {
                    0.0
                }
            });
            if let Some(f) = feed_value(self.frame.feed, &words, m.duration_s) {
                line.extend_from_slice(b" F");
                push_feed(&mut line, f);
            }
        }
        line.extend_from_slice(self.dialect.block_end().as_bytes());
        self.lines += 1;
        self.started = true;
        self.written = target;
        let result = self.out.write_all(&line);
        self.line = line;
        result
    }
}

/// FiberPath's `; Parameters {…}` line: the mandrel and the tow as JSON.
fn fiberpath_parameters(p: &Parameters) -> String {
    let mandrel = format!(
        "\"mandrel\": {{\"diameter\": {}, \"windLength\": {}}}",
        p.diameter_mm, p.wind_length_mm
    );
    let tow = format!(
        "\"tow\": {{\"width\": {}, \"thickness\": {}}}",
        p.tow_width_mm, p.tow_thickness_mm
    );
    format!("; Parameters {{{mandrel}, {tow}}}\n")
}

/// A program read back: its moves (absolute, unwrapped, with durations from the feed words) and
/// its layer boundaries.
pub fn read(text: &str, dialect: Dialect) -> Result<Recording, Error> {
    read_in_frame(text, dialect, &Frame::of_dialect(dialect))
}

/// A program written in a machine's `frame` read back into the planner's frame (moves of the
/// axes the machine lacks keep the value they had, 0 from the start).
pub fn read_in_frame(text: &str, dialect: Dialect, frame: &Frame) -> Result<Recording, Error> {
    let mut rec = Recording::default();
    let mut modal = Modal::default();
    for (n, raw_line) in text.lines().enumerate() {
        let line_no = n + 1;
        let code = strip_comments(raw_line, line_no, dialect, &mut rec)?;
        let code = code.trim();
        let code = if dialect == Dialect::FwCnc {
            code.strip_suffix(';').unwrap_or(code).trim_end()
        } else {
            code
        };
        if code.is_empty() || code == "%" {
            continue;
        }
        let words = words_of(code, raw_line, line_no)?;
        let block = modal.block(&words, line_no, dialect, frame)?;
        if let Some(m) = modal.apply(&block, frame) {
            rec.moves.push(m);
        }
    }
    Ok(rec)
}

/// A line's code without its comments (`( … )`, and `; …` in Marlin), noting the layer marks
/// the comments carry.
fn strip_comments(
    raw_line: &str,
    line_no: usize,
    dialect: Dialect,
    rec: &mut Recording,
) -> Result<String, Error> {
    let mut code = String::with_capacity(raw_line.len());
    let mut rest = raw_line;
    while !rest.is_empty() {
        if dialect == Dialect::Marlin && rest.starts_with(';') {
            note_layer(&rest[1..], rec);
            break;
        }
        if let Some(body) = rest.strip_prefix('(') {
            let Some(end) = body.find(')') else {
                return Err(Error::at(
                    line_no,
                    raw_line.len() - rest.len() + 1,
                    "comment without `)`",
                ));
            };
            note_layer(&body[..end], rec);
            rest = &body[end + 1..];
            continue;
        }
        let ch = rest.chars().next().expect("not empty");
        code.push(ch);
        rest = &rest[ch.len_utf8()..];
    }
    Ok(code)
}

/// A word: its letter (upper case), its number and its 1-based column in the raw line.
type Word = (u8, f64, usize);

/// The words of a line's code: a letter and a number, spaces allowed between them.
fn words_of(code: &str, raw_line: &str, line_no: usize) -> Result<Vec<Word>, Error> {
    let bytes = code.as_bytes();
    let mut i = 0;
    let mut words: Vec<Word> = Vec::with_capacity(8);
    while i < bytes.len() {
        if bytes[i] == b' ' {
            i += 1;
            continue;
        }
        let col = raw_line.len() - raw_line.trim_start().len() + i + 1;
        let letter = bytes[i].to_ascii_uppercase();
        if !letter.is_ascii_alphabetic() {
            return Err(Error::at(
                line_no,
                col,
                format!("expected a word letter, found `{}`", bytes[i] as char),
            ));
        }
        i += 1;
        while i < bytes.len() && bytes[i] == b' ' {
            i += 1;
        }
        let start = i;
        while i < bytes.len() && matches!(bytes[i], b'0'..=b'9' | b'.' | b'-' | b'+') {
            i += 1;
        }
        let value: f64 = code[start..i]
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite())
            .ok_or_else(|| {
                Error::at(
                    line_no,
                    col,
                    format!("word {} has no number", letter as char),
                )
            })?;
        words.push((letter, value, col));
    }
    Ok(words)
}

/// What one block asks for.
struct Block {
    motion: Option<MoveKind>,
    /// `G92`: the position is set, nothing moves.
    set_position: bool,
    feed: Option<f64>,
    /// The axes' words, in the machine's axis order.
    axis_words: [Option<f64>; 4],
}

/// The reader's modal state: where the axes stand (written frame), the `G92` offset of the
/// first axis, `G91` and `G93`.
#[derive(Default)]
struct Modal {
    pos: [f64; 4],
    offset: f64,
    incremental: bool,
    inverse_time: bool,
}

impl Modal {
    /// Reads a block's words, taking its modal words (`G90`/`G91`, `G93`/`G94`) into the
    /// state; refuses a word the dialect's writer does not write.
    fn block(
        &mut self,
        words: &[Word],
        line_no: usize,
        dialect: Dialect,
        frame: &Frame,
    ) -> Result<Block, Error> {
        let mut block = Block {
            motion: None,
            set_position: false,
            feed: None,
            axis_words: [None; 4],
        };
        for &(letter, value, col) in words {
            let bad = |what: &str| Error::at(line_no, col, format!("{what} in {dialect}"));
            match letter {
                b'G' => match value as i64 {
                    0 if value == 0.0 => block.motion = Some(MoveKind::Rapid),
                    1 if value == 1.0 => block.motion = Some(MoveKind::Feed),
                    90 => self.incremental = false,
                    91 => self.incremental = true,
                    92 => block.set_position = true,
                    93 => self.inverse_time = true,
                    94 => self.inverse_time = false,
                    17..=21 => {}
                    64 => {}
                    _ => return Err(bad(&format!("G{value} is not written"))),
                },
                b'M' => match value as i64 {
                    2 | 30 | 400 => {}
                    _ => return Err(bad(&format!("M{value} is not written"))),
                },
                b'F' => block.feed = Some(value),
                b'O' | b'N' => {}
                b'P' if words.iter().any(|w| w.0 == b'G' && w.1 == 64.0) => {}
                l => {
                    let Some(axis) = frame.letters.iter().position(|x| *x == Some(l)) else {
                        return Err(bad(&format!("axis {} is not written", l as char)));
                    };
                    block.axis_words[axis] = Some(value);
                }
            }
        }
        Ok(block)
    }

    /// Carries out a block: `G92` sets the offset; a block with axis words moves them (the move
    /// in the planner's frame, its duration from the feed word).
    fn apply(&mut self, block: &Block, frame: &Frame) -> Option<Move> {
        let axis_words = &block.axis_words;
        let pos = self.pos;
        if block.set_position {
            if let Some(v) = axis_words[0] {
                self.offset = pos[0] - v;
            }
            return None;
        }
        if axis_words.iter().all(Option::is_none) {
            return None;
        }
        let kind = block.motion.unwrap_or(MoveKind::Feed);
        let mut next = pos;
        for i in 0..4 {
            if let Some(v) = axis_words[i] {
                next[i] = if self.incremental {
                    pos[i] + v
                } else if i == 0 {
                    v + self.offset
                } else {
                    v
                };
            }
        }
        let delta: [f64; 4] = std::array::from_fn(|i| {
            if axis_words[i].is_some() {
                next[i] - pos[i]
            } else {
                0.0
            }
        });
        let duration_s = match (kind, block.feed) {
            (MoveKind::Rapid, _) => 0.0,
            (MoveKind::Feed, Some(f)) if f > 0.0 => {
                let mode = if frame.feed == Feed::InverseTime && !self.inverse_time {
                    Feed::AllWords
                } else {
                    frame.feed
                };
                duration_from(mode, &delta, f)
            }
            (MoveKind::Feed, _) => 0.0,
        };
        self.pos = next;
        Some(Move {
            kind,
            to: Axes::from_array(std::array::from_fn(|i| frame.to_planner(i, next[i]))),
            duration_s,
        })
    }
}

/// Records a layer mark from a comment `layer N KIND: C circuits, …`.
fn note_layer(comment: &str, rec: &mut Recording) {
    let mut it = comment.split_whitespace();
    if it.next() != Some("layer") {
        return;
    }
    let Some(number) = it.next().and_then(|n| n.parse().ok()) else {
        return;
    };
    let kind = match it.next() {
        Some("hoop:") => LayerKind::Hoop,
        Some("helical:") => LayerKind::Helical,
        Some("skip:") => LayerKind::Skip,
        Some("polar:") => LayerKind::Polar,
        _ => return,
    };
    let circuits = it.next().and_then(|c| c.parse().ok()).unwrap_or(0);
    rec.layer_starts.push(rec.moves.len());
    rec.layers.push(LayerMark {
        number,
        kind,
        circuits,
        tow_length_mm: 0.0,
        winding_radius_mm: 0.0,
        wind_angle_deg: 0.0,
    });
}

#[cfg(test)]
mod tests;
