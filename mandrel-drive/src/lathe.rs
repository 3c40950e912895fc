//! The lathe winder's axis controller (seed 000 §9.7, Fig 9-4; seed 003 §4): every interrupt it
//! reads the encoders, applies the PD law per axis, guards DAC polarity reversals and writes the
//! DACs; around that, the machine routines of seed 003: machine-zero search, part zero, electronic
//! gearing. Interrupts are paced by an [`InterruptClock`]: [`SimulatedClock`] (machine time only,
//! for tests and `lathe run`) or [`WallClock`] (real time, jitter measured).

use std::time::{Duration, Instant};

use paths::control::Pd;

use crate::Error;
use crate::servo::{AxisIo, EncoderCounter, PolarityGuard, dac_code};

/// The controller's settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoopConfig {
    /// Interrupts per second (§6.7: 200).
    pub interrupt_hz: f64,
    /// The PD law (same gains on every axis, §5.8).
    pub pd: Pd,
    /// Insert a zero-volt interrupt on DAC polarity reversal (§9.11).
    pub polarity_guard: bool,
}

impl LoopConfig {
    /// The velocity feed-forward that makes the steady following error zero on a plant
    /// `K/(s(s + p))` (codes per count-per-interrupt): the code that holds the planned speed,
    /// `hz · p / K`, plus the `K_d` the derivative term takes away.
    pub fn feed_forward(interrupt_hz: f64, plant: (f64, f64), kd: f64) -> f64 {
        interrupt_hz * plant.1 / plant.0 + kd
    }
}

/// What one interrupt did.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Tick {
    /// Measured positions, counts from the origin (machine zero + part zero).
    pub position: [i64; 3],
    /// DAC codes written.
    pub dac: [u16; 3],
    /// Axes whose DAC output saturated.
    pub saturated: [bool; 3],
}

/// Per-axis loop state.
#[derive(Debug, Clone, Copy, PartialEq)]
struct AxisLoop {
    counter: EncoderCounter,
    guard: PolarityGuard,
    last: i64,
}

/// The three-axis (A, X, Y) controller over an [`AxisIo`].
#[derive(Debug)]
pub struct Controller<I: AxisIo> {
    io: I,
    config: LoopConfig,
    axes: [AxisLoop; 3],
    /// Counts from the power-on position to the current origin, per axis.
    origin: [i64; 3],
}

impl<I: AxisIo> Controller<I> {
    /// A controller over `io` (three axes, A X Y); the current position is the origin.
    pub fn new(mut io: I, config: LoopConfig) -> Result<Self, Error> {
        if io.axis_count() != 3 {
            return Err(Error::OutOfRange {
                name: "axis_count",
                value: io.axis_count() as f64,
                expected: "the lathe controller drives exactly 3 axes (A, X, Y)",
            });
        }
        if !(config.interrupt_hz > 0.0 && config.interrupt_hz <= 1000.0) {
            return Err(Error::OutOfRange {
                name: "interrupt_hz",
                value: config.interrupt_hz,
                expected: "0 < rate ≤ 1000 Hz",
            });
        }
        let axes = std::array::from_fn(|i| {
            let raw = io.read_encoder(i);
            AxisLoop {
                counter: EncoderCounter::new(raw, 0),
                guard: PolarityGuard::default(),
                last: 0,
            }
        });
        Ok(Controller {
            io,
            config,
            axes,
            origin: [0; 3],
        })
    }

    /// The settings.
    pub fn config(&self) -> &LoopConfig {
        &self.config
    }

    /// The I/O (the simulator's state, for a trace).
    pub fn io(&self) -> &I {
        &self.io
    }

    /// Mutable I/O.
    pub fn io_mut(&mut self) -> &mut I {
        &mut self.io
    }

    /// The interrupt period, s.
    pub fn period_s(&self) -> f64 {
        1.0 / self.config.interrupt_hz
    }

    /// Last measured positions, counts from the origin.
    pub fn position(&self) -> [i64; 3] {
        std::array::from_fn(|i| self.axes[i].last - self.origin[i])
    }

    /// Moves the origin by `offset` counts (from the current origin): the part zero as an
    /// offset from machine zero (seed 003 §4.2).
    pub fn shift_origin(&mut self, offset: [i64; 3]) {
        for (o, d) in self.origin.iter_mut().zip(offset) {
            *o += d;
        }
    }

    /// One interrupt: read, control towards `desired` (counts from the origin) with planned
    /// velocity `planned_velocity` (counts per interrupt), write. A made limit switch stops every
    /// drive and is an error.
    pub fn tick(&mut self, desired: [f64; 3], planned_velocity: [f64; 3]) -> Result<Tick, Error> {
        let mut tick = Tick::default();
        for i in 0..3 {
            let raw = self.io.read_encoder(i);
            let a = &mut self.axes[i];
            let pos = a.counter.update(raw);
            let measured_velocity = (pos - a.last) as f64;
            a.last = pos;
            let limits = self.io.read_limits(i);
            if limits.cut() {
                self.stop();
                return Err(Error::LimitTripped {
                    axis: ['A', 'X', 'Y'][i],
                    side: if limits.low { "low" } else { "high" },
                    position_counts: pos - self.origin[i],
                });
            }
            let error = desired[i] - (pos - self.origin[i]) as f64;
            let c = self
                .config
                .pd
                .output(error, measured_velocity, planned_velocity[i]);
            let (mut code, saturated) = dac_code(c);
            if self.config.polarity_guard {
                code = self.axes[i].guard.filter(code);
            }
            self.io.write_dac(i, code);
            tick.position[i] = pos - self.origin[i];
            tick.dac[i] = code;
            tick.saturated[i] = saturated;
        }
        Ok(tick)
    }

    /// Writes 0 V to every DAC.
    pub fn stop(&mut self) {
        for i in 0..3 {
            self.io.write_dac(i, crate::servo::DAC_ZERO_CODE);
        }
    }

    /// Machine-zero search on `axis` (seed 003 §4.2; App. A "0-X"): move toward the home switch at
    /// `approach` counts per interrupt until it is made, stop, creep back at `creep` counts per
    /// interrupt until it releases, then move `backoff` more whole encoder pulses and make that
    /// position the axis's zero. `max_travel` bounds the search. Returns the interrupts used.
    pub fn home(
        &mut self,
        axis: usize,
        approach: f64,
        creep: f64,
        backoff: i64,
        max_travel: i64,
        clock: &mut dyn InterruptClock,
    ) -> Result<u64, Error> {
        let letter = ['A', 'X', 'Y'][axis];
        let mut desired = self.position().map(|p| p as f64);
        let start = desired[axis];
        let mut n = 0u64;
        let mut step = |c: &mut Self, desired: &[f64; 3], v: f64, n: &mut u64| {
            clock.wait();
            let mut vel = [0.0; 3];
            vel[axis] = v;
            let t = c.tick(*desired, vel);
            c.io.elapse(c.period_s());
            *n += 1;
            t
        };
        // 1. Toward the switch.
        while !self.io.read_limits(axis).home {
            if (start - desired[axis]).abs() > max_travel as f64 {
                self.stop();
                return Err(Error::HomeNotFound {
                    axis: letter,
                    searched_counts: max_travel,
                });
            }
            desired[axis] -= approach;
            step(self, &desired, -approach, &mut n)?;
        }
        // 2. Stop a little inside it and settle (the last reading may predate the switch).
        desired[axis] = self.position()[axis] as f64 - 2.0 * approach;
        for _ in 0..(self.config.interrupt_hz * 0.2) as usize {
            step(self, &desired, 0.0, &mut n)?;
        }
        // 3. Creep off it until it releases; the first count read with the switch open is the
        //    reference edge.
        while self.io.read_limits(axis).home {
            desired[axis] += creep;
            step(self, &desired, creep, &mut n)?;
        }
        let edge = self.axes[axis].last;
        // 4. Back off a whole number of pulses from the edge and settle there: machine zero.
        let target = (edge + backoff - self.origin[axis]) as f64;
        while desired[axis] < target {
            desired[axis] = (desired[axis] + creep * 4.0).min(target);
            step(self, &desired, creep * 4.0, &mut n)?;
        }
        for _ in 0..(self.config.interrupt_hz * 0.3) as usize {
            step(self, &desired, 0.0, &mut n)?;
        }
        self.origin[axis] = edge + backoff;
        Ok(n)
    }
}

/// What paces the interrupts.
pub trait InterruptClock {
    /// Waits for the next interrupt (returns at once on simulated time).
    fn wait(&mut self);
}

/// Simulated time: every interrupt is on time and takes no wall time.
#[derive(Debug, Clone, Copy, Default)]
pub struct SimulatedClock;

impl InterruptClock for SimulatedClock {
    fn wait(&mut self) {}
}

/// Jitter figures of a wall-clock run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Jitter {
    /// Interrupts timed.
    pub interrupts: u64,
    /// Median lateness of the wake-up after its deadline, µs.
    pub p50_us: f64,
    /// 99th percentile, µs.
    pub p99_us: f64,
    /// Worst, µs.
    pub max_us: f64,
    /// Interrupts that woke a whole period or more late (a missed interrupt).
    pub missed: u64,
}

/// Real time: absolute deadlines every period from the start, a sleep to just before each and a
/// short spin to it; the lateness of every wake-up is recorded.
#[derive(Debug)]
pub struct WallClock {
    period: Duration,
    next: Option<Instant>,
    spin: Duration,
    lateness_ns: Vec<u64>,
    missed: u64,
}

impl WallClock {
    /// A clock at `hz` (1 … 1000 Hz).
    pub fn new(hz: f64) -> Result<Self, Error> {
        if !(1.0..=1000.0).contains(&hz) {
            return Err(Error::OutOfRange {
                name: "interrupt_hz",
                value: hz,
                expected: "1 … 1000 Hz",
            });
        }
        Ok(WallClock {
            period: Duration::from_secs_f64(1.0 / hz),
            next: None,
            spin: Duration::from_micros(150),
            lateness_ns: Vec::new(),
            missed: 0,
        })
    }

    /// Spins (busy-waits) the last `spin` before each deadline instead of 150 µs; at least the
    /// whole period never sleeps, which keeps an idle virtual CPU from being parked between
    /// interrupts (its wake-up is what the host delays), at the cost of a core.
    pub fn with_spin(mut self, spin: Duration) -> Self {
        self.spin = spin;
        self
    }

    /// The figures so far.
    pub fn jitter(&self) -> Jitter {
        let mut v = self.lateness_ns.clone();
        v.sort_unstable();
        let pick = |q: f64| -> f64 {
            if v.is_empty() {
                0.0
            } else {
                v[((v.len() - 1) as f64 * q).round() as usize] as f64 / 1000.0
            }
        };
        Jitter {
            interrupts: v.len() as u64,
            p50_us: pick(0.5),
            p99_us: pick(0.99),
            max_us: pick(1.0),
            missed: self.missed,
        }
    }
}

impl InterruptClock for WallClock {
    fn wait(&mut self) {
        let now = Instant::now();
        let deadline = match self.next {
            None => {
                self.next = Some(now + self.period);
                return;
            }
            Some(d) => d,
        };
        if deadline > now + self.spin {
            std::thread::sleep(deadline - now - self.spin);
        }
        while Instant::now() < deadline {
            std::hint::spin_loop();
        }
        let woke = Instant::now();
        let late = woke - deadline;
        self.lateness_ns.push(late.as_nanos() as u64);
        let mut next = deadline + self.period;
        // A wake-up a whole period late has lost at least one interrupt: count it and keep the
        // schedule (deadlines stay on the original grid).
        while next <= woke {
            self.missed += 1;
            next += self.period;
        }
        self.next = Some(next);
    }
}

/// Electronic gearing (seed 003 §4.1 item 3): the mandrel A is the master, run to `master`
/// (counts per interrupt, planned), and the carriage X follows the *measured* master position
/// times `ratio` (slave counts per master count). Returns the largest |X − ratio·A| seen, counts.
pub fn run_geared<I: AxisIo>(
    controller: &mut Controller<I>,
    master: &[f64],
    ratio: f64,
    clock: &mut dyn InterruptClock,
) -> Result<f64, Error> {
    if !ratio.is_finite() {
        return Err(Error::OutOfRange {
            name: "gear_ratio",
            value: ratio,
            expected: "must be finite",
        });
    }
    let mut worst = 0.0f64;
    let mut last_master = controller.position()[0] as f64;
    let mut last_a = last_master;
    for (k, &m) in master.iter().enumerate() {
        clock.wait();
        let pos = controller.position();
        let a = pos[0] as f64;
        let y = pos[2] as f64;
        let slave = ratio * a;
        let v_master = if k == 0 { 0.0 } else { m - last_master };
        let v_slave = ratio * (a - last_a);
        if k > 0 {
            worst = worst.max((pos[1] as f64 - slave).abs());
        }
        controller.tick([m, slave, y], [v_master, v_slave, 0.0])?;
        let period = controller.period_s();
        controller.io_mut().elapse(period);
        last_master = m;
        last_a = a;
    }
    Ok(worst)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::servo::{Amplifier, LatheAxis, ServoAxis, SimulatedAxes};

    fn config() -> LoopConfig {
        let plant = Amplifier::Voltage { k_amp: 0.45 }.plant();
        LoopConfig {
            interrupt_hz: 200.0,
            pd: Pd {
                kff: LoopConfig::feed_forward(200.0, plant, 4.0),
                ..Pd::THESIS
            },
            polarity_guard: true,
        }
    }

    fn machine() -> SimulatedAxes {
        SimulatedAxes::lathe(0.45, 1000.0, 200.0).unwrap()
    }

    #[test]
    fn pd_holds_and_moves_an_axis() {
        let mut c = Controller::new(machine(), config()).unwrap();
        let mut desired = [0.0f64; 3];
        for _ in 0..400 {
            let next = (desired[1] + 10.0).min(2000.0);
            let v = next - desired[1];
            desired[1] = next;
            c.tick(desired, [0.0, v, 0.0]).unwrap();
            c.io_mut().elapse(0.005);
        }
        assert!((c.position()[1] - 2000).abs() <= 2, "{:?}", c.position());
    }

    #[test]
    fn thesis_gains_are_stable_for_the_three_amplifier_gains() {
        // Notes-000 §2.10: C = 2e − 4Δθ at 5 ms is stable for K_amp 0.2, 0.45 and 2.0.
        for k_amp in [0.2, 0.45, 2.0] {
            let m = SimulatedAxes::new(vec![
                ServoAxis::new(Amplifier::Voltage { k_amp }).unwrap(),
                ServoAxis::new(Amplifier::Voltage { k_amp }).unwrap(),
                ServoAxis::new(Amplifier::Voltage { k_amp }).unwrap(),
            ]);
            let cfg = LoopConfig {
                interrupt_hz: 200.0,
                pd: Pd::THESIS,
                polarity_guard: false,
            };
            let mut c = Controller::new(m, cfg).unwrap();
            let mut peak = 0i64;
            for _ in 0..400 {
                let t = c.tick([0.0, 1000.0, 0.0], [0.0; 3]).unwrap();
                peak = peak.max(t.position[1]);
                c.io_mut().elapse(0.005);
            }
            assert!(
                (c.position()[1] - 1000).abs() <= 3,
                "{k_amp}: {:?}",
                c.position()
            );
            assert!(peak <= 1000 + 45, "{k_amp}: overshoot to {peak}");
        }
    }

    #[test]
    fn limit_switch_stops_the_run_with_an_error() {
        let mut c = Controller::new(machine(), config()).unwrap();
        let mut x = 0.0;
        let err = loop {
            x += 40.0;
            match c.tick([0.0, x, 0.0], [0.0, 40.0, 0.0]) {
                Ok(_) => c.io_mut().elapse(0.005),
                Err(e) => break e,
            }
            assert!(x < 1e7);
        };
        assert!(
            matches!(
                err,
                Error::LimitTripped {
                    axis: 'X',
                    side: "high",
                    ..
                }
            ),
            "{err}"
        );
        assert!(c.io().axes[1].limits().cut());
    }

    fn home_from(start_mm: f64) -> (f64, i64) {
        let x = LatheAxis::X.counts_per_unit();
        let mut m = machine();
        m.axes[1] = m.axes[1].clone().at(start_mm * x);
        let mut c = Controller::new(m, config()).unwrap();
        c.home(1, 20.0, 0.25, 100, 200_000, &mut SimulatedClock)
            .unwrap();
        let physical = c.io().axes[1].position().floor() as i64;
        (c.io().axes[1].position(), physical)
    }

    #[test]
    fn machine_zero_search_ends_at_the_same_count_from_any_start() {
        let results: Vec<(f64, i64)> = [3.0, 57.3, 250.0, 611.1].map(home_from).to_vec();
        let counts: Vec<i64> = results.iter().map(|r| r.1).collect();
        assert!(counts.iter().all(|&c| c == counts[0]), "{results:?}");
        // Home switch at −1 mm = −55.358 counts; zero is 100 pulses beyond the release edge.
        assert!((counts[0] - (-55 + 100)).abs() <= 1, "{counts:?}");
    }

    #[test]
    fn home_search_gives_up_after_max_travel() {
        let mut m = machine();
        m.axes[1] = ServoAxis::new(Amplifier::Voltage { k_amp: 0.45 }).unwrap();
        let mut c = Controller::new(m, config()).unwrap();
        let e = c.home(1, 20.0, 0.25, 100, 5000, &mut SimulatedClock);
        assert!(matches!(e, Err(Error::HomeNotFound { axis: 'X', .. })));
    }

    #[test]
    fn part_zero_offsets_the_origin() {
        let mut c = Controller::new(machine(), config()).unwrap();
        c.shift_origin([0, 500, 0]);
        assert_eq!(c.position(), [0, -500, 0]);
        for _ in 0..400 {
            c.tick([0.0; 3], [0.0; 3]).unwrap();
            c.io_mut().elapse(0.005);
        }
        assert!((c.io().axes[1].position() - 500.0).abs() < 2.0);
    }

    #[test]
    fn electronic_gearing_keeps_the_carriage_at_the_ratio() {
        let mut c = Controller::new(machine(), config()).unwrap();
        // Mandrel ramps up to 30 counts per interrupt over 1 s, runs 3 s; carriage at 0.5.
        let mut master = Vec::new();
        let (mut p, mut v) = (0.0, 0.0);
        for _ in 0..800 {
            v = (v + 0.15f64).min(30.0);
            p += v;
            master.push(p);
        }
        let worst = run_geared(&mut c, &master, 0.5, &mut SimulatedClock).unwrap();
        let pos = c.position();
        assert!(worst < 20.0, "{worst}");
        assert!(
            (pos[1] as f64 - 0.5 * pos[0] as f64).abs() < 20.0,
            "{pos:?}"
        );
        assert!(pos[0] > 20_000);
        assert!(run_geared(&mut c, &master, f64::NAN, &mut SimulatedClock).is_err());
    }

    #[test]
    fn wall_clock_paces_interrupts() {
        let mut clock = WallClock::new(1000.0).unwrap();
        let start = Instant::now();
        for _ in 0..51 {
            clock.wait();
        }
        let elapsed = start.elapsed();
        assert!(elapsed >= Duration::from_millis(50), "{elapsed:?}");
        let j = clock.jitter();
        assert_eq!(j.interrupts, 50);
        assert!(j.p50_us >= 0.0 && j.max_us >= j.p99_us && j.p99_us >= j.p50_us);
        assert!(WallClock::new(2000.0).is_err());
        // Spinning the whole period instead of sleeping paces the same way.
        let mut clock = WallClock::new(1000.0)
            .unwrap()
            .with_spin(Duration::from_millis(1));
        let start = Instant::now();
        for _ in 0..51 {
            clock.wait();
        }
        let elapsed = start.elapsed();
        assert!(elapsed >= Duration::from_millis(50), "{elapsed:?}");
        assert!(elapsed < Duration::from_millis(500), "{elapsed:?}");
        assert_eq!(clock.jitter().interrupts, 50);
    }

    #[test]
    fn controller_refuses_bad_rates_and_axis_counts() {
        let mut cfg = config();
        cfg.interrupt_hz = 2000.0;
        assert!(Controller::new(machine(), cfg).is_err());
        let two = SimulatedAxes::new(vec![
            ServoAxis::new(Amplifier::Voltage { k_amp: 0.45 }).unwrap(),
            ServoAxis::new(Amplifier::Voltage { k_amp: 0.45 }).unwrap(),
        ]);
        assert!(Controller::new(two, config()).is_err());
    }
}
