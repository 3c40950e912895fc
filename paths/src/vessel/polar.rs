//! Polar (planar, in-plane) winding of a vessel with hemispherical domes and equal polar
//! openings, on a lathe winder.
//!
//! Seed 002 names polar winding only as the work of racetrack (in-plane) winders, "effective
//! for winding angles close to zero" on parts of length-to-diameter ratio up to 1.8–2.0 "to
//! obviate the fiber slippage" (§1); it gives no equations. What follows is our reading
//! (`docs/seed-readings.md` R002-5).
//!
//! **The plane.** The fibre lies in one plane P that touches the polar opening (radius rp) at
//! one end on one side and at the other end on the opposite side. With the openings at
//! `z = ±Zp`, `Zp = Lc/2 + √(Rc² − rp²)` (the hemisphere of radius Rc centred at the cylinder's
//! end, seed 002 Fig. 1), P is `y = −z·tan α` with
//!
//! ```text
//! tan α = 2·rp / (Lc + 2·√(Rc² − rp²))        (= (r1 + r2)/L for openings r1, r2 a distance L apart)
//! ```
//!
//! α is the fibre's angle to the axis where it crosses the middle of the cylinder. In P, with `u`
//! along x and `w` along `(0, −sin α, cos α)`, the vessel's section is convex (the vessel is the
//! set of points within Rc of the axis segment `|z| ≤ Lc/2`): on the cylinder the ellipse
//! `u² + w²·sin²α = Rc²`, on each dome a circle of radius `√(Rc² − (Lc/2)²·sin²α)` about
//! `w = ±(Lc/2)·cos α`, through the tangent point of the opening. The laid fibre is that section.
//!
//! **Slip.** The section is not a geodesic. On a dome it is a small circle of the sphere, its
//! plane `(Lc/2)·sin α` from the sphere's centre, so the ratio of geodesic to normal curvature
//! (what friction must hold) is `λ = (Lc/2)·sin α / √(Rc² − (Lc/2)²·sin²α)`. On the cylinder,
//! unrolled, the section is the sine `z = (Rc/tan α)·sin t` and `λ(t) = |sin t| / √(tan²α +
//! cos²t)`, which grows from 0 at the middle to the dome's value at the cylinder's ends; so that
//! value is the layer's largest, and a layer is refused when it exceeds the slip limit μ.
//!
//! **The lathe.** The eye stays in the machine's meridian half-plane; in the mandrel's frame, at
//! mandrel angle θ it is at azimuth −θ. For the free fibre to stay in P (it is tangent to the
//! planar fibre path, so it lies in P) the eye must be in P: an eye point `(u, w)` of P is the
//! machine position `θ = atan2(w·sin α, u)`, carriage `X = w·cos α`, cross-feed
//! `ρ = √(u² + w²·sin²α)`. The eye goes once round an ellipse of P enclosing the section per
//! circuit, so the mandrel turns once per circuit while the carriage swings out past each pole
//! and back, and the fibre is wound round the section. With cross-feed the ellipse's semi-axes
//! are `Re` across the cylinder and the opening's distance plus `Re − Rc` toward the poles; with
//! no cross-feed the eye keeps the radius Re (the ellipse `u = Re·cos ψ`,
//! `w = Re·sin ψ / sin α`, which swings the carriage by `±Re / tan α`).
//!
//! **Advance.** Each circuit lays a band at +α on one side of the cylinder and at −α on the other;
//! the band covers `b / cos α` of the circumference where it crosses the middle, so
//! `N = ⌈2π·Rc·cos α / b⌉` circuits cover it, and the plane turns by `360°/N` per circuit: spread
//! evenly over the circuit, as a polar winder's mandrel turns slowly while its arm goes round. The
//! pattern closes by construction (N advances make one turn).

use std::f64::consts::{PI, TAU};

/// Largest distance, mm, of the eye from the plane P between two emitted stations (the
/// controller interpolates the axes linearly).
pub const EYE_PLANE_TOLERANCE_MM: f64 = 0.05;

/// The polar plane of a vessel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PolarPlane {
    cylinder_radius_mm: f64,
    half_length_mm: f64,
    alpha_rad: f64,
}

/// One eye station of a circuit, before the circuit's advance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PolarStation {
    /// Fraction of the circuit (the eye's parameter over 2π).
    pub fraction: f64,
    /// Mandrel turn from the circuit's start, degrees.
    pub mandrel_deg: f64,
    /// Carriage, mm from the cylinder's middle.
    pub carriage_mm: f64,
    /// The eye's distance from the axis, mm.
    pub cross_feed_mm: f64,
    /// Eye rotation: 90° less the free fibre's angle to the axis, signed by the way the fibre
    /// runs along the axis (as on a tube's helical layers), degrees.
    pub eye_deg: f64,
}

impl PolarPlane {
    /// The plane touching both openings of a vessel with cylinder radius Rc, length Lc and polar
    /// openings rp (0 < rp < Rc).
    pub fn new(cylinder_radius_mm: f64, cylinder_length_mm: f64, polar_radius_mm: f64) -> Self {
        let zp = cylinder_length_mm / 2.0
            + (cylinder_radius_mm.powi(2) - polar_radius_mm.powi(2)).sqrt();
        PolarPlane {
            cylinder_radius_mm,
            half_length_mm: cylinder_length_mm / 2.0,
            alpha_rad: (polar_radius_mm / zp).atan(),
        }
    }

    /// α, the fibre's angle to the axis at the middle of the cylinder, degrees.
    pub fn wind_angle_deg(&self) -> f64 {
        self.alpha_rad.to_degrees()
    }

    /// The largest ratio of geodesic to normal curvature along the fibre (on the domes).
    pub fn slip_ratio(&self) -> f64 {
        let d = self.half_length_mm * self.alpha_rad.sin();
        d / (self.cylinder_radius_mm.powi(2) - d * d).sqrt()
    }

    /// Circuits that cover the cylinder with a band `band_mm` wide.
    pub fn circuits(&self, band_mm: f64) -> f64 {
        (TAU * self.cylinder_radius_mm * self.alpha_rad.cos() / band_mm - 1e-9).ceil()
    }

    /// The section's boundary on the ray of P at angle `psi` from `u`: the distance from the
    /// centre.
    pub fn section_radius_mm(&self, psi: f64) -> f64 {
        let (s, c) = psi.sin_cos();
        let (sa, ca) = self.alpha_rad.sin_cos();
        let rc = self.cylinder_radius_mm;
        let h = self.half_length_mm;
        let on_cylinder = rc / (c * c + s * s * sa * sa).sqrt();
        if on_cylinder * s.abs() * ca <= h {
            on_cylinder
        } else {
            // s² − 2·s·h·|sin ψ|·cos α + h² − Rc² = 0, the far root.
            let b = h * s.abs() * ca;
            b + (b * b - h * h + rc * rc).sqrt()
        }
    }

    /// The 3-D distance from a point of P to the axis segment `|z| ≤ Lc/2`.
    fn distance_to_core_mm(&self, u: f64, w: f64) -> f64 {
        let (sa, ca) = self.alpha_rad.sin_cos();
        let r = u.hypot(w * sa);
        let beyond = ((w * ca).abs() - self.half_length_mm).max(0.0);
        r.hypot(beyond)
    }

    /// The fibre laid in one circuit: the section's perimeter, mm (chords of 20 000 points).
    pub fn circuit_length_mm(&self) -> f64 {
        let n = 20_000;
        let point = |i: usize| {
            let psi = TAU * i as f64 / n as f64;
            let r = self.section_radius_mm(psi);
            (r * psi.cos(), r * psi.sin())
        };
        (0..n)
            .map(|i| {
                let (a, b) = (point(i), point(i + 1));
                (b.0 - a.0).hypot(b.1 - a.1)
            })
            .sum()
    }

    /// The eye's ellipse in P: semi-axes across (`u`) and along (`w`).
    pub fn eye_ellipse(
        &self,
        eye_radius_mm: f64,
        cross_feed: bool,
        polar_radius_mm: f64,
    ) -> (f64, f64) {
        let (sa, ca) = self.alpha_rad.sin_cos();
        if cross_feed {
            let zp = polar_radius_mm / self.alpha_rad.tan();
            (
                eye_radius_mm,
                zp / ca + (eye_radius_mm - self.cylinder_radius_mm),
            )
        } else {
            (eye_radius_mm, eye_radius_mm / sa)
        }
    }

    /// The stations of one circuit, the eye going once round the ellipse `(a_u, a_w)` from the
    /// middle of the cylinder, close enough that the linear move between neighbours keeps the eye
    /// within [`EYE_PLANE_TOLERANCE_MM`] of P; `None` if the eye would touch the vessel.
    pub fn stations(&self, a_u: f64, a_w: f64, eye_rotation: bool) -> Option<Vec<PolarStation>> {
        let (sa, ca) = self.alpha_rad.sin_cos();
        // The section, counter-clockwise in (u, w), for the fibre's contact point.
        let m = 4096;
        let section: Vec<(f64, f64)> = (0..m)
            .map(|i| {
                let psi = TAU * i as f64 / m as f64;
                let r = self.section_radius_mm(psi);
                (r * psi.cos(), r * psi.sin())
            })
            .collect();
        let at = |psi: f64, unwrap_from: f64| -> Option<PolarStation> {
            let (u, w) = (a_u * psi.cos(), a_w * psi.sin());
            if self.distance_to_core_mm(u, w) <= self.cylinder_radius_mm {
                return None;
            }
            let mut theta = (w * sa).atan2(u);
            while theta < unwrap_from - PI {
                theta += TAU;
            }
            let eye_deg = if eye_rotation {
                // The contact point: where the section's forward tangent points at the eye
                // (the cross product turns from + to − going counter-clockwise).
                let cross = |i: usize| {
                    let (p, q) = (section[i], section[(i + 1) % m]);
                    let t = (q.0 - p.0, q.1 - p.1);
                    (
                        t.0 * (w - p.1) - t.1 * (u - p.0),
                        t.0 * (u - p.0) + t.1 * (w - p.1),
                    )
                };
                let contact = (0..m).find(|&i| {
                    let (c0, _) = cross(i);
                    let (c1, d1) = cross((i + 1) % m);
                    c0 > 0.0 && c1 <= 0.0 && d1 > 0.0
                })?;
                let p = section[(contact + 1) % m];
                let (tu, tw) = (u - p.0, w - p.1);
                let tw_unit = tw / tu.hypot(tw);
                let gamma = (tw_unit.abs() * ca).acos().to_degrees();
                tw_unit.signum() * (90.0 - gamma)
            } else {
                0.0
            };
            Some(PolarStation {
                fraction: psi / TAU,
                mandrel_deg: theta.to_degrees(),
                carriage_mm: w * ca,
                cross_feed_mm: u.hypot(w * sa),
                eye_deg,
            })
        };
        let off_plane = |a: &PolarStation, b: &PolarStation| {
            // The interpolated eye's distance from P: |X·sin α − ρ·sin θ·cos α|.
            let theta = (0.5 * (a.mandrel_deg + b.mandrel_deg)).to_radians();
            let x = 0.5 * (a.carriage_mm + b.carriage_mm);
            let rho = 0.5 * (a.cross_feed_mm + b.cross_feed_mm);
            (x * sa - rho * theta.sin() * ca).abs()
        };
        let first = at(0.0, 0.0)?;
        let mut out = vec![first];
        // Start from eight equal parts of the circuit, then bisect.
        let quarter: Vec<f64> = (0..=8).map(|i| TAU * i as f64 / 8.0).collect();
        for pair in quarter.windows(2) {
            let a = *out.last()?;
            let b = at(pair[1], a.mandrel_deg.to_radians())?;
            let mut stack = vec![(pair[0], a, pair[1], b, 0u32)];
            while let Some((pa, a, pb, b, depth)) = stack.pop() {
                let pm = 0.5 * (pa + pb);
                if depth < 30 && off_plane(&a, &b) > EYE_PLANE_TOLERANCE_MM {
                    let mid = at(pm, a.mandrel_deg.to_radians())?;
                    stack.push((pm, mid, pb, b, depth + 1));
                    stack.push((pa, a, pm, mid, depth + 1));
                } else {
                    out.push(b);
                }
            }
        }
        Some(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;

    /// Seed 002's mandrel: Rc 60, Lc 84.1, rp 21 (TV vectors in `docs/seed-readings.md`).
    fn seed() -> PolarPlane {
        PolarPlane::new(60.0, 84.1, 21.0)
    }

    #[test]
    fn the_plane_touches_both_openings() {
        let p = seed();
        // By hand: √(60² − 21²) = 56.20498, Zp = 42.05 + 56.20498 = 98.25498,
        // α = atan(21 / 98.25498) = 12.06429°.
        assert_abs_diff_eq!(p.wind_angle_deg(), 12.06429, epsilon = 1e-5);
        // The opening's edge (0, −21, Zp) lies in y = −z·tan α and on the section.
        let zp = 98.25498;
        let w = zp / p.alpha_rad.cos();
        assert_abs_diff_eq!(p.section_radius_mm(PI / 2.0), w, epsilon = 1e-3);
        // Across the middle of the cylinder the section is at Rc.
        assert_abs_diff_eq!(p.section_radius_mm(0.0), 60.0, epsilon = 1e-12);
    }

    #[test]
    fn slip_ratio_is_the_small_circle_of_the_dome() {
        // λ = 42.05·sin α / √(60² − (42.05·sin α)²), sin 12.06429° = 0.2090091.
        let d = 42.05 * 0.2090091;
        assert_abs_diff_eq!(
            seed().slip_ratio(),
            d / (3600.0f64 - d * d).sqrt(),
            epsilon = 1e-5
        );
        assert_abs_diff_eq!(seed().slip_ratio(), 0.148078, epsilon = 1e-6);
    }

    #[test]
    fn the_circuit_is_two_ellipse_arcs_and_two_circle_arcs() {
        let p = seed();
        let (rc, h) = (60.0f64, 42.05f64);
        let a = p.alpha_rad;
        // The cylinder part, parametrised by the mandrel angle t of the unrolled sine
        // z = (Rc / tan α)·sin t: ds = Rc·√(1 + cos²t / tan²α) dt, |t| ≤ t_e,
        // sin t_e = h·tan α / Rc (Simpson).
        let te = (h * a.tan() / rc).asin();
        let n = 10_000;
        let f = |t: f64| rc * (1.0 + t.cos().powi(2) / a.tan().powi(2)).sqrt();
        let step = 2.0 * te / n as f64;
        let ellipse_arc: f64 = (0..=n)
            .map(|i| {
                let wgt = if i == 0 || i == n {
                    1.0
                } else if i % 2 == 1 {
                    4.0
                } else {
                    2.0
                };
                wgt * f(-te + i as f64 * step)
            })
            .sum::<f64>()
            * step
            / 3.0;
        // The dome part: a circle of radius √(Rc² − h²·sin²α) about w = h·cos α, from one
        // junction (w = h / cos α, u = ±Rc·cos t_e) round over the pole.
        let rd = (rc * rc - (h * a.sin()).powi(2)).sqrt();
        let phi = (rc * te.cos()).atan2(h * a.sin().powi(2) / a.cos());
        let dome_arc = 2.0 * phi * rd;
        assert_abs_diff_eq!(
            p.circuit_length_mm(),
            2.0 * ellipse_arc + 2.0 * dome_arc,
            epsilon = 1e-3
        );
    }

    #[test]
    fn stations_keep_the_eye_in_the_plane_and_outside_the_vessel() {
        let p = seed();
        let (au, aw) = p.eye_ellipse(90.0, true, 21.0);
        let st = p.stations(au, aw, true).unwrap();
        let a = p.alpha_rad;
        assert_abs_diff_eq!(st.last().unwrap().mandrel_deg, 360.0, epsilon = 1e-9);
        for w in st.windows(2) {
            assert!(w[1].mandrel_deg > w[0].mandrel_deg);
            for s in w {
                // In P: X·tan α = ρ·sin θ.
                assert_abs_diff_eq!(
                    s.carriage_mm * a.tan(),
                    s.cross_feed_mm * s.mandrel_deg.to_radians().sin(),
                    epsilon = 1e-9
                );
            }
        }
        // Across the cylinder's middle the eye is at Re and the fibre at α: eye 90° − α.
        assert_abs_diff_eq!(st[0].cross_feed_mm, 90.0, epsilon = 1e-12);
        assert_abs_diff_eq!(st[0].carriage_mm, 0.0, epsilon = 1e-12);
        // Beyond the pole the eye passes Zp + (Re − Rc)·cos α along the axis.
        let far = st.iter().map(|s| s.carriage_mm).fold(f64::MIN, f64::max);
        assert_abs_diff_eq!(far, 98.25498 + 30.0 * a.cos(), epsilon = 1e-3);
        // An eye too close to the vessel is refused.
        assert!(p.stations(61.0, aw, true).is_none());
    }

    #[test]
    fn the_eye_must_clear_the_domes_too() {
        let p = seed();
        let (sa, ca) = (0.2090091f64, 0.9779137f64);
        // By hand: the point w = 100 of P above the pole is at y = −100·sin α = −20.901,
        // z = 100·cos α = 97.791, 55.741 beyond the cylinder's end: 59.531 from the dome's
        // centre, inside the dome (Rc = 60). At w = 102 it is 61.510 away, outside.
        assert_abs_diff_eq!(
            p.distance_to_core_mm(0.0, 100.0),
            (100.0 * sa).hypot(100.0 * ca - 42.05),
            epsilon = 1e-4
        );
        assert_abs_diff_eq!(p.distance_to_core_mm(0.0, 100.0), 59.531, epsilon = 1e-3);
        assert_abs_diff_eq!(p.distance_to_core_mm(0.0, 102.0), 61.510, epsilon = 1e-3);
        // Beside the cylinder only the distance from the axis counts.
        assert_abs_diff_eq!(
            p.distance_to_core_mm(50.0, 20.0),
            50.0f64.hypot(20.0 * sa),
            epsilon = 1e-6
        );
        assert!(p.stations(90.0, 100.0, false).is_none());
        assert!(p.stations(90.0, 102.0, false).is_some());
    }
}
