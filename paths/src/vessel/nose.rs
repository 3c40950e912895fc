//! Helical passes on a nose: a surface of revolution that narrows from its base to a tip (the
//! von Kármán ogive of `.wind` files with a `profile`), wound on the geodesic or, with a
//! friction ratio λ, on the path that leans on friction to climb closer to the tip.
//!
//! # The surface
//!
//! The von Kármán ogive is the Haack series with C = 0: with `x` the distance from the tip, `L`
//! the length and `R` the base radius, `φ = acos(1 − 2x/L)` and
//!
//! ```text
//! r = (R / √π) · √(φ − sin 2φ / 2)
//! ```
//!
//! (r = R at the base, x = L, φ = π; r = 0 at the tip; r = R/√2 half way). We measure `z` from
//! the base, as the carriage runs, and parametrise the meridian by `u = π − φ` (0 at the base, π
//! at the tip): `z = L·(1 − cos u)/2`, `F(u) = π − u + sin 2u / 2`, `r = R·√(F/π)` and the
//! meridian's slope
//!
//! ```text
//! r' = dr/dz = −(2R / (L√π)) · sin u / √F,      dr'/du = −(2R / (L√π)) · (cos u / √F + sin³u / F^{3/2})
//! ```
//!
//! The slope is 0 at the base (the ogive meets a cylinder there) but the meridian's curvature
//! grows like z^{−1/2} toward the base (r ≈ R − c·z^{3/2}), which is why we integrate in u and
//! not in z or in arc length: in u every term below is smooth at the base.
//!
//! # The path
//!
//! A fibre crossing the meridian at the angle α (from the meridian, toward the tip) advances by
//! `dm = cos α·ds` along the meridian (arc length `dm = √(1 + r'²)·dz`) and by `r·dθ = sin α·ds`
//! around it. Its geodesic curvature (Liouville's formula for a surface of revolution, in the
//! orthonormal frame of meridian and parallel, whose parallel has geodesic curvature
//! `(dr/dm)/r`) is
//!
//! ```text
//! k_g = dα/ds + sin α · (dr/dm) / r
//! ```
//!
//! and its normal curvature (Euler) is `k_n = k_m·cos²α + k_p·sin²α`, from the meridian's
//! curvature `k_m = −r'' / (1 + r'²)^{3/2}` and the parallel's normal curvature
//! `k_p = 1 / (r·√(1 + r'²))` (both positive on a convex nose). A geodesic has `k_g = 0`:
//! `d(r·sin α)/ds = cos α·(r·dα/ds + sin α·dr/dm) = 0`, Clairaut's relation `r·sin α = C`. A tow
//! held by friction can have `|k_g| ≤ λ·k_n` (the slip condition: the sideways pull per unit
//! tension, `k_g`, against the surface's reaction, `k_n`, times the friction ratio λ). The path
//! that climbs farthest takes `k_g = −λ·k_n`, holding α back:
//!
//! ```text
//! dα/ds = −sin α · (dr/dm) / r − λ · (k_m·cos²α + k_p·sin²α)
//! ```
//!
//! With `dτ = ds / m_u` (m_u = dm/du = z_u·√(1 + r'²), z_u = dz/du) the system integrated is
//!
//! ```text
//! du/dτ = cos α
//! dα/dτ = −sin α · r'·z_u / r − λ · (−(dr'/du)·cos²α / (1 + r'²) + z_u·sin²α / r)
//! dθ/dτ = z_u·√(1 + r'²) · sin α / r
//! ds/dτ = z_u·√(1 + r'²)
//! ```
//!
//! smooth at the base (z_u = 0 there, but du/dτ = cos α is not) and through α = 90°.
//!
//! # The turnaround
//!
//! α grows toward the tip. Where it reaches 90° the fibre runs along a parallel: on the
//! geodesic that is where `r = C`; with friction it is deeper (smaller r). There
//! `dα/dτ = z_u·(|r'| − λ)/r`, so the path turns back toward the base whenever the meridian is
//! steeper than λ, and the way back is the mirror image of the way out (the mirror of a path
//! with `|k_g| = λ·k_n` has the same curvatures). The pass ends there, with no dwell: a hoop
//! turn with the carriage still at the turnaround would need the friction ratio |r'| there (the
//! parallel's `k_g / k_n`), above λ. All the end turns (lead-out, lock, pattern steps) are made
//! at the base, where the ogive's slope is 0 and a hoop is a geodesic.
//!
//! A path that would reach the tip region (radius below [`TIP_FRACTION`] of the base) without
//! turning is refused; so is one that friction turns back onto the meridian (α ≤ 0).
//!
//! # Accuracy and bounds
//!
//! Classical RK4 with a step of at most `r/200` of fibre (r the local radius) and at most
//! [`Meridian::max_du`] of the parameter; the turnaround (α = 90°) and each break (the end of
//! the lead-in) are landed on exactly by Newton's method on the last step. The tests check the
//! geodesic against Clairaut's invariant (to 10⁻⁹ of the radius), its turn against the
//! closed-form quadrature `dθ/dz = C·√(1 + r'²) / (r·√(r² − C²))`, a cone against
//! [`super::cone`], and the friction path's curvatures on the embedded 3-D curve. At most
//! [`MAX_STEPS`] steps are taken: a longer path is refused, so time and memory are bounded
//! whatever the input.

use super::cone::{CHORD_TOLERANCE_MM, Station};
use std::f64::consts::{FRAC_PI_2, PI};

/// Most integration steps one pass may take (each stored: about 48 bytes).
pub const MAX_STEPS: usize = 400_000;

/// A pass must turn around before the radius falls below this fraction of the base radius.
pub const TIP_FRACTION: f64 = 0.01;

/// Fibre per step, as a fraction of the local radius.
const STEP_PER_RADIUS: f64 = 1.0 / 200.0;

/// The meridian at parameter `u`: the surface's geometry the integration needs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeridianPoint {
    /// Axial distance from the base, mm.
    pub z: f64,
    /// dz/du.
    pub z_u: f64,
    /// Radius, mm.
    pub r: f64,
    /// The slope dr/dz.
    pub slope: f64,
    /// d(slope)/du.
    pub slope_u: f64,
}

/// A meridian parametrised by `u` from the base (u = 0) toward its end.
pub trait Meridian {
    /// The geometry at `u`.
    fn at(&self, u: f64) -> MeridianPoint;
    /// The parameter at axial distance `z` from the base.
    fn u_at(&self, z: f64) -> f64;
    /// The parameter's end (the tip or the far end).
    fn end(&self) -> f64;
    /// Largest parameter step of the integration.
    fn max_du(&self) -> f64;
}

/// The von Kármán ogive (Haack series, C = 0) from its base (radius `base_radius_mm`, z = 0) to
/// its tip (z = `length_mm`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VonKarman {
    /// R, mm.
    pub base_radius_mm: f64,
    /// L, mm.
    pub length_mm: f64,
}

impl VonKarman {
    /// The radius at axial distance `z` from the base, mm (the Haack formula in φ).
    pub fn radius_at(&self, z: f64) -> f64 {
        self.at(self.u_at(z)).r
    }
}

impl Meridian for VonKarman {
    fn at(&self, u: f64) -> MeridianPoint {
        let (r0, l) = (self.base_radius_mm, self.length_mm);
        let f = (PI - u + (2.0 * u).sin() / 2.0).max(0.0);
        let (s, c) = u.sin_cos();
        let k = 2.0 * r0 / (l * PI.sqrt());
        MeridianPoint {
            z: l * (1.0 - c) / 2.0,
            z_u: l * s / 2.0,
            r: r0 * (f / PI).sqrt(),
            slope: -k * s / f.sqrt(),
            slope_u: -k * (c / f.sqrt() + s.powi(3) / f.powf(1.5)),
        }
    }

    fn u_at(&self, z: f64) -> f64 {
        (1.0 - 2.0 * z / self.length_mm).clamp(-1.0, 1.0).acos()
    }

    fn end(&self) -> f64 {
        PI
    }

    fn max_du(&self) -> f64 {
        2e-3
    }
}

/// One integration node of a pass.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Node {
    /// The meridian parameter.
    pub u: f64,
    /// Axial distance from the base, mm.
    pub along_mm: f64,
    /// Radius, mm.
    pub radius_mm: f64,
    /// The fibre's angle from the meridian, radians.
    pub alpha_rad: f64,
    /// Mandrel turn since the base, radians.
    pub turn_rad: f64,
    /// Fibre length since the base, mm.
    pub length_mm: f64,
}

/// Why a nose pass cannot be wound.
#[derive(Debug, Clone, PartialEq)]
pub enum NoseRefusal {
    /// The wind angle or λ is outside what the integration accepts.
    Input(String),
    /// The path reaches the tip region without turning around.
    ReachesTip {
        /// The radius where it was stopped, mm.
        radius_mm: f64,
    },
    /// Friction turns the fibre back onto the meridian (α ≤ 0) before it turns around.
    OntoMeridian {
        /// Where, mm from the base.
        along_mm: f64,
    },
    /// The pass needs more than [`MAX_STEPS`] steps.
    TooManySteps,
}

impl std::fmt::Display for NoseRefusal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            NoseRefusal::Input(m) => f.write_str(m),
            NoseRefusal::ReachesTip { radius_mm } => write!(
                f,
                "the path reaches the tip (radius {radius_mm:.3} mm) without turning around"
            ),
            NoseRefusal::OntoMeridian { along_mm } => write!(
                f,
                "friction turns the fibre onto the meridian (0°) {along_mm:.3} mm from the base \
                 before it turns around; lower frictionLambda or raise the wind angle"
            ),
            NoseRefusal::TooManySteps => write!(
                f,
                "the pass needs more than {MAX_STEPS} integration steps of 1/200 of the local \
                 radius (a nose too slender for its length, or a path circling near its \
                 turnaround)"
            ),
        }
    }
}

/// A pass from the base to its turnaround.
#[derive(Debug, Clone, PartialEq)]
pub struct NosePass {
    nodes: Vec<Node>,
    breaks: Vec<usize>,
}

type State = [f64; 4];

/// The system above: (u, α, θ, s) per unit τ.
fn rate<M: Meridian>(m: &M, lambda: f64, y: &State) -> State {
    let p = m.at(y[0]);
    let (sa, ca) = y[1].sin_cos();
    let w2 = 1.0 + p.slope * p.slope;
    let m_u = p.z_u * w2.sqrt();
    [
        ca,
        -sa * p.slope * p.z_u / p.r - lambda * (-p.slope_u * ca * ca / w2 + p.z_u * sa * sa / p.r),
        m_u * sa / p.r,
        m_u,
    ]
}

fn rk4<M: Meridian>(m: &M, lambda: f64, y: &State, h: f64) -> State {
    let add = |a: &State, k: &State, f: f64| [0, 1, 2, 3].map(|i| a[i] + f * k[i]);
    let k1 = rate(m, lambda, y);
    let k2 = rate(m, lambda, &add(y, &k1, h / 2.0));
    let k3 = rate(m, lambda, &add(y, &k2, h / 2.0));
    let k4 = rate(m, lambda, &add(y, &k3, h));
    [0, 1, 2, 3].map(|i| y[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]))
}

/// The step from `y` (guess `h`) after which component `i` equals `target`, by Newton's method
/// on one RK4 step (the component's rate is its derivative in the step).
fn land<M: Meridian>(m: &M, lambda: f64, y: &State, mut h: f64, i: usize, target: f64) -> State {
    let mut end = rk4(m, lambda, y, h);
    for _ in 0..30 {
        let miss = end[i] - target;
        if miss.abs() < 1e-14 {
            break;
        }
        let slope = rate(m, lambda, &end)[i];
        if slope == 0.0 || !slope.is_finite() {
            break;
        }
        h = (h - miss / slope).max(0.0);
        end = rk4(m, lambda, y, h);
    }
    end[i] = target;
    end
}

impl NosePass {
    /// The pass leaving the base at `wind_angle_deg` from the meridian, on the geodesic
    /// (`lambda` 0) or the friction path with `|k_g| = lambda·k_n`, to its turnaround; with a
    /// node at each of `breaks` (axial distances from the base) that it reaches.
    pub fn trace<M: Meridian>(
        m: &M,
        wind_angle_deg: f64,
        lambda: f64,
        breaks: &[f64],
    ) -> Result<Self, NoseRefusal> {
        Self::trace_scaled(m, wind_angle_deg, lambda, breaks, 1.0)
    }

    /// [`NosePass::trace`] with the step limits times `scale`.
    fn trace_scaled<M: Meridian>(
        m: &M,
        wind_angle_deg: f64,
        lambda: f64,
        breaks: &[f64],
        scale: f64,
    ) -> Result<Self, NoseRefusal> {
        if !(wind_angle_deg > 0.0 && wind_angle_deg < 90.0) {
            return Err(NoseRefusal::Input(format!(
                "wind angle {wind_angle_deg}° must be between 0° and 90°"
            )));
        }
        if !(lambda >= 0.0 && lambda.is_finite()) {
            return Err(NoseRefusal::Input(format!(
                "friction ratio {lambda} must be ≥ 0"
            )));
        }
        let base = m.at(0.0);
        let tip_radius = TIP_FRACTION * base.r;
        let mut cuts: Vec<f64> = breaks
            .iter()
            .copied()
            .filter(|b| *b > 0.0 && b.is_finite())
            .map(|b| m.u_at(b))
            .collect();
        cuts.sort_by(f64::total_cmp);
        cuts.dedup();
        cuts.reverse();
        let node = |y: &State| {
            let p = m.at(y[0]);
            Node {
                u: y[0],
                along_mm: p.z,
                radius_mm: p.r,
                alpha_rad: y[1],
                turn_rad: y[2],
                length_mm: y[3],
            }
        };
        let mut y: State = [0.0, wind_angle_deg.to_radians(), 0.0, 0.0];
        let mut nodes = vec![node(&y)];
        let mut marks = Vec::new();
        while nodes.len() <= MAX_STEPS {
            let p = m.at(y[0]);
            let m_u = p.z_u * (1.0 + p.slope * p.slope).sqrt();
            let ds = scale * STEP_PER_RADIUS * p.r;
            let h = (ds / m_u).min(scale * m.max_du() / y[1].cos().abs().max(1e-9));
            let next = rk4(m, lambda, &y, h);
            if !next.iter().all(|v| v.is_finite()) {
                return Err(NoseRefusal::ReachesTip { radius_mm: p.r });
            }
            if next[1] >= FRAC_PI_2 {
                y = land(m, lambda, &y, h, 1, FRAC_PI_2);
                nodes.push(node(&y));
                return Ok(NosePass {
                    nodes,
                    breaks: marks,
                });
            }
            if let Some(&cut) = cuts.last()
                && next[0] >= cut
            {
                cuts.pop();
                y = land(m, lambda, &y, h, 0, cut);
                marks.push(nodes.len());
                nodes.push(node(&y));
                continue;
            }
            if next[0] >= m.end() || m.at(next[0]).r < tip_radius {
                return Err(NoseRefusal::ReachesTip { radius_mm: p.r });
            }
            if next[1] <= 0.0 {
                return Err(NoseRefusal::OntoMeridian { along_mm: p.z });
            }
            y = next;
            nodes.push(node(&y));
        }
        Err(NoseRefusal::TooManySteps)
    }

    /// Every integration node, from the base to the turnaround.
    pub fn nodes(&self) -> &[Node] {
        &self.nodes
    }

    /// The turnaround (α = 90°).
    pub fn turnaround(&self) -> Node {
        self.nodes[self.nodes.len() - 1]
    }

    /// The mandrel turn from the base to the turnaround, degrees.
    pub fn turn_deg(&self) -> f64 {
        self.turnaround().turn_rad.to_degrees()
    }

    /// Fibre length from the base to the turnaround, mm.
    pub fn length_mm(&self) -> f64 {
        self.turnaround().length_mm
    }

    /// Distance on the surface between node `k` and the straight move (in carriage and mandrel
    /// angle) from node `a` to node `b`, in the flat frame tangent at `k` (meridian length
    /// `√(1 + r'²)·dz` across, `r·dθ` around).
    fn off_chord(&self, m_slope: &[f64], a: usize, b: usize, k: usize) -> f64 {
        let (na, nb, nk) = (self.nodes[a], self.nodes[b], self.nodes[k]);
        let w = (1.0 + m_slope[k] * m_slope[k]).sqrt();
        let p = |n: Node| {
            (
                (n.along_mm - nk.along_mm) * w,
                (n.turn_rad - nk.turn_rad) * nk.radius_mm,
            )
        };
        let ((ax, ay), (bx, by)) = (p(na), p(nb));
        let (dx, dy) = (bx - ax, by - ay);
        let len2 = dx * dx + dy * dy;
        let t = if len2 > 0.0 {
            (-(ax * dx + ay * dy) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        (ax + t * dx).hypot(ay + t * dy)
    }

    /// Stations from the base to the turnaround, each break among them, so that every node of
    /// the path between two neighbours lies within [`CHORD_TOLERANCE_MM`] of the straight move
    /// between them (greedy: each station reaches as far as the tolerance allows, found by
    /// doubling then bisection).
    pub fn stations<M: Meridian>(&self, m: &M) -> Vec<Station> {
        let slopes: Vec<f64> = self.nodes.iter().map(|n| m.at(n.u).slope).collect();
        let last = self.nodes.len() - 1;
        let fits = |a: usize, b: usize| {
            (a + 1..b).all(|k| self.off_chord(&slopes, a, b, k) <= CHORD_TOLERANCE_MM)
        };
        let station = |n: &Node| Station {
            along_mm: n.along_mm,
            turn_deg: n.turn_rad.to_degrees(),
            wind_angle_deg: n.alpha_rad.to_degrees(),
        };
        let mut out = vec![station(&self.nodes[0])];
        let mut a = 0;
        while a < last {
            // The next station may not pass the next break.
            let limit = self.breaks.iter().copied().find(|&b| b > a).unwrap_or(last);
            let (mut good, mut step) = (a + 1, 1);
            while good < limit {
                let try_at = (a + 2 * step).min(limit);
                if !fits(a, try_at) {
                    break;
                }
                good = try_at;
                step *= 2;
            }
            let mut bad = (a + 2 * step).min(limit + 1);
            while bad - good > 1 {
                let mid = (good + bad) / 2;
                if fits(a, mid) { good = mid } else { bad = mid }
            }
            out.push(station(&self.nodes[good]));
            a = good;
        }
        out
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;

    /// FiberPath's nose example: 98 mm base, 300 mm long.
    fn nose() -> VonKarman {
        VonKarman {
            base_radius_mm: 49.0,
            length_mm: 300.0,
        }
    }

    #[test]
    fn the_ogive_has_the_haack_radius_at_known_stations() {
        let n = nose();
        // Base, tip, and the Haack formula by hand: x from the tip, φ = acos(1 − 2x/L).
        assert_abs_diff_eq!(n.radius_at(0.0), 49.0, epsilon = 1e-12);
        assert_abs_diff_eq!(n.radius_at(300.0), 0.0, epsilon = 1e-12);
        // Half way φ = π/2: r = R·√((π/2)/π) = R/√2.
        assert_abs_diff_eq!(n.radius_at(150.0), 49.0 / 2f64.sqrt(), epsilon = 1e-12);
        // x = L/4 (z = 225): φ = π/3, r = R·√((π/3 − √3/4)/π).
        let third = PI / 3.0 - 3f64.sqrt() / 4.0;
        assert_abs_diff_eq!(
            n.radius_at(225.0),
            49.0 * (third / PI).sqrt(),
            epsilon = 1e-12
        );
        // x = 3L/4 (z = 75): φ = 2π/3, r = R·√((2π/3 + √3/4)/π).
        let two = 2.0 * PI / 3.0 + 3f64.sqrt() / 4.0;
        assert_abs_diff_eq!(n.radius_at(75.0), 49.0 * (two / PI).sqrt(), epsilon = 1e-12);
        // Monotone from base to tip.
        let rs: Vec<f64> = (0..=300).map(|z| n.radius_at(f64::from(z))).collect();
        assert!(rs.windows(2).all(|w| w[1] < w[0]));
    }

    #[test]
    fn slope_and_its_derivative_match_finite_differences() {
        let n = nose();
        for u in [0.05, 0.4, 1.0, 1.6, 2.2, 2.8, 3.0] {
            let h = 1e-6;
            let (a, b, p) = (n.at(u - h), n.at(u + h), n.at(u));
            assert_abs_diff_eq!(p.z_u, (b.z - a.z) / (2.0 * h), epsilon = 1e-6);
            // r' = (dr/du) / (dz/du).
            let r_u = (b.r - a.r) / (2.0 * h);
            assert_abs_diff_eq!(p.slope, r_u / p.z_u, epsilon = 1e-6);
            let rel = (p.slope_u - (b.slope - a.slope) / (2.0 * h)) / p.slope_u.abs().max(1.0);
            assert!(rel.abs() < 1e-6, "{u}: {rel}");
        }
        // The base is flat: the ogive meets a cylinder tangentially.
        assert_eq!(n.at(0.0).slope, 0.0);
        assert_abs_diff_eq!(n.u_at(150.0), FRAC_PI_2, epsilon = 1e-15);
    }

    #[test]
    fn the_geodesic_keeps_clairauts_invariant_and_turns_at_c() {
        let n = nose();
        let pass = NosePass::trace(&n, 30.0, 0.0, &[]).unwrap();
        let c = 49.0 * 30f64.to_radians().sin();
        for node in pass.nodes() {
            let drift = node.radius_mm * node.alpha_rad.sin() - c;
            assert!(drift.abs() < 1e-9 * 49.0, "{node:?}: {drift}");
        }
        let end = pass.turnaround();
        assert_abs_diff_eq!(end.alpha_rad, FRAC_PI_2, epsilon = 1e-12);
        assert_abs_diff_eq!(end.radius_mm, c, epsilon = 1e-7);
        assert!(pass.nodes().len() < 20_000, "{}", pass.nodes().len());
    }

    /// θ at the turnaround by the closed-form quadrature of Clairaut's relation,
    /// `dθ/dz = C·√(1 + r'²) / (r·√(r² − C²))`, with `z = z_t − v²` to remove the square-root
    /// singularity at the turnaround, by Simpson's rule in v; and the length likewise from
    /// `ds/dz = r·√(1 + r'²) / √(r² − C²)`.
    pub(crate) fn clairaut_quadrature(n: &VonKarman, alpha_deg: f64) -> (f64, f64, f64) {
        let c = n.base_radius_mm * alpha_deg.to_radians().sin();
        let (mut lo, mut hi) = (0.0, n.length_mm);
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if n.radius_at(mid) > c {
                lo = mid
            } else {
                hi = mid
            }
        }
        let zt = lo;
        let slope = |z: f64| n.at(n.u_at(z)).slope;
        let f = |v: f64, num: fn(f64, f64) -> f64| {
            let z = zt - v * v;
            let r = n.radius_at(z);
            let d = (r * r - c * c).max(0.0).sqrt();
            if v == 0.0 {
                // The limit: r² − C² ≈ 2C·|r'|·v², so 2v/√(r² − C²) → 2/√(2C|r'|).
                let s = slope(zt);
                return num(r, c) * (1.0 + s * s).sqrt() * 2.0 / (2.0 * c * s.abs()).sqrt();
            }
            num(r, c) * (1.0 + slope(z).powi(2)).sqrt() * 2.0 * v / d
        };
        let vmax = zt.sqrt();
        let k = 20_000;
        let h = vmax / f64::from(k);
        let simpson = |num: fn(f64, f64) -> f64| {
            (0..=k)
                .map(|i| {
                    let w = if i == 0 || i == k {
                        1.0
                    } else if i % 2 == 1 {
                        4.0
                    } else {
                        2.0
                    };
                    w * f(f64::from(i) * h, num)
                })
                .sum::<f64>()
                * h
                / 3.0
        };
        (zt, simpson(|r, c| c / r), simpson(|r, _| r))
    }

    #[test]
    fn the_geodesic_turn_and_length_match_clairauts_quadrature() {
        let n = nose();
        for alpha in [10.0, 30.0, 60.0] {
            let pass = NosePass::trace(&n, alpha, 0.0, &[]).unwrap();
            let (zt, theta, length) = clairaut_quadrature(&n, alpha);
            assert_abs_diff_eq!(pass.turnaround().along_mm, zt, epsilon = 1e-6);
            assert_abs_diff_eq!(pass.turnaround().turn_rad, theta, epsilon = 1e-6);
            assert_abs_diff_eq!(pass.length_mm(), length, epsilon = 1e-5);
        }
    }

    /// A frustum as a meridian (u = z): its geodesic is closed-form in [`super::super::cone`].
    struct Frustum {
        r0: f64,
        r1: f64,
        l: f64,
    }

    impl Meridian for Frustum {
        fn at(&self, u: f64) -> MeridianPoint {
            let slope = (self.r1 - self.r0) / self.l;
            MeridianPoint {
                z: u,
                z_u: 1.0,
                r: self.r0 + slope * u,
                slope,
                slope_u: 0.0,
            }
        }
        fn u_at(&self, z: f64) -> f64 {
            z
        }
        fn end(&self) -> f64 {
            // A cone continued to its apex.
            self.l * self.r0 / (self.r0 - self.r1)
        }
        fn max_du(&self) -> f64 {
            1.0
        }
    }

    #[test]
    fn on_a_cone_the_geodesic_is_the_closed_form_one() {
        use super::super::cone::ConeGeodesic;
        // The cone continued past its small end turns around at r = C = 24.5; the closed form
        // up to the small end (27 mm) must agree at every node before it.
        let f = Frustum {
            r0: 49.0,
            r1: 27.0,
            l: 120.0,
        };
        let g = ConeGeodesic::new(49.0, 27.0, 120.0, 30.0).unwrap();
        let pass = NosePass::trace(&f, 30.0, 0.0, &[120.0]).unwrap();
        let mut checked = 0;
        for node in pass.nodes().iter().filter(|n| n.along_mm <= 120.0) {
            assert_abs_diff_eq!(
                node.turn_rad.to_degrees(),
                g.turn_deg(node.along_mm),
                epsilon = 1e-7
            );
            assert_abs_diff_eq!(
                node.alpha_rad.to_degrees(),
                g.wind_angle_deg(node.along_mm),
                epsilon = 1e-9
            );
            checked += 1;
        }
        assert!(checked > 100);
        let at_end = pass.nodes().iter().find(|n| n.along_mm == 120.0).unwrap();
        assert_abs_diff_eq!(at_end.length_mm, g.length_mm(), epsilon = 1e-7);
        assert_abs_diff_eq!(pass.turnaround().radius_mm, 24.5, epsilon = 1e-7);
    }

    /// The friction path's curvatures measured on the embedded curve X(s) = (r cos θ, r sin θ,
    /// z), by central differences over the nodes, against the surface normal.
    fn curvature_ratio(n: &VonKarman, pass: &NosePass, i: usize) -> f64 {
        let nodes = pass.nodes();
        let x = |k: usize| {
            let nd = nodes[k];
            [
                nd.radius_mm * nd.turn_rad.cos(),
                nd.radius_mm * nd.turn_rad.sin(),
                nd.along_mm,
            ]
        };
        let (a, b, c) = (x(i - 1), x(i), x(i + 1));
        let (h1, h2) = (
            nodes[i].length_mm - nodes[i - 1].length_mm,
            nodes[i + 1].length_mm - nodes[i].length_mm,
        );
        let t: Vec<f64> = (0..3).map(|j| (c[j] - a[j]) / (h1 + h2)).collect();
        let acc: Vec<f64> = (0..3)
            .map(|j| 2.0 * ((c[j] - b[j]) / h2 - (b[j] - a[j]) / h1) / (h1 + h2))
            .collect();
        // Outward normal of the surface at the node: (cos θ, sin θ, −r') / √(1 + r'²).
        let nd = nodes[i];
        let s = n.at(nd.u).slope;
        let w = (1.0 + s * s).sqrt();
        let normal = [nd.turn_rad.cos() / w, nd.turn_rad.sin() / w, -s / w];
        let dot = |p: &[f64], q: &[f64]| p[0] * q[0] + p[1] * q[1] + p[2] * q[2];
        let side = [
            normal[1] * t[2] - normal[2] * t[1],
            normal[2] * t[0] - normal[0] * t[2],
            normal[0] * t[1] - normal[1] * t[0],
        ];
        // Curvature toward the inside is positive normal curvature on a convex nose.
        -dot(&acc, &side) / -dot(&acc, &normal)
    }

    #[test]
    fn the_friction_path_holds_kg_at_lambda_times_kn() {
        let n = nose();
        let pass = NosePass::trace(&n, 30.0, 0.15, &[]).unwrap();
        let len = pass.nodes().len();
        // Also next to the base, where the meridian's curvature grows as z^(-1/2).
        for i in [
            3,
            10,
            30,
            len / 10,
            len / 3,
            len / 2,
            2 * len / 3,
            9 * len / 10,
        ] {
            let ratio = curvature_ratio(&n, &pass, i);
            assert_abs_diff_eq!(ratio.abs(), 0.15, epsilon = 2e-4);
        }
        // And the geodesic has none.
        let g = NosePass::trace(&n, 30.0, 0.0, &[]).unwrap();
        let len = g.nodes().len();
        for i in [len / 10, len / 2, 9 * len / 10] {
            assert!(curvature_ratio(&n, &g, i).abs() < 2e-3);
        }
        // Friction lays deeper: the turnaround is nearer the tip, on a smaller radius.
        assert!(pass.turnaround().along_mm > g.turnaround().along_mm + 50.0);
        // At the turnaround the meridian is steeper than λ (else the path could not turn).
        assert!(n.at(pass.turnaround().u).slope.abs() > 0.15);
    }

    #[test]
    fn the_friction_path_tends_to_the_geodesic_as_lambda_tends_to_zero() {
        let n = nose();
        let g = NosePass::trace(&n, 30.0, 0.0, &[]).unwrap();
        let f = NosePass::trace(&n, 30.0, 1e-9, &[]).unwrap();
        assert_abs_diff_eq!(f.turn_deg(), g.turn_deg(), epsilon = 1e-5);
        assert_abs_diff_eq!(f.length_mm(), g.length_mm(), epsilon = 1e-5);
        let small = NosePass::trace(&n, 30.0, 1e-3, &[]).unwrap();
        assert!(small.turnaround().along_mm > g.turnaround().along_mm);
    }

    #[test]
    fn halving_the_step_changes_nothing_that_matters() {
        // RK4's error falls 16-fold per halving: the default step against twice and half of it
        // bounds its error far below the comparison's 0.01° of wind angle.
        let n = nose();
        for lambda in [0.0, 0.15] {
            let f = NosePass::trace(&n, 30.0, lambda, &[]).unwrap();
            for scale in [0.5, 2.0] {
                let c = NosePass::trace_scaled(&n, 30.0, lambda, &[], scale).unwrap();
                assert_abs_diff_eq!(f.turn_deg(), c.turn_deg(), epsilon = 1e-6);
                assert_abs_diff_eq!(f.length_mm(), c.length_mm(), epsilon = 1e-6);
                assert_abs_diff_eq!(
                    f.turnaround().along_mm,
                    c.turnaround().along_mm,
                    epsilon = 1e-6
                );
            }
        }
    }

    #[test]
    fn breaks_are_nodes_and_stations_and_stations_keep_the_chord() {
        let n = nose();
        let pass = NosePass::trace(&n, 30.0, 0.15, &[5.0, -1.0, 0.0, 1e6]).unwrap();
        assert!(pass.nodes().iter().any(|x| (x.along_mm - 5.0).abs() < 1e-9));
        let st = pass.stations(&n);
        assert_eq!(st[0].along_mm, 0.0);
        assert_eq!(st[0].turn_deg, 0.0);
        assert_eq!(st.last().unwrap().wind_angle_deg, 90.0);
        assert!(st.iter().any(|s| (s.along_mm - 5.0).abs() < 1e-9));
        assert!(st.windows(2).all(|w| w[1].along_mm > w[0].along_mm));
        // Every node between two stations is within the tolerance of their chord: the chord
        // (straight in carriage and mandrel angle) mapped onto the surface in 3-D, its nearest
        // point to the node found by ternary search.
        let nodes = pass.nodes();
        let on_surface = |z: f64, theta_rad: f64| {
            let r = n.radius_at(z);
            [r * theta_rad.cos(), r * theta_rad.sin(), z]
        };
        let dist = |p: [f64; 3], q: [f64; 3]| {
            ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
        };
        let mut j = 0;
        let mut worst = 0.0f64;
        let mut spans = Vec::new();
        for w in st.windows(2) {
            let mut span = 0.0f64;
            let chord = |t: f64| {
                on_surface(
                    w[0].along_mm + t * (w[1].along_mm - w[0].along_mm),
                    (w[0].turn_deg + t * (w[1].turn_deg - w[0].turn_deg)).to_radians(),
                )
            };
            while nodes[j].along_mm < w[0].along_mm {
                j += 1;
            }
            while j < nodes.len() && nodes[j].along_mm <= w[1].along_mm {
                let nd = nodes[j];
                let p = on_surface(nd.along_mm, nd.turn_rad);
                let (mut lo, mut hi) = (0.0, 1.0);
                for _ in 0..100 {
                    let (a, b) = (lo + (hi - lo) / 3.0, hi - (hi - lo) / 3.0);
                    if dist(p, chord(a)) < dist(p, chord(b)) {
                        hi = b
                    } else {
                        lo = a
                    }
                }
                span = span.max(dist(p, chord(lo)));
                j += 1;
            }
            worst = worst.max(span);
            spans.push(span);
        }
        // Each station reaches as far as the tolerance allows: most spans come close to it.
        let full = spans
            .iter()
            .filter(|d| **d > 0.8 * CHORD_TOLERANCE_MM)
            .count();
        // All but the two spans cut short, by the break and by the turnaround (80 of 82).
        assert!(full + 2 >= spans.len(), "{full} of {}", spans.len());
        assert!(worst <= 1.05 * CHORD_TOLERANCE_MM, "{worst}");
        assert!(worst > 0.5 * CHORD_TOLERANCE_MM, "{worst}");
        assert!(st.len() < 2000, "{}", st.len());
        assert!(st.len() * 5 < nodes.len());
    }

    #[test]
    fn refusals() {
        let n = nose();
        assert!(matches!(
            NosePass::trace(&n, 0.0, 0.0, &[]),
            Err(NoseRefusal::Input(_))
        ));
        assert!(matches!(
            NosePass::trace(&n, 90.0, 0.0, &[]),
            Err(NoseRefusal::Input(_))
        ));
        assert!(matches!(
            NosePass::trace(&n, 30.0, -0.1, &[]),
            Err(NoseRefusal::Input(_))
        ));
        assert!(matches!(
            NosePass::trace(&n, 30.0, f64::NAN, &[]),
            Err(NoseRefusal::Input(_))
        ));
        // A shallow wind with much friction is turned onto the meridian near the base, where
        // the meridian's curvature is large.
        match NosePass::trace(&n, 2.0, 0.5, &[]) {
            Err(NoseRefusal::OntoMeridian { along_mm }) => assert!(along_mm < 150.0),
            other => panic!("{other:?}"),
        }
        // A very small angle's geodesic reaches the tip region (C < 1 % of R).
        match NosePass::trace(&n, 0.3, 0.0, &[]) {
            Err(NoseRefusal::ReachesTip { radius_mm }) => assert!(radius_mm < 0.6),
            other => panic!("{other:?}"),
        }
        // A geodesic on a cylinder never turns around: a steep one circles until the step cap.
        assert_eq!(
            NosePass::trace(&Cylinder, 89.0, 0.0, &[]),
            Err(NoseRefusal::TooManySteps)
        );
    }

    #[test]
    fn each_step_is_the_stated_one() {
        // Every step but the landings is r/200 of fibre (r at its start) or 0.002 of the
        // parameter, whichever is shorter: the larger of the two ratios is 1.
        let n = nose();
        for lambda in [0.0, 0.15] {
            let pass = NosePass::trace(&n, 30.0, lambda, &[]).unwrap();
            let nodes = pass.nodes();
            let (mut by_s, mut by_u) = (0, 0);
            for w in nodes[..nodes.len() - 1].windows(2) {
                let rs = (w[1].length_mm - w[0].length_mm) / (w[0].radius_mm / 200.0);
                let ru = (w[1].u - w[0].u) / 2e-3;
                assert!((0.997..=1.003).contains(&rs.max(ru)), "{w:?}: {rs} {ru}");
                if rs > ru { by_s += 1 } else { by_u += 1 }
            }
            // Near the base the parameter limits the step, farther on the fibre length.
            assert!(by_s > 1000 && by_u > 300, "{by_s} {by_u}");
        }
    }

    #[test]
    fn landing_stops_where_the_component_does_not_move() {
        // On a cylinder's geodesic α does not change: Newton has no slope to follow, and the
        // landing keeps the step it was given rather than dividing by zero.
        let y: State = [0.0, 30f64.to_radians(), 0.0, 0.0];
        let end = land(&Cylinder, 0.0, &y, 1.0, 1, FRAC_PI_2);
        assert!(end.iter().all(|v| v.is_finite()), "{end:?}");
        assert_abs_diff_eq!(end[0], 30f64.to_radians().cos(), epsilon = 1e-12);
        assert_eq!(end[1], FRAC_PI_2);
        // Where it moves, it lands: u = 2 on the cylinder after a step of 2 / cos 30°.
        let end = land(&Cylinder, 0.0, &y, 1.0, 0, 2.0);
        assert_eq!(end[0], 2.0);
        assert_abs_diff_eq!(end[3], 2.0 / 30f64.to_radians().cos(), epsilon = 1e-12);
    }

    /// A cylinder of radius 50 mm, endless.
    struct Cylinder;

    impl Meridian for Cylinder {
        fn at(&self, u: f64) -> MeridianPoint {
            MeridianPoint {
                z: u,
                z_u: 1.0,
                r: 50.0,
                slope: 0.0,
                slope_u: 0.0,
            }
        }
        fn u_at(&self, z: f64) -> f64 {
            z
        }
        fn end(&self) -> f64 {
            f64::INFINITY
        }
        fn max_du(&self) -> f64 {
            1.0
        }
    }
}
