//! Pulse-by-pulse motion of the indexer's rate generator (seed 001 §5.3.2, docs/mandrel-drive.md).
//!
//! Each step is integrated exactly under constant acceleration: a step that takes the rate from
//! `v` to `v' = sqrt(v² ± 2a)` lasts `2 / (v + v')`. Deceleration to the stop velocity starts at the
//! first step boundary where the steps left are no more than `(v² − v0²) / 2a`. Cruise steps are
//! counted in closed form, so an hour of motion costs only its ramps.

use crate::profile::StepProfile;

/// One move or continuous run, in motor steps.
#[derive(Debug, Clone, PartialEq)]
pub struct Motion {
    profile: StepProfile,
    /// Target cruise rate (steps/s).
    target_sps: f64,
    /// Steps left in a preset move; `None` turns until stopped.
    remaining: Option<u64>,
    /// Step rate at the last step boundary (steps/s).
    v_sps: f64,
    /// Clock time of the last step boundary (s).
    t_s: f64,
    /// Ramping down to stop: once begun, it continues to the last step.
    braking: bool,
}

impl Motion {
    /// A preset move of `steps` steps starting at `now_s`: the rate jumps to the start velocity.
    pub fn preset(profile: StepProfile, steps: u64, now_s: f64) -> Self {
        Motion {
            profile,
            target_sps: profile.vmax_sps,
            remaining: Some(steps),
            v_sps: profile.v0_sps.min(profile.vmax_sps),
            t_s: now_s,
            braking: false,
        }
    }

    /// A continuous run at `profile.vmax_sps` starting at `now_s`.
    pub fn continuous(profile: StepProfile, now_s: f64) -> Self {
        Motion {
            remaining: None,
            ..Motion::preset(profile, 0, now_s)
        }
    }

    /// Changes the cruise rate of a running motion (MC: new `V`, then `G`).
    pub fn retarget(&mut self, vmax_sps: f64) {
        self.profile.vmax_sps = vmax_sps;
        self.target_sps = vmax_sps;
    }

    /// Decelerates to the stop velocity and stops (X-language `S`, GRBL feed hold / jog cancel).
    pub fn decelerate(&mut self) {
        let steps = self.stop_steps().ceil().max(1.0) as u64;
        self.remaining = Some(self.remaining.map_or(steps, |r| r.min(steps)));
    }

    /// True when a preset move has emitted all its steps.
    pub fn is_done(&self) -> bool {
        self.remaining == Some(0)
    }

    /// Step rate at the last step boundary (steps/s).
    pub fn rate_sps(&self) -> f64 {
        if self.is_done() { 0.0 } else { self.v_sps }
    }

    /// Clock time of the last emitted step (the completion time once done).
    pub fn last_step_s(&self) -> f64 {
        self.t_s
    }

    /// Clock time of a preset move's last step, computed ahead by running a copy of the motion
    /// to its end (its ramps and cruise in closed form, as [`Motion::advance`] does); `None` for
    /// a continuous run, or a move that would never end (a zero rate).
    pub fn end_s(&self) -> Option<f64> {
        self.remaining?;
        let mut ahead = self.clone();
        ahead.advance(f64::INFINITY);
        ahead.is_done().then_some(ahead.t_s)
    }

    /// True while the rate is changing (accelerating, slowing to a new target or braking).
    pub fn is_ramping(&self) -> bool {
        !self.is_done() && (self.braking || self.v_sps != self.target_sps || self.stop_steps_due())
    }

    /// True when a preset move has reached the steps where its braking ramp begins.
    fn stop_steps_due(&self) -> bool {
        self.remaining.is_some_and(|r| {
            (r as f64) <= self.stop_steps() + 1e-9 && self.v_sps > self.profile.v0_sps
        })
    }

    /// The rate the motion is heading for (steps/s): its cruise rate.
    pub fn target_sps(&self) -> f64 {
        self.target_sps
    }

    /// Steps needed to slow from the current rate to the stop velocity.
    fn stop_steps(&self) -> f64 {
        let (v, v0, a) = (self.v_sps, self.profile.v0_sps, self.profile.accel_sps2);
        ((v * v - v0 * v0) / (2.0 * a)).max(0.0)
    }

    /// Duration of the next step and the rate at its end.
    fn next_step(&self) -> (f64, f64) {
        let v = self.v_sps;
        let a = self.profile.accel_sps2;
        let v0 = self.profile.v0_sps;
        let stopping = self.braking
            || self
                .remaining
                .is_some_and(|r| (r as f64) <= self.stop_steps() + 1e-9 && v > v0);
        let (floor, accelerate) = if stopping {
            (v0, false)
        } else if v < self.target_sps {
            (self.target_sps, true)
        } else if v > self.target_sps {
            (self.target_sps.max(v0), false)
        } else {
            return (1.0 / v, v);
        };
        if accelerate {
            let v2 = v * v + 2.0 * a;
            if v2 <= floor * floor {
                let vn = v2.sqrt();
                (2.0 / (v + vn), vn)
            } else {
                let ramp = (floor * floor - v * v) / (2.0 * a);
                ((floor - v) / a + (1.0 - ramp) / floor, floor)
            }
        } else {
            let v2 = v * v - 2.0 * a;
            if v2 >= floor * floor {
                let vn = v2.sqrt();
                (2.0 / (v + vn), vn)
            } else if floor > 0.0 {
                let ramp = (v * v - floor * floor) / (2.0 * a);
                ((v - floor) / a + (1.0 - ramp) / floor, floor)
            } else {
                // Stopping to rest: the last step ends at (numerically about) zero rate.
                let vn = v2.max(0.0).sqrt();
                (2.0 / (v + vn), vn)
            }
        }
    }

    /// Skips whole ramp steps in closed form: under constant acceleration the step durations
    /// `2/(v + v')` telescope, so `n` steps from rate `v` end at `sqrt(v² ± 2an)` after
    /// `|v_n − v| / a`. Stops a step short of any boundary (target rate, start of braking, end of
    /// the move, `until_s`), which the step-by-step loop then handles. Returns the steps skipped.
    fn skip_ramp(&mut self, until_s: f64) -> u64 {
        let (v, a, v0) = (self.v_sps, self.profile.accel_sps2, self.profile.v0_sps);
        let dt = until_s - self.t_s;
        if !(a > 0.0 && dt > 0.0 && v.is_finite()) {
            return 0;
        }
        let stopping = self.braking
            || self
                .remaining
                .is_some_and(|r| (r as f64) <= self.stop_steps() + 1e-9 && v > v0);
        let n = if stopping || v > self.target_sps {
            let floor = if stopping {
                v0
            } else {
                self.target_sps.max(v0)
            };
            let by_floor = (v * v - floor * floor) / (2.0 * a);
            let v_t = v - a * dt;
            let by_time = if v_t <= floor {
                by_floor
            } else {
                (v * v - v_t * v_t) / (2.0 * a)
            };
            let mut n = by_time.min(by_floor).floor();
            if let Some(r) = self.remaining {
                n = n.min(r as f64);
            }
            n
        } else if v < self.target_sps {
            let target = self.target_sps;
            let v_t = v + a * dt;
            let mut n = ((target * target - v * v) / (2.0 * a))
                .min((v_t * v_t - v * v) / (2.0 * a))
                .floor();
            if let Some(r) = self.remaining {
                n = n.min(((r as f64 - self.stop_steps()) / 2.0).floor());
            }
            n
        } else {
            return 0;
        } - 1.0;
        if n.is_nan() || n < 2.0 {
            return 0;
        }
        let steps = n as u64;
        let decelerating = stopping || v > self.target_sps;
        let vn = if decelerating {
            (v * v - 2.0 * a * n).max(0.0).sqrt()
        } else {
            (v * v + 2.0 * a * n).sqrt()
        };
        self.t_s += (vn - v).abs() / a;
        self.v_sps = vn;
        if stopping {
            self.braking = true;
        }
        if let Some(r) = self.remaining.as_mut() {
            *r -= steps;
        }
        steps
    }

    /// Emits every step whose end lies at or before `until_s`; returns how many.
    pub fn advance(&mut self, until_s: f64) -> u64 {
        let mut emitted = 0u64;
        loop {
            if self.remaining == Some(0) {
                return emitted;
            }
            emitted += self.skip_ramp(until_s);
            // Cruise: count whole steps in closed form.
            if self.v_sps == self.target_sps && self.v_sps > 0.0 {
                let by_time = ((until_s - self.t_s) * self.v_sps).floor();
                let mut n = if by_time > 0.0 { by_time as u64 } else { 0 };
                if let Some(r) = self.remaining {
                    let s = self.stop_steps();
                    let before_decel = if (r as f64) > s {
                        r - s.floor() as u64
                    } else {
                        0
                    };
                    // Leave the boundary where deceleration starts to the step-by-step loop.
                    n = n.min(before_decel.saturating_sub(1));
                }
                if n > 1 {
                    let n = n - 1;
                    self.t_s += n as f64 / self.v_sps;
                    if let Some(r) = self.remaining.as_mut() {
                        *r -= n;
                    }
                    emitted += n;
                }
            }
            let (dt, vn) = self.next_step();
            if !dt.is_finite() || self.t_s + dt > until_s {
                return emitted;
            }
            if vn < self.v_sps && self.remaining.is_some() && vn < self.target_sps {
                self.braking = true;
            }
            self.t_s += dt;
            self.v_sps = vn;
            if let Some(r) = self.remaining.as_mut() {
                *r -= 1;
            }
            emitted += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::profile::trapezoid_duration_s;
    use approx::assert_abs_diff_eq;

    fn run_to_end(mut m: Motion) -> (u64, f64) {
        let mut steps = 0;
        let mut t = 0.0;
        while !m.is_done() {
            t += 0.01;
            steps += m.advance(t);
            assert!(t < 1e4);
        }
        (steps, m.last_step_s())
    }

    /// Each preset move's steps all arrive, its end computed ahead ([`Motion::end_s`]) is the
    /// end reached by advancing in 10 ms slices, and that is the analytic trapezoid's duration
    /// (seed 001 §4.1.5 ramp profile), within the tolerance given: 1 ms, or one step period at
    /// the start rate for the short moves, whose steps are coarse against the continuous ramp.
    #[test]
    fn matches_analytic_trapezoid() {
        for (d, v0, vmax, a, tolerance_s) in [
            (1846u64, 200.0, 2000.0, 4000.0, 1e-3),
            (1846, 0.0, 2000.0, 4000.0, 1e-3),
            (100, 300.0, 5000.0, 2000.0, 1e-3),
            (50_000, 400.0, 9000.0, 20_000.0, 1e-3),
            (7, 50.0, 60.0, 10.0, 1e-3),
            (37, 200.0, 2000.0, 4000.0, 1.0 / 200.0),
            (1, 100.0, 1000.0, 1000.0, 1.0 / 100.0),
        ] {
            let p = StepProfile {
                v0_sps: v0,
                vmax_sps: vmax,
                accel_sps2: a,
            };
            let m = Motion::preset(p, d, 0.0);
            let ahead = m.end_s().unwrap();
            let (steps, t) = run_to_end(m);
            assert_eq!(steps, d);
            assert_abs_diff_eq!(ahead, t, epsilon = 1e-9);
            assert_abs_diff_eq!(t, trapezoid_duration_s(d as f64, p), epsilon = tolerance_s);
        }
    }

    #[test]
    fn continuous_then_decelerate() {
        let p = StepProfile {
            v0_sps: 100.0,
            vmax_sps: 1000.0,
            accel_sps2: 1000.0,
        };
        let mut m = Motion::continuous(p, 0.0);
        let n = m.advance(10.0);
        // ramp 0.9 s covering 495 steps, then 9.1 s at 1000 steps/s
        assert!((n as f64 - (495.0 + 9100.0)).abs() <= 2.0, "{n}");
        m.decelerate();
        let n2 = m.advance(20.0);
        assert!(m.is_done());
        assert!((n2 as f64 - 495.0).abs() <= 2.0, "{n2}");
    }

    /// A continuous run has no end until it is told to stop; then its end is the braking ramp's.
    #[test]
    fn a_continuous_run_ends_where_it_brakes() {
        let p = StepProfile {
            v0_sps: 100.0,
            vmax_sps: 1000.0,
            accel_sps2: 1000.0,
        };
        let mut m = Motion::continuous(p, 0.0);
        assert_eq!(m.end_s(), None);
        assert!(m.is_ramping());
        m.advance(5.0);
        assert!(!m.is_ramping(), "cruising at the target rate");
        m.decelerate();
        assert!(m.is_ramping());
        // Braking from 1000 to 100 steps/s at 1000 steps/s²: 0.9 s.
        assert_abs_diff_eq!(m.end_s().unwrap(), 5.9, epsilon = 2e-3);
    }
}
