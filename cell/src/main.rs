//! `windcell`: the filament-winding cell coordinator.
//!
//! One file per subcommand under `src/cli/`. A user error (bad file, bad argument) prints one line
//! and exits with code 2; a device or link failure exits with code 1. Nothing panics on bad input.

mod cli;

use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    let args = cli::Cli::parse();
    match cli::run(args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(failure) => {
            eprintln!("windcell: {}", failure.message);
            ExitCode::from(failure.exit_code)
        }
    }
}
