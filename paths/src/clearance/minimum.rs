//! The certified minimum of a Lipschitz function on `[0, 1]`.
//!
//! If `|f(x) − f(y)| ≤ L |x − y|`, then on an interval `[a, b]` with end values `fa`, `fb`
//! no value lies below `(fa + fb − L (b − a)) / 2`. The search splits intervals, left first,
//! until that bound rises to within the resolution of the least value found (or, while no value
//! below the threshold has been found, to within the resolution of the threshold). So:
//!
//! - the minimum returned is at most `max(resolution, RELATIVE · |minimum|)` above the true
//!   minimum (a clearance of 80 mm is reported to 0.8 mm, one of 0.5 mm to 0.005 mm);
//! - a dip below `threshold` deeper than `resolution` is always found, and the earliest such
//!   dip is reported (to within the interval where it starts);
//! - intervals shrink to `resolution / L`, so the work is bounded by `2 L / resolution`
//!   evaluations in the worst case and is logarithmic near a single minimum.
//!
//! Signed distance to a solid is 1-Lipschitz in the query point, so along a segment of length
//! `ℓ` (the free fibre) it is `ℓ`-Lipschitz in the segment parameter; over the time of a move it is
//! Lipschitz with the largest speed of any point of the moving part ([`super::sweep`]). This is
//! what bounds what the sweep can miss between its evaluations.

/// The least value of a function over `[0, 1]`, and the first dip below a threshold.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Minimum {
    /// The least value found (within the resolution of the true minimum).
    pub value: f64,
    /// Where it was found.
    pub at: f64,
    /// The earliest point found where the value is below the threshold, and the value there.
    pub first_below: Option<(f64, f64)>,
    /// Evaluations made.
    pub evaluations: usize,
    /// False when the search stopped at [`MAX_EVALUATIONS`] before reaching its resolution.
    pub complete: bool,
}

/// Relative resolution of the reported minimum (see the module documentation).
pub const RELATIVE: f64 = 0.01;

/// Most evaluations of one search; reached only with a Lipschitz constant far beyond any real
/// motion (about `2 L / resolution`), and then reported through [`Minimum::complete`].
pub const MAX_EVALUATIONS: usize = 1 << 16;

/// The minimum of `f` on `[0, 1]`, given its Lipschitz constant `lipschitz` (≥ 0), to within
/// `resolution` (> 0), with the earliest dip below `threshold` (see the module documentation).
pub fn certified_min(
    f: &mut dyn FnMut(f64) -> f64,
    lipschitz: f64,
    resolution: f64,
    threshold: f64,
) -> Minimum {
    search(f, lipschitz, resolution, threshold, true)
}

/// Like [`certified_min`], but only for the earliest dip below `threshold`: intervals are split
/// only while they could hide a value below `threshold − resolution`. The `value` returned is the
/// least value evaluated, an upper bound on the true minimum; when `first_below` is `None` the
/// true minimum is at least `threshold − resolution`. For functions that sit near the threshold's
/// side of zero over long stretches (the free fibre, touching at its tangent point).
pub fn first_below(
    f: &mut dyn FnMut(f64) -> f64,
    lipschitz: f64,
    resolution: f64,
    threshold: f64,
) -> Minimum {
    search(f, lipschitz, resolution, threshold, false)
}

fn search(
    f: &mut dyn FnMut(f64) -> f64,
    lipschitz: f64,
    resolution: f64,
    threshold: f64,
    certify_min: bool,
) -> Minimum {
    let lipschitz = if lipschitz.is_finite() {
        lipschitz.max(0.0)
    } else {
        f64::MAX
    };
    let f0 = f(0.0);
    let f1 = f(1.0);
    let mut m = Minimum {
        value: f0.min(f1),
        at: if f0 <= f1 { 0.0 } else { 1.0 },
        first_below: None,
        evaluations: 2,
        complete: true,
    };
    if f0 < threshold {
        m.first_below = Some((0.0, f0));
    } else if f1 < threshold {
        m.first_below = Some((1.0, f1));
    }
    // Interval stack, left intervals on top; at most one entry per level per side.
    let mut stack: Vec<(f64, f64, f64, f64)> = vec![(0.0, 1.0, f0, f1)];
    let min_width = resolution / lipschitz.max(f64::MIN_POSITIVE);
    while let Some((a, b, fa, fb)) = stack.pop() {
        let lower = 0.5 * (fa + fb - lipschitz * (b - a));
        let first_at = m.first_below.map_or(f64::INFINITY, |(t, _)| t);
        let for_min = certify_min && lower < m.value - resolution.max(RELATIVE * m.value.abs());
        let for_first = a < first_at && lower < threshold - resolution;
        if !(for_min || for_first) || b - a <= min_width {
            continue;
        }
        if m.evaluations >= MAX_EVALUATIONS {
            m.complete = false;
            break;
        }
        let mid = 0.5 * (a + b);
        let fm = f(mid);
        m.evaluations += 1;
        if fm < m.value {
            m.value = fm;
            m.at = mid;
        }
        if fm < threshold && mid < first_at {
            m.first_below = Some((mid, fm));
        }
        stack.push((mid, b, fm, fb));
        stack.push((a, mid, fa, fm));
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_a_narrow_dip_that_the_ends_do_not_show() {
        // A 1-Lipschitz notch 0.002 wide and 0.001 deep at 0.6137, on a constant 0.0005.
        let mut f = |x: f64| 0.0005 + ((x - 0.6137).abs() - 0.001).min(0.0);
        let m = certified_min(&mut f, 1.0, 1e-4, 0.0);
        assert!(m.complete);
        assert!(m.value < -0.0004, "{m:?}");
        assert!((m.at - 0.6137).abs() < 1e-3);
        let (t, v) = m.first_below.unwrap();
        assert!(v < 0.0 && (t - 0.6137).abs() < 1e-3);
    }

    #[test]
    fn reports_the_earliest_of_two_dips_and_the_deeper_minimum() {
        let mut f = |x: f64| {
            let a = (x - 0.3).abs() * 10.0 - 0.5;
            let b = (x - 0.8).abs() * 10.0 - 2.0;
            a.min(b).min(1.0)
        };
        let m = certified_min(&mut f, 10.0, 1e-6, 0.0);
        // To 1 % of the minimum.
        assert!((m.value + 2.0).abs() <= 0.02, "{m:?}");
        assert!((m.at - 0.8).abs() < 0.002);
        let (t, _) = m.first_below.unwrap();
        assert!((0.2499..0.3).contains(&t), "{t}");
    }

    #[test]
    fn first_below_ignores_a_flat_stretch_at_zero_but_finds_a_dip() {
        // Zero over [0, 0.5], then a dip to −0.05 at 0.75 (1-Lipschitz in units of the interval).
        let mut f = |x: f64| {
            if x < 0.5 {
                0.0
            } else {
                -(0.25 - (x - 0.75).abs()).max(0.0) * 0.2
            }
        };
        let m = first_below(&mut f, 1.0, 0.005, -0.01);
        let (t, v) = m.first_below.unwrap();
        assert!(v < -0.01 && t > 0.5 && t < 0.75, "{m:?}");
        assert!(m.evaluations < 2000, "{}", m.evaluations);
        let mut flat = |_: f64| 0.0;
        let m = first_below(&mut flat, 1.0, 0.005, -0.01);
        assert!(m.first_below.is_none());
        assert!(m.evaluations < 200, "{}", m.evaluations);
    }

    #[test]
    fn clear_function_stops_early() {
        let mut f = |x: f64| 5.0 + x;
        let m = certified_min(&mut f, 1.0, 1e-3, 0.0);
        assert_eq!(m.value, 5.0);
        assert!(m.first_below.is_none());
        assert!(m.evaluations <= 3, "{}", m.evaluations);
    }

    #[test]
    fn nan_lipschitz_is_treated_as_unbounded_and_stops_incomplete() {
        let mut f = |x: f64| x;
        let m = certified_min(&mut f, f64::NAN, 1e-3, -1.0);
        assert_eq!(m.value, 0.0);
        assert!(!m.complete);
        assert_eq!(m.evaluations, MAX_EVALUATIONS);
        let m = certified_min(&mut f, 1.0, 1e-3, -1.0);
        assert!(m.complete);
    }
}
