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
    /// A run cannot start or go on: `input` true when the operator's files or arguments are at
    /// fault (exit code 2), false for the cell (exit code 1).
    #[error("{message}")]
    Run {
        /// One line for the operator.
        message: String,
        /// True for bad input.
        input: bool,
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
            Error::Named { source, .. } => return source.is_input(),
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
        )
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
