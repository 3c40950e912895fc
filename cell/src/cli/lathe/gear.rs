//! `windcell lathe gear`: electronic gearing (seed 003 §4.1 item 3) as the alternative to
//! interpolated axes: the mandrel is the master, the carriage follows its measured angle at a
//! programmable ratio.

use clap::Args;
use mandrel_drive::servo::Amplifier;
use paths::limits::{fixed, shown};
use serde_json::json;

use crate::cli::{Failure, print};

/// Run the carriage geared to the mandrel on the simulated machine.
#[derive(Debug, Args)]
pub struct LatheGearArgs {
    /// Carriage millimetres per mandrel degree (negative: the carriage runs toward machine zero).
    #[arg(long, value_name = "MM_PER_DEG", allow_hyphen_values = true)]
    pub ratio: f64,
    /// Mandrel turns.
    #[arg(
        long,
        value_name = "N",
        default_value_t = 2.0,
        allow_negative_numbers = true
    )]
    pub turns: f64,
    /// Mandrel speed, degrees per second.
    #[arg(
        long,
        value_name = "DEG_S",
        default_value_t = 90.0,
        allow_negative_numbers = true
    )]
    pub speed: f64,
    /// Time to reach the speed (and to stop), s.
    #[arg(
        long,
        value_name = "S",
        default_value_t = 0.5,
        allow_negative_numbers = true
    )]
    pub ramp: f64,
    /// Interrupt rate, Hz.
    #[arg(
        long,
        value_name = "HZ",
        default_value_t = 200.0,
        allow_negative_numbers = true
    )]
    pub rate: f64,
    /// Servo amplifier gain K_amp.
    #[arg(long, default_value_t = 0.45, allow_negative_numbers = true)]
    pub k_amp: f64,
    /// Report as JSON.
    #[arg(long)]
    pub json: bool,
}

/// Runs `windcell lathe gear`.
pub fn run(args: LatheGearArgs) -> Result<(), Failure> {
    super::check_rate(args.rate)?;
    super::check_k_amp(args.k_amp)?;
    let setup = cell::lathe::Setup {
        amplifier: Amplifier::Voltage { k_amp: args.k_amp },
        interrupt_hz: args.rate,
        ..cell::lathe::Setup::default()
    };
    let g = cell::lathe::gear(&setup, args.ratio, args.speed, args.turns, args.ramp)
        .map_err(Failure::from_cell)?;
    if args.json {
        let text = serde_json::to_string_pretty(&json!(g)).map_err(Failure::runtime)?;
        return print(&format!("{text}\n"));
    }
    print(&format!(
        "geared at {} mm/°: mandrel {}°, carriage {} mm (ratio × angle {} mm), \
         worst |X − ratio·A| {} mm over {} interrupts\n",
        shown(g.ratio_mm_per_deg),
        fixed(g.mandrel_deg, 3),
        fixed(g.carriage_mm, 3),
        fixed(g.ratio_mm_per_deg * g.mandrel_deg, 3),
        fixed(g.worst_error_mm, 3),
        g.interrupts
    ))
}
