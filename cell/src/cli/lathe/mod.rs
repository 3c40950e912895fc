//! `windcell lathe …`: the lathe winder of seed 000 (part programs on PD-controlled servo axes)
//! and the gain choice of seed 003. One module per subcommand.

use clap::{Args, Subcommand};

use super::Failure;

pub mod gear;
pub mod home;
pub mod plan;
pub mod run;
pub mod tune;

/// The lathe winder's commands.
#[derive(Debug, Args)]
pub struct LatheArgs {
    #[command(subcommand)]
    pub command: LatheCommand,
}

/// `windcell lathe` subcommands.
#[derive(Debug, Subcommand)]
pub enum LatheCommand {
    /// Plan a vessel (TOML) or `.wind` job and write its G-code.
    Plan(plan::LathePlanArgs),
    /// Run a part program (Fig 9-1 format) on the simulated lathe winder.
    Run(run::LatheRunArgs),
    /// Machine-zero search of X and Y against the home switch (seed 003 §4.2).
    Home(home::LatheHomeArgs),
    /// Carriage geared to the mandrel at a programmable ratio (seed 003 §4.1).
    Gear(gear::LatheGearArgs),
    /// Position-loop gain by seed 003 Eq. 8 with the Routh check, and the servo step response.
    Tune(tune::LatheTuneArgs),
}

/// Runs `windcell lathe …`.
pub fn run(args: LatheArgs) -> Result<(), Failure> {
    match args.command {
        LatheCommand::Plan(a) => plan::run(a),
        LatheCommand::Run(a) => run::run(a),
        LatheCommand::Tune(a) => tune::run(a),
        LatheCommand::Home(a) => home::run(a),
        LatheCommand::Gear(a) => gear::run(a),
    }
}
