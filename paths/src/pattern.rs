//! Winding patterns for a cylinder with hemispherical ends and equal polar openings (seed 002
//! §2.2, Eqs. 1–9): the geodesic wind angle, the mandrel angles along the cylinder and over a dome,
//! the cycle angle, the pattern pitch snapped to a value that closes, the dwell at the turnarounds,
//! the band-width advance, and the cycles per pattern and per layer.
//!
//! Frame: z is the axial coordinate measured from a dome's equator (its junction with the
//! cylinder) towards its pole; angles are radians inside, degrees in the fields named `_deg`.
//!
//! # Pitch snapping and its tolerance
//!
//! After one cycle (out and back) the tow returns to its start latitude turned by the calculated
//! pitch Φp* (Eq. 7). It closes a pattern only if the pitch is a whole fraction of turns:
//! Φp = 360°·k/n with n cycles per pattern. The seed lists {60, 72, 90, 120, 180}° (360°/n) for
//! 60° < Φp* ≤ 180° and {240, 270, 288, 300, 360}° (360°·(n−1)/n) above 180°, and takes "the next
//! value up"; the gap is closed by a dwell Φf = (Φp − Φp*)/2 at each of the two turnarounds
//! (Eq. 8). We extend both families to n ≤ [`MAX_CYCLES_PER_PATTERN`] so that Φp* ≤ 60° and
//! Φp* > 300° have answers too.
//!
//! The seed's own validation mandrel has Φp* = 60.0125° and was wound as Φp = 60° with no dwell:
//! "the next value up" would have given 72°. So a calculated pitch within
//! [`PITCH_TOLERANCE_DEG`] (0.02°) of an allowed value takes that value with **no dwell**, and the
//! small remainder (Φp* − Φp per cycle) is reported as the layer's closure drift
//! ([`Pattern::closure_drift_deg`]): 24 × 0.0125° = 0.3° (0.31 mm at R = 60 mm, 8 % of a 4 mm
//! band) on the seed's mandrel. Outside the tolerance the next value up is taken and the dwell
//! closes the pattern exactly.

use crate::Error;
use std::f64::consts::{FRAC_PI_2, PI, TAU};

/// A calculated pitch this close to an allowed value (degrees) snaps to it with no dwell.
pub const PITCH_TOLERANCE_DEG: f64 = 0.02;

/// The most cycles a pattern may have (the seed's lists stop at 6; beyond that the pattern is
/// still valid but rarely wanted).
pub const MAX_CYCLES_PER_PATTERN: u32 = 36;

/// The largest dwell per turnaround (degrees) a plan accepts before it asks for another pattern.
pub const MAX_DWELL_DEG: f64 = 180.0;

/// Eq. 1: the wind angle on the cylinder of a geodesic that just touches the polar opening
/// (Clairaut: r·sin β = rp), radians.
pub fn cylinder_wind_angle(cylinder_radius_mm: f64, polar_radius_mm: f64) -> f64 {
    (polar_radius_mm / cylinder_radius_mm).asin()
}

/// Eq. 2: the mandrel turn while the tow crosses a cylinder of length `length_mm`, radians.
pub fn cylinder_mandrel_angle(length_mm: f64, cylinder_radius_mm: f64, wind_angle_rad: f64) -> f64 {
    length_mm * wind_angle_rad.tan() / cylinder_radius_mm
}

/// Eq. 3: the geodesic's wind angle at height `z_mm` on the hemispherical dome, radians.
pub fn dome_wind_angle(z_mm: f64, cylinder_radius_mm: f64, polar_radius_mm: f64) -> f64 {
    let r = (cylinder_radius_mm * cylinder_radius_mm - z_mm * z_mm).sqrt();
    (polar_radius_mm / r).min(1.0).asin()
}

/// Eq. 4 in closed form: the mandrel turn from the dome's equator to height `z_mm`,
/// `Φs(z) = atan(rp·z / (Rc·√(zp² − z²)))` (the geodesic on a sphere is a great circle), radians.
/// At the polar opening (z = zp) it is π/2 (Eq. 5).
pub fn dome_mandrel_angle(z_mm: f64, cylinder_radius_mm: f64, polar_radius_mm: f64) -> f64 {
    let zp2 = cylinder_radius_mm * cylinder_radius_mm - polar_radius_mm * polar_radius_mm;
    let rest = (zp2 - z_mm * z_mm).max(0.0).sqrt();
    (polar_radius_mm * z_mm).atan2(cylinder_radius_mm * rest)
}

/// Eq. 10's reading: the radial extent Δr of a band of width `band_mm` laid at the polar
/// opening, `b·cos(βc + b/(2Rc))` (the seed's "bcos(βc + R%)"; `docs/seed-readings.md`), mm. On
/// the sphere it is the chord of the band's arc, `Rc·[sin(βc + b/Rc) − sin βc]`, to second order.
pub fn opening_band_extent(band_mm: f64, cylinder_radius_mm: f64, polar_radius_mm: f64) -> f64 {
    let beta_c = cylinder_wind_angle(cylinder_radius_mm, polar_radius_mm);
    band_mm * (beta_c + band_mm / (2.0 * cylinder_radius_mm)).cos()
}

/// Eqs. 10–11, the "flat solution" for the dome's laminate (seed 002 §2.4): the thickness at
/// height `z_mm` above the dome's equator as a multiple of the cylinder's, `t(z)/t_c`. Eq. 11,
/// `Rc·cos βc / √(Rc² − rp² − z²)` (the conservation law `t·r·cos β` = constant of a geodesic
/// winding), holds up to `z0` ([`dome_thickness_switch_z`]); beyond it, where the band laid at
/// the opening covers the whole remaining dome, Eq. 10's constant `Rc·cos βc / √(Δr·(2·rp +
/// Δr))` with Δr from [`opening_band_extent`]. The two meet at `z0`. `z_mm` is clamped to
/// `[0, zp]` (the opening's height).
pub fn dome_thickness_ratio(
    z_mm: f64,
    cylinder_radius_mm: f64,
    polar_radius_mm: f64,
    band_mm: f64,
) -> f64 {
    let (rc, rp) = (cylinder_radius_mm, polar_radius_mm);
    let beta_c = cylinder_wind_angle(rc, rp);
    let numerator = rc * beta_c.cos();
    let z0 = dome_thickness_switch_z(rc, rp, band_mm);
    if z_mm.max(0.0) < z0 {
        numerator / (rc * rc - rp * rp - z_mm * z_mm).sqrt()
    } else {
        let dr = opening_band_extent(band_mm, rc, rp);
        numerator / (dr * (2.0 * rp + dr)).sqrt()
    }
}

/// The height where Eq. 11 gives way to Eq. 10's constant: the band's inner edge at the
/// opening, radius `rp + Δr`, `z0 = √(Rc² − (rp + Δr)²)`, mm.
pub fn dome_thickness_switch_z(cylinder_radius_mm: f64, polar_radius_mm: f64, band_mm: f64) -> f64 {
    let r0 = polar_radius_mm + opening_band_extent(band_mm, cylinder_radius_mm, polar_radius_mm);
    (cylinder_radius_mm * cylinder_radius_mm - r0 * r0)
        .max(0.0)
        .sqrt()
}

/// Eq. 9: the extra mandrel turn that shifts the pattern by one band width `band_mm`, radians.
pub fn band_advance(band_mm: f64, cylinder_radius_mm: f64, wind_angle_rad: f64) -> f64 {
    band_mm / (cylinder_radius_mm * wind_angle_rad.cos())
}

/// An allowed pitch: Φp = 360°·`turns`/`cycles`, `turns` and `cycles` coprime.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct Pitch {
    /// Whole turns the pattern's start advances over its cycles (k).
    pub turns: u32,
    /// Cycles per pattern (n): after n cycles the tow is back where it started.
    pub cycles: u32,
}

impl Pitch {
    /// The pitch angle, degrees.
    pub fn deg(self) -> f64 {
        360.0 * f64::from(self.turns) / f64::from(self.cycles)
    }

    /// The angular gap between neighbouring bands of one pattern, 360°/n, degrees.
    pub fn gap_deg(self) -> f64 {
        360.0 / f64::from(self.cycles)
    }

    /// The allowed pitches of Eq. 7's two lists, extended to `MAX_CYCLES_PER_PATTERN`, ascending.
    pub fn allowed() -> Vec<Pitch> {
        let mut set: Vec<Pitch> = (2..=MAX_CYCLES_PER_PATTERN)
            .map(|n| Pitch {
                turns: 1,
                cycles: n,
            })
            .chain((3..=MAX_CYCLES_PER_PATTERN).map(|n| Pitch {
                turns: n - 1,
                cycles: n,
            }))
            .chain(std::iter::once(Pitch {
                turns: 1,
                cycles: 1,
            }))
            .collect();
        set.sort_by(|a, b| a.deg().total_cmp(&b.deg()));
        set
    }

    /// The pitches with exactly `cycles` cycles per pattern (k coprime with n), ascending.
    pub fn with_cycles(cycles: u32) -> Vec<Pitch> {
        if cycles == 1 {
            return vec![Pitch {
                turns: 1,
                cycles: 1,
            }];
        }
        (1..cycles)
            .filter(|&k| gcd(k, cycles) == 1)
            .map(|turns| Pitch { turns, cycles })
            .collect()
    }
}

fn gcd(a: u32, b: u32) -> u32 {
    if b == 0 { a } else { gcd(b, a % b) }
}

/// What the operator asks of a helical layer's pattern.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct PatternRequest {
    /// Cycles per pattern (n), or `None` to take Eq. 7's next allowed pitch.
    pub cycles_per_pattern: Option<u32>,
    /// A fixed dwell per turnaround (degrees), or `None` for Eq. 8's.
    pub dwell_deg: Option<f64>,
    /// The advance per pattern (degrees) instead of Eq. 9's band width (the seed's groove mandrel
    /// used 15°).
    pub advance_deg: Option<f64>,
}

/// A helical layer's pattern on one winding surface (Table 3/4's columns and the counts).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Pattern {
    /// βc, Eq. 1.
    pub wind_angle_deg: f64,
    /// Φc, Eq. 2.
    pub cylinder_angle_deg: f64,
    /// Φs, Eq. 5 (one side of one dome, 90°).
    pub dome_angle_deg: f64,
    /// Φ1 = 2Φc + 4Φs, Eq. 6.
    pub cycle_angle_deg: f64,
    /// Φp*, Eq. 7.
    pub calculated_pitch_deg: f64,
    /// The accepted pitch Φp.
    pub pitch: Pitch,
    /// Φf, the dwell at each turnaround, Eq. 8.
    pub dwell_deg: f64,
    /// Φw from the band width, Eq. 9 (or the requested advance).
    pub band_advance_deg: f64,
    /// The advance actually used per pattern: the gap 360°/n split into a whole number of
    /// patterns (never more than `band_advance_deg`, so neighbouring bands overlap rather than gap).
    pub advance_deg: f64,
    /// Patterns per layer (m).
    pub patterns_per_layer: u32,
    /// Φp* − Φp − 2Φf per cycle: non-zero only when the pitch snapped within the tolerance.
    pub residual_per_cycle_deg: f64,
}

impl Pattern {
    /// Cycles per pattern (n).
    pub fn cycles_per_pattern(&self) -> u32 {
        self.pitch.cycles
    }

    /// Cycles per layer, n·m.
    pub fn cycles_per_layer(&self) -> u32 {
        self.pitch.cycles * self.patterns_per_layer
    }

    /// How far a layer's last band lands from where exact closure puts it (degrees).
    pub fn closure_drift_deg(&self) -> f64 {
        self.residual_per_cycle_deg * f64::from(self.cycles_per_layer())
    }

    /// Plans the pattern of a vessel with cylinder radius `cylinder_radius_mm`, polar opening
    /// `polar_radius_mm`, cylinder length `length_mm` and band `band_mm` (seed 002 Eqs. 1–9).
    pub fn plan(
        cylinder_radius_mm: f64,
        polar_radius_mm: f64,
        length_mm: f64,
        band_mm: f64,
        request: &PatternRequest,
    ) -> Result<Pattern, Error> {
        check_geometry(cylinder_radius_mm, polar_radius_mm, length_mm, band_mm)?;
        let beta = cylinder_wind_angle(cylinder_radius_mm, polar_radius_mm);
        let phi_c = cylinder_mandrel_angle(length_mm, cylinder_radius_mm, beta);
        let phi_s = FRAC_PI_2;
        let phi_1 = 2.0 * phi_c + 4.0 * phi_s;
        let calculated = (phi_1 - TAU * (phi_1 / TAU).floor()).to_degrees();
        let band_advance_deg = match request.advance_deg {
            Some(a) if !(a > 0.0 && a.is_finite()) => {
                return Err(Error::OutOfRange {
                    name: "advance_deg",
                    value: a,
                    expected: "must be > 0",
                });
            }
            Some(a) => a,
            None => band_advance(band_mm, cylinder_radius_mm, beta).to_degrees(),
        };
        let (pitch, dwell_deg) =
            choose_pitch(calculated, request).map_err(|reason| Error::PatternNotClosed {
                reason,
                alternatives: alternatives(
                    cylinder_radius_mm,
                    length_mm,
                    beta.to_degrees(),
                    calculated,
                    request,
                ),
            })?;
        let gap = pitch.gap_deg();
        let patterns = (gap / band_advance_deg - 1e-9).ceil().max(1.0);
        if patterns > f64::from(u32::MAX) {
            return Err(Error::OutOfRange {
                name: "band_mm",
                value: band_mm,
                expected: "too narrow: more patterns than can be counted",
            });
        }
        let patterns_per_layer = patterns as u32;
        Ok(Pattern {
            wind_angle_deg: beta.to_degrees(),
            cylinder_angle_deg: phi_c.to_degrees(),
            dome_angle_deg: phi_s.to_degrees(),
            cycle_angle_deg: phi_1.to_degrees(),
            calculated_pitch_deg: calculated,
            pitch,
            dwell_deg,
            band_advance_deg,
            advance_deg: gap / f64::from(patterns_per_layer),
            patterns_per_layer,
            residual_per_cycle_deg: wrap_signed(calculated + 2.0 * dwell_deg - pitch.deg()),
        })
    }
}

/// Brings an angle difference into (−180°, 180°].
fn wrap_signed(deg: f64) -> f64 {
    let w = deg.rem_euclid(360.0);
    if w > 180.0 { w - 360.0 } else { w }
}

fn check_geometry(rc: f64, rp: f64, lc: f64, band: f64) -> Result<(), Error> {
    let checks: [(&'static str, f64, bool, &'static str); 4] = [
        ("cylinder_radius_mm", rc, rc > 0.0, "must be > 0"),
        (
            "polar_opening_radius_mm",
            rp,
            rp > 0.0 && rp < rc,
            "must be > 0 and smaller than the cylinder radius",
        ),
        ("cylinder_length_mm", lc, lc >= 0.0, "must be ≥ 0"),
        ("band_width_mm", band, band > 0.0, "must be > 0"),
    ];
    for (name, value, ok, expected) in checks {
        if !ok || !value.is_finite() {
            return Err(Error::OutOfRange {
                name,
                value,
                expected,
            });
        }
    }
    Ok(())
}

/// Picks Φp and Φf for a calculated pitch (degrees), or says why none fits the request.
fn choose_pitch(calculated: f64, request: &PatternRequest) -> Result<(Pitch, f64), String> {
    let candidates = match request.cycles_per_pattern {
        None => Pitch::allowed(),
        Some(n) if n == 0 || n > MAX_CYCLES_PER_PATTERN => {
            return Err(format!(
                "cycles per pattern {n} is outside 1..={MAX_CYCLES_PER_PATTERN}"
            ));
        }
        Some(n) => Pitch::with_cycles(n),
    };
    // Within the tolerance: the pitch itself, no dwell (TV-4's 60.0125° → 60°).
    let near = candidates
        .iter()
        .copied()
        .filter(|p| (p.deg() - calculated).abs() <= PITCH_TOLERANCE_DEG)
        .min_by(|a, b| {
            (a.deg() - calculated)
                .abs()
                .total_cmp(&(b.deg() - calculated).abs())
        });
    match request.dwell_deg {
        Some(dwell) => {
            if !(dwell.is_finite() && (0.0..=MAX_DWELL_DEG).contains(&dwell)) {
                return Err(format!(
                    "dwell {dwell}° per turnaround is outside 0..={MAX_DWELL_DEG}°"
                ));
            }
            let turned = (calculated + 2.0 * dwell).rem_euclid(360.0);
            candidates
                .iter()
                .copied()
                .find(|p| {
                    let d = wrap_signed(turned - p.deg()).abs();
                    d <= PITCH_TOLERANCE_DEG
                })
                .map(|p| (p, dwell))
                .ok_or_else(|| {
                    format!(
                        "with a dwell of {dwell}° per turnaround a cycle turns the pattern by \
                         {turned:.4}°, which is not 360°·k/n{}",
                        request
                            .cycles_per_pattern
                            .map(|n| format!(" for n = {n}"))
                            .unwrap_or_default()
                    )
                })
        }
        None => {
            if let Some(p) = near {
                return Ok((p, 0.0));
            }
            let next = candidates
                .iter()
                .copied()
                .find(|p| p.deg() > calculated)
                .or_else(|| {
                    // Wrap past 360°: one more turn of dwell.
                    candidates.first().copied()
                });
            let Some(p) = next else {
                return Err("no pitch is allowed".to_string());
            };
            let mut dwell = (p.deg() - calculated) / 2.0;
            if dwell < 0.0 {
                dwell += 180.0;
            }
            if dwell > MAX_DWELL_DEG {
                return Err(format!(
                    "the pitch {:.4}° needs a dwell of {dwell:.4}° per turnaround (more than \
                     {MAX_DWELL_DEG}°)",
                    p.deg()
                ));
            }
            Ok((p, dwell))
        }
    }
}

/// The nearest valid alternatives to a layer that does not close, in words: pattern numbers that
/// close without dwell, the dwell that closes the requested pattern, and the wind angle (with its
/// polar-opening radius) that closes it with no dwell.
fn alternatives(
    rc: f64,
    lc: f64,
    beta_deg: f64,
    calculated: f64,
    request: &PatternRequest,
) -> String {
    let mut out = Vec::new();
    // Pattern numbers whose next pitch up needs the least dwell.
    let mut by_dwell: Vec<(u32, f64)> = (1..=MAX_CYCLES_PER_PATTERN)
        .filter_map(|n| {
            let p = Pitch::with_cycles(n)
                .into_iter()
                .find(|p| p.deg() >= calculated - PITCH_TOLERANCE_DEG)?;
            Some((n, ((p.deg() - calculated) / 2.0).max(0.0)))
        })
        .collect();
    by_dwell.sort_by(|a, b| a.1.total_cmp(&b.1));
    let listed: Vec<String> = by_dwell
        .iter()
        .take(3)
        .map(|(n, d)| format!("{n} (dwell {d:.4}°)"))
        .collect();
    out.push(format!("cycles per pattern {}", listed.join(", ")));
    if let Some(n) = request.cycles_per_pattern.filter(|&n| n >= 1) {
        if let Some(p) = Pitch::with_cycles(n)
            .into_iter()
            .find(|p| p.deg() >= calculated - PITCH_TOLERANCE_DEG)
        {
            out.push(format!(
                "dwell {:.4}° per turnaround for {n} cycles per pattern",
                ((p.deg() - calculated) / 2.0).max(0.0)
            ));
        }
        // Wind angle: Φp* = 2Φc mod 360 (the domes add 360°); solve 2Φc ≡ Φp (mod 360) for the
        // nearest Φc and so for βc = atan(Φc·Rc/Lc).
        if lc > 0.0 {
            let phi_c_now = (lc * beta_deg.to_radians().tan() / rc).to_degrees();
            let best = Pitch::with_cycles(n)
                .into_iter()
                .flat_map(|p| {
                    let half = p.deg() / 2.0;
                    let j = ((phi_c_now - half) / 180.0).round();
                    [-1.0, 0.0, 1.0].map(|d| half + 180.0 * (j + d))
                })
                .filter(|phi| *phi > 0.0)
                .map(|phi| (phi.to_radians() * rc / lc).atan().to_degrees())
                .min_by(|a, b| (a - beta_deg).abs().total_cmp(&(b - beta_deg).abs()));
            if let Some(beta) = best {
                out.push(format!(
                    "wind angle {beta:.4}° (polar opening radius {:.3} mm) for {n} cycles per \
                     pattern with no dwell",
                    rc * beta.to_radians().sin()
                ));
            }
        }
    }
    out.join("; ")
}

/// Mandrel turn of the cycle (Eq. 6) from its parts, radians; exposed for the path planner.
pub fn cycle_angle(cylinder_angle_rad: f64) -> f64 {
    2.0 * cylinder_angle_rad + 2.0 * PI
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;

    const RC: f64 = 60.0;
    const RP: f64 = 21.0;

    #[test]
    fn tv1_polar_wind_angle() {
        assert_abs_diff_eq!(
            cylinder_wind_angle(RC, RP).to_degrees(),
            20.48732,
            epsilon = 1e-5
        );
    }

    /// TV-8 (`../shared/spec/notes-002-004.md`, Eqs. 10–11, b = 4 mm): t(0)/t_c = 1 exactly,
    /// t(40)/t_c = 1.42348, t(50)/t_c = 2.18944, the opening's t_s0/t_c = 4.3234 with Δr =
    /// 3.6983 and the switch at z0 = 54.681 mm; the other reading, Δr = b·cos βc, gives 4.2929.
    #[test]
    fn tv8_dome_thickness_flat_solution() {
        assert_abs_diff_eq!(dome_thickness_ratio(0.0, RC, RP, 4.0), 1.0, epsilon = 1e-12);
        assert_abs_diff_eq!(
            dome_thickness_ratio(40.0, RC, RP, 4.0),
            1.42348,
            epsilon = 1e-5
        );
        assert_abs_diff_eq!(
            dome_thickness_ratio(50.0, RC, RP, 4.0),
            2.18944,
            epsilon = 1e-5
        );
        assert_abs_diff_eq!(opening_band_extent(4.0, RC, RP), 3.6983, epsilon = 1e-4);
        let z0 = dome_thickness_switch_z(RC, RP, 4.0);
        assert_abs_diff_eq!(z0, 54.681, epsilon = 1e-3);
        // Eq. 10's constant from z0 to the opening, and Eq. 11 meets it at z0.
        let t0 = dome_thickness_ratio(z0, RC, RP, 4.0);
        assert_abs_diff_eq!(t0, 4.3234, epsilon = 1e-4);
        assert_abs_diff_eq!(dome_thickness_ratio(57.0, RC, RP, 4.0), t0, epsilon = 1e-12);
        let zp = (RC * RC - RP * RP).sqrt();
        assert_abs_diff_eq!(dome_thickness_ratio(zp, RC, RP, 4.0), t0, epsilon = 1e-12);
        assert_abs_diff_eq!(
            dome_thickness_ratio(z0 - 1e-9, RC, RP, 4.0),
            t0,
            epsilon = 1e-6
        );
        // The alternative reading of Eq. 10 (Δr = b·cos βc), worked out here: 4.2929.
        let beta_c = cylinder_wind_angle(RC, RP);
        let dr = 4.0 * beta_c.cos();
        assert_abs_diff_eq!(
            RC * beta_c.cos() / (dr * (2.0 * RP + dr)).sqrt(),
            4.2929,
            epsilon = 1e-4
        );
        // Monotonic: the dome thickens toward the opening.
        let mut last = 0.0;
        for k in 0..=57 {
            let t = dome_thickness_ratio(k as f64, RC, RP, 4.0);
            assert!(t >= last, "z = {k}: {t} < {last}");
            last = t;
        }
    }

    #[test]
    fn tv2_cylinder_mandrel_angles() {
        let b = cylinder_wind_angle(RC, RP);
        assert_abs_diff_eq!(
            cylinder_mandrel_angle(84.1, RC, b).to_degrees(),
            30.00626,
            epsilon = 1e-5
        );
        assert_abs_diff_eq!(
            cylinder_mandrel_angle(160.0, RC, b).to_degrees(),
            57.08682,
            epsilon = 1e-5
        );
    }

    #[test]
    fn tv3_casing_pattern_snaps_up_with_dwell() {
        let p = Pattern::plan(RC, RP, 160.0, 4.0, &PatternRequest::default()).unwrap();
        assert_abs_diff_eq!(p.dome_angle_deg, 90.0, epsilon = 1e-12);
        assert_abs_diff_eq!(p.cycle_angle_deg, 474.1736, epsilon = 1e-4);
        assert_abs_diff_eq!(p.calculated_pitch_deg, 114.1736, epsilon = 1e-4);
        assert_eq!(p.pitch.deg(), 120.0);
        assert_eq!(p.cycles_per_pattern(), 3);
        assert_abs_diff_eq!(p.dwell_deg, 2.9132, epsilon = 1e-4);
        assert_abs_diff_eq!(p.residual_per_cycle_deg, 0.0, epsilon = 1e-9);
        // Gap 120° in bands of 4.0776°: 30 patterns, 90 cycles (the seed's 88–90).
        assert_eq!(p.patterns_per_layer, 30);
        assert_eq!(p.cycles_per_layer(), 90);
        assert!(p.advance_deg <= p.band_advance_deg);
    }

    #[test]
    fn tv4_groove_pattern_snaps_within_tolerance() {
        let p = Pattern::plan(RC, RP, 84.1, 4.0, &PatternRequest::default()).unwrap();
        assert_abs_diff_eq!(p.cycle_angle_deg, 420.0125, epsilon = 1e-4);
        assert_abs_diff_eq!(p.calculated_pitch_deg, 60.0125, epsilon = 1e-4);
        assert_eq!(p.pitch.deg(), 60.0);
        assert_eq!(p.dwell_deg, 0.0);
        assert_abs_diff_eq!(p.residual_per_cycle_deg, 0.0125, epsilon = 1e-4);
    }

    #[test]
    fn tv4_without_tolerance_the_next_value_up_is_72() {
        // Just outside the tolerance: Φp* = 60.03° takes 72° with a 5.985° dwell.
        let b = cylinder_wind_angle(RC, RP);
        let lc = (60.03f64 / 2.0).to_radians() * RC / b.tan();
        let p = Pattern::plan(RC, RP, lc, 4.0, &PatternRequest::default()).unwrap();
        assert_eq!(p.pitch.deg(), 72.0);
        assert_abs_diff_eq!(p.dwell_deg, (72.0 - 60.03) / 2.0, epsilon = 1e-9);
    }

    #[test]
    fn tv5_band_advance() {
        let b = cylinder_wind_angle(RC, RP);
        assert_abs_diff_eq!(
            band_advance(4.0, RC, b).to_degrees(),
            4.07763,
            epsilon = 1e-5
        );
        assert_abs_diff_eq!(
            band_advance(3.5, RC, b).to_degrees(),
            3.56793,
            epsilon = 1e-5
        );
    }

    #[test]
    fn tv6_groove_mandrel_counts_with_15_degree_advance() {
        let request = PatternRequest {
            advance_deg: Some(15.0),
            ..PatternRequest::default()
        };
        let p = Pattern::plan(RC, RP, 84.1, 4.0, &request).unwrap();
        assert_eq!(p.cycles_per_pattern(), 6);
        assert_eq!(p.patterns_per_layer, 4);
        assert_eq!(p.cycles_per_layer(), 24);
        assert_abs_diff_eq!(p.cycle_angle_deg, 420.012, epsilon = 1e-3);
        assert_abs_diff_eq!(p.advance_deg, 15.0, epsilon = 1e-12);
    }

    #[test]
    fn tv7_dome_angles() {
        let expect_beta = [
            (0.0, 20.487),
            (15.0, 21.191),
            (30.0, 23.838),
            (45.0, 31.948),
            (50.0, 39.285),
            (55.0, 61.135),
        ];
        for (z, b) in expect_beta {
            assert_abs_diff_eq!(dome_wind_angle(z, RC, RP).to_degrees(), b, epsilon = 1e-3);
        }
        let expect_phi = [
            (0.0, 0.0),
            (15.0, 5.5360),
            (30.0, 12.4576),
            (40.0, 19.5231),
            (45.0, 25.0658),
            (50.0, 34.2824),
            (55.0, 58.9797),
        ];
        for (z, phi) in expect_phi {
            assert_abs_diff_eq!(
                dome_mandrel_angle(z, RC, RP).to_degrees(),
                phi,
                epsilon = 1e-4
            );
        }
        let zp = (RC * RC - RP * RP).sqrt();
        assert_abs_diff_eq!(zp, 56.20498, epsilon = 1e-5);
        assert_abs_diff_eq!(dome_wind_angle(zp, RC, RP), FRAC_PI_2, epsilon = 1e-9);
        assert_abs_diff_eq!(dome_mandrel_angle(zp, RC, RP), FRAC_PI_2, epsilon = 1e-9);
    }

    /// Eq. 4 by quadrature (Simpson on a substitution that removes the end singularity) against
    /// the closed form.
    #[test]
    fn eq4_closed_form_matches_quadrature() {
        let zp = (RC * RC - RP * RP).sqrt();
        for z in [10.0, 30.0, 50.0, 56.0] {
            // z = zp·sin(u): dz = zp cos u du, √(zp² − z²) = zp cos u.
            let u_end = (z / zp).asin();
            let n = 2000;
            let h = u_end / n as f64;
            let f = |u: f64| {
                let zz = zp * u.sin();
                RC * RP / (RC * RC - zz * zz)
            };
            let mut s = f(0.0) + f(u_end);
            for i in 1..n {
                s += f(i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 };
            }
            let integral = s * h / 3.0;
            assert_abs_diff_eq!(dome_mandrel_angle(z, RC, RP), integral, epsilon = 1e-9);
        }
    }

    #[test]
    fn allowed_pitches_contain_the_seed_lists() {
        let allowed: Vec<f64> = Pitch::allowed().iter().map(|p| p.deg()).collect();
        for v in [
            60.0, 72.0, 90.0, 120.0, 180.0, 240.0, 270.0, 288.0, 300.0, 360.0,
        ] {
            assert!(allowed.iter().any(|a| (a - v).abs() < 1e-12), "{v}");
        }
        let p = Pitch {
            turns: 3,
            cycles: 4,
        };
        assert_eq!(p.gap_deg(), 90.0);
        assert_eq!(Pitch::with_cycles(6).len(), 2); // 60° and 300°
    }

    #[test]
    fn fixed_cycles_take_the_dwell_that_closes() {
        let request = PatternRequest {
            cycles_per_pattern: Some(4),
            ..PatternRequest::default()
        };
        // Φp* = 114.17° with n = 4: 270° is the next coprime pitch up.
        let p = Pattern::plan(RC, RP, 160.0, 4.0, &request).unwrap();
        assert_eq!(p.pitch.deg(), 270.0);
        assert_abs_diff_eq!(p.dwell_deg, (270.0 - 114.1736) / 2.0, epsilon = 1e-4);
    }

    #[test]
    fn fixed_dwell_that_does_not_close_names_alternatives() {
        let request = PatternRequest {
            cycles_per_pattern: Some(4),
            dwell_deg: Some(0.0),
            ..PatternRequest::default()
        };
        let err = Pattern::plan(RC, RP, 160.0, 4.0, &request).unwrap_err();
        let Error::PatternNotClosed {
            reason,
            alternatives,
        } = err
        else {
            panic!("{err:?}")
        };
        assert!(reason.contains("114.1736"), "{reason}");
        assert!(alternatives.contains("dwell 77.9132°"), "{alternatives}");
        // The suggested wind angle closes: plan with its polar radius and no dwell.
        let beta: f64 = alternatives
            .split("wind angle ")
            .nth(1)
            .and_then(|s| s.split('°').next())
            .and_then(|s| s.parse().ok())
            .unwrap();
        let rp = RC * beta.to_radians().sin();
        let p = Pattern::plan(RC, rp, 160.0, 4.0, &request).unwrap();
        assert_eq!(p.cycles_per_pattern(), 4);
        assert!(p.residual_per_cycle_deg.abs() < PITCH_TOLERANCE_DEG);
    }

    #[test]
    fn fixed_dwell_that_closes_is_kept() {
        let request = PatternRequest {
            dwell_deg: Some(2.9132),
            ..PatternRequest::default()
        };
        let p = Pattern::plan(RC, RP, 160.0, 4.0, &request).unwrap();
        assert_eq!(p.pitch.deg(), 120.0);
        assert_eq!(p.dwell_deg, 2.9132);
    }

    #[test]
    fn bad_geometry_is_refused() {
        for (rc, rp, lc, b) in [
            (60.0, 60.0, 10.0, 4.0),
            (60.0, 0.0, 10.0, 4.0),
            (-1.0, 0.5, 10.0, 4.0),
            (60.0, 21.0, -1.0, 4.0),
            (60.0, 21.0, 10.0, 0.0),
            (60.0, 21.0, f64::NAN, 4.0),
        ] {
            assert!(matches!(
                Pattern::plan(rc, rp, lc, b, &PatternRequest::default()),
                Err(Error::OutOfRange { .. })
            ));
        }
    }

    #[test]
    fn cycle_angle_is_eq6() {
        assert_abs_diff_eq!(
            cycle_angle(30.0f64.to_radians()).to_degrees(),
            420.0,
            epsilon = 1e-12
        );
    }
}
