//! `windcell verify DIR --job JOB.toml`: reads the robot programs in DIR back, checks them
//! against the job's plan and the arm, and runs them on a model of the cell (`cell::verify`).
//! Exit 0 clean, 3 with findings (each naming `FILE:LINE`), 2 for a file it cannot read.

use std::path::PathBuf;

use clap::Args;
use sequences::Job;

use super::Failure;

/// Read robot programs back, check them against the plan and run them on a model of the cell.
#[derive(Debug, Args)]
pub struct VerifyArgs {
    /// The folder of programs (one format: .mod, .src/.dat, .ls or .script).
    pub dir: PathBuf,
    /// The job the programs were posted from.
    #[arg(long, value_name = "JOB.toml")]
    pub job: PathBuf,
    /// The cell file (read for its errors only: the programs carry their own signals).
    #[arg(long, value_name = "CELL.toml")]
    pub cell: Option<PathBuf>,
}

/// Runs `windcell verify`.
pub fn run(args: VerifyArgs) -> Result<(), Failure> {
    let (job, text) = Job::load(&args.job).map_err(Failure::input)?;
    if let Some(cell) = &args.cell {
        cell::run::cellfile::Cell::load(cell).map_err(Failure::from_cell)?;
    }
    let opt = cell::predict::Options::default();
    let verified = cell::verify::verify(&job, &text, &args.job, &args.dir, &opt)
        .map_err(Failure::from_cell)?;
    super::print(&verified.text())?;
    if verified.findings.is_empty() {
        Ok(())
    } else {
        Err(Failure {
            message: format!(
                "verify: {} findings; first: {}",
                verified.findings.len(),
                verified.findings[0]
            ),
            exit_code: super::check::EXIT_FINDING,
        })
    }
}
