//! Robot programs for today's controllers: one neutral motion representation ([`ProgramPath`]),
//! one writer and one reader per format (ABB RAPID [`rapid`], KUKA KRL [`krl`], FANUC TP
//! [`fanuc`], Universal Robots URScript [`urscript`]) and the vendors' configuration data
//! computed from the joints ([`config`]). The conventions and their sources are in
//! `docs/robot-programs.md`.
//!
//! # Frames and units
//! A [`ProgramTarget`] is the tool frame (the payout eye, `paths::arm`'s tool frame) in the
//! **work frame** of its [`ProgramPath`]: millimetres and a unit quaternion `[w, x, y, z]`. For a
//! decoupled mandrel the work frame is given in the robot base frame (usually the identity). For
//! a coupled mandrel the targets are in the mandrel frame, which the controller turns with the
//! external axis, and [`ProgramPath::work`] is that frame as the controller's coordinated frame
//! takes it: relative to the positioner's calibrated moving frame (ABB `wobjdata` of the `ufmec`
//! unit, KUKA `EK` offset; FANUC user frame 1 on a coordinated axis). Joint angles are the
//! controller's, degrees.
//!
//! # Writing and reading
//! [`write`] returns every file of the program set as `(file name, contents)`, the main program
//! first; the caller writes them. [`read`] parses such a set (the statements windcell writes plus
//! comments, blank lines and the declarations a controller's editor adds), follows the main
//! program's calls across the files and returns every motion target, output and wait in the
//! order the controller runs them. A syntax error is [`Error::Parse`] naming the file, line and
//! column. Reading is linear in the input (calls are expanded at most [`MAX_STEPS`] steps and
//! [`MAX_CALL_DEPTH`] deep).

pub mod config;
pub mod fanuc;
pub mod krl;
mod lex;
pub mod rapid;
pub mod urscript;

use std::collections::HashMap;
use std::fmt;

use paths::arm::{Config, Elbow, Shoulder, SixAxisArm, SixAxisKind, Wrist};

use crate::Error;

pub use config::{AbbConf, FanucConfig, KukaStatus};

/// A frame in another: origin in mm and orientation as a unit quaternion `[w, x, y, z]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frame {
    /// Origin, mm.
    pub position_mm: [f64; 3],
    /// Orientation, unit quaternion `[w, x, y, z]` (`w` the real part).
    pub orientation: [f64; 4],
}

impl Frame {
    /// The identity frame.
    pub const IDENTITY: Frame = Frame {
        position_mm: [0.0; 3],
        orientation: [1.0, 0.0, 0.0, 0.0],
    };

    /// Whether origin and orientation are the identity within 1e-9.
    pub fn is_identity(&self) -> bool {
        self.position_mm.iter().all(|v| v.abs() < 1e-9)
            && (self.orientation[0].abs() - 1.0).abs() < 1e-9
            && self.orientation[1..].iter().all(|v| v.abs() < 1e-9)
    }
}

/// The tool centre point in the flange frame.
pub type ToolFrame = Frame;
/// The frame the targets are expressed in, in the robot base frame.
pub type WorkFrame = Frame;

/// The two robot digital signals the thesis's indexer handshake uses (seed 001 App. D: the start
/// output and the in-position input), as numbers of the robot controller's digital I/O.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SyncSignals {
    /// The robot output that starts the indexer's segment.
    pub start_output: u16,
    /// The robot input the indexer raises when the mandrel is in position.
    pub in_position_input: u16,
}

/// Which external axis of the robot controller turns the mandrel (degrees).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ExternalAxis {
    /// 1-based external axis number; the writers take the mandrel on axis 1 only (RAPID
    /// `eax_a`, KRL `E1`, FANUC `E1`).
    pub number: u8,
    /// The controller's name of the mechanical unit that carries it (ABB `ufmec`, e.g.
    /// `"STN1"`); KRL uses `MACHINE_DEF[number + 1]` and FANUC the extended axis of group 1.
    pub mechanical_unit: String,
}

/// Who turns the mandrel while the program runs.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum MandrelCoupling {
    /// windcell's indexer turns it; the program meets it at the sync points.
    Decoupled {
        /// The handshake signals.
        sync: SyncSignals,
    },
    /// The robot controller turns it as an external axis with a coordinated work frame.
    Coupled {
        /// The axis.
        axis: ExternalAxis,
    },
}

/// One fibre path of a job: one robot program (before splitting).
#[derive(Debug, Clone, PartialEq)]
pub struct ProgramPath {
    /// The path's name (e.g. `SBEND_1`); each writer makes it a valid identifier of its
    /// controller ([`identifier`]).
    pub name: String,
    /// The tool centre point in the flange frame.
    pub tool: ToolFrame,
    /// The frame the targets are expressed in: decoupled, in the robot base frame; coupled, the
    /// mandrel frame relative to the positioner's moving frame (see the module documentation).
    pub work: WorkFrame,
    /// Who turns the mandrel.
    pub mandrel: MandrelCoupling,
    /// The path's start pose first, then one per segment end, in order.
    pub targets: Vec<ProgramTarget>,
}

/// One pose of a path.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProgramTarget {
    /// The tool centre point in the work frame, mm.
    pub position_mm: [f64; 3],
    /// The tool frame's orientation in the work frame, unit quaternion `[w, x, y, z]`.
    pub orientation: [f64; 4],
    /// The controller's joint angles, degrees (for the configuration data and turn numbers).
    pub joints_deg: [f64; 6],
    /// The mandrel axis angle when coupled, degrees.
    pub external_deg: Option<f64>,
    /// Time of the move into this target, s (0 for the first).
    pub duration_s: f64,
    /// Tool centre point speed of the move into this target, mm/s.
    pub speed_mm_s: f64,
    /// Blending radius allowed at this target, mm (0: a stop point).
    pub zone_mm: f64,
    /// Decoupled mandrel: the move into this target is one indexer segment: start output on
    /// before it, the move to a stop point, then wait for the in-position input, start output
    /// off, wait for the input to drop (`docs/robot-programs.md`, "Sync points").
    pub sync: bool,
}

/// The four program formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Format {
    /// ABB RAPID modules (`.mod`).
    Rapid,
    /// KUKA KRL (`.src` + `.dat`).
    Krl,
    /// FANUC TP in ASCII form (`.ls`).
    Fanuc,
    /// Universal Robots URScript (`.script`).
    UrScript,
}

impl Format {
    /// All formats.
    pub const ALL: [Format; 4] = [Format::Rapid, Format::Krl, Format::Fanuc, Format::UrScript];

    /// `rapid`, `krl`, `fanuc`, `urscript`.
    pub fn name(self) -> &'static str {
        match self {
            Format::Rapid => "rapid",
            Format::Krl => "krl",
            Format::Fanuc => "fanuc",
            Format::UrScript => "urscript",
        }
    }

    /// The format of a `--format` name (case-insensitive).
    pub fn from_name(name: &str) -> Option<Format> {
        Format::ALL
            .into_iter()
            .find(|f| f.name().eq_ignore_ascii_case(name))
    }

    /// The file name extensions of the format's program files (without the dot).
    pub fn extensions(self) -> &'static [&'static str] {
        match self {
            Format::Rapid => &["mod"],
            Format::Krl => &["src", "dat"],
            Format::Fanuc => &["ls"],
            Format::UrScript => &["script"],
        }
    }

    /// The most targets one file holds before the program is split (see each writer).
    pub fn default_targets_per_file(self) -> usize {
        match self {
            Format::Rapid => rapid::TARGETS_PER_MODULE,
            Format::Krl => krl::TARGETS_PER_FILE,
            Format::Fanuc => fanuc::TARGETS_PER_PROGRAM,
            Format::UrScript => usize::MAX,
        }
    }
}

impl fmt::Display for Format {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// How a writer lays out the program set.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct WriteOptions {
    /// The most targets in one file (module, `.src`, TP program) before the program is split
    /// into parts run in turn by a main program; `None`: the format's default
    /// ([`Format::default_targets_per_file`]).
    pub targets_per_file: Option<usize>,
}

/// The mechanical configuration data of a target as a program states it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ConfigData {
    /// ABB `confdata [cf1, cf4, cf6, cfx]`.
    Abb(AbbConf),
    /// KUKA `S` (Status) and `T` (Turn).
    Kuka(KukaStatus),
    /// FANUC `CONFIG : 'F/N U/D T/B, t1, t4, t6'`.
    Fanuc(FanucConfig),
    /// No configuration data (URScript).
    None,
}

impl ConfigData {
    /// The configuration data `format` states for the joints (`None` for URScript): what a
    /// target's configuration read from a program must equal.
    pub fn of(format: Format, arm: &SixAxisArm, joints_deg: &[f64; 6]) -> ConfigData {
        match format {
            Format::Rapid => ConfigData::Abb(config::abb_conf(arm, joints_deg)),
            Format::Krl => ConfigData::Kuka(config::kuka_status(arm, joints_deg)),
            Format::Fanuc => ConfigData::Fanuc(config::fanuc_config(arm, joints_deg)),
            Format::UrScript => ConfigData::None,
        }
    }

    /// The arm configuration (inverse-kinematics branch) the data names, to solve a read target's
    /// joints with: ABB `cfx`, KUKA `S`, FANUC's letters. The wrist bit of ABB and KUKA is the
    /// sign of axis 5, turned into the model's wrist solution with the arm's axis-5 sign. `None`
    /// for URScript (no configuration data) and a UR arm.
    pub fn arm_config(&self, arm: &SixAxisArm) -> Option<Config> {
        let axis5_sign = match &arm.kind {
            SixAxisKind::Opw(o) => o.signs[4],
            SixAxisKind::Ur(_) => return None,
        };
        let wrist = |axis5_negative: bool| {
            if axis5_negative == (axis5_sign > 0) {
                Wrist::Flip
            } else {
                Wrist::NoFlip
            }
        };
        let side = |back: bool| {
            if back {
                Shoulder::Back
            } else {
                Shoulder::Front
            }
        };
        Some(match *self {
            ConfigData::Abb(c) => Config {
                shoulder: side(c.cfx & 4 != 0),
                elbow: if c.cfx & 2 != 0 {
                    Elbow::Down
                } else {
                    Elbow::Up
                },
                wrist: wrist(c.cfx & 1 != 0),
            },
            ConfigData::Kuka(k) => Config {
                shoulder: side(k.s & 1 != 0),
                elbow: if k.s & 2 != 0 { Elbow::Up } else { Elbow::Down },
                wrist: wrist(k.s & 4 != 0),
            },
            ConfigData::Fanuc(f) => Config {
                shoulder: side(!f.front),
                elbow: if f.up { Elbow::Up } else { Elbow::Down },
                wrist: if f.flip { Wrist::Flip } else { Wrist::NoFlip },
            },
            ConfigData::None => return None,
        })
    }
}

/// How a move was programmed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Motion {
    /// Joint interpolation (the first move of a program: `MoveJ`, `PTP`, `J`, `movej`).
    Joint,
    /// Linear interpolation of the tool centre point.
    Linear,
}

/// The blending a move asks for at its target.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Zone {
    /// A stop point (`fine`, no `C_DIS`, `FINE`, no `r`).
    Fine,
    /// Blending within this distance of the target, mm.
    Distance(f64),
    /// FANUC `CNTn` (0–100: not a distance, see `docs/robot-programs.md`).
    Cnt(u8),
}

impl Zone {
    /// The blending radius in mm (FANUC `CNTn` read as `n` mm, the convention windcell writes).
    pub fn radius_mm(self) -> f64 {
        match self {
            Zone::Fine => 0.0,
            Zone::Distance(d) => d,
            Zone::Cnt(n) => f64::from(n),
        }
    }
}

/// A motion target as read from a program.
#[derive(Debug, Clone, PartialEq)]
pub struct ReadTarget {
    /// The file of the move instruction.
    pub file: String,
    /// The 1-based line of the move instruction.
    pub line: usize,
    /// Joint or linear.
    pub motion: Motion,
    /// Tool centre point in the work frame, mm.
    pub position_mm: [f64; 3],
    /// Tool orientation in the work frame, unit quaternion `[w, x, y, z]`: for RAPID as printed
    /// (normalised, its sign kept: `orientation[0] < 0` is a file whose `q1` is negative, which
    /// windcell never writes); for the others converted from the format's angles (`w ≥ 0`).
    pub orientation: [f64; 4],
    /// The configuration data as read.
    pub config: ConfigData,
    /// External axis 1, degrees, when the target has one (unused axes `9E9` read as `None`).
    pub external_deg: Option<f64>,
    /// The programmed tool centre point speed, mm/s (`None` for a joint move given in %).
    pub speed_mm_s: Option<f64>,
    /// The programmed time of the move, s (RAPID `\T`, URScript `t`), when given.
    pub duration_s: Option<f64>,
    /// The blending.
    pub zone: Zone,
}

/// One step of a program as the controller runs it.
#[derive(Debug, Clone, PartialEq)]
pub enum Step {
    /// A move.
    Move(ReadTarget),
    /// A digital output set.
    Output {
        /// File.
        file: String,
        /// 1-based line.
        line: usize,
        /// Output number.
        number: u16,
        /// On or off.
        on: bool,
    },
    /// A wait for a digital input.
    Wait {
        /// File.
        file: String,
        /// 1-based line.
        line: usize,
        /// Input number.
        number: u16,
        /// The state waited for.
        on: bool,
    },
}

/// A program set as read.
#[derive(Debug, Clone, PartialEq)]
pub struct ReadProgram {
    /// The format.
    pub format: Format,
    /// The main program's file.
    pub main_file: String,
    /// The files in the order their first step runs (main first).
    pub files: Vec<String>,
    /// The tool frame the program sets, when it states one (FANUC programs name a tool number).
    pub tool: Option<ToolFrame>,
    /// The work frame the program sets, when it states one.
    pub work: Option<WorkFrame>,
    /// Every step in the order the controller runs it.
    pub steps: Vec<Step>,
}

impl ReadProgram {
    /// The motion targets in order.
    pub fn targets(&self) -> impl Iterator<Item = &ReadTarget> {
        self.steps.iter().filter_map(|s| match s {
            Step::Move(t) => Some(t),
            _ => None,
        })
    }
}

/// The most steps and calls a program set expands to when calls are followed (a path of the job
/// limit of 10 000 segments, each synchronised, is 50 000 steps; a step takes about 200 B).
pub const MAX_STEPS: usize = 500_000;
/// The largest program file the caller should hand to [`read`] (a 10 000-target RAPID module is
/// about 1.3 MB); the readers themselves take any `&str` in time and memory linear in its length.
pub const MAX_PROGRAM_BYTES: u64 = 16 << 20;
/// The deepest chain of calls followed.
pub const MAX_CALL_DEPTH: usize = 16;

/// Writes `path` in `format` for `arm` (whose configuration data the targets' joints give):
/// every file of the set, the main program first, as `(file name, contents)`.
pub fn write(
    format: Format,
    path: &ProgramPath,
    arm: &SixAxisArm,
    options: WriteOptions,
) -> Result<Vec<(String, String)>, Error> {
    check_path(format, path, arm)?;
    let per_file = options
        .targets_per_file
        .unwrap_or(format.default_targets_per_file())
        .max(1);
    let files = match format {
        Format::Rapid => rapid::write(path, arm, per_file),
        Format::Krl => krl::write(path, arm, per_file),
        Format::Fanuc => fanuc::write(path, arm, per_file),
        Format::UrScript => urscript::write(path),
    }?;
    read_back(format, path, &files)?;
    Ok(files)
}

/// Reads the written set with windcell's own reader and checks that every target is there in
/// order within the printed precision, so that a program windcell writes is always one it reads
/// (as every writer of the crate does, `crate::error::written`).
fn read_back(format: Format, path: &ProgramPath, files: &[(String, String)]) -> Result<(), Error> {
    let unwritable = |line, column, message: String| Error::Unwritable {
        format: "robot program",
        line,
        column,
        message,
    };
    let main = files.first().map(|f| f.0.as_str());
    let read = read(format, files, main).map_err(|e| match e {
        Error::Parse {
            line,
            column,
            message,
            file,
        } => unwritable(
            line,
            column,
            format!(
                "{}: {message}",
                file.map(|f| f.display().to_string()).unwrap_or_default()
            ),
        ),
        other => other,
    })?;
    let tolerance_mm = if format == Format::UrScript {
        0.001
    } else {
        0.01
    };
    let mut n = 0;
    for (t, want) in read.targets().zip(&path.targets) {
        n += 1;
        let d: f64 = (0..3)
            .map(|i| (t.position_mm[i] - want.position_mm[i]).powi(2))
            .sum::<f64>()
            .sqrt();
        let dot: f64 = (0..4).map(|i| t.orientation[i] * want.orientation[i]).sum();
        let angle_deg = 2.0 * dot.abs().min(1.0).acos().to_degrees();
        if !(d <= tolerance_mm && angle_deg <= 0.01) {
            return Err(unwritable(
                t.line,
                1,
                format!(
                    "target {n} reads back {} mm and {}° from the plan",
                    crate::error::shown(d),
                    crate::error::shown(angle_deg)
                ),
            ));
        }
    }
    if n != path.targets.len() {
        return Err(unwritable(
            1,
            1,
            format!("{n} targets read back of {}", path.targets.len()),
        ));
    }
    Ok(())
}

/// Reads a program set: `files` as `(file name, contents)`; the main program is `main` when
/// given, else the one file no other file calls.
pub fn read(
    format: Format,
    files: &[(String, String)],
    main: Option<&str>,
) -> Result<ReadProgram, Error> {
    let units = match format {
        Format::Krl => krl::parse_set(files)?,
        _ => {
            let mut units = Vec::new();
            for (name, text) in files {
                let unit = match format {
                    Format::Rapid => rapid::parse(text),
                    Format::Fanuc => fanuc::parse(text),
                    _ => urscript::parse(text),
                }
                .map_err(|e| e.in_file(name))?;
                units.push((name.clone(), unit));
            }
            units
        }
    };
    link(format, units, main)
}

/// The file name of the main program of a path written in `format`.
pub fn main_file_name(format: Format, path_name: &str) -> String {
    let id = identifier(format, path_name);
    match format {
        Format::Rapid => format!("{id}.mod"),
        Format::Krl => format!("{id}.src"),
        Format::Fanuc => format!("{id}.ls"),
        Format::UrScript => format!("{id}.script"),
    }
}

/// `name` as an identifier of the format's controller: ASCII letters, digits and `_`, starting
/// with a letter (an `W` is put in front otherwise), at most 32 characters for RAPID (RAPID
/// reference, "Identifiers"), 24 for KRL (KSS programming manual: names of up to 24 characters),
/// 36 for FANUC TP program names (R-30iB) and 32 for URScript; RAPID, KRL and FANUC names are
/// upper case, URScript names lower case. The length leaves room for the part suffix `_Pnn`.
pub fn identifier(format: Format, name: &str) -> String {
    let max = match format {
        Format::Rapid => 32,
        Format::Krl => 24,
        Format::Fanuc => 36,
        Format::UrScript => 32,
    } - 5;
    let mut id: String = name
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect();
    if !id.starts_with(|c: char| c.is_ascii_alphabetic()) {
        id.insert(0, 'W');
    }
    id.truncate(max);
    if format == Format::UrScript {
        id.make_ascii_lowercase();
    } else {
        id.make_ascii_uppercase();
    }
    id
}

/// Refuses what no format can write: no targets, non-finite figures, a URScript program of a
/// coupled mandrel or a UR arm in an industrial controller's format (and the reverse).
fn check_path(format: Format, path: &ProgramPath, arm: &SixAxisArm) -> Result<(), Error> {
    let refuse = |message: String| {
        Err(Error::Content {
            file: None,
            message,
        })
    };
    match (format, &arm.kind) {
        (Format::UrScript, SixAxisKind::Opw(_)) => {
            return refuse(
                "a URScript program needs a Universal Robots arm (the cell's arm is an OPW arm)"
                    .into(),
            );
        }
        (Format::Rapid | Format::Krl | Format::Fanuc, SixAxisKind::Ur(_)) => {
            return refuse(format!(
                "a {} program needs an ABB, KUKA or FANUC arm (the cell's arm is a Universal \
                 Robots arm: use --format urscript)",
                format.name()
            ));
        }
        _ => {}
    }
    if format == Format::UrScript && matches!(path.mandrel, MandrelCoupling::Coupled { .. }) {
        return refuse(
            "a URScript program cannot drive a coupled mandrel (a UR controller has no external \
             axes): set the mandrel drive to the indexer"
                .into(),
        );
    }
    if let MandrelCoupling::Coupled { axis } = &path.mandrel
        && axis.number != 1
    {
        return refuse(format!(
            "external axis {}: the mandrel must be the controller's first external axis (eax_a, \
             E1)",
            axis.number
        ));
    }
    if path.targets.is_empty() {
        return refuse(format!("path {} has no targets", path.name));
    }
    for f in [&path.tool, &path.work] {
        if !(f.position_mm.iter().all(|v| v.is_finite() && v.abs() < 1e6)
            && unit_quaternion(f.orientation).is_some())
        {
            return refuse(format!(
                "path {}: the tool or work frame is not finite or its quaternion is not a rotation",
                path.name
            ));
        }
    }
    let coupled = matches!(path.mandrel, MandrelCoupling::Coupled { .. });
    for (i, t) in path.targets.iter().enumerate() {
        let finite = t.position_mm.iter().all(|v| v.is_finite() && v.abs() < 1e6)
            && t.joints_deg
                .iter()
                .all(|v| v.is_finite() && v.abs() <= 720.0)
            && t.duration_s.is_finite()
            && t.duration_s >= 0.0
            && t.speed_mm_s.is_finite()
            && t.speed_mm_s >= 0.0
            && t.zone_mm.is_finite()
            && t.zone_mm >= 0.0
            && unit_quaternion(t.orientation).is_some()
            && t.external_deg
                .is_none_or(|e| e.is_finite() && e.abs() < 1e6);
        if !finite {
            return refuse(format!(
                "path {} target {}: a figure is not finite, negative where it must not be, or \
                 the quaternion is not a rotation",
                path.name,
                i + 1
            ));
        }
        if i > 0 && t.speed_mm_s < 0.1 {
            return refuse(format!(
                "path {} target {}: the speed {} mm/s is below the 0.1 mm/s the formats print",
                path.name,
                i + 1,
                crate::error::shown(t.speed_mm_s)
            ));
        }
        if coupled && t.external_deg.is_none() {
            return refuse(format!(
                "path {} target {}: a coupled mandrel needs the axis angle of every target",
                path.name,
                i + 1
            ));
        }
    }
    Ok(())
}

/// The quaternion normalised with `w ≥ 0` (the same rotation), or `None` when its norm is not
/// within 1e-6 of 1 or a component is not finite.
pub fn unit_quaternion(q: [f64; 4]) -> Option<[f64; 4]> {
    let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
    if !(n.is_finite() && (n - 1.0).abs() < 1e-6) {
        return None;
    }
    let s = if q[0] < 0.0 { -1.0 / n } else { 1.0 / n };
    Some(q.map(|v| v * s))
}

/// The rotation matrix (rows) of a unit quaternion `[w, x, y, z]`.
pub fn quaternion_matrix(q: [f64; 4]) -> [[f64; 3]; 3] {
    let [w, x, y, z] = q;
    [
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
        ],
        [
            2.0 * (x * y + w * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - w * x),
        ],
        [
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            1.0 - 2.0 * (x * x + y * y),
        ],
    ]
}

/// The unit quaternion `[w, x, y, z]` (`w ≥ 0`) of a rotation matrix (rows), by the largest of
/// the four diagonal combinations (Shepperd's method).
pub fn matrix_quaternion(m: [[f64; 3]; 3]) -> [f64; 4] {
    let tr = m[0][0] + m[1][1] + m[2][2];
    let q = if tr >= m[0][0].max(m[1][1]).max(m[2][2]) {
        let s = (1.0 + tr).max(0.0).sqrt() * 2.0;
        [
            s / 4.0,
            (m[2][1] - m[1][2]) / s,
            (m[0][2] - m[2][0]) / s,
            (m[1][0] - m[0][1]) / s,
        ]
    } else if m[0][0] >= m[1][1] && m[0][0] >= m[2][2] {
        let s = (1.0 + m[0][0] - m[1][1] - m[2][2]).max(0.0).sqrt() * 2.0;
        [
            (m[2][1] - m[1][2]) / s,
            s / 4.0,
            (m[0][1] + m[1][0]) / s,
            (m[0][2] + m[2][0]) / s,
        ]
    } else if m[1][1] >= m[2][2] {
        let s = (1.0 + m[1][1] - m[0][0] - m[2][2]).max(0.0).sqrt() * 2.0;
        [
            (m[0][2] - m[2][0]) / s,
            (m[0][1] + m[1][0]) / s,
            s / 4.0,
            (m[1][2] + m[2][1]) / s,
        ]
    } else {
        let s = (1.0 + m[2][2] - m[0][0] - m[1][1]).max(0.0).sqrt() * 2.0;
        [
            (m[1][0] - m[0][1]) / s,
            (m[0][2] + m[2][0]) / s,
            (m[1][2] + m[2][1]) / s,
            s / 4.0,
        ]
    };
    let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
    let s = if q[0] < 0.0 { -1.0 / n } else { 1.0 / n };
    q.map(|v| v * s)
}

/// `[A, B, C]` degrees with `R = Rz(A)·Ry(B)·Rx(C)`: KUKA's Z-Y′-X″ Euler angles, which are the
/// same numbers as FANUC's `[R, P, W]` (rotations W about the fixed x, P about the fixed y, R
/// about the fixed z, in that order). `B` in [−90°, 90°]; at `|B| = 90°` only `A ∓ C` is
/// defined and `C` is set to 0.
pub fn quaternion_zyx_deg(q: [f64; 4]) -> [f64; 3] {
    let m = quaternion_matrix(q);
    let cb = m[0][0].hypot(m[1][0]);
    let b = (-m[2][0]).atan2(cb);
    let (a, c) = if cb > 1e-9 {
        (m[1][0].atan2(m[0][0]), m[2][1].atan2(m[2][2]))
    } else {
        // R = Rz(A)·Ry(±90°): the first row gives A − C or A + C; C = 0.
        ((-m[0][1]).atan2(m[1][1]), 0.0)
    };
    [a.to_degrees(), b.to_degrees(), c.to_degrees()]
}

/// The unit quaternion of `Rz(A)·Ry(B)·Rx(C)`, angles in degrees.
pub fn zyx_deg_quaternion(abc_deg: [f64; 3]) -> [f64; 4] {
    let [a, b, c] = abc_deg.map(|v| v.to_radians() / 2.0);
    let (sa, ca) = a.sin_cos();
    let (sb, cb) = b.sin_cos();
    let (sc, cc) = c.sin_cos();
    let q = [
        ca * cb * cc + sa * sb * sc,
        ca * cb * sc - sa * sb * cc,
        ca * sb * cc + sa * cb * sc,
        sa * cb * cc - ca * sb * sc,
    ];
    if q[0] < 0.0 { q.map(|v| -v) } else { q }
}

/// The rotation vector (axis × angle, radians, angle in [0, π]) of a unit quaternion: URScript's
/// orientation of a pose `p[x, y, z, rx, ry, rz]`.
pub fn quaternion_rotation_vector(q: [f64; 4]) -> [f64; 3] {
    let q = if q[0] < 0.0 { q.map(|v| -v) } else { q };
    let s = (q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
    if s < 1e-300 {
        return [0.0; 3];
    }
    let angle = 2.0 * s.atan2(q[0]);
    [q[1] / s * angle, q[2] / s * angle, q[3] / s * angle]
}

/// The unit quaternion (`w ≥ 0`) of a rotation vector, radians.
pub fn rotation_vector_quaternion(r: [f64; 3]) -> [f64; 4] {
    let angle = (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt();
    if angle < 1e-300 {
        return [1.0, 0.0, 0.0, 0.0];
    }
    let (s, c) = (angle / 2.0).sin_cos();
    let q = [c, r[0] / angle * s, r[1] / angle * s, r[2] / angle * s];
    if q[0] < 0.0 { q.map(|v| -v) } else { q }
}

/// `value` with `decimals` decimals, never `-0.000`.
pub(crate) fn fixed(value: f64, decimals: usize) -> String {
    let s = format!("{value:.decimals$}");
    if s.starts_with('-') && s[1..].chars().all(|c| c == '0' || c == '.') {
        s[1..].to_string()
    } else {
        s
    }
}

/// One routine of a parsed file: its name and body.
#[derive(Debug, Clone)]
pub(crate) struct Routine {
    pub name: String,
    pub body: Vec<Item>,
}

/// A statement of a routine body as the linker needs it.
#[derive(Debug, Clone)]
pub(crate) enum Item {
    /// A move, output or wait (its `file` is filled in when linked).
    Step(Step),
    /// A call of another routine by name, at a line and column.
    Call {
        name: String,
        line: usize,
        column: usize,
    },
}

/// What a reader makes of one file.
#[derive(Debug, Clone, Default)]
pub(crate) struct Unit {
    pub routines: Vec<Routine>,
    pub tool: Option<Frame>,
    pub work: Option<Frame>,
}

/// Follows the calls from the main routine through every file, filling in each step's file.
fn link(
    format: Format,
    units: Vec<(String, Unit)>,
    main: Option<&str>,
) -> Result<ReadProgram, Error> {
    let mut by_name: HashMap<String, (usize, usize)> = HashMap::new();
    for (u, (file, unit)) in units.iter().enumerate() {
        for (r, routine) in unit.routines.iter().enumerate() {
            let key = routine.name.to_ascii_uppercase();
            if by_name.insert(key, (u, r)).is_some() {
                return Err(Error::content(format!(
                    "routine {} is defined twice (the second in {file})",
                    routine.name
                )));
            }
        }
    }
    let main_unit = match main {
        Some(m) => units.iter().position(|(f, _)| f == m).ok_or_else(|| {
            Error::content(format!("the main program {m} is not among the files"))
        })?,
        None => {
            let called: std::collections::HashSet<String> = units
                .iter()
                .flat_map(|(_, u)| u.routines.iter())
                .flat_map(|r| r.body.iter())
                .filter_map(|i| match i {
                    Item::Call { name, .. } => Some(name.to_ascii_uppercase()),
                    _ => None,
                })
                .collect();
            let roots: Vec<usize> = units
                .iter()
                .enumerate()
                .filter(|(_, (_, u))| {
                    !u.routines.is_empty()
                        && u.routines
                            .iter()
                            .all(|r| !called.contains(&r.name.to_ascii_uppercase()))
                })
                .map(|(i, _)| i)
                .collect();
            match roots.as_slice() {
                [one] => *one,
                [] => {
                    return Err(Error::content(
                        "no main program: every program is called by another",
                    ));
                }
                many => {
                    return Err(Error::content(format!(
                        "{} programs are called by no other ({}); name the main one",
                        many.len(),
                        many.iter()
                            .map(|&i| units[i].0.as_str())
                            .collect::<Vec<_>>()
                            .join(", ")
                    )));
                }
            }
        }
    };
    let (main_file, main_routine) = {
        let (file, unit) = &units[main_unit];
        let r = unit
            .routines
            .iter()
            .position(|r| r.name.eq_ignore_ascii_case("main"))
            .unwrap_or(0);
        if unit.routines.is_empty() {
            return Err(Error::content(format!("{file} holds no program")));
        }
        (file.clone(), r)
    };
    let mut out = ReadProgram {
        format,
        main_file: main_file.clone(),
        files: Vec::new(),
        tool: units[main_unit].1.tool,
        work: units[main_unit].1.work,
        steps: Vec::new(),
    };
    let mut stack: Vec<(usize, usize)> = Vec::new();
    let mut visited = 0;
    expand(
        &units,
        &by_name,
        (main_unit, main_routine),
        &mut stack,
        &mut visited,
        &mut out,
    )?;
    Ok(out)
}

fn expand(
    units: &[(String, Unit)],
    by_name: &HashMap<String, (usize, usize)>,
    at: (usize, usize),
    stack: &mut Vec<(usize, usize)>,
    visited: &mut usize,
    out: &mut ReadProgram,
) -> Result<(), Error> {
    let (file, unit) = &units[at.0];
    if !out.files.contains(file) {
        out.files.push(file.clone());
    }
    if out.tool.is_none() {
        out.tool = unit.tool;
    }
    if out.work.is_none() {
        out.work = unit.work;
    }
    stack.push(at);
    for item in &unit.routines[at.1].body {
        // Calls count as steps too: a chain of routines that call each other many times over
        // without moving would otherwise run without bound.
        *visited += 1;
        if *visited > MAX_STEPS {
            return Err(Error::content(format!(
                "the program runs more than {MAX_STEPS} steps and calls"
            )));
        }
        match item {
            Item::Step(s) => {
                let mut s = s.clone();
                match &mut s {
                    Step::Move(t) => t.file = file.clone(),
                    Step::Output { file: f, .. } | Step::Wait { file: f, .. } => *f = file.clone(),
                }
                out.steps.push(s);
            }
            Item::Call { name, line, column } => {
                let Some(&target) = by_name.get(&name.to_ascii_uppercase()) else {
                    return Err(Error::at(
                        *line,
                        *column,
                        format!("calls {name}, which none of the files defines"),
                    )
                    .in_file(file));
                };
                if stack.contains(&target) {
                    return Err(
                        Error::at(*line, *column, format!("{name} calls itself")).in_file(file)
                    );
                }
                if stack.len() >= MAX_CALL_DEPTH {
                    return Err(Error::at(
                        *line,
                        *column,
                        format!("calls nested deeper than {MAX_CALL_DEPTH}"),
                    )
                    .in_file(file));
                }
                expand(units, by_name, target, stack, visited, out)?;
            }
        }
    }
    stack.pop();
    Ok(())
}

/// The targets of a path cut into parts of at most `per_file` targets.
pub(crate) fn parts(path: &ProgramPath, per_file: usize) -> Vec<&[ProgramTarget]> {
    path.targets.chunks(per_file.max(1)).collect()
}

/// The name of part `k` (0-based) of `n` of the program `id`: `id` itself when there is one
/// part, else `id_Pk+1`.
pub(crate) fn part_name(id: &str, k: usize, n: usize) -> String {
    if n == 1 {
        id.to_string()
    } else {
        format!("{id}_P{}", k + 1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn euler_and_rotation_vector_round_trip() {
        let mut seed = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        for _ in 0..1000 {
            let q = [next(), next(), next(), next()];
            let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
            let q = unit_quaternion(q.map(|v| v / n)).unwrap();
            let back = zyx_deg_quaternion(quaternion_zyx_deg(q));
            let dot: f64 = q.iter().zip(back).map(|(a, b)| a * b).sum();
            assert!(dot.abs() > 1.0 - 1e-12, "{q:?} {back:?}");
            let back = rotation_vector_quaternion(quaternion_rotation_vector(q));
            let dot: f64 = q.iter().zip(back).map(|(a, b)| a * b).sum();
            assert!(dot.abs() > 1.0 - 1e-12);
            let back = matrix_quaternion(quaternion_matrix(q));
            let dot: f64 = q.iter().zip(back).map(|(a, b)| a * b).sum();
            assert!(dot.abs() > 1.0 - 1e-12);
        }
        // Gimbal lock: B = 90°.
        let q = zyx_deg_quaternion([30.0, 90.0, 0.0]);
        let back = zyx_deg_quaternion(quaternion_zyx_deg(q));
        let dot: f64 = q.iter().zip(back).map(|(a, b)| a * b).sum();
        assert!(dot.abs() > 1.0 - 1e-12);
    }

    #[test]
    fn identifiers_follow_the_controllers_rules() {
        assert_eq!(identifier(Format::Rapid, "sbend 1"), "SBEND_1");
        assert_eq!(identifier(Format::Krl, "1st-path"), "W1ST_PATH");
        assert!(identifier(Format::Krl, &"x".repeat(40)).len() <= 19);
        assert_eq!(identifier(Format::UrScript, "SBEND 1"), "sbend_1");
        for f in Format::ALL {
            assert!(
                main_file_name(f, "S-bend 2")
                    .to_ascii_lowercase()
                    .starts_with("s_bend_2.")
            );
        }
        assert_eq!(fixed(-0.0001, 3), "0.000");
        assert_eq!(fixed(-1.5, 1), "-1.5");
    }
}
