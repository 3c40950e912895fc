//! The robot's working range (seed 001 §4.1.1: ASEA IRB 6/2, five revolute axes, wrist pitch and
//! roll, 2300 mm/s arm extended, 630 mm/s retracted).
//!
//! The envelope is a cylindrical shell about the pedestal axis. The defaults describe an
//! IRB 6/2-class arm approximately; a cell file sets the real robot's figures.

use nalgebra::Point3;

use crate::Error;

/// Working range of the payout eye and of the wrist that carries it, in the cell frame (origin on
/// the pedestal axis at the base, `z` up).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Robot {
    /// Least horizontal distance from the pedestal axis.
    pub reach_min_mm: f64,
    /// Greatest horizontal distance from the pedestal axis.
    pub reach_max_mm: f64,
    /// Lowest height.
    pub z_min_mm: f64,
    /// Highest height.
    pub z_max_mm: f64,
    /// Fastest tool speed (arm extended).
    pub max_speed_mm_s: f64,
}

impl Default for Robot {
    fn default() -> Self {
        Robot {
            reach_min_mm: 250.0,
            reach_max_mm: 1200.0,
            z_min_mm: -300.0,
            z_max_mm: 1300.0,
            max_speed_mm_s: 2300.0,
        }
    }
}

impl Robot {
    /// Checks that a point lies in the working range; `segment` is for the error.
    pub fn check(&self, p: &Point3<f64>, segment: usize) -> Result<(), Error> {
        // Squared radii: no square root on the planner's hot path.
        let horizontal_sq = p.x * p.x + p.y * p.y;
        let limit = if horizontal_sq < self.reach_min_mm * self.reach_min_mm
            || horizontal_sq > self.reach_max_mm * self.reach_max_mm
        {
            "horizontal reach"
        } else if p.z < self.z_min_mm || p.z > self.z_max_mm {
            "height range"
        } else {
            return Ok(());
        };
        Err(Error::OutOfReach {
            segment,
            x_mm: p.x,
            y_mm: p.y,
            z_mm: p.z,
            limit,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn accepts_inside_and_names_the_limit_outside() {
        let robot = Robot::default();
        assert!(robot.check(&Point3::new(700.0, 30.0, 400.0), 3).is_ok());
        let err = robot
            .check(&Point3::new(1500.0, 0.0, 400.0), 3)
            .unwrap_err();
        assert!(matches!(
            err,
            Error::OutOfReach {
                limit: "horizontal reach",
                segment: 3,
                ..
            }
        ));
        let err = robot
            .check(&Point3::new(700.0, 0.0, 2000.0), 0)
            .unwrap_err();
        assert!(matches!(
            err,
            Error::OutOfReach {
                limit: "height range",
                ..
            }
        ));
    }
}
