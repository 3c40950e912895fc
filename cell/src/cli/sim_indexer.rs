//! `windcell sim-indexer [--pty] [--dialect x|grbl]`: the mandrel indexer simulator on a
//! pseudo-terminal (docs/mandrel-drive.md).
//!
//! Prints the slave device path on one line, serves the simulated indexer on the master side in
//! real time until SIGINT or SIGTERM, then exits 0.
//!
//! Fault injection (X-language): SIGUSR1 takes the motor's pull-in torque away (its pull-in rate
//! becomes [`WEAK_PULL_IN_SPS`], so the next move's start stalls, as a motor whose drive lost
//! current would); SIGUSR2 gives it back.

use std::sync::{Arc, Mutex};

use clap::{Args, ValueEnum};
use mandrel_drive::Drive;
use mandrel_drive::sim::machine::PULL_IN_SPS;
use mandrel_drive::sim::{Machine, WallClock, grbl::Controller, serve, xlang::Card};

use super::pty::{Ptys, Signals, stop_records};
use super::{Failure, print};

/// The motor's pull-in rate after SIGUSR1, steps/s: below any start velocity.
pub const WEAK_PULL_IN_SPS: f64 = 1.0;

/// The command language the simulator speaks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Dialect {
    /// Compumotor X-language (2100 / PC21 / OEM family).
    X,
    /// GRBL 1.1, the mandrel on the A axis.
    Grbl,
}

/// Arguments of `windcell sim-indexer`.
#[derive(Debug, Args)]
#[command(allow_negative_numbers = true)]
pub struct SimIndexerArgs {
    /// Serve on a new pseudo-terminal and print its device path. This is the only transport and
    /// the default: the flag may be given or left out.
    #[arg(long)]
    pub pty: bool,
    /// Command language.
    #[arg(long, value_enum, default_value = "x")]
    pub dialect: Dialect,
    /// X-language device address (1–255).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u8).range(1..), allow_negative_numbers = true)]
    pub address: u8,
    /// Log every move the indexer finishes as a JSON line (docs/file-formats.md, "Simulator
    /// logs"; X-language only).
    #[arg(long, value_name = "FILE")]
    pub log: Option<std::path::PathBuf>,
    /// Motor pull-in rate, steps/s: a start velocity above it stalls the motor.
    #[arg(long, default_value_t = PULL_IN_SPS, allow_negative_numbers = true)]
    pub pull_in_sps: f64,
}

/// Runs the simulator until SIGINT or SIGTERM.
pub fn run(args: SimIndexerArgs) -> Result<(), Failure> {
    if !(args.pull_in_sps.is_finite() && args.pull_in_sps > 0.0) {
        return Err(Failure::input(format!(
            "sim-indexer: --pull-in-sps {} must be a positive number",
            args.pull_in_sps
        )));
    }
    // The log is created before the pseudo-terminal is offered (nothing printed on a refusal).
    let log = match (&args.log, args.dialect) {
        (Some(p), Dialect::X) => Some(
            std::fs::File::create(p)
                .map_err(|e| Failure::input(format!("{}: {e}", p.display())))?,
        ),
        _ => None,
    };
    let signals = Signals::register("sim-indexer", true)?;
    let ptys = Ptys::open("sim-indexer", 1)?;
    print(&format!("{}\n", ptys.paths()?.join("\n")))?;
    let machine = Machine::new(Drive::default(), args.pull_in_sps);
    let clock = WallClock::new();
    let (stop, weaken, restore) = (&signals.stop, &signals.usr1, &signals.usr2);
    ptys.serve(|masters| {
        let Some(master) = masters.into_iter().next() else {
            return Ok(());
        };
        match args.dialect {
            Dialect::X => {
                let card = Arc::new(Mutex::new(Card::new(machine, args.address)));
                // The log notes when each `S` arrives (wall clock), for the stop latency.
                let (tap, stops) = cell::sim::wiretap::StopTap::new(
                    master,
                    cell::sim::wiretap::StopPattern::IndexerStop,
                );
                let master = tap;
                std::thread::scope(|scope| {
                    // Fault injection: SIGUSR1 weakens the motor, SIGUSR2 restores it.
                    {
                        let card = &card;
                        let nominal = args.pull_in_sps;
                        scope.spawn(move || {
                            use std::sync::atomic::Ordering::Relaxed;
                            while !stop.load(Relaxed) {
                                let set = if weaken.swap(false, Relaxed) {
                                    Some(WEAK_PULL_IN_SPS)
                                } else if restore.swap(false, Relaxed) {
                                    Some(nominal)
                                } else {
                                    None
                                };
                                if let (Some(rate), Ok(mut c)) = (set, card.lock()) {
                                    c.machine.pull_in_sps = rate;
                                }
                                std::thread::sleep(std::time::Duration::from_millis(1));
                            }
                        });
                    }
                    if let Some(mut file) = log {
                        let (card, clock, stops) = (&card, &clock, &stops);
                        scope.spawn(move || {
                            use mandrel_drive::sim::{Clock as _, Frontend as _};
                            use std::io::Write as _;
                            let mut moving = false;
                            while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                                let Ok(c) = card.lock() else { return };
                                let m = c.machine();
                                if moving && !m.is_moving() {
                                    let line = serde_json::json!({
                                        "device": "indexer", "t_s": clock.now_s(),
                                        "steps": m.steps_since_move_start(),
                                    });
                                    let _ = writeln!(file, "{line}");
                                }
                                moving = m.is_moving();
                                drop(c);
                                for r in stop_records("indexer", stops, clock.now_s()) {
                                    let _ = writeln!(file, "{r}");
                                }
                                std::thread::sleep(std::time::Duration::from_millis(1));
                            }
                        });
                    }
                    serve(master, &card, &clock, stop)
                })
            }
            Dialect::Grbl => serve(
                master,
                &Arc::new(Mutex::new(Controller::new(machine))),
                &clock,
                stop,
            ),
        }
    })
}
