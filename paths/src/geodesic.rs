//! Fibre paths on an analytic mandrel: the helix on a cylinder and the geodesic on a swept tube,
//! traced from a start point at a wind angle (seed 001 §2.1, §6.4).
//!
//! The geodesic solves `ü^k + Γ^k_ij u̇^i u̇^j = 0` in the tube's `(u, v)` parameters with
//! Christoffel symbols from the analytic surface derivatives, `Γ^k_ij = g^kl X_ij·X_l`, by the
//! classical fourth-order Runge–Kutta method in arc length. On a straight tube the exact helix
//! is available too; the tests use it to measure the integrator's error.

use crate::limits;
use std::f64::consts::FRAC_PI_2;

use crate::{Error, Tube};

/// Which way along the mandrel a path is wound.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Direction {
    /// From the top (highest spine knot) down.
    Down,
    /// From the bottom up.
    Up,
}

impl Direction {
    fn sign(self) -> f64 {
        match self {
            Direction::Down => -1.0,
            Direction::Up => 1.0,
        }
    }
}

/// Where and how a fibre path starts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathStart {
    /// Angle around the spine at the start, from the spine normal `N` (mandrel `+x` on a vertical
    /// spine), counter-clockwise seen from above.
    pub angle_rad: f64,
    /// Angle between the fibre and the spine, in (0, π/2). The fibre always turns counter-clockwise
    /// around the spine (`v` increases), so a down pass followed by an up pass is one circuit.
    pub wind_angle_rad: f64,
    /// Down from the top end or up from the bottom end.
    pub direction: Direction,
}

impl PathStart {
    fn validate(&self) -> Result<(), Error> {
        if !(self.wind_angle_rad > 0.0 && self.wind_angle_rad < FRAC_PI_2) {
            return Err(Error::OutOfRange {
                name: "wind_angle_deg",
                value: self.wind_angle_rad.to_degrees(),
                expected: "must lie in (0°, 90°)",
            });
        }
        if !self.angle_rad.is_finite() {
            return Err(Error::OutOfRange {
                name: "start_angle_deg",
                value: self.angle_rad,
                expected: "must be finite",
            });
        }
        Ok(())
    }
}

/// One sample of a path: arc length, surface parameters and their arc-length derivatives.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// Arc length from the start, mm.
    pub s_mm: f64,
    /// Spine height parameter.
    pub u: f64,
    /// Angle around the spine, rad.
    pub v: f64,
    /// du/ds.
    pub du: f64,
    /// dv/ds.
    pub dv: f64,
}

/// A fibre path on a tube, as arc-length samples of its surface parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct SurfacePath {
    /// Samples in order, the first at `s = 0`, the last at the mandrel's far end.
    pub samples: Vec<Sample>,
}

impl SurfacePath {
    /// Total arc length, mm.
    pub fn length_mm(&self) -> f64 {
        self.samples.last().map_or(0.0, |s| s.s_mm)
    }

    /// `(u, v)` at arc length `s_mm` by cubic Hermite interpolation between samples (exact for a
    /// helix, fourth-order accurate for a geodesic).
    pub fn at(&self, s_mm: f64) -> (f64, f64) {
        let samples = &self.samples;
        let i = samples
            .partition_point(|x| x.s_mm <= s_mm)
            .clamp(1, samples.len() - 1);
        let (a, b) = (&samples[i - 1], &samples[i]);
        let h = b.s_mm - a.s_mm;
        if h <= 0.0 {
            return (a.u, a.v);
        }
        let t = ((s_mm - a.s_mm) / h).clamp(0.0, 1.0);
        let hermite = |p0: f64, m0: f64, p1: f64, m1: f64| {
            let t2 = t * t;
            let t3 = t2 * t;
            (2.0 * t3 - 3.0 * t2 + 1.0) * p0
                + (t3 - 2.0 * t2 + t) * h * m0
                + (-2.0 * t3 + 3.0 * t2) * p1
                + (t3 - t2) * h * m1
        };
        (hermite(a.u, a.du, b.u, b.du), hermite(a.v, a.dv, b.v, b.dv))
    }
}

fn start_state(tube: &Tube, start: &PathStart) -> [f64; 4] {
    let u0 = match start.direction {
        Direction::Down => tube.u_max(),
        Direction::Up => tube.u_min(),
    };
    let d = tube.derivatives(u0, start.angle_rad);
    let (sin_a, cos_a) = start.wind_angle_rad.sin_cos();
    [
        u0,
        start.angle_rad,
        start.direction.sign() * cos_a / d.xu.norm(),
        sin_a / d.xv.norm(),
    ]
}

/// The exact helix on a straight tube (a cylinder): the geodesic at a constant wind angle.
/// Samples every `step_mm` of arc length, the last exactly at the far end.
pub fn helix(tube: &Tube, start: &PathStart, step_mm: f64) -> Result<SurfacePath, Error> {
    start.validate()?;
    if !tube.spine().is_straight() {
        return Err(Error::OutOfRange {
            name: "spine",
            value: 0.0,
            expected: "a helix needs a straight spine (use the geodesic tracer)",
        });
    }
    let [u0, v0, du, dv] = start_state(tube, start);
    let length = (tube.u_max() - tube.u_min()) / du.abs();
    limits::at_most("path length_mm", length, limits::MAX_PATH_LENGTH_MM)?;
    let n = (length / step_mm).ceil().max(1.0);
    limits::at_most("path samples", n, limits::MAX_PATH_SAMPLES as f64)?;
    let n = n as usize;
    let samples = (0..=n)
        .map(|i| {
            let s = length * i as f64 / n as f64;
            Sample {
                s_mm: s,
                u: u0 + du * s,
                v: v0 + dv * s,
                du,
                dv,
            }
        })
        .collect();
    Ok(SurfacePath { samples })
}

/// The geodesic equation with the spine height `u` as the parameter, for a path `v(u)` that keeps
/// moving along the spine: `v'' = −Γ^v(x', x') + Γ^u(x', x') v'` with `x' = (1, v')`, and arc
/// length `s' = |X_u + X_v v'|`. State `[v, v', s]`.
///
/// Height is the natural parameter here because the spine is a cubic spline: the tube's second
/// derivatives contain the spine's third derivative, which jumps at every knot. Stepping in height
/// lets every Runge–Kutta step lie inside one polynomial piece, where the right-hand side is smooth,
/// so the integrator keeps its fourth order (stepping in arc length across the jumps loses it).
fn geodesic_rhs(tube: &Tube, piece: usize, u: f64, y: [f64; 3]) -> [f64; 3] {
    let [v, dv, _] = y;
    let d = tube.derivatives_on_piece(piece, u, v);
    let e = d.xu.dot(&d.xu);
    let f = d.xu.dot(&d.xv);
    let g = d.xv.dot(&d.xv);
    let acc = d.xuu + d.xuv * (2.0 * dv) + d.xvv * (dv * dv);
    let (pu, pv) = (d.xu.dot(&acc), d.xv.dot(&acc));
    let det = e * g - f * f;
    let gamma_u = (g * pu - f * pv) / det;
    let gamma_v = (e * pv - f * pu) / det;
    let speed = (e + 2.0 * f * dv + g * dv * dv).sqrt();
    [dv, -gamma_v + gamma_u * dv, speed]
}

fn rk4_step(tube: &Tube, piece: usize, u: f64, y: [f64; 3], h: f64) -> [f64; 3] {
    let add =
        |a: [f64; 3], k: [f64; 3], s: f64| [a[0] + k[0] * s, a[1] + k[1] * s, a[2] + k[2] * s];
    let k1 = geodesic_rhs(tube, piece, u, y);
    let k2 = geodesic_rhs(tube, piece, u + h / 2.0, add(y, k1, h / 2.0));
    let k3 = geodesic_rhs(tube, piece, u + h / 2.0, add(y, k2, h / 2.0));
    let k4 = geodesic_rhs(tube, piece, u + h, add(y, k3, h));
    let mut out = y;
    for i in 0..3 {
        out[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
    }
    out
}

/// The steepest a path may wind before the tracer calls it turned back: the fibre within 0.5° of
/// a circumferential circle.
const MAX_WIND_ANGLE_RAD: f64 = 89.5 * std::f64::consts::PI / 180.0;

/// Converts the height-parameter state at `u` into an arc-length sample. `y[2]` is `∫ s' du`,
/// negative on a downward path, hence the `sign`.
fn sample(tube: &Tube, u: f64, y: [f64; 3], sign: f64) -> Result<Sample, Error> {
    let [v, dv_du, s] = y;
    let d = tube.derivatives(u, v);
    let speed = (d.xu + d.xv * dv_du).norm();
    // cos of the angle between the fibre and the spine direction X_u.
    let cos_wind = d.xu.norm() / speed;
    if !(cos_wind.is_finite() && cos_wind.acos() < MAX_WIND_ANGLE_RAD) {
        return Err(Error::PathTurnedBack { height_mm: u });
    }
    Ok(Sample {
        s_mm: sign * s,
        u,
        v,
        du: sign / speed,
        dv: sign * dv_du / speed,
    })
}

/// Traces the geodesic from `start` until it reaches the mandrel's far end, with classical RK4
/// steps of at most about `step_mm` of arc length.
///
/// The path is integrated with the height `u` as the parameter, one spine interval at a time with
/// steps that end exactly on every knot (see `geodesic_rhs`), so the error falls as `step⁴`: on
/// the S-bend at 45° the far end moves by less than 1 µm between 0.25 mm and 0.05 mm steps (test
/// `sbend_geodesic_converges_at_fourth_order`). A path that turns back along the spine (winds within
/// 0.5° of a circle) is an error.
pub fn trace(tube: &Tube, start: &PathStart, step_mm: f64) -> Result<SurfacePath, Error> {
    start.validate()?;
    if step_mm.is_nan() || step_mm <= 0.0 {
        return Err(Error::OutOfRange {
            name: "step_mm",
            value: step_mm,
            expected: "must be > 0",
        });
    }
    let sign = start.direction.sign();
    let [u0, v0, du0, dv0] = start_state(tube, start);
    let mut y = [v0, dv0 / du0, 0.0];
    let mut u = u0;
    let mut samples = vec![sample(tube, u, y, sign)?];
    let knots = tube.spine().knot_heights_mm();
    let pieces = knots.len() - 1;
    // Spine intervals in travel order: (piece index, height at its far end).
    let intervals: Vec<(usize, f64)> = match start.direction {
        Direction::Up => (0..pieces).map(|i| (i, knots[i + 1])).collect(),
        Direction::Down => (0..pieces).rev().map(|i| (i, knots[i])).collect(),
    };
    for (piece, end) in intervals {
        // Arc length per unit height at the interval's start sets the number of steps.
        let ds_du = geodesic_rhs(tube, piece, u, y)[2];
        let span = end - u;
        let n = (span.abs() * ds_du / step_mm).ceil().max(1.0);
        limits::at_most(
            "path samples",
            samples.len() as f64 + n,
            limits::MAX_PATH_SAMPLES as f64,
        )?;
        let n = n as usize;
        let interval_start = u;
        for k in 1..=n {
            let next_u = if k == n {
                end
            } else {
                interval_start + span * k as f64 / n as f64
            };
            y = rk4_step(tube, piece, u, y, next_u - u);
            u = next_u;
            samples.push(sample(tube, u, y, sign)?);
        }
    }
    Ok(SurfacePath { samples })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spine::{SBEND_SMOOTHING_MM, SBEND_TABLE_6_1_MM, Spine};
    use approx::assert_abs_diff_eq;
    use std::f64::consts::{PI, TAU};

    fn start(direction: Direction) -> PathStart {
        PathStart {
            angle_rad: 0.0,
            wind_angle_rad: 48.3f64.to_radians(),
            direction,
        }
    }

    #[test]
    fn cylinder_helix_at_48_3_deg_turns_once_per_178_mm_pass() {
        // Seed 001 §6.4: tan 48.3° · 178 / 31.75 ≈ 2π.
        let tube = Tube::cylinder(63.5, 178.0, 0.0, 0.0).unwrap();
        for dir in [Direction::Down, Direction::Up] {
            let path = helix(&tube, &start(dir), 1.0).unwrap();
            let last = path.samples.last().unwrap();
            let turns = (last.v - path.samples[0].v) / TAU;
            assert!((turns - 1.0).abs() < 0.01, "{turns} turns");
        }
    }

    #[test]
    fn geodesic_tracer_reproduces_the_helix_on_cylinders() {
        let r = 31.75;
        for (bottom, top) in [(0.0, 0.0), (2.0 * r, 2.0 * r), (r, 3.0 * r)] {
            let tube = Tube::cylinder(63.5, 178.0, bottom, top).unwrap();
            for dir in [Direction::Down, Direction::Up] {
                let exact = helix(&tube, &start(dir), 1.0).unwrap();
                let traced = trace(&tube, &start(dir), 0.5).unwrap();
                assert_abs_diff_eq!(traced.length_mm(), exact.length_mm(), epsilon = 1e-6);
                for k in 0..=20 {
                    let s = exact.length_mm() * k as f64 / 20.0;
                    let (ue, ve) = exact.at(s);
                    let (ut, vt) = traced.at(s);
                    let gap = (tube.point(ue, ve) - tube.point(ut, vt)).norm();
                    assert!(gap < 1e-6, "gap {gap} mm at s = {s}");
                }
            }
        }
    }

    /// The S-bend of seed 001 §6.4: Table 6.1's spine, 57 mm diameter.
    fn sbend() -> Tube {
        Tube::new(
            Spine::smoothing(&SBEND_TABLE_6_1_MM, SBEND_SMOOTHING_MM).unwrap(),
            28.5,
        )
        .unwrap()
    }

    /// 45° to the spine, starting at 90° around the circumference.
    fn sbend_start(direction: Direction) -> PathStart {
        PathStart {
            angle_rad: PI / 2.0,
            wind_angle_rad: PI / 4.0,
            direction,
        }
    }

    #[test]
    fn sbend_geodesic_reaches_both_ends_and_stays_unit_speed() {
        let tube = sbend();
        for dir in [Direction::Down, Direction::Up] {
            let st = sbend_start(dir);
            let path = trace(&tube, &st, 0.25).unwrap();
            let last = path.samples.last().unwrap();
            let end = if dir == Direction::Down { 0.0 } else { 350.0 };
            assert_abs_diff_eq!(last.u, end, epsilon = 1e-9);
            for s in &path.samples {
                let d = tube.derivatives(s.u, s.v);
                assert_abs_diff_eq!((d.xu * s.du + d.xv * s.dv).norm(), 1.0, epsilon = 1e-9);
            }
            // Geodesic: the path's curvature vector is normal to the surface (no geodesic curvature).
            let mid = path.length_mm() / 2.0;
            let h = 0.25;
            let p = |s: f64| {
                let (u, v) = path.at(s);
                tube.point(u, v)
            };
            let acc = (p(mid + h).coords - p(mid).coords * 2.0 + p(mid - h).coords) / (h * h);
            let (u, v) = path.at(mid);
            let n = tube.normal(u, v);
            let tangential = (acc - n * acc.dot(&n)).norm();
            assert!(
                tangential < 1e-3 * acc.norm().max(1e-3),
                "kg residual {tangential}"
            );
        }
    }

    #[test]
    fn sbend_geodesic_converges_at_fourth_order() {
        // Steps end on every spine knot, where the tube's X_uu jumps; the far end then moves by
        // far less than a micrometre from 1 mm to 0.05 mm steps. (Stepping across the knots in arc
        // length left millimetres of error at 0.25 mm steps.)
        let tube = sbend();
        for dir in [Direction::Down, Direction::Up] {
            let st = sbend_start(dir);
            let end = |step: f64| {
                let path = trace(&tube, &st, step).unwrap();
                let last = *path.samples.last().unwrap();
                (tube.point(last.u, last.v), path.length_mm())
            };
            let (fine, fine_len) = end(0.05);
            for step in [1.0, 0.25] {
                let (coarse, coarse_len) = end(step);
                let gap = (coarse - fine).norm();
                assert!(gap < 1e-4, "step {step}: far end moves {gap} mm");
                assert_abs_diff_eq!(coarse_len, fine_len, epsilon = 1e-4);
            }
        }
    }

    #[test]
    fn rejects_wind_angles_outside_the_open_quarter_turn() {
        let tube = Tube::cylinder(63.5, 178.0, 0.0, 0.0).unwrap();
        for deg in [0.0, 90.0, -10.0, 120.0] {
            let st = PathStart {
                wind_angle_rad: f64::to_radians(deg),
                ..start(Direction::Up)
            };
            assert!(matches!(
                trace(&tube, &st, 1.0),
                Err(Error::OutOfRange { .. })
            ));
        }
    }
}
