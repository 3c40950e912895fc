//! Position-control laws and discrete transfer functions for the lathe winder's servo axes.
//!
//! - [`Proportional`]: the PE law `C = K_p (θ_d − θ)` of seed 000 §5.5.
//! - [`Pd`]: the thesis's PD law `C = K_p (θ_d − θ) − K_d dθ/dt` (§5.5.2, §5.6): the derivative acts
//!   on the *measured* velocity, here the encoder difference over one interrupt, with optional
//!   velocity feed-forward of the planned velocity ("velocity-based path control", §8.3).
//! - [`Pid`]: PID with anti-windup (the integral is frozen while the output is saturated and
//!   pushing further into saturation), for the steady load the thesis discusses in §5.5.1.
//! - [`ContinuousTf`] and [`DiscreteTf`]: transfer functions in `s` and `z`, Tustin and zero-order
//!   hold discretisation, series and unity-feedback connection, poles, difference equations and
//!   step responses with their metrics, enough to design and run the seed 004 lead compensator
//!   (Mbaocha et al. 2015, Eqs. 17, 22–25; `docs/seed-readings.md` R004-1).
//!
//! Polynomials are coefficient vectors in *descending* powers (`[1, 0.1, 0]` is `s² + 0.1 s`).

use nalgebra::{Complex, DMatrix, DVector};

use crate::Error;

/// The proportional-error (PE) law of seed 000 §5.5: `C = K_p (θ_d − θ)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Proportional {
    /// K_p, output units per count of error.
    pub kp: f64,
}

impl Proportional {
    /// The actuation for a position error (desired − measured).
    pub fn output(&self, error: f64) -> f64 {
        self.kp * error
    }
}

/// The PD law of seed 000 §5.5.2: `C_n = K_p (θ_d[n] − θ[n]) − K_d (θ[n] − θ[n−1]) + K_ff v_d[n]`,
/// all in encoder counts per interrupt; `K_ff = 0` is the thesis's law as printed (`docs/seed-readings.md` R000-3).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pd {
    /// K_p (thesis: 2), output per count of position error.
    pub kp: f64,
    /// K_d (thesis: 4), output per count-per-interrupt of measured velocity.
    pub kd: f64,
    /// Velocity feed-forward, output per count-per-interrupt of planned velocity.
    pub kff: f64,
}

impl Pd {
    /// The thesis's tuned gains, K_p = 2 and K_d = 4, without feed-forward (§5.8).
    pub const THESIS: Pd = Pd {
        kp: 2.0,
        kd: 4.0,
        kff: 0.0,
    };

    /// The actuation from the position error, the measured velocity (counts per interrupt) and
    /// the planned velocity (counts per interrupt).
    pub fn output(&self, error: f64, measured_velocity: f64, planned_velocity: f64) -> f64 {
        self.kp * error - self.kd * measured_velocity + self.kff * planned_velocity
    }
}

/// PID with output limits and anti-windup (conditional integration): the integral does not grow
/// while the output is saturated in the direction the error pushes it.
#[derive(Debug, Clone, PartialEq)]
pub struct Pid {
    /// Proportional gain.
    pub kp: f64,
    /// Integral gain per sample (the integral is the plain sum of errors).
    pub ki: f64,
    /// Derivative gain on the measured velocity (per sample).
    pub kd: f64,
    /// Lowest output.
    pub min: f64,
    /// Highest output.
    pub max: f64,
    integral: f64,
}

impl Pid {
    /// A PID with zero integral. `min < max` is required.
    pub fn new(kp: f64, ki: f64, kd: f64, min: f64, max: f64) -> Result<Self, Error> {
        if min.partial_cmp(&max) != Some(std::cmp::Ordering::Less) {
            return Err(Error::OutOfRange {
                name: "pid_output_range",
                value: max - min,
                expected: "min must be < max",
            });
        }
        Ok(Pid {
            kp,
            ki,
            kd,
            min,
            max,
            integral: 0.0,
        })
    }

    /// The integral (sum of errors) carried so far.
    pub fn integral(&self) -> f64 {
        self.integral
    }

    /// One sample: the clamped output from the error and the measured velocity.
    pub fn output(&mut self, error: f64, measured_velocity: f64) -> f64 {
        let candidate = self.integral + error;
        let unclamped = self.kp * error + self.ki * candidate - self.kd * measured_velocity;
        let saturated_high = unclamped > self.max && error > 0.0;
        let saturated_low = unclamped < self.min && error < 0.0;
        if !(saturated_high || saturated_low) {
            self.integral = candidate;
        }
        (self.kp * error + self.ki * self.integral - self.kd * measured_velocity)
            .clamp(self.min, self.max)
    }
}

/// A continuous transfer function `N(s)/D(s)`.
#[derive(Debug, Clone, PartialEq)]
pub struct ContinuousTf {
    /// Numerator, descending powers of `s`.
    pub num: Vec<f64>,
    /// Denominator, descending powers of `s`.
    pub den: Vec<f64>,
}

/// A discrete transfer function `N(z)/D(z)` at sample period `period_s`.
#[derive(Debug, Clone, PartialEq)]
pub struct DiscreteTf {
    /// Numerator, descending powers of `z`.
    pub num: Vec<f64>,
    /// Denominator, descending powers of `z` (leading coefficient 1 after [`DiscreteTf::new`]).
    pub den: Vec<f64>,
    /// The sample period.
    pub period_s: f64,
}

fn trim(mut p: Vec<f64>) -> Vec<f64> {
    while p.len() > 1 && p[0] == 0.0 {
        p.remove(0);
    }
    p
}

fn check_tf(num: &[f64], den: &[f64]) -> Result<(), Error> {
    if den.is_empty() || den.iter().all(|&c| c == 0.0) {
        return Err(Error::OutOfRange {
            name: "denominator",
            value: 0.0,
            expected: "must not be zero",
        });
    }
    if num.iter().chain(den).any(|c| !c.is_finite()) {
        return Err(Error::OutOfRange {
            name: "coefficient",
            value: f64::NAN,
            expected: "must be finite",
        });
    }
    let (num, den) = (trim(num.to_vec()), trim(den.to_vec()));
    if num.len() > den.len() {
        return Err(Error::OutOfRange {
            name: "numerator_degree",
            value: (num.len() - 1) as f64,
            expected: "must not exceed the denominator's degree (proper transfer function)",
        });
    }
    Ok(())
}

/// Polynomial product.
pub fn poly_mul(a: &[f64], b: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; a.len() + b.len() - 1];
    for (i, x) in a.iter().enumerate() {
        for (j, y) in b.iter().enumerate() {
            out[i + j] += x * y;
        }
    }
    out
}

/// Polynomial sum (aligned at the constant term).
pub fn poly_add(a: &[f64], b: &[f64]) -> Vec<f64> {
    let n = a.len().max(b.len());
    let mut out = vec![0.0; n];
    for (i, x) in a.iter().rev().enumerate() {
        out[n - 1 - i] += x;
    }
    for (i, x) in b.iter().rev().enumerate() {
        out[n - 1 - i] += x;
    }
    out
}

fn poly_pow(p: &[f64], k: usize) -> Vec<f64> {
    (0..k).fold(vec![1.0], |acc, _| poly_mul(&acc, p))
}

/// The roots of a polynomial (descending powers) as complex numbers, from the companion
/// matrix's eigenvalues.
pub fn roots(p: &[f64]) -> Vec<Complex<f64>> {
    let p = trim(p.to_vec());
    let n = p.len() - 1;
    if n == 0 {
        return Vec::new();
    }
    let mut c = DMatrix::<f64>::zeros(n, n);
    for j in 0..n {
        c[(0, j)] = -p[j + 1] / p[0];
    }
    for i in 1..n {
        c[(i, i - 1)] = 1.0;
    }
    let mut r: Vec<Complex<f64>> = c.complex_eigenvalues().iter().copied().collect();
    r.sort_by(|a, b| b.re.total_cmp(&a.re).then(b.im.total_cmp(&a.im)));
    r
}

/// Characteristic polynomial `det(zI − M)` (Faddeev–LeVerrier), descending powers.
fn char_poly(m: &DMatrix<f64>) -> Vec<f64> {
    let n = m.nrows();
    let mut coeffs = vec![1.0];
    let mut mk = DMatrix::<f64>::identity(n, n);
    let mut c = 1.0;
    for k in 1..=n {
        let am = m * &mk;
        c = -am.trace() / k as f64;
        coeffs.push(c);
        mk = am + DMatrix::identity(n, n) * c;
    }
    let _ = c;
    coeffs
}

impl ContinuousTf {
    /// `num/den`, proper (numerator degree ≤ denominator degree), finite, nonzero denominator.
    pub fn new(num: Vec<f64>, den: Vec<f64>) -> Result<Self, Error> {
        check_tf(&num, &den)?;
        Ok(ContinuousTf {
            num: trim(num),
            den: trim(den),
        })
    }

    /// The poles (roots of the denominator).
    pub fn poles(&self) -> Vec<Complex<f64>> {
        roots(&self.den)
    }

    /// Tustin (bilinear) discretisation: `s = (2/T)(z − 1)/(z + 1)` (seed 004 §3.3 step 9).
    pub fn tustin(&self, period_s: f64) -> Result<DiscreteTf, Error> {
        check_period(period_s)?;
        let n = self.den.len() - 1;
        let k = 2.0 / period_s;
        let map = |p: &[f64]| -> Vec<f64> {
            let deg = p.len() - 1;
            let mut out = vec![0.0; n + 1];
            for (i, c) in p.iter().enumerate() {
                let power = deg - i;
                let term = poly_mul(
                    &poly_pow(&[1.0, -1.0], power),
                    &poly_pow(&[1.0, 1.0], n - power),
                );
                let scale = c * k.powi(power as i32);
                out = poly_add(&out, &term.iter().map(|t| t * scale).collect::<Vec<_>>());
            }
            out
        };
        DiscreteTf::new(map(&self.num), map(&self.den), period_s)
    }

    /// Zero-order-hold discretisation `G(z) = (1 − z⁻¹) Z{G(s)/s}`, exact for a piecewise
    /// constant input (seed 004 Eq. 23), through the controllable canonical state space and the
    /// matrix exponential.
    pub fn zoh(&self, period_s: f64) -> Result<DiscreteTf, Error> {
        check_period(period_s)?;
        let a0 = self.den[0];
        let den: Vec<f64> = self.den.iter().map(|c| c / a0).collect();
        let n = den.len() - 1;
        let mut num = vec![0.0; n + 1 - self.num.len()];
        num.extend(self.num.iter().map(|c| c / a0));
        if n == 0 {
            return DiscreteTf::new(vec![num[0]], vec![1.0], period_s);
        }
        let d = num[0];
        // Controllable canonical form: x' = A x + B u, y = C x + D u.
        let mut a = DMatrix::<f64>::zeros(n, n);
        for i in 0..n - 1 {
            a[(i, i + 1)] = 1.0;
        }
        for j in 0..n {
            a[(n - 1, j)] = -den[n - j];
        }
        let c = DMatrix::from_fn(1, n, |_, j| num[n - j] - den[n - j] * d);
        // exp([[A, B], [0, 0]] T) = [[Φ, Γ], [0, I]].
        let mut m = DMatrix::<f64>::zeros(n + 1, n + 1);
        m.view_mut((0, 0), (n, n)).copy_from(&(a * period_s));
        m[(n - 1, n)] = period_s;
        let e = m.exp();
        let phi = e.view((0, 0), (n, n)).into_owned();
        let gamma = e.view((0, n), (n, 1)).into_owned();
        let den_z = char_poly(&phi);
        let closed = char_poly(&(&phi - &gamma * &c));
        let num_z = poly_add(
            &poly_add(&closed, &den_z.iter().map(|x| -x).collect::<Vec<_>>()),
            &den_z.iter().map(|x| x * d).collect::<Vec<_>>(),
        );
        DiscreteTf::new(num_z, den_z, period_s)
    }

    /// The unit-step response by RK4 on the controllable canonical state space, sampled every
    /// `dt_s` for `duration_s`.
    pub fn step_response(&self, dt_s: f64, duration_s: f64) -> Result<Vec<f64>, Error> {
        check_period(dt_s)?;
        let a0 = self.den[0];
        let den: Vec<f64> = self.den.iter().map(|c| c / a0).collect();
        let n = den.len() - 1;
        let mut num = vec![0.0; n + 1 - self.num.len()];
        num.extend(self.num.iter().map(|c| c / a0));
        let d = num[0];
        let steps = (duration_s / dt_s).round() as usize;
        if n == 0 {
            return Ok(vec![d; steps + 1]);
        }
        let deriv = |x: &DVector<f64>| -> DVector<f64> {
            let mut dx = DVector::zeros(n);
            for i in 0..n - 1 {
                dx[i] = x[i + 1];
            }
            dx[n - 1] = 1.0 - (0..n).map(|j| den[n - j] * x[j]).sum::<f64>();
            dx
        };
        let out = |x: &DVector<f64>| -> f64 {
            (0..n)
                .map(|j| (num[n - j] - den[n - j] * d) * x[j])
                .sum::<f64>()
                + d
        };
        let mut x = DVector::zeros(n);
        let mut y = Vec::with_capacity(steps + 1);
        y.push(d);
        for _ in 0..steps {
            let k1 = deriv(&x);
            let k2 = deriv(&(&x + &k1 * (dt_s / 2.0)));
            let k3 = deriv(&(&x + &k2 * (dt_s / 2.0)));
            let k4 = deriv(&(&x + &k3 * dt_s));
            x += (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (dt_s / 6.0);
            y.push(out(&x));
        }
        Ok(y)
    }
}

fn check_period(period_s: f64) -> Result<(), Error> {
    if !(period_s > 0.0 && period_s.is_finite()) {
        return Err(Error::OutOfRange {
            name: "period_s",
            value: period_s,
            expected: "must be > 0",
        });
    }
    Ok(())
}

impl DiscreteTf {
    /// `num/den` in `z`, normalised so `den[0] = 1`; proper, finite, nonzero denominator.
    pub fn new(num: Vec<f64>, den: Vec<f64>, period_s: f64) -> Result<Self, Error> {
        check_tf(&num, &den)?;
        check_period(period_s)?;
        let den = trim(den);
        let a0 = den[0];
        Ok(DiscreteTf {
            num: trim(num).iter().map(|c| c / a0).collect(),
            den: den.iter().map(|c| c / a0).collect(),
            period_s,
        })
    }

    /// The poles (roots of the denominator).
    pub fn poles(&self) -> Vec<Complex<f64>> {
        roots(&self.den)
    }

    /// The zeros (roots of the numerator).
    pub fn zeros(&self) -> Vec<Complex<f64>> {
        roots(&self.num)
    }

    /// The leading numerator coefficient (the gain in zero–pole–gain form).
    pub fn gain(&self) -> f64 {
        self.num[0]
    }

    /// Whether every pole lies strictly inside the unit circle.
    pub fn is_stable(&self) -> bool {
        self.poles().iter().all(|p| p.norm() < 1.0)
    }

    /// `self · other` (series connection).
    pub fn series(&self, other: &DiscreteTf) -> Result<DiscreteTf, Error> {
        DiscreteTf::new(
            poly_mul(&self.num, &other.num),
            poly_mul(&self.den, &other.den),
            self.period_s,
        )
    }

    /// The unity-feedback closed loop `L/(1 + L)` of this open loop.
    pub fn unity_feedback(&self) -> Result<DiscreteTf, Error> {
        DiscreteTf::new(
            self.num.clone(),
            poly_add(&self.den, &self.num),
            self.period_s,
        )
    }

    /// The difference equation `y[k] = Σ b_i x[k−i] − Σ a_i y[k−i]` as `(b, a)` with `a[0] = 1`,
    /// both indexed by delay (`b[i]` multiplies `x[k−i]`).
    pub fn difference_equation(&self) -> (Vec<f64>, Vec<f64>) {
        let n = self.den.len();
        let mut b = vec![0.0; n - self.num.len()];
        b.extend_from_slice(&self.num);
        (b, self.den.clone())
    }

    /// A running filter of this transfer function with zero initial state.
    pub fn filter(&self) -> Filter {
        let (b, a) = self.difference_equation();
        Filter {
            x: vec![0.0; b.len()],
            y: vec![0.0; a.len()],
            b,
            a,
        }
    }

    /// The unit-step response `y[0..=samples]`.
    pub fn step_response(&self, samples: usize) -> Vec<f64> {
        let mut f = self.filter();
        (0..=samples).map(|_| f.next(1.0)).collect()
    }
}

/// A difference equation running sample by sample (direct form I).
#[derive(Debug, Clone)]
pub struct Filter {
    b: Vec<f64>,
    a: Vec<f64>,
    x: Vec<f64>,
    y: Vec<f64>,
}

impl Filter {
    /// Feeds input `x[k]` and returns `y[k]`.
    pub fn next(&mut self, input: f64) -> f64 {
        self.x.rotate_right(1);
        self.x[0] = input;
        // After the rotation y[i] holds y[k − i] for i ≥ 1.
        self.y.rotate_right(1);
        let feed: f64 = self.b.iter().zip(&self.x).map(|(b, x)| b * x).sum();
        let back: f64 = self.a.iter().zip(&self.y).skip(1).map(|(a, y)| a * y).sum();
        self.y[0] = feed - back;
        self.y[0]
    }
}

/// Step-response metrics of a sampled response with a final value of 1.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepMetrics {
    /// Highest sample.
    pub peak: f64,
    /// Time of the peak, s.
    pub peak_time_s: f64,
    /// `(peak − final)/final`, percent (0 when the response never exceeds the final value).
    pub overshoot_pct: f64,
    /// 10 %–90 % rise time, linearly interpolated between samples, s.
    pub rise_time_s: f64,
    /// Last time the response is outside `±band` of the final value, interpolated, s.
    pub settling_time_s: f64,
}

/// The metrics of `samples` (taken every `dt_s` from `t = 0`) against `final_value`, with the
/// settling band `band` as a fraction (0.02 for 2 %). The MATLAB `stepinfo` conventions: rise
/// from 10 % to 90 %, settling at the interpolated last exit from the band.
pub fn step_metrics(samples: &[f64], dt_s: f64, final_value: f64, band: f64) -> StepMetrics {
    let (peak_index, peak) =
        samples
            .iter()
            .copied()
            .enumerate()
            .fold((0, f64::NEG_INFINITY), |best, (i, v)| {
                if v > best.1 { (i, v) } else { best }
            });
    let crossing = |level: f64| -> f64 {
        for i in 1..samples.len() {
            if samples[i] >= level && samples[i - 1] < level {
                let f = (level - samples[i - 1]) / (samples[i] - samples[i - 1]);
                return (i as f64 - 1.0 + f) * dt_s;
            }
        }
        f64::INFINITY
    };
    let rise = crossing(0.9 * final_value) - crossing(0.1 * final_value);
    let tol = band * final_value.abs();
    let mut settling = 0.0;
    for i in (1..samples.len()).rev() {
        let out = (samples[i] - final_value).abs() > tol;
        let prev_out = (samples[i - 1] - final_value).abs() > tol;
        if out {
            settling = i as f64 * dt_s;
            break;
        }
        if prev_out {
            let d0 = samples[i - 1] - final_value;
            let d1 = samples[i] - final_value;
            let edge = tol * d0.signum();
            let f = (d0 - edge) / (d0 - d1);
            settling = (i as f64 - 1.0 + f) * dt_s;
            break;
        }
    }
    StepMetrics {
        peak,
        peak_time_s: peak_index as f64 * dt_s,
        overshoot_pct: ((peak - final_value) / final_value * 100.0).max(0.0),
        rise_time_s: rise,
        settling_time_s: settling,
    }
}

/// The damping class of the PE-controlled axis `J θ'' + F θ' = −K_p θ` (seed 000 §5.5).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Damping {
    /// `F² > 4 K_p J`: no oscillation.
    Overdamped,
    /// `F² = 4 K_p J`: fastest without overshoot.
    Critical,
    /// `F² < 4 K_p J`: a damped sinusoid.
    Underdamped,
}

/// Classifies `J θ'' + F θ' + K_p θ = 0` (seed 000 §5.5: "if F²/4K_p > J" overdamped, …), with a
/// relative tolerance of 1e-9 for the critical case.
pub fn pe_damping(inertia: f64, friction: f64, kp: f64) -> Damping {
    let disc = friction * friction - 4.0 * kp * inertia;
    let scale = (friction * friction)
        .max(4.0 * kp * inertia)
        .max(f64::MIN_POSITIVE);
    if disc.abs() <= 1e-9 * scale {
        Damping::Critical
    } else if disc > 0.0 {
        Damping::Overdamped
    } else {
        Damping::Underdamped
    }
}

/// Seed 003 Eq. 8 (Koren–Bollinger IAE fit): the position-loop gain
/// `K = (1/τ)[0.5664 − 0.2966 (T/τ) + 0.1135 (T/τ)² + 0.0197 (T/τ)³]` for a loop `K/(s(1 + τs))`
/// sampled every `T`. Refuses `τ ≤ 0`, `T ≤ 0` and `T/τ ≥ π` (the sampling condition of Eq. 1).
pub fn iae_gain(tau_s: f64, period_s: f64) -> Result<f64, Error> {
    if !(tau_s > 0.0 && tau_s.is_finite()) {
        return Err(Error::OutOfRange {
            name: "tau_s",
            value: tau_s,
            expected: "must be > 0",
        });
    }
    check_period(period_s)?;
    let r = period_s / tau_s;
    if r >= std::f64::consts::PI {
        return Err(Error::OutOfRange {
            name: "period_over_tau",
            value: r,
            expected: "must be < π (seed 003 Eq. 1: F ≥ ω0/π)",
        });
    }
    Ok((0.5664 - 0.2966 * r + 0.1135 * r * r + 0.0197 * r * r * r) / tau_s)
}

/// The Routh array of a polynomial (descending powers): its first column. Stable (all roots in
/// the open left half plane) iff every entry has the same sign and none is zero.
pub fn routh_first_column(poly: &[f64]) -> Vec<f64> {
    let p = trim(poly.to_vec());
    let n = p.len();
    let width = n.div_ceil(2);
    let mut rows: Vec<Vec<f64>> = vec![
        p.iter().step_by(2).copied().collect(),
        p.iter().skip(1).step_by(2).copied().collect(),
    ];
    for r in rows.iter_mut() {
        r.resize(width, 0.0);
    }
    while rows.len() < n {
        let (a, b) = (&rows[rows.len() - 2], &rows[rows.len() - 1]);
        if b[0] == 0.0 {
            break;
        }
        let mut next = vec![0.0; width];
        for j in 0..width - 1 {
            next[j] = (b[0] * a[j + 1] - a[0] * b[j + 1]) / b[0];
        }
        rows.push(next);
    }
    rows.iter().map(|r| r[0]).collect()
}

/// The Routh check of seed 003 Eqs. 3–6 for the position loop `K/(s(1 + τs))`: characteristic
/// equation `τ s² + s + K = 0`, stable iff `K > 0` and `τ > 0`. Returns the first column, or an
/// error naming the sign change.
pub fn routh_position_loop(gain: f64, tau_s: f64) -> Result<Vec<f64>, Error> {
    if !(gain.is_finite() && tau_s.is_finite()) {
        return Err(Error::OutOfRange {
            name: "gain",
            value: gain,
            expected: "must be finite",
        });
    }
    let column = routh_first_column(&[tau_s, 1.0, gain]);
    let stable = column.len() == 3 && column.iter().all(|&c| c > 0.0);
    if stable {
        Ok(column)
    } else if tau_s <= 0.0 {
        Err(Error::OutOfRange {
            name: "tau_s",
            value: tau_s,
            expected: "must be > 0 for a stable loop (Routh, seed 003 Eq. 6)",
        })
    } else {
        Err(Error::OutOfRange {
            name: "gain",
            value: gain,
            expected: "must be > 0 for a stable loop (Routh, seed 003 Eq. 6)",
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;

    fn seed_004_lead() -> ContinuousTf {
        ContinuousTf::new(vec![20.3, 20.3 * 0.33], vec![1.0, 3.66]).unwrap()
    }

    fn seed_004_plant() -> ContinuousTf {
        ContinuousTf::new(vec![0.1], vec![1.0, 0.1, 0.0]).unwrap()
    }

    #[test]
    fn tustin_gives_seed_004_eq_22() {
        let d = seed_004_lead().tustin(1.0).unwrap();
        assert_abs_diff_eq!(d.gain(), 8.356714, epsilon = 1e-6);
        let z = d.zeros();
        let p = d.poles();
        assert_abs_diff_eq!(z[0].re, 0.716738, epsilon = 1e-6);
        assert_abs_diff_eq!(p[0].re, -0.293286, epsilon = 1e-6);
        let (b, a) = d.difference_equation();
        assert_abs_diff_eq!(b[0], 8.356714, epsilon = 1e-6);
        assert_abs_diff_eq!(b[1], -5.989576, epsilon = 1e-6);
        assert_abs_diff_eq!(a[1], 0.293286, epsilon = 1e-6);
    }

    #[test]
    fn zoh_gives_seed_004_eq_23() {
        let g = seed_004_plant().zoh(1.0).unwrap();
        assert_eq!(g.den.len(), 3);
        assert_abs_diff_eq!(g.den[1], -1.9048374, epsilon = 1e-7);
        assert_abs_diff_eq!(g.den[2], 0.9048374, epsilon = 1e-7);
        assert_abs_diff_eq!(g.num[g.num.len() - 2], 0.0483742, epsilon = 1e-7);
        assert_abs_diff_eq!(g.num[g.num.len() - 1], 0.0467884, epsilon = 1e-7);
    }

    #[test]
    fn zoh_of_a_first_order_lag_is_exact() {
        // a/(s + a) → (1 − e^{−aT})/(z − e^{−aT}).
        let g = ContinuousTf::new(vec![2.0], vec![1.0, 2.0])
            .unwrap()
            .zoh(0.1)
            .unwrap();
        let e = (-0.2f64).exp();
        assert_abs_diff_eq!(g.den[1], -e, epsilon = 1e-12);
        assert_abs_diff_eq!(*g.num.last().unwrap(), 1.0 - e, epsilon = 1e-12);
    }

    #[test]
    fn seed_004_closed_loop_poles_and_step() {
        let d = seed_004_lead().tustin(1.0).unwrap();
        let g = seed_004_plant().zoh(1.0).unwrap();
        let l = d.series(&g).unwrap();
        assert_abs_diff_eq!(l.gain(), 0.40425, epsilon = 1e-5);
        let t = l.unity_feedback().unwrap();
        assert!(t.is_stable());
        let p = t.poles();
        assert_abs_diff_eq!(p[0].re, 0.585270, epsilon = 1e-5);
        assert_abs_diff_eq!(p[0].im.abs(), 0.248715, epsilon = 1e-5);
        assert_abs_diff_eq!(p[2].re, 0.036761, epsilon = 1e-5);
        let y = t.step_response(12);
        let expected = [
            0.0, 0.40425, 0.99356, 1.24391, 1.28850, 1.23908, 1.16318, 1.09433, 1.04442, 1.01385,
            0.99825, 0.99235, 0.99175,
        ];
        for (k, (a, b)) in y.iter().zip(expected).enumerate() {
            assert_abs_diff_eq!(*a, b, epsilon = 1e-5);
            let _ = k;
        }
        let long = t.step_response(60);
        let m = step_metrics(&long, 1.0, 1.0, 0.02);
        assert_abs_diff_eq!(m.overshoot_pct, 28.85, epsilon = 0.01);
        assert_abs_diff_eq!(m.peak_time_s, 4.0);
        assert_abs_diff_eq!(m.rise_time_s, 1.594, epsilon = 0.001);
        assert_abs_diff_eq!(m.settling_time_s, 8.80, epsilon = 0.01);
    }

    #[test]
    fn seed_004_difference_equations_by_hand() {
        // The controller and plant difference equations of `docs/seed-readings.md` R004-1, run directly.
        let (mut u1, mut e1) = (0.0, 0.0);
        let (mut y1, mut y2, mut u2) = (0.0, 0.0, 0.0);
        let mut ys = Vec::new();
        for _ in 0..5 {
            let y = 1.9048374 * y1 - 0.9048374 * y2 + 0.0483742 * u1 + 0.0467884 * u2;
            let e = 1.0 - y;
            let u = -0.293286 * u1 + 8.356714 * e - 5.989576 * e1;
            ys.push(y);
            (y2, y1, u2, u1, e1) = (y1, y, u1, u, e);
        }
        let t = seed_004_lead()
            .tustin(1.0)
            .unwrap()
            .series(&seed_004_plant().zoh(1.0).unwrap())
            .unwrap()
            .unity_feedback()
            .unwrap();
        for (a, b) in ys.iter().zip(t.step_response(4)) {
            assert_abs_diff_eq!(*a, b, epsilon = 1e-6);
        }
    }

    #[test]
    fn continuous_seed_004_loops() {
        let unc = ContinuousTf::new(vec![0.1], vec![1.0, 0.1, 0.1]).unwrap();
        let y = unc.step_response(0.01, 150.0).unwrap();
        let m = step_metrics(&y, 0.01, 1.0, 0.02);
        assert_abs_diff_eq!(m.overshoot_pct, 60.47, epsilon = 0.05);
        assert_abs_diff_eq!(m.settling_time_s, 73.2, epsilon = 0.2);
        let comp =
            ContinuousTf::new(vec![2.03, 0.6699], vec![1.0, 3.7595, 2.3957, 0.6699]).unwrap();
        let y = comp.step_response(0.001, 40.0).unwrap();
        let m = step_metrics(&y, 0.001, 1.0, 0.02);
        assert_abs_diff_eq!(m.overshoot_pct, 15.98, epsilon = 0.1);
        assert_abs_diff_eq!(m.rise_time_s, 2.05, epsilon = 0.02);
        assert_abs_diff_eq!(m.settling_time_s, 11.0, epsilon = 0.1);
    }

    #[test]
    fn bad_transfer_functions_are_errors() {
        assert!(ContinuousTf::new(vec![1.0, 0.0, 0.0], vec![1.0, 1.0]).is_err());
        assert!(ContinuousTf::new(vec![1.0], vec![0.0]).is_err());
        assert!(ContinuousTf::new(vec![f64::NAN], vec![1.0]).is_err());
        assert!(seed_004_lead().tustin(0.0).is_err());
        assert!(seed_004_lead().zoh(-1.0).is_err());
    }

    #[test]
    fn pid_integral_stops_growing_in_saturation() {
        let mut pid = Pid::new(1.0, 0.5, 0.0, -10.0, 10.0).unwrap();
        for _ in 0..100 {
            assert_eq!(pid.output(50.0, 0.0), 10.0);
        }
        assert!(pid.integral() <= 50.0, "{}", pid.integral());
        // Once the error reverses, the output leaves saturation at once.
        assert!(pid.output(-5.0, 0.0) < 10.0);
        let mut unsat = Pid::new(1.0, 0.5, 0.0, -100.0, 100.0).unwrap();
        unsat.output(2.0, 0.0);
        assert_abs_diff_eq!(unsat.output(2.0, 0.0), 2.0 + 0.5 * 4.0);
        assert_abs_diff_eq!(unsat.output(0.0, 4.0), 0.5 * 4.0);
        assert!(Pid::new(1.0, 0.0, 0.0, 1.0, 1.0).is_err());
    }

    #[test]
    fn pid_with_derivative_on_measurement() {
        let mut pid = Pid::new(2.0, 0.0, 4.0, -100.0, 100.0).unwrap();
        assert_abs_diff_eq!(pid.output(3.0, 1.0), 2.0 * 3.0 - 4.0);
    }

    #[test]
    fn pd_and_pe_laws() {
        assert_abs_diff_eq!(Pd::THESIS.output(10.0, 3.0, 5.0), 20.0 - 12.0);
        let pd = Pd {
            kff: 2.0,
            ..Pd::THESIS
        };
        assert_abs_diff_eq!(pd.output(10.0, 3.0, 5.0), 18.0);
        assert_abs_diff_eq!(Proportional { kp: 2.5 }.output(-4.0), -10.0);
    }

    #[test]
    fn pe_damping_classes_match_a_simulation() {
        // J θ'' + F θ' + K θ = 0 from θ = 1: overdamped never crosses zero.
        let crosses = |j: f64, f: f64, k: f64| {
            let (mut th, mut om) = (1.0f64, 0.0f64);
            let dt = 1e-4;
            for _ in 0..200_000 {
                let acc = (-f * om - k * th) / j;
                om += acc * dt;
                th += om * dt;
                if th < -1e-6 {
                    return true;
                }
            }
            false
        };
        assert_eq!(pe_damping(1.0, 5.0, 2.0), Damping::Overdamped);
        assert!(!crosses(1.0, 5.0, 2.0));
        assert_eq!(pe_damping(1.0, 1.0, 2.0), Damping::Underdamped);
        assert!(crosses(1.0, 1.0, 2.0));
        assert_eq!(pe_damping(1.0, 4.0, 4.0), Damping::Critical);
    }

    #[test]
    fn eq_8_gain_and_routh() {
        let k = iae_gain(1.0, std::f64::consts::FRAC_PI_2).unwrap();
        assert_abs_diff_eq!(k, 0.456905, epsilon = 1e-6);
        assert_abs_diff_eq!(iae_gain(1.0, 1.0).unwrap(), 0.4030, epsilon = 1e-4);
        assert_abs_diff_eq!(iae_gain(2.0, 2.0).unwrap(), 0.4030 / 2.0, epsilon = 1e-4);
        assert!(iae_gain(0.0, 1.0).is_err());
        assert!(iae_gain(1.0, 4.0).is_err());
        let col = routh_position_loop(k, 1.0).unwrap();
        assert_eq!(col.len(), 3);
        assert!(matches!(
            routh_position_loop(0.0, 1.0),
            Err(Error::OutOfRange { name: "gain", .. })
        ));
        assert!(matches!(
            routh_position_loop(-0.1, 1.0),
            Err(Error::OutOfRange { name: "gain", .. })
        ));
        assert!(matches!(
            routh_position_loop(0.5, 0.0),
            Err(Error::OutOfRange { name: "tau_s", .. })
        ));
        assert!(matches!(
            routh_position_loop(0.5, -1.0),
            Err(Error::OutOfRange { name: "tau_s", .. })
        ));
    }

    #[test]
    fn routh_agrees_with_the_roots() {
        // s³ + 3.7595 s² + 2.3957 s + 0.6699 (seed 004 Eq. 21): stable.
        let col = routh_first_column(&[1.0, 3.7595, 2.3957, 0.6699]);
        assert!(col.iter().all(|&c| c > 0.0));
        let unstable = [1.0, 1.0, 1.0, 5.0];
        assert!(routh_first_column(&unstable).iter().any(|&c| c < 0.0));
        assert!(roots(&unstable).iter().any(|r| r.re > 0.0));
    }

    #[test]
    fn biproper_step_response_has_its_direct_term() {
        // (s + 2)/(s + 1): y(t) = 2 − e^(−t), which starts at the direct term 1.
        let g = ContinuousTf::new(vec![1.0, 2.0], vec![1.0, 1.0]).unwrap();
        let dt = 1e-3;
        let y = g.step_response(dt, 5.0).unwrap();
        assert_eq!(y.len(), 5001);
        for (k, v) in y.iter().enumerate().step_by(250) {
            let t = k as f64 * dt;
            assert!((v - (2.0 - (-t).exp())).abs() < 1e-9, "t {t}: {v}");
        }
    }
}
