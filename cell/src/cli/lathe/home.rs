//! `windcell lathe home`: the machine-zero search of seed 003 §4.2 on the simulated lathe winder's
//! X and Y: toward the home switch, off it, then a whole number of encoder pulses beyond the
//! release edge. Reports where each axis ended (the same encoder count from any start).

use clap::Args;
use mandrel_drive::servo::Amplifier;
use serde_json::json;

use crate::cli::{Failure, print};

/// Machine-zero search of X and Y on the simulated machine.
#[derive(Debug, Args)]
pub struct LatheHomeArgs {
    /// Power-on position of X and Y as X_MM,Y_MM (the home switch is made at −1 mm).
    #[arg(
        long,
        value_name = "X,Y",
        default_value = "150,10",
        allow_hyphen_values = true
    )]
    pub from: String,
    /// Whole encoder pulses beyond the switch's release edge.
    #[arg(
        long,
        value_name = "PULSES",
        default_value_t = 100,
        allow_negative_numbers = true
    )]
    pub backoff: i64,
    /// Power-on value of the 16-bit encoder counters.
    #[arg(
        long,
        value_name = "RAW",
        default_value_t = 0,
        allow_negative_numbers = true
    )]
    pub counter_start: u16,
    /// Servo amplifier gain K_amp.
    #[arg(long, default_value_t = 0.45, allow_negative_numbers = true)]
    pub k_amp: f64,
    /// Report as JSON.
    #[arg(long)]
    pub json: bool,
}

/// Runs `windcell lathe home`.
pub fn run(args: LatheHomeArgs) -> Result<(), Failure> {
    let v: Vec<f64> = args
        .from
        .split(',')
        .map(|s| s.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| Failure::input(format!("--from: '{}' is not X_MM,Y_MM", args.from)))?;
    let [x, y] = v.as_slice() else {
        return Err(Failure::input(format!(
            "--from: '{}' is not X_MM,Y_MM",
            args.from
        )));
    };
    super::check_k_amp(args.k_amp)?;
    let setup = cell::lathe::Setup {
        amplifier: Amplifier::Voltage { k_amp: args.k_amp },
        counter_start: args.counter_start,
        ..cell::lathe::Setup::default()
    };
    let homed = cell::lathe::home(&setup, [*x, *y], args.backoff).map_err(Failure::from_cell)?;
    if args.json {
        let text =
            serde_json::to_string_pretty(&json!({ "axes": homed })).map_err(Failure::runtime)?;
        return print(&format!("{text}\n"));
    }
    let mut out = String::new();
    for h in &homed {
        out.push_str(&format!(
            "{}: from {} mm, machine zero at encoder count {} (counter {}), {} interrupts ({:.2} s)\n",
            h.axis,
            paths::limits::shown(h.start_mm),
            h.machine_zero_count,
            h.raw_counter,
            h.interrupts,
            h.interrupts as f64 / setup.interrupt_hz
        ));
    }
    print(&out)
}
