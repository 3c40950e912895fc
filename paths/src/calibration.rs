//! The cell as measured (seed 001 §6.2.1 item 2: "the orientation of the rotational centre of the
//! mandrel drive with respect to the axis of link 1 is important … assumed to be aligned"; the
//! thesis measured 0.1 mm in the x–z plane and 0.15 mm in the y–z plane along a 178 mm mandrel).
//!
//! The nominal cell has the rotation axis vertical through `(b, 0)`. A calibration moves it to the
//! measured position and tilt, and says where the drive's zero angle lies and which way a positive
//! step turns the mandrel. `docs/geometry.md` describes how an operator measures each figure.

use nalgebra::{Matrix3, Point3, Rotation3, Unit, Vector3};

use crate::Error;

/// Measured corrections to the nominal cell.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Calibration {
    /// Where the rotation axis crosses the mandrel frame's origin height, relative to the nominal
    /// `(b, 0)`, cell frame `[x, y]`, mm.
    pub axis_offset_mm: [f64; 2],
    /// The rotation axis's lean from the vertical: toward `+x` (in the x–z plane) and toward `+y`
    /// (in the y–z plane), rad. The axis direction is `(tan t_x, tan t_y, 1)` normalised.
    pub axis_tilt_rad: [f64; 2],
    /// The mandrel angle (counter-clockwise from above, mandrel frame `x` against the drive frame)
    /// at which the indexer's position reads zero, rad.
    pub zero_angle_rad: f64,
    /// `+1` when a positive step count turns the mandrel counter-clockwise seen from above, `−1`
    /// when clockwise.
    pub rotation_sign: i8,
}

impl Default for Calibration {
    /// The nominal cell: axis vertical through `(b, 0)`, zero at 0, positive steps counter-clockwise.
    fn default() -> Self {
        Calibration {
            axis_offset_mm: [0.0, 0.0],
            axis_tilt_rad: [0.0, 0.0],
            zero_angle_rad: 0.0,
            rotation_sign: 1,
        }
    }
}

/// The calibrated transform from the drive frame to the cell frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CellTransform {
    /// The robot distance the tangent angle (eq 3.7) sees: pedestal axis to rotation axis,
    /// horizontally, mm.
    pub robot_distance_mm: f64,
    /// Drive frame to cell frame: `p_cell = origin + rotation · p_drive`.
    pub rotation: Matrix3<f64>,
    /// The drive frame's origin in the cell frame.
    pub origin: Vector3<f64>,
}

impl Calibration {
    /// Checks that every figure is finite, the tilt below 10° and the sign ±1.
    pub fn validate(&self) -> Result<(), Error> {
        for (name, value) in [
            ("axis_offset_mm", self.axis_offset_mm[0]),
            ("axis_offset_mm", self.axis_offset_mm[1]),
            ("zero_angle_deg", self.zero_angle_rad.to_degrees()),
        ] {
            if !value.is_finite() {
                return Err(Error::OutOfRange {
                    name,
                    value,
                    expected: "must be finite",
                });
            }
        }
        for t in self.axis_tilt_rad {
            if t.abs() >= 10f64.to_radians() || t.is_nan() {
                return Err(Error::OutOfRange {
                    name: "axis_tilt_deg",
                    value: t.to_degrees(),
                    expected: "must lie within ±10° (a measured misalignment)",
                });
            }
        }
        if self.rotation_sign != 1 && self.rotation_sign != -1 {
            return Err(Error::OutOfRange {
                name: "rotation_sign",
                value: f64::from(self.rotation_sign),
                expected: "must be 1 or -1",
            });
        }
        Ok(())
    }

    /// The transform for a cell with the robot `robot_distance_mm` from the nominal axis and the
    /// mandrel frame's origin `mandrel_height_mm` above the base. The drive frame's `x` axis points
    /// horizontally from the pedestal axis through the measured rotation axis (so eq 3.7 holds
    /// with the measured distance), its `z` axis along the tilted rotation axis.
    pub fn transform(&self, robot_distance_mm: f64, mandrel_height_mm: f64) -> CellTransform {
        let x = robot_distance_mm + self.axis_offset_mm[0];
        let y = self.axis_offset_mm[1];
        let heading = Rotation3::from_axis_angle(&Vector3::z_axis(), y.atan2(x));
        let axis = Unit::new_normalize(Vector3::new(
            self.axis_tilt_rad[0].tan(),
            self.axis_tilt_rad[1].tan(),
            1.0,
        ));
        let tilt = Rotation3::rotation_between(&Vector3::z(), &axis).unwrap_or_default();
        CellTransform {
            robot_distance_mm: x.hypot(y),
            rotation: (tilt * heading).into_inner(),
            origin: Vector3::new(x, y, mandrel_height_mm),
        }
    }

    /// The indexer position (signed, in its own sense of rotation) for the physical mandrel angle
    /// `mandrel_rad`, rad.
    pub fn drive_angle_rad(&self, mandrel_rad: f64) -> f64 {
        f64::from(self.rotation_sign) * (mandrel_rad - self.zero_angle_rad)
    }
}

impl CellTransform {
    /// A drive-frame point in the cell frame.
    pub fn to_cell(&self, p: &Point3<f64>) -> Point3<f64> {
        Point3::from(self.origin + self.rotation * p.coords)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;

    #[test]
    fn nominal_cell_is_a_translation_to_b_0_h() {
        let t = Calibration::default().transform(800.0, 300.0);
        assert_eq!(t.robot_distance_mm, 800.0);
        assert_abs_diff_eq!(
            t.to_cell(&Point3::new(1.0, 2.0, 3.0)),
            Point3::new(801.0, 2.0, 303.0),
            epsilon = 1e-12
        );
    }

    #[test]
    fn measured_axis_is_where_the_drive_frame_sits() {
        // The thesis's 0.1 mm (x–z) and 0.15 mm (y–z) over 178 mm, and a 2 mm offset in y.
        let c = Calibration {
            axis_offset_mm: [-1.0, 2.0],
            axis_tilt_rad: [(0.1f64 / 178.0).atan(), (0.15f64 / 178.0).atan()],
            ..Calibration::default()
        };
        let t = c.transform(800.0, 300.0);
        assert_abs_diff_eq!(t.robot_distance_mm, 799.0f64.hypot(2.0), epsilon = 1e-12);
        // The drive frame's origin is the measured axis point; 178 mm up the axis it has moved
        // 0.1 mm in x and 0.15 mm in y.
        let top = t.to_cell(&Point3::new(0.0, 0.0, 178.0));
        let bottom = t.to_cell(&Point3::origin());
        assert_abs_diff_eq!(bottom, Point3::new(799.0, 2.0, 300.0), epsilon = 1e-12);
        let lean = top - bottom;
        assert_abs_diff_eq!(lean.x / lean.z * 178.0, 0.1, epsilon = 1e-9);
        assert_abs_diff_eq!(lean.y / lean.z * 178.0, 0.15, epsilon = 1e-9);
        // The drive frame's −x points back at the pedestal axis (horizontally).
        let toward_pedestal = t.rotation * -Vector3::x();
        let expected = -Vector3::new(799.0, 2.0, 0.0).normalize();
        assert_abs_diff_eq!(toward_pedestal.xy(), expected.xy(), epsilon = 1e-6);
    }

    #[test]
    fn drive_angle_follows_zero_and_sign() {
        let c = Calibration {
            zero_angle_rad: 0.5,
            rotation_sign: -1,
            ..Calibration::default()
        };
        assert_abs_diff_eq!(c.drive_angle_rad(0.7), -0.2, epsilon = 1e-15);
        assert!(c.validate().is_ok());
        let bad = Calibration {
            rotation_sign: 0,
            ..Calibration::default()
        };
        assert!(bad.validate().is_err());
    }
}
