//! Where the mandrel turns, in the robot base frame (`[cell.mandrel]`), and who turns it.
//!
//! The **mandrel frame** has its origin on the rotation axis at the mandrel's start (spine
//! distance 0) and its `z` axis along the rotation axis. At mandrel angle 0 its `x` axis is
//! [`MandrelAxis::zero_direction`]; a positive angle turns it counter-clockwise seen from the
//! axis's tip (right-handed about the axis). The thesis cell (seed 001 §5.6 c–d) is the default:
//! axis vertical through `(b, 0)` at the start height, `x` along the base's `x`, which is the
//! nominal cell of [`crate::calibration`].

use nalgebra::{
    Isometry3, Matrix3, Point3, Rotation3, Translation3, Unit, UnitQuaternion, Vector3,
};

use crate::Error;

/// Who turns the mandrel.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MandrelDrive {
    /// windcell's indexer turns it (decoupled, as in the thesis cell).
    Indexer,
    /// The robot controller turns it as an external axis (coupled: the plan carries the axis
    /// angle per pose).
    Robot,
}

/// The mandrel's rotation axis in the robot base frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MandrelAxis {
    /// A point of the axis: the mandrel frame's origin (spine distance 0), base frame, mm.
    pub origin_mm: Point3<f64>,
    /// The axis direction (the mandrel frame's `z`), base frame.
    pub direction: Unit<Vector3<f64>>,
    /// The mandrel frame's `x` at angle 0, perpendicular to `direction`.
    pub zero_direction: Unit<Vector3<f64>>,
    /// Who turns it.
    pub drive: MandrelDrive,
}

impl MandrelAxis {
    /// The thesis cell: axis vertical through `(robot_distance_mm, 0, start_height_mm)`, the
    /// indexer turning it.
    pub fn thesis(robot_distance_mm: f64, start_height_mm: f64) -> Self {
        MandrelAxis {
            origin_mm: Point3::new(robot_distance_mm, 0.0, start_height_mm),
            direction: Vector3::z_axis(),
            zero_direction: Vector3::x_axis(),
            drive: MandrelDrive::Indexer,
        }
    }

    /// An axis through `origin_mm` along `direction` (any length); its zero direction is the
    /// base's `x` made perpendicular to the axis, or the base's `z` when the axis lies along `x`.
    /// Refuses a non-finite figure or a zero direction.
    pub fn new(
        origin_mm: [f64; 3],
        direction: [f64; 3],
        drive: MandrelDrive,
    ) -> Result<Self, Error> {
        for v in origin_mm {
            if !(v.is_finite() && v.abs() <= 100_000.0) {
                return Err(Error::OutOfRange {
                    name: "axis_origin_mm",
                    value: v,
                    expected: "must be finite and within ±100 000 mm",
                });
            }
        }
        let d = Vector3::from(direction);
        let n = d.norm();
        if !(n.is_finite() && n > 1e-9) {
            return Err(Error::OutOfRange {
                name: "axis_direction",
                value: n,
                expected: "must be a finite, non-zero vector",
            });
        }
        let direction = Unit::new_normalize(d);
        let reference = if direction.x.abs() > 0.999_999 {
            Vector3::z()
        } else {
            Vector3::x()
        };
        let zero = Unit::new_normalize(reference - direction.as_ref() * direction.dot(&reference));
        Ok(MandrelAxis {
            origin_mm: Point3::from(origin_mm),
            direction,
            zero_direction: zero,
            drive,
        })
    }

    /// The mandrel frame in the base frame at mandrel angle `angle_rad`.
    pub fn frame(&self, angle_rad: f64) -> Isometry3<f64> {
        let z = self.direction.into_inner();
        let x = self.zero_direction.into_inner();
        let y = z.cross(&x);
        let align = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[x, y, z]));
        let turn = Rotation3::from_axis_angle(&Vector3::z_axis(), angle_rad);
        Isometry3::from_parts(
            Translation3::from(self.origin_mm.coords),
            UnitQuaternion::from_rotation_matrix(&(align * turn)),
        )
    }

    /// A mandrel-frame point in the base frame at mandrel angle `angle_rad`.
    pub fn to_base(&self, angle_rad: f64, p_mandrel: &Point3<f64>) -> Point3<f64> {
        self.frame(angle_rad) * p_mandrel
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thesis_axis_is_the_nominal_cell() {
        let a = MandrelAxis::thesis(800.0, 300.0);
        let p = a.to_base(0.0, &Point3::new(10.0, 0.0, 5.0));
        assert!((p - Point3::new(810.0, 0.0, 305.0)).norm() < 1e-12);
        // A quarter turn counter-clockwise from above takes mandrel x onto base y.
        let q = a.to_base(std::f64::consts::FRAC_PI_2, &Point3::new(10.0, 0.0, 0.0));
        assert!((q - Point3::new(800.0, 10.0, 300.0)).norm() < 1e-12);
    }

    #[test]
    fn horizontal_axis_turns_about_itself() {
        let a =
            MandrelAxis::new([1000.0, 0.0, 800.0], [0.0, 2.0, 0.0], MandrelDrive::Robot).unwrap();
        assert!((a.zero_direction.into_inner() - Vector3::x()).norm() < 1e-12);
        // Points on the axis stay put at any angle; a point 50 mm off it stays 50 mm off.
        for angle in [0.0, 1.0, 2.5] {
            let on = a.to_base(angle, &Point3::new(0.0, 0.0, 120.0));
            assert!((on - Point3::new(1000.0, 120.0, 800.0)).norm() < 1e-9);
            let off = a.to_base(angle, &Point3::new(50.0, 0.0, 0.0));
            assert!(((off - a.origin_mm).norm() - 50.0).abs() < 1e-9);
            assert!((off - a.origin_mm).dot(&a.direction).abs() < 1e-9);
        }
        let along_x = MandrelAxis::new([0.0; 3], [-1.0, 0.0, 0.0], MandrelDrive::Indexer).unwrap();
        assert!((along_x.zero_direction.into_inner() - Vector3::z()).norm() < 1e-12);
        assert!(MandrelAxis::new([0.0; 3], [0.0; 3], MandrelDrive::Indexer).is_err());
        assert!(
            MandrelAxis::new([f64::NAN, 0.0, 0.0], [0.0, 0.0, 1.0], MandrelDrive::Indexer).is_err()
        );
    }
}
