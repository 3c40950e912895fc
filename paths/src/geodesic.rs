//! Fibre paths on an analytic mandrel: the helix on a cylinder and the geodesic on a swept tube,
//! traced from a start point at a wind angle (seed 001 §2.1, §6.4).
//!
//! The geodesic solves `ü^k + Γ^k_ij u̇^i u̇^j = 0` in the tube's `(u, v)` parameters with
//! Christoffel symbols from the analytic surface derivatives, `Γ^k_ij = g^kl X_ij·X_l`, by the
//! classical fourth-order Runge–Kutta method in arc length. On a straight tube the exact helix
//! is available too; the tests use it to measure the integrator's error.
//!
//! # Ends
//! A path runs from one end of the mandrel to the other. [`trace`] stops on the tube's own end
//! caps, the sections perpendicular to the spine at its first and last knots (how the straight
//! and tilted cylinders of seed 001 §6.4 are cut). [`trace_between_end_planes`] stops on the
//! horizontal planes through the spine's end points instead, `z = u_min` and `z = u_max`: how a
//! mandrel made along a measured spine is cut (the S-bend is 0–350 mm long with horizontal end
//! faces). Near a tilted end a horizontal plane cuts the tube beyond the last knot on one side;
//! there the spine is its end piece's cubic continued, the curve [`crate::Spine::eval`] gives.

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

/// Where a traced path stops (see the module documentation, "Ends").
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ends {
    /// The end sections perpendicular to the spine at its first and last knots.
    Square,
    /// The horizontal planes `z = u_min` and `z = u_max` through the spine's end points.
    Horizontal,
}

/// The height `u` at which the surface curve `v = const` meets the horizontal plane `z = plane`,
/// near `guess`: `z(u) = u − r g cos v / √(1 + g²)` with `g` the spine slope, by Newton's method.
fn plane_height(tube: &Tube, v: f64, plane: f64, guess: f64) -> f64 {
    let mut u = guess;
    for _ in 0..50 {
        let d = tube.derivatives(u, v);
        let z = tube.point(u, v).z;
        let step = (z - plane) / d.xu.z;
        u -= step;
        if step.abs() < 1e-13 {
            break;
        }
    }
    u
}

fn start_height(tube: &Tube, start: &PathStart, ends: Ends) -> f64 {
    let u0 = match start.direction {
        Direction::Down => tube.u_max(),
        Direction::Up => tube.u_min(),
    };
    match ends {
        Ends::Square => u0,
        Ends::Horizontal => plane_height(tube, start.angle_rad, u0, u0),
    }
}

fn start_state(tube: &Tube, start: &PathStart, ends: Ends) -> [f64; 4] {
    let u0 = start_height(tube, start, ends);
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
    let [u0, v0, du, dv] = start_state(tube, start, Ends::Square);
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

/// Traces the geodesic from `start` until it reaches the mandrel's far end cap (its end section
/// perpendicular to the spine, [`Ends::Square`]), with classical RK4 steps of at most about
/// `step_mm` of arc length.
///
/// The path is integrated with the height `u` as the parameter, one spine interval at a time with
/// steps that end exactly on every knot (see `geodesic_rhs`), so the error falls as `step⁴`: on
/// the S-bend at 45° the observed order between 2, 1 and 0.5 mm steps is above 3.5 (test
/// `sbend_geodesic_converges_at_fourth_order`). A path that turns back along the spine (winds
/// within 0.5° of a circle) is an error, and so is one that would take more than
/// [`limits::MAX_PATH_SAMPLES`] steps.
pub fn trace(tube: &Tube, start: &PathStart, step_mm: f64) -> Result<SurfacePath, Error> {
    trace_to(tube, start, step_mm, Ends::Square)
}

/// [`trace`] from and to the horizontal end planes `z = u_min` and `z = u_max`
/// ([`Ends::Horizontal`]): the path starts where the start angle's surface line meets the start
/// plane and stops where it meets the far plane, found within the last step to 1e-12 mm.
pub fn trace_between_end_planes(
    tube: &Tube,
    start: &PathStart,
    step_mm: f64,
) -> Result<SurfacePath, Error> {
    trace_to(tube, start, step_mm, Ends::Horizontal)
}

/// [`trace`] or [`trace_between_end_planes`], as `ends` says.
pub fn trace_to(
    tube: &Tube,
    start: &PathStart,
    step_mm: f64,
    ends: Ends,
) -> Result<SurfacePath, Error> {
    start.validate()?;
    if step_mm.is_nan() || step_mm <= 0.0 {
        return Err(Error::OutOfRange {
            name: "step_mm",
            value: step_mm,
            expected: "must be > 0",
        });
    }
    let sign = start.direction.sign();
    let [u0, v0, du0, dv0] = start_state(tube, start, ends);
    let mut y = [v0, dv0 / du0, 0.0];
    let mut u = u0;
    let mut samples = vec![sample(tube, u, y, sign)?];
    let knots = tube.spine().knot_heights_mm();
    let pieces = knots.len() - 1;
    // The far end plane, and how far beyond the last knot a horizontal cut can reach: the tube's
    // section leans by at most its radius.
    let (plane, reach) = match start.direction {
        Direction::Up => (tube.u_max(), tube.radius_mm()),
        Direction::Down => (tube.u_min(), -tube.radius_mm()),
    };
    // Spine intervals in travel order: (piece index, height at its far end). With horizontal
    // ends the first and last pieces are continued beyond their knots as far as a cut can reach,
    // and an interval the path starts beyond is skipped.
    let mut intervals: Vec<(usize, f64)> = match start.direction {
        Direction::Up => (0..pieces).map(|i| (i, knots[i + 1])).collect(),
        Direction::Down => (0..pieces).rev().map(|i| (i, knots[i])).collect(),
    };
    if ends == Ends::Horizontal {
        if let Some(last) = intervals.last_mut() {
            last.1 = plane + reach;
        }
        intervals.retain(|&(_, end)| (end - u) * sign > 0.0);
    }
    // Signed height above the far plane, positive before it is reached.
    let before_plane = |u: f64, v: f64| (plane - tube.point(u, v).z) * sign;
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
            let next = rk4_step(tube, piece, u, y, next_u - u);
            if ends == Ends::Horizontal
                && (next_u - plane).abs() <= tube.radius_mm() + (next_u - u).abs()
                && before_plane(next_u, next[0]) <= 0.0
            {
                // The far plane lies within this step: find where by bisection on the step
                // length, each trial one RK4 step from the step's start.
                let (mut lo, mut hi) = (0.0, next_u - u);
                for _ in 0..200 {
                    let mid = 0.5 * (lo + hi);
                    let trial = rk4_step(tube, piece, u, y, mid);
                    if before_plane(u + mid, trial[0]) > 0.0 {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                    if (hi - lo).abs() < 1e-13 {
                        break;
                    }
                }
                let h = 0.5 * (lo + hi);
                let last = rk4_step(tube, piece, u, y, h);
                samples.push(sample(tube, u + h, last, sign)?);
                return Ok(SurfacePath { samples });
            }
            y = next;
            u = next_u;
            samples.push(sample(tube, u, y, sign)?);
        }
    }
    if ends == Ends::Horizontal {
        // The cut's reach bounds every crossing; not meeting the plane means the path left.
        return Err(Error::PathTurnedBack { height_mm: u });
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
    fn sbend_geodesic_reaches_both_ends_and_its_arc_length_is_the_curve_length() {
        let tube = sbend();
        for dir in [Direction::Down, Direction::Up] {
            let st = sbend_start(dir);
            let path = trace(&tube, &st, 0.25).unwrap();
            let last = path.samples.last().unwrap();
            let end = if dir == Direction::Down { 0.0 } else { 350.0 };
            assert_abs_diff_eq!(last.u, end, epsilon = 1e-9);
            // The integrated arc length against the curve itself: between samples 0.25 mm apart
            // the chord of a curve of curvature κ is shorter than the arc by κ² Δs³ / 24, and
            // κ ≤ 1/(r (1 − r κ_spine)) < 2/r here; a wrong arc length (a missing or doubled
            // factor in s') is off by a share of Δs.
            let bound = |ds: f64| ds.powi(3) / 24.0 * (2.0 / tube.radius_mm()).powi(2) + 1e-12;
            for w in path.samples.windows(2) {
                let ds = w[1].s_mm - w[0].s_mm;
                let chord = (tube.point(w[1].u, w[1].v) - tube.point(w[0].u, w[0].v)).norm();
                assert!(ds > 0.0 && ds < 0.5, "{ds}");
                assert!(
                    (-1e-12..=bound(ds)).contains(&(ds - chord)),
                    "arc {ds} vs chord {chord} at u = {}",
                    w[0].u
                );
            }
            // The stored derivatives against three-point differences of the samples: O(Δs²)
            // inside a spine piece, O(Δs) at a knot, where the path's second derivative jumps with
            // the spine's third.
            for w in path.samples.windows(3) {
                let (h1, h2) = (w[1].s_mm - w[0].s_mm, w[2].s_mm - w[1].s_mm);
                let d = |f0: f64, f1: f64, f2: f64| {
                    (h1 * h1 * f2 - h2 * h2 * f0 + (h2 * h2 - h1 * h1) * f1) / (h1 * h2 * (h1 + h2))
                };
                let at_knot = tube.spine().knot_heights_mm().contains(&w[1].u);
                let tolerance = if at_knot { 5e-3 } else { 1e-4 };
                assert_abs_diff_eq!(d(w[0].u, w[1].u, w[2].u), w[1].du, epsilon = tolerance);
                assert_abs_diff_eq!(d(w[0].v, w[1].v, w[2].v), w[1].dv, epsilon = tolerance);
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

    /// The far end of the path traced at steps about `h`, `h/2` and `h/4`, and the observed order
    /// of convergence from the two differences (Richardson), with the effective step ratio (the
    /// tracer rounds each interval's step count up, so the ratio is near but not exactly 2).
    fn observed_order(tube: &Tube, st: &PathStart, ends: Ends, h: f64) -> (f64, f64) {
        let run = |step: f64| {
            let path = trace_to(tube, st, step, ends).unwrap();
            let last = *path.samples.last().unwrap();
            let mean_step = path.length_mm() / (path.samples.len() - 1) as f64;
            (tube.point(last.u, last.v), mean_step)
        };
        let (e1, h1) = run(h);
        let (e2, h2) = run(h / 2.0);
        let (e3, h3) = run(h / 4.0);
        let (d12, d23) = ((e1 - e2).norm(), (e2 - e3).norm());
        let ratio = ((h1 / h2) * (h2 / h3)).sqrt();
        let order = (d12 / d23).ln() / ratio.ln();
        // Richardson: the error left in the finest run.
        (order, d23 / (ratio.powf(order) - 1.0))
    }

    #[test]
    fn sbend_geodesic_converges_at_fourth_order() {
        // Steps end on every spine knot, where the tube's X_uu jumps, so each RK4 step lies on one
        // polynomial piece. (Stepping across the knots in arc length lost the order.)
        let tube = sbend();
        for ends in [Ends::Square, Ends::Horizontal] {
            for dir in [Direction::Down, Direction::Up] {
                let (order, error_mm) = observed_order(&tube, &sbend_start(dir), ends, 4.0);
                assert!(order >= 3.5, "{ends:?} {dir:?}: observed order {order}");
                assert!(
                    error_mm < 1e-5,
                    "{ends:?} {dir:?}: {error_mm} mm left at 1 mm steps"
                );
            }
        }
    }

    #[test]
    fn sbend_paths_end_on_the_horizontal_end_planes() {
        let tube = sbend();
        let r = tube.radius_mm();
        for dir in [Direction::Down, Direction::Up] {
            for start_deg in [0.0, 45.0, 90.0, 180.0, 270.0] {
                let st = PathStart {
                    angle_rad: f64::to_radians(start_deg),
                    ..sbend_start(dir)
                };
                let (from, to) = match dir {
                    Direction::Down => (350.0, 0.0),
                    Direction::Up => (0.0, 350.0),
                };
                let square = trace(&tube, &st, 0.25).unwrap();
                let cut = trace_between_end_planes(&tube, &st, 0.25).unwrap();
                let z = |s: &Sample| tube.point(s.u, s.v).z;
                let (first, last) = (&cut.samples[0], cut.samples.last().unwrap());
                assert_abs_diff_eq!(z(first), from, epsilon = 1e-9);
                assert_abs_diff_eq!(z(last), to, epsilon = 1e-9);
                for s in &cut.samples {
                    assert!((-1e-9..=350.0 + 1e-9).contains(&z(s)), "z = {}", z(s));
                }
                // The square-cut path ends on the end section instead: up to r·|slope| away.
                let lean = (z(square.samples.last().unwrap()) - to).abs();
                assert!(lean < r, "{lean}");
                // Where the two agree on the start (start angle 90° or 270°: the section's
                // lowest and highest points lie on the spine's side), the paths coincide until
                // the cut one stops.
                if start_deg == 90.0 {
                    assert_abs_diff_eq!(first.u, square.samples[0].u, epsilon = 1e-12);
                    let s = cut.length_mm().min(square.length_mm());
                    let (a, b) = (cut.at(s * 0.5), square.at(s * 0.5));
                    assert!((tube.point(a.0, a.1) - tube.point(b.0, b.1)).norm() < 1e-9);
                }
            }
        }
        // The 45° paths of the S-bend examples: the square cut ends 6.3 mm below the bottom and
        // 4.7 mm above the top.
        let end_z = |dir| {
            let p = trace(&tube, &sbend_start(dir), 0.25).unwrap();
            let last = *p.samples.last().unwrap();
            tube.point(last.u, last.v).z
        };
        assert!(
            (end_z(Direction::Down) + 6.3).abs() < 0.05,
            "{}",
            end_z(Direction::Down)
        );
        assert!(
            (end_z(Direction::Up) - 354.7).abs() < 0.05,
            "{}",
            end_z(Direction::Up)
        );
    }

    #[test]
    fn absurdly_long_paths_are_refused_before_sampling() {
        let long = Tube::cylinder(63.5, 1e9, 0.0, 0.0).unwrap();
        assert!(matches!(
            helix(&long, &start(Direction::Up), 1.0),
            Err(Error::OverLimit { .. })
        ));
        assert!(matches!(
            trace(&long, &start(Direction::Up), 1.0),
            Err(Error::OverLimit { .. })
        ));
        // Just inside the limit: a 178 mm cylinder at steps that need MAX_PATH_SAMPLES or fewer.
        let most = limits::MAX_PATH_SAMPLES as f64;
        let tube = Tube::cylinder(63.5, 178.0, 0.0, 0.0).unwrap();
        let length = 178.0 / 48.3f64.to_radians().cos();
        assert!(helix(&tube, &start(Direction::Up), length / most * 1.001).is_ok());
        assert!(helix(&tube, &start(Direction::Up), length / most * 0.99).is_err());
        let sbend = sbend();
        assert!(trace(&sbend, &sbend_start(Direction::Up), 2e-3).is_ok());
        assert!(matches!(
            trace(&sbend, &sbend_start(Direction::Up), 5e-4),
            Err(Error::OverLimit { .. })
        ));
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
