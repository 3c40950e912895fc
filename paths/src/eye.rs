//! The payout-eye position (seed 001 §3.2, eqs 3.8–3.14, Fig. 3.2).

use nalgebra::Point3;

/// The eye on the fibre's tangent, `offset_mm` beyond the tangent point `p2` along the chord from
/// the previous tangent point `p1`: `eye = P2 + offset · (P2 − P1)/|P2 − P1|`. This is eqs 3.8–3.14
/// written as one vector (the thesis resolves the same displacement into x, y, z through α and β).
/// Returns `None` when the two points coincide.
pub fn position(p1: &Point3<f64>, p2: &Point3<f64>, offset_mm: f64) -> Option<Point3<f64>> {
    let chord = p2 - p1;
    let length = chord.norm();
    (length > 1e-12).then(|| p2 + chord * (offset_mm / length))
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;

    /// Eqs 3.8–3.14 literally, for a chord with X2' > X1'.
    fn thesis(p1: &Point3<f64>, p2: &Point3<f64>, offset: f64) -> Point3<f64> {
        let alpha = ((p2.z - p1.z) / (p2.x - p1.x)).atan(); // 3.8
        let beta = ((p2.y - p1.y) / (p2.x - p1.x)).atan(); // 3.9
        let x = offset / (1.0 / beta.cos().powi(2) + alpha.tan().powi(2)).sqrt(); // 3.12
        let y = x * beta.tan(); // 3.13
        let z = x * alpha.tan(); // 3.14
        Point3::new(p2.x + x, p2.y + y, p2.z + z)
    }

    #[test]
    fn vector_form_equals_eqs_3_8_to_3_14() {
        let p1 = Point3::new(10.0, 31.0, 100.0);
        for p2 in [
            Point3::new(12.0, 30.0, 96.0),
            Point3::new(15.0, 35.0, 101.0),
        ] {
            let eye = position(&p1, &p2, 100.0).unwrap();
            assert_abs_diff_eq!(eye, thesis(&p1, &p2, 100.0), epsilon = 1e-9);
            assert_abs_diff_eq!((eye - p2).norm(), 100.0, epsilon = 1e-9);
        }
        assert!(position(&p1, &p1, 100.0).is_none());
    }
}
