//! The delivery eye of a lathe winder over a cylinder with hemispherical domes (seed 002 §3.2,
//! Eqs. 12–21, Figs. 10–11).
//!
//! Frames. The mandrel frame xyz has z on the mandrel axis, origin at the dome's centre, z towards
//! the pole. On a dome the tow lies on a great circle in the plane tilted about x by the cylinder
//! wind angle βc; α is the angle in that plane from x̄ to the tangent point M: α = 0 puts M on the
//! equator, α = 90° at the polar opening, α = 180° back on the equator on the other side. The eye
//! sits on the free tow, `s` millimetres beyond M along the tow's tangent: on the 4-axis machine
//! s = λ = √(Re² − Rc²) (Eq. 12), the eye then runs on a circle of radius Re around the dome's
//! centre (Eq. 13); on a 2-axis machine (no cross-feed) s is whatever puts the eye at the fixed
//! radius of its carriage.
//!
//! Machine axes (Eq. 16): X, the eye's angle about the mandrel axis in the mandrel frame (the
//! mandrel turns the opposite way); Y, the eye's axial position; Z, the eye's distance from the
//! axis (cross-feed); A, the eye rotation π/2 − β at M (Eq. 21).

use std::f64::consts::FRAC_PI_2;

/// A point of the eye path in the machine's terms (Eq. 16), in the dome's frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EyePoint {
    /// The eye's angle about the axis in the mandrel frame, radians, in (−π, π] (Eq. 17's X).
    pub angle_rad: f64,
    /// The eye's axial position from the dome centre towards the pole, mm (Eq. 17's Y).
    pub axial_mm: f64,
    /// The eye's distance from the axis, mm (Eq. 17's Z).
    pub radius_mm: f64,
    /// The eye rotation π/2 − β at the tangent point, radians (Eq. 21), ≥ 0.
    pub rotation_rad: f64,
}

/// The dome and cylinder of a vessel with equal polar openings, and where the eye rides.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EyePath {
    /// Rc, the winding radius of the cylinder and of the hemispheres, mm.
    pub cylinder_radius_mm: f64,
    /// rp, the polar opening's radius, mm.
    pub polar_radius_mm: f64,
    /// s, the free tow length from the tangent point to the eye, mm (λ for the 4-axis machine).
    pub free_length_mm: f64,
}

impl EyePath {
    /// The 4-axis machine: the eye on a circle of radius `eye_radius_mm` (Re) about the dome's
    /// centre, free length λ = √(Re² − Rc²) (Eq. 12). `None` if Re ≤ Rc.
    pub fn on_circle(
        cylinder_radius_mm: f64,
        polar_radius_mm: f64,
        eye_radius_mm: f64,
    ) -> Option<EyePath> {
        let l2 = eye_radius_mm * eye_radius_mm - cylinder_radius_mm * cylinder_radius_mm;
        (l2 > 0.0).then(|| EyePath {
            cylinder_radius_mm,
            polar_radius_mm,
            free_length_mm: l2.sqrt(),
        })
    }

    /// sin βc and cos βc (Eq. 1).
    fn wind(&self) -> (f64, f64) {
        let s = self.polar_radius_mm / self.cylinder_radius_mm;
        (s, (1.0 - s * s).sqrt())
    }

    /// The tangent point M and the tow's unit tangent at α, in the mandrel frame (Eqs. 13–14
    /// written as vectors: eye = M + s·T).
    fn tangent(&self, alpha_rad: f64) -> ([f64; 3], [f64; 3]) {
        let (sb, cb) = self.wind();
        let (sa, ca) = alpha_rad.sin_cos();
        let rc = self.cylinder_radius_mm;
        // Plane frame: M̄ = Rc(cos α, 0, sin α), T̄ = (−sin α, 0, cos α); rotate about x by βc.
        let m = [rc * ca, -rc * sa * sb, rc * sa * cb];
        let t = [-sa, -ca * sb, ca * cb];
        (m, t)
    }

    /// Eq. 21 at the tangent point of α: π/2 − β with sin β = rp / r(M), r(M)² = Rc² cos² α +
    /// rp² sin² α.
    fn rotation_at(&self, alpha_rad: f64) -> f64 {
        let (sa, ca) = alpha_rad.sin_cos();
        let rc = self.cylinder_radius_mm;
        let rp = self.polar_radius_mm;
        let r = (rc * rc * ca * ca + rp * rp * sa * sa).sqrt();
        FRAC_PI_2 - (rp / r).min(1.0).asin()
    }

    /// The eye on the dome at α with free length `s_mm` (Eq. 17 when s = λ).
    fn dome_at(&self, alpha_rad: f64, s_mm: f64) -> EyePoint {
        let (m, t) = self.tangent(alpha_rad);
        let e = [m[0] + s_mm * t[0], m[1] + s_mm * t[1], m[2] + s_mm * t[2]];
        EyePoint {
            angle_rad: e[1].atan2(e[0]),
            axial_mm: e[2],
            radius_mm: e[0].hypot(e[1]),
            rotation_rad: self.rotation_at(alpha_rad),
        }
    }

    /// The 4-axis eye on the dome at α (Eq. 17, Eq. 21).
    pub fn dome(&self, alpha_rad: f64) -> EyePoint {
        self.dome_at(alpha_rad, self.free_length_mm)
    }

    /// The 2-axis eye on the dome at α: the point of the free tow at distance `radius_mm` from
    /// the axis (no cross-feed, no eye rotation). `None` if the tow line never gets that far
    /// (only when `radius_mm` is inside the mandrel).
    pub fn dome_fixed_radius(&self, alpha_rad: f64, radius_mm: f64) -> Option<EyePoint> {
        let (m, t) = self.tangent(alpha_rad);
        // |(m + s t)_xy|² = radius²: a s² + 2 b s + c = 0, take the root ahead of M.
        let a = t[0] * t[0] + t[1] * t[1];
        let b = m[0] * t[0] + m[1] * t[1];
        let c = m[0] * m[0] + m[1] * m[1] - radius_mm * radius_mm;
        let disc = b * b - a * c;
        if a <= 0.0 || disc < 0.0 || c > 0.0 {
            return None;
        }
        let s = (-b + disc.sqrt()) / a;
        Some(self.dome_at(alpha_rad, s))
    }

    /// α* = arcsin(Rc/Re): where the eye is nearest the axis on the way to the pole and farthest
    /// out axially (the split point of the seed's grid). For free length s it is atan(Rc/s).
    pub fn split_alpha_rad(&self) -> f64 {
        self.cylinder_radius_mm.atan2(self.free_length_mm)
    }

    /// The eye on the cylinder (Eq. 20): constant radius √(Rc² + λ² sin² βc), axial lead λ cos βc
    /// ahead of the tangent point, angle lead atan(λ sin βc / Rc) behind it, rotation π/2 − βc:
    /// the dome's eye at α = 0, where the two pieces join, for a tangent point at angle 0.
    pub fn cylinder(&self) -> EyePoint {
        self.dome(0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;

    fn seed() -> EyePath {
        EyePath::on_circle(60.0, 21.0, 90.0).unwrap()
    }

    /// Eq. 17 as printed (with Eq. 13's "+" sign).
    fn eq17(alpha: f64) -> (f64, f64, f64) {
        let (rc, rp) = (60.0f64, 21.0f64);
        let l = (90.0f64 * 90.0 - rc * rc).sqrt();
        let (sa, ca) = alpha.sin_cos();
        let u = rc * sa + l * ca;
        let v = rc * ca - l * sa;
        let x = (-rp * u).atan2(rc * v);
        let y = (rc * rc - rp * rp).sqrt() / rc * u;
        let z = (v * v + (rp / rc).powi(2) * u * u).sqrt();
        (x, y, z)
    }

    #[test]
    fn tv9_lambda_and_eye_positions() {
        let p = seed();
        assert_abs_diff_eq!(p.free_length_mm, 67.08204, epsilon = 1e-5);
        let e0 = p.dome(0.0);
        assert_abs_diff_eq!(e0.axial_mm, 62.8391, epsilon = 1e-4);
        assert_abs_diff_eq!(e0.radius_mm, 64.4302, epsilon = 1e-4);
        assert_abs_diff_eq!(e0.angle_rad.to_degrees(), -21.3710, epsilon = 1e-4);
        let e90 = p.dome(90f64.to_radians());
        assert_abs_diff_eq!(e90.axial_mm, 56.2050, epsilon = 1e-4);
        assert_abs_diff_eq!(e90.radius_mm, 70.2922, epsilon = 1e-4);
        assert_abs_diff_eq!(e90.angle_rad.to_degrees(), -162.6173, epsilon = 1e-4);
        assert_abs_diff_eq!(e90.rotation_rad, 0.0, epsilon = 1e-9);
        let star = p.split_alpha_rad();
        assert_abs_diff_eq!(star.to_degrees(), 41.8103, epsilon = 1e-4);
        let es = p.dome(star);
        assert_abs_diff_eq!(es.radius_mm, 31.5, epsilon = 1e-9);
        assert_abs_diff_eq!(es.axial_mm, 84.3075, epsilon = 1e-4);
        let ez = p.dome(star + 90f64.to_radians());
        assert_abs_diff_eq!(ez.radius_mm, 90.0, epsilon = 1e-9);
        assert_abs_diff_eq!(ez.axial_mm, 0.0, epsilon = 1e-9);
    }

    #[test]
    fn vector_form_is_eq17_everywhere() {
        let p = seed();
        for i in 0..=180 {
            let a = f64::from(i).to_radians();
            let (x, y, z) = eq17(a);
            let e = p.dome(a);
            assert_abs_diff_eq!(e.angle_rad, x, epsilon = 1e-12);
            assert_abs_diff_eq!(e.axial_mm, y, epsilon = 1e-9);
            assert_abs_diff_eq!(e.radius_mm, z, epsilon = 1e-9);
        }
    }

    #[test]
    fn tv11_cylinder_eye() {
        let c = seed().cylinder();
        assert_abs_diff_eq!(c.radius_mm, 64.4302, epsilon = 1e-4);
        assert_abs_diff_eq!(c.rotation_rad.to_degrees(), 69.5127, epsilon = 1e-4);
        // Eq. 20's Z from the involute screw surface at any θ.
        let (rc, l, b) = (60.0f64, 67.08204f64, (21.0f64 / 60.0).asin());
        for th in [0.0f64, 0.5, 2.0] {
            let z = ((rc * th.cos() + l * b.sin() * th.sin()).powi(2)
                + (rc * th.sin() - l * b.sin() * th.cos()).powi(2))
            .sqrt();
            assert_abs_diff_eq!(z, c.radius_mm, epsilon = 1e-4);
        }
    }

    #[test]
    fn fixed_radius_eye_keeps_its_radius_and_meets_the_circle_eye() {
        let p = seed();
        for i in 0..=18 {
            let a = f64::from(i * 10).to_radians();
            let e = p.dome_fixed_radius(a, 90.0).unwrap();
            assert_abs_diff_eq!(e.radius_mm, 90.0, epsilon = 1e-9);
        }
        // Where the circle eye is at radius Re (α* + 90°) the two eyes coincide.
        let a = p.split_alpha_rad() + 90f64.to_radians();
        let fixed = p.dome_fixed_radius(a, 90.0).unwrap();
        let circle = p.dome(a);
        assert_abs_diff_eq!(fixed.axial_mm, circle.axial_mm, epsilon = 1e-9);
        assert_abs_diff_eq!(fixed.angle_rad, circle.angle_rad, epsilon = 1e-9);
        assert!(p.dome_fixed_radius(0.3, 30.0).is_none());
        assert!(EyePath::on_circle(60.0, 21.0, 60.0).is_none());
    }
}
