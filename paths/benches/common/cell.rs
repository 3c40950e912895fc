//! The thesis cell the planning benchmarks run on (`pose`, `mesh`, `clearance`): the robot 800 mm
//! from the mandrel axis, the axis 300 mm high, the eye offset 100 mm (seed 001 §5.6, the S-bend
//! job of `examples/sbend.toml`), and its speeds.

#![allow(dead_code)]

use paths::plan::ENTRY_ANGLE_MAX_DEG;
use paths::{Arm, Calibration, Gearing, MandrelProfile, Movement, Setup, Speeds};

/// The cell with `arm`.
pub fn setup(arm: Arm) -> Setup {
    Setup {
        robot_distance_mm: 800.0,
        mandrel_height_mm: 300.0,
        offset_mm: 100.0,
        arm,
        entry_angle_max_rad: ENTRY_ANGLE_MAX_DEG.to_radians(),
        calibration: Calibration::default(),
        gearing: Gearing::default(),
        six_axis: None,
    }
}

/// The mandrel at up to 0.1 rev/s (1 rev/s², 0.05 rev/s start/stop), the robot at 1000–2000 mm/s,
/// in `movement`.
pub fn speeds(movement: Movement) -> Speeds {
    Speeds {
        mandrel: MandrelProfile {
            accel_rps2: 1.0,
            start_stop_rps: 0.05,
            max_rps: 0.1,
        },
        base_speed_mm_s: 1000.0,
        max_speed_mm_s: 2000.0,
        movement,
    }
}
