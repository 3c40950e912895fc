//! Physical units at the mandrel → motor steps, in one place (seed 001 §4.1.4–4.1.6).
//!
//! All conversions go through [`paths::Gearing`]: 400 half-steps per motor revolution and the
//! 13:60 timing belt give 400 · 60/13 ≈ 1846.15 steps per mandrel revolution (≈ 0.195° per step).

use paths::Gearing;

use crate::error::Result;

/// The translator's pulse-rate limit, SLO-SYN TM600U (seed 001 §4.1.5).
pub const TRANSLATOR_LIMIT_PPS: f64 = 10_000.0;

/// The drive train: motor, belt and translator.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Drive {
    /// Steps per motor revolution and belt teeth.
    pub gearing: Gearing,
    /// Highest pulse rate the translator accepts (steps/s).
    pub pulse_limit_pps: f64,
}

impl Default for Drive {
    /// The thesis drive: 400 steps/rev, 13:60, 10 000 pulses/s.
    fn default() -> Self {
        Drive {
            gearing: Gearing::default(),
            pulse_limit_pps: TRANSLATOR_LIMIT_PPS,
        }
    }
}

impl Drive {
    /// A drive after checking the gearing.
    pub fn new(gearing: Gearing, pulse_limit_pps: f64) -> Result<Self> {
        gearing.validate()?;
        Ok(Drive {
            gearing,
            pulse_limit_pps,
        })
    }

    /// Motor steps per mandrel revolution.
    pub fn steps_per_mandrel_rev(&self) -> f64 {
        self.gearing.steps_per_mandrel_rev()
    }

    /// Motor revolutions per mandrel revolution (60/13).
    pub fn motor_revs_per_mandrel_rev(&self) -> f64 {
        self.gearing.mandrel_teeth as f64 / self.gearing.motor_teeth as f64
    }

    /// A mandrel rate or acceleration (rev/s, rev/s²) in motor rev/s (rev/s²).
    pub fn motor_rps(&self, mandrel_rps: f64) -> f64 {
        mandrel_rps * self.motor_revs_per_mandrel_rev()
    }

    /// A motor rate (rev/s) back at the mandrel.
    pub fn mandrel_rps(&self, motor_rps: f64) -> f64 {
        motor_rps / self.motor_revs_per_mandrel_rev()
    }

    /// A mandrel rate (rev/s, or rev/s²) in motor steps per second (per second²).
    pub fn steps_per_s(&self, mandrel_rps: f64) -> f64 {
        mandrel_rps * self.steps_per_mandrel_rev()
    }

    /// A mandrel angle in degrees, rounded to whole motor steps.
    pub fn steps_from_deg(&self, mandrel_deg: f64) -> i64 {
        (mandrel_deg / 360.0 * self.steps_per_mandrel_rev()).round() as i64
    }

    /// Motor steps as a mandrel angle in degrees.
    pub fn deg_from_steps(&self, steps: f64) -> f64 {
        steps / self.steps_per_mandrel_rev() * 360.0
    }

    /// Motor steps per degree at the mandrel (GRBL `$103`).
    pub fn steps_per_deg(&self) -> f64 {
        self.steps_per_mandrel_rev() / 360.0
    }

    /// Refuses a mandrel rate whose pulse rate exceeds the translator limit.
    pub fn check_pulse_rate(&self, mandrel_rps: f64) -> Result<()> {
        let pps = self.steps_per_s(mandrel_rps).abs();
        if pps > self.pulse_limit_pps {
            return Err(crate::Error::PulseRate {
                requested_pps: pps,
                limit_pps: self.pulse_limit_pps,
            });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn full_turn_is_1846_steps() {
        let d = Drive::default();
        assert_eq!(d.steps_from_deg(360.0), 1846);
        assert_relative_eq!(d.deg_from_steps(1.0), 0.195, epsilon = 1e-3);
        assert_relative_eq!(d.motor_rps(1.0), 60.0 / 13.0, epsilon = 1e-12);
    }

    #[test]
    fn pulse_limit_named() {
        let d = Drive::default();
        assert!(d.check_pulse_rate(5.0).is_ok()); // 9231 pulses/s
        let e = d.check_pulse_rate(6.0).unwrap_err().to_string(); // 11 077 pulses/s
        assert!(e.contains("10000 pulses/s"), "{e}");
    }
}
