//! The simulated drive: indexer card, translator, motor and belt (seed 001 §4.1.4–4.1.8).
//!
//! The indexer holds the profile, mode, direction and distance, and emits pulses through
//! [`Motion`]. The translator passes at most its pulse limit (seed 001 §4.1.5: "capable of
//! producing up to 10,000 pulses per second"); above it pulses are **lost silently**, as on a real
//! translator: the indexer counts every commanded step, the motor turns only the fraction the
//! translator passed, and nothing on the serial line says so ([`Machine::lost_steps`] is the
//! simulator's truth for tests and prediction). The motor follows the pulses unless the start
//! velocity exceeds its pull-in rate, or the ramp asks for more torque than the motor has at the
//! rate it has reached ([`Motor`], the pull-out torque): then it stalls, the indexer still counts
//! steps, the mandrel stops turning, and the move is reported as failed. A stop (`S`) ramps the
//! rate down at the profile's deceleration; a kill (`K`) stops the pulses at once. The belt turns
//! motor steps into the mandrel angle.

use std::f64::consts::TAU;

use crate::profile::StepProfile;
use crate::sim::motion::Motion;
use crate::sim::motor::Motor;
use crate::units::Drive;

/// Default pull-in rate of the motor (steps/s) above which a start from rest stalls.
///
/// Our figure for the SLO-SYN M112 in half-step mode at the mandrel's inertia; the thesis only
/// says that too high a start velocity stalls the motor (§5.3.2). Configurable per simulator.
pub const PULL_IN_SPS: f64 = 1_000.0;

/// Reasons the simulated hardware refuses to start a motion.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum Refusal {
    /// The step rate exceeds the translator's pulse limit.
    PulseRate {
        /// Requested steps/s.
        requested_pps: f64,
        /// The limit.
        limit_pps: f64,
    },
    /// The controller is still resetting.
    Busy,
}

impl std::fmt::Display for Refusal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Refusal::PulseRate {
                requested_pps,
                limit_pps,
            } => write!(
                f,
                "{requested_pps:.0} pulses/s exceeds the translator limit of {limit_pps:.0} pulses/s"
            ),
            Refusal::Busy => write!(f, "busy resetting"),
        }
    }
}

/// The simulated indexer + translator + motor + gear.
#[derive(Debug, Clone)]
pub struct Machine {
    /// Gearing and pulse limit.
    pub drive: Drive,
    /// Motor pull-in rate (steps/s).
    pub pull_in_sps: f64,
    /// The motor's pull-out torque curve and its load.
    pub motor: Motor,
    /// The current profile in steps.
    pub profile: StepProfile,
    /// Busy after a reset until this clock time (s).
    pub reset_until_s: f64,
    /// Indexer position counter (steps, absolute since reset or `PZ`).
    counter_steps: i64,
    /// Counter at the start of the last move (for `W3`).
    move_start_steps: i64,
    /// Motor position (steps); differs from the counter after a stall.
    motor_steps: i64,
    motion: Option<(Motion, i64)>,
    stalled: bool,
    /// Commanded steps of the current motion the motor still follows before the ramp outruns
    /// its pull-out torque (`None`: it follows them all).
    follow_steps: Option<u64>,
    /// Fraction of a step the translator has passed but the motor not yet taken (lost pulses).
    passed_frac: f64,
    lost_steps: u64,
    now_s: f64,
    completed_s: Option<f64>,
    /// Clock time of the current preset move's last step, computed when the motion starts or
    /// changes ([`Machine::next_event_s`]). Kept rather than derived at each call: the simulated
    /// cell asks at every poll, and recomputing it there cost a fifth of a discrete batch's CPU
    /// (13.8 against 17.1 ms).
    predicted_end_s: Option<f64>,
}

impl Machine {
    /// A machine at rest at 0 with a gentle default profile.
    pub fn new(drive: Drive, pull_in_sps: f64) -> Self {
        Machine {
            drive,
            pull_in_sps,
            motor: Motor::thesis(
                drive.gearing.steps_per_motor_rev as f64,
                drive.motor_revs_per_mandrel_rev(),
            ),
            profile: StepProfile {
                v0_sps: 0.0,
                vmax_sps: drive.gearing.steps_per_motor_rev as f64,
                accel_sps2: 100.0 * drive.gearing.steps_per_motor_rev as f64,
            },
            reset_until_s: 0.0,
            counter_steps: 0,
            move_start_steps: 0,
            motor_steps: 0,
            motion: None,
            stalled: false,
            follow_steps: None,
            passed_frac: 0.0,
            lost_steps: 0,
            now_s: 0.0,
            completed_s: None,
            predicted_end_s: None,
        }
    }

    /// Runs the motion up to clock time `t_s`.
    pub fn advance(&mut self, t_s: f64) {
        if t_s <= self.now_s {
            return;
        }
        self.now_s = t_s;
        if let Some((m, dir)) = self.motion.as_mut() {
            let t_prev = m.last_step_s();
            let pulses = m.advance(t_s);
            let n = (pulses as i64).saturating_mul(*dir);
            self.counter_steps = self.counter_steps.saturating_add(n);
            // Above the translator's limit only `limit / rate` of the pulses reach the motor; the
            // rate is the mean over this interval's pulses (exact when the clock is sampled finer
            // than the ramps).
            let span = m.last_step_s() - t_prev;
            let rate = if pulses > 0 && span > 0.0 {
                pulses as f64 / span
            } else {
                m.rate_sps()
            };
            let limit = self.drive.pulse_limit_pps;
            let passed = if rate > limit * (1.0 + 1e-6) {
                self.passed_frac += pulses as f64 * limit / rate;
                let whole = self.passed_frac.floor();
                self.passed_frac -= whole;
                self.lost_steps += pulses - (whole as u64).min(pulses);
                whole as i64
            } else {
                pulses as i64
            };
            let mut taken = passed;
            if let Some(left) = self.follow_steps.as_mut() {
                let n = passed.unsigned_abs();
                if n > *left {
                    // The rate has passed the pull-out curve: the rotor falls out of step after
                    // the steps it could still follow.
                    taken = *left as i64;
                    *left = 0;
                    if !self.stalled {
                        self.motor_steps = self.motor_steps.saturating_add(taken * *dir);
                    }
                    self.stalled = true;
                } else {
                    *left -= n;
                }
            }
            if !self.stalled {
                self.motor_steps = self.motor_steps.saturating_add(taken.saturating_mul(*dir));
            }
            if m.is_done() {
                self.completed_s = Some(m.last_step_s());
                self.motion = None;
                self.predicted_end_s = None;
            }
        }
    }

    /// When the drive next needs [`Machine::advance`] for its timing to be exact (clock time,
    /// s): the end of a reset; the last step of a preset move (the card's completion, which
    /// releases its buffered commands); and, while a ramp runs towards a rate above the
    /// translator's pulse limit, `sample_s` after the drive's clock, since the share of pulses
    /// the translator passes is taken from each advance's mean rate. `None` when nothing is due
    /// (at rest, or cruising without end): the drive then gives the same result however seldom
    /// it is advanced.
    pub fn next_event_s(&self, sample_s: f64) -> Option<f64> {
        let mut due: Option<f64> = None;
        let mut at = |t: f64| due = Some(due.map_or(t, |d: f64| d.min(t)));
        if self.now_s < self.reset_until_s {
            at(self.reset_until_s);
        }
        if let Some((m, _)) = &self.motion {
            if let Some(end) = self.predicted_end_s {
                at(end);
            }
            let limit = self.drive.pulse_limit_pps;
            if m.is_ramping() && m.target_sps().max(m.rate_sps()) > limit {
                at(self.now_s + sample_s);
            }
        }
        due
    }

    /// Recomputes the end of the current preset move after its motion changed.
    fn predict_end(&mut self) {
        self.predicted_end_s = self.motion.as_ref().and_then(|(m, _)| m.end_s());
    }

    /// Commanded steps from rate `from_sps` before a ramp at the profile's acceleration towards
    /// `peak_sps` outruns the motor's pull-out torque; `None` if the motor keeps up all the way.
    /// The motor sees at most the translator's pulse limit.
    fn steps_before_pull_out(&self, from_sps: f64, peak_sps: f64) -> Option<u64> {
        let a = self.profile.accel_sps2;
        let limit = self.motor.pull_out_sps(a);
        if peak_sps.min(self.drive.pulse_limit_pps) <= limit || a.is_nan() || a <= 0.0 {
            return None;
        }
        Some(((limit * limit - from_sps * from_sps).max(0.0) / (2.0 * a)).floor() as u64)
    }

    fn check(&self, _rate_sps: f64) -> Result<(), Refusal> {
        if self.now_s < self.reset_until_s {
            return Err(Refusal::Busy);
        }
        // A rate above the translator's limit is not refused: the pulses beyond it are lost.
        Ok(())
    }

    /// Commanded steps the translator dropped because they came faster than its pulse limit (the
    /// simulator's truth; no dialect reports it).
    pub fn lost_steps(&self) -> u64 {
        self.lost_steps
    }

    /// Clock time of the last step of the last finished preset move (its completion).
    pub fn completed_s(&self) -> Option<f64> {
        self.completed_s
    }

    /// Starts a preset move of `steps` (signed) at the current clock time.
    pub fn start_preset(&mut self, steps: i64) -> Result<(), Refusal> {
        self.check(self.profile.vmax_sps.max(self.profile.v0_sps))?;
        self.completed_s = None;
        self.move_start_steps = self.counter_steps;
        self.stalled = self.profile.v0_sps > self.pull_in_sps;
        let (v0, a) = (self.profile.v0_sps, self.profile.accel_sps2);
        let peak = (v0 * v0 + a * steps.unsigned_abs() as f64)
            .sqrt()
            .min(self.profile.vmax_sps.max(v0));
        self.follow_steps = self.steps_before_pull_out(v0.min(self.profile.vmax_sps), peak);
        if steps != 0 {
            let m = Motion::preset(self.profile, steps.unsigned_abs(), self.now_s);
            self.motion = Some((m, steps.signum()));
        }
        self.predict_end();
        Ok(())
    }

    /// Starts (or re-speeds) a continuous run in direction `dir` (±1).
    pub fn start_continuous(&mut self, dir: i64) -> Result<(), Refusal> {
        self.check(self.profile.vmax_sps)?;
        if let Some((m, d)) = self.motion.as_mut()
            && *d == dir
        {
            m.retarget(self.profile.vmax_sps);
            let v = m.rate_sps();
            if self.profile.vmax_sps > v {
                self.follow_steps = self.steps_before_pull_out(v, self.profile.vmax_sps);
            }
            self.predict_end();
            return Ok(());
        }
        self.move_start_steps = self.counter_steps;
        self.stalled = self.profile.v0_sps > self.pull_in_sps;
        self.follow_steps = self.steps_before_pull_out(
            self.profile.v0_sps.min(self.profile.vmax_sps),
            self.profile.vmax_sps,
        );
        if self.profile.vmax_sps > 0.0 {
            let m = Motion::continuous(self.profile, self.now_s);
            self.motion = Some((m, dir.signum()));
        } else {
            self.motion = None;
        }
        self.predict_end();
        Ok(())
    }

    /// Decelerates to the stop velocity and stops.
    pub fn stop(&mut self) {
        if let Some((m, _)) = self.motion.as_mut() {
            m.decelerate();
        }
        self.predict_end();
    }

    /// Stops at once (no deceleration).
    pub fn kill(&mut self) {
        self.motion = None;
        self.predicted_end_s = None;
    }

    /// Power-up reset: stops, zeroes the counters, clears the stall, busy for `busy_s`.
    pub fn reset(&mut self, busy_s: f64) {
        self.motion = None;
        self.predicted_end_s = None;
        self.counter_steps = 0;
        self.move_start_steps = 0;
        self.motor_steps = 0;
        self.stalled = false;
        self.follow_steps = None;
        self.reset_until_s = self.now_s + busy_s;
    }

    /// Zeroes the absolute position counter (`PZ`).
    pub fn zero(&mut self) {
        self.counter_steps = 0;
        self.motor_steps = 0;
        self.move_start_steps = 0;
    }

    /// True while pulses are being emitted or a reset is under way.
    pub fn is_busy(&self) -> bool {
        self.motion.is_some() || self.now_s < self.reset_until_s
    }

    /// True while pulses are being emitted.
    pub fn is_moving(&self) -> bool {
        self.motion.is_some()
    }

    /// True when the last motion stalled the motor.
    pub fn is_stalled(&self) -> bool {
        self.stalled
    }

    /// The indexer's absolute step counter.
    pub fn counter_steps(&self) -> i64 {
        self.counter_steps
    }

    /// Steps since the start of the last move (`W3`).
    pub fn steps_since_move_start(&self) -> i64 {
        self.counter_steps.saturating_sub(self.move_start_steps)
    }

    /// Motor steps actually turned (the mandrel position in steps).
    pub fn motor_steps(&self) -> i64 {
        self.motor_steps
    }

    /// Current step rate (steps/s, unsigned).
    pub fn rate_sps(&self) -> f64 {
        self.motion.as_ref().map_or(0.0, |(m, _)| m.rate_sps())
    }

    /// Direction of the current motion (±1, 0 at rest).
    pub fn direction(&self) -> i64 {
        self.motion.as_ref().map_or(0, |(_, d)| *d)
    }

    /// Clock time of the last emitted step of the current or last motion.
    pub fn now_s(&self) -> f64 {
        self.now_s
    }

    /// The mandrel angle (rad) from the motor position through the belt.
    pub fn mandrel_angle_rad(&self) -> f64 {
        self.motor_steps as f64 / self.drive.steps_per_mandrel_rev() * TAU
    }

    /// The mandrel angle (rad) the indexer's step counter commands: the true angle
    /// ([`Machine::mandrel_angle_rad`]) and this part when the translator loses steps or the
    /// motor stalls (seed 001 §6.2.1).
    pub fn commanded_angle_rad(&self) -> f64 {
        self.counter_steps as f64 / self.drive.steps_per_mandrel_rev() * TAU
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::profile::{Profile, trapezoid_duration_s};
    use approx::assert_abs_diff_eq;

    /// A machine for tests of the translator: a motor strong enough for any ramp, from rest to
    /// `vmax_sps` at `accel_sps2`.
    fn strong_motor(vmax_sps: f64, accel_sps2: f64) -> Machine {
        let mut m = Machine::new(Drive::default(), PULL_IN_SPS);
        m.motor.holding_nm = 1.0e9;
        m.profile = StepProfile {
            v0_sps: 0.0,
            vmax_sps,
            accel_sps2,
        };
        m
    }

    fn run(m: &mut Machine) {
        let mut t = m.now_s();
        while m.is_moving() {
            t += 0.001;
            m.advance(t);
        }
    }

    #[test]
    fn full_mandrel_turn_at_thesis_gearing() {
        let drive = Drive::default();
        let mut m = Machine::new(drive, PULL_IN_SPS);
        let p = Profile {
            accel_rps2: 2.0,
            start_rps: 0.2,
            max_rps: 1.0,
        };
        m.profile = p.in_steps(&drive);
        let steps = drive.steps_from_deg(360.0);
        assert_eq!(steps, 1846);
        m.advance(0.5);
        m.start_preset(steps).unwrap();
        assert!(m.is_busy());
        run(&mut m);
        assert_eq!(m.counter_steps(), 1846);
        assert_eq!(m.motor_steps(), 1846);
        let took = m.completed_s().unwrap() - 0.5;
        assert_abs_diff_eq!(
            took,
            trapezoid_duration_s(1846.0, m.profile),
            epsilon = 1e-3
        );
        assert_abs_diff_eq!(
            m.mandrel_angle_rad(),
            1846.0 / drive.steps_per_mandrel_rev() * TAU
        );
    }

    /// Above 10 000 pulses/s (seed 001 §4.1.5) the translator passes 10 000 of every rate's
    /// pulses per second: at a steady 12 500 pulses/s the motor takes 4 of every 5 commanded
    /// steps, while the indexer counts them all.
    #[test]
    fn over_the_pulse_limit_steps_are_lost_silently() {
        // The translator is the subject here: a motor strong enough for the instant ramp.
        let mut m = strong_motor(12_500.0, 1.0e9);
        m.start_preset(125_000).unwrap();
        run(&mut m);
        assert_eq!(m.counter_steps(), 125_000);
        let lost = m.lost_steps() as f64;
        assert!((lost - 25_000.0).abs() < 10.0, "{lost}");
        assert_eq!(m.motor_steps() + m.lost_steps() as i64, 125_000);
        assert!(!m.is_stalled());
        // At the limit nothing is lost.
        let mut m = strong_motor(10_000.0, 1.0e9);
        m.start_preset(20_000).unwrap();
        run(&mut m);
        assert_eq!(m.lost_steps(), 0);
        assert_eq!(m.motor_steps(), 20_000);
    }

    #[test]
    fn start_above_pull_in_stalls() {
        let mut m = Machine::new(Drive::default(), PULL_IN_SPS);
        m.profile = StepProfile {
            v0_sps: 1500.0,
            vmax_sps: 3000.0,
            accel_sps2: 5000.0,
        };
        m.start_preset(1000).unwrap();
        run(&mut m);
        assert!(m.is_stalled());
        assert_eq!(m.counter_steps(), 1000);
        assert_eq!(m.motor_steps(), 0);
    }

    /// The rate where the seed's 840 oz-in, flat to the corner and falling as corner/rate,
    /// meets the load's `J·α + T_f`, from the figures in `sim::motor` (not from `Motor`).
    fn pull_out_rate(accel_sps2: f64) -> f64 {
        use crate::sim::motor::{
            CORNER_SPS, FRICTION_NM, MANDREL_INERTIA_KG_M2, ROTOR_INERTIA_KG_M2,
        };
        let j = ROTOR_INERTIA_KG_M2 + MANDREL_INERTIA_KG_M2 * (13.0f64 / 60.0).powi(2);
        let need = j * accel_sps2 * TAU / 400.0 + FRICTION_NM;
        840.0 * 0.007_061_552 * CORNER_SPS / need
    }

    /// A ramp too steep for the motor at the rate it reaches stalls where the pull-out curve
    /// meets the load; the same move with a gentler ramp runs to the end.
    #[test]
    fn a_steep_ramp_stalls_where_pull_out_torque_runs_out() {
        let steep = StepProfile {
            v0_sps: 0.0,
            vmax_sps: 6_000.0,
            accel_sps2: 40_000.0,
        };
        let f = pull_out_rate(steep.accel_sps2);
        assert!(f > 1_000.0 && f < 6_000.0, "{f}");
        let mut m = Machine::new(Drive::default(), PULL_IN_SPS);
        m.profile = steep;
        m.start_preset(20_000).unwrap();
        run(&mut m);
        assert!(m.is_stalled());
        assert_eq!(m.counter_steps(), 20_000);
        // From rest to f at a: f²/2a steps.
        let want = (f * f / (2.0 * steep.accel_sps2)).floor() as i64;
        assert!(
            (m.motor_steps() - want).abs() <= 1,
            "{} {want}",
            m.motor_steps()
        );

        let gentle = StepProfile {
            accel_sps2: 4_000.0,
            ..steep
        };
        assert!(pull_out_rate(gentle.accel_sps2) > 6_000.0);
        let mut m = Machine::new(Drive::default(), PULL_IN_SPS);
        m.profile = gentle;
        m.start_preset(20_000).unwrap();
        run(&mut m);
        assert!(!m.is_stalled());
        assert_eq!(m.motor_steps(), 20_000);
    }

    /// At a given ramp the speed decides: 9000 steps/s asks for more than the motor has there,
    /// 6000 does not. A continuous run, backwards, stalls the same way.
    #[test]
    fn a_speed_beyond_the_pull_out_rate_stalls() {
        let a = 8_000.0;
        let f = pull_out_rate(a);
        assert!(f > 6_000.0 && f < 9_000.0, "{f}");
        for (vmax, stalls) in [(9_000.0, true), (6_000.0, false)] {
            let mut m = Machine::new(Drive::default(), PULL_IN_SPS);
            m.profile = StepProfile {
                v0_sps: 0.0,
                vmax_sps: vmax,
                accel_sps2: a,
            };
            m.start_continuous(-1).unwrap();
            m.advance(3.0);
            assert_eq!(m.is_stalled(), stalls, "{vmax}");
            if stalls {
                let want = -((f * f / (2.0 * a)).floor() as i64);
                assert!((m.motor_steps() - want).abs() <= 1, "{}", m.motor_steps());
            } else {
                assert_eq!(m.motor_steps(), m.counter_steps());
            }
        }
        // Speeding a running motion up past the curve (a new V, then G) stalls it too.
        let mut m = Machine::new(Drive::default(), PULL_IN_SPS);
        m.profile = StepProfile {
            v0_sps: 0.0,
            vmax_sps: 6_000.0,
            accel_sps2: a,
        };
        m.start_continuous(1).unwrap();
        m.advance(2.0);
        assert!(!m.is_stalled());
        let at = m.counter_steps() as f64;
        m.profile.vmax_sps = 9_000.0;
        m.start_continuous(1).unwrap();
        m.advance(4.0);
        assert!(m.is_stalled());
        let want = at + (f * f - 6_000.0f64.powi(2)) / (2.0 * a);
        assert!(
            (m.motor_steps() as f64 - want).abs() <= 2.0,
            "{}",
            m.motor_steps()
        );
    }

    /// `S` ramps the rate down at the profile's deceleration: (v² − v0²)/2a more steps over
    /// (v − v0)/a; `K` stops the pulses at once.
    #[test]
    fn stop_decelerates_and_kill_stops_dead() {
        let p = StepProfile {
            v0_sps: 100.0,
            vmax_sps: 3_000.0,
            accel_sps2: 6_000.0,
        };
        let mut m = Machine::new(Drive::default(), PULL_IN_SPS);
        m.profile = p;
        m.start_continuous(1).unwrap();
        m.advance(1.0);
        assert!((m.rate_sps() - 3_000.0).abs() < 1e-6);
        let at = m.counter_steps();
        m.stop();
        run(&mut m);
        let more = (m.counter_steps() - at) as f64;
        let want = (3_000.0f64.powi(2) - 100.0f64.powi(2)) / (2.0 * 6_000.0);
        assert!((more - want).abs() <= 2.0, "{more} {want}");
        assert!((m.now_s() - 1.0 - (3_000.0 - 100.0) / 6_000.0).abs() < 0.01);
        assert!(!m.is_stalled());

        let mut m = Machine::new(Drive::default(), PULL_IN_SPS);
        m.profile = p;
        m.start_continuous(1).unwrap();
        m.advance(1.0);
        let at = m.counter_steps();
        m.kill();
        assert!(!m.is_moving());
        m.advance(2.0);
        assert_eq!(m.counter_steps(), at);
    }

    #[test]
    fn reset_is_busy_then_zeroed() {
        let mut m = Machine::new(Drive::default(), PULL_IN_SPS);
        m.start_preset(500).unwrap();
        m.advance(0.2);
        m.reset(1.0);
        assert!(m.is_busy() && !m.is_moving());
        assert_eq!(m.counter_steps(), 0);
        assert!(m.start_preset(10).is_err());
        m.advance(1.3);
        assert!(!m.is_busy());
        m.start_preset(10).unwrap();
    }

    /// Advanced only at the times it names, the drive completes its moves at the instants it
    /// completes them when advanced every millisecond: the event-driven simulated cell relies
    /// on this.
    #[test]
    fn next_event_is_the_completion() {
        let p = StepProfile {
            v0_sps: 200.0,
            vmax_sps: 2_000.0,
            accel_sps2: 4_000.0,
        };
        let mut polled = Machine::new(Drive::default(), PULL_IN_SPS);
        polled.profile = p;
        let mut evented = polled.clone();
        assert_eq!(evented.next_event_s(1e-3), None, "at rest");
        for m in [&mut polled, &mut evented] {
            m.advance(0.25);
            m.start_preset(-1846).unwrap();
        }
        run(&mut polled);
        let mut events = 0;
        while let Some(t) = evented.next_event_s(1e-3) {
            assert!(t > evented.now_s());
            evented.advance(t);
            events += 1;
            assert!(events < 10);
        }
        assert_eq!(events, 1, "one event: the last step");
        assert!(!evented.is_moving());
        assert_abs_diff_eq!(
            evented.completed_s().unwrap(),
            polled.completed_s().unwrap(),
            epsilon = 1e-9
        );
        assert_eq!(evented.counter_steps(), polled.counter_steps());
        assert_eq!(evented.counter_steps(), -1846);
        // A reset is due at its end.
        evented.reset(0.5);
        let due = evented.next_event_s(1e-3).unwrap();
        assert_abs_diff_eq!(due, evented.now_s() + 0.5, epsilon = 1e-12);
        evented.advance(due);
        assert!(!evented.is_busy());
        assert_eq!(evented.next_event_s(1e-3), None);
        // A stop during a continuous run brings the braking ramp's end forward.
        evented.start_continuous(1).unwrap();
        assert_eq!(
            evented.next_event_s(1e-3),
            None,
            "no end, under the pulse limit"
        );
        evented.advance(due + 2.0);
        evented.stop();
        let end = evented.next_event_s(1e-3).unwrap();
        assert_abs_diff_eq!(end, due + 2.0 + (2_000.0 - 200.0) / 4_000.0, epsilon = 2e-3);
        evented.advance(end);
        assert!(!evented.is_moving());
    }

    /// Towards a rate the translator cannot pass, the drive asks to be sampled finely while it
    /// ramps (the share of pulses passed follows the mean rate of each advance), and not once it
    /// cruises.
    #[test]
    fn ramping_past_the_pulse_limit_is_sampled() {
        let mut m = Machine::new(Drive::default(), PULL_IN_SPS);
        m.profile = StepProfile {
            v0_sps: 200.0,
            vmax_sps: 12_500.0,
            accel_sps2: 50_000.0,
        };
        m.start_continuous(1).unwrap();
        assert_abs_diff_eq!(m.next_event_s(1e-3).unwrap(), 1e-3, epsilon = 1e-12);
        m.advance(1.0);
        assert_eq!(m.next_event_s(1e-3), None);
        // A long preset move cruising above the limit is not sampled until its braking ramp:
        // its next event is its end.
        m.kill();
        m.start_preset(200_000).unwrap();
        m.advance(2.0);
        let end = m.next_event_s(1e-3).unwrap();
        assert!(end > 10.0, "{end}");
    }

    /// Over any stretch wholly above the pulse limit the translator passes exactly `limit`
    /// pulses a second, however the rate changes within it, so the lost steps are
    /// `pulses − limit · span` whatever the sampling. A ramp at 20 000 steps/s² from rest to
    /// 12 500 steps/s, advanced in 50 ms ticks: from the limit (0.5 s) to the end of the ramp
    /// (0.625 s) the closed form is ∫(f − L) df / a = (12 500 − 10 000)² / (2 · 20 000) =
    /// 156.25 steps; each tick's end rate would count 205. Just above the limit, 10 000.5
    /// steps/s for 10 s, 5 of the 100 005 pulses are lost.
    #[test]
    fn the_translator_passes_its_limit_over_a_ramp_sampled_coarsely() {
        let mut m = strong_motor(12_500.0, 20_000.0);
        m.start_continuous(1).unwrap();
        for k in 1..=10 {
            m.advance(0.05 * f64::from(k));
        }
        assert_eq!(m.lost_steps(), 0, "below the limit until 0.5 s");
        for t in [0.55, 0.6, 0.625] {
            m.advance(t);
        }
        let lost = m.lost_steps() as f64;
        assert!((lost - 156.25).abs() <= 2.0, "{lost}");

        let mut m = strong_motor(10_000.5, 1.0e9);
        m.start_continuous(1).unwrap();
        for k in 1..=100 {
            m.advance(0.1 * f64::from(k));
        }
        let lost = m.lost_steps();
        assert!((4..=6).contains(&lost), "{lost} of {}", m.counter_steps());
    }

    /// What the simulated indexer says when it refuses a command.
    #[test]
    fn refusals_read_as_the_operator_sees_them() {
        let rate = Refusal::PulseRate {
            requested_pps: 12_500.4,
            limit_pps: 10_000.0,
        };
        assert_eq!(
            rate.to_string(),
            "12500 pulses/s exceeds the translator limit of 10000 pulses/s"
        );
        assert_eq!(Refusal::Busy.to_string(), "busy resetting");
    }

    /// The pull-in rate is the fastest start the motor takes: a start at exactly 1000 steps/s
    /// runs, one above it stalls at once, for a preset move and a continuous run alike.
    #[test]
    fn a_start_at_the_pull_in_rate_runs_and_one_above_stalls() {
        for (v0, stalls) in [(PULL_IN_SPS, false), (PULL_IN_SPS + 1.0, true)] {
            for preset in [true, false] {
                let mut m = Machine::new(Drive::default(), PULL_IN_SPS);
                m.profile = StepProfile {
                    v0_sps: v0,
                    vmax_sps: 2_000.0,
                    accel_sps2: 2_000.0,
                };
                if preset {
                    m.start_preset(500).unwrap();
                } else {
                    m.start_continuous(1).unwrap();
                }
                m.advance(0.2);
                assert_eq!(m.is_stalled(), stalls, "{v0} preset {preset}");
            }
        }
    }

    /// A short preset move from a start rate peaks at √(v0² + a·steps) (half the steps up, half
    /// down). With the steep ramp of 40 000 steps/s² (pull-out rate f ≈ 2183 steps/s) from
    /// 900 steps/s, 107 steps peak above f and stall after ⌊(f² − v0²)/2a⌋ steps; 60 steps peak
    /// at about 1792 steps/s and run through.
    #[test]
    fn a_short_move_stalls_only_if_its_peak_passes_the_pull_out_rate() {
        let (v0, a) = (900.0, 40_000.0);
        let f = pull_out_rate(a);
        assert!((f - 2183.0).abs() < 5.0, "{f}");
        for (steps, stalls) in [(107_i64, true), (60, false)] {
            let peak = (v0 * v0 + a * steps as f64).sqrt();
            assert_eq!(peak > f, stalls, "{steps}: peak {peak}");
            let mut m = Machine::new(Drive::default(), PULL_IN_SPS);
            m.profile = StepProfile {
                v0_sps: v0,
                vmax_sps: 6_000.0,
                accel_sps2: a,
            };
            m.start_preset(steps).unwrap();
            run(&mut m);
            assert_eq!(m.is_stalled(), stalls, "{steps}");
            assert_eq!(m.counter_steps(), steps);
            let want = if stalls {
                ((f * f - v0 * v0) / (2.0 * a)).floor() as i64
            } else {
                steps
            };
            assert_eq!(m.motor_steps(), want, "{steps}");
        }
    }

    /// A continuous run at a top speed of zero does not start (nothing to run at).
    #[test]
    fn a_continuous_run_at_zero_speed_does_not_start() {
        let mut m = Machine::new(Drive::default(), PULL_IN_SPS);
        m.profile = StepProfile {
            v0_sps: 0.0,
            vmax_sps: 0.0,
            accel_sps2: 2_000.0,
        };
        m.start_continuous(1).unwrap();
        assert!(!m.is_moving());
        m.advance(1.0);
        assert_eq!(m.counter_steps(), 0);
    }

    /// The direction of the motion under way: +1 forwards, −1 backwards, 0 at rest.
    #[test]
    fn direction_follows_the_motion() {
        let mut m = Machine::new(Drive::default(), PULL_IN_SPS);
        assert_eq!(m.direction(), 0);
        m.start_continuous(-1).unwrap();
        assert_eq!(m.direction(), -1);
        m.kill();
        assert_eq!(m.direction(), 0);
        m.start_preset(100).unwrap();
        assert_eq!(m.direction(), 1);
    }
}
