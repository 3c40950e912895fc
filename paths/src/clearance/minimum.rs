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

/// Relative margin added to the cap handed to a capped function, against rounding.
const CAP_MARGIN: f64 = 1e-12;

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
    search(f, lipschitz, resolution, threshold, f64::INFINITY, true)
}

/// Like [`certified_min`], with two savings for a search that is one of many (the moves of a
/// job, each after the last):
///
/// - The minimum is certified only where it could lie below `ceiling` (the least value already
///   known elsewhere): an interval whose bound cannot fall below `min(value, ceiling)` by more
///   than the tolerance `max(resolution, RELATIVE·|min(value, ceiling)|)` is not split. So
///   either `value` is the minimum to within that tolerance, or the true minimum lies no more
///   than the tolerance below `ceiling`.
/// - `f(t, cap)` may stop short of the exact value when it is at least `cap`: it must return the
///   exact value when that is below `cap`, and otherwise any value from `cap` up to the exact
///   one. The search asks for a `cap` above which the value would change nothing: neither half
///   of the interval would be split, and neither the least value nor the first dip would move.
///   A lower bound in place of the value keeps every interval's bound a true bound.
///
/// Dips below `threshold` are searched for as in [`certified_min`]. When both ends answer at or
/// above their cap (the whole interval then lies above the ceiling, less the tolerance, and above
/// the threshold), the search ends at once with `value` the lesser answer: a bound, not a value
/// the function takes.
pub fn certified_min_below(
    f: &mut dyn FnMut(f64, f64) -> f64,
    lipschitz: f64,
    resolution: f64,
    threshold: f64,
    ceiling: f64,
) -> Minimum {
    search_capped(f, lipschitz, resolution, threshold, ceiling, true)
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
    search(f, lipschitz, resolution, threshold, f64::INFINITY, false)
}

fn search(
    f: &mut dyn FnMut(f64) -> f64,
    lipschitz: f64,
    resolution: f64,
    threshold: f64,
    ceiling: f64,
    certify_min: bool,
) -> Minimum {
    search_capped(
        &mut |t, _| f(t),
        lipschitz,
        resolution,
        threshold,
        ceiling,
        certify_min,
    )
}

fn search_capped(
    f: &mut dyn FnMut(f64, f64) -> f64,
    lipschitz: f64,
    resolution: f64,
    threshold: f64,
    ceiling: f64,
    certify_min: bool,
) -> Minimum {
    let lipschitz = if lipschitz.is_finite() {
        lipschitz.max(0.0)
    } else {
        f64::MAX
    };
    // The ends are needed exactly only where the whole interval could hold a value below the
    // ceiling (or a dip below the threshold): at or above `end_cap` at both ends, it cannot.
    let end_cap = if ceiling.is_finite() && lipschitz < f64::MAX {
        let mut level = threshold - resolution;
        if certify_min {
            level = level.max(ceiling - resolution.max(RELATIVE * ceiling.abs()));
        }
        let cap = level + 0.5 * lipschitz;
        cap + CAP_MARGIN * (1.0 + cap.abs())
    } else {
        f64::INFINITY
    };
    let f0 = f(0.0, end_cap);
    let f1 = f(1.0, end_cap);
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
        let least = m.value.min(ceiling);
        let for_min = certify_min && lower < least - resolution.max(RELATIVE * least.abs());
        let for_first = a < first_at && lower < threshold - resolution;
        if !(for_min || for_first) || b - a <= min_width {
            continue;
        }
        if m.evaluations >= MAX_EVALUATIONS {
            m.complete = false;
            break;
        }
        let mid = 0.5 * (a + b);
        // A half `[x, mid]` (width `w/2`) with end value `fx` is split again only while
        // `(fx + fm − L·w/2)/2` lies below the level it is searched to; with `fm` at or above
        // `cap` it would not be, for either half and either purpose.
        let half = lipschitz * (b - a) * 0.5;
        let fx = fa.min(fb);
        let mut cap = m.value.max(threshold);
        if certify_min {
            let least = m.value.min(ceiling);
            let tol = resolution.max(RELATIVE * least.abs());
            cap = cap.max(2.0 * (least - tol) + half - fx);
        }
        if a < first_at {
            cap = cap.max(2.0 * (threshold - resolution) + half - fx);
        }
        // A hair above, so that the halves' bounds computed from `cap` itself clear their level
        // despite rounding.
        let cap = cap + CAP_MARGIN * (1.0 + cap.abs());
        let fm = f(mid, cap);
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

    /// A 1-Lipschitz saw of notches: `count` dips of random depth and place on a level of 3.
    fn notches(seed: u64, count: usize) -> Vec<(f64, f64)> {
        let mut next = crate::clearance::test_support::uniform(seed);
        (0..count).map(|_| (next(), 4.0 * next())).collect()
    }

    fn saw(dips: &[(f64, f64)], t: f64) -> f64 {
        dips.iter()
            .map(|&(at, depth)| 3.0 - (depth - 10.0 * (t - at).abs()).max(0.0))
            .fold(3.0, f64::min)
    }

    /// The capped search against the plain one on random saws: answering only `cap` wherever
    /// the value is at least `cap` (the least a capped function may say) changes neither the
    /// minimum (to its tolerance) nor the first dip below the threshold; a ceiling below the
    /// minimum leaves it uncertified but never reports a value below the true minimum.
    #[test]
    fn capped_search_finds_what_the_plain_search_finds() {
        for seed in 1..200u64 {
            let dips = notches(
                seed.wrapping_mul(0x9e37_79b9_7f4a_7c15),
                1 + (seed % 5) as usize,
            );
            let exact = |t: f64| saw(&dips, t);
            let dense = (0..=200_000)
                .map(|i| exact(i as f64 / 200_000.0))
                .fold(f64::INFINITY, f64::min);
            let plain = certified_min(&mut |t| exact(t), 10.0, 1e-4, 0.0);
            let mut asked = 0;
            let mut stopped = 0;
            let capped = certified_min_below(
                &mut |t, cap| {
                    asked += 1;
                    let v = exact(t);
                    if v >= cap {
                        stopped += 1;
                        cap
                    } else {
                        v
                    }
                },
                10.0,
                1e-4,
                0.0,
                f64::INFINITY,
            );
            // Both to their stated tolerance (relative to the value found).
            for m in [&capped, &plain] {
                let tol = 1e-4f64.max(RELATIVE * m.value.abs()) + 1e-9;
                assert!((m.value - dense).abs() <= tol, "{seed}: {m:?} vs {dense}");
            }
            assert!(
                capped.value >= dense - 1e-4,
                "{seed}: below the least sample"
            );
            match (plain.first_below, capped.first_below) {
                (None, None) => {}
                (Some((a, _)), Some((b, v))) => {
                    assert!((a - b).abs() < 0.01, "{seed}: first dip {a} vs {b}");
                    assert!(v < 0.0 && (v - exact(b)).abs() < 1e-12);
                }
                other => panic!("{seed}: first dips differ: {other:?}"),
            }
            assert!(asked >= 2 && stopped <= asked);
            // A ceiling below the minimum: nothing is certified, but the value is one the
            // function takes, and the truth lies no lower than the ceiling's tolerance.
            let low = certified_min_below(
                &mut |t, _| exact(t),
                10.0,
                1e-4,
                f64::NEG_INFINITY,
                dense - 1.0,
            );
            assert!(low.value >= dense - 1e-4, "{seed}: below the least sample");
        }
    }

    /// The cap is enough: answering only `cap` wherever the value is at least `cap` splits no
    /// interval that the exact value would not, so the search makes the same evaluations, finds
    /// the same first dip and, without a ceiling, the same minimum at the same place; with a
    /// ceiling the minimum differs only where both ends stopped at their cap.
    #[test]
    fn answering_only_the_cap_changes_nothing_but_the_work() {
        let mut extra = [0usize; 4];
        for seed in 1..300u64 {
            let dips = notches(
                seed.wrapping_mul(0x2545_f491_4f6c_dd1d),
                1 + (seed % 6) as usize,
            );
            let exact = |t: f64| saw(&dips, t) - 2.0;
            let dense = (0..=20_000)
                .map(|i| exact(i as f64 / 20_000.0))
                .fold(f64::INFINITY, f64::min);
            for (k, ceiling) in [f64::INFINITY, dense + 1.0, dense + 0.01, dense - 0.5]
                .into_iter()
                .enumerate()
            {
                let full = certified_min_below(&mut |t, _| exact(t), 10.0, 1e-4, 0.0, ceiling);
                let mut stops = 0;
                let weakest = certified_min_below(
                    &mut |t, cap| {
                        let v = exact(t);
                        if v >= cap {
                            stops += 1;
                            cap
                        } else {
                            v
                        }
                    },
                    10.0,
                    1e-4,
                    0.0,
                    ceiling,
                );
                assert_eq!(full.evaluations, weakest.evaluations, "{seed} {ceiling}");
                assert_eq!(full.first_below, weakest.first_below, "{seed} {ceiling}");
                if ceiling.is_infinite() {
                    assert_eq!(full, weakest, "{seed}");
                } else if weakest.evaluations > 2 {
                    assert_eq!(full.value, weakest.value, "{seed} {ceiling}");
                }
                assert!(stops <= weakest.evaluations);
                // And the cap is no higher than it must be: answering a little less (still no
                // less than any value already returned nor the threshold, so still a valid
                // answer) splits more.
                let mut least = f64::NEG_INFINITY;
                let under = certified_min_below(
                    &mut |t, cap| {
                        let v = exact(t);
                        let answer = if v >= cap {
                            (cap - 1e-6 * (1.0 + cap.abs())).max(least).max(0.0)
                        } else {
                            v
                        };
                        least = if least.is_finite() {
                            least.min(answer)
                        } else {
                            answer
                        };
                        answer
                    },
                    10.0,
                    1e-4,
                    0.0,
                    ceiling,
                );
                assert!(under.evaluations >= full.evaluations, "{seed} {ceiling}");
                extra[k] += under.evaluations - full.evaluations;
            }
        }
        // Every kind of search splits more somewhere when answered below its caps.
        assert!(extra.iter().all(|&e| e > 0), "{extra:?}");
    }

    /// A ceiling saves evaluations: a function whose least value lies far above the ceiling
    /// needs only its two ends.
    #[test]
    fn a_ceiling_below_the_function_saves_evaluations() {
        let dips = notches(7, 4);
        let mut f = |t: f64, _cap: f64| saw(&dips, t) - 2.5;
        let free = certified_min_below(&mut f, 10.0, 1e-4, f64::NEG_INFINITY, f64::INFINITY);
        let ceiling = certified_min_below(&mut f, 10.0, 1e-4, f64::NEG_INFINITY, -20.0);
        assert!(free.evaluations > 10, "{}", free.evaluations);
        assert_eq!(ceiling.evaluations, 2, "{}", ceiling.evaluations);
        // The ends are asked with a cap that both clear (so neither needs its exact value):
        // the ceiling less its tolerance, plus half the Lipschitz bound, here −20.2 + 5.
        let mut caps = Vec::new();
        let capped = certified_min_below(
            &mut |t, cap| {
                caps.push(cap);
                let v = saw(&dips, t) - 2.5;
                if v >= cap { cap } else { v }
            },
            10.0,
            1e-4,
            f64::NEG_INFINITY,
            -20.0,
        );
        assert_eq!(capped.evaluations, 2);
        assert_eq!(caps.len(), 2);
        for cap in caps {
            assert!((cap - (-20.2 + 5.0)).abs() < 1e-9, "{cap}");
        }
        // Answered just under that cap, the ends no longer settle the interval.
        let under = certified_min_below(
            &mut |_, cap| cap - 1e-6,
            10.0,
            1e-4,
            f64::NEG_INFINITY,
            -20.0,
        );
        assert!(under.evaluations > 2, "{}", under.evaluations);
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
