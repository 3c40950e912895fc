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
    /// An input file could not be read.
    #[error("{}: {source}", file.display())]
    Read {
        /// The file.
        file: PathBuf,
        /// The system's error.
        source: std::io::Error,
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
    /// True when the operator's input is at fault (exit code 2), false for run-time failures.
    pub fn is_input(&self) -> bool {
        matches!(
            self,
            Error::File(sequences::Error::Parse { .. })
                | Error::File(sequences::Error::Content { .. })
                | Error::Plan { .. }
                | Error::Mesh { .. }
                | Error::Read { .. }
        )
    }
}
