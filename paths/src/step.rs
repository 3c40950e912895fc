//! Mandrel step planning (seed 001 §4.1.4–4.1.5, §6.2.1 item 8).
//!
//! The thesis rounded each segment's step count and let the rounding error pile up. We round the
//! *cumulative* ideal angle instead and command the difference, which carries each segment's
//! remainder into the next: the commanded angle never drifts more than half a step from the ideal,
//! over any number of segments.

use std::f64::consts::TAU;

use crate::Error;

/// The drive train from motor steps to mandrel angle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gearing {
    /// Motor steps per motor revolution (400 in half-step mode, seed 001 §4.1.4).
    pub steps_per_motor_rev: u32,
    /// Teeth on the motor pulley (13, seed 001 §4.1.5).
    pub motor_teeth: u32,
    /// Teeth on the mandrel pulley (60).
    pub mandrel_teeth: u32,
}

impl Default for Gearing {
    /// The thesis drive: SLO-SYN M112 at 400 half-steps per revolution, 13:60 timing belt.
    fn default() -> Self {
        Gearing {
            steps_per_motor_rev: 400,
            motor_teeth: 13,
            mandrel_teeth: 60,
        }
    }
}

impl Gearing {
    /// Checks that every count is positive.
    pub fn validate(&self) -> Result<(), Error> {
        for (name, value) in [
            ("steps_per_rev", self.steps_per_motor_rev),
            ("motor_teeth", self.motor_teeth),
            ("mandrel_teeth", self.mandrel_teeth),
        ] {
            if value == 0 {
                return Err(Error::OutOfRange {
                    name,
                    value: 0.0,
                    expected: "must be > 0",
                });
            }
        }
        Ok(())
    }

    /// Motor steps per mandrel revolution (400 · 60/13 ≈ 1846.15 for the thesis drive).
    pub fn steps_per_mandrel_rev(&self) -> f64 {
        self.steps_per_motor_rev as f64 * self.mandrel_teeth as f64 / self.motor_teeth as f64
    }

    /// The mandrel angle of one motor step (≈ 0.195°).
    pub fn step_angle_rad(&self) -> f64 {
        TAU / self.steps_per_mandrel_rev()
    }

    /// A mandrel angle in (fractional) motor steps.
    pub fn steps(&self, mandrel_angle_rad: f64) -> f64 {
        mandrel_angle_rad / self.step_angle_rad()
    }
}

/// Per-segment step counts for a sequence of ideal cumulative mandrel angles.
#[derive(Debug, Clone, PartialEq)]
pub struct StepPlan {
    /// Steps commanded for each segment (signed: positive turns the mandrel counter-clockwise seen
    /// from above).
    pub steps: Vec<i64>,
    /// Worst |commanded − ideal| over the segment ends, in steps.
    pub max_drift_steps: f64,
}

impl StepPlan {
    /// The commanded cumulative step count at each segment end (0 at the start).
    pub fn cumulative(&self) -> Vec<i64> {
        self.steps
            .iter()
            .scan(0i64, |total, s| {
                *total += s;
                Some(*total)
            })
            .collect()
    }
}

fn drift(ideal_steps: &[f64], steps: &[i64]) -> f64 {
    let mut total = 0i64;
    let mut worst = 0.0f64;
    for (ideal, s) in ideal_steps.iter().zip(steps) {
        total += s;
        worst = worst.max((total as f64 - ideal).abs());
    }
    worst
}

/// The remainder-carrying rule, one segment at a time: round the cumulative ideal step count and
/// command the difference from the last commanded count.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RemainderCarrier {
    /// Commanded cumulative steps so far.
    pub commanded: i64,
}

impl RemainderCarrier {
    /// Steps for the segment ending at `ideal_steps` (cumulative, relative to the start).
    pub fn next(&mut self, ideal_steps: f64) -> i64 {
        let rounded = ideal_steps.round() as i64;
        let steps = rounded - self.commanded;
        self.commanded = rounded;
        steps
    }
}

/// Steps that carry each segment's remainder: round the cumulative ideal, command the difference.
/// `ideal_rad` holds the ideal cumulative rotation at each segment end, relative to the start.
pub fn carrying_remainder(ideal_rad: &[f64], gearing: &Gearing) -> StepPlan {
    let ideal: Vec<f64> = ideal_rad.iter().map(|&a| gearing.steps(a)).collect();
    let mut carrier = RemainderCarrier::default();
    let steps = ideal
        .iter()
        .map(|&cumulative| carrier.next(cumulative))
        .collect::<Vec<_>>();
    let max_drift_steps = drift(&ideal, &steps);
    StepPlan {
        steps,
        max_drift_steps,
    }
}

/// The thesis's plan: each segment's rotation rounded on its own (seed 001 §6.2.1 item 8). Kept to
/// show, and measure, the drift it accumulates.
pub fn rounding_each_segment(ideal_rad: &[f64], gearing: &Gearing) -> StepPlan {
    let ideal: Vec<f64> = ideal_rad.iter().map(|&a| gearing.steps(a)).collect();
    let mut previous = 0.0;
    let steps = ideal
        .iter()
        .map(|&cumulative| {
            let s = (cumulative - previous).round() as i64;
            previous = cumulative;
            s
        })
        .collect::<Vec<_>>();
    let max_drift_steps = drift(&ideal, &steps);
    StepPlan {
        steps,
        max_drift_steps,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The thesis's rounding, by hand: cumulative ideals of 0.6, 1.2 and 1.8 steps give three
    /// segments of 0.6 steps, each rounded up on its own to 1 (3 steps where 1.8 were meant), a
    /// drift of 1.2 steps at the end.
    #[test]
    fn rounding_each_segment_rounds_each_difference_on_its_own() {
        let g = Gearing::default();
        let ideal: Vec<f64> = [0.6, 1.2, 1.8]
            .iter()
            .map(|s| s * g.step_angle_rad())
            .collect();
        let naive = rounding_each_segment(&ideal, &g);
        assert_eq!(naive.steps, vec![1, 1, 1]);
        assert!(
            (naive.max_drift_steps - 1.2).abs() < 1e-9,
            "{}",
            naive.max_drift_steps
        );
    }

    #[test]
    fn thesis_drive_has_about_0_2_deg_per_step() {
        let g = Gearing::default();
        assert!((g.step_angle_rad().to_degrees() - 0.195).abs() < 1e-3);
        assert_eq!(g.steps(TAU).round() as i64, 1846);
    }

    #[test]
    fn remainder_carrying_stays_within_half_a_step_over_10000_segments() {
        let g = Gearing::default();
        // 10 000 segments of 0.7 step and a little more: each rounds to 1 on its own.
        let per_segment = 0.7123 * g.step_angle_rad();
        let ideal: Vec<f64> = (1..=10_000).map(|k| k as f64 * per_segment).collect();
        let carried = carrying_remainder(&ideal, &g);
        assert!(
            carried.max_drift_steps <= 0.5 + 1e-9,
            "{}",
            carried.max_drift_steps
        );
        let naive = rounding_each_segment(&ideal, &g);
        assert!(naive.max_drift_steps > 100.0, "{}", naive.max_drift_steps);
        assert_eq!(
            carried.cumulative().last(),
            Some(&((10_000.0f64 * 0.7123).round() as i64))
        );
    }

    #[test]
    fn signed_rotations_are_carried_too() {
        let g = Gearing::default();
        let ideal: Vec<f64> = (1..=1000).map(|k| -(k as f64) * 0.013).collect();
        let carried = carrying_remainder(&ideal, &g);
        assert!(carried.max_drift_steps <= 0.5 + 1e-9);
        assert!(carried.steps.iter().all(|&s| s <= 0));
    }

    #[test]
    fn zero_counts_are_rejected() {
        let g = Gearing {
            motor_teeth: 0,
            ..Gearing::default()
        };
        assert!(g.validate().is_err());
    }
}
