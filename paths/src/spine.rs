//! The mandrel spine (directrix): the centroid offset `x(z)` of each cross-section from the rotation
//! axis, as a function of height, in the plane y = 0 of the mandrel frame (seed 001 §3.1, Table 6.1).
//!
//! The measured knots are joined by a natural cubic spline, so the spine is C² and the swept tube has
//! a continuous normal curvature (which the geodesic equation needs). Two knots give a straight spine,
//! which is how the cylinders of seed 001 §6.4 (on axis, offset, tilted) are described.

use crate::Error;

/// A natural cubic spline `x(z)` through measured spine knots `(z_mm, x_mm)`.
#[derive(Debug, Clone, PartialEq)]
pub struct Spine {
    /// Knot heights, strictly increasing.
    z_mm: Vec<f64>,
    /// Per interval `[a, b, c, d]`: `x = a + b t + c t² + d t³` with `t = z - z_i`.
    coefficients: Vec<[f64; 4]>,
}

impl Spine {
    /// Builds the spline through `knots` (height, offset), both in millimetres.
    pub fn new(knots: &[(f64, f64)]) -> Result<Self, Error> {
        if knots.len() < 2 {
            return Err(Error::OutOfRange {
                name: "spine knot count",
                value: knots.len() as f64,
                expected: "at least 2 knots",
            });
        }
        crate::limits::at_most(
            "spine knot count",
            knots.len() as f64,
            crate::limits::MAX_SPINE_KNOTS as f64,
        )?;
        for (index, &(z, x)) in knots.iter().enumerate() {
            if !z.is_finite() || !x.is_finite() {
                return Err(Error::OutOfRange {
                    name: "spine knot",
                    value: if z.is_finite() { x } else { z },
                    expected: "must be finite",
                });
            }
            if index > 0 && z <= knots[index - 1].0 {
                return Err(Error::SpineNotIncreasing {
                    index,
                    height_mm: z,
                });
            }
        }
        let n = knots.len() - 1;
        let h: Vec<f64> = (0..n).map(|i| knots[i + 1].0 - knots[i].0).collect();
        // Second derivatives m_i with m_0 = m_n = 0 (natural), tridiagonal solve (Thomas).
        let mut m = vec![0.0; n + 1];
        if n >= 2 {
            let size = n - 1;
            let mut diag = vec![0.0; size];
            let mut upper = vec![0.0; size];
            let mut rhs = vec![0.0; size];
            for k in 0..size {
                let i = k + 1;
                diag[k] = 2.0 * (h[i - 1] + h[i]);
                upper[k] = h[i];
                rhs[k] = 6.0
                    * ((knots[i + 1].1 - knots[i].1) / h[i]
                        - (knots[i].1 - knots[i - 1].1) / h[i - 1]);
            }
            for k in 1..size {
                let lower = h[k];
                let w = lower / diag[k - 1];
                diag[k] -= w * upper[k - 1];
                rhs[k] -= w * rhs[k - 1];
            }
            for k in (0..size).rev() {
                let next = if k + 1 < size { m[k + 2] } else { 0.0 };
                m[k + 1] = (rhs[k] - upper[k] * next) / diag[k];
            }
        }
        let coefficients = (0..n)
            .map(|i| {
                let a = knots[i].1;
                let b = (knots[i + 1].1 - knots[i].1) / h[i] - h[i] * (2.0 * m[i] + m[i + 1]) / 6.0;
                let c = m[i] / 2.0;
                let d = (m[i + 1] - m[i]) / (6.0 * h[i]);
                [a, b, c, d]
            })
            .collect();
        Ok(Spine {
            z_mm: knots.iter().map(|k| k.0).collect(),
            coefficients,
        })
    }

    /// The cubic smoothing spline (Reinsch) through `knots` whose values stay within
    /// `tolerance_mm` of the measured offsets: the smoothest spine that the measurement accuracy
    /// allows (Table 6.1 is accurate to ±0.5 mm, seed 001 §6.4). A zero tolerance interpolates.
    ///
    /// It minimises `Σ (x_i − g_i)² + α ∫ x''² dz`; `α` is found by bisection on `log α` so that the
    /// largest deviation equals the tolerance.
    pub fn smoothing(knots: &[(f64, f64)], tolerance_mm: f64) -> Result<Self, Error> {
        let interpolating = Spine::new(knots)?;
        if !(tolerance_mm >= 0.0 && tolerance_mm.is_finite()) {
            return Err(Error::OutOfRange {
                name: "spine tolerance_mm",
                value: tolerance_mm,
                expected: "must be ≥ 0",
            });
        }
        if tolerance_mm == 0.0 || knots.len() < 3 {
            return Ok(interpolating);
        }
        let smoothed = |alpha: f64| smoothed_values(knots, alpha);
        let deviation = |values: &[f64]| {
            knots
                .iter()
                .zip(values)
                .map(|(k, g)| (k.1 - g).abs())
                .fold(0.0, f64::max)
        };
        let (mut lo, mut hi) = (-12.0f64, 12.0f64);
        if deviation(&smoothed(10f64.powf(hi))) <= tolerance_mm {
            lo = hi;
        } else {
            for _ in 0..60 {
                let mid = 0.5 * (lo + hi);
                if deviation(&smoothed(10f64.powf(mid))) <= tolerance_mm {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
        }
        let values = smoothed(10f64.powf(lo));
        let points: Vec<(f64, f64)> = knots.iter().zip(&values).map(|(k, &g)| (k.0, g)).collect();
        Spine::new(&points)
    }

    /// A straight spine from `(0, bottom_mm)` to `(height_mm, top_mm)`.
    pub fn straight(height_mm: f64, bottom_mm: f64, top_mm: f64) -> Result<Self, Error> {
        Spine::new(&[(0.0, bottom_mm), (height_mm, top_mm)])
    }

    /// Lowest knot height.
    pub fn z_min_mm(&self) -> f64 {
        self.z_mm[0]
    }

    /// Highest knot height.
    pub fn z_max_mm(&self) -> f64 {
        self.z_mm[self.z_mm.len() - 1]
    }

    /// The knots' heights.
    pub fn knot_heights_mm(&self) -> &[f64] {
        &self.z_mm
    }

    /// Offset and its first three derivatives with respect to height at `z_mm` (the end intervals
    /// are extended beyond the knots).
    pub fn eval(&self, z_mm: f64) -> [f64; 4] {
        self.eval_piece(self.piece_of(z_mm), z_mm)
    }

    /// [`Spine::eval`], trying first the interval `piece` holds (where the last evaluation of a
    /// caller moving along the spine fell), and leaving there the interval used: the same
    /// interval, so the same value, as [`Spine::eval`] gives.
    pub fn eval_near(&self, piece: &std::cell::Cell<usize>, z_mm: f64) -> [f64; 4] {
        let k = &self.z_mm;
        let i = piece.get();
        let i = if i + 1 < k.len()
            && k[i].total_cmp(&z_mm).is_le()
            && z_mm.total_cmp(&k[i + 1]).is_lt()
        {
            i
        } else {
            self.piece_of(z_mm)
        };
        piece.set(i);
        self.eval_piece(i, z_mm)
    }

    /// The interval holding `z_mm`: the last knot at or below it (in `total_cmp` order),
    /// clamped to the first and last interval. Tried first where evenly spaced knots would put
    /// it (the mandrel tables are), then by bisection.
    fn piece_of(&self, z_mm: f64) -> usize {
        let k = &self.z_mm;
        let last = self.coefficients.len() - 1;
        if let (Some(&first), Some(&top)) = (k.first(), k.last()) {
            let guess = (z_mm - first) / (top - first) * (k.len() - 1) as f64;
            if guess >= 0.0 && guess < (k.len() - 1) as f64 {
                // Truncation is the floor here (the guess is not negative).
                let i = guess as usize;
                if k[i].total_cmp(&z_mm).is_le() && z_mm.total_cmp(&k[i + 1]).is_lt() {
                    return i.min(last);
                }
            }
        }
        match k.binary_search_by(|k| k.total_cmp(&z_mm)) {
            Ok(i) => i.min(last),
            Err(0) => 0,
            Err(i) => (i - 1).min(last),
        }
    }

    /// Like [`Spine::eval`], but on the polynomial of interval `piece` (between knots `piece` and
    /// `piece + 1`; clamped to the valid range) wherever `z_mm` lies. At a knot the third
    /// derivative jumps, so a caller integrating across one says which side it means.
    pub fn eval_piece(&self, piece: usize, z_mm: f64) -> [f64; 4] {
        let i = piece.min(self.coefficients.len() - 1);
        let [a, b, c, d] = self.coefficients[i];
        let t = z_mm - self.z_mm[i];
        [
            a + t * (b + t * (c + t * d)),
            b + t * (2.0 * c + 3.0 * d * t),
            2.0 * c + 6.0 * d * t,
            6.0 * d,
        ]
    }

    /// Offset of the section centroid from the rotation axis at `z_mm`.
    pub fn offset_mm(&self, z_mm: f64) -> f64 {
        self.eval(z_mm)[0]
    }

    /// True when every interval is linear with one slope (a straight spine).
    pub fn is_straight(&self) -> bool {
        let slope = self.coefficients[0][1];
        self.coefficients
            .iter()
            .all(|&[_, b, c, d]| c.abs() < 1e-12 && d.abs() < 1e-12 && (b - slope).abs() < 1e-12)
    }
}

/// Smoothed knot values `g = y − α Q γ` with `(R + α QᵀQ) γ = Qᵀ y` (Green & Silverman's
/// formulation of the Reinsch algorithm, unit weights).
fn smoothed_values(knots: &[(f64, f64)], alpha: f64) -> Vec<f64> {
    use nalgebra::{DMatrix, DVector};
    let n = knots.len();
    let h: Vec<f64> = (0..n - 1).map(|i| knots[i + 1].0 - knots[i].0).collect();
    let m = n - 2;
    let mut q = DMatrix::<f64>::zeros(n, m);
    let mut r = DMatrix::<f64>::zeros(m, m);
    for j in 0..m {
        let i = j + 1;
        q[(i - 1, j)] = 1.0 / h[i - 1];
        q[(i, j)] = -1.0 / h[i - 1] - 1.0 / h[i];
        q[(i + 1, j)] = 1.0 / h[i];
        r[(j, j)] = (h[i - 1] + h[i]) / 3.0;
        if j + 1 < m {
            r[(j, j + 1)] = h[i] / 6.0;
            r[(j + 1, j)] = h[i] / 6.0;
        }
    }
    let y = DVector::from_iterator(n, knots.iter().map(|k| k.1));
    let system = &r + (q.transpose() * &q) * alpha;
    let gamma = system
        .cholesky()
        .map(|c| c.solve(&(q.transpose() * &y)))
        .unwrap_or_else(|| DVector::zeros(m));
    (y - q * gamma * alpha).iter().copied().collect()
}

/// How far the S-bend spine may depart from Table 6.1, mm. The interpolating spline bends with a
/// radius of 12.9 mm at 140 mm, and one held to the table's ±0.5 mm still bends with 24.3 mm: a
/// 57 mm tube around either folds onto itself. Within 1.0 mm (inside the mandrel's own ±1.3 mm
/// diametrical deviation, seed 001 App. C) the tightest bend is 61.9 mm.
pub const SBEND_SMOOTHING_MM: f64 = 1.0;

/// The spine of the S-bend mandrel: seed 001 Table 6.1, offsets every 10 mm from the rotation axis.
/// The table gives magnitudes; the spine crosses the axis at 130 mm, so offsets after it are negative.
pub const SBEND_TABLE_6_1_MM: [(f64, f64); 36] = [
    (0.0, 0.0),
    (10.0, 2.5),
    (20.0, 4.0),
    (30.0, 6.0),
    (40.0, 7.5),
    (50.0, 8.5),
    (60.0, 9.0),
    (70.0, 10.0),
    (80.0, 10.0),
    (90.0, 9.5),
    (100.0, 7.0),
    (110.0, 5.0),
    (120.0, 3.0),
    (130.0, 0.0),
    (140.0, -5.0),
    (150.0, -6.0),
    (160.0, -9.0),
    (170.0, -11.5),
    (180.0, -15.0),
    (190.0, -17.0),
    (200.0, -18.0),
    (210.0, -19.0),
    (220.0, -20.0),
    (230.0, -20.0),
    (240.0, -19.0),
    (250.0, -17.5),
    (260.0, -16.0),
    (270.0, -15.5),
    (280.0, -14.0),
    (290.0, -12.0),
    (300.0, -11.0),
    (310.0, -9.0),
    (320.0, -7.0),
    (330.0, -4.5),
    (340.0, -2.0),
    (350.0, 0.0),
];

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;

    /// From any hint, the interval (so every bit of the value) is [`Spine::eval`]'s, at and
    /// between knots, outside the ends and for a NaN; the hint moves to it.
    #[test]
    fn eval_near_is_eval_from_any_hint() {
        let spine = Spine::smoothing(&SBEND_TABLE_6_1_MM, SBEND_SMOOTHING_MM).unwrap();
        let uneven = Spine::new(&[(0.0, 1.0), (3.0, 2.0), (10.0, -1.0), (11.0, 0.5)]).unwrap();
        for spine in [spine, uneven] {
            let knots = spine.knot_heights_mm().to_vec();
            let mut zs: Vec<f64> = knots.clone();
            zs.extend(knots.windows(2).map(|w| 0.5 * (w[0] + w[1])));
            zs.extend(knots.iter().map(|k| k - 1e-9));
            zs.extend([-50.0, 1e9, -0.0, f64::NAN, -f64::NAN, f64::INFINITY]);
            let bits = |a: [f64; 4]| a.map(f64::to_bits);
            for hint in 0..knots.len() + 2 {
                for &z in &zs {
                    let piece = std::cell::Cell::new(hint);
                    assert_eq!(
                        bits(spine.eval_near(&piece, z)),
                        bits(spine.eval(z)),
                        "z = {z}, hint {hint}"
                    );
                    assert_eq!(piece.get(), spine.piece_of(z), "z = {z}, hint {hint}");
                }
            }
        }
    }

    #[test]
    fn passes_through_every_knot_of_table_6_1() {
        let spine = Spine::new(&SBEND_TABLE_6_1_MM).unwrap();
        for &(z, x) in &SBEND_TABLE_6_1_MM {
            assert_abs_diff_eq!(spine.offset_mm(z), x, epsilon = 1e-9);
        }
    }

    #[test]
    fn is_c2_at_interior_knots() {
        let spine = Spine::new(&SBEND_TABLE_6_1_MM).unwrap();
        for &(z, _) in &SBEND_TABLE_6_1_MM[1..35] {
            let below = spine.eval(z - 1e-9);
            let above = spine.eval(z + 1e-9);
            assert_abs_diff_eq!(below[1], above[1], epsilon = 1e-6);
            assert_abs_diff_eq!(below[2], above[2], epsilon = 1e-6);
        }
    }

    #[test]
    fn smoothing_spline_stays_within_tolerance_and_bends_less() {
        let interpolating = Spine::new(&SBEND_TABLE_6_1_MM).unwrap();
        let smooth = Spine::smoothing(&SBEND_TABLE_6_1_MM, 0.5).unwrap();
        let max_curvature = |s: &Spine| {
            (0..=3500)
                .map(|i| {
                    let [_, g, dg, _] = s.eval(i as f64 * 0.1);
                    dg.abs() / (1.0 + g * g).powf(1.5)
                })
                .fold(0.0, f64::max)
        };
        for &(z, x) in &SBEND_TABLE_6_1_MM {
            assert!((smooth.offset_mm(z) - x).abs() <= 0.5 + 1e-9);
        }
        assert!(max_curvature(&smooth) < 0.8 * max_curvature(&interpolating));
        assert_eq!(
            Spine::smoothing(&SBEND_TABLE_6_1_MM, 0.0).unwrap(),
            interpolating
        );
    }

    #[test]
    fn straight_spine_is_linear() {
        let spine = Spine::straight(100.0, 10.0, 30.0).unwrap();
        assert!(spine.is_straight());
        assert_abs_diff_eq!(spine.offset_mm(50.0), 20.0, epsilon = 1e-12);
        assert_abs_diff_eq!(spine.eval(25.0)[1], 0.2, epsilon = 1e-12);
        assert!(!Spine::new(&SBEND_TABLE_6_1_MM).unwrap().is_straight());
    }

    #[test]
    fn rejects_unordered_and_short_knots() {
        assert!(matches!(
            Spine::new(&[(0.0, 0.0), (0.0, 1.0)]),
            Err(Error::SpineNotIncreasing { index: 1, .. })
        ));
        assert!(Spine::new(&[(0.0, 0.0)]).is_err());
        assert!(Spine::new(&[(0.0, f64::NAN), (1.0, 0.0)]).is_err());
    }

    /// The interval found by the even-spacing guess is the one bisection finds, on the S-bend's
    /// even knots and on uneven ones, at knots, between, outside, at ±0 and for NaN.
    #[test]
    fn piece_of_is_the_bisection() {
        let bisect = |s: &Spine, z: f64| match s.z_mm.binary_search_by(|k| k.total_cmp(&z)) {
            Ok(i) => i.min(s.coefficients.len() - 1),
            Err(0) => 0,
            Err(i) => (i - 1).min(s.coefficients.len() - 1),
        };
        let even = Spine::new(&SBEND_TABLE_6_1_MM).unwrap();
        let uneven =
            Spine::new(&[(0.0, 0.0), (1.0, 0.5), (7.5, 1.0), (8.0, 0.2), (40.0, 3.0)]).unwrap();
        for spine in [&even, &uneven] {
            let mut zs: Vec<f64> = (-200..=4000).map(|k| k as f64 * 0.1 - 5.0).collect();
            zs.extend(spine.z_mm.iter().copied());
            zs.extend(spine.z_mm.iter().map(|z| z.next_down()));
            zs.extend([
                0.0,
                -0.0,
                f64::NAN,
                -f64::NAN,
                f64::INFINITY,
                f64::NEG_INFINITY,
            ]);
            for z in zs {
                assert_eq!(spine.piece_of(z), bisect(spine, z), "z = {z}");
            }
        }
    }
}
