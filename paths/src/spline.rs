//! B-splines over `nalgebra::SVector<f64, D>`.
//!
//! [`BSpline`] is a clamped B-spline of any degree up to [`MAX_DEGREE`] (cubic by default):
//! evaluation by de Boor's algorithm, first derivative from the derivative control points,
//! interpolation and least-squares fitting with chord-length parameters, projection of points onto
//! the curve, arc length and equal-arc-length division. It smooths the fibre paths that arrive
//! from CAD as point lists and divides them into equal-length segments, as seed 001 §5.5 did in
//! AutoCAD ("smoothed out by spline fitting ... divided into equal length segments").
//!
//! [`UniformCubic`] is the lathe winder's approximating uniform cubic B-spline of seed 000
//! (Haq 1994 §8.7, §8.8.1, §9.6): the part-program
//! points are the control points, the first and last are tripled, and each segment is sampled at
//! `N` knot-points ("knot" meaning a sample point, as in the thesis glossary).

use std::ops::RangeInclusive;

use nalgebra::SVector;

use crate::Error;

/// The highest degree a [`BSpline`] may have (evaluation works in fixed-size buffers).
pub const MAX_DEGREE: usize = 7;

/// Estimated absolute error of [`BSpline::length`] per knot span, in millimetres.
pub const LENGTH_TOLERANCE_MM: f64 = 1e-10;

/// Largest error, in arc length, of the points of [`BSpline::equal_length`], in millimetres.
pub const EQUAL_LENGTH_TOLERANCE_MM: f64 = 1e-8;

/// A clamped B-spline curve in `D` dimensions.
///
/// The knot vector `u_0 ≤ … ≤ u_{n+p}` has its first and last `p + 1` knots equal, so the curve
/// starts at the first control point and ends at the last; the domain is `[u_p, u_n]`.
#[derive(Debug, Clone, PartialEq)]
pub struct BSpline<const D: usize> {
    degree: usize,
    knots: Vec<f64>,
    control_points: Vec<SVector<f64, D>>,
}

impl<const D: usize> BSpline<D> {
    /// A spline from its parts; checks that the knots are finite, non-decreasing, clamped, of
    /// length `control_points + degree + 1`, and that the domain is not empty.
    pub fn new(
        degree: usize,
        knots: Vec<f64>,
        control_points: Vec<SVector<f64, D>>,
    ) -> Result<Self, Error> {
        if degree == 0 || degree > MAX_DEGREE {
            return Err(Error::OutOfRange {
                name: "b-spline degree",
                value: degree as f64,
                expected: "must be 1..=7",
            });
        }
        check_points(&control_points, "b-spline", degree + 1)?;
        let n = control_points.len();
        if knots.len() != n + degree + 1 {
            return Err(Error::BadKnots {
                index: knots.len(),
                reason: "the knot count must be control points + degree + 1",
            });
        }
        for (index, &u) in knots.iter().enumerate() {
            if !u.is_finite() {
                return Err(Error::BadKnots {
                    index,
                    reason: "not finite",
                });
            }
            if index > 0 && u < knots[index - 1] {
                return Err(Error::BadKnots {
                    index,
                    reason: "smaller than the knot before it",
                });
            }
        }
        for i in 1..=degree {
            if knots[i] != knots[0] {
                return Err(Error::BadKnots {
                    index: i,
                    reason: "the first degree + 1 knots must be equal (clamped)",
                });
            }
            let j = knots.len() - 1 - i;
            if knots[j] != knots[knots.len() - 1] {
                return Err(Error::BadKnots {
                    index: j,
                    reason: "the last degree + 1 knots must be equal (clamped)",
                });
            }
        }
        if knots[degree] >= knots[n] {
            return Err(Error::BadKnots {
                index: n,
                reason: "the domain is empty",
            });
        }
        Ok(BSpline {
            degree,
            knots,
            control_points,
        })
    }

    /// A cubic (or lower, with fewer than four points) spline on `[0, 1]` with uniformly spaced
    /// interior knots.
    pub fn from_control_points(control_points: Vec<SVector<f64, D>>) -> Result<Self, Error> {
        check_points(&control_points, "b-spline", 2)?;
        let degree = (control_points.len() - 1).min(3);
        let n = control_points.len();
        let spans = n - degree;
        let mut knots = vec![0.0; degree + 1];
        knots.extend((1..spans).map(|j| j as f64 / spans as f64));
        knots.extend(std::iter::repeat_n(1.0, degree + 1));
        BSpline::new(degree, knots, control_points)
    }

    /// The cubic spline through every point (seed 001 §5.5 "spline fitting"): chord-length
    /// parameters on `[0, 1]`, interior knots by averaging the parameters (Piegl & Tiller eq 9.8),
    /// clamped ends. With two or three points the degree drops to 1 or 2.
    pub fn interpolate(points: &[SVector<f64, D>]) -> Result<Self, Error> {
        check_points(points, "spline interpolant", 2)?;
        let params = chord_parameters(points)?;
        let degree = (points.len() - 1).min(3);
        let n = points.len();
        let mut knots = vec![0.0; degree + 1];
        for j in 1..n - degree {
            knots.push(params[j..j + degree].iter().sum::<f64>() / degree as f64);
        }
        knots.extend(std::iter::repeat_n(1.0, degree + 1));
        let mut band = Band::new(n, degree);
        let mut shell = BSpline {
            degree,
            knots,
            control_points: Vec::new(),
        };
        for (row, &t) in params.iter().enumerate() {
            let span = shell.span(t);
            let basis = shell.basis(span, t);
            for (k, &b) in basis.iter().enumerate().take(degree + 1) {
                band.add(row, span - degree + k, b)?;
            }
        }
        shell.control_points = band.solve(points.to_vec(), "interpolation")?;
        Ok(shell)
    }

    /// The least-squares spline with the fewest control points whose [`max_deviation`] from
    /// `points` is at most `tolerance_mm` (Piegl & Tiller §9.4.1): chord-length parameters, knots
    /// placed so every span holds a parameter (after eq 9.69), first and last points kept exactly.
    /// A candidate whose control polygon is more than twice as long as the points' polyline is
    /// rejected as oscillating, however close it passes to the points.
    ///
    /// The control-point count is searched by doubling and then bisection; the deviation is
    /// nearly but not strictly monotone in the count, so the result is the smallest count the
    /// bisection reaches, and always meets the tolerance (at worst it interpolates every point).
    ///
    /// [`max_deviation`]: BSpline::max_deviation
    pub fn fit(points: &[SVector<f64, D>], tolerance_mm: f64) -> Result<Self, Error> {
        if !(tolerance_mm > 0.0 && tolerance_mm.is_finite()) {
            return Err(Error::OutOfRange {
                name: "fit tolerance_mm",
                value: tolerance_mm,
                expected: "must be > 0",
            });
        }
        check_points(points, "spline fit", 2)?;
        let params = chord_parameters(points)?;
        let degree = (points.len() - 1).min(3);
        let all = points.len();
        let accept = |count: usize| -> Result<Option<Self>, Error> {
            let curve = if count >= all {
                BSpline::interpolate(points)?
            } else {
                BSpline::least_squares(points, &params, degree, count)?
            };
            let polygon = polyline_length(curve.control_points());
            let calm = polygon.is_finite() && polygon <= 2.0 * polyline_length(points);
            Ok((calm && curve.max_deviation(points) <= tolerance_mm).then_some(curve))
        };
        let mut failed = degree;
        let mut step = 1;
        let (mut good_count, mut good) = loop {
            let count = (failed + step).min(all);
            if let Some(curve) = accept(count)? {
                break (count, curve);
            }
            if count == all {
                // Interpolation misses only by rounding; return it rather than fail.
                return BSpline::interpolate(points);
            }
            failed = count;
            step *= 2;
        };
        while good_count - failed > 1 {
            let mid = failed + (good_count - failed) / 2;
            match accept(mid)? {
                Some(curve) => {
                    good_count = mid;
                    good = curve;
                }
                None => failed = mid,
            }
        }
        Ok(good)
    }

    /// Least squares with `count` control points, ends fixed.
    fn least_squares(
        points: &[SVector<f64, D>],
        params: &[f64],
        degree: usize,
        count: usize,
    ) -> Result<Self, Error> {
        let m = points.len() - 1;
        let n = count - 1;
        let mut knots = vec![0.0; degree + 1];
        // Interior knot j at fractional index j·d of the parameters, d = m / (n − p + 1) ≥ 1,
        // so every span holds at least one parameter (Schoenberg–Whitney) and the end spans
        // hold two, which keeps the normal equations well conditioned.
        let d = m as f64 / (n - degree + 1) as f64;
        for j in 1..=n - degree {
            let jd = j as f64 * d;
            let i = (jd.floor() as usize).min(m - 1);
            let alpha = jd - i as f64;
            knots.push((1.0 - alpha) * params[i] + alpha * params[i + 1]);
        }
        knots.extend(std::iter::repeat_n(1.0, degree + 1));
        let mut shell = BSpline {
            degree,
            knots,
            control_points: Vec::new(),
        };
        let first = points[0];
        let last = points[m];
        if n < 2 {
            shell.control_points = vec![first, last];
            return Ok(shell);
        }
        // Unknowns P_1..P_{n-1}; normal equations (AᵀA) P = Aᵀ R, bandwidth p.
        let unknowns = n - 1;
        let mut band = Band::new(unknowns, degree);
        let mut rhs = vec![SVector::<f64, D>::zeros(); unknowns];
        for (k, &t) in params.iter().enumerate().take(m).skip(1) {
            let span = shell.span(t);
            let basis = shell.basis(span, t);
            let mut r = points[k];
            for (a, &b) in basis.iter().enumerate().take(degree + 1) {
                let i = span - degree + a;
                if i == 0 {
                    r -= first * b;
                } else if i == n {
                    r -= last * b;
                }
            }
            for (a, &ba) in basis.iter().enumerate().take(degree + 1) {
                let i = span - degree + a;
                if i == 0 || i == n {
                    continue;
                }
                rhs[i - 1] += r * ba;
                for (c, &bc) in basis.iter().enumerate().take(degree + 1) {
                    let j = span - degree + c;
                    if j == 0 || j == n {
                        continue;
                    }
                    band.add(i - 1, j - 1, ba * bc)?;
                }
            }
        }
        let inner = band.solve(rhs, "least-squares")?;
        let mut control_points = Vec::with_capacity(count);
        control_points.push(first);
        control_points.extend(inner);
        control_points.push(last);
        shell.control_points = control_points;
        Ok(shell)
    }

    /// The degree `p`.
    pub fn degree(&self) -> usize {
        self.degree
    }

    /// The knot vector.
    pub fn knots(&self) -> &[f64] {
        &self.knots
    }

    /// The control points.
    pub fn control_points(&self) -> &[SVector<f64, D>] {
        &self.control_points
    }

    /// The parameter domain `[u_p, u_n]`.
    pub fn domain(&self) -> RangeInclusive<f64> {
        self.knots[self.degree]..=self.knots[self.control_points.len()]
    }

    /// The point at parameter `t` (clamped to the domain), by de Boor's algorithm.
    pub fn eval(&self, t: f64) -> SVector<f64, D> {
        let t = self.clamp(t);
        let span = self.span(t);
        let p = self.degree;
        let mut d = [SVector::<f64, D>::zeros(); MAX_DEGREE + 1];
        d[..=p].copy_from_slice(&self.control_points[span - p..=span]);
        de_boor(p, &self.knots, span, t, &mut d)
    }

    /// The first derivative `dC/dt` at `t` (clamped to the domain): de Boor's algorithm on the
    /// derivative control points `p (P_{i+1} − P_i) / (u_{i+p+1} − u_{i+1})`, degree `p − 1`.
    pub fn derivative(&self, t: f64) -> SVector<f64, D> {
        let t = self.clamp(t);
        let span = self.span(t);
        let p = self.degree;
        let mut d = [SVector::<f64, D>::zeros(); MAX_DEGREE + 1];
        for (j, slot) in d.iter_mut().enumerate().take(p) {
            let i = span - p + j;
            let h = self.knots[i + p + 1] - self.knots[i + 1];
            if h > 0.0 {
                *slot = (self.control_points[i + 1] - self.control_points[i]) * (p as f64 / h);
            }
        }
        de_boor(p - 1, &self.knots[1..], span - 1, t, &mut d)
    }

    /// The second derivative `d²C/dt²` at `t` (clamped to the domain); zero for degree 1.
    pub fn second_derivative(&self, t: f64) -> SVector<f64, D> {
        let p = self.degree;
        if p < 2 {
            return SVector::zeros();
        }
        let t = self.clamp(t);
        let span = self.span(t);
        let u = &self.knots;
        let first = |i: usize| {
            let h = u[i + p + 1] - u[i + 1];
            if h > 0.0 {
                (self.control_points[i + 1] - self.control_points[i]) * (p as f64 / h)
            } else {
                SVector::zeros()
            }
        };
        let mut d = [SVector::<f64, D>::zeros(); MAX_DEGREE + 1];
        for (j, slot) in d.iter_mut().enumerate().take(p - 1) {
            let i = span - p + j;
            let h = u[i + p + 1] - u[i + 2];
            if h > 0.0 {
                *slot = (first(i + 1) - first(i)) * ((p - 1) as f64 / h);
            }
        }
        de_boor(p - 2, &u[2..], span - 2, t, &mut d)
    }

    /// The closest point of the curve to `point`: its parameter and distance. Spans are visited
    /// nearest first by the distance to the box around their control points (the convex-hull
    /// property bounds the curve), and in each the local minima of the distance are found as the
    /// sign changes of `C'(t)·(C(t) − q)` over 16 samples, solved by safeguarded Newton steps.
    pub fn project(&self, point: &SVector<f64, D>) -> (f64, f64) {
        let boxes = self.span_boxes();
        self.project_with(point, &boxes)
    }

    fn project_with(&self, point: &SVector<f64, D>, boxes: &[SpanBox<D>]) -> (f64, f64) {
        let mut order: Vec<(f64, usize)> = boxes
            .iter()
            .enumerate()
            .map(|(i, b)| (b.distance(point), i))
            .collect();
        order.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut best = (self.knots[self.degree], f64::INFINITY);
        for (lower_bound, index) in order {
            if lower_bound > best.1 {
                break;
            }
            let b = &boxes[index];
            let candidate = self.project_in(point, b.start, b.end);
            if candidate.1 < best.1 {
                best = candidate;
            }
        }
        best
    }

    /// The closest point within span `[a, b]`. The distance has a local minimum where
    /// `g(t) = C'(t)·(C(t) − q)` changes sign from − to +; `g` is sampled at 16 intervals (halved
    /// further where the tangent turns by more than 45°) and every such sign change is solved by
    /// safeguarded Newton iteration (bisection when a step leaves the bracket). The span's ends
    /// and the samples themselves are candidates too.
    fn project_in(&self, point: &SVector<f64, D>, a: f64, b: f64) -> (f64, f64) {
        const SAMPLES: usize = 16;
        let at = |j: usize| a + (b - a) * j as f64 / SAMPLES as f64;
        let mut best = (a, (self.eval(a) - point).norm());
        let mut previous = self.probe(point, a);
        for j in 1..=SAMPLES {
            let current = self.probe(point, at(j));
            self.scan(point, previous, current, 0, &mut best);
            previous = current;
        }
        best
    }

    /// `(t, C'(t), g(t))` at `t`.
    fn probe(&self, point: &SVector<f64, D>, t: f64) -> (f64, SVector<f64, D>, f64) {
        let tangent = self.derivative(t);
        (t, tangent, tangent.dot(&(self.eval(t) - point)))
    }

    /// Looks for a minimum between two probes; an interval over which the tangent turns by more
    /// than 45° (where `g` may change sign twice) is halved, up to 10 times.
    fn scan(
        &self,
        point: &SVector<f64, D>,
        left: (f64, SVector<f64, D>, f64),
        right: (f64, SVector<f64, D>, f64),
        depth: usize,
        best: &mut (f64, f64),
    ) {
        let turn_cos = left.1.dot(&right.1) / (left.1.norm() * right.1.norm());
        // False for a NaN (a zero tangent), which also splits.
        let gentle = turn_cos >= std::f64::consts::FRAC_1_SQRT_2;
        if depth < 10 && !gentle {
            let mid = self.probe(point, 0.5 * (left.0 + right.0));
            self.scan(point, left, mid, depth + 1, best);
            self.scan(point, mid, right, depth + 1, best);
            return;
        }
        let mut consider = |t: f64| {
            let d = (self.eval(t) - point).norm();
            if d < best.1 {
                *best = (t, d);
            }
        };
        consider(right.0);
        if left.2 < 0.0 && right.2 >= 0.0 {
            consider(self.root(point, left.0, right.0));
        }
    }

    /// The root of `g(t) = C'(t)·(C(t) − q)` in `[lo, hi]`, where `g(lo) < 0 ≤ g(hi)`.
    fn root(&self, point: &SVector<f64, D>, mut lo: f64, mut hi: f64) -> f64 {
        let mut t = 0.5 * (lo + hi);
        for _ in 0..60 {
            let offset = self.eval(t) - point;
            let first = self.derivative(t);
            let value = first.dot(&offset);
            if value == 0.0 {
                return t;
            }
            if value < 0.0 {
                lo = t;
            } else {
                hi = t;
            }
            let slope = self.second_derivative(t).dot(&offset) + first.norm_squared();
            let newton = t - value / slope;
            let next = if slope > 0.0 && newton > lo && newton < hi {
                newton
            } else {
                0.5 * (lo + hi)
            };
            if (next - t).abs() <= 1e-15 * (1.0 + t.abs())
                || hi - lo <= f64::EPSILON * (1.0 + t.abs())
            {
                return next;
            }
            t = next;
        }
        t
    }

    /// The largest distance from any of `points` to the curve, each point projected onto the
    /// curve ([`BSpline::project`]), not compared at an assumed parameter. Zero for no points.
    pub fn max_deviation(&self, points: &[SVector<f64, D>]) -> f64 {
        let boxes = self.span_boxes();
        points
            .iter()
            .map(|p| self.project_with(p, &boxes).1)
            .fold(0.0, f64::max)
    }

    /// The arc length in millimetres: adaptive 5-point Gauss–Legendre quadrature of `|C'(t)|`
    /// over each knot span, halving until two levels agree to [`LENGTH_TOLERANCE_MM`].
    pub fn length(&self) -> f64 {
        self.spans().map(|(a, b)| self.length_between(a, b)).sum()
    }

    /// Arc length between parameters `a ≤ b` of one span (adaptive Gauss–Legendre).
    ///
    /// Each piece is accepted when its two halves agree with it to its share (by width) of
    /// [`LENGTH_TOLERANCE_MM`], or to rounding (1e-14 relative); at most [`MAX_PIECES`] pieces
    /// are evaluated per call, which bounds the work on a curve with a cusp.
    fn length_between(&self, a: f64, b: f64) -> f64 {
        /// The most pieces one span is split into.
        const MAX_PIECES: usize = 4096;
        let width = b - a;
        if width <= 0.0 {
            return 0.0;
        }
        let mut stack = vec![(a, b, self.gauss(a, b))];
        let mut total = 0.0;
        let mut pieces = 0;
        while let Some((lo, hi, whole)) = stack.pop() {
            let mid = 0.5 * (lo + hi);
            let left = self.gauss(lo, mid);
            let right = self.gauss(mid, hi);
            let sum = left + right;
            pieces += 1;
            let share = LENGTH_TOLERANCE_MM * (hi - lo) / width;
            let error = (sum - whole).abs();
            if !sum.is_finite()
                || error <= share.max(1e-14 * sum.abs())
                || pieces + stack.len() >= MAX_PIECES
                || mid <= lo
                || mid >= hi
            {
                total += sum;
            } else {
                stack.push((mid, hi, right));
                stack.push((lo, mid, left));
            }
        }
        total
    }

    fn gauss(&self, a: f64, b: f64) -> f64 {
        // 5-point Gauss–Legendre nodes and weights on [-1, 1].
        const NODES: [(f64, f64); 5] = [
            (0.0, 0.568_888_888_888_888_9),
            (-0.538_469_310_105_683_1, 0.478_628_670_499_366_5),
            (0.538_469_310_105_683_1, 0.478_628_670_499_366_5),
            (-0.906_179_845_938_664, 0.236_926_885_056_189_1),
            (0.906_179_845_938_664, 0.236_926_885_056_189_1),
        ];
        let half = 0.5 * (b - a);
        let mid = 0.5 * (a + b);
        half * NODES
            .iter()
            .map(|&(x, w)| w * self.derivative(mid + half * x).norm())
            .sum::<f64>()
    }

    /// The parameters of `segments + 1` points at equal arc length along the curve, both ends
    /// included; each lies within [`EQUAL_LENGTH_TOLERANCE_MM`] of its target arc length.
    pub fn equal_length_parameters(&self, segments: usize) -> Result<Vec<f64>, Error> {
        if segments == 0 {
            return Err(Error::OutOfRange {
                name: "segments",
                value: 0.0,
                expected: "must be ≥ 1",
            });
        }
        let spans: Vec<(f64, f64)> = self.spans().collect();
        let mut cumulative = Vec::with_capacity(spans.len() + 1);
        cumulative.push(0.0);
        let mut total = 0.0;
        for &(a, b) in &spans {
            total += self.length_between(a, b);
            cumulative.push(total);
        }
        let domain = self.domain();
        let mut out = Vec::with_capacity(segments + 1);
        out.push(*domain.start());
        for j in 1..segments {
            let target = total * j as f64 / segments as f64;
            let index = cumulative
                .partition_point(|&c| c <= target)
                .saturating_sub(1)
                .min(spans.len() - 1);
            let (a, b) = spans[index];
            let remaining = target - cumulative[index];
            out.push(self.parameter_in_span(a, b, remaining));
        }
        out.push(*domain.end());
        Ok(out)
    }

    /// `segments + 1` points at equal arc length, both ends included (seed 001 §5.5 "divided
    /// into equal length segments"), to [`EQUAL_LENGTH_TOLERANCE_MM`] in arc length.
    pub fn equal_length(&self, segments: usize) -> Result<Vec<SVector<f64, D>>, Error> {
        Ok(self
            .equal_length_parameters(segments)?
            .into_iter()
            .map(|t| self.eval(t))
            .collect())
    }

    /// The parameter in span `[a, b]` at arc length `s` from `a`: safeguarded Newton iteration.
    fn parameter_in_span(&self, a: f64, b: f64, s: f64) -> f64 {
        let span_length = self.length_between(a, b);
        if span_length <= 0.0 {
            return a;
        }
        let (mut lo, mut hi) = (a, b);
        let mut t = a + (b - a) * (s / span_length).clamp(0.0, 1.0);
        for _ in 0..100 {
            let f = self.length_between(a, t) - s;
            if f.abs() <= 0.1 * EQUAL_LENGTH_TOLERANCE_MM {
                break;
            }
            if f > 0.0 {
                hi = t;
            } else {
                lo = t;
            }
            let speed = self.derivative(t).norm();
            let newton = t - f / speed;
            t = if speed > 0.0 && newton > lo && newton < hi {
                newton
            } else {
                0.5 * (lo + hi)
            };
            if hi - lo <= f64::EPSILON * (b - a).abs() {
                break;
            }
        }
        t
    }

    /// The non-empty knot spans `[u_k, u_{k+1}]`.
    fn spans(&self) -> impl Iterator<Item = (f64, f64)> + '_ {
        (self.degree..self.control_points.len())
            .map(|k| (self.knots[k], self.knots[k + 1]))
            .filter(|(a, b)| b > a)
    }

    fn span_boxes(&self) -> Vec<SpanBox<D>> {
        let p = self.degree;
        (p..self.control_points.len())
            .filter(|&k| self.knots[k + 1] > self.knots[k])
            .map(|k| {
                let hull = &self.control_points[k - p..=k];
                let mut min = hull[0];
                let mut max = hull[0];
                for q in hull {
                    min = min.inf(q);
                    max = max.sup(q);
                }
                SpanBox {
                    start: self.knots[k],
                    end: self.knots[k + 1],
                    min,
                    max,
                }
            })
            .collect()
    }

    fn clamp(&self, t: f64) -> f64 {
        let (a, b) = (
            self.knots[self.degree],
            self.knots[self.control_points.len()],
        );
        if t.is_nan() { a } else { t.clamp(a, b) }
    }

    /// The span `k` with `u_k ≤ t < u_{k+1}` (the last non-empty span for `t` at the end).
    fn span(&self, t: f64) -> usize {
        let p = self.degree;
        // The control-point count, from the knots (set before the control points while solving).
        let n = self.knots.len() - p - 1;
        if t >= self.knots[n] {
            let mut k = n - 1;
            while k > p && self.knots[k] >= self.knots[k + 1] {
                k -= 1;
            }
            return k;
        }
        // Largest k in [p, n-1] with u_k ≤ t.
        let k = self.knots[..n].partition_point(|&u| u <= t);
        k.saturating_sub(1).clamp(p, n - 1)
    }

    /// The `p + 1` non-zero basis functions `N_{span-p..=span, p}(t)` (Cox–de Boor recursion).
    fn basis(&self, span: usize, t: f64) -> [f64; MAX_DEGREE + 1] {
        let p = self.degree;
        let mut n = [0.0; MAX_DEGREE + 1];
        let mut left = [0.0; MAX_DEGREE + 1];
        let mut right = [0.0; MAX_DEGREE + 1];
        n[0] = 1.0;
        for j in 1..=p {
            left[j] = t - self.knots[span + 1 - j];
            right[j] = self.knots[span + j] - t;
            let mut saved = 0.0;
            for r in 0..j {
                let denominator = right[r + 1] + left[j - r];
                let temp = if denominator != 0.0 {
                    n[r] / denominator
                } else {
                    0.0
                };
                n[r] = saved + right[r + 1] * temp;
                saved = left[j - r] * temp;
            }
            n[j] = saved;
        }
        n
    }
}

/// De Boor's algorithm on the local control points `d[0..=p]` of span `span` of `knots`.
fn de_boor<const D: usize>(
    p: usize,
    knots: &[f64],
    span: usize,
    t: f64,
    d: &mut [SVector<f64, D>; MAX_DEGREE + 1],
) -> SVector<f64, D> {
    for r in 1..=p {
        for j in (r..=p).rev() {
            let lo = knots[j + span - p];
            let hi = knots[j + 1 + span - r];
            let alpha = if hi > lo { (t - lo) / (hi - lo) } else { 0.0 };
            d[j] = d[j - 1] * (1.0 - alpha) + d[j] * alpha;
        }
    }
    d[p]
}

/// The box around one span's control points, and the span's parameters.
#[derive(Debug, Clone, Copy)]
struct SpanBox<const D: usize> {
    start: f64,
    end: f64,
    min: SVector<f64, D>,
    max: SVector<f64, D>,
}

impl<const D: usize> SpanBox<D> {
    fn distance(&self, p: &SVector<f64, D>) -> f64 {
        let mut sum = 0.0;
        for i in 0..D {
            let excess = (self.min[i] - p[i]).max(p[i] - self.max[i]).max(0.0);
            sum += excess * excess;
        }
        sum.sqrt()
    }
}

fn polyline_length<const D: usize>(points: &[SVector<f64, D>]) -> f64 {
    points.windows(2).map(|w| (w[1] - w[0]).norm()).sum()
}

/// Chord-length parameters on `[0, 1]`.
fn chord_parameters<const D: usize>(points: &[SVector<f64, D>]) -> Result<Vec<f64>, Error> {
    let mut params = Vec::with_capacity(points.len());
    params.push(0.0);
    let mut total = 0.0;
    for (index, pair) in points.windows(2).enumerate() {
        let chord = (pair[1] - pair[0]).norm();
        if chord <= 0.0 {
            return Err(Error::CoincidentPoints { index: index + 1 });
        }
        total += chord;
        params.push(total);
    }
    for t in &mut params {
        *t /= total;
    }
    if let Some(last) = params.last_mut() {
        *last = 1.0;
    }
    Ok(params)
}

fn check_points<const D: usize>(
    points: &[SVector<f64, D>],
    what: &'static str,
    needed: usize,
) -> Result<(), Error> {
    if points.len() < needed {
        return Err(Error::TooFewPoints {
            what,
            count: points.len(),
            needed,
        });
    }
    if let Some(index) = points.iter().position(|p| p.iter().any(|c| !c.is_finite())) {
        return Err(Error::NonFinitePoint { index });
    }
    Ok(())
}

/// A square banded matrix (half-bandwidth `w`) solved by Gaussian elimination without pivoting,
/// which is stable for B-spline collocation matrices (totally positive) and for the symmetric
/// positive definite normal equations.
#[derive(Debug)]
struct Band {
    n: usize,
    w: usize,
    data: Vec<f64>,
}

impl Band {
    fn new(n: usize, w: usize) -> Self {
        Band {
            n,
            w,
            data: vec![0.0; n * (2 * w + 1)],
        }
    }

    fn index(&self, row: usize, col: usize) -> Option<usize> {
        (row < self.n && col < self.n && col + self.w >= row && col <= row + self.w)
            .then(|| row * (2 * self.w + 1) + col + self.w - row)
    }

    fn add(&mut self, row: usize, col: usize, value: f64) -> Result<(), Error> {
        let i = self.index(row, col).ok_or(Error::SingularSystem {
            system: "banded",
            row,
        })?;
        self.data[i] += value;
        Ok(())
    }

    fn get(&self, row: usize, col: usize) -> f64 {
        self.index(row, col).map_or(0.0, |i| self.data[i])
    }

    fn solve<const D: usize>(
        mut self,
        mut rhs: Vec<SVector<f64, D>>,
        system: &'static str,
    ) -> Result<Vec<SVector<f64, D>>, Error> {
        let n = self.n;
        let w = self.w;
        let scale = self.data.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for k in 0..n {
            let pivot = self.get(k, k);
            if pivot.abs() <= 1e-14 * scale || !pivot.is_finite() {
                return Err(Error::SingularSystem { system, row: k });
            }
            for i in k + 1..(k + w + 1).min(n) {
                let factor = self.get(i, k) / pivot;
                if factor == 0.0 {
                    continue;
                }
                for j in k..(k + w + 1).min(n) {
                    let v = self.get(k, j);
                    if let Some(index) = self.index(i, j) {
                        self.data[index] -= factor * v;
                    }
                }
                let r = rhs[k];
                rhs[i] -= r * factor;
            }
        }
        for i in (0..n).rev() {
            let mut sum = rhs[i];
            let end = (i + w + 1).min(n);
            for (j, x) in rhs.iter().enumerate().take(end).skip(i + 1) {
                sum -= x * self.get(i, j);
            }
            rhs[i] = sum / self.get(i, i);
        }
        Ok(rhs)
    }
}

/// The lathe winder's uniform cubic approximating B-spline (seed 000 §8.8.1, §9.6; `docs/seed-readings.md` V000-1 to V000-6).
///
/// Segment `i` (0-based) uses control points `P_i … P_{i+3}` and is
/// `P(t) = B₀(t) P_i + B₁(t) P_{i+1} + B₂(t) P_{i+2} + B₃(t) P_{i+3}`, `t ∈ [0, 1]`, with
/// `B₀ = (1−t)³/6`, `B₁ = (3t³−6t²+4)/6`, `B₂ = (−3t³+3t²+3t+1)/6`, `B₃ = t³/6`.
/// It approximates: the curve passes near, not through, interior points (node residual
/// `d_i = (P_{i−1} − 2P_i + P_{i+1})/6`, `docs/seed-readings.md` R000-8).
#[derive(Debug, Clone, PartialEq)]
pub struct UniformCubic<const D: usize> {
    control_points: Vec<SVector<f64, D>>,
}

impl<const D: usize> UniformCubic<D> {
    /// The spline of a part program's absolute points with the first and last point tripled
    /// (§9.6: "adds two extra points which have the same coordinates as the given starting
    /// point ... The same treatment is applied for the end point"), so the curve starts and ends
    /// exactly on them with zero velocity. At least two points.
    pub fn new(points: &[SVector<f64, D>]) -> Result<Self, Error> {
        check_points(points, "uniform cubic b-spline", 2)?;
        let first = points[0];
        let last = points[points.len() - 1];
        let mut control_points = Vec::with_capacity(points.len() + 4);
        control_points.extend([first, first]);
        control_points.extend_from_slice(points);
        control_points.extend([last, last]);
        Ok(UniformCubic { control_points })
    }

    /// The spline of `control_points` exactly as given (no tripling), as in Fig 8-3. At least
    /// four points.
    pub fn from_control_points(control_points: Vec<SVector<f64, D>>) -> Result<Self, Error> {
        check_points(&control_points, "uniform cubic b-spline", 4)?;
        Ok(UniformCubic { control_points })
    }

    /// The control points (with the tripled ends when built by [`UniformCubic::new`]).
    pub fn control_points(&self) -> &[SVector<f64, D>] {
        &self.control_points
    }

    /// The number of segments, `m − 3` for `m` control points.
    pub fn segment_count(&self) -> usize {
        self.control_points.len() - 3
    }

    /// The §8.8.1 coefficients `[a₀, a₁, a₂, a₃]` of segment `segment` (`P(t) = a₃t³ + a₂t² +
    /// a₁t + a₀`), or `None` past the last segment.
    pub fn coefficients(&self, segment: usize) -> Option<[SVector<f64, D>; 4]> {
        let w = self.control_points.get(segment..segment + 4)?;
        let (p0, p1, p2, p3) = (w[0], w[1], w[2], w[3]);
        Some([
            (p0 + p1 * 4.0 + p2) / 6.0,
            (p2 - p0) / 2.0,
            (p0 - p1 * 2.0 + p2) / 2.0,
            (-p0 + p1 * 3.0 - p2 * 3.0 + p3) / 6.0,
        ])
    }

    /// The point of segment `segment` at `t ∈ [0, 1]` (`t` is clamped), or `None` past the last
    /// segment.
    pub fn eval(&self, segment: usize, t: f64) -> Option<SVector<f64, D>> {
        let [a0, a1, a2, a3] = self.coefficients(segment)?;
        let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
        Some(((a3 * t + a2) * t + a1) * t + a0)
    }

    /// Position and the first three derivatives with respect to the segment parameter
    /// `[P, dP/dt, d²P/dt², d³P/dt³]` of segment `segment` at `t ∈ [0, 1]` (clamped), or `None`
    /// past the last segment. Divide the k-th derivative by `T^k` for a segment traversed in time
    /// `T`: velocity, acceleration and jerk (§8.8.1: continuous up to the second derivative; the
    /// jerk `6 a₃` is constant within a segment and steps at the joins).
    pub fn derivatives(&self, segment: usize, t: f64) -> Option<[SVector<f64, D>; 4]> {
        let [a0, a1, a2, a3] = self.coefficients(segment)?;
        let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
        Some([
            ((a3 * t + a2) * t + a1) * t + a0,
            (a3 * (3.0 * t) + a2 * 2.0) * t + a1,
            a3 * (6.0 * t) + a2 * 2.0,
            a3 * 6.0,
        ])
    }

    /// The number of knot-points [`UniformCubic::sample`] gives: `K = (m − 3) N + 1`.
    pub fn knot_count(&self, knots_per_segment: usize) -> usize {
        self.segment_count() * knots_per_segment + 1
    }

    /// The knot-points (§9.6, Fig 9-3): every segment sampled at `t = j/N`, `j = 0 … N−1`, plus
    /// the final point, `K = (m − 3) N + 1` points for `m` control points. `N` is the FW-CNC.PAR
    /// "number of knot points to be interpolated between two points", read as intervals per
    /// segment (`docs/seed-readings.md` R000-5).
    pub fn sample(&self, knots_per_segment: usize) -> Result<Vec<SVector<f64, D>>, Error> {
        if knots_per_segment == 0 {
            return Err(Error::OutOfRange {
                name: "knots_per_segment",
                value: 0.0,
                expected: "must be ≥ 1",
            });
        }
        let segments = self.segment_count();
        let mut out = Vec::with_capacity(segments * knots_per_segment + 1);
        for i in 0..segments {
            let w = &self.control_points[i..i + 4];
            let (p0, p1, p2, p3) = (w[0], w[1], w[2], w[3]);
            let a0 = (p0 + p1 * 4.0 + p2) / 6.0;
            let a1 = (p2 - p0) / 2.0;
            let a2 = (p0 - p1 * 2.0 + p2) / 2.0;
            let a3 = (-p0 + p1 * 3.0 - p2 * 3.0 + p3) / 6.0;
            for j in 0..knots_per_segment {
                let t = j as f64 / knots_per_segment as f64;
                out.push(((a3 * t + a2) * t + a1) * t + a0);
            }
        }
        let w = &self.control_points[segments - 1..segments + 3];
        out.push((w[1] + w[2] * 4.0 + w[3]) / 6.0);
        Ok(out)
    }

    /// The node residuals `d_i = (P_{i−1} − 2P_i + P_{i+1})/6` of the interior control points
    /// `i = 1 … m−2` (`docs/seed-readings.md` R000-8): how far the curve at node `i` falls short of `P_i`
    /// (the curve there is `P_i + d_i`).
    pub fn node_residuals(&self) -> Vec<SVector<f64, D>> {
        self.control_points
            .windows(3)
            .map(|w| (w[0] - w[1] * 2.0 + w[2]) / 6.0)
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;
    use nalgebra::{Vector1, Vector2, Vector3};
    use proptest::prelude::*;

    fn circle(radius_mm: f64, count: usize) -> Vec<Vector2<f64>> {
        (0..count)
            .map(|i| {
                let a = std::f64::consts::PI * 1.5 * i as f64 / (count - 1) as f64;
                Vector2::new(radius_mm * a.cos(), radius_mm * a.sin())
            })
            .collect()
    }

    fn helix(count: usize) -> Vec<Vector3<f64>> {
        (0..count)
            .map(|i| {
                let a = 4.0 * std::f64::consts::PI * i as f64 / (count - 1) as f64;
                Vector3::new(50.0 * a.cos(), 50.0 * a.sin(), 20.0 * a)
            })
            .collect()
    }

    #[test]
    fn new_rejects_bad_knots() {
        let pts = vec![Vector1::new(0.0), Vector1::new(1.0)];
        assert!(matches!(
            BSpline::new(1, vec![0.0, 0.0, 1.0], pts.clone()),
            Err(Error::BadKnots { .. })
        ));
        assert!(matches!(
            BSpline::new(1, vec![0.0, 1.0, 1.0, 1.0], pts.clone()),
            Err(Error::BadKnots { index: 1, .. })
        ));
        assert!(matches!(
            BSpline::new(1, vec![0.0, 0.0, 0.0, 0.0], pts.clone()),
            Err(Error::BadKnots { .. })
        ));
        assert!(matches!(
            BSpline::new(0, vec![0.0, 1.0], pts),
            Err(Error::OutOfRange { .. })
        ));
    }

    #[test]
    fn eval_and_derivative_of_a_bezier_segment() {
        // One cubic span with knots 0,0,0,0,1,1,1,1 is the Bézier curve of its control points.
        let p = [0.0, 1.0, 3.0, 2.0].map(Vector1::new).to_vec();
        let s = BSpline::new(3, vec![0., 0., 0., 0., 1., 1., 1., 1.], p).unwrap();
        for t in [0.0, 0.2, 0.5, 0.9, 1.0] {
            let u = 1.0 - t;
            let x = 3.0 * u * u * t + 3.0 * 3.0 * u * t * t + 2.0 * t * t * t;
            // dC/dt = 3 Σ (P_{i+1} − P_i) B_{i,2}(t), differences 1, 2, −1.
            let dx = 3.0 * (u * u + 2.0 * u * t * 2.0 - t * t);
            assert_abs_diff_eq!(s.eval(t).x, x, epsilon = 1e-12);
            assert_abs_diff_eq!(s.derivative(t).x, dx, epsilon = 1e-12);
        }
        assert_eq!(s.domain(), 0.0..=1.0);
    }

    #[test]
    fn derivatives_match_finite_differences() {
        let s = BSpline::interpolate(&helix(30)).unwrap();
        for t in [0.01, 0.3, 0.5, 0.77, 0.99] {
            let h = 1e-6;
            let numeric = (s.eval(t + h) - s.eval(t - h)) / (2.0 * h);
            assert_abs_diff_eq!((s.derivative(t) - numeric).norm(), 0.0, epsilon = 1e-3);
            let h = 1e-4;
            let numeric = (s.derivative(t + h) - s.derivative(t - h)) / (2.0 * h);
            let relative = (s.second_derivative(t) - numeric).norm() / numeric.norm();
            assert!(relative < 1e-5, "t = {t}: {relative}");
        }
        // A quadratic Bézier has the constant second derivative 2 (P0 − 2 P1 + P2).
        let q = BSpline::new(
            2,
            vec![0., 0., 0., 1., 1., 1.],
            [0.0, 5.0, 2.0].map(Vector1::new).to_vec(),
        )
        .unwrap();
        assert_abs_diff_eq!(q.second_derivative(0.3).x, -16.0, epsilon = 1e-12);
        let line = BSpline::interpolate(&[Vector1::new(0.0), Vector1::new(1.0)]).unwrap();
        assert_eq!(line.second_derivative(0.5).x, 0.0);
    }

    #[test]
    fn interpolation_reproduces_a_straight_line_exactly() {
        let a = Vector3::new(1.0, -2.0, 3.0);
        let dir = Vector3::new(3.0, 4.0, 12.0) / 13.0;
        let s_mm = [0.0, 1.0, 5.0, 5.5, 20.0, 21.0, 40.0];
        let pts: Vec<_> = s_mm.iter().map(|&s| a + dir * s).collect();
        let spline = BSpline::interpolate(&pts).unwrap();
        for i in 0..=100 {
            let t = i as f64 / 100.0;
            let expected = a + dir * (40.0 * t);
            assert_abs_diff_eq!((spline.eval(t) - expected).norm(), 0.0, epsilon = 1e-9);
        }
        assert_abs_diff_eq!(spline.length(), 40.0, epsilon = 1e-9);
        assert!(spline.max_deviation(&pts) < 1e-9);
    }

    #[test]
    fn interpolation_passes_through_every_point() {
        let pts = helix(25);
        let s = BSpline::interpolate(&pts).unwrap();
        assert_eq!(s.degree(), 3);
        assert_eq!(s.control_points().len(), 25);
        assert!(s.max_deviation(&pts) < 1e-9);
        assert_abs_diff_eq!((s.eval(0.0) - pts[0]).norm(), 0.0, epsilon = 1e-12);
        assert_abs_diff_eq!((s.eval(1.0) - pts[24]).norm(), 0.0, epsilon = 1e-12);
    }

    #[test]
    fn two_and_three_points_lower_the_degree() {
        let two = [Vector2::new(0.0, 0.0), Vector2::new(3.0, 4.0)];
        let s = BSpline::interpolate(&two).unwrap();
        assert_eq!(s.degree(), 1);
        assert_abs_diff_eq!(s.length(), 5.0, epsilon = 1e-12);
        let three = [
            Vector2::new(0.0, 0.0),
            Vector2::new(1.0, 1.0),
            Vector2::new(2.0, 0.0),
        ];
        assert_eq!(BSpline::interpolate(&three).unwrap().degree(), 2);
    }

    #[test]
    fn bad_points_are_errors() {
        let one = [Vector2::new(0.0, 0.0)];
        assert!(matches!(
            BSpline::interpolate(&one),
            Err(Error::TooFewPoints { count: 1, .. })
        ));
        let dup = [
            Vector2::new(0.0, 0.0),
            Vector2::new(1.0, 0.0),
            Vector2::new(1.0, 0.0),
        ];
        assert!(matches!(
            BSpline::interpolate(&dup),
            Err(Error::CoincidentPoints { index: 2 })
        ));
        let nan = [Vector2::new(0.0, 0.0), Vector2::new(f64::NAN, 0.0)];
        assert!(matches!(
            BSpline::fit(&nan, 0.1),
            Err(Error::NonFinitePoint { index: 1 })
        ));
        assert!(matches!(
            BSpline::fit(&circle(10.0, 10), 0.0),
            Err(Error::OutOfRange { .. })
        ));
        assert!(UniformCubic::<2>::new(&one).is_err());
        assert!(
            UniformCubic::new(&circle(1.0, 5))
                .unwrap()
                .sample(0)
                .is_err()
        );
    }

    #[test]
    fn circle_is_fitted_to_tolerance_with_few_control_points() {
        let radius_mm = 100.0;
        let pts = circle(radius_mm, 361);
        let tolerance_mm = 0.01;
        let s = BSpline::fit(&pts, tolerance_mm).unwrap();
        assert!(s.max_deviation(&pts) <= tolerance_mm);
        assert!(
            s.control_points().len() < 40,
            "{} control points",
            s.control_points().len()
        );
        // Ends kept exactly.
        assert_eq!(s.eval(0.0), pts[0]);
        assert_eq!(s.eval(1.0), pts[360]);
        // Between the data points the curve stays on the circle too.
        for i in 0..=1000 {
            let r = s.eval(i as f64 / 1000.0).norm();
            assert!((r - radius_mm).abs() < 2.0 * tolerance_mm, "r = {r}");
        }
        // One control point fewer misses the tolerance (the count is minimal where bisection ends).
        let fewer = s.control_points().len() - 1;
        let params = chord_parameters(&pts).unwrap();
        let worse = BSpline::least_squares(&pts, &params, 3, fewer).unwrap();
        assert!(worse.max_deviation(&pts) > tolerance_mm);
        // The arc length is that of three quarters of a circle.
        assert_abs_diff_eq!(
            s.length(),
            1.5 * std::f64::consts::PI * radius_mm,
            epsilon = 0.05
        );
    }

    #[test]
    fn max_deviation_projects_rather_than_compares_parameters() {
        // A straight line from 0 to 10 on x; a point above x = 7 is 2 mm away whatever its
        // chord parameter would have been.
        let s = BSpline::interpolate(&[Vector2::new(0.0, 0.0), Vector2::new(10.0, 0.0)]).unwrap();
        assert_abs_diff_eq!(
            s.max_deviation(&[Vector2::new(7.0, 2.0)]),
            2.0,
            epsilon = 1e-9
        );
        let (t, d) = s.project(&Vector2::new(7.0, -3.0));
        assert_abs_diff_eq!(t, 0.7, epsilon = 1e-12);
        assert_abs_diff_eq!(d, 3.0, epsilon = 1e-9);
        // Beyond the end, the end point is nearest.
        assert_abs_diff_eq!(
            s.max_deviation(&[Vector2::new(13.0, 4.0)]),
            5.0,
            epsilon = 1e-9
        );
    }

    #[test]
    fn helix_is_divided_into_equal_lengths() {
        let pts = helix(200);
        let s = BSpline::interpolate(&pts).unwrap();
        // True helix length: 4π turns-angle × sqrt(50² + 20²).
        let exact = 4.0 * std::f64::consts::PI * (50f64.powi(2) + 20f64.powi(2)).sqrt();
        assert_abs_diff_eq!(s.length(), exact, epsilon = 1e-3);
        let segments = 60;
        let params = s.equal_length_parameters(segments).unwrap();
        assert_eq!(params.len(), segments + 1);
        let step = s.length() / segments as f64;
        for pair in params.windows(2) {
            let arc = s.length_between(pair[0], pair[1]);
            assert_abs_diff_eq!(arc, step, epsilon = 10.0 * EQUAL_LENGTH_TOLERANCE_MM);
        }
        let points = s.equal_length(segments).unwrap();
        assert_eq!(points.len(), segments + 1);
        assert_eq!(points[0], pts[0]);
        assert_abs_diff_eq!((points[segments] - pts[199]).norm(), 0.0, epsilon = 1e-12);
        // Equal arcs of a helix have equal chords.
        let chord = 2.0 * 50.0 * (step / exact * 2.0 * std::f64::consts::PI).sin();
        let _ = chord;
        let chords: Vec<f64> = points.windows(2).map(|w| (w[1] - w[0]).norm()).collect();
        let mean = chords.iter().sum::<f64>() / chords.len() as f64;
        for c in chords {
            assert_abs_diff_eq!(c, mean, epsilon = 1e-4);
        }
        assert!(s.equal_length(0).is_err());
    }

    // Seed 000 test vectors (`docs/seed-readings.md` V000-1 to V000-6).

    #[test]
    fn uniform_cubic_reproduces_a_line_and_the_coefficients() {
        // §7 item 1: X = [0, 10, 20, 30] gives a₀ = 10, a₁ = 10, a₂ = 0, a₃ = 0; X(0.5) = 15.
        let s =
            UniformCubic::from_control_points([0.0, 10.0, 20.0, 30.0].map(Vector1::new).to_vec())
                .unwrap();
        let [a0, a1, a2, a3] = s.coefficients(0).unwrap();
        assert_abs_diff_eq!(a0.x, 10.0, epsilon = 1e-12);
        assert_abs_diff_eq!(a1.x, 10.0, epsilon = 1e-12);
        assert_abs_diff_eq!(a2.x, 0.0, epsilon = 1e-12);
        assert_abs_diff_eq!(a3.x, 0.0, epsilon = 1e-12);
        assert_abs_diff_eq!(s.eval(0, 0.5).unwrap().x, 15.0, epsilon = 1e-12);
        // X = [0, 0, 60, 60]: a₀ = 10, a₁ = 30, a₂ = 30, a₃ = −20, X(1) = 50.
        let s =
            UniformCubic::from_control_points([0.0, 0.0, 60.0, 60.0].map(Vector1::new).to_vec())
                .unwrap();
        let [a0, a1, a2, a3] = s.coefficients(0).unwrap();
        assert_abs_diff_eq!(a0.x, 10.0, epsilon = 1e-12);
        assert_abs_diff_eq!(a1.x, 30.0, epsilon = 1e-12);
        assert_abs_diff_eq!(a2.x, 30.0, epsilon = 1e-12);
        assert_abs_diff_eq!(a3.x, -20.0, epsilon = 1e-12);
        assert_abs_diff_eq!(s.eval(0, 1.0).unwrap().x, 50.0, epsilon = 1e-12);
        assert!(s.eval(1, 0.0).is_none());
    }

    #[test]
    fn uniform_cubic_straight_lines_stay_straight_with_tripled_ends() {
        // Collinear, equally spaced points: the whole curve lies on the line, ends are hit.
        let pts: Vec<_> = (0..6)
            .map(|i| Vector3::new(1.0, 2.0, 3.0) * i as f64)
            .collect();
        let s = UniformCubic::new(&pts).unwrap();
        let samples = s.sample(5).unwrap();
        let dir = Vector3::new(1.0, 2.0, 3.0).normalize();
        for q in &samples {
            assert_abs_diff_eq!(q.cross(&dir).norm(), 0.0, epsilon = 1e-12);
        }
        assert_eq!(samples[0], pts[0]);
        assert_abs_diff_eq!(
            (samples[samples.len() - 1] - pts[5]).norm(),
            0.0,
            epsilon = 1e-12
        );
        // Interior equally spaced collinear nodes have zero residual.
        for d in &s.node_residuals()[2..s.control_points().len() - 4] {
            assert_abs_diff_eq!(d.norm(), 0.0, epsilon = 1e-12);
        }
    }

    #[test]
    fn uniform_cubic_joints_are_c2() {
        // §7 item 2: seg_i(1) = seg_{i+1}(0), and the first two derivatives match.
        let p = [0.0, 3.0, -1.0, 7.0, 2.0].map(Vector1::new).to_vec();
        let s = UniformCubic::from_control_points(p.clone()).unwrap();
        let [_, b1, b2, b3] = s.coefficients(0).unwrap();
        let [c0, c1, c2, _] = s.coefficients(1).unwrap();
        assert_abs_diff_eq!(s.eval(0, 1.0).unwrap().x, c0.x, epsilon = 1e-12);
        assert_abs_diff_eq!(
            s.eval(0, 1.0).unwrap().x,
            (p[1].x + 4.0 * p[2].x + p[3].x) / 6.0,
            epsilon = 1e-12
        );
        assert_abs_diff_eq!(b1.x + 2.0 * b2.x + 3.0 * b3.x, c1.x, epsilon = 1e-12);
        assert_abs_diff_eq!(2.0 * b2.x + 6.0 * b3.x, 2.0 * c2.x, epsilon = 1e-12);
    }

    #[test]
    fn uniform_cubic_output_lengths() {
        // §7 item 3: Fig 8-3, m = 7 control points, N = 4: K = 17; tripled (m = 11): K = 33.
        let v: Vec<_> = (0..7)
            .map(|i| Vector2::new(i as f64, (i * i) as f64))
            .collect();
        let plain = UniformCubic::from_control_points(v.clone()).unwrap();
        assert_eq!(plain.sample(4).unwrap().len(), 17);
        let tripled = UniformCubic::new(&v).unwrap();
        assert_eq!(tripled.control_points().len(), 11);
        assert_eq!(tripled.sample(4).unwrap().len(), 33);
    }

    #[test]
    fn uniform_cubic_derivatives_match_finite_differences_and_rest_at_tripled_ends() {
        let pts: Vec<_> = [0.0, 3.0, -2.0, 7.0, 7.5]
            .iter()
            .map(|&v| Vector1::new(v))
            .collect();
        let s = UniformCubic::new(&pts).unwrap();
        let h = 1e-4;
        for seg in 0..s.segment_count() {
            for t in [0.2, 0.5, 0.8] {
                let [p, v, a, j] = s.derivatives(seg, t).unwrap();
                let f = |t: f64| s.eval(seg, t).unwrap().x;
                assert_abs_diff_eq!(p.x, f(t), epsilon = 1e-12);
                assert_abs_diff_eq!(v.x, (f(t + h) - f(t - h)) / (2.0 * h), epsilon = 1e-6);
                assert_abs_diff_eq!(
                    a.x,
                    (f(t + h) - 2.0 * f(t) + f(t - h)) / (h * h),
                    epsilon = 1e-4
                );
                let g = |t: f64| s.derivatives(seg, t).unwrap()[2].x;
                assert_abs_diff_eq!(j.x, (g(t + h) - g(t - h)) / (2.0 * h), epsilon = 1e-6);
            }
        }
        // Tripled ends: at rest, no acceleration, at both ends; C² at the joins.
        let [p0, v0, a0, _] = s.derivatives(0, 0.0).unwrap();
        assert_eq!((p0.x, v0.x, a0.x), (0.0, 0.0, 0.0));
        let last = s.segment_count() - 1;
        let [p1, v1, a1, _] = s.derivatives(last, 1.0).unwrap();
        assert_abs_diff_eq!(p1.x, 7.5, epsilon = 1e-12);
        assert_abs_diff_eq!(v1.x, 0.0, epsilon = 1e-12);
        assert_abs_diff_eq!(a1.x, 0.0, epsilon = 1e-12);
        for seg in 1..s.segment_count() {
            let end = s.derivatives(seg - 1, 1.0).unwrap();
            let start = s.derivatives(seg, 0.0).unwrap();
            for k in 0..3 {
                assert_abs_diff_eq!(end[k].x, start[k].x, epsilon = 1e-12);
            }
        }
        assert!(s.derivatives(s.segment_count(), 0.0).is_none());
        assert_eq!(s.knot_count(4), s.sample(4).unwrap().len());
    }

    #[test]
    fn uniform_cubic_tripled_start_ramps_softly() {
        // §7 item 4: P₀ = 0, P₁ = 60, N = 4: 0, 0.15625, 1.25, 4.21875, 10.
        let s = UniformCubic::new(&[Vector1::new(0.0), Vector1::new(60.0)]).unwrap();
        let k = s.sample(4).unwrap();
        for (got, want) in k.iter().zip([0.0, 0.15625, 1.25, 4.21875, 10.0]) {
            assert_abs_diff_eq!(got.x, want, epsilon = 1e-12);
        }
        assert_abs_diff_eq!(k[k.len() - 1].x, 60.0, epsilon = 1e-12);
    }

    #[test]
    fn uniform_cubic_out_and_back_reaches_two_thirds() {
        // §7 item 5: [0,0,0,10000,0,0,0] at N = 1 gives 0, 1666.67, 6666.67, 1666.67, 0.
        let s = UniformCubic::new(&[0.0, 10000.0, 0.0].map(Vector1::new)).unwrap();
        let k: Vec<f64> = s.sample(1).unwrap().iter().map(|v| v.x).collect();
        let want = [0.0, 10000.0 / 6.0, 20000.0 / 3.0, 10000.0 / 6.0, 0.0];
        assert_eq!(k.len(), want.len());
        for (got, want) in k.iter().zip(want) {
            assert_abs_diff_eq!(*got, want, epsilon = 1e-9);
        }
        // Tripling the turnaround reaches it exactly.
        let s =
            UniformCubic::new(&[0.0, 10000.0, 10000.0, 10000.0, 0.0].map(Vector1::new)).unwrap();
        let peak = s.sample(1).unwrap().iter().map(|v| v.x).fold(0.0, f64::max);
        assert_abs_diff_eq!(peak, 10000.0, epsilon = 1e-9);
    }

    /// Fig 9-1 (seed 000): the O999 circuit as incremental (A deg, X mm, Y mm).
    const FIG_9_1: [(f64, f64, f64); 26] = [
        (10.13, 15.79, 0.0),
        (10.64, 18.01, 0.0),
        (9.79, 19.18, 0.0),
        (17.68, 42.61, 0.0),
        (13.03, 45.36, 0.0),
        (34.77, 119.56, 0.0),
        (18.10, 54.48, 25.70),
        (17.54, 9.39, 28.53),
        (18.98, 5.77, 17.57),
        (26.04, 1.21, 3.64),
        (25.89, -3.12, -9.45),
        (19.66, -7.55, -22.96),
        (16.58, -21.14, -43.03),
        (7.94, -31.35, 0.0),
        (8.98, -39.95, 0.0),
        (6.69, -30.29, 0.0),
        (7.88, -39.13, 0.0),
        (14.20, -58.98, 0.0),
        (22.65, -82.27, 0.0),
        (22.40, -79.75, 0.0),
        (57.27, -39.24, 22.44),
        (27.50, 7.43, -22.44),
        (22.46, 32.53, 0.0),
        (22.60, 30.82, 0.0),
        (11.47, 15.64, 0.0),
        (10.11, 14.99, 0.0),
    ];

    #[test]
    fn uniform_cubic_fig_9_1_knot_count_and_node_residuals() {
        // §7 items 3 and 6: 27 absolute points, tripled to 31, N = 4 gives K = 113; the largest
        // |d| are X 12.37 mm, Y 7.48 mm, A 5.81°.
        let mut p = Vector3::zeros();
        let mut pts = vec![p];
        for (a, x, y) in FIG_9_1 {
            p += Vector3::new(a, x, y);
            pts.push(p);
        }
        let s = UniformCubic::new(&pts).unwrap();
        assert_eq!(s.control_points().len(), 31);
        assert_eq!(s.sample(4).unwrap().len(), 113);
        let residuals = s.node_residuals();
        let max = |axis: usize| residuals.iter().map(|d| d[axis].abs()).fold(0.0, f64::max);
        assert_abs_diff_eq!(max(0), 5.81, epsilon = 0.005);
        assert_abs_diff_eq!(max(1), 12.37, epsilon = 0.005);
        assert_abs_diff_eq!(max(2), 7.48, epsilon = 0.005);
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 64, max_shrink_iters: 200, ..ProptestConfig::default() })]

        #[test]
        fn interpolation_hits_random_points(
            steps in prop::collection::vec((0.5f64..20.0, -3.0f64..3.0, -1.0f64..1.0), 1..30)
        ) {
            // A path that moves forward along x so that no two points coincide.
            let mut p = Vector3::zeros();
            let mut pts = vec![p];
            for (dx, dy, dz) in steps {
                p += Vector3::new(dx, dy, dz);
                pts.push(p);
            }
            let s = BSpline::interpolate(&pts).unwrap();
            for (i, q) in pts.iter().enumerate() {
                let d = s.max_deviation(std::slice::from_ref(q));
                prop_assert!(d < 1e-7, "point {} off by {}", i, d);
            }
            let fitted = BSpline::fit(&pts, 0.2).unwrap();
            prop_assert!(fitted.max_deviation(&pts) <= 0.2);
            prop_assert!(fitted.control_points().len() <= pts.len());
            let eq = fitted.equal_length(7).unwrap();
            prop_assert_eq!(eq.len(), 8);
            prop_assert!((eq[0] - pts[0]).norm() < 1e-12);
            prop_assert!((eq[7] - pts[pts.len() - 1]).norm() < 1e-9);
        }

        #[test]
        fn arbitrary_points_give_a_curve_or_an_error(
            grid in prop::collection::vec((-5i32..5, -5i32..5), 0..25),
            tolerance_mm in 0.01f64..2.0,
        ) {
            // Coarse grid points: repeats, back-tracking and collinear runs are common.
            let pts: Vec<Vector2<f64>> = grid
                .iter()
                .map(|&(x, y)| Vector2::new(f64::from(x) * 3.0, f64::from(y) * 3.0))
                .collect();
            if let Ok(s) = BSpline::interpolate(&pts) {
                prop_assert!(s.max_deviation(&pts) < 1e-6);
                prop_assert!(s.length().is_finite());
            }
            if let Ok(s) = BSpline::fit(&pts, tolerance_mm) {
                prop_assert!(s.max_deviation(&pts) <= tolerance_mm);
                let eq = s.equal_length(5).unwrap();
                prop_assert_eq!(eq.len(), 6);
            }
        }

        #[test]
        fn uniform_cubic_hits_both_ends(
            xs in prop::collection::vec(-1000.0f64..1000.0, 2..20),
            n in 1usize..10,
        ) {
            let pts: Vec<_> = xs.iter().map(|&x| Vector1::new(x)).collect();
            let k = UniformCubic::new(&pts).unwrap().sample(n).unwrap();
            prop_assert_eq!(k.len(), (pts.len() + 1) * n + 1);
            prop_assert!((k[0].x - xs[0]).abs() < 1e-9);
            prop_assert!((k[k.len() - 1].x - xs[xs.len() - 1]).abs() < 1e-9);
        }
    }
}
