//! `windcell run --clock real|fast --speed FACTOR`: how the built-in simulated cell keeps time.
//!
//! `fast` runs the cell's virtual clock as fast as the coordinator waits on it (a batch in
//! milliseconds). `real` paces it by the wall clock ([`paths::link::VirtualClock::paced`]), at
//! `--speed` cell seconds per wall second (1 by default: the real cell's speed), so that a live
//! viewer sees the cell move as it would. `--live` makes `real` the default; `--speed` alone
//! implies `real`. A cell on serial ports keeps its own time: both options are refused there.

use clap::ValueEnum;

use super::Failure;

/// `--clock`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ClockArg {
    /// The wall clock's pace, times `--speed`.
    Real,
    /// As fast as the computer runs the simulators.
    Fast,
}

/// `--speed FACTOR`: a finite number within [`cell::sim::SPEED_RANGE`].
pub fn speed_factor(text: &str) -> Result<f64, String> {
    let (lo, hi) = cell::sim::SPEED_RANGE;
    match text.trim().parse::<f64>() {
        Ok(k) if k.is_finite() && (lo..=hi).contains(&k) => Ok(k),
        _ => Err(format!(
            "the speed factor must be a number from {lo} to {hi} (cell seconds per wall second)"
        )),
    }
}

/// The simulated cell's pace: `None` for the fast clock, `Some(speed)` for the real one.
/// `simulated` is false for a cell on serial ports, where `--clock` and `--speed` are refused.
pub fn pace(
    clock: Option<ClockArg>,
    speed: Option<f64>,
    live: bool,
    simulated: bool,
) -> Result<Option<f64>, Failure> {
    if !simulated && (clock.is_some() || speed.is_some()) {
        return Err(Failure::input(
            "--clock and --speed set the built-in simulated cell's time; this cell's devices are \
             on serial ports and keep their own",
        ));
    }
    if !simulated {
        return Ok(None);
    }
    match (clock, speed) {
        (Some(ClockArg::Fast), Some(k)) => Err(Failure::input(format!(
            "--speed {k}: the fast clock has no speed (it runs as fast as it can); use --clock real"
        ))),
        (Some(ClockArg::Fast), None) => Ok(None),
        (Some(ClockArg::Real), k) => Ok(Some(k.unwrap_or(1.0))),
        (None, Some(k)) => Ok(Some(k)),
        (None, None) => Ok(live.then_some(1.0)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Inside the range and finite only; the real clock by default with `--live`, the fast one
    /// otherwise; `--speed` alone means the real clock; `--speed` with `--clock fast` and either
    /// on serial ports are refused as bad input.
    #[test]
    fn the_pace_follows_the_options() {
        assert_eq!(speed_factor("1"), Ok(1.0));
        assert_eq!(speed_factor(" 20 "), Ok(20.0));
        assert_eq!(speed_factor("0.1"), Ok(0.1));
        assert_eq!(speed_factor("1000"), Ok(1000.0));
        for bad in ["0", "-1", "0.05", "1001", "nan", "inf", "1e400", "", "fast"] {
            assert!(speed_factor(bad).is_err(), "{bad}");
        }
        assert_eq!(pace(None, None, false, true).unwrap(), None);
        assert_eq!(pace(None, None, true, true).unwrap(), Some(1.0));
        assert_eq!(pace(Some(ClockArg::Fast), None, true, true).unwrap(), None);
        assert_eq!(
            pace(Some(ClockArg::Real), None, false, true).unwrap(),
            Some(1.0)
        );
        assert_eq!(pace(None, Some(5.0), false, true).unwrap(), Some(5.0));
        assert_eq!(
            pace(Some(ClockArg::Real), Some(5.0), true, true).unwrap(),
            Some(5.0)
        );
        let e = pace(Some(ClockArg::Fast), Some(5.0), false, true).unwrap_err();
        assert_eq!(e.exit_code, super::super::EXIT_INPUT);
        assert!(pace(Some(ClockArg::Real), None, false, false).is_err());
        assert!(pace(None, Some(2.0), true, false).is_err());
        assert_eq!(pace(None, None, true, false).unwrap(), None);
    }
}
