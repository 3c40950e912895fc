//! The tangent angle: how far to turn the mandrel so that the robot sees a path point on the
//! tangent (seed 001 §3.2, eqs 3.1–3.7, Fig. 3.1).
//!
//! # Frames
//! The **drive frame** is fixed in the cell: origin on the rotation axis at the mandrel frame's
//! origin, `z` up the rotation axis, `x` pointing away from the robot, whose pedestal stands at
//! `(−b, 0)`. A mandrel angle `φ` turns the mandrel frame about `z` into the drive frame.

use nalgebra::Vector2;

/// Eq 3.7 as the thesis writes it: `θ = arccos((−r − R cos Ψ)/b) − Ψ`, the angle of the section
/// centroid in the drive frame at which the robot line is tangent to the point at `Ψ`.
/// Returns the argument of `arccos` as the error when it lies outside [−1, 1].
pub fn eq_3_7_rad(
    centroid_offset_mm: f64,
    radius_mm: f64,
    psi_rad: f64,
    robot_distance_mm: f64,
) -> Result<f64, f64> {
    let argument = (-radius_mm - centroid_offset_mm * psi_rad.cos()) / robot_distance_mm;
    if argument.abs() > 1.0 || !argument.is_finite() {
        return Err(argument);
    }
    Ok(argument.acos() - psi_rad)
}

/// Which of the two tangent flanks the robot sees the point on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Flank {
    /// The outward normal points to `+y` of the drive frame (eq 3.7's `+arccos`).
    Left,
    /// The outward normal points to `−y` (`−arccos`).
    Right,
}

/// The mandrel angle `φ` that puts a point on the tangent plane through the robot pedestal's
/// vertical line, for any surface: `point_xy` and `normal_xy` are the horizontal parts of the point
/// and its outward surface normal in the mandrel frame.
///
/// With the normal `n` horizontal and of length 1 the tangency condition `(Rφ p + b x̂)·Rφ n = 0`
/// reads `p·n + b cos(α + φ) = 0`, `α` the normal's angle, so `φ = ±arccos(−p·n/b) − α`. For a
/// circular section `p·n = r + R cos Ψ` and `α − γ = Ψ` (`γ` the centroid's angle), which is
/// eq 3.7 with `θ = φ + γ`. For tilted sections the exact normal replaces the circle.
pub fn mandrel_angle_rad(
    point_xy: Vector2<f64>,
    normal_xy: Vector2<f64>,
    robot_distance_mm: f64,
    flank: Flank,
) -> Result<f64, f64> {
    solve(point_xy, normal_xy, robot_distance_mm, flank).map(|a| a.rad)
}

/// A mandrel angle with its cosine and sine.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Angle {
    /// The angle in (−π, π].
    pub rad: f64,
    /// Its cosine.
    pub cos: f64,
    /// Its sine.
    pub sin: f64,
}

/// [`mandrel_angle_rad`] with the angle's cosine and sine, found without trigonometric calls but
/// one `atan2`: `φ = β − α` with `cos β = −p·n/b`, `sin β = ±√(1 − cos² β)` and `(cos α, sin α)`
/// the unit normal.
pub fn solve(
    point_xy: Vector2<f64>,
    normal_xy: Vector2<f64>,
    robot_distance_mm: f64,
    flank: Flank,
) -> Result<Angle, f64> {
    let n = normal_xy.normalize();
    let cos_b = -point_xy.dot(&n) / robot_distance_mm;
    if cos_b.abs() > 1.0 || !cos_b.is_finite() {
        return Err(cos_b);
    }
    let sin_b = match flank {
        Flank::Left => (1.0 - cos_b * cos_b).sqrt(),
        Flank::Right => -(1.0 - cos_b * cos_b).sqrt(),
    };
    let cos = cos_b * n.x + sin_b * n.y;
    let sin = sin_b * n.x - cos_b * n.y;
    Ok(Angle {
        rad: sin.atan2(cos),
        cos,
        sin,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;
    use nalgebra::Rotation2;

    /// The edge of eq 3.7's domain: with `b = r + R` and `Ψ = 0` the argument is exactly −1, a
    /// valid arccos (θ = π: the point faces the robot along the line of centres); just past it
    /// the argument is refused.
    #[test]
    fn eq_3_7_takes_the_edge_of_its_domain() {
        assert_eq!(eq_3_7_rad(10.0, 30.0, 0.0, 40.0), Ok(std::f64::consts::PI));
        let past = eq_3_7_rad(10.0, 30.0, 0.0, 39.0);
        assert!(matches!(past, Err(a) if a < -1.0), "{past:?}");
        // The same edge in `solve`: a point 30 mm out along its own normal, the robot 30 mm
        // away, on either flank: β = π, so φ = π.
        for flank in [Flank::Left, Flank::Right] {
            let at = solve(Vector2::new(30.0, 0.0), Vector2::new(1.0, 0.0), 30.0, flank).unwrap();
            assert_eq!((at.rad, at.cos, at.sin), (std::f64::consts::PI, -1.0, 0.0));
        }
        assert!(
            solve(
                Vector2::new(30.0, 0.0),
                Vector2::new(1.0, 0.0),
                29.0,
                Flank::Left
            )
            .is_err()
        );
    }

    /// Direct tangency check: rotate the section by θ about the drive axis, then the line from the
    /// robot pedestal (−b, 0) to the point is perpendicular to the radius at the point.
    fn tangency_residual(big_r: f64, r: f64, psi: f64, b: f64, theta: f64) -> f64 {
        let centroid = Vector2::new(big_r * theta.cos(), big_r * theta.sin()); // eqs 3.2, 3.3
        let radial = Vector2::new((psi + theta).cos(), (psi + theta).sin());
        let point = centroid + radial * r; // eqs 3.4, 3.5
        let robot_line = point - Vector2::new(-b, 0.0);
        robot_line.dot(&radial) / robot_line.norm()
    }

    #[test]
    fn eq_3_7_agrees_with_direct_tangency_for_r_0_to_3_radii() {
        let (r, b) = (31.75, 800.0);
        for k in 0..=3 {
            let big_r = k as f64 * r;
            for i in 0..72 {
                let psi = i as f64 * 5f64.to_radians() - std::f64::consts::PI;
                let theta = eq_3_7_rad(big_r, r, psi, b).unwrap();
                assert_abs_diff_eq!(
                    tangency_residual(big_r, r, psi, b, theta),
                    0.0,
                    epsilon = 1e-9
                );
            }
        }
    }

    #[test]
    fn general_form_reduces_to_eq_3_7_for_circular_sections() {
        let (r, b) = (31.75, 800.0);
        for k in 0..=3 {
            let big_r = k as f64 * r;
            for i in 0..36 {
                let psi = i as f64 * 10f64.to_radians();
                // Centroid on +x of the mandrel frame (γ = 0), point at Ψ around it.
                let n = Vector2::new(psi.cos(), psi.sin());
                let p = Vector2::new(big_r, 0.0) + n * r;
                let phi = mandrel_angle_rad(p, n, b, Flank::Left).unwrap();
                let theta = eq_3_7_rad(big_r, r, psi, b).unwrap();
                let wrapped = (phi - theta).rem_euclid(std::f64::consts::TAU);
                assert!(
                    wrapped < 1e-12 || std::f64::consts::TAU - wrapped < 1e-12,
                    "{phi} {theta}"
                );
                // And it is tangent after rotating by φ.
                let rot = Rotation2::new(phi);
                let (pr, nr) = (rot * p, rot * n);
                assert_abs_diff_eq!((pr + Vector2::new(b, 0.0)).dot(&nr), 0.0, epsilon = 1e-9);
            }
        }
    }

    #[test]
    fn robot_too_close_is_reported_with_the_argument() {
        let err = eq_3_7_rad(3.0 * 31.75, 31.75, 0.0, 100.0).unwrap_err();
        assert!(err.abs() > 1.0);
        let n = Vector2::new(1.0, 0.0);
        assert!(mandrel_angle_rad(n * 150.0, n, 100.0, Flank::Right).is_err());
    }
}
