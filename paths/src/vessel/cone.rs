//! The geodesic on a reducing cone (a frustum): how a helical layer of a `.wind` job is wound
//! when `endDiameter` is below `diameter`.
//!
//! Seed 002 winds only cylinders with domes; the cone is our reading of the `.wind` format
//! (`docs/seed-readings.md` R002-4). A cone is developable: cut along a generator it unrolls
//! into a plane sector with the apex at the centre, a point at radius `r` lying at distance
//! `s = r / sin φ` from the apex (φ the half-angle, `tan φ = (r0 − r1) / L`), and a mandrel turn
//! `θ` opening the sector by `ψ = θ·sin φ`. A geodesic is a straight line of that plane. At
//! distance `p` from the apex the line meets the ray at distance `s` at `sin α = p / s` from the
//! generator, so `r·sin α = p·sin φ = C` along it (Clairaut's relation), and the polar angle
//! swept from `s0` to `s` is `acos(p/s) − acos(p/s0)`, which gives the mandrel turn
//!
//! ```text
//! θ(z) = [acos(C / r0) − acos(C / r(z))] / sin φ,   r(z) = r0 − z·tan φ,   C = r0·sin α0
//! ```
//!
//! (z from the large end) and the length between the ends
//! `[√(r0² − C²) − √(r1² − C²)] / sin φ`. On a cylinder (φ → 0) `dθ/dz` tends to `tan α / r`,
//! the helix of seed 002 Eq. 20.
//!
//! The wind angle of the file is α0, the angle at the large end (z = 0), as FiberPath's
//! `wind-format.md` defines it; the fibre steepens toward the small end to `asin(C / r1)`, and
//! the geodesic reaches the small end only if `C ≤ r1`.

/// Largest distance on the surface, mm, between the geodesic and the straight move (in carriage
/// and mandrel angle) a controller interpolates between two emitted stations.
pub const CHORD_TOLERANCE_MM: f64 = 0.01;

/// A geodesic from the large end of a reducing cone to its small end.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConeGeodesic {
    large_radius_mm: f64,
    small_radius_mm: f64,
    length_mm: f64,
    clairaut_mm: f64,
    sin_half_angle: f64,
}

/// A point of a pass: distance from the large end along the axis, the mandrel turn since the
/// large end, and the local wind angle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Station {
    /// Axial distance from the large end, mm.
    pub along_mm: f64,
    /// Mandrel turn from the large end, degrees.
    pub turn_deg: f64,
    /// The fibre's angle from the generator here, degrees.
    pub wind_angle_deg: f64,
}

/// Why a cone cannot be wound at the requested angle.
#[derive(Debug, Clone, PartialEq)]
pub enum ConeRefusal {
    /// The far end is not smaller than the near one.
    NotReducing,
    /// `C = r0·sin α0` exceeds the small end's radius.
    TooSteep {
        /// C, mm.
        clairaut_mm: f64,
        /// The steepest angle at the large end whose geodesic reaches the small end, degrees.
        steepest_deg: f64,
    },
}

impl ConeGeodesic {
    /// The geodesic leaving the large end (radius `large_radius_mm`) at `wind_angle_deg` from
    /// the generator, on a cone of axial length `length_mm` ending at `small_radius_mm`.
    pub fn new(
        large_radius_mm: f64,
        small_radius_mm: f64,
        length_mm: f64,
        wind_angle_deg: f64,
    ) -> Result<Self, ConeRefusal> {
        if small_radius_mm >= large_radius_mm {
            return Err(ConeRefusal::NotReducing);
        }
        let clairaut_mm = large_radius_mm * wind_angle_deg.to_radians().sin();
        if clairaut_mm > small_radius_mm {
            return Err(ConeRefusal::TooSteep {
                clairaut_mm,
                steepest_deg: (small_radius_mm / large_radius_mm).asin().to_degrees(),
            });
        }
        let drop = large_radius_mm - small_radius_mm;
        Ok(ConeGeodesic {
            large_radius_mm,
            small_radius_mm,
            length_mm,
            clairaut_mm,
            sin_half_angle: drop / drop.hypot(length_mm),
        })
    }

    /// Radius at `along_mm` from the large end.
    pub fn radius_mm(&self, along_mm: f64) -> f64 {
        self.large_radius_mm
            - (self.large_radius_mm - self.small_radius_mm) * along_mm / self.length_mm
    }

    /// `C / r`, at most 1 (C ≤ r1 ≤ r holds by construction; the bound only absorbs rounding
    /// at the small end when C = r1).
    fn ratio(&self, radius_mm: f64) -> f64 {
        (self.clairaut_mm / radius_mm).min(1.0)
    }

    /// The mandrel turn from the large end to `along_mm`, degrees (the formula above).
    pub fn turn_deg(&self, along_mm: f64) -> f64 {
        let r = self.radius_mm(along_mm);
        ((self.ratio(self.large_radius_mm).acos() - self.ratio(r).acos()) / self.sin_half_angle)
            .to_degrees()
    }

    /// The fibre's angle from the generator at `along_mm`: `asin(C / r)`, degrees.
    pub fn wind_angle_deg(&self, along_mm: f64) -> f64 {
        self.ratio(self.radius_mm(along_mm)).asin().to_degrees()
    }

    /// Length of the fibre from end to end, mm.
    pub fn length_mm(&self) -> f64 {
        let c2 = self.clairaut_mm * self.clairaut_mm;
        ((self.large_radius_mm.powi(2) - c2).max(0.0).sqrt()
            - (self.small_radius_mm.powi(2) - c2).max(0.0).sqrt())
            / self.sin_half_angle
    }

    /// The small end's radius, mm.
    pub fn small_radius_mm(&self) -> f64 {
        self.small_radius_mm
    }

    /// Stations from the large end to the small end, each `breaks` point among them, close
    /// enough that the straight move between neighbours stays within [`CHORD_TOLERANCE_MM`] of
    /// the geodesic at its middle (bisection; the first station is the large end).
    pub fn stations(&self, breaks: &[f64]) -> Vec<Station> {
        let at = |along_mm: f64| Station {
            along_mm,
            turn_deg: self.turn_deg(along_mm),
            wind_angle_deg: self.wind_angle_deg(along_mm),
        };
        let mut cuts: Vec<f64> = breaks
            .iter()
            .copied()
            .filter(|b| *b > 0.0 && *b < self.length_mm)
            .chain([0.0, self.length_mm])
            .collect();
        cuts.sort_by(f64::total_cmp);
        cuts.dedup();
        let mut out = vec![at(0.0)];
        for pair in cuts.windows(2) {
            let mut stack = vec![(at(pair[0]), at(pair[1]), 0u32)];
            // Depth-first, right half pushed first so stations come out in order.
            while let Some((a, b, depth)) = stack.pop() {
                let mid = at(0.5 * (a.along_mm + b.along_mm));
                let off = self.radius_mm(mid.along_mm)
                    * (mid.turn_deg - 0.5 * (a.turn_deg + b.turn_deg))
                        .abs()
                        .to_radians();
                if off > CHORD_TOLERANCE_MM && depth < 40 {
                    stack.push((mid, b, depth + 1));
                    stack.push((a, mid, depth + 1));
                } else {
                    out.push(b);
                }
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;

    /// FiberPath's cone example: 98 → 54 mm over 120 mm, 30° at the large end.
    fn reducer() -> ConeGeodesic {
        ConeGeodesic::new(49.0, 27.0, 120.0, 30.0).unwrap()
    }

    /// The geodesic traced independently: short straight steps on the unrolled sector, each
    /// mapped back to (z, θ) by the sector's polar coordinates.
    fn unrolled(steps: usize) -> (f64, f64, f64) {
        let (r0, r1, l) = (49.0f64, 27.0f64, 120.0f64);
        let sin_phi = (r0 - r1) / (r0 - r1).hypot(l);
        let s0 = r0 / sin_phi;
        let alpha = 30f64.to_radians();
        // Start at (s0, 0) heading at α from the generator, toward the apex.
        let (mut x, mut y) = (s0, 0.0);
        let (dx, dy) = (-alpha.cos(), alpha.sin());
        let h = 1e-3;
        let mut length = 0.0;
        for _ in 0..steps {
            let (nx, ny) = (x + h * dx, y + h * dy);
            if nx.hypot(ny) * sin_phi < r1 {
                break;
            }
            x = nx;
            y = ny;
            length += h;
        }
        let s = x.hypot(y);
        let z = (s0 - s) * (1.0 - sin_phi * sin_phi).sqrt();
        let theta = y.atan2(x) / sin_phi;
        (z, theta.to_degrees(), length)
    }

    #[test]
    fn the_turn_and_length_match_the_unrolled_sector() {
        let g = reducer();
        let (z, theta_deg, length) = unrolled(10_000_000);
        // The walk stops within one step of the small end.
        assert_abs_diff_eq!(z, 120.0, epsilon = 2e-3);
        assert_abs_diff_eq!(g.turn_deg(z), theta_deg, epsilon = 1e-3);
        assert_abs_diff_eq!(g.length_mm(), length, epsilon = 2e-3);
        // Clairaut: at the small end sin α = 49·sin 30° / 27.
        assert_abs_diff_eq!(
            g.wind_angle_deg(120.0),
            (24.5f64 / 27.0).asin().to_degrees(),
            epsilon = 1e-9
        );
        assert_abs_diff_eq!(g.wind_angle_deg(0.0), 30.0, epsilon = 1e-9);
    }

    #[test]
    fn a_nearly_straight_cone_turns_like_the_helix() {
        // r 50 → 49.999 over 100 mm at 45°: dθ/dz → tan α / r (seed 002 Eq. 20). The taper's
        // own effect is of the order Δr/r = 2·10⁻⁵ of the turn (0.005°).
        let g = ConeGeodesic::new(50.0, 49.999, 100.0, 45.0).unwrap();
        assert_abs_diff_eq!(
            g.turn_deg(100.0),
            (100.0f64 / 50.0).to_degrees(),
            epsilon = 1e-2
        );
        assert_abs_diff_eq!(g.length_mm(), 100.0 * 2f64.sqrt(), epsilon = 2e-3);
    }

    #[test]
    fn stations_keep_the_chord_and_end_on_the_breaks() {
        let g = reducer();
        let st = g.stations(&[5.0, 115.0]);
        assert_eq!(st[0].along_mm, 0.0);
        assert_eq!(st.last().unwrap().along_mm, 120.0);
        assert!(st.iter().any(|s| s.along_mm == 5.0));
        assert!(st.iter().any(|s| s.along_mm == 115.0));
        for w in st.windows(2) {
            assert!(w[1].along_mm > w[0].along_mm);
            // Check the chord at the quarter points too, not only where it was bisected.
            for f in [0.25, 0.5, 0.75] {
                let z = w[0].along_mm + f * (w[1].along_mm - w[0].along_mm);
                let lin = w[0].turn_deg + f * (w[1].turn_deg - w[0].turn_deg);
                let off = g.radius_mm(z) * (g.turn_deg(z) - lin).abs().to_radians();
                assert!(off <= 1.2 * CHORD_TOLERANCE_MM, "{z}: {off}");
            }
        }
        assert!(st.len() < 200, "{}", st.len());
        // Breaks outside the cone are ignored: the stations stay on it.
        let outside = g.stations(&[-5.0, 130.0]);
        assert_eq!(outside, g.stations(&[]));
        assert!(outside.iter().all(|s| (0.0..=120.0).contains(&s.along_mm)));
    }

    #[test]
    fn refuses_expanding_cones_and_steep_angles() {
        assert_eq!(
            ConeGeodesic::new(27.0, 49.0, 120.0, 30.0),
            Err(ConeRefusal::NotReducing)
        );
        // FiberPath's unreachable case: 40° on 98 → 54 mm; the steepest is asin(27/49).
        match ConeGeodesic::new(49.0, 27.0, 120.0, 40.0) {
            Err(ConeRefusal::TooSteep {
                clairaut_mm,
                steepest_deg,
            }) => {
                assert_abs_diff_eq!(clairaut_mm, 31.496, epsilon = 1e-3);
                assert_abs_diff_eq!(steepest_deg, 33.4370, epsilon = 1e-3);
            }
            other => panic!("{other:?}"),
        }
        // At exactly the steepest angle the fibre reaches the small end tangent to it.
        let edge = (27.0f64 / 49.0).asin().to_degrees();
        let g = ConeGeodesic::new(49.0, 27.0, 120.0, edge - 1e-9).unwrap();
        assert_abs_diff_eq!(g.wind_angle_deg(120.0), 90.0, epsilon = 1e-2);
    }
}
