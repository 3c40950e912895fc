//! Wrist orientation as the robot's quaternion Q1..Q4 (seed 001 App. A).
//!
//! The ASEA wrist has pitch and roll but no yaw. App. A composes a pitch θ about Y with a roll Φ
//! about the rotated X (eqs A.2–A.16): `Q1 = cos(θ/2)cos(Φ/2)`, `Q2 = cos(θ/2)sin(Φ/2)`,
//! `Q3 = sin(θ/2)cos(Φ/2)`, `Q4 = −sin(θ/2)sin(Φ/2)`, scalar first. We point the tool's `z` axis
//! (the payout eye's bore) along the free fibre, from the eye to the tangent point: any direction
//! is reachable with pitch and roll alone, and the eye does not care about the turn about its bore.

use nalgebra::{Quaternion, Unit, UnitQuaternion, Vector3};

/// The App. A quaternion for `pitch_rad` (about Y) then `roll_rad` (about the new X).
pub fn from_pitch_roll(pitch_rad: f64, roll_rad: f64) -> UnitQuaternion<f64> {
    UnitQuaternion::from_axis_angle(&Vector3::y_axis(), pitch_rad)
        * UnitQuaternion::from_axis_angle(&Vector3::x_axis(), roll_rad)
}

/// Pitch and roll that point the tool `z` axis along `direction`: with `R = R_y(θ) R_x(Φ)`,
/// `R ẑ = (cos Φ sin θ, −sin Φ, cos Φ cos θ)`.
pub fn pitch_roll_toward(direction: &Unit<Vector3<f64>>) -> (f64, f64) {
    let d = direction.as_ref();
    let roll = (-d.y).clamp(-1.0, 1.0).asin();
    let pitch = d.x.atan2(d.z);
    (pitch, roll)
}

/// The App. A quaternion whose tool `z` axis points along `direction`: the same rotation as
/// `from_pitch_roll(pitch_roll_toward(direction))`, from half-angle identities instead of
/// trigonometric calls (pitch in (−π, π], roll in [−π/2, π/2]).
pub fn toward(direction: &Unit<Vector3<f64>>) -> UnitQuaternion<f64> {
    let d = direction.as_ref();
    let cos_roll = (d.x * d.x + d.z * d.z).sqrt();
    let sin_roll = -d.y;
    let (cos_pitch, sin_pitch) = if cos_roll > 1e-15 {
        (d.z / cos_roll, d.x / cos_roll)
    } else {
        (1.0, 0.0)
    };
    let half = |c: f64, s: f64| {
        let ch = (0.5 * (1.0 + c)).max(0.0).sqrt();
        let sh = (0.5 * (1.0 - c)).max(0.0).sqrt();
        (ch, if s < 0.0 { -sh } else { sh })
    };
    let (ct, st) = half(cos_pitch, sin_pitch);
    let (cf, sf) = half(cos_roll, sin_roll);
    // Eqs A.13–A.16.
    UnitQuaternion::new_unchecked(Quaternion::new(ct * cf, ct * sf, st * cf, -st * sf))
}

/// Pitch and roll of an App. A quaternion (the inverse of [`from_pitch_roll`]).
pub fn pitch_roll(q: &UnitQuaternion<f64>) -> (f64, f64) {
    pitch_roll_toward(&Unit::new_normalize(q * Vector3::z()))
}

/// Scalar-first components `[q1, q2, q3, q4]` as the robot takes them.
pub fn components(q: &UnitQuaternion<f64>) -> [f64; 4] {
    [q.w, q.i, q.j, q.k]
}

/// `q` or `−q` (the same rotation), whichever keeps `q·previous ≥ 0`, so consecutive poses never
/// flip sign and the controller never sees a 360° wrist turn.
pub fn continuous(q: UnitQuaternion<f64>, previous: &UnitQuaternion<f64>) -> UnitQuaternion<f64> {
    if q.coords.dot(&previous.coords) < 0.0 {
        UnitQuaternion::new_unchecked(-q.into_inner())
    } else {
        q
    }
}

/// The quaternion from scalar-first components, normalised.
pub fn from_components(q: [f64; 4]) -> UnitQuaternion<f64> {
    UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;
    use std::f64::consts::FRAC_PI_2;

    #[test]
    fn app_a_vectors() {
        let q = components(&from_pitch_roll(FRAC_PI_2, FRAC_PI_2));
        assert_abs_diff_eq!(
            q.as_slice(),
            [0.5, 0.5, 0.5, -0.5].as_slice(),
            epsilon = 1e-12
        );
        let q = components(&from_pitch_roll(0.0, 0.0));
        assert_abs_diff_eq!(
            q.as_slice(),
            [1.0, 0.0, 0.0, 0.0].as_slice(),
            epsilon = 1e-12
        );
    }

    #[test]
    fn matches_the_closed_form_of_eqs_a13_to_a16() {
        for &(t, f) in &[(0.3, -1.1), (2.0, 0.4), (-0.7, 2.9)] {
            let q = components(&from_pitch_roll(t, f));
            let (h, g) = (t / 2.0, f / 2.0);
            let expected = [
                h.cos() * g.cos(),
                h.cos() * g.sin(),
                h.sin() * g.cos(),
                -h.sin() * g.sin(),
            ];
            assert_abs_diff_eq!(q.as_slice(), expected.as_slice(), epsilon = 1e-12);
        }
    }

    #[test]
    fn pitch_roll_points_the_tool_axis_along_the_direction() {
        for d in [
            Vector3::new(1.0, 0.2, 0.5),
            Vector3::new(-0.3, -0.9, -0.1),
            Vector3::z(),
        ] {
            let dir = Unit::new_normalize(d);
            let (pitch, roll) = pitch_roll_toward(&dir);
            let axis = from_pitch_roll(pitch, roll) * Vector3::z();
            assert_abs_diff_eq!(axis, dir.into_inner(), epsilon = 1e-12);
        }
    }

    #[test]
    fn toward_equals_pitch_then_roll() {
        for d in [
            Vector3::new(1.0, 0.2, 0.5),
            Vector3::new(-0.3, -0.9, -0.1),
            Vector3::new(0.4, 0.1, -0.9),
            Vector3::new(-0.4, 0.3, -0.9),
            Vector3::z(),
            -Vector3::z(),
            Vector3::y(),
            -Vector3::y(),
        ]
        .into_iter()
        // And a sphere of directions, 15° apart.
        .chain((0..24).flat_map(|i| {
            (1..12).map(move |j| {
                let (a, b) = (
                    f64::from(i) * 15f64.to_radians(),
                    f64::from(j) * 15f64.to_radians(),
                );
                Vector3::new(b.sin() * a.cos(), b.sin() * a.sin(), b.cos())
            })
        })) {
            let dir = Unit::new_normalize(d);
            let (pitch, roll) = pitch_roll_toward(&dir);
            let expected = from_pitch_roll(pitch, roll);
            let q = toward(&dir);
            // The tool axis always points along the direction.
            assert_abs_diff_eq!(q * Vector3::z(), dir.into_inner(), epsilon = 1e-12);
            if d.y.abs() > (1.0 - 1e-12) * d.norm() {
                // Along ±Y every pitch points the axis the same way (gimbal lock); pitch 0 is chosen.
                continue;
            }
            // q and −q are one rotation; at pitch ±180° the two formulas may pick either sign.
            let gap = (q.coords - expected.coords)
                .norm()
                .min((q.coords + expected.coords).norm());
            assert!(gap < 1e-12, "{d:?}: {q:?} vs {expected:?}");
            assert_abs_diff_eq!(q.norm(), 1.0, epsilon = 1e-14);
            let (p2, r2) = pitch_roll(&q);
            let pitch_gap = (p2 - pitch).rem_euclid(std::f64::consts::TAU);
            assert!(
                pitch_gap.min(std::f64::consts::TAU - pitch_gap) < 1e-9,
                "{d:?}: pitch {p2} vs {pitch}"
            );
            assert_abs_diff_eq!(r2, roll, epsilon = 1e-9);
        }
    }

    #[test]
    fn continuity_removes_sign_flips() {
        let prev = from_pitch_roll(0.1, 0.2);
        let flipped = UnitQuaternion::new_unchecked(-from_pitch_roll(0.12, 0.2).into_inner());
        let q = continuous(flipped, &prev);
        assert!(q.coords.dot(&prev.coords) > 0.0);
        assert_abs_diff_eq!(q.angle_to(&flipped), 0.0, epsilon = 1e-12);
    }
}
