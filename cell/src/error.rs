//! The one error type of the `cell` crate.

use std::path::PathBuf;

use thiserror::Error;

/// What can go wrong in the coordinator.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum Error {
    /// An operator file is malformed or out of range (already names file, line and column).
    #[error(transparent)]
    File(#[from] sequences::Error),
    /// Planning failed at a place in the job file.
    #[error("{}:{line}:{column}: {source}", file.display())]
    Plan {
        /// The job file.
        file: PathBuf,
        /// 1-based line of the field to change.
        line: usize,
        /// 1-based column.
        column: usize,
        /// What the geometry said.
        source: paths::Error,
    },
    /// An imported path is longer than its samples may cover: refused at the drawing's
    /// coordinate that makes it so, before any sample is allocated.
    #[error(
        "{}:{line}:{column}: path point {point} at {} mm makes the path longer than the limit of \
         {} mm (a wrong coordinate or unit? docs/ARCHITECTURE.md, \"Limits\")",
        file.display(), short(*value_mm), short(*limit_mm)
    )]
    PathTooLong {
        /// The DXF file.
        file: PathBuf,
        /// 1-based line of the coordinate.
        line: usize,
        /// 1-based column.
        column: usize,
        /// The point, 1-based in path order.
        point: usize,
        /// The coordinate, mm.
        value_mm: f64,
        /// The longest path accepted, mm.
        limit_mm: f64,
    },
    /// An imported path's point lies farther from the mandrel surface than the job allows.
    #[error(
        "{}:{line}:{column}: path point {point} lies {} mm from the mandrel surface, more than \
         surface_tolerance_mm = {tolerance_mm} mm (worst point {} mm; the drawing is read in {units})",
        file.display(), short(*distance_mm), short(*worst_mm)
    )]
    OffSurface {
        /// The DXF file.
        file: PathBuf,
        /// 1-based line of the point's x value.
        line: usize,
        /// 1-based column.
        column: usize,
        /// The point, 1-based in path order.
        point: usize,
        /// Its signed distance to the surface, mm (negative inside).
        distance_mm: f64,
        /// The largest |distance| of any point, mm.
        worst_mm: f64,
        /// The job's limit, mm.
        tolerance_mm: f64,
        /// The drawing's units, in words.
        units: String,
    },
    /// A path's stored program does not fit the robot's memory (seed 001 §4.1.2).
    #[error(
        "{}:{line}:{column}: program {program} needs {positioning} positioning and {control} \
         control instructions, more than the robot's memory holds (470 positioning, or 300 \
         positioning and 200 control; seed 001 §4.1.2): at most {max_segments} segments in \
         {movement} movement",
        file.display()
    )]
    ProgramMemory {
        /// The job file.
        file: PathBuf,
        /// 1-based line of the path's `segments`.
        line: usize,
        /// 1-based column.
        column: usize,
        /// Program number.
        program: u8,
        /// Positioning instructions the program needs.
        positioning: usize,
        /// Control instructions the program needs.
        control: usize,
        /// The most segments that fit.
        max_segments: usize,
        /// `fine` or `medium`.
        movement: &'static str,
    },
    /// An instruction number that does not fit the robot's 16 bits (1–65535).
    #[error("program {program}: instruction number {number} does not fit 1–65535")]
    InstructionNumber {
        /// Program number.
        program: u8,
        /// The number that does not fit.
        number: usize,
    },
    /// A mesh file is malformed or not a usable surface: `FILE:LINE:COL: message` for the text
    /// formats, `FILE: byte N: message` for binary STL, where the reader knows the place.
    #[error("{}", mesh_place(file, source))]
    Mesh {
        /// The mesh file.
        file: PathBuf,
        /// What the mesh reader said.
        source: paths::Error,
    },
    /// A robot control file's value does not fit the robot's telegram (seed 001 §5.4.1): the
    /// program and the .ROB instruction number (`None`: the header's speeds).
    #[error("program {program}: {}: {source}", place(*instruction))]
    RobotTransfer {
        /// Program number of the .ROB file.
        program: u8,
        /// The file's instruction number; `None` for the header.
        instruction: Option<u16>,
        /// What the telegram encoder refused.
        source: asea_protocol::EncodeError,
    },
    /// A mandrel move does not fit the indexer or the drive (seed 001 §5.3.2, §4.1.5): the .ROB
    /// instruction number, or `None` for the move of a .IND file.
    #[error("{}: {source}", mandrel_place(*instruction))]
    IndexerTransfer {
        /// The .ROB instruction whose mandrel move it is; `None` for the .IND file's move.
        instruction: Option<u16>,
        /// What the drive's units or the X-language refused.
        source: mandrel_drive::Error,
    },
    /// A discrete-movement file given where a stored program is needed (discrete positions are
    /// sent one at a time as immediate moves, seed 001 §5.4.1).
    #[error("program {program}: movement is discrete; send it as immediate moves")]
    DiscreteProgram {
        /// Program number of the .ROB file.
        program: u8,
    },
    /// The lathe winder's controller refused a setting or stopped (a limit switch).
    #[error("lathe controller: {source}")]
    Lathe {
        /// What the controller said.
        source: mandrel_drive::Error,
    },
    /// A file the job names (`mesh`, `dxf`, `spine_dxf`) cannot be used: the job line and column
    /// that name it, then the file's own problem.
    #[error("{}:{line}:{column}: {source}", job.display())]
    Named {
        /// The job file.
        job: PathBuf,
        /// 1-based line of the value naming the file (or its layer).
        line: usize,
        /// 1-based column.
        column: usize,
        /// What is wrong with the named file.
        source: Box<Error>,
    },
    /// The output path cannot take the output (a file where a folder is needed, a folder where a
    /// file would go, control files of an earlier plan in the way); nothing was written.
    #[error("{}: {reason}", path.display())]
    OutputPath {
        /// The output folder or file.
        path: PathBuf,
        /// What is in the way, in words.
        reason: String,
    },
    /// A cell description that cannot be used: `CELL.toml` at a line and column, or the job's
    /// `[cell]` (`place` `None`).
    #[error("{}{}: {problem}", file.display(), cell_place(*place))]
    Cell {
        /// `CELL.toml`, or the job file.
        file: PathBuf,
        /// 1-based line and column in `CELL.toml`; `None` for the job's `[cell]`.
        place: Option<(usize, usize)>,
        /// What is wrong.
        problem: CellProblem,
    },
    /// A program the run file runs that no control file of the sequence is (seed 001 §5.4.1).
    #[error("{}:{line}:1: program {program} is not loaded by the sequence", file.display())]
    ProgramNotLoaded {
        /// The run file.
        file: PathBuf,
        /// 1-based line of the program's record.
        line: usize,
        /// The program number.
        program: u8,
    },
    /// Two control files of one batch carry the same program number: uploading the second
    /// would overwrite the first in the robot's memory (seed 001 §5.6.3), so a run file's
    /// number could not say which path it means.
    #[error(
        "{}:{line}:{column}: program {program} is also the program of {}: each control file \
         of a batch needs its own number",
        file.display(),
        other.display()
    )]
    DuplicateProgram {
        /// The later control file (`.ROB`).
        file: PathBuf,
        /// 1-based line of its `program` record.
        line: usize,
        /// 1-based column of the number.
        column: usize,
        /// The program number.
        program: u8,
        /// The earlier control file with the same number.
        other: PathBuf,
    },
    /// A lathe winder setting or start out of range, refused before anything moves.
    #[error(transparent)]
    LatheSetting(LatheSetting),
    /// A run cannot start or go on: `input` true when the operator's files or arguments are at
    /// fault (exit code 2), false for the cell (exit code 1).
    #[error("{message}")]
    Run {
        /// One line for the operator.
        message: String,
        /// True for bad input.
        input: bool,
    },
    /// `post` of a job for the IRB 6/2 (its robot computer reads `.ROB` files, `windcell plan`).
    #[error(
        "{}:{line}:{column}: {format} programs are for six-axis arms; this job plans for the \
         IRB 6/2 (give [cell.robot] kind = \"opw\" or \"ur\"; its control files come from \
         `windcell plan`)",
        file.display()
    )]
    PostNeedsSixAxis {
        /// The job file.
        file: PathBuf,
        /// Line of `[cell.robot] kind` (or the job's name).
        line: usize,
        /// Column there.
        column: usize,
        /// The format asked for.
        format: &'static str,
    },
    /// A plan whose poses are not a six-axis arm's, given to `post`.
    #[error("{path}: the plan holds no six-axis poses")]
    PostNotSixAxisPlan {
        /// The path's name.
        path: String,
    },
    /// `post` of a decoupled mandrel in a flying movement.
    #[error(
        "{job}: a mandrel windcell's indexer turns meets the robot program at stop points, one \
         per segment: post it in discrete movement (movement = \"discrete\" or --mode \
         discrete), or let the robot controller turn it ([cell.mandrel] drive = \"robot\"), \
         not in {movement} movement"
    )]
    PostDecoupledFlying {
        /// The job's name.
        job: String,
        /// The movement asked for.
        movement: &'static str,
    },
    /// A command that drives or simulates the IRB 6/2 cell, given a job for a six-axis arm.
    #[error(
        "{}:{line}:{column}: {command} drives the IRB 6/2 cell; this job's arm is \"{kind}\" \
         (plan and check it, and write its controller's programs with `windcell post`)",
        file.display()
    )]
    SixAxisNotDriven {
        /// The job file.
        file: PathBuf,
        /// Line of `[cell.robot] kind`.
        line: usize,
        /// Column there.
        column: usize,
        /// The arm kind.
        kind: &'static str,
        /// The command refused (`run`, `predict`).
        command: &'static str,
    },
    /// A control file planned for another movement, wound in continuous mode (its timing is a
    /// property of the plan: docs/continuous.md).
    #[error(
        "planned for {movement} movement; continuous mode needs files planned for it \
         (movement = \"continuous\" in the job)"
    )]
    NotPlannedForContinuous {
        /// The movement it was planned for.
        movement: &'static str,
    },
    /// A relative position in a robot control file: the coordinator resumes to absolute ones.
    #[error(
        "instruction {instruction}: relative positions cannot be resumed; the coordinator needs \
         absolute ones"
    )]
    RelativePosition {
        /// The file's instruction number.
        instruction: u16,
    },
    /// An instruction's eye target outside the arm's working range (checked before anything is
    /// sent).
    #[error(
        "instruction {instruction}: the eye at ({:.1}, {:.1}, {:.1}) mm is out of the \
         arm's reach ({:.0}–{:.0} mm from the axis, height {:.0}–{:.0} mm)",
        eye_mm[0], eye_mm[1], eye_mm[2], radius_mm.0, radius_mm.1, height_mm.0, height_mm.1
    )]
    OutOfReach {
        /// The file's instruction number.
        instruction: u16,
        /// The target, cell frame, mm.
        eye_mm: [f64; 3],
        /// Least and greatest horizontal distance from the pedestal axis, mm.
        radius_mm: (f64, f64),
        /// Lowest and highest height, mm.
        height_mm: (f64, f64),
    },
    /// An instruction's pose the arm cannot take: inside the envelope, but with no joint solution
    /// inside the arm's ranges with the eye's roll axis in the arm's plane (the robot controller
    /// would stop on it with error 9; seed 001 §4.1.1).
    #[error(
        "instruction {instruction}: the arm cannot take the eye at ({:.1}, {:.1}, {:.1}) mm with \
         this wrist orientation (no joint solution inside its ranges)",
        eye_mm[0], eye_mm[1], eye_mm[2]
    )]
    ArmCannotTake {
        /// The file's instruction number.
        instruction: u16,
        /// The target, cell frame, mm.
        eye_mm: [f64; 3],
    },
    /// A robot control file with no instruction.
    #[error("the robot control file has no instruction")]
    EmptyProgram,
    /// A file the batch needs is not there.
    #[error("{}: missing ({why})", file.display())]
    MissingFile {
        /// The file.
        file: PathBuf,
        /// Why it is needed.
        why: &'static str,
    },
    /// A mandrel file whose move does not turn what its robot file's instructions turn.
    #[error("the move turns {ind_steps} steps, the .ROB's instructions {rob_steps}")]
    MandrelSteps {
        /// Steps of the `.IND` move.
        ind_steps: i64,
        /// Steps of the `.ROB` instructions together.
        rob_steps: i64,
    },
    /// The batch's programs do not fit the robot's memory with room to resume the longest
    /// (seed 001 §4.1.2).
    #[error(
        "the batch needs {} memory units of the robot's {capacity_units} ({programs_units} for \
         {programs} programs + {reserve_units} kept free to resume the longest): it does not fit",
        programs_units + reserve_units
    )]
    BatchMemory {
        /// Units the batch's programs take.
        programs_units: u32,
        /// Distinct programs.
        programs: usize,
        /// Units kept free for a resumed program.
        reserve_units: u32,
        /// The robot's memory, units.
        capacity_units: u32,
    },
    /// A plan that `windcell run` would refuse (its pre-run check on the job's own cell): the
    /// job, then what the check found.
    #[error(
        "{}{}: the plan cannot be wound as it stands, the pre-run check refuses it: {source}",
        job.display(),
        place.map_or(String::new(), |(line, column)| format!(":{line}:{column}"))
    )]
    NotRunnable {
        /// The job file.
        job: PathBuf,
        /// 1-based line and column of the job value behind the refusal, where one value is.
        place: Option<(usize, usize)>,
        /// What the pre-run check found.
        source: Box<Error>,
    },
    /// `windcell sweep` of a job with no traced path to repeat.
    #[error(
        "{}: the job has no traced [[path]] (direction, wind_angle_deg, start_angle_deg) to sweep",
        job.display()
    )]
    NoSweepPattern {
        /// The job file.
        job: PathBuf,
    },
    /// A journal that is not this batch's (`--resume`), at its record (the journal's line).
    #[error("journal record {line}: {0}", line = .0.line())]
    JournalMismatch(JournalMismatch),
    /// A control file's value the devices cannot take, naming the file (`NAME.ROB`, or
    /// `NAME.IND` for its move) before the program and instruction ([`Error::in_item`]).
    #[error(
        "{file}{}: {source}",
        place.map_or(String::new(), |(line, column)| format!(":{line}:{column}"))
    )]
    ControlFile {
        /// The control file's name, or its path when it was read from one.
        file: String,
        /// 1-based line and column of the refused value, when the file was read from disk.
        place: Option<(usize, usize)>,
        /// What the conversion refused.
        source: Box<Error>,
    },
    /// The same, naming the journal ([`Error::in_journal`]): `FILE:LINE:1: …`.
    #[error("{}:{}:1: {mismatch}", file.display(), mismatch.line())]
    Journal {
        /// The journal given to `--resume`.
        file: PathBuf,
        /// How it fails to be the batch's.
        mismatch: JournalMismatch,
    },
    /// A recording (MCAP file or live server) could not be opened or finished.
    #[error("{}: recording failed: {message}", path.display())]
    Record {
        /// The MCAP file (or the live server's address).
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// Writing output failed.
    #[error("{}: {source}", path.display())]
    Output {
        /// The file or directory.
        path: PathBuf,
        /// The system's error.
        source: std::io::Error,
    },
}

impl Error {
    /// True when the operator's input is at fault (exit code 2): a file, a value, the output path
    /// (a missing or read-only folder, a name the file system refuses); false for run-time
    /// failures (a full disk, a device).
    pub fn is_input(&self) -> bool {
        use std::io::ErrorKind;
        match self {
            Error::Named { source, .. } | Error::NotRunnable { source, .. } => {
                return source.is_input();
            }
            Error::Output { source, .. } => {
                return matches!(
                    source.kind(),
                    ErrorKind::PermissionDenied
                        | ErrorKind::NotADirectory
                        | ErrorKind::IsADirectory
                        | ErrorKind::AlreadyExists
                        | ErrorKind::InvalidFilename
                        | ErrorKind::ReadOnlyFilesystem
                        | ErrorKind::NotFound
                );
            }
            _ => {}
        }
        matches!(
            self,
            Error::File(_)
                | Error::OutputPath { .. }
                | Error::Plan { .. }
                | Error::PathTooLong { .. }
                | Error::OffSurface { .. }
                | Error::ProgramMemory { .. }
                | Error::InstructionNumber { .. }
                | Error::Mesh { .. }
                | Error::RobotTransfer { .. }
                | Error::IndexerTransfer { .. }
                | Error::Lathe {
                    source: mandrel_drive::Error::OutOfRange { .. }
                }
                | Error::Run { input: true, .. }
                | Error::Cell { .. }
                | Error::ProgramNotLoaded { .. }
                | Error::DuplicateProgram { .. }
                | Error::LatheSetting(_)
                | Error::NotPlannedForContinuous { .. }
                | Error::RelativePosition { .. }
                | Error::OutOfReach { .. }
                | Error::ArmCannotTake { .. }
                | Error::SixAxisNotDriven { .. }
                | Error::PostNeedsSixAxis { .. }
                | Error::PostDecoupledFlying { .. }
                | Error::EmptyProgram
                | Error::MissingFile { .. }
                | Error::MandrelSteps { .. }
                | Error::BatchMemory { .. }
                | Error::NoSweepPattern { .. }
                | Error::JournalMismatch(_)
                | Error::Journal { .. }
                | Error::ControlFile { .. }
        )
    }
}

/// How a journal given to `--resume` fails to be the batch's.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum JournalMismatch {
    /// Its first record is not `begin`.
    #[error("the journal does not start with its begin record")]
    NoBegin,
    /// It names another job's files.
    #[error("the journal belongs to another job (its control files differ)")]
    OtherJob,
    /// Its `begin` record names other paths than the batch winds.
    #[error("the journal's paths ({journal}) are not this batch's ({batch})")]
    OtherItems {
        /// The journal's `items`, as written (shortened).
        journal: String,
        /// The batch's control-file names.
        batch: String,
    },
    /// A record's number does not fit the batch (a path or segment it does not have, a
    /// counter beyond the batch's travel, a record out of order).
    #[error("{field} = {value} does not fit this batch ({min} … {max})")]
    OutOfRange {
        /// 1-based record, which is the journal's line.
        record: usize,
        /// The field.
        field: &'static str,
        /// Its value as written (empty when missing).
        value: String,
        /// Least value that fits.
        min: i64,
        /// Greatest value that fits.
        max: i64,
    },
    /// It was written in another mode.
    #[error("the journal was written in {journal} mode, this run is {run}")]
    OtherMode {
        /// The journal's mode keyword.
        journal: String,
        /// This run's mode keyword.
        run: &'static str,
    },
}

impl JournalMismatch {
    /// The journal's line the mismatch is at (its `begin` record, line 1, unless a later
    /// record's number is at fault).
    pub fn line(&self) -> usize {
        match self {
            JournalMismatch::OutOfRange { record, .. } => *record,
            _ => 1,
        }
    }
}

impl Error {
    /// A conversion error of the batch item `name`'s control files, naming the file; any other
    /// error as it is.
    pub fn in_item(self, name: &str) -> Error {
        let file = match &self {
            Error::RobotTransfer { .. }
            | Error::DiscreteProgram { .. }
            | Error::NotPlannedForContinuous { .. }
            | Error::RelativePosition { .. }
            | Error::OutOfReach { .. }
            | Error::ArmCannotTake { .. }
            | Error::EmptyProgram => format!("{name}.ROB"),
            Error::MandrelSteps { .. } => format!("{name}.IND"),
            Error::IndexerTransfer {
                instruction: Some(_),
                ..
            } => format!("{name}.ROB"),
            Error::IndexerTransfer {
                instruction: None, ..
            } => format!("{name}.IND"),
            _ => return self,
        };
        Error::ControlFile {
            file,
            place: None,
            source: Box::new(self),
        }
    }

    /// The control-file value a pre-run refusal is about: the file (`.ROB` or `.IND`), the
    /// instruction (`None` for a file-level value: a `.ROB` header's, the `.IND` move's) and the
    /// field as [`sequences::RobotFile::parse_placed`] names it, with the part of a list value
    /// (`pos_mm`'s x, y, z as 0, 1, 2). `None` for a refusal of no one value.
    pub fn control_value(&self) -> Option<ControlValue> {
        use ControlFileKind::{Ind, Rob};
        let value = |kind, instruction, field| ControlValue {
            kind,
            instruction,
            field,
            part: 0,
        };
        Some(match self {
            Error::ControlFile { source, .. } => return source.control_value(),
            Error::RobotTransfer {
                instruction: None,
                source: asea_protocol::EncodeError::OutOfRange { name, .. },
                ..
            } => value(
                Rob,
                None,
                if *name == "max_speed" {
                    "max_speed_mm_s"
                } else {
                    "base_speed_mm_s"
                },
            ),
            Error::RobotTransfer {
                instruction: Some(n),
                source,
                ..
            } => match source {
                asea_protocol::EncodeError::OutOfRange { name: "speed", .. } => {
                    value(Rob, Some(*n), "speed_pct")
                }
                asea_protocol::EncodeError::OutOfRange { name, .. }
                    if ["x", "y", "z"].contains(name) =>
                {
                    ControlValue {
                        part: usize::from(*name == "y") + 2 * usize::from(*name == "z"),
                        ..value(Rob, Some(*n), "pos_mm")
                    }
                }
                _ => value(Rob, Some(*n), "q"),
            },
            Error::IndexerTransfer {
                instruction,
                source,
            } => value(
                if instruction.is_some() { Rob } else { Ind },
                *instruction,
                match source {
                    mandrel_drive::Error::OutOfRange { name, .. } if name.starts_with("accel") => {
                        "accel_rps2"
                    }
                    mandrel_drive::Error::OutOfRange { name, .. } if name.starts_with("start") => {
                        "start_rps"
                    }
                    mandrel_drive::Error::Unsupported { .. } => "start_rps",
                    mandrel_drive::Error::OutOfRange { .. }
                    | mandrel_drive::Error::PulseRate { .. } => "max_rps",
                    _ => "steps",
                },
            ),
            Error::DiscreteProgram { .. } | Error::NotPlannedForContinuous { .. } => {
                value(Rob, None, "movement")
            }
            Error::RelativePosition { instruction, .. } => value(Rob, Some(*instruction), "ref"),
            Error::OutOfReach { instruction, .. } | Error::ArmCannotTake { instruction, .. } => {
                value(Rob, Some(*instruction), "pos_mm")
            }
            Error::MandrelSteps { .. } => value(Ind, None, "steps"),
            _ => return None,
        })
    }

    /// A journal mismatch, naming the journal file; any other error as it is.
    pub fn in_journal(self, file: &std::path::Path) -> Error {
        match self {
            Error::JournalMismatch(mismatch) => Error::Journal {
                file: file.to_path_buf(),
                mismatch,
            },
            other => other,
        }
    }
}

/// The control-file value a pre-run refusal is about ([`Error::control_value`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ControlValue {
    /// The `.ROB` or the `.IND`.
    pub kind: ControlFileKind,
    /// The instruction; `None` for a file-level value.
    pub instruction: Option<u16>,
    /// The field, as the reader names it.
    pub field: &'static str,
    /// The part of a list value, 0-based (0 for a single value).
    pub part: usize,
}

/// A batch item's two control files.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ControlFileKind {
    /// The robot control file, `NAME.ROB`.
    Rob,
    /// The mandrel control file, `NAME.IND`.
    Ind,
}

/// What is wrong with a cell description (docs/file-formats.md, "Cell file").
#[derive(Debug, Error)]
pub enum CellProblem {
    /// The TOML reader refused the text.
    #[error("{0}")]
    Syntax(String),
    /// The drive's gearing is one the drive cannot run.
    #[error(transparent)]
    Drive(mandrel_drive::Error),
    /// Some of the ports named, not all.
    #[error(
        "name the robot and indexer ports (and the sync port for program mode) or none (the \
         simulated cell)"
    )]
    Ports,
    /// The simulated sync lines' opto-isolator delay out of range.
    #[error("opto_delay_s = {}: expected 0–1 s", sequences::error::shown(*value_s))]
    OptoDelay {
        /// The delay given, s.
        value_s: f64,
    },
    /// A calibration tolerance not finite or outside 0–100.
    #[error("[tolerance]: every figure must be finite and 0–100")]
    Tolerance,
    /// A six-axis arm controller's sync signal number outside 1–4096 (`[robot_io]`).
    #[error("[robot_io]: signal {signal}: expected 1–4096")]
    RobotIoSignal {
        /// The signal number given.
        signal: u16,
    },
    /// An indexer dialect the built-in simulated cell does not speak (its card is the
    /// X-language's; `windcell sim-indexer --dialect grbl` serves a GRBL one on a port).
    #[error(
        "[indexer] dialect = \"{dialect}\": the built-in simulated cell's indexer speaks the \
         X-language; name the ports of a {dialect} indexer (windcell sim-indexer --dialect \
         {dialect} --pty serves one)"
    )]
    SimulatedDialect {
        /// The dialect named.
        dialect: &'static str,
    },
    /// A movement the indexer's dialect cannot drive: program mode arms each mandrel move on
    /// the start line (seed 001 App. D), and a GRBL controller has no trigger input.
    #[error(
        "[indexer] dialect = \"{dialect}\": {mode} mode arms each mandrel move on the start line, \
         and a {dialect} indexer has no trigger input; wind in discrete mode"
    )]
    DialectMode {
        /// The dialect.
        dialect: &'static str,
        /// The movement asked for.
        mode: &'static str,
    },
}

/// A lathe winder setting or start refused before anything moves (seed 000 Ch. 7, seed 003
/// §4.1–4.2).
#[derive(Debug, Clone, PartialEq, Error)]
pub enum LatheSetting {
    /// A feed the axes cannot reach: it would be planned and then not followed.
    #[error(
        "feed {} counts/interrupt is above the axes' top speed of {top_counts_per_interrupt:.1} \
         (the plant {plant_gain:.1}/(s (s + {pole_per_s})) at full DAC output, {interrupt_hz} Hz)",
        paths::limits::shown(*feed_counts_per_interrupt)
    )]
    FeedAboveTopSpeed {
        /// The feed asked for, counts per interrupt.
        feed_counts_per_interrupt: f64,
        /// The plant's steady speed at full DAC output, counts per interrupt.
        top_counts_per_interrupt: f64,
        /// The plant's gain.
        plant_gain: f64,
        /// The plant's pole, 1/s.
        pole_per_s: f64,
        /// The interrupt rate, Hz.
        interrupt_hz: f64,
    },
    /// A homing start outside the limit switches.
    #[error(
        "start {axis} = {} mm is outside the limit switches (−5 … {travel_mm} mm)",
        paths::limits::shown(*start_mm)
    )]
    HomeStart {
        /// `X` or `Y`.
        axis: char,
        /// The start, mm from the home switch's frame.
        start_mm: f64,
        /// The axis's travel, mm.
        travel_mm: f64,
    },
    /// A homing back-off outside 0 … 4000 encoder pulses.
    #[error("back-off {pulses} pulses is outside 0 … 4000")]
    HomeBackoff {
        /// The back-off asked for.
        pulses: i64,
    },
    /// A gear ratio that is not finite.
    #[error("--ratio {} mm/° is not finite", paths::limits::shown(*ratio_mm_per_deg))]
    GearRatio {
        /// Carriage millimetres per mandrel degree.
        ratio_mm_per_deg: f64,
    },
    /// A geared mandrel speed outside (0, 3600] °/s.
    #[error("--speed: mandrel speed {} °/s is outside (0, 3600]", paths::limits::shown(*speed_deg_s))]
    GearSpeed {
        /// The mandrel's speed, °/s.
        speed_deg_s: f64,
    },
    /// Geared turns outside (0, 1000].
    #[error("--turns {} is outside (0, 1000]", paths::limits::shown(*turns))]
    GearTurns {
        /// Mandrel turns.
        turns: f64,
    },
    /// A ramp outside [0, 60] s.
    #[error("--ramp {} s is outside [0, 60]", paths::limits::shown(*ramp_s))]
    GearRamp {
        /// The ramp, s.
        ramp_s: f64,
    },
    /// A geared run longer than an hour.
    #[error(
        "{}° at {} °/s takes more than an hour",
        paths::limits::shown(*angle_deg),
        paths::limits::shown(*speed_deg_s)
    )]
    GearTooLong {
        /// The mandrel's whole turn, degrees.
        angle_deg: f64,
        /// Its speed, °/s.
        speed_deg_s: f64,
    },
    /// A geared carriage that would pass a limit switch.
    #[error(
        "the carriage would reach {} mm from machine zero, beyond the limit switches (0 … \
         {travel_mm} mm): ratio {} mm/° over {}°",
        paths::limits::fixed(*end_mm, 2),
        paths::limits::shown(*ratio_mm_per_deg),
        paths::limits::shown(*angle_deg)
    )]
    CarriageBeyondLimits {
        /// Where the carriage would end, mm from machine zero.
        end_mm: f64,
        /// The carriage's travel, mm.
        travel_mm: f64,
        /// Carriage millimetres per mandrel degree.
        ratio_mm_per_deg: f64,
        /// The mandrel's whole turn, degrees.
        angle_deg: f64,
    },
}

/// Where in a cell description: `:LINE:COL` in `CELL.toml`, `: [cell]` in a job.
fn cell_place(place: Option<(usize, usize)>) -> String {
    match place {
        Some((line, column)) => format!(":{line}:{column}"),
        None => ": [cell]".to_string(),
    }
}

/// A length for a message: plain below a million, in exponent form above (`1e308`, not 309
/// digits).
fn short(mm: f64) -> String {
    if mm.abs() < 1e6 {
        format!("{:.3}", mm)
            .trim_end_matches('0')
            .trim_end_matches('.')
            .to_string()
    } else {
        format!("{mm:e}")
    }
}

fn mesh_place(file: &std::path::Path, source: &paths::Error) -> String {
    match source {
        paths::Error::MeshSyntax {
            line: Some(line),
            column: Some(column),
            message,
            ..
        } => format!("{}:{line}:{column}: {message}", file.display()),
        other => format!("{}: {other}", file.display()),
    }
}

fn place(instruction: Option<u16>) -> String {
    match instruction {
        Some(n) => format!("instruction {n}"),
        None => "header".to_string(),
    }
}

fn mandrel_place(instruction: Option<u16>) -> String {
    match instruction {
        Some(n) => format!("instruction {n}: mandrel move"),
        None => "mandrel move".to_string(),
    }
}
