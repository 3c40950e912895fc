//! Machine profiles: which axes a lathe winder has, the letter each answers to, its units, where
//! its carriage zero is, how its controller applies a feed word, and its travel (soft limits).
//!
//! A profile is a small TOML file (`--machine FILE.toml`) or one of the built-ins
//! ([`MachineProfile::builtin`]):
//!
//! | name             | axes (mandrel, carriage, cross-feed, eye) | carriage zero  | feed                       | source |
//! |------------------|-------------------------------------------|----------------|----------------------------|--------|
//! | `fiberpath-xab`  | A, X, —, B                                | mandrel start  | F over the linear words    | FiberPath 0.11's `marlin-xab` profile (carriage X, mandrel A, delivery head B) |
//! | `fw-cnc`         | A, X, Y, —                                | mandrel middle | none (the controller's)    | seed 000 (Haq 1994) §4, Fig 9-1; travel X 0…1000, Y 0…200 mm from machine zero, part zero X 150, Y 10 |
//! | `grbl-4axis`     | A, X, Y, B                                | mandrel start  | G93 inverse time           | GRBL 1.1 / grblHAL with A and B |
//! | `linuxcnc-4axis` | A, X, Y, B                                | mandrel start  | G93 inverse time           | LinuxCNC `trivkins coordinates=XYAB` |
//! | `marlin-4axis`   | A, X, Y, B                                | mandrel start  | F over the linear words    | Marlin 2.1 with `AXIS4_ROTATES`, `AXIS5_ROTATES` |
//! | `mach3-4axis`    | X, Y, Z, A                                | mandrel start  | F over every word          | seed 002 Appendix A (X the mandrel in degrees) |
//! | `fanuc-4axis`    | A, X, Y, B                                | mandrel start  | G93 inverse time           | FANUC 0i/30i class |
//!
//! The planner's frame ([`paths::motion`]) has the carriage at 0 in the middle of the mandrel.
//! A profile's `origin` says where the written carriage zero is: `mandrel-start`, the end of
//! the mandrel where winding starts (the large end of a cone, the base of a nose, the first
//! polar opening's plane of a vessel), so the carriage runs 0 … wound length as in FiberPath's
//! programs; or `mandrel-middle`, the planner's own frame (seed 000's part zero). The mandrel
//! angle's zero is where the program starts; the cross-feed is the eye's distance from the
//! mandrel axis; the eye's zero has its roller axis along the mandrel axis.
//!
//! The file:
//!
//! ```toml
//! name = "my-winder"
//! units = "mm"              # linear axes: "mm" or "inch"; rotary axes are in degrees
//! origin = "mandrel-start"  # carriage zero: "mandrel-start" or "mandrel-middle"
//! feed = "linear-words"     # "inverse-time", "linear-words", "all-words" or "none"
//! fiberpath_header = false  # FiberPath's `; Parameters` header, no M-codes (its reader's codes)
//!
//! [axes.mandrel]            # required
//! letter = "A"
//! [axes.carriage]           # required
//! letter = "X"
//! min = 0.0                 # travel, in the program's coordinates (optional)
//! max = 1500.0
//! [axes.cross_feed]         # optional: without it the eye stays where it is
//! letter = "Y"
//! [axes.eye]                # optional
//! letter = "B"
//! min = -90.0
//! max = 90.0
//! ```

use std::path::Path;

use serde::Deserialize;
use toml::Spanned;

use crate::Error;
use crate::gcode::Frame;
use paths::motion::{LayerMark, MotionSink, Move};

/// How a controller reads a feed word on a multi-axis move.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FeedMode {
    /// No feed word (the controller's own feed, seed 000's FW-CNC).
    None,
    /// G93: F is the inverse of the move's time in minutes (GRBL, LinuxCNC, FANUC).
    InverseTime,
    /// G94: F is the distance over every axis word per minute, degrees counted as millimetres
    /// (Mach3, seed 002 Appendix A).
    AllWords,
    /// G94: F is the distance over the linear axes per minute; the rotary axes' when no linear
    /// axis moves (Marlin 2.1's planner with rotational axes).
    LinearWords,
}

impl FeedMode {
    fn from_name(name: &str) -> Option<FeedMode> {
        Some(match name {
            "none" => FeedMode::None,
            "inverse-time" => FeedMode::InverseTime,
            "all-words" => FeedMode::AllWords,
            "linear-words" => FeedMode::LinearWords,
            _ => return None,
        })
    }
}

/// Where the written carriage zero is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Origin {
    /// The end of the mandrel where winding starts: the carriage runs 0 … wound length.
    MandrelStart,
    /// The middle of the mandrel (the planner's frame; seed 000's part zero).
    MandrelMiddle,
}

/// Linear units of the written program.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LinearUnit {
    /// Millimetres (G21).
    Mm,
    /// Inches (G20).
    Inch,
}

impl LinearUnit {
    /// Millimetres per unit.
    pub fn mm(self) -> f64 {
        match self {
            LinearUnit::Mm => 1.0,
            LinearUnit::Inch => 25.4,
        }
    }
}

/// One axis of a machine.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MachineAxis {
    /// The address letter (`A`, `X`, …).
    pub letter: u8,
    /// Lowest written value allowed (program coordinates, the axis's units).
    pub min: Option<f64>,
    /// Highest written value allowed.
    pub max: Option<f64>,
}

/// The axes in the planner's order.
pub const AXIS_NAMES: [&str; 4] = ["mandrel", "carriage", "cross_feed", "eye"];

/// A lathe winder's profile.
#[derive(Debug, Clone, PartialEq)]
pub struct MachineProfile {
    /// Its name (a built-in's, or the file's `name`).
    pub name: String,
    /// Mandrel, carriage, cross-feed, eye; `None` where the machine has no such axis.
    pub axes: [Option<MachineAxis>; 4],
    /// Where the carriage zero is.
    pub origin: Origin,
    /// Linear units.
    pub units: LinearUnit,
    /// How the controller reads F.
    pub feed: FeedMode,
    /// Write FiberPath's `; Parameters {…}` header and no M-codes, so that `fiberpath simulate`
    /// and `fiberpath plot` read the program.
    pub fiberpath_header: bool,
    /// Where each field is in the file (for soft-limit refusals), `FILE:LINE:COL` of `min` and
    /// `max` per axis; empty for built-ins.
    pub limit_places: [[Option<String>; 2]; 4],
}

/// The built-in profiles' names.
pub const BUILTINS: [&str; 7] = [
    "fiberpath-xab",
    "fw-cnc",
    "grbl-4axis",
    "linuxcnc-4axis",
    "marlin-4axis",
    "mach3-4axis",
    "fanuc-4axis",
];

fn axis(letter: u8, min: Option<f64>, max: Option<f64>) -> Option<MachineAxis> {
    Some(MachineAxis { letter, min, max })
}

impl MachineProfile {
    /// A built-in profile by name (see the module's table).
    pub fn builtin(name: &str) -> Option<MachineProfile> {
        let four = |letters: [u8; 4], feed: FeedMode| MachineProfile {
            name: name.to_string(),
            axes: letters.map(|l| axis(l, None, None)),
            origin: Origin::MandrelStart,
            units: LinearUnit::Mm,
            feed,
            fiberpath_header: false,
            limit_places: Default::default(),
        };
        Some(match name {
            "fiberpath-xab" => MachineProfile {
                axes: [
                    axis(b'A', None, None),
                    axis(b'X', None, None),
                    None,
                    axis(b'B', None, None),
                ],
                fiberpath_header: true,
                ..four([b'A', b'X', b'Y', b'B'], FeedMode::LinearWords)
            },
            // Seed 000 §4: travel X 0…1000 mm, Y 0…200 mm from machine zero; part zero X 150,
            // Y 10 (seed 003 §4.2), so the program's X runs −150 … 850 and Y −10 … 190.
            "fw-cnc" => MachineProfile {
                axes: [
                    axis(b'A', None, None),
                    axis(b'X', Some(-150.0), Some(850.0)),
                    axis(b'Y', Some(-10.0), Some(190.0)),
                    None,
                ],
                origin: Origin::MandrelMiddle,
                ..four([b'A', b'X', b'Y', b'B'], FeedMode::None)
            },
            "grbl-4axis" | "linuxcnc-4axis" | "fanuc-4axis" => {
                four([b'A', b'X', b'Y', b'B'], FeedMode::InverseTime)
            }
            "marlin-4axis" => four([b'A', b'X', b'Y', b'B'], FeedMode::LinearWords),
            "mach3-4axis" => four([b'X', b'Y', b'Z', b'A'], FeedMode::AllWords),
            _ => return None,
        })
    }

    /// Reads a profile file; every refusal names the file, line and column.
    pub fn load(path: &Path) -> Result<MachineProfile, Error> {
        let text = crate::source::read_text(path, crate::source::MAX_JOB_BYTES)?;
        MachineProfile::parse(&text, &path.display().to_string()).map_err(|e| e.in_file(path))
    }

    /// Parses a profile's text; `file` names it in the soft-limit places.
    pub fn parse(text: &str, file: &str) -> Result<MachineProfile, Error> {
        let raw: RawProfile = toml::from_str(text).map_err(|e| {
            let (offset, message) = crate::error::toml_refusal(&e);
            Error::at_offset(text, offset, message)
        })?;
        let at = |span: std::ops::Range<usize>, message: String| {
            Error::at_offset(text, span.start, message)
        };
        let choice = |s: &Spanned<String>, what: &str, names: &str| {
            at(
                s.span(),
                format!("{what} `{}`: one of {names}", s.get_ref()),
            )
        };
        let units = match raw.units.as_ref().map(|s| s.get_ref().as_str()) {
            None | Some("mm") => LinearUnit::Mm,
            Some("inch") => LinearUnit::Inch,
            Some(_) => {
                let s = raw.units.as_ref().expect("matched Some");
                return Err(choice(s, "units", "mm, inch"));
            }
        };
        let origin = match raw.origin.as_ref().map(|s| s.get_ref().as_str()) {
            None | Some("mandrel-start") => Origin::MandrelStart,
            Some("mandrel-middle") => Origin::MandrelMiddle,
            Some(_) => {
                let s = raw.origin.as_ref().expect("matched Some");
                return Err(choice(s, "origin", "mandrel-start, mandrel-middle"));
            }
        };
        let feed = FeedMode::from_name(raw.feed.get_ref()).ok_or_else(|| {
            choice(
                &raw.feed,
                "feed",
                "inverse-time, linear-words, all-words, none",
            )
        })?;
        let mut axes = [None; 4];
        let mut limit_places: [[Option<String>; 2]; 4] = Default::default();
        let mut seen: Vec<u8> = Vec::new();
        let raws = [
            Some(&raw.axes.mandrel),
            Some(&raw.axes.carriage),
            raw.axes.cross_feed.as_ref(),
            raw.axes.eye.as_ref(),
        ];
        for (i, a) in raws.into_iter().enumerate() {
            let Some(a) = a else { continue };
            let letter = a.letter.get_ref();
            let byte = match letter.as_bytes() {
                [b] if b"XYZABCUVW".contains(&b.to_ascii_uppercase()) => b.to_ascii_uppercase(),
                _ => {
                    return Err(at(
                        a.letter.span(),
                        format!(
                            "axes.{}.letter `{letter}`: one of X, Y, Z, A, B, C, U, V, W",
                            AXIS_NAMES[i]
                        ),
                    ));
                }
            };
            if seen.contains(&byte) {
                return Err(at(
                    a.letter.span(),
                    format!(
                        "axes.{}.letter `{letter}` is already another axis's letter",
                        AXIS_NAMES[i]
                    ),
                ));
            }
            seen.push(byte);
            let mut bound = |v: &Option<Spanned<f64>>, k: usize| -> Result<Option<f64>, Error> {
                let Some(v) = v else { return Ok(None) };
                if !v.get_ref().is_finite() {
                    return Err(at(
                        v.span(),
                        format!(
                            "axes.{}: a travel limit must be a finite number",
                            AXIS_NAMES[i]
                        ),
                    ));
                }
                let (line, col) = crate::error::line_column(text, v.span().start);
                limit_places[i][k] = Some(format!("{file}:{line}:{col}"));
                Ok(Some(*v.get_ref()))
            };
            let min = bound(&a.min, 0)?;
            let max = bound(&a.max, 1)?;
            if let (Some(lo), Some(hi), Some(m)) = (min, max, &a.max)
                && lo >= hi
            {
                return Err(at(
                    m.span(),
                    format!(
                        "axes.{}: max = {} is not above min = {}",
                        AXIS_NAMES[i],
                        crate::error::shown(hi),
                        crate::error::shown(lo)
                    ),
                ));
            }
            axes[i] = Some(MachineAxis {
                letter: byte,
                min,
                max,
            });
        }
        let name = raw.name.get_ref().trim().to_string();
        if name.is_empty() {
            return Err(at(raw.name.span(), "name is empty".to_string()));
        }
        Ok(MachineProfile {
            name,
            axes,
            origin,
            units,
            feed,
            fiberpath_header: raw.fiberpath_header.unwrap_or(false),
            limit_places,
        })
    }

    /// The letter of axis `i` (planner order), if the machine has it.
    pub fn letter(&self, i: usize) -> Option<u8> {
        self.axes[i].map(|a| a.letter)
    }

    /// Whether axis `i` is linear (carriage, cross-feed).
    pub fn is_linear(i: usize) -> bool {
        i == 1 || i == 2
    }

    /// The machine's carriage coordinate of the planner's carriage 0 (the mandrel's middle),
    /// given where the mandrel starts in the planner's frame (a negative number), mm.
    pub fn carriage_offset_mm(&self, mandrel_start_mm: f64) -> f64 {
        match self.origin {
            Origin::MandrelStart => -mandrel_start_mm,
            Origin::MandrelMiddle => 0.0,
        }
    }
}

/// What a plan asks of a machine, in the machine's written coordinates: the range of every axis
/// and whether it moves after the first positioning. A [`MotionSink`]: run the plan into it
/// before writing, then [`MachineProfile::admits`].
#[derive(Debug, Clone)]
pub struct Extent {
    frame: Frame,
    /// Lowest written value per axis (planner order).
    pub lo: [f64; 4],
    /// Highest written value per axis.
    pub hi: [f64; 4],
    first: Option<[f64; 4]>,
    /// Whether the axis takes more than one value.
    pub moved: [bool; 4],
}

impl Extent {
    /// An empty extent in `frame`.
    pub fn new(frame: Frame) -> Extent {
        Extent {
            frame,
            lo: [f64::INFINITY; 4],
            hi: [f64::NEG_INFINITY; 4],
            first: None,
            moved: [false; 4],
        }
    }
}

impl MotionSink for Extent {
    type Error = std::convert::Infallible;
    fn layer(&mut self, _: &LayerMark) -> Result<(), Self::Error> {
        Ok(())
    }
    fn motion(&mut self, m: &Move) -> Result<(), Self::Error> {
        let p = m.to.to_array();
        let v: [f64; 4] = std::array::from_fn(|i| self.frame.to_machine(i, p[i]));
        let first = *self.first.get_or_insert(v);
        for i in 0..4 {
            self.lo[i] = self.lo[i].min(v[i]);
            self.hi[i] = self.hi[i].max(v[i]);
            // Beyond the written resolution (0.001).
            self.moved[i] |= (v[i] - first[i]).abs() >= 0.0005;
        }
        Ok(())
    }
}

impl MachineProfile {
    /// Whether the machine can run a plan of `extent` (for the axes the plan `used`): every axis
    /// that moves is one the machine has, and every written value is within its travel. The
    /// refusal names the profile's `min`/`max` (`FILE:LINE:COL`) where it came from a file.
    pub fn admits(&self, extent: &Extent, used: [bool; 4]) -> Result<(), Refusal> {
        const SPOKEN: [&str; 4] = ["mandrel", "carriage", "cross-feed", "eye-rotation"];
        for i in 0..4 {
            if !used[i] || extent.first.is_none() {
                continue;
            }
            let unit = if MachineProfile::is_linear(i) {
                match self.units {
                    LinearUnit::Mm => "mm",
                    LinearUnit::Inch => "in",
                }
            } else {
                "°"
            };
            let Some(axis) = self.axes[i] else {
                if extent.moved[i] {
                    return Err(Refusal::unplaced(format!(
                        "machine `{}` has no {} axis, and the plan moves it ({} … {} {unit}): \
                         choose a machine with one (--machine)",
                        self.name,
                        SPOKEN[i],
                        crate::error::shown(extent.lo[i]),
                        crate::error::shown(extent.hi[i])
                    )));
                }
                continue;
            };
            let letter = axis.letter as char;
            let beyond = |value: f64, bound: f64, which: usize| Refusal {
                place: self.limit_places[i][which].clone(),
                message: format!(
                    "the plan moves {letter} to {} {unit}, beyond {} = {} {unit} of machine `{}`",
                    crate::error::shown(value),
                    ["min", "max"][which],
                    crate::error::shown(bound),
                    self.name
                ),
            };
            if let Some(min) = axis.min
                && extent.lo[i] < min - 0.0005
            {
                return Err(beyond(extent.lo[i], min, 0));
            }
            if let Some(max) = axis.max
                && extent.hi[i] > max + 0.0005
            {
                return Err(beyond(extent.hi[i], max, 1));
            }
        }
        Ok(())
    }
}

/// Why a machine cannot run a plan.
#[derive(Debug, Clone, PartialEq)]
pub struct Refusal {
    /// `FILE:LINE:COL` of the profile's field that refuses it, when it came from a file.
    pub place: Option<String>,
    /// What is wrong.
    pub message: String,
}

impl Refusal {
    fn unplaced(message: String) -> Refusal {
        Refusal {
            place: None,
            message,
        }
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawProfile {
    name: Spanned<String>,
    units: Option<Spanned<String>>,
    origin: Option<Spanned<String>>,
    feed: Spanned<String>,
    fiberpath_header: Option<bool>,
    axes: RawAxes,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawAxes {
    mandrel: RawAxis,
    carriage: RawAxis,
    cross_feed: Option<RawAxis>,
    eye: Option<RawAxis>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawAxis {
    letter: Spanned<String>,
    min: Option<Spanned<f64>>,
    max: Option<Spanned<f64>>,
}

#[cfg(test)]
mod tests {
    use super::*;

    const FILE: &str = r#"name = "bench"
units = "mm"
origin = "mandrel-start"
feed = "linear-words"

[axes.mandrel]
letter = "A"
[axes.carriage]
letter = "X"
min = 0.0
max = 600.0
[axes.eye]
letter = "B"
"#;

    #[test]
    fn a_file_reads_with_its_limits_located() {
        let p = MachineProfile::parse(FILE, "bench.toml").unwrap();
        assert_eq!(p.letter(0), Some(b'A'));
        assert_eq!(p.letter(1), Some(b'X'));
        assert_eq!(p.letter(2), None);
        assert_eq!(p.letter(3), Some(b'B'));
        assert_eq!(p.axes[1].unwrap().max, Some(600.0));
        assert_eq!(p.limit_places[1][1].as_deref(), Some("bench.toml:11:7"));
        assert_eq!(p.carriage_offset_mm(-250.0), 250.0);
    }

    #[test]
    fn bad_fields_are_located() {
        for (from, to, expect) in [
            (
                "feed = \"linear-words\"",
                "feed = \"fast\"",
                "4:8: feed `fast`",
            ),
            ("units = \"mm\"", "units = \"cm\"", "2:9: units `cm`"),
            (
                "letter = \"B\"",
                "letter = \"X\"",
                "13:10: axes.eye.letter `X` is already",
            ),
            (
                "letter = \"B\"",
                "letter = \"G\"",
                "13:10: axes.eye.letter `G`: one of",
            ),
            (
                "max = 600.0",
                "max = -1.0",
                "11:7: axes.carriage: max = -1 is not above min = 0",
            ),
            (
                "origin = \"mandrel-start\"",
                "origin = \"tail\"",
                "3:10: origin `tail`",
            ),
            ("[axes.eye]", "[axes.tail]", "12:7: unknown field `tail`"),
        ] {
            let text = FILE.replace(from, to);
            let e = MachineProfile::parse(&text, "m.toml")
                .unwrap_err()
                .to_string();
            assert!(e.starts_with(expect), "{to}: {e}");
        }
    }

    #[test]
    fn builtins_have_distinct_letters_and_the_named_axes() {
        for name in BUILTINS {
            let p = MachineProfile::builtin(name).unwrap();
            let letters: Vec<u8> = (0..4).filter_map(|i| p.letter(i)).collect();
            let mut unique = letters.clone();
            unique.dedup();
            assert_eq!(letters.len(), unique.len(), "{name}");
            assert!(p.letter(0).is_some() && p.letter(1).is_some(), "{name}");
        }
        // FiberPath's marlin-xab: carriage X, mandrel A, delivery head B, no cross-feed.
        let fp = MachineProfile::builtin("fiberpath-xab").unwrap();
        assert_eq!(
            (fp.letter(0), fp.letter(1), fp.letter(2), fp.letter(3)),
            (Some(b'A'), Some(b'X'), None, Some(b'B'))
        );
        assert!(MachineProfile::builtin("haas").is_none());
    }
}
