//! Off-line trajectory generation for the lathe winder (seed 000 §8.3–8.8, §9.5–9.6).
//!
//! The given points (absolute, in encoder counts per axis) become a table of desired positions,
//! one per interrupt ("the desired velocities of all the axes at each interrupt are calculated and
//! stored in the form of arrays or tables", §8.3). The feed rate is "the velocity of the fastest
//! axis specified in terms of encoder counts per interrupt" (glossary); every axis also has its own
//! velocity and acceleration limits.
//!
//! - [`Interpolation::PointToPoint`] (§8.4 a): each segment starts and ends at rest, with a
//!   trapezoidal velocity profile inside the axis limits; every point is met exactly.
//! - [`Interpolation::Linear`] (§8.4 b, §9.5): constant velocity per segment, travel time
//!   `max |Δ| / F`; the velocity steps at every point.
//! - [`Interpolation::ParabolicBlend`] (§8.5): the linear profile with every velocity step
//!   replaced by a constant-acceleration ramp (parabolic position) inside the acceleration limits.
//! - [`Interpolation::BSpline`] (§8.7–8.8, §9.6): the uniform cubic B-spline of the points with
//!   tripled ends, sampled at `N` knot-points per segment, run at a constant time per unit of the
//!   spline parameter (so velocity and acceleration stay continuous) and slowed where an axis would
//!   exceed its velocity limit (`docs/seed-readings.md` R000-7: "uniform-t with clamp").
//!
//! Times are in interrupts; a segment's time may be fractional, and the desired positions are the
//! planned path sampled at whole interrupts, so the last one is exactly the last point.
//! [`Trajectory::deviations`] reports how far the planned path passes from each given point, with
//! the thesis's remedies (§8.8, §10.7, Ch. 11).

use nalgebra::SVector;

use crate::Error;
use crate::spline::UniformCubic;

/// The thesis's interrupt rate, Hz (§6.7: "A hardware clock of 200 Hz").
pub const DEFAULT_INTERRUPT_HZ: f64 = 200.0;
/// The most desired positions one trajectory may hold (about 5.5 h at 200 Hz).
pub const MAX_SETPOINTS: usize = 4_000_000;

/// How the path between the given points is generated.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Interpolation {
    /// Stop at every point (§8.4 a).
    PointToPoint,
    /// Constant velocity per segment, continuous path (§8.4 b, §9.5).
    Linear,
    /// Linear with parabolic blends at the points (§8.5).
    ParabolicBlend,
    /// Uniform cubic B-spline with `knots_per_segment` knot-points per segment (§9.6).
    BSpline {
        /// `N`, intervals per segment (FW-CNC.PAR's "number of knot points").
        knots_per_segment: usize,
    },
}

/// One axis's limits, in encoder counts per interrupt (and per interrupt²).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxisLimits {
    /// Highest speed, counts per interrupt.
    pub max_velocity: f64,
    /// Highest acceleration, counts per interrupt².
    pub max_acceleration: f64,
}

/// The planner's settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Planner<const D: usize> {
    /// Interrupts per second.
    pub interrupt_hz: f64,
    /// Feed rate: the fastest axis's counts per interrupt.
    pub feed: f64,
    /// Per-axis limits.
    pub limits: [AxisLimits; D],
    /// B-spline only: interrupts per unit of spline parameter before the velocity clamp. `None`
    /// takes the mean, over the spline's segments, of the dominant-axis travel divided by the
    /// feed, so a typical segment runs at about the feed rate.
    pub spline_interrupts_per_segment: Option<f64>,
}

/// A planned trajectory: the desired position at every interrupt.
#[derive(Debug, Clone, PartialEq)]
pub struct Trajectory<const D: usize> {
    /// Interrupts per second.
    pub interrupt_hz: f64,
    /// Desired positions, counts; `setpoints[0]` is the first given point, the last is the last.
    pub setpoints: Vec<SVector<f64, D>>,
    /// The given points the trajectory was planned from.
    pub points: Vec<SVector<f64, D>>,
    /// The geometric path (knot-points for the B-spline, the blended path for the parabolic
    /// blends, the points themselves otherwise), for the deviation report.
    pub path: Vec<SVector<f64, D>>,
}

/// Peak magnitudes per axis of velocity, acceleration and jerk, per second.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Peaks<const D: usize> {
    /// counts/s.
    pub velocity: SVector<f64, D>,
    /// counts/s².
    pub acceleration: SVector<f64, D>,
    /// counts/s³.
    pub jerk: SVector<f64, D>,
}

/// Peak |velocity|, |acceleration| and |jerk| per axis of positions sampled at `rate_hz`, by
/// backward differences (used on planned and on measured positions alike).
#[allow(clippy::needless_range_loop)]
pub fn peaks<const D: usize>(samples: &[SVector<f64, D>], rate_hz: f64) -> Peaks<D> {
    let mut out = Peaks {
        velocity: SVector::zeros(),
        acceleration: SVector::zeros(),
        jerk: SVector::zeros(),
    };
    let h = [rate_hz, rate_hz * rate_hz, rate_hz * rate_hz * rate_hz];
    for i in 1..samples.len() {
        for axis in 0..D {
            let x = |k: usize| samples[k][axis];
            let v = x(i) - x(i - 1);
            out.velocity[axis] = out.velocity[axis].max(v.abs() * h[0]);
            if i >= 2 {
                let a = v - (x(i - 1) - x(i - 2));
                out.acceleration[axis] = out.acceleration[axis].max(a.abs() * h[1]);
            }
            if i >= 3 {
                let j = x(i) - 3.0 * x(i - 1) + 3.0 * x(i - 2) - x(i - 3);
                out.jerk[axis] = out.jerk[axis].max(j.abs() * h[2]);
            }
        }
    }
    out
}

/// A way to bring the path closer to a given point (§8.8, §10.7, Ch. 11; `docs/seed-readings.md` R000-8).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Remedy {
    /// Repeat the point twice more (three coincident points): the B-spline then passes through
    /// it, at rest.
    TriplePoint,
    /// Add the midpoints of the chords on either side: the point's second difference, and with
    /// it the node residual `(P_{i−1} − 2P_i + P_{i+1})/6`, halves.
    InsertMidpoints,
    /// Run this stretch with linear interpolation instead.
    UseLinear,
}

/// The closest approach of the planned path to one given point.
#[derive(Debug, Clone, PartialEq)]
pub struct Deviation<const D: usize> {
    /// Index of the given point.
    pub index: usize,
    /// Path point minus given point at the closest approach, counts per axis.
    pub offset: SVector<f64, D>,
    /// Whether some axis is beyond its tolerance.
    pub exceeds: bool,
    /// What would bring the path closer (empty when within tolerance).
    pub remedies: Vec<Remedy>,
}

fn check_points<const D: usize>(points: &[SVector<f64, D>]) -> Result<(), Error> {
    if points.len() < 2 {
        return Err(Error::OutOfRange {
            name: "point_count",
            value: points.len() as f64,
            expected: "must be ≥ 2 (a start and a target)",
        });
    }
    if let Some(i) = points.iter().position(|p| p.iter().any(|c| !c.is_finite())) {
        return Err(Error::OutOfRange {
            name: "point",
            value: i as f64,
            expected: "coordinates must be finite",
        });
    }
    Ok(())
}

impl<const D: usize> Planner<D> {
    /// A planner at `interrupt_hz` and feed `feed` with the same limits on every axis.
    pub fn new(interrupt_hz: f64, feed: f64, limits: AxisLimits) -> Self {
        Planner {
            interrupt_hz,
            feed,
            limits: [limits; D],
            spline_interrupts_per_segment: None,
        }
    }

    fn check(&self) -> Result<(), Error> {
        let positive = |name: &'static str, v: f64| {
            if v > 0.0 && v.is_finite() {
                Ok(())
            } else {
                Err(Error::OutOfRange {
                    name,
                    value: v,
                    expected: "must be > 0",
                })
            }
        };
        positive("interrupt_hz", self.interrupt_hz)?;
        positive("feed_counts_per_interrupt", self.feed)?;
        for l in &self.limits {
            positive("max_velocity_counts_per_interrupt", l.max_velocity)?;
            positive("max_acceleration_counts_per_interrupt2", l.max_acceleration)?;
        }
        if let Some(t) = self.spline_interrupts_per_segment {
            positive("spline_interrupts_per_segment", t)?;
        }
        Ok(())
    }

    /// The speed limit of each axis: the feed, or the axis's own limit where lower.
    fn speed_limits(&self) -> SVector<f64, D> {
        SVector::from_fn(|i, _| self.feed.min(self.limits[i].max_velocity))
    }

    /// Travel time of a move `delta` at the speed limits (§9.5: `T = max |Δ| / F`), interrupts.
    fn travel_time(&self, delta: &SVector<f64, D>) -> f64 {
        let limits = self.speed_limits();
        (0..D)
            .map(|i| delta[i].abs() / limits[i])
            .fold(0.0, f64::max)
    }

    /// Plans the trajectory through `points` (absolute counts; `points[0]` is where the axes
    /// are at the start).
    pub fn plan(
        &self,
        points: &[SVector<f64, D>],
        interpolation: Interpolation,
    ) -> Result<Trajectory<D>, Error> {
        self.check()?;
        check_points(points)?;
        let (setpoints, path) = match interpolation {
            Interpolation::PointToPoint => (self.point_to_point(points)?, points.to_vec()),
            Interpolation::Linear => {
                let times: Vec<f64> = points
                    .windows(2)
                    .map(|w| self.travel_time(&(w[1] - w[0])))
                    .collect();
                (resample(points, &times)?, points.to_vec())
            }
            Interpolation::ParabolicBlend => {
                let s = self.parabolic_blend(points)?;
                (s.clone(), s)
            }
            Interpolation::BSpline { knots_per_segment } => {
                self.bspline(points, knots_per_segment)?
            }
        };
        Ok(Trajectory {
            interrupt_hz: self.interrupt_hz,
            setpoints,
            points: points.to_vec(),
            path,
        })
    }

    fn point_to_point(&self, points: &[SVector<f64, D>]) -> Result<Vec<SVector<f64, D>>, Error> {
        let mut out = vec![points[0]];
        for w in points.windows(2) {
            let delta = w[1] - w[0];
            // Path parameter s ∈ [0, 1]: speed and acceleration limits in s per interrupt.
            let mut v_max = f64::INFINITY;
            let mut a_max = f64::INFINITY;
            let limits = self.speed_limits();
            for i in 0..D {
                let d = delta[i].abs();
                if d > 0.0 {
                    v_max = v_max.min(limits[i] / d);
                    a_max = a_max.min(self.limits[i].max_acceleration / d);
                }
            }
            if !v_max.is_finite() {
                continue;
            }
            // Trapezoid (or triangle when the top speed is never reached).
            let (t_acc, v_top) = if v_max * v_max / a_max >= 1.0 {
                let v = a_max.sqrt();
                (v / a_max, v)
            } else {
                (v_max / a_max, v_max)
            };
            let t_cruise = (1.0 - v_top * t_acc) / v_top;
            let total = 2.0 * t_acc + t_cruise.max(0.0);
            // Compared as f64 first: a tiny feed makes `total` too large for any usize sum.
            if !fits(out.len() as f64 + total.ceil()) {
                return Err(too_long());
            }
            let steps = total.ceil() as usize;
            for k in 1..=steps {
                let t = k as f64;
                let s = if k == steps {
                    1.0
                } else if t < t_acc {
                    0.5 * a_max * t * t
                } else if t < t_acc + t_cruise.max(0.0) {
                    0.5 * v_top * t_acc + v_top * (t - t_acc)
                } else {
                    let r = (total - t).max(0.0);
                    1.0 - 0.5 * a_max * r * r
                };
                out.push(if k == steps {
                    w[1]
                } else {
                    w[0] + delta * s.clamp(0.0, 1.0)
                });
            }
        }
        Ok(out)
    }

    fn parabolic_blend(&self, points: &[SVector<f64, D>]) -> Result<Vec<SVector<f64, D>>, Error> {
        let times: Vec<f64> = points
            .windows(2)
            .map(|w| self.travel_time(&(w[1] - w[0])))
            .collect();
        let linear = resample(points, &times)?;
        // Velocities per interrupt, with rest before and after.
        let mut v: Vec<SVector<f64, D>> = linear.windows(2).map(|w| w[1] - w[0]).collect();
        // A box filter of width w turns each velocity step Δv into a ramp Δv / w; any w-wide
        // window spans at most a change of 2 v_max, so w ≥ 2 v_max / a_max keeps every axis
        // inside its acceleration limit.
        let mut width = 1usize;
        for i in 0..D {
            let vmax = v.iter().map(|x| x[i].abs()).fold(0.0, f64::max);
            let w = (2.0 * vmax / self.limits[i].max_acceleration).ceil();
            if !fits(linear.len() as f64 + w) {
                return Err(too_long());
            }
            width = width.max(w as usize);
        }
        v.extend(std::iter::repeat_n(SVector::zeros(), width - 1));
        let mut out = Vec::with_capacity(v.len() + 1);
        let mut pos = points[0];
        out.push(pos);
        let mut window_sum = SVector::<f64, D>::zeros();
        for k in 0..v.len() {
            window_sum += v[k];
            if k >= width {
                window_sum -= v[k - width];
            }
            pos += window_sum / width as f64;
            out.push(pos);
        }
        if let Some(last) = out.last_mut() {
            *last = points[points.len() - 1];
        }
        Ok(out)
    }

    #[allow(clippy::type_complexity)]
    fn bspline(
        &self,
        points: &[SVector<f64, D>],
        knots_per_segment: usize,
    ) -> Result<(Vec<SVector<f64, D>>, Vec<SVector<f64, D>>), Error> {
        let spline = UniformCubic::new(points)?;
        let knots = spline.sample(knots_per_segment)?;
        let per_segment = match self.spline_interrupts_per_segment {
            Some(t) => t,
            None => {
                let segments = spline.segment_count();
                let total: f64 = (0..segments)
                    .map(|s| {
                        let a = spline.eval(s, 0.0).unwrap_or_else(SVector::zeros);
                        let b = spline.eval(s, 1.0).unwrap_or_else(SVector::zeros);
                        self.travel_time(&(b - a))
                    })
                    .sum();
                (total / segments as f64).max(1e-9)
            }
        };
        // Parameter speed σ (segments per interrupt): the nominal 1/per_segment, lowered
        // wherever an axis would pass its speed limit, σ(u) = min(σ_nom, min_i F_i/|P_i'(u)|).
        // σ is continuous, so the axis velocities P'(u)·σ(u) are continuous and never above the
        // limits. Time is ∫ du/σ, tabulated on a fine grid of the parameter.
        let limits = self.speed_limits();
        let sigma_nom = 1.0 / per_segment;
        let segments = spline.segment_count();
        let coefficients: Vec<[SVector<f64, D>; 4]> = (0..segments)
            .map(|seg| spline.coefficients(seg).unwrap_or([SVector::zeros(); 4]))
            .collect();
        // 1/σ at parameter t of segment seg.
        let inv_sigma = |seg: usize, t: f64| -> f64 {
            let [_, a1, a2, a3] = &coefficients[seg];
            let mut sigma = sigma_nom;
            for i in 0..D {
                let d = (3.0 * a3[i] * t + 2.0 * a2[i]) * t + a1[i];
                sigma = sigma.min(limits[i] / d.abs());
            }
            1.0 / sigma
        };
        const SUBSTEPS: usize = 128;
        let mut table_u = Vec::with_capacity(segments * SUBSTEPS + 1);
        let mut table_t = Vec::with_capacity(segments * SUBSTEPS + 1);
        let (mut u, mut time) = (0.0f64, 0.0f64);
        table_u.push(u);
        table_t.push(time);
        let du = 1.0 / SUBSTEPS as f64;
        for seg in 0..segments {
            let mut left = inv_sigma(seg, 0.0);
            for k in 0..SUBSTEPS {
                // Simpson's rule on 1/σ over the substep.
                let t0 = k as f64 * du;
                let right = inv_sigma(seg, t0 + du);
                time += du / 6.0 * (left + 4.0 * inv_sigma(seg, t0 + du / 2.0) + right);
                left = right;
                u += du;
                table_u.push(u);
                table_t.push(time);
            }
        }
        if !fits(time.ceil() + 1.0) {
            return Err(too_long());
        }
        let steps = time.ceil() as usize;
        let mut setpoints = Vec::with_capacity(steps + 1);
        let mut row = 0usize;
        for k in 0..=steps {
            let t = k as f64;
            while row + 1 < table_t.len() - 1 && table_t[row + 1] <= t {
                row += 1;
            }
            let (t0, t1) = (table_t[row], table_t[row + 1]);
            let f = if t1 > t0 {
                ((t - t0) / (t1 - t0)).clamp(0.0, 1.0)
            } else {
                1.0
            };
            let u = table_u[row] + (table_u[row + 1] - table_u[row]) * f;
            let seg = (u.floor() as usize).min(segments - 1);
            let t = (u - seg as f64).clamp(0.0, 1.0);
            let [a0, a1, a2, a3] = &coefficients[seg];
            setpoints.push(((a3 * t + a2) * t + a1) * t + a0);
        }
        if let Some(last) = setpoints.last_mut() {
            *last = knots[knots.len() - 1];
        }
        Ok((setpoints, knots))
    }
}

/// Whether `count` setpoints (a float, so that no cast saturates or sum wraps first; NaN does not
/// fit) are within [`MAX_SETPOINTS`].
fn fits(count: f64) -> bool {
    (0.0..=MAX_SETPOINTS as f64).contains(&count)
}

fn too_long() -> Error {
    Error::OutOfRange {
        name: "trajectory_interrupts",
        value: MAX_SETPOINTS as f64,
        expected: "the trajectory must fit in MAX_SETPOINTS interrupts (raise the feed)",
    }
}

/// Samples the polyline `points` (vertex `i` reached at the cumulative time of `times[..i]`) at
/// every whole interrupt; the final sample is the last point.
fn resample<const D: usize>(
    points: &[SVector<f64, D>],
    times: &[f64],
) -> Result<Vec<SVector<f64, D>>, Error> {
    let total: f64 = times.iter().sum();
    if !fits(total.ceil() + 1.0) {
        return Err(too_long());
    }
    let steps = total.ceil() as usize;
    let mut out = Vec::with_capacity(steps + 1);
    out.push(points[0]);
    let mut seg = 0usize;
    let mut seg_start = 0.0;
    for k in 1..=steps {
        let t = k as f64;
        while seg < times.len() && seg_start + times[seg] <= t {
            seg_start += times[seg];
            seg += 1;
        }
        if seg >= times.len() {
            out.push(points[points.len() - 1]);
        } else {
            let f = if times[seg] > 0.0 {
                (t - seg_start) / times[seg]
            } else {
                1.0
            };
            out.push(points[seg] + (points[seg + 1] - points[seg]) * f);
        }
    }
    if let Some(last) = out.last_mut() {
        *last = points[points.len() - 1];
    }
    Ok(out)
}

impl<const D: usize> Trajectory<D> {
    /// Number of interrupts from the first desired position to the last.
    pub fn interrupts(&self) -> usize {
        self.setpoints.len() - 1
    }

    /// Duration, s.
    pub fn duration_s(&self) -> f64 {
        self.interrupts() as f64 / self.interrupt_hz
    }

    /// Peak planned velocity, acceleration and jerk per axis.
    pub fn peaks(&self) -> Peaks<D> {
        peaks(&self.setpoints, self.interrupt_hz)
    }

    /// The closest approach of the planned path (the geometric path, refined by the desired
    /// positions) to every given point, flagged against `tolerance` (counts per axis), with
    /// remedies for the flagged ones. The first and last points are met exactly by every
    /// interpolation and are reported too.
    pub fn deviations(&self, tolerance: &SVector<f64, D>) -> Vec<Deviation<D>> {
        self.points
            .iter()
            .enumerate()
            .map(|(index, p)| {
                let offset = closest_offset(&self.path, p);
                let exceeds = (0..D).any(|i| offset[i].abs() > tolerance[i]);
                let remedies = if exceeds {
                    vec![
                        Remedy::TriplePoint,
                        Remedy::InsertMidpoints,
                        Remedy::UseLinear,
                    ]
                } else {
                    Vec::new()
                };
                Deviation {
                    index,
                    offset,
                    exceeds,
                    remedies,
                }
            })
            .collect()
    }
}

/// The offset from `p` to the nearest point of the polyline `path` (nearest in the Euclidean
/// norm of counts).
fn closest_offset<const D: usize>(
    path: &[SVector<f64, D>],
    p: &SVector<f64, D>,
) -> SVector<f64, D> {
    if path.len() == 1 {
        return path[0] - p;
    }
    let mut best = SVector::<f64, D>::repeat(f64::INFINITY);
    let mut best_norm = f64::INFINITY;
    for w in path.windows(2) {
        let d = w[1] - w[0];
        let len2 = d.norm_squared();
        let f = if len2 > 0.0 {
            ((p - w[0]).dot(&d) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let off = w[0] + d * f - p;
        let n = off.norm_squared();
        if n < best_norm {
            best_norm = n;
            best = off;
        }
    }
    best
}

/// Applies a remedy to the points at `indices` (interior indices only; ends are already exact):
/// [`Remedy::TriplePoint`] repeats each twice, [`Remedy::InsertMidpoints`] adds the chord
/// midpoints on either side. [`Remedy::UseLinear`] leaves the points as they are (it changes the
/// interpolation, not the points).
pub fn apply_remedy<const D: usize>(
    points: &[SVector<f64, D>],
    indices: &[usize],
    remedy: Remedy,
) -> Vec<SVector<f64, D>> {
    let interior = |i: usize| i > 0 && i + 1 < points.len() && indices.contains(&i);
    let mut out = Vec::with_capacity(points.len() + 2 * indices.len());
    for (i, p) in points.iter().enumerate() {
        match remedy {
            Remedy::TriplePoint if interior(i) => out.extend([*p, *p, *p]),
            Remedy::InsertMidpoints if interior(i) => {
                let before = (points[i - 1] + p) / 2.0;
                let after = (points[i + 1] + p) / 2.0;
                if out.last() != Some(&before) {
                    out.push(before);
                }
                out.extend([*p, after]);
            }
            _ => {
                if out.last() != Some(p) || !matches!(remedy, Remedy::InsertMidpoints) {
                    out.push(*p);
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;
    use nalgebra::{Vector1, Vector2, Vector3};

    fn planner<const D: usize>(feed: f64) -> Planner<D> {
        Planner::new(
            200.0,
            feed,
            AxisLimits {
                max_velocity: 1000.0,
                max_acceleration: 2.0,
            },
        )
    }

    fn out_and_back() -> Vec<Vector1<f64>> {
        [0.0, 10000.0, 0.0].map(Vector1::new).to_vec()
    }

    #[test]
    fn linear_time_is_the_dominant_axis_over_the_feed() {
        // Notes-000 §7 item 8: first Fig 9-1 block, A 356.39 counts, X 874.10 counts, F = 10:
        // T = 87.41 interrupts, v_X = 10, v_A ≈ 4.08 counts per interrupt.
        let p = [Vector3::zeros(), Vector3::new(356.39, 874.10, 0.0)];
        let t = planner::<3>(10.0).plan(&p, Interpolation::Linear).unwrap();
        assert_eq!(t.interrupts(), 88);
        let v = t.setpoints[1] - t.setpoints[0];
        assert_abs_diff_eq!(v[1], 10.0, epsilon = 1e-9);
        assert_abs_diff_eq!(v[0], 356.39 / 87.41, epsilon = 1e-9);
        assert_eq!(t.setpoints[88], p[1]);
        assert_abs_diff_eq!(t.peaks().velocity[1], 2000.0, epsilon = 1e-6);
    }

    #[test]
    fn an_axis_limit_below_the_feed_sets_the_time() {
        let mut pl = planner::<2>(50.0);
        pl.limits[1].max_velocity = 5.0;
        let p = [
            SVector::<f64, 2>::zeros(),
            SVector::<f64, 2>::new(500.0, 100.0),
        ];
        let t = pl.plan(&p, Interpolation::Linear).unwrap();
        assert_eq!(t.interrupts(), 20);
        for w in t.setpoints.windows(2) {
            assert!((w[1][1] - w[0][1]).abs() <= 5.0 + 1e-9);
            assert!((w[1][0] - w[0][0]).abs() <= 50.0 + 1e-9);
        }
    }

    #[test]
    fn point_to_point_stops_on_every_point_within_the_limits() {
        let pts = out_and_back();
        let t = planner::<1>(80.0)
            .plan(&pts, Interpolation::PointToPoint)
            .unwrap();
        assert!(t.setpoints.contains(&Vector1::new(10000.0)));
        assert_eq!(t.setpoints.last().unwrap().x, 0.0);
        let v: Vec<f64> = t.setpoints.windows(2).map(|w| w[1].x - w[0].x).collect();
        assert!(v.iter().all(|x| x.abs() <= 80.0 + 1e-9));
        for w in v.windows(2) {
            assert!((w[1] - w[0]).abs() <= 2.0 + 1e-6, "{w:?}");
        }
        // At rest at the turnaround: the sample at 10000 has zero velocity on both sides.
        let k = t.setpoints.iter().position(|p| p.x == 10000.0).unwrap();
        assert!(v[k - 1].abs() < 2.0 + 1e-9 && v[k].abs() < 2.0 + 1e-9);
    }

    /// The point-to-point profile's length against its closed forms (counts and interrupts, the
    /// acceleration limit A = 2): a leg of d = 10 000 at feed 80 is a trapezoid of
    /// d/v + v/A = 125 + 40 = 165 interrupts; a leg of d = 100 never reaches the feed and is a
    /// triangle of 2·√(d/A) = 14.14, so 15 interrupts, peaking at √(A·d) = 14.1 counts per
    /// interrupt. Both start from rest: the first step is at most one acceleration's worth.
    #[test]
    fn point_to_point_legs_take_their_closed_form_time() {
        let trapezoid = planner::<1>(80.0)
            .plan(&out_and_back(), Interpolation::PointToPoint)
            .unwrap();
        assert_eq!(trapezoid.setpoints.len(), 2 * 165 + 1);
        let short = [0.0, 100.0].map(Vector1::new);
        let triangle = planner::<1>(80.0)
            .plan(&short, Interpolation::PointToPoint)
            .unwrap();
        assert_eq!(triangle.setpoints.len(), 15 + 1);
        for t in [&trapezoid, &triangle] {
            let v: Vec<f64> = t.setpoints.windows(2).map(|w| w[1].x - w[0].x).collect();
            assert!(v[0].abs() <= 2.0 + 1e-9, "{}", v[0]);
            for w in v.windows(2) {
                assert!((w[1] - w[0]).abs() <= 2.0 + 1e-6, "{w:?}");
            }
        }
        let peak = triangle
            .setpoints
            .windows(2)
            .map(|w| w[1].x - w[0].x)
            .fold(0.0, f64::max);
        assert!(
            peak <= (2.0f64 * 100.0).sqrt() + 1e-9 && peak > 12.0,
            "{peak}"
        );
    }

    /// Two legs of 3001 interrupts each fit well within the setpoint limit: the check adds the
    /// setpoints so far to the next leg's (a product of the two, 9 million, would refuse them).
    #[test]
    fn point_to_point_counts_the_setpoints_it_has() {
        let pts = [0.0, 3000.0, 0.0].map(Vector1::new);
        let t = planner::<1>(1.0)
            .plan(&pts, Interpolation::PointToPoint)
            .unwrap();
        assert_eq!(t.setpoints.len(), 2 * 3001 + 1);
    }

    /// Linear resampling across legs, by hand: out to 10 000 and back at feed 80 is 125
    /// interrupts each way; at interrupt 125 the setpoint is the turning point, at 200 it is
    /// 75 × 80 counts back (4000), and the last is 0. The parabolic blend of the same moves adds
    /// one box filter's width less one, ⌈2 v / A⌉ − 1 = 79 interrupts at v = 80, at rest.
    #[test]
    fn linear_and_blended_moves_across_legs_by_hand() {
        let linear = planner::<1>(80.0)
            .plan(&out_and_back(), Interpolation::Linear)
            .unwrap();
        assert_eq!(linear.interrupts(), 250);
        assert_abs_diff_eq!(linear.setpoints[125].x, 10000.0, epsilon = 1e-9);
        assert_abs_diff_eq!(linear.setpoints[200].x, 4000.0, epsilon = 1e-9);
        assert_abs_diff_eq!(linear.setpoints[62].x, 62.0 * 80.0, epsilon = 1e-9);
        assert_eq!(linear.setpoints[250].x, 0.0);
        let blended = planner::<1>(80.0)
            .plan(&out_and_back(), Interpolation::ParabolicBlend)
            .unwrap();
        // The resampled speed is 80 to within rounding, which the width's ceiling can take up
        // (80 + 1e-14 makes it 81: the filter errs wide, the acceleration low).
        let v = linear
            .setpoints
            .windows(2)
            .map(|w| (w[1].x - w[0].x).abs())
            .fold(0.0, f64::max);
        assert_abs_diff_eq!(v, 80.0, epsilon = 1e-9);
        let width = (2.0 * v / 2.0).ceil() as usize;
        assert!(width == 80 || width == 81);
        assert_eq!(blended.interrupts(), 250 + width - 1);
    }

    /// The setpoint limit is exact: a linear move of 3 999 999 interrupts (4 000 000 setpoints,
    /// the limit) plans, one of 4 000 000 does not.
    #[test]
    fn the_setpoint_limit_is_exact() {
        let at = [0.0, (MAX_SETPOINTS - 1) as f64].map(Vector1::new);
        let t = planner::<1>(1.0).plan(&at, Interpolation::Linear).unwrap();
        assert_eq!(t.setpoints.len(), MAX_SETPOINTS);
        let over = [0.0, MAX_SETPOINTS as f64].map(Vector1::new);
        assert!(matches!(
            planner::<1>(1.0).plan(&over, Interpolation::Linear),
            Err(Error::OutOfRange {
                name: "trajectory_interrupts",
                ..
            })
        ));
        // The blend adds its filter's width (2 × 1 / 0.01 = 200 interrupts at A = 0.01) to the
        // linear samples: 3 999 901 + 200 is over the limit, 100 000 + 200 well under it.
        let mut gentle = planner::<1>(1.0);
        gentle.limits[0].max_acceleration = 0.01;
        let near = [0.0, (MAX_SETPOINTS - 100) as f64].map(Vector1::new);
        assert!(gentle.plan(&near, Interpolation::ParabolicBlend).is_err());
        let short = [0.0, 99_999.0].map(Vector1::new);
        let t = gentle.plan(&short, Interpolation::ParabolicBlend).unwrap();
        assert!((100_000 + 199..=100_000 + 200).contains(&t.setpoints.len()));
    }

    #[test]
    fn parabolic_blends_respect_the_acceleration_limit_and_end_exactly() {
        let pts = [0.0, 3000.0, 4000.0, -2000.0].map(Vector1::new);
        let t = planner::<1>(40.0)
            .plan(&pts, Interpolation::ParabolicBlend)
            .unwrap();
        let v: Vec<f64> = t.setpoints.windows(2).map(|w| w[1].x - w[0].x).collect();
        for w in v.windows(2) {
            assert!((w[1] - w[0]).abs() <= 2.0 + 1e-9);
        }
        assert!(v.iter().all(|x| x.abs() <= 40.0 + 1e-9));
        assert_eq!(t.setpoints.last().unwrap().x, -2000.0);
        assert_eq!(t.setpoints[0].x, 0.0);
        let lin = planner::<1>(40.0)
            .plan(&pts, Interpolation::Linear)
            .unwrap();
        assert!(t.peaks().acceleration.x < lin.peaks().acceleration.x / 10.0);
    }

    #[test]
    fn bspline_out_and_back_reaches_two_thirds_and_is_flagged() {
        let pts = out_and_back();
        let t = planner::<1>(80.0)
            .plan(
                &pts,
                Interpolation::BSpline {
                    knots_per_segment: 4,
                },
            )
            .unwrap();
        let peak = t.setpoints.iter().map(|p| p.x).fold(0.0, f64::max);
        assert!(peak <= 20000.0 / 3.0 + 1e-6);
        assert_abs_diff_eq!(
            t.path.iter().map(|p| p.x).fold(0.0, f64::max),
            20000.0 / 3.0,
            epsilon = 1e-6
        );
        let dev = t.deviations(&Vector1::new(27.7));
        assert!(!dev[0].exceeds && !dev[2].exceeds);
        assert!(dev[1].exceeds);
        assert_abs_diff_eq!(dev[1].offset.x, 20000.0 / 3.0 - 10000.0, epsilon = 1e-6);
        assert_eq!(dev[1].remedies[0], Remedy::TriplePoint);
        // The remedy: triple the turnaround; the curve reaches it and the report is clean.
        let fixed = apply_remedy(&pts, &[1], Remedy::TriplePoint);
        assert_eq!(fixed.len(), 5);
        let t = planner::<1>(80.0)
            .plan(
                &fixed,
                Interpolation::BSpline {
                    knots_per_segment: 4,
                },
            )
            .unwrap();
        assert!(t.deviations(&Vector1::new(27.7)).iter().all(|d| !d.exceeds));
        assert_abs_diff_eq!(
            t.path.iter().map(|p| p.x).fold(0.0, f64::max),
            10000.0,
            epsilon = 1e-6
        );
        let near = t.setpoints.iter().map(|p| p.x).fold(0.0, f64::max);
        assert!(10000.0 - near < 1.0, "{near}");
    }

    #[test]
    fn midpoints_halve_the_residual() {
        let pts: Vec<Vector2<f64>> = [0.0, 1200.0, 0.0, 1200.0, 0.0]
            .iter()
            .enumerate()
            .map(|(i, &y)| Vector2::new(1000.0 * i as f64, y))
            .collect();
        let tol = Vector2::new(1.0, 1.0);
        let plan = |p: &[Vector2<f64>]| {
            planner::<2>(20.0)
                .plan(
                    p,
                    Interpolation::BSpline {
                        knots_per_segment: 8,
                    },
                )
                .unwrap()
        };
        let before = plan(&pts).deviations(&tol)[2].offset;
        assert_abs_diff_eq!(before.y, 400.0, epsilon = 1e-6);
        assert_abs_diff_eq!(before.x, 0.0, epsilon = 1e-6);
        let fixed = apply_remedy(&pts, &[2], Remedy::InsertMidpoints);
        assert_eq!(fixed.len(), 7);
        assert_eq!(fixed[3], pts[2]);
        let after = plan(&fixed).deviations(&tol)[3].offset;
        assert_abs_diff_eq!(after.y, 200.0, epsilon = 1e-6);
        assert_eq!(apply_remedy(&pts, &[2], Remedy::UseLinear), pts);
        assert_eq!(apply_remedy(&pts, &[0, 4], Remedy::TriplePoint), pts);
    }

    #[test]
    fn bspline_ramps_up_gently_and_respects_the_feed() {
        let pts = out_and_back();
        let lin = planner::<1>(80.0)
            .plan(&pts, Interpolation::Linear)
            .unwrap();
        let bs = planner::<1>(80.0)
            .plan(
                &pts,
                Interpolation::BSpline {
                    knots_per_segment: 4,
                },
            )
            .unwrap();
        let v: Vec<f64> = bs.setpoints.windows(2).map(|w| w[1].x - w[0].x).collect();
        let vmax = v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        assert!(vmax <= 80.0 * 1.005, "{vmax}");
        // "the change in velocity from zero to the feed rate limit is gradual in small steps"
        // (§10.2): the first knot interval runs at 1/32 of the feed.
        assert!(v[0].abs() < 80.0 / 20.0, "starts gently: {}", v[0]);
        let steps_to_feed = v.iter().position(|x| x.abs() > 79.0).unwrap();
        assert!(steps_to_feed > 20, "{steps_to_feed}");
        assert!(bs.peaks().acceleration.x < lin.peaks().acceleration.x / 4.0);
        assert!(bs.peaks().jerk.x < lin.peaks().jerk.x / 4.0);
        assert_eq!(bs.setpoints.last().unwrap().x, 0.0);
    }

    #[test]
    fn bad_settings_are_errors() {
        let pts = out_and_back();
        assert!(planner::<1>(0.0).plan(&pts, Interpolation::Linear).is_err());
        assert!(
            planner::<1>(10.0)
                .plan(&pts[..1], Interpolation::Linear)
                .is_err()
        );
        let nan = [Vector1::new(0.0), Vector1::new(f64::NAN)];
        assert!(
            planner::<1>(10.0)
                .plan(&nan, Interpolation::Linear)
                .is_err()
        );
        assert!(
            planner::<1>(10.0)
                .plan(
                    &pts,
                    Interpolation::BSpline {
                        knots_per_segment: 0
                    }
                )
                .is_err()
        );
        let far = [Vector1::new(0.0), Vector1::new(1e12)];
        assert!(planner::<1>(1.0).plan(&far, Interpolation::Linear).is_err());
    }

    /// A feed so small that the trajectory's interrupt count overflows any integer is refused
    /// as too long, by every interpolation, at once (it used to wrap the count and loop).
    #[test]
    fn a_vanishing_feed_is_too_long_for_every_interpolation() {
        let pts = out_and_back();
        let mut steep = planner::<1>(10.0);
        steep.limits[0].max_acceleration = 1e-300;
        for (pl, interpolation) in [
            (planner::<1>(1e-300), Interpolation::Linear),
            (planner::<1>(1e-300), Interpolation::PointToPoint),
            (planner::<1>(1e-300), Interpolation::ParabolicBlend),
            (steep, Interpolation::ParabolicBlend),
            (steep, Interpolation::PointToPoint),
            (
                planner::<1>(1e-300),
                Interpolation::BSpline {
                    knots_per_segment: 4,
                },
            ),
        ] {
            match pl.plan(&pts, interpolation) {
                Err(Error::OutOfRange { name, .. }) => {
                    assert_eq!(name, "trajectory_interrupts", "{interpolation:?}")
                }
                other => panic!("{interpolation:?}: {other:?}"),
            }
        }
    }

    #[test]
    fn peaks_of_a_parabola() {
        let s: Vec<Vector1<f64>> = (0..10).map(|k| Vector1::new((k * k) as f64)).collect();
        let p = peaks(&s, 10.0);
        assert_abs_diff_eq!(p.velocity.x, 17.0 * 10.0);
        assert_abs_diff_eq!(p.acceleration.x, 2.0 * 100.0);
        assert_abs_diff_eq!(p.jerk.x, 0.0);
    }
}
