//! The mandrel motion profile: acceleration, start/stop velocity, maximum velocity (seed 001 §5.3.2).
//!
//! "The stepper motor will start to operate if the velocity has reached the start velocity, and
//! stop operating when it reaches the stop velocity": the step rate jumps from 0 to `v0`, ramps at
//! `a` to `vmax`, ramps back down to `v0` and stops (docs/mandrel-drive.md, simulator).

use crate::error::{Error, Result};
use crate::units::Drive;

/// A motion profile in physical units at the mandrel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Profile {
    /// Angular acceleration (and deceleration), mandrel rev/s².
    pub accel_rps2: f64,
    /// Start/stop velocity, mandrel rev/s (0 = start from rest).
    pub start_rps: f64,
    /// Maximum velocity, mandrel rev/s.
    pub max_rps: f64,
}

impl Profile {
    /// Checks signs and ordering and the translator's pulse limit.
    pub fn validate(&self, drive: &Drive) -> Result<()> {
        if !(self.accel_rps2.is_finite() && self.accel_rps2 > 0.0) {
            return Err(Error::OutOfRange {
                name: "accel_rps2",
                value: self.accel_rps2,
                expected: "> 0",
            });
        }
        if !(self.max_rps.is_finite() && self.max_rps > 0.0) {
            return Err(Error::OutOfRange {
                name: "max_rps",
                value: self.max_rps,
                expected: "> 0",
            });
        }
        if !(self.start_rps.is_finite() && self.start_rps >= 0.0 && self.start_rps <= self.max_rps)
        {
            return Err(Error::OutOfRange {
                name: "start_rps",
                value: self.start_rps,
                expected: "0 ≤ start_rps ≤ max_rps",
            });
        }
        drive.check_pulse_rate(self.max_rps)
    }

    /// The profile in motor steps: (start steps/s, max steps/s, steps/s²).
    pub fn in_steps(&self, drive: &Drive) -> StepProfile {
        StepProfile {
            v0_sps: drive.steps_per_s(self.start_rps),
            vmax_sps: drive.steps_per_s(self.max_rps),
            accel_sps2: drive.steps_per_s(self.accel_rps2),
        }
    }
}

/// A profile in motor steps.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepProfile {
    /// Start/stop step rate (steps/s).
    pub v0_sps: f64,
    /// Maximum step rate (steps/s).
    pub vmax_sps: f64,
    /// Acceleration (steps/s²).
    pub accel_sps2: f64,
}

/// Duration of a preset move of `distance_steps` on the trapezoid with start/stop velocity `v0`:
/// jump to `v0`, ramp at `a` to `vmax` (or to the peak `sqrt(v0² + a·d)` if the move is too short),
/// cruise, ramp down to `v0`, stop. Seconds; 0 for a zero distance.
pub fn trapezoid_duration_s(distance_steps: f64, p: StepProfile) -> f64 {
    let d = distance_steps.abs();
    let (v0, vmax, a) = (p.v0_sps, p.vmax_sps, p.accel_sps2);
    if d == 0.0 {
        return 0.0;
    }
    if v0 >= vmax {
        return d / vmax;
    }
    let ramp = (vmax * vmax - v0 * v0) / (2.0 * a);
    if 2.0 * ramp <= d {
        2.0 * (vmax - v0) / a + (d - 2.0 * ramp) / vmax
    } else {
        let peak = (v0 * v0 + a * d).sqrt();
        2.0 * (peak - v0) / a
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn duration_cases() {
        let p = StepProfile {
            v0_sps: 100.0,
            vmax_sps: 1100.0,
            accel_sps2: 1000.0,
        };
        // ramp 1 s each way covering 600 steps each; 800 steps cruise at 1100 steps/s
        assert_relative_eq!(trapezoid_duration_s(2000.0, p), 2.0 + 800.0 / 1100.0);
        // triangle: peak sqrt(100² + 1000·200) = 458.26
        assert_relative_eq!(
            trapezoid_duration_s(200.0, p),
            2.0 * ((100.0f64 * 100.0 + 1000.0 * 200.0).sqrt() - 100.0) / 1000.0
        );
        // 1000 steps lie between one ramp (600) and two (1200): a triangle, peak
        // sqrt(100² + 1000·1000) = 1004.99 steps/s, 1.81 s; not a cruise of negative length.
        assert_relative_eq!(
            trapezoid_duration_s(1000.0, p),
            2.0 * ((100.0f64 * 100.0 + 1000.0 * 1000.0).sqrt() - 100.0) / 1000.0
        );
        let flat = StepProfile {
            v0_sps: 500.0,
            vmax_sps: 500.0,
            accel_sps2: 1.0,
        };
        assert_relative_eq!(trapezoid_duration_s(-1000.0, flat), 2.0);
    }

    #[test]
    fn validation() {
        let d = Drive::default();
        let ok = Profile {
            accel_rps2: 1.0,
            start_rps: 0.1,
            max_rps: 1.0,
        };
        assert!(ok.validate(&d).is_ok());
        assert!(
            Profile {
                start_rps: 2.0,
                ..ok
            }
            .validate(&d)
            .is_err()
        );
        assert!(
            Profile {
                accel_rps2: f64::NAN,
                ..ok
            }
            .validate(&d)
            .is_err()
        );
        assert!(matches!(
            Profile { max_rps: 6.0, ..ok }.validate(&d),
            Err(Error::PulseRate { .. })
        ));
        // Each figure at, below and beyond its bounds: zero, negative and infinite acceleration
        // or top speed are refused by name; a start speed of 0 and one equal to the top are not.
        for bad in [0.0, -1.0, f64::INFINITY] {
            let a = Profile {
                accel_rps2: bad,
                ..ok
            };
            assert!(
                matches!(
                    a.validate(&d),
                    Err(Error::OutOfRange {
                        name: "accel_rps2",
                        ..
                    })
                ),
                "{bad}"
            );
            let m = Profile { max_rps: bad, ..ok };
            assert!(
                matches!(
                    m.validate(&d),
                    Err(Error::OutOfRange {
                        name: "max_rps",
                        ..
                    })
                ),
                "{bad}"
            );
        }
        for good in [0.0, 1.0] {
            assert!(
                Profile {
                    start_rps: good,
                    ..ok
                }
                .validate(&d)
                .is_ok()
            );
        }
        assert!(matches!(
            Profile {
                start_rps: -0.1,
                ..ok
            }
            .validate(&d),
            Err(Error::OutOfRange {
                name: "start_rps",
                ..
            })
        ));
    }
}
