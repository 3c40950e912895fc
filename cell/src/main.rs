//! `windcell`: the filament-winding cell coordinator.
//!
//! One file per subcommand under `src/cli/`. A user error (bad file, bad argument) prints one line
//! and exits with code 2; a device or link failure exits with code 1. Nothing panics on bad input.

mod cli;

use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    let argv: Vec<String> = std::env::args_os()
        .map(|a| a.to_string_lossy().into_owned())
        .collect();
    let args = match cli::Cli::try_parse() {
        Ok(args) => args,
        Err(error) => {
            use clap::error::ErrorKind;
            if matches!(
                error.kind(),
                ErrorKind::DisplayHelp | ErrorKind::DisplayVersion
            ) {
                // `--help` and `--version` go to standard output; a closed pipe is not an error.
                let _ = cli::print(&error.render().to_string());
                return ExitCode::SUCCESS;
            }
            eprintln!(
                "windcell: {}",
                cli::one_line(&cli::argument_error::render(&error, &argv))
            );
            return ExitCode::from(cli::EXIT_INPUT);
        }
    };
    match cli::run(args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(failure) => {
            eprintln!("windcell: {}", cli::one_line(&failure.message));
            ExitCode::from(failure.exit_code)
        }
    }
}
