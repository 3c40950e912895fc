//! The lathe winder's DC servo axes (seed 000 Ch. 6–7, §9.11, App. B; constants in `docs/lathe.md` "Parameters").
//!
//! Each axis is a DAC channel (12 bits, ±10 V, offset binary with code 2048 at 0 V), a servo
//! amplifier, a DC motor with its load, and a 1000-line encoder read in quadrature (4000 counts per
//! revolution) through a 16-bit counter. The plant from DAC code to encoder counts is
//! `G_p(s) = K / (s (s + p))`:
//!
//! - [`Amplifier::Voltage`]: Ch. 7's model, `K = 1772 K_amp`, `p = 46.7 /s` (Eq. 7-11: DAC
//!   20 V / 4096, motor `570 / (s (s + 46.7))` rad/V, encoder 4000 / 2π counts/rad).
//! - [`Amplifier::Current`]: §6.4's torque amplifiers (up to 4 A/V): `J θ'' + F θ' = K_T i`, with
//!   `J = 3.597e-4 kg·m²` (the inertia that gives Ch. 7's τ_m = 0.0214 s) and a light viscous
//!   friction `F/J = 1 /s` [reading: the thesis gives no friction figure].
//!
//! Hardware limit switches "disconnect the power supply to that axis motor" (§9.11): the simulated
//! axis coasts under friction alone once its switch trips, until reset. [`PolarityGuard`] inserts
//! one zero-volt interrupt whenever the DAC output would reverse polarity (§9.11).
//! [`EncoderCounter`] accumulates the 16-bit counter across rollover (seed 003 §4.1).
//! [`AxisIo`] is the seam a real I/O card implements; [`SimulatedAxes`] is the simulator.

use crate::Error;

/// DAC resolution (§6.2: "12 bit DAC channels").
pub const DAC_BITS: u32 = 12;
/// The highest DAC code.
pub const DAC_MAX_CODE: u16 = 4095;
/// The code for 0 V (offset binary, App. B: "0 to 4095" for −10 … +10 V).
pub const DAC_ZERO_CODE: u16 = 2048;
/// Volts per DAC code (§7.3: "20 volt / 4096 count").
pub const DAC_VOLTS_PER_CODE: f64 = 20.0 / 4096.0;
/// Encoder counts per motor revolution (§6.5: 1000 lines, quadrature).
pub const ENCODER_COUNTS_PER_REV: u32 = 4000;

/// One of the lathe winder's servo axes (Fig 2-4).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum LatheAxis {
    /// Mandrel rotation, degrees.
    A,
    /// Carriage along the mandrel axis, mm.
    X,
    /// Pay-out eye cross-feed, mm.
    Y,
}

impl LatheAxis {
    /// The three axes in the controller's order (A, X, Y, as in the part program).
    pub const ALL: [LatheAxis; 3] = [LatheAxis::A, LatheAxis::X, LatheAxis::Y];

    /// Encoder counts per unit of the axis (§4.3–4.5): A 35.18159 counts/°, X 55.358 counts/mm,
    /// Y 62.294 counts/mm.
    pub fn counts_per_unit(self) -> f64 {
        match self {
            LatheAxis::A => 35.18159,
            LatheAxis::X => 55.358,
            LatheAxis::Y => 62.294,
        }
    }

    /// The unit of the axis (`deg` or `mm`).
    pub fn unit(self) -> &'static str {
        match self {
            LatheAxis::A => "deg",
            _ => "mm",
        }
    }

    /// The axis letter.
    pub fn letter(self) -> char {
        match self {
            LatheAxis::A => 'A',
            LatheAxis::X => 'X',
            LatheAxis::Y => 'Y',
        }
    }

    /// Index in [`LatheAxis::ALL`].
    pub fn index(self) -> usize {
        self as usize
    }
}

/// The servo amplifier in front of the motor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Amplifier {
    /// Ch. 7's voltage-driven motor with amplifier gain `K_amp` (0 … 8; 0.45 for X, §7.5).
    Voltage {
        /// K_amp.
        k_amp: f64,
    },
    /// §6.4's torque (current) amplifier, amperes per volt (at most 4).
    Current {
        /// Amplifier gain, A/V.
        amps_per_volt: f64,
    },
}

/// Motor torque constant K_T, N·m/A (§6.3).
pub const TORQUE_CONSTANT_NM_PER_A: f64 = 0.082;
/// Reflected inertia for τ_m = 0.0214 s, kg·m² (`docs/seed-readings.md` R000-1).
pub const AXIS_INERTIA_KG_M2: f64 = 3.597e-4;
/// Viscous friction over inertia of the current-amplifier variant, 1/s [reading].
pub const CURRENT_MODE_FRICTION_PER_S: f64 = 1.0;

impl Amplifier {
    /// `(K, p)` of `G_p(s) = K / (s (s + p))`, DAC codes to encoder counts.
    pub fn plant(self) -> (f64, f64) {
        match self {
            Amplifier::Voltage { k_amp } => (1772.0 * k_amp, 46.7),
            Amplifier::Current { amps_per_volt } => (
                DAC_VOLTS_PER_CODE * amps_per_volt * TORQUE_CONSTANT_NM_PER_A / AXIS_INERTIA_KG_M2
                    * (ENCODER_COUNTS_PER_REV as f64 / std::f64::consts::TAU),
                CURRENT_MODE_FRICTION_PER_S,
            ),
        }
    }

    fn check(self) -> Result<(), Error> {
        let (name, v, max) = match self {
            Amplifier::Voltage { k_amp } => ("k_amp", k_amp, 8.0),
            Amplifier::Current { amps_per_volt } => ("amps_per_volt", amps_per_volt, 4.0),
        };
        if v > 0.0 && v <= max {
            Ok(())
        } else {
            Err(Error::OutOfRange {
                name,
                value: v,
                expected: "K_amp in (0, 8], current gain in (0, 4] A/V",
            })
        }
    }
}

/// The state of an axis's switches: the two hardware limit switches that cut the drive (§9.11,
/// CN5) and the home opto-switch read on the status port (App. B, 030ch bits 7 and 8).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Limits {
    /// The limit switch at the low (zero) end is made.
    pub low: bool,
    /// The limit switch at the high end is made.
    pub high: bool,
    /// The home opto-switch is made (the axis is at or below its home position).
    pub home: bool,
}

impl Limits {
    /// Either limit switch made (the drive is cut).
    pub fn cut(self) -> bool {
        self.low || self.high
    }
}

/// The DAC code for an actuation in codes about 0 V, and whether it had to saturate.
pub fn dac_code(actuation: f64) -> (u16, bool) {
    let raw = f64::from(DAC_ZERO_CODE) + actuation.round();
    if raw.is_nan() {
        return (DAC_ZERO_CODE, true);
    }
    let code = raw.clamp(0.0, f64::from(DAC_MAX_CODE));
    (code as u16, code != raw)
}

/// The output voltage of a DAC code.
pub fn dac_volts(code: u16) -> f64 {
    (f64::from(code.min(DAC_MAX_CODE)) - f64::from(DAC_ZERO_CODE)) * DAC_VOLTS_PER_CODE
}

/// §9.11's guard: "if the present polarity is reverse then a zero volt pulse is introduced".
/// Exactly one zero-volt interrupt separates outputs of opposite sign.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct PolarityGuard {
    last_sign: i8,
}

impl PolarityGuard {
    /// The code to write this interrupt for the wanted `code`.
    pub fn filter(&mut self, code: u16) -> u16 {
        let sign = match code.cmp(&DAC_ZERO_CODE) {
            std::cmp::Ordering::Greater => 1i8,
            std::cmp::Ordering::Less => -1,
            std::cmp::Ordering::Equal => 0,
        };
        if sign != 0 && self.last_sign == -sign {
            self.last_sign = 0;
            return DAC_ZERO_CODE;
        }
        self.last_sign = sign;
        code
    }
}

/// Position from a 16-bit up/down counter that rolls over (seed 003 §4.1: "the counter restarts
/// from zero when it reaches its maximum", read in real time). Exact as long as the axis moves
/// fewer than 32 768 counts between reads (at the encoder's 100 000 counts/s limit that is
/// 0.33 s).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EncoderCounter {
    last: u16,
    total: i64,
}

impl EncoderCounter {
    /// A counter whose first reading is `raw`, taken as position `position`.
    pub fn new(raw: u16, position: i64) -> Self {
        EncoderCounter {
            last: raw,
            total: position,
        }
    }

    /// Takes a new raw reading; returns the accumulated position.
    pub fn update(&mut self, raw: u16) -> i64 {
        self.total += i64::from(raw.wrapping_sub(self.last) as i16);
        self.last = raw;
        self.total
    }

    /// The accumulated position.
    pub fn position(&self) -> i64 {
        self.total
    }
}

/// The axis I/O of the controller: a real card (encoder counters, DACs, the status port's limit
/// opto-switches, App. B) or the simulator.
pub trait AxisIo {
    /// Number of axes.
    fn axis_count(&self) -> usize;
    /// The raw 16-bit encoder counter of `axis`.
    fn read_encoder(&mut self, axis: usize) -> u16;
    /// Writes a 12-bit DAC code to `axis` (held until the next write).
    fn write_dac(&mut self, axis: usize, code: u16);
    /// The limit switches of `axis`.
    fn read_limits(&mut self, axis: usize) -> Limits;
    /// Lets `dt_s` of machine time pass with the DAC outputs held. Real hardware moves on its own
    /// and does nothing here; the simulator integrates its axes.
    fn elapse(&mut self, dt_s: f64);
}

/// One simulated servo axis.
#[derive(Debug, Clone, PartialEq)]
pub struct ServoAxis {
    gain: f64,
    pole: f64,
    /// Position, encoder counts (fractional: the shaft is between counts).
    position: f64,
    /// Velocity, counts/s.
    velocity: f64,
    code: u16,
    counter_offset: u16,
    switches: Option<(f64, f64)>,
    home: Option<f64>,
    tripped: bool,
    /// `(dt, e^{−p dt})` of the last step (the period rarely changes).
    decay: (f64, f64),
}

impl ServoAxis {
    /// An axis at rest at position 0 with amplifier `amplifier`, no switches.
    pub fn new(amplifier: Amplifier) -> Result<Self, Error> {
        amplifier.check()?;
        let (gain, pole) = amplifier.plant();
        Ok(ServoAxis {
            gain,
            pole,
            position: 0.0,
            velocity: 0.0,
            code: DAC_ZERO_CODE,
            counter_offset: 0,
            switches: None,
            home: None,
            tripped: false,
            decay: (0.0, 1.0),
        })
    }

    /// Limit switches made at or below `low` and at or above `high` (counts).
    pub fn with_switches(mut self, low: f64, high: f64) -> Self {
        self.switches = Some((low, high));
        self
    }

    /// A home opto-switch made at or below `position` counts (inside the limit switches).
    pub fn with_home(mut self, position: f64) -> Self {
        self.home = Some(position);
        self
    }

    /// Starts the hardware counter at `raw` (the counter's power-on value is arbitrary).
    pub fn with_counter(mut self, raw: u16) -> Self {
        self.counter_offset = raw;
        self
    }

    /// Places the axis at `position` counts, at rest.
    pub fn at(mut self, position: f64) -> Self {
        self.position = position;
        self
    }

    /// Position, counts.
    pub fn position(&self) -> f64 {
        self.position
    }

    /// Velocity, counts/s.
    pub fn velocity(&self) -> f64 {
        self.velocity
    }

    /// Whether a limit switch has cut the drive.
    pub fn tripped(&self) -> bool {
        self.tripped
    }

    /// Reconnects the drive after a limit trip (the operator's reset).
    pub fn reset(&mut self) {
        self.tripped = false;
    }

    /// The limit switches' state now.
    pub fn limits(&self) -> Limits {
        let (low, high) = match self.switches {
            Some((low, high)) => (self.position <= low, self.position >= high),
            None => (false, false),
        };
        Limits {
            low,
            high,
            home: self.home.is_some_and(|h| self.position <= h),
        }
    }

    /// The 16-bit counter (floor of the position, wrapped).
    pub fn counter(&self) -> u16 {
        let counts = self.position.floor() as i64;
        (counts.wrapping_add(i64::from(self.counter_offset))).rem_euclid(65536) as u16
    }

    /// Integrates `dt_s` exactly with the DAC code held (zero-order hold on
    /// `θ'' = −p θ' + K u`). A made switch cuts the drive (u = 0) until [`ServoAxis::reset`].
    pub fn advance(&mut self, dt_s: f64) {
        if self.limits().cut() {
            self.tripped = true;
        }
        let u = if self.tripped {
            0.0
        } else {
            f64::from(self.code) - f64::from(DAC_ZERO_CODE)
        };
        let (k, p) = (self.gain, self.pole);
        if self.decay.0 != dt_s {
            self.decay = (dt_s, (-p * dt_s).exp());
        }
        let e = self.decay.1;
        let v_inf = k * u / p;
        let v0 = self.velocity;
        self.velocity = v_inf + (v0 - v_inf) * e;
        self.position += v_inf * dt_s + (v0 - v_inf) * (1.0 - e) / p;
    }
}

/// The simulated machine: one [`ServoAxis`] per axis behind the [`AxisIo`] seam.
#[derive(Debug, Clone, PartialEq)]
pub struct SimulatedAxes {
    /// The axes, in the controller's order.
    pub axes: Vec<ServoAxis>,
    /// Time elapsed, s.
    pub time_s: f64,
    /// Simulation sub-steps per [`AxisIo::elapse`] call (1 is exact for a held DAC).
    pub substeps: usize,
}

impl SimulatedAxes {
    /// A machine of `axes`.
    pub fn new(axes: Vec<ServoAxis>) -> Self {
        SimulatedAxes {
            axes,
            time_s: 0.0,
            substeps: 1,
        }
    }

    /// The lathe winder of the thesis: A, X, Y with voltage amplifiers at `k_amp`; X and Y limit
    /// switches 5 mm below zero and at `x_travel_mm` and `y_travel_mm`; home opto-switches at
    /// −1 mm (machine zero is found from them, [`crate::lathe::Controller::home`]).
    pub fn lathe(k_amp: f64, x_travel_mm: f64, y_travel_mm: f64) -> Result<Self, Error> {
        let amp = Amplifier::Voltage { k_amp };
        let x = LatheAxis::X.counts_per_unit();
        let y = LatheAxis::Y.counts_per_unit();
        Ok(SimulatedAxes::new(vec![
            ServoAxis::new(amp)?,
            ServoAxis::new(amp)?
                .with_switches(-5.0 * x, x_travel_mm * x)
                .with_home(-x),
            ServoAxis::new(amp)?
                .with_switches(-5.0 * y, y_travel_mm * y)
                .with_home(-y),
        ]))
    }
}

impl AxisIo for SimulatedAxes {
    fn axis_count(&self) -> usize {
        self.axes.len()
    }

    fn read_encoder(&mut self, axis: usize) -> u16 {
        self.axes[axis].counter()
    }

    fn write_dac(&mut self, axis: usize, code: u16) {
        self.axes[axis].code = code.min(DAC_MAX_CODE);
    }

    fn read_limits(&mut self, axis: usize) -> Limits {
        self.axes[axis].limits()
    }

    fn elapse(&mut self, dt_s: f64) {
        let n = self.substeps.max(1);
        for axis in &mut self.axes {
            for _ in 0..n {
                axis.advance(dt_s / n as f64);
            }
        }
        self.time_s += dt_s;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;
    use paths::control::step_metrics;

    /// Closed loop with G_c = 1 (C = e in DAC codes per count), sampled finely enough to stand
    /// for the continuous loop of Ch. 7, from rest to a `target`-count step.
    fn step(k_amp: f64, target: f64) -> Vec<f64> {
        let mut axis = ServoAxis::new(Amplifier::Voltage { k_amp }).unwrap();
        let dt = 1e-4;
        let mut out = vec![0.0];
        for _ in 0..10_000 {
            let e = target - axis.position();
            axis.code = dac_code(e).0;
            axis.advance(dt);
            out.push(axis.position() / target);
        }
        out
    }

    #[test]
    fn plant_constants_follow_the_thesis() {
        // (20/4096)·570·(4000/2π) = 1771.8 (`docs/seed-readings.md` R000-1).
        let k = DAC_VOLTS_PER_CODE * 570.0 * 4000.0 / std::f64::consts::TAU;
        assert_abs_diff_eq!(k, 1772.0, epsilon = 0.5);
        assert_eq!(Amplifier::Voltage { k_amp: 1.0 }.plant(), (1772.0, 46.7));
        assert!(ServoAxis::new(Amplifier::Voltage { k_amp: 0.0 }).is_err());
        assert!(ServoAxis::new(Amplifier::Current { amps_per_volt: 5.0 }).is_err());
    }

    #[test]
    fn step_response_k_amp_045_settles_in_about_125_ms_without_overshoot() {
        let y = step(0.45, 1500.0);
        let m = step_metrics(&y, 1e-4, 1.0, 0.05);
        assert!(m.overshoot_pct < 2.0, "{m:?}");
        assert_abs_diff_eq!(m.settling_time_s, 0.125, epsilon = 0.01);
    }

    #[test]
    fn step_response_k_amp_2_is_fast_with_about_26_percent_overshoot() {
        let y = step(2.0, 1500.0);
        let m = step_metrics(&y, 1e-4, 1.0, 0.05);
        assert_abs_diff_eq!(m.overshoot_pct, 26.2, epsilon = 1.5);
        // "about 50 msec": the peak at 57 ms.
        assert_abs_diff_eq!(m.peak_time_s, 0.057, epsilon = 0.006);
    }

    #[test]
    fn step_response_k_amp_02_is_slower_than_500_ms() {
        let y = step(0.2, 1500.0);
        let m = step_metrics(&y, 1e-4, 1.0, 0.01);
        assert_eq!(m.overshoot_pct, 0.0);
        assert!(m.settling_time_s > 0.5, "{m:?}");
        let fast = step_metrics(&step(0.45, 1500.0), 1e-4, 1.0, 0.01);
        assert!(fast.settling_time_s < 0.5 && fast.settling_time_s < m.settling_time_s);
    }

    /// The machine's sub-steps split each interval evenly: with 4 sub-steps an axis held at a
    /// DAC code lands where one exact step of the whole interval puts it (the zero-order hold
    /// composes), and the machine's clock counts whole intervals.
    #[test]
    fn sub_steps_split_the_interval_and_the_clock_counts_it() {
        let mut m = SimulatedAxes::lathe(0.45, 1000.0, 200.0).unwrap();
        m.substeps = 4;
        let mut one = m.axes[0].clone();
        m.write_dac(0, 2548);
        one.code = 2548;
        for _ in 0..3 {
            m.elapse(0.005);
            one.advance(0.005);
        }
        assert_abs_diff_eq!(m.axes[0].position(), one.position(), epsilon = 1e-9);
        assert_abs_diff_eq!(m.axes[0].velocity(), one.velocity(), epsilon = 1e-9);
        assert_abs_diff_eq!(m.time_s, 0.015, epsilon = 1e-15);
    }

    #[test]
    fn exact_integration_matches_fine_steps() {
        let mut a = ServoAxis::new(Amplifier::Voltage { k_amp: 0.45 }).unwrap();
        let mut b = a.clone();
        a.code = 2548;
        b.code = 2548;
        a.advance(0.005);
        for _ in 0..5000 {
            b.advance(1e-6);
        }
        assert_abs_diff_eq!(a.position(), b.position(), epsilon = 1e-6);
        assert_abs_diff_eq!(a.velocity(), b.velocity(), epsilon = 1e-6);
        // Steady speed: K u / p counts/s.
        for _ in 0..1000 {
            a.advance(0.005);
        }
        assert_abs_diff_eq!(a.velocity(), 1772.0 * 0.45 * 500.0 / 46.7, epsilon = 1e-6);
    }

    #[test]
    fn current_amplifier_accelerates_nearly_freely() {
        let amp = Amplifier::Current { amps_per_volt: 4.0 };
        let (k, p) = amp.plant();
        // K_T·i/J converted: 1 V = 204.8 codes → 4 A → 0.328 N·m → 912 rad/s² → 580 600 counts/s².
        assert_abs_diff_eq!(
            k * 204.8,
            0.328 / AXIS_INERTIA_KG_M2 * 4000.0 / std::f64::consts::TAU,
            epsilon = 1.0
        );
        assert_eq!(p, 1.0);
        let mut a = ServoAxis::new(amp).unwrap();
        a.code = DAC_ZERO_CODE + 100;
        a.advance(0.01);
        assert_abs_diff_eq!(
            a.velocity(),
            k * 100.0 * (1.0 - (-0.01f64).exp()),
            epsilon = 1e-6
        );
    }

    #[test]
    fn dac_codes_volts_and_saturation() {
        assert_eq!(dac_code(0.0), (2048, false));
        assert_eq!(dac_code(100.4), (2148, false));
        assert_eq!(dac_code(-2048.0), (0, false));
        assert_eq!(dac_code(3000.0), (4095, true));
        assert_eq!(dac_code(-3000.0), (0, true));
        assert_eq!(dac_code(f64::NAN), (2048, true));
        assert_abs_diff_eq!(dac_volts(4095), 10.0 - 20.0 / 4096.0);
        assert_abs_diff_eq!(dac_volts(0), -10.0);
        assert_abs_diff_eq!(dac_volts(2048), 0.0);
    }

    #[test]
    fn polarity_reversal_gets_exactly_one_zero_volt_sample() {
        let mut g = PolarityGuard::default();
        let out: Vec<u16> = [2100, 2200, 1900, 1800, 2048, 1700, 2300, 2300]
            .iter()
            .map(|&c| g.filter(c))
            .collect();
        assert_eq!(out, [2100, 2200, 2048, 1800, 2048, 1700, 2048, 2300]);
    }

    #[test]
    fn counter_survives_16_bit_rollover() {
        // A move from 65 000 through 65 535 → 0 and on, read every 5 ms.
        let mut axis = ServoAxis::new(Amplifier::Voltage { k_amp: 0.45 })
            .unwrap()
            .with_counter(65_000);
        let mut c = EncoderCounter::new(axis.counter(), 0);
        axis.code = DAC_ZERO_CODE + 800;
        let mut wrapped = false;
        let mut last_raw = axis.counter();
        for _ in 0..400 {
            axis.advance(0.005);
            let raw = axis.counter();
            wrapped |= raw < last_raw;
            last_raw = raw;
            assert_eq!(c.update(raw), axis.position().floor() as i64);
        }
        assert!(wrapped && axis.position() > 20_000.0, "{}", axis.position());
        // And backwards through zero.
        let mut c = EncoderCounter::new(3, 3);
        assert_eq!(c.update(65_530), -6);
        assert_eq!(c.update(10), 10);
    }

    #[test]
    fn limit_switch_cuts_the_drive() {
        let mut m = SimulatedAxes::lathe(0.45, 100.0, 80.0).unwrap();
        m.write_dac(1, 3000);
        let mut t = 0;
        while !m.read_limits(1).high {
            m.elapse(0.005);
            t += 1;
            assert!(t < 10_000);
        }
        m.elapse(0.005);
        assert!(m.axes[1].tripped());
        let v = m.axes[1].velocity();
        // Drive cut: the axis decelerates under its own damping, whatever the DAC says.
        for _ in 0..200 {
            m.elapse(0.005);
        }
        assert!(m.axes[1].velocity().abs() < v.abs() * 0.01);
        m.axes[1].reset();
        assert!(!m.axes[1].tripped());
        assert_eq!(m.read_limits(0), Limits::default());
    }

    #[test]
    fn axis_letters_units_and_order() {
        assert_eq!(LatheAxis::ALL.map(LatheAxis::letter), ['A', 'X', 'Y']);
        assert_eq!(LatheAxis::ALL.map(LatheAxis::unit), ["deg", "mm", "mm"]);
        assert_eq!(LatheAxis::ALL.map(LatheAxis::index), [0, 1, 2]);
    }

    #[test]
    fn counter_position_is_the_accumulated_count() {
        let mut c = EncoderCounter::new(65_530, 1000);
        assert_eq!(c.position(), 1000);
        // 65 530 → 4 is ten counts forward across the wrap; 4 → 65 526 fourteen back.
        assert_eq!(c.update(4), 1010);
        assert_eq!(c.position(), 1010);
        assert_eq!(c.update(65_526), 996);
        assert_eq!(c.position(), 996);
    }
}
