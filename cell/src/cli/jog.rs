//! `windcell jog`: manual control (seed 001 §5.3.2, §5.4): one robot position (absolute or
//! relative, rectangular or joint, wrist pitch and roll, speed) and one mandrel instruction, sent
//! together and each confirmed, with the run's limit checks.

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use asea_protocol::{Flags, Interpolation, Pose, Positioning, Reference, Speed, Zone};
use cell::run::cellfile::Cell;
use cell::run::coordinator::{Coordinator, Event, Halt, Reach};
use cell::run::journal::Journal;
use clap::Args;
use sequences::MandrelMove;

use super::{Failure, print};

/// Arguments of `windcell jog`.
#[derive(Debug, Args)]
pub struct JogArgs {
    /// Eye position `X,Y,Z`, mm (cell frame; with `--rel` an offset from where the eye is).
    #[arg(
        long,
        value_name = "X,Y,Z",
        value_delimiter = ',',
        required = true,
        allow_negative_numbers = true
    )]
    pub pos: Vec<f64>,
    /// Relative to the robot's position now.
    #[arg(long)]
    pub rel: bool,
    /// Robot (joint) movement instead of rectangular (a straight line).
    #[arg(long)]
    pub joint: bool,
    /// Wrist pitch, degrees (App. A).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub pitch_deg: f64,
    /// Wrist roll, degrees (App. A).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub roll_deg: f64,
    /// Speed, % of the base speed.
    #[arg(long, default_value_t = 10.0, allow_negative_numbers = true)]
    pub speed_pct: f64,
    /// Base speed, mm/s (§5.4.1).
    #[arg(long, default_value_t = 1000.0, allow_negative_numbers = true)]
    pub base_speed_mm_s: f64,
    /// Maximum speed, mm/s.
    #[arg(long, default_value_t = 2000.0, allow_negative_numbers = true)]
    pub max_speed_mm_s: f64,
    /// Mandrel move, motor steps (0: none).
    #[arg(long, default_value_t = 0, allow_negative_numbers = true)]
    pub steps: i64,
    /// Mandrel acceleration, rev/s².
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    pub accel_rps2: f64,
    /// Mandrel start/stop velocity, rev/s.
    #[arg(long, default_value_t = 0.05, allow_negative_numbers = true)]
    pub start_rps: f64,
    /// Mandrel maximum velocity, rev/s.
    #[arg(long, default_value_t = 0.1, allow_negative_numbers = true)]
    pub max_rps: f64,
    /// The cell (default: the built-in simulated cell, powered up for this one move).
    #[arg(long, value_name = "CELL.toml")]
    pub cell: Option<PathBuf>,
}

/// Runs `windcell jog`: the arguments checked (nothing is sent before every check passed), then
/// the one move on the cell.
pub fn run(args: JogArgs) -> Result<(), Failure> {
    let cell = match &args.cell {
        Some(p) => Cell::load(p).map_err(Failure::from_cell)?,
        None => Cell::simulated(),
    };
    let [x, y, z] = <[f64; 3]>::try_from(args.pos.as_slice())
        .map_err(|_| Failure::input("jog: --pos needs X,Y,Z"))?;
    let q = wrist(&args)?;
    check_profile(&args, &cell)?;
    let p = Positioning {
        flags: Flags {
            interpolation: if args.joint {
                Interpolation::Joint
            } else {
                Interpolation::Rectangular
            },
            reference: Reference::Absolute,
            zone: Zone::Fine,
        },
        pose: Pose::from_mm([x, y, z], q).map_err(|e| Failure::input(format!("jog: {e}")))?,
        speed: telegram_speed("--speed-pct", args.speed_pct, 100.0, "%")?,
    };
    let speeds = (
        telegram_speed("--base-speed-mm-s", args.base_speed_mm_s, 1000.0, "mm/s")?,
        telegram_speed("--max-speed-mm-s", args.max_speed_mm_s, 1000.0, "mm/s")?,
    );
    let mandrel = mandrel_move(&args, &cell)?;
    if !args.rel && !Reach::default().holds([x, y, z]) {
        return Err(Failure::input(format!(
            "jog: the eye at ({x:.1}, {y:.1}, {z:.1}) mm is out of the arm's reach"
        )));
    }
    let (devices, _sim) =
        super::run::devices(&cell, None, &cell::record::linktap::RecordSlot::default())?;
    let mut sink = |_e: Event| {};
    let mut c = Coordinator::new(
        devices,
        Arc::new(AtomicBool::new(false)),
        Journal::none(),
        &mut sink,
    );
    match c.jog(speeds, p, args.rel, mandrel, Reach::default()) {
        Ok((at, counter)) => print(&format!(
            "robot at ({:.2}, {:.2}, {:.2}) mm; indexer counter {counter} steps\n",
            at[0], at[1], at[2]
        )),
        Err(s) => Err(match s.halt {
            Halt::Interrupted { reason } => Failure {
                message: format!("jog interrupted ({reason})"),
                exit_code: super::run::EXIT_INTERRUPTED,
            },
            // A target the arm or the telegram cannot take is the input's fault, found before
            // the robot moved; anything else happened at the devices.
            Halt::Fault(f) if f.is_input() => Failure {
                message: format!("jog: {f}"),
                exit_code: super::EXIT_INPUT,
            },
            Halt::Fault(f) => Failure::runtime(format!("jog: {f}")),
        }),
    }
}

/// The wrist quaternion of `--pitch-deg` and `--roll-deg`. They are angles: beyond a turn either
/// way they are wrong values, refused here rather than by the robot computer after the telegram
/// went out.
fn wrist(args: &JogArgs) -> Result<[f64; 4], Failure> {
    for (flag, deg) in [
        ("--pitch-deg", args.pitch_deg),
        ("--roll-deg", args.roll_deg),
    ] {
        if !(deg.is_finite() && deg.abs() <= 360.0) {
            return Err(Failure::input(format!(
                "jog: {flag} {} must lie in -360 … 360 degrees",
                paths::limits::shown(deg)
            )));
        }
    }
    Ok(paths::wrist::components(&paths::wrist::from_pitch_roll(
        args.pitch_deg.to_radians(),
        args.roll_deg.to_radians(),
    )))
}

/// A speed flag `name` of value `v` in its own unit (`per_unit` of it make the telegram's 1.0):
/// its range is the telegram's, told in that unit; a speed that rounds to zero is refused.
fn telegram_speed(name: &'static str, v: f64, per_unit: f64, unit: &str) -> Result<Speed, Failure> {
    let limit = f64::from(u16::MAX) / 8192.0 * per_unit;
    let s = Speed::from_value(name, v / per_unit).map_err(|_| {
        Failure::input(format!(
            "jog: {name} {}: out of range (0 to {limit:.2} {unit}, the telegram's)",
            paths::limits::shown(v)
        ))
    })?;
    if s.0 == 0 {
        return Err(Failure::input(format!(
            "jog: {name} {} rounds to zero",
            paths::limits::shown(v)
        )));
    }
    Ok(s)
}

/// The mandrel's profile flags, checked whether or not this jog turns the mandrel, by the
/// indexer profile's own validation, and named as the flags they came from.
fn check_profile(args: &JogArgs, cell: &Cell) -> Result<(), Failure> {
    mandrel_drive::Profile {
        accel_rps2: args.accel_rps2,
        start_rps: args.start_rps,
        max_rps: args.max_rps,
    }
    .validate(&cell.drive)
    .map_err(|e| match e {
        mandrel_drive::Error::OutOfRange {
            name,
            value,
            expected,
        } => Failure::input(format!(
            "jog: --{} {}: must be {expected}",
            name.replace('_', "-"),
            paths::limits::shown(value)
        )),
        other => Failure::input(format!("jog: {other}")),
    })
}

/// The jog's mandrel move (`None` for `--steps 0`), checked as the pre-run check checks one: in
/// the indexer's ranges, and ending within the coordinator's wait for it (a longer one would be
/// sent, turn the mandrel, and then be called a device failure).
fn mandrel_move(args: &JogArgs, cell: &Cell) -> Result<Option<MandrelMove>, Failure> {
    if args.steps == 0 {
        return Ok(None);
    }
    let m = MandrelMove {
        accel_rps2: args.accel_rps2,
        start_stop_rps: args.start_rps,
        max_rps: args.max_rps,
        steps: args.steps,
    };
    let least_s =
        (m.steps.unsigned_abs() as f64) / (m.max_rps * cell.drive.steps_per_mandrel_rev());
    if least_s.is_nan() || least_s > cell::run::coordinator::MOVE_TIMEOUT_S {
        return Err(Failure::input(format!(
            "jog: --steps {} takes at least {} s at --max-rps {}, longer than the {} s a move may \
             take",
            m.steps,
            paths::limits::shown(least_s),
            paths::limits::shown(m.max_rps),
            cell::run::coordinator::MOVE_TIMEOUT_S
        )));
    }
    cell::run::transfer::indexer_move(
        &m,
        &cell::run::transfer::IndexerSetup {
            drive: cell.drive,
            start_velocity_command: true,
        },
        None,
    )
    .map_err(Failure::from_cell)?;
    Ok(Some(m))
}
