//! `windcell lathe …`: the lathe winder of seed 000 (part programs on PD-controlled servo axes)
//! and the gain choice of seed 003. One module per subcommand.

use clap::{Args, Subcommand};

use super::Failure;

pub mod gear;
pub mod home;
pub mod machine;
pub mod out_file;
pub mod plan;
pub mod run;
pub mod stream;
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
    /// Stream a G-code program to a GRBL-class controller over a serial port.
    Stream(stream::LatheStreamArgs),
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
        LatheCommand::Stream(a) => stream::run(a),
        LatheCommand::Tune(a) => tune::run(a),
        LatheCommand::Home(a) => home::run(a),
        LatheCommand::Gear(a) => gear::run(a),
    }
}

/// `--rate`: the interrupt rate the controller runs at, 1 … 1000 Hz.
fn check_rate(hz: f64) -> Result<(), Failure> {
    if !(1.0..=1000.0).contains(&hz) {
        return Err(Failure::input(format!(
            "--rate: {} Hz is outside 1 … 1000 Hz",
            paths::limits::shown(hz)
        )));
    }
    Ok(())
}

/// `--k-amp`: the voltage amplifier's gain, (0, 8] (seed 000 Ch. 7).
fn check_k_amp(k_amp: f64) -> Result<(), Failure> {
    if !(k_amp > 0.0 && k_amp <= 8.0) {
        return Err(Failure::input(format!(
            "--k-amp: {} is outside (0, 8] (Ch. 7)",
            paths::limits::shown(k_amp)
        )));
    }
    Ok(())
}
