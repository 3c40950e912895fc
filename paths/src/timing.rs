//! Mandrel move timing: the indexer's trapezoid (seed 001 §5.3.2: "the stepper motor will start to
//! operate if the velocity has reached the start velocity, and stop operating when it reaches the
//! stop velocity"; §5.6.2: each mandrel instruction carries an acceleration, a start/stop velocity,
//! a maximum velocity and a step count).
//!
//! A move jumps to the start/stop velocity `v0`, ramps at `a` to `vmax` (or less when the move is
//! too short), cruises, ramps back toward `v0` and stops, deciding step by step as a step indexer
//! does ([`MandrelProfile::time_at_step_s`]; the same rule as the indexer simulator in
//! `mandrel-drive`). The robot's speed for a segment comes from the time of this move, not from
//! `d / vmax`: a 37-step segment of the thesis drive at 0.1 rev/s takes 0.221 s, not 0.200 s.

use crate::Error;

/// One mandrel move's velocity profile, at the mandrel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MandrelProfile {
    /// Acceleration and deceleration, rev/s².
    pub accel_rps2: f64,
    /// Start/stop velocity, rev/s (0 starts from rest).
    pub start_stop_rps: f64,
    /// Maximum (cruise) velocity, rev/s.
    pub max_rps: f64,
}

impl MandrelProfile {
    /// Checks the figures: acceleration and maximum velocity positive, `0 ≤ v0 ≤ vmax`.
    pub fn validate(&self) -> Result<(), Error> {
        for (name, value) in [
            ("accel_rps2", self.accel_rps2),
            ("mandrel_speed_rps", self.max_rps),
        ] {
            if !(value > 0.0 && value.is_finite()) {
                return Err(Error::OutOfRange {
                    name,
                    value,
                    expected: "must be > 0",
                });
            }
        }
        if !(self.start_stop_rps >= 0.0 && self.start_stop_rps <= self.max_rps) {
            return Err(Error::OutOfRange {
                name: "start_stop_rps",
                value: self.start_stop_rps,
                expected: "must lie between 0 and the mandrel speed (mandrel_speed_rps)",
            });
        }
        Ok(())
    }

    /// The time of a move of `steps` motor steps (`steps_per_rev` at the mandrel), s; 0 for no
    /// move. See [`MandrelProfile::time_at_step_s`].
    pub fn duration_s(&self, steps: u64, steps_per_rev: f64) -> f64 {
        self.time_at_step_s(steps, steps, steps_per_rev)
    }

    /// The time at which a move of `total` steps emits its step number `n` (`n ≤ total`), s: the
    /// position–time curve of one move, as a step indexer runs it. The rate jumps to `v0`, each
    /// step under acceleration `a` takes the rate from `v` to `√(v² ± 2a)` in `2/(v + v')`
    /// (so ramps take `Δv / a`), and the indexer decides to decelerate at the first step boundary
    /// where the steps left are no more than the braking distance `(v² − v0²)/2a`; it then brakes
    /// over exactly the steps left, ending a little above `v0`.
    pub fn time_at_step_s(&self, n: u64, total: u64, steps_per_rev: f64) -> f64 {
        let (n, d) = (n.min(total) as f64, total as f64);
        let v0 = self.start_stop_rps * steps_per_rev;
        let vmax = self.max_rps * steps_per_rev;
        let a = self.accel_rps2 * steps_per_rev;
        if n == 0.0 {
            return 0.0;
        }
        if v0 >= vmax {
            return n / vmax;
        }
        // Rate after x steps of acceleration from v0, and the time to get there.
        let up = |x: f64| (v0 * v0 + 2.0 * a * x).sqrt();
        let braking = (vmax * vmax - v0 * v0) / (2.0 * a);
        // First boundary k with d − k ≤ k (braking distance after k accelerating steps is k).
        let k_peak = (d / 2.0 - 1e-9).ceil();
        let (brake_at, v_brake, t_brake) = if k_peak <= braking {
            let v = up(k_peak);
            (k_peak, v, (v - v0) / a)
        } else {
            let p = (d - braking - 1e-9).ceil();
            (p, vmax, (vmax - v0) / a + (p - braking) / vmax)
        };
        if n <= brake_at {
            if n <= braking.min(brake_at) {
                (up(n) - v0) / a
            } else {
                (vmax - v0) / a + (n - braking) / vmax
            }
        } else {
            let v = (v_brake * v_brake - 2.0 * a * (n - brake_at))
                .max(0.0)
                .sqrt();
            t_brake + (v_brake - v) / a
        }
    }

    /// The profile, with the same acceleration, whose move of `steps` takes `duration_s` (at least
    /// this profile's own time): the rule that slows a discrete segment's mandrel move to the
    /// robot's time. The cruise velocity is lowered (bisection on the monotone step-exact time,
    /// to 1e-12 relative); when even `vmax = v0` is too fast, the move runs at the constant
    /// velocity that takes `duration_s` (start/stop and maximum velocity equal).
    pub fn slowed_to(&self, steps: u64, steps_per_rev: f64, duration_s: f64) -> MandrelProfile {
        if steps == 0 || duration_s <= self.duration_s(steps, steps_per_rev) {
            return *self;
        }
        let constant = steps as f64 / (duration_s * steps_per_rev);
        if constant <= self.start_stop_rps {
            return MandrelProfile {
                start_stop_rps: constant,
                max_rps: constant,
                ..*self
            };
        }
        let (mut lo, mut hi) = (self.start_stop_rps, self.max_rps);
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            let t = MandrelProfile {
                max_rps: mid,
                ..*self
            }
            .duration_s(steps, steps_per_rev);
            if t > duration_s {
                lo = mid;
            } else {
                hi = mid;
            }
            if hi - lo <= 1e-12 * hi {
                break;
            }
        }
        MandrelProfile {
            max_rps: lo,
            ..*self
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;

    fn thesis() -> MandrelProfile {
        MandrelProfile {
            accel_rps2: 1.0,
            start_stop_rps: 0.05,
            max_rps: 0.1,
        }
    }

    const STEPS_PER_REV: f64 = 400.0 * 60.0 / 13.0;

    #[test]
    fn a_37_step_segment_takes_0_221_s() {
        // 37 steps at 0.1 rev/s (184.6 steps/s), from 0.05 rev/s (92.3 steps/s) at 1 rev/s²
        // (1846.2 steps/s²), by hand: the braking distance is (184.6² − 92.3²)/(2·1846.2) = 6.92
        // steps; the ramp up takes 0.05 s; braking starts at step 31 (the first boundary with
        // ≤ 6.92 steps left) and brakes over 6 steps to √(184.6² − 2·1846.2·6) = 109.2 steps/s.
        let (v0, vmax, a) = (0.05 * STEPS_PER_REV, 0.1 * STEPS_PER_REV, STEPS_PER_REV);
        let braking = (vmax * vmax - v0 * v0) / (2.0 * a);
        let v_end = (vmax * vmax - 2.0 * a * 6.0).sqrt();
        let expected = 0.05 + (31.0 - braking) / vmax + (vmax - v_end) / a;
        let t = thesis().duration_s(37, STEPS_PER_REV);
        assert_abs_diff_eq!(t, expected, epsilon = 1e-12);
        assert!((t - 0.2213).abs() < 1e-4, "{t}");
        // The constant-speed figure, 37 / 184.6 = 0.2004 s, is 10 % short.
        assert!(t / (37.0 / vmax) > 1.10);
    }

    #[test]
    fn short_moves_brake_from_half_way() {
        // 5 steps never reach the cruise rate: accelerate 3 steps (the first boundary with no
        // more steps left than taken), brake over 2.
        let (v0, a) = (0.05 * STEPS_PER_REV, STEPS_PER_REV);
        let v3 = (v0 * v0 + 6.0 * a).sqrt();
        let v5 = (v3 * v3 - 4.0 * a).sqrt();
        let expected = (v3 - v0) / a + (v3 - v5) / a;
        assert_abs_diff_eq!(
            thesis().duration_s(5, STEPS_PER_REV),
            expected,
            epsilon = 1e-12
        );
        assert_eq!(thesis().duration_s(0, STEPS_PER_REV), 0.0);
    }

    #[test]
    fn time_at_runs_the_same_curve_to_the_end() {
        let p = thesis();
        for total in [3u64, 37, 1849, 100_000] {
            assert_eq!(p.time_at_step_s(0, total, STEPS_PER_REV), 0.0);
            let mut last = 0.0;
            for n in 1..=total.min(2000) {
                let t = p.time_at_step_s(n, total, STEPS_PER_REV);
                assert!(t > last, "{total} {n}");
                last = t;
            }
        }
    }

    #[test]
    fn slowed_profile_takes_the_asked_time() {
        let p = thesis();
        for (steps, factor) in [(37u64, 1.3), (37, 3.0), (900, 1.01), (4, 50.0), (37, 0.5)] {
            let own = p.duration_s(steps, STEPS_PER_REV);
            let slowed = p.slowed_to(steps, STEPS_PER_REV, own * factor);
            assert!(slowed.max_rps <= p.max_rps);
            assert_abs_diff_eq!(
                slowed.duration_s(steps, STEPS_PER_REV),
                own * factor.max(1.0),
                epsilon = 1e-9
            );
            assert!(slowed.validate().is_ok());
        }
    }
}
