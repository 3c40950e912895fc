//! Mandrel move timing: the indexer's trapezoid (seed 001 §5.3.2: "the stepper motor will start to
//! operate if the velocity has reached the start velocity, and stop operating when it reaches the
//! stop velocity"; §5.6.2: each mandrel instruction carries an acceleration, a start/stop velocity,
//! a maximum velocity and a step count).
//!
//! A move of `d` revolutions jumps to the start/stop velocity `v0`, ramps at `a` to `vmax` (or to
//! the peak `√(v0² + a·d)` when the move is too short), cruises, ramps back to `v0` and stops. The
//! robot's speed for a segment comes from the time of this move, not from `d / vmax`: a 37-step
//! segment of the thesis drive at 0.1 rev/s takes 0.225 s, not 0.200 s.

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
                expected: "must lie between 0 and the maximum velocity",
            });
        }
        Ok(())
    }

    /// The time of a move of `rev` revolutions (either sign), s; 0 for no move.
    pub fn duration_s(&self, rev: f64) -> f64 {
        let d = rev.abs();
        let (v0, vmax, a) = (self.start_stop_rps, self.max_rps, self.accel_rps2);
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
            2.0 * ((v0 * v0 + a * d).sqrt() - v0) / a
        }
    }

    /// The time at which a move of `total_rev` has covered `rev` (both taken as magnitudes,
    /// `rev ≤ total_rev`), s: the position–time curve of one continuous move.
    pub fn time_at_s(&self, rev: f64, total_rev: f64) -> f64 {
        let (d, s) = (total_rev.abs(), rev.abs().min(total_rev.abs()));
        let (v0, a) = (self.start_stop_rps, self.accel_rps2);
        if d == 0.0 {
            return 0.0;
        }
        if v0 >= self.max_rps {
            return s / self.max_rps;
        }
        // Peak velocity and the length of each ramp.
        let peak = self.max_rps.min((v0 * v0 + a * d).sqrt());
        let ramp = (peak * peak - v0 * v0) / (2.0 * a);
        // Time to cover x on the ramp from v0: x = v0 t + a t²/2.
        let on_ramp = |x: f64| ((v0 * v0 + 2.0 * a * x).sqrt() - v0) / a;
        if s <= ramp {
            on_ramp(s)
        } else if s <= d - ramp {
            on_ramp(ramp) + (s - ramp) / peak
        } else {
            self.duration_s(d) - on_ramp(d - s)
        }
    }

    /// The profile, with the same acceleration, whose move of `rev` takes `duration_s` (at least
    /// this profile's own time): the rule that slows a discrete segment's mandrel move to the
    /// robot's time. The cruise velocity solves `(vmax − v0)²/a + d = T·vmax` (the trapezoid's time
    /// `T = 2(vmax − v0)/a + (d − (vmax² − v0²)/a)/vmax`); when even `vmax = v0` is too fast, the
    /// move runs at the constant velocity `d / T` (start/stop and maximum velocity equal).
    pub fn slowed_to(&self, rev: f64, duration_s: f64) -> MandrelProfile {
        let d = rev.abs();
        if d == 0.0 || duration_s <= self.duration_s(d) {
            return *self;
        }
        let (v0, a, t) = (self.start_stop_rps, self.accel_rps2, duration_s);
        if d / t <= v0 {
            return MandrelProfile {
                start_stop_rps: d / t,
                max_rps: d / t,
                ..*self
            };
        }
        let b = 2.0 * v0 + a * t;
        let c = v0 * v0 + a * d;
        let vmax = (b - (b * b - 4.0 * c).max(0.0).sqrt()) / 2.0;
        MandrelProfile {
            max_rps: vmax.clamp(v0, self.max_rps),
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

    #[test]
    fn a_37_step_segment_takes_0_225_s() {
        // 37 steps of 1846.15 per revolution at 0.1 rev/s: 0.2004 s at constant speed. By hand:
        // ramps 0.05 → 0.1 rev/s at 1 rev/s² take 0.05 s and cover 0.00375 rev each; the cruise
        // covers 0.020042 − 0.0075 rev in 0.12542 s: 0.22542 s in all.
        let rev = 37.0 * 13.0 / (400.0 * 60.0);
        let t = thesis().duration_s(rev);
        assert_abs_diff_eq!(t, 0.1 + (rev - 0.0075) / 0.1, epsilon = 1e-12);
        assert!((t - 0.2254).abs() < 1e-4, "{t}");
    }

    #[test]
    fn time_at_runs_the_same_curve_to_the_end() {
        let p = thesis();
        for total in [0.002, 0.02, 1.0] {
            assert_abs_diff_eq!(
                p.time_at_s(total, total),
                p.duration_s(total),
                epsilon = 1e-12
            );
            assert_eq!(p.time_at_s(0.0, total), 0.0);
            // Strictly increasing, and symmetric: the last x takes as long as the first.
            let mut last = 0.0;
            for i in 1..=100 {
                let t = p.time_at_s(total * i as f64 / 100.0, total);
                assert!(t > last);
                last = t;
            }
            let x = total * 0.1;
            assert_abs_diff_eq!(
                p.time_at_s(x, total),
                p.duration_s(total) - p.time_at_s(total - x, total),
                epsilon = 1e-12
            );
        }
    }

    #[test]
    fn slowed_profile_takes_the_asked_time() {
        let p = thesis();
        for (rev, factor) in [
            (0.02, 1.3),
            (0.02, 3.0),
            (0.5, 1.01),
            (0.002, 50.0),
            (0.02, 0.5),
        ] {
            let own = p.duration_s(rev);
            let slowed = p.slowed_to(rev, own * factor);
            assert!(slowed.max_rps <= p.max_rps);
            assert_abs_diff_eq!(
                slowed.duration_s(rev),
                own * factor.max(1.0),
                epsilon = 1e-9
            );
            assert!(slowed.validate().is_ok());
        }
    }
}
