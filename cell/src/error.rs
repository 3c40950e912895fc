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
    /// A mesh file is malformed or not a usable surface (the source names the line or triangle).
    #[error("{}: {source}", file.display())]
    Mesh {
        /// The mesh file.
        file: PathBuf,
        /// What the mesh reader said.
        source: paths::Error,
    },
    /// The check's recording could not be written.
    #[error("recording: {message}")]
    Record {
        /// What the MCAP writer said.
        message: String,
    },
    /// An input file could not be read.
    #[error("{}: {source}", file.display())]
    Read {
        /// The file.
        file: PathBuf,
        /// The system's error.
        source: std::io::Error,
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
                | Error::Mesh { .. }
                | Error::Read { .. }
                | Error::RobotTransfer { .. }
                | Error::IndexerTransfer { .. }
                | Error::Run { input: true, .. }
        )
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
