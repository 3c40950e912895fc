//! `windcell predict JOB.toml [--mode M …] [--mandrel-rps R] [--json] [--svg FILE] [--record
//! FILE.mcap]`: time and placement error of each mode before winding (seed 001 Chapter 6;
//! `cell::predict`).

use std::path::PathBuf;

use cell::predict::{self, Mode, Options};
use cell::run::cellfile::Cell;
use cell::run::coordinator::RunMode;
use clap::{Args, ValueEnum};
use sequences::Job;

use super::Failure;

/// `--mode`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum PredictMode {
    /// File control: both devices stop at every point.
    Discrete,
    /// Program control, 1 mm zone.
    Fine,
    /// Program control, 10 mm zone.
    Medium,
    /// Program control kept in step with the mandrel (docs/continuous.md).
    Continuous,
}

/// Predict each mode's time and placement error on the simulated cell.
#[derive(Debug, Args)]
pub struct PredictArgs {
    /// The job file (TOML).
    pub job: PathBuf,
    /// Modes to predict (repeatable; default: discrete, fine, medium and continuous).
    #[arg(long = "mode", value_enum)]
    pub modes: Vec<PredictMode>,
    /// Mandrel speed for every mode, rev/s (default: the job's).
    #[arg(long, value_name = "R", allow_negative_numbers = true)]
    pub mandrel_rps: Option<f64>,
    /// The cell description (its `[tolerance]` drives the setup Monte Carlo).
    #[arg(long, value_name = "CELL.toml")]
    pub cell: Option<PathBuf>,
    /// Monte Carlo samples of the setup error.
    #[arg(long, default_value_t = 200, allow_negative_numbers = true)]
    pub samples: usize,
    /// The Monte Carlo's seed.
    #[arg(long, default_value_t = 1, allow_negative_numbers = true)]
    pub seed: u64,
    /// The report as one JSON document.
    #[arg(long)]
    pub json: bool,
    /// Draw the desired and predicted paths unrolled, and the error along them, as SVG.
    #[arg(long, value_name = "FILE")]
    pub svg: Option<PathBuf>,
    /// Record the desired and laid fibre of every mode and path, the laid fibre growing over
    /// cell time, as MCAP for Foxglove (docs/operator.md).
    #[arg(long, value_name = "FILE.mcap")]
    pub record: Option<PathBuf>,
}

/// Most Monte Carlo samples accepted.
pub const MAX_SAMPLES: usize = 100_000;

/// Runs `windcell predict`.
pub fn run(args: PredictArgs) -> Result<(), Failure> {
    if !(1..=MAX_SAMPLES).contains(&args.samples) {
        return Err(Failure::input(format!(
            "--samples {}: must lie in 1..={MAX_SAMPLES}",
            args.samples
        )));
    }
    let (job, text) = Job::load(&args.job).map_err(Failure::input)?;
    let own = Cell::of_job(&job, &args.job).map_err(Failure::from_cell)?;
    let cell = match &args.cell {
        Some(p) => {
            let cell = Cell::load(p).map_err(Failure::from_cell)?;
            super::same_drive(&cell, own.drive, &args.job)?;
            cell
        }
        None => own,
    };
    let mut modes: Vec<Mode> = args
        .modes
        .iter()
        .map(|m| {
            Mode::Run(match m {
                PredictMode::Discrete => RunMode::Discrete,
                PredictMode::Fine => RunMode::Fine,
                PredictMode::Medium => RunMode::Medium,
                PredictMode::Continuous => RunMode::Continuous,
            })
        })
        .collect();
    if modes.is_empty() {
        modes = Options::default().modes;
    }
    let opt = Options {
        modes,
        mandrel_rps: args.mandrel_rps,
        samples: args.samples,
        seed: args.seed,
        tolerances: cell.tolerances,
        ..Options::default()
    };
    let mut inputs = cell::plan::output::inputs_of_job(&job, &args.job);
    inputs.extend(args.cell.iter().cloned());
    let outputs: Vec<&std::path::Path> = args
        .svg
        .iter()
        .chain(&args.record)
        .map(|p| p.as_path())
        .collect();
    cell::plan::output::check_output_files(&outputs, &inputs).map_err(Failure::from_cell)?;
    let prediction =
        predict::predict(&job, &text, &args.job, &cell, &opt).map_err(Failure::from_cell)?;
    no_mode_winds(&prediction)?;
    if let Some(svg) = &args.svg {
        let tube =
            cell::plan::tool::mandrel_in(&job, &text, &args.job).map_err(Failure::from_cell)?;
        let text = prediction
            .svg(&tube)
            .map_err(|e| Failure::runtime(format!("{}: {e}", svg.display())))?;
        cell::plan::output::write_file(svg, text.as_bytes()).map_err(Failure::from_cell)?;
    }
    if let Some(path) = &args.record {
        let sinks = cell::record::Sinks {
            mcap: Some(path.clone()),
            live: None,
        };
        let epoch_ns = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos() as u64);
        let rec = cell::record::Recorder::open(&sinks, epoch_ns).map_err(Failure::from_cell)?;
        prediction.record(&rec);
        rec.finish().map_err(Failure::from_cell)?;
    }
    if args.json {
        let mut out = serde_json::to_string_pretty(&prediction.json()).map_err(Failure::runtime)?;
        out.push('\n');
        super::print(&out)
    } else {
        super::print(&prediction.text())
    }
}

/// When no mode asked for can wind the job, there is nothing to predict: the first mode's reason
/// in one line (its `FILE:LINE:COL` first), exit code 2, nothing written. A report with at least
/// one mode predicted keeps the others' reasons in it.
fn no_mode_winds(prediction: &predict::Prediction) -> Result<(), Failure> {
    let mut refused = prediction.modes.iter().filter_map(|m| {
        m.outcome
            .as_ref()
            .err()
            .map(|e| (m.mode.keyword(), m.mandrel_rps, e))
    });
    let Some((mode, rps, reason)) = refused.next() else {
        return Ok(());
    };
    let others: Vec<&str> = refused.map(|(m, _, _)| m).collect();
    if others.len() + 1 < prediction.modes.len() {
        return Ok(());
    }
    let also = if others.is_empty() {
        String::new()
    } else {
        format!("; {} cannot either", others.join(", "))
    };
    Err(Failure::input(format!(
        "{reason} ({mode} at {rps} rev/s{also})"
    )))
}
