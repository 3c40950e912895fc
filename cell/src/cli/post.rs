//! `windcell post JOB.toml --format rapid|krl|fanuc|urscript -o DIR [--cell CELL.toml]`: a
//! six-axis job's programs for the arm's own controller (`docs/robot-programs.md`). The job is
//! planned and checked first: a plan the check finds a collision or snag in is not posted
//! (exit 3); bad input is one line and exit 2; the programs land whole or not at all.

use std::path::PathBuf;

use cell::plan::{check, output, post};
use clap::{Args, ValueEnum};
use sequences::Job;
use sequences::program::Format;

use super::Failure;

/// The controller's language.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum FormatArg {
    /// ABB RAPID modules (`.mod`).
    Rapid,
    /// KUKA KRL (`.src` + `.dat`).
    Krl,
    /// FANUC TP programs in ASCII (`.ls`).
    Fanuc,
    /// Universal Robots URScript (`.script`).
    Urscript,
}

impl FormatArg {
    /// The format.
    pub fn format(self) -> Format {
        match self {
            FormatArg::Rapid => Format::Rapid,
            FormatArg::Krl => Format::Krl,
            FormatArg::Fanuc => Format::Fanuc,
            FormatArg::Urscript => Format::UrScript,
        }
    }
}

/// Write a six-axis job's robot programs for its controller.
#[derive(Debug, Args)]
pub struct PostArgs {
    /// The job file (TOML), planned for a six-axis arm.
    pub job: PathBuf,
    /// The controller's language.
    #[arg(long, value_enum)]
    pub format: FormatArg,
    /// Where to write the programs (created if missing; written all or nothing).
    #[arg(short = 'o', long = "out", value_name = "DIR")]
    pub out: PathBuf,
    /// The cell file: the robot I/O of the sync lines (`[robot_io]`) of a decoupled mandrel.
    #[arg(long, value_name = "CELL.toml")]
    pub cell: Option<PathBuf>,
}

/// Runs `windcell post`.
pub fn run(args: PostArgs) -> Result<(), Failure> {
    let (job, text) = Job::load(&args.job).map_err(Failure::input)?;
    let format = args.format.format();
    let arm = post::six_axis_arm(&job, &text, &args.job, format).map_err(Failure::from_cell)?;
    let sync = match &args.cell {
        Some(path) => {
            cell::run::cellfile::Cell::load(path)
                .map_err(Failure::from_cell)?
                .robot_io
        }
        None => cell::run::cellfile::DEFAULT_ROBOT_IO,
    };
    output::check_dir(&args.out).map_err(Failure::from_cell)?;
    let checked = check::run(&job, &text, &args.job).map_err(Failure::from_cell)?;
    let files = post::program_files(&job, &checked.plan, &arm, format, sync).map_err(|e| {
        let f = Failure::from_cell(e);
        Failure {
            message: format!("{}: {}", args.job.display(), f.message),
            ..f
        }
    })?;
    if !checked.report.is_clear() {
        return Err(Failure {
            message: format!(
                "{}: not posted: {}",
                args.job.display(),
                check::summary(&checked)
            ),
            exit_code: super::check::EXIT_FINDING,
        });
    }
    output::write_all(&args.out, &files, job.name.get_ref(), output::Stale::Refuse)
        .map_err(Failure::from_cell)?;
    let mut out = check::summary(&checked);
    out.push('\n');
    out += &format!(
        "wrote {} {} files for {} paths to {}\n",
        files.len(),
        format.name(),
        checked.plan.paths.len(),
        args.out.display()
    );
    super::print(&out)
}
