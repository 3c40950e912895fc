//! The `windcell` command line: one module per subcommand.

use clap::{Parser, Subcommand};

pub mod argument_error;
pub mod check;
pub mod geodesic;
pub mod jog;
pub mod lathe;
pub mod plan;
pub mod post;
pub mod predict;
pub mod progress;
pub mod pty;
pub mod run;
pub mod run_clock;
pub mod sim_cell;
pub mod sim_grbl;
pub mod sim_indexer;
pub mod sim_marlin;
pub mod sim_robot;
pub mod sweep;
pub mod triasym;
pub mod verify;

/// Exit code for bad input: a file, a field or an argument the operator must fix.
pub const EXIT_INPUT: u8 = 2;
/// Exit code for a failure at run time: a device, a link, the file system.
pub const EXIT_RUNTIME: u8 = 1;

/// The longest simulated duration an argument may ask for (`--home-s`), s: an hour.
pub const MAX_SIM_SECONDS: f64 = 3600.0;
/// The fastest a simulator's motion may run against the wall clock (`--time-scale`).
pub const MAX_TIME_SCALE: f64 = 1e6;

/// A failed command: one line for the operator and the process exit code.
#[derive(Debug)]
pub struct Failure {
    /// The one-line message (file:line:col first where there is one).
    pub message: String,
    /// [`EXIT_INPUT`] or [`EXIT_RUNTIME`].
    pub exit_code: u8,
}

impl Failure {
    /// Bad input (exit code 2).
    pub fn input(message: impl std::fmt::Display) -> Self {
        Failure {
            message: message.to_string(),
            exit_code: EXIT_INPUT,
        }
    }

    /// A run-time failure (exit code 1).
    pub fn runtime(message: impl std::fmt::Display) -> Self {
        Failure {
            message: message.to_string(),
            exit_code: EXIT_RUNTIME,
        }
    }

    /// A coordinator error, input or run time as it says.
    pub fn from_cell(error: cell::Error) -> Self {
        if error.is_input() {
            Failure::input(error)
        } else {
            Failure::runtime(error)
        }
    }
}

/// windcell: coordinator for robotic filament-winding cells.
#[derive(Debug, Parser)]
#[command(name = "windcell", version, about)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Plan a job: write .ROB, .IND, sequence and run files (the TOOL step).
    Plan(plan::PlanArgs),
    /// Write a six-axis job's programs for its controller (RAPID, KRL, FANUC TP, URScript).
    Post(post::PostArgs),
    /// Read robot programs back, check them against the plan and run them on a model (exit 3).
    Verify(verify::VerifyArgs),
    /// Check a job for collisions of the eye and the arm and snags of the free fibre (exit 3).
    Check(check::CheckArgs),
    /// Predict each mode's time and placement error on the simulated cell, before winding.
    Predict(predict::PredictArgs),
    /// Wind a batch on the cell: a job (planned first) or a sequence of control files.
    Run(run::RunArgs),
    /// Manual control: one robot position and one mandrel move, sent together.
    Jog(jog::JogArgs),
    /// Serve the simulated cell (both simulators, one clock, sync lines on a socket) on ptys.
    SimCell(sim_cell::SimCellArgs),
    /// Run the multi-axis GRBL controller simulator (lathe winder) on a pseudo-terminal.
    SimGrbl(sim_grbl::SimGrblArgs),
    /// Run the Marlin controller simulator (lathe winder) on a pseudo-terminal.
    SimMarlin(sim_marlin::SimMarlinArgs),
    /// Run the mandrel indexer simulator on a pseudo-terminal.
    SimIndexer(sim_indexer::SimIndexerArgs),
    /// Run the ASEA robot-computer simulator on a pseudo-terminal.
    SimRobot(sim_robot::SimRobotArgs),
    /// Trace a geodesic on a triangulated mandrel (STL or OBJ).
    Geodesic(geodesic::GeodesicArgs),
    /// Plan a coverage set: the job's first path repeated around the mandrel.
    Sweep(sweep::SweepArgs),
    /// Mesh a job's tube mandrel (TRIASYM) and write it as STL.
    Triasym(triasym::TriasymArgs),
    /// The lathe winder: run a part program on the servo axes, choose the loop gain.
    Lathe(lathe::LatheArgs),
}

/// A cell (`--cell`) must drive the mandrel with the gearing `job` was planned for: the control
/// files carry motor steps, and another gearing would turn the mandrel through other angles.
pub fn same_drive(
    cell: &cell::run::cellfile::Cell,
    planned: mandrel_drive::units::Drive,
    job: &std::path::Path,
) -> Result<(), Failure> {
    if planned.gearing == cell.drive.gearing {
        return Ok(());
    }
    let describe = |g: paths::step::Gearing| {
        format!(
            "{} steps/rev, {}:{} belt",
            g.steps_per_motor_rev, g.motor_teeth, g.mandrel_teeth
        )
    };
    Err(Failure::input(format!(
        "{}: the drive ({}) is not the one {} was planned for ({}): its steps would turn the mandrel through other angles; plan the job with this drive",
        cell.source,
        describe(cell.drive.gearing),
        job.display(),
        describe(planned.gearing)
    )))
}

/// The one line a failure prints, as the operator must see it (docs/testing.md, "Bad input"):
/// every control character (a line break, an escape sequence, a bell from a file or an
/// argument) written as an escape, and every number longer than 20 characters in short form
/// (`1e300`, not 301 digits). The last step of every message, whichever reader or check made
/// it.
pub fn one_line(message: &str) -> String {
    let mut out = String::with_capacity(message.len());
    let mut number = String::new();
    let flush = |number: &mut String, out: &mut String| {
        if number.len() > 20
            && let Ok(v) = number.parse::<f64>()
        {
            out.push_str(&sequences::error::shown(v));
        } else {
            out.push_str(number);
        }
        number.clear();
    };
    let mut chars = message.chars().peekable();
    while let Some(c) = chars.next() {
        let continues = c.is_ascii_digit()
            || (c == '.' && !number.is_empty() && chars.peek().is_some_and(char::is_ascii_digit))
            || (matches!(c, 'e' | 'E')
                && !number.is_empty()
                && chars
                    .peek()
                    .is_some_and(|d| d.is_ascii_digit() || *d == '-' || *d == '+'))
            || (matches!(c, '-' | '+') && number.ends_with(['e', 'E']));
        if continues {
            number.push(c);
            continue;
        }
        flush(&mut number, &mut out);
        if c.is_control() {
            out.extend(c.escape_default());
        } else {
            out.push(c);
        }
    }
    flush(&mut number, &mut out);
    out
}

/// Writes `text` to standard output; a closed pipe (`windcell … | head`) is not an error.
pub fn print(text: &str) -> Result<(), Failure> {
    use std::io::Write;
    let mut stdout = std::io::stdout().lock();
    match stdout
        .write_all(text.as_bytes())
        .and_then(|()| stdout.flush())
    {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => Err(Failure::runtime(e)),
        _ => Ok(()),
    }
}

/// Runs one parsed command line.
pub fn run(cli: Cli) -> Result<(), Failure> {
    match cli.command {
        Command::Plan(args) => plan::run(args),
        Command::Check(args) => check::run(args),
        Command::Post(args) => post::run(args),
        Command::Verify(args) => verify::run(args),
        Command::Run(args) => run::run(args),
        Command::Predict(args) => predict::run(args),
        Command::Jog(args) => jog::run(args),
        Command::SimCell(args) => sim_cell::run(args),
        Command::SimGrbl(args) => sim_grbl::run(args),
        Command::SimMarlin(args) => sim_marlin::run(args),
        Command::SimIndexer(args) => sim_indexer::run(args),
        Command::SimRobot(args) => sim_robot::run(args),
        Command::Geodesic(args) => geodesic::run(args),
        Command::Sweep(args) => sweep::run(args),
        Command::Triasym(args) => triasym::run(args),
        Command::Lathe(args) => lathe::run(args),
    }
}

/// Refuses a plan of the IRB 6/2 cell, made into `files`, that `windcell run` would refuse on
/// the job's own cell (`cell::run::batch::admit`, the pre-run check `run` makes): `plan` and
/// `sweep` exit 2 with its line before anything is written. A six-axis arm's plan is its
/// controller's to run.
pub fn admit(
    job: &sequences::Job,
    text: &str,
    job_path: &std::path::Path,
    files: &[(std::path::PathBuf, String)],
) -> Result<(), Failure> {
    if job.robot_kind() != sequences::job::RobotKind::Irb6 {
        return Ok(());
    }
    cell::run::batch::admit(job, text, job_path, files, None).map_err(Failure::from_cell)?;
    Ok(())
}

/// [`admit`] for a command that has the plan but not its files (`check`): they are made only
/// for the IRB 6/2.
pub fn admit_plan(
    job: &sequences::Job,
    text: &str,
    job_path: &std::path::Path,
    plan: &cell::plan::tool::JobPlan,
) -> Result<(), Failure> {
    if job.robot_kind() != sequences::job::RobotKind::Irb6 {
        return Ok(());
    }
    let files = cell::plan::files::control_files(job, plan).map_err(Failure::from_cell)?;
    admit(job, text, job_path, &files)
}

#[cfg(test)]
mod tests {
    use super::one_line;

    #[test]
    fn long_numbers_are_shortened_and_control_characters_escaped() {
        let big = format!("1{}", "0".repeat(300));
        assert_eq!(
            one_line(&format!("wind angle {big}° is outside 1°..=89°")),
            "wind angle 1e300° is outside 1°..=89°"
        );
        let tiny = format!("0.{}1", "0".repeat(299));
        assert_eq!(one_line(&format!("length {tiny} mm")), "length 1e-300 mm");
        // Short numbers, places and words are kept as they are.
        let kept = "job.toml:12:7: segments = 1e9 exceeds 10000 (CYL_1, 0.25 mm, 1e-3)";
        assert_eq!(one_line(kept), kept);
        assert_eq!(
            one_line("unexpected character '\u{7}' in \u{1b}[2J\nnext"),
            "unexpected character '\\u{7}' in \\u{1b}[2J\\nnext"
        );
    }
}
