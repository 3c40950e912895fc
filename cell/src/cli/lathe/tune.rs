//! `windcell lathe tune`: the position-loop gain of seed 003 Eq. 8 (Koren–Bollinger IAE fit) for
//! the servo axis's time constant and the interrupt period, its Routh stability check (Eqs. 3–6),
//! the matching K_p of the PD law for the seed 000 plant, and that plant's closed-loop step
//! response (Ch. 7, G_c = 1).

use clap::Args;
use mandrel_drive::servo::Amplifier;
use paths::control::{ContinuousTf, iae_gain, routh_position_loop, step_metrics};
use serde_json::json;

use crate::cli::{Failure, print};

/// Choose the position-loop gain (seed 003 Eq. 8) and check it (Routh).
#[derive(Debug, Args)]
pub struct LatheTuneArgs {
    /// Servo amplifier gain K_amp (Ch. 7 plant 1772·K_amp / (s (s + 46.7))).
    #[arg(long, default_value_t = 0.45, allow_negative_numbers = true)]
    pub k_amp: f64,
    /// Interrupt rate, Hz (the sampling period T = 1/rate).
    #[arg(
        long,
        value_name = "HZ",
        default_value_t = 200.0,
        allow_negative_numbers = true
    )]
    pub rate: f64,
    /// Mechanical time constant τ, s (default: the plant's, 1/46.7).
    #[arg(long, value_name = "S", allow_negative_numbers = true)]
    pub tau: Option<f64>,
    /// Report as JSON.
    #[arg(long)]
    pub json: bool,
}

/// The fastest sampling `--rate` (1 MHz: a microsecond period) and the longest `--tau` (a day),
/// beyond any servo axis.
const MAX_RATE_HZ: f64 = 1e6;
const MAX_TAU_S: f64 = 86_400.0;

/// Runs `windcell lathe tune`.
pub fn run(args: LatheTuneArgs) -> Result<(), Failure> {
    super::check_k_amp(args.k_amp)?;
    // Any rate: Eq. 8 is for any sampled axis (seed 003's worked value has T = π/2 s); the
    // lathe controller's own 1 … 1000 Hz applies to `lathe run` and `lathe gear`.
    if !(args.rate > 0.0 && args.rate <= MAX_RATE_HZ) {
        return Err(Failure::input(format!(
            "--rate: {} must be > 0 and at most {MAX_RATE_HZ} Hz",
            paths::limits::shown(args.rate)
        )));
    }
    // Below or at zero, Eq. 8's own check refuses it (`tau_s = … must be > 0`).
    if let Some(tau) = args.tau
        && tau > MAX_TAU_S
    {
        return Err(Failure::input(format!(
            "--tau: {} s is more than {MAX_TAU_S} s",
            paths::limits::shown(tau)
        )));
    }
    let (plant_gain, pole) = Amplifier::Voltage { k_amp: args.k_amp }.plant();
    let tau = args.tau.unwrap_or(1.0 / pole);
    let period = 1.0 / args.rate;
    let gain = iae_gain(tau, period).map_err(Failure::input)?;
    let routh = routh_position_loop(gain, tau).map_err(Failure::input)?;
    // Loop gain K = K_p · (plant gain / pole) for K_p in DAC codes per count.
    let kp = gain * pole / plant_gain;
    let closed = ContinuousTf::new(vec![plant_gain], vec![1.0, pole, plant_gain])
        .map_err(Failure::runtime)?;
    let dt = 1e-4;
    let y = closed.step_response(dt, 1.5).map_err(Failure::runtime)?;
    let m5 = step_metrics(&y, dt, 1.0, 0.05);
    let m2 = step_metrics(&y, dt, 1.0, 0.02);
    if args.json {
        let v = json!({
            "tau_s": tau,
            "period_s": period,
            "period_over_tau": period / tau,
            "eq8_gain_per_s": gain,
            "routh_first_column": routh,
            "stable": true,
            "kp_dac_codes_per_count": kp,
            "plant": {"gain": plant_gain, "pole_per_s": pole},
            "step_unity_feedback": {
                "overshoot_pct": m5.overshoot_pct,
                "peak_time_s": m5.peak_time_s,
                "rise_time_s": m5.rise_time_s,
                "settling_5pct_s": m5.settling_time_s,
                "settling_2pct_s": m2.settling_time_s,
            },
        });
        let text = serde_json::to_string_pretty(&v).map_err(Failure::runtime)?;
        return print(&format!("{text}\n"));
    }
    print(&format!(
        "τ = {} s, T = {period:.5} s, T/τ = {:.4}\n\
         Eq. 8 loop gain K = {gain:.4} /s (Routh first column {:?}: stable)\n\
         K_p = {} DAC codes per count for the plant {}/(s (s + {pole}))\n\
         step response with G_c = 1: overshoot {:.1} %, peak {:.0} ms, 5 % settling {:.0} ms, \
         2 % settling {:.0} ms\n",
        paths::limits::fixed(tau, 5),
        period / tau,
        routh
            .iter()
            .map(|c| (c * 1e4).round() / 1e4)
            .collect::<Vec<_>>(),
        paths::limits::fixed(kp, 3),
        paths::limits::fixed(plant_gain, 1),
        m5.overshoot_pct,
        m5.peak_time_s * 1e3,
        m5.settling_time_s * 1e3,
        m2.settling_time_s * 1e3,
    ))
}
