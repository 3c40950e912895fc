//! The stepper motor's torque against speed, and the load it turns (seed 001 §4.1.6, §5.3.2).
//!
//! A stepper follows its pulses only while the torque the load asks for stays below the
//! motor's **pull-out torque** at the present step rate; above it the rotor falls out of step,
//! the motor stalls, and the translator's later pulses are lost (the indexer still counts them).
//! The load asks for `J·α + T_friction` while it accelerates at `α` (rad/s² at the motor), and
//! `T_friction` while it cruises; braking asks for `J·α − T_friction`, less than the same ramp
//! up, so the ramp up decides.
//!
//! **The torque curve.** Seed 001 §4.1.6 gives the SLO-SYN M112 FD25's torque, 840 oz-in
//! (5.93 N·m), and its half-step mode (400 steps/rev); it gives no curve against speed, no rotor
//! inertia and no mandrel mass. The rest is ours, stated as an assumption:
//!
//! - the pull-out torque is flat at the seed's 5.93 N·m up to a corner rate of
//!   [`CORNER_SPS`] (1000 half-steps/s, 150 rpm), and falls as `corner/rate` above it (constant
//!   power, the shape an L/R-limited winding gives once the current can no longer rise within a
//!   step). At the translator's 10 000 pulses/s that leaves 0.59 N·m, a tenth of the holding
//!   torque, which is what catalogue curves of 3–4 inch frame steppers on a constant-current
//!   translator show at 1500 rpm;
//! - the rotor's inertia [`ROTOR_INERTIA_KG_M2`], 1.5 × 10⁻³ kg·m², is of the order catalogues
//!   give for NEMA 42 frames (1–3 × 10⁻³);
//! - the mandrel [`MANDREL_INERTIA_KG_M2`], 0.05 kg·m² at the mandrel, is a 230 mm diameter,
//!   550 mm long aluminium tube with a 3 mm wall (3.2 kg, `m r²` = 0.042 kg·m²) with its shaft,
//!   chuck and pulley (§4.1.4, Table 6.1's largest mandrel); through the 13:60 belt it is
//!   0.05 / (60/13)² = 2.35 × 10⁻³ kg·m² at the motor;
//! - the friction [`FRICTION_NM`], 0.3 N·m at the motor: bearings and belt, and about 10 N of
//!   fibre tension at the mandrel's 115 mm radius (1.15 N·m, 0.25 N·m at the motor).
//!
//! With these figures the thesis's profiles (1–4 mandrel rev/s², up to 2 rev/s) keep a margin
//! of more than two, and the pull-out limit is reached only by ramps several times steeper, or
//! by speeds near the translator's limit: a steady 10 000 pulses/s needs only the friction, and
//! the motor has 0.59 N·m there.

use std::f64::consts::TAU;

/// SLO-SYN M112 FD25 torque, N·m: "840 oz-in" (seed 001 §4.1.6), 840 × 7.0616 × 10⁻³.
pub const HOLDING_TORQUE_NM: f64 = 840.0 * 7.061_552e-3;

/// Step rate (half-steps/s) up to which the pull-out torque is the holding torque. Ours (the
/// seed gives no curve): 1000 half-steps/s, 2.5 rev/s, 150 rpm.
pub const CORNER_SPS: f64 = 1_000.0;

/// Rotor inertia, kg·m². Ours (the seed gives none): the order of NEMA 42 rotors.
pub const ROTOR_INERTIA_KG_M2: f64 = 1.5e-3;

/// Inertia of the mandrel with its shaft and pulley, at the mandrel, kg·m². Ours: a 230 × 550 mm
/// aluminium tube, 3 mm wall (seed 001 §4.1.4 gives the size, not the mass).
pub const MANDREL_INERTIA_KG_M2: f64 = 0.05;

/// Friction and fibre tension at the motor shaft, N·m. Ours: see the module documentation.
pub const FRICTION_NM: f64 = 0.3;

/// The motor and its load, as the simulator's pull-out check sees them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Motor {
    /// Pull-out torque at low rates, N·m.
    pub holding_nm: f64,
    /// Rate (steps/s) above which the pull-out torque falls as `corner / rate`.
    pub corner_sps: f64,
    /// Rotor plus load inertia reflected to the motor shaft, kg·m².
    pub inertia_kg_m2: f64,
    /// Friction torque at the motor shaft, N·m.
    pub friction_nm: f64,
    /// Motor steps per revolution (400 in half-step mode).
    pub steps_per_rev: f64,
}

impl Motor {
    /// The thesis's motor and mandrel: seed figures and the assumptions above, the mandrel's
    /// inertia reflected through a belt of `motor_revs_per_mandrel_rev` (60/13).
    pub fn thesis(steps_per_rev: f64, motor_revs_per_mandrel_rev: f64) -> Self {
        Motor {
            holding_nm: HOLDING_TORQUE_NM,
            corner_sps: CORNER_SPS,
            inertia_kg_m2: ROTOR_INERTIA_KG_M2
                + MANDREL_INERTIA_KG_M2 / (motor_revs_per_mandrel_rev * motor_revs_per_mandrel_rev),
            friction_nm: FRICTION_NM,
            steps_per_rev,
        }
    }

    /// Pull-out torque at `rate_sps` (N·m): flat to the corner, then `corner / rate`.
    pub fn pull_out_nm(&self, rate_sps: f64) -> f64 {
        let r = rate_sps.abs();
        if r <= self.corner_sps {
            self.holding_nm
        } else {
            self.holding_nm * self.corner_sps / r
        }
    }

    /// Torque the load asks for while accelerating at `accel_sps2` (steps/s²), N·m.
    pub fn demand_nm(&self, accel_sps2: f64) -> f64 {
        self.inertia_kg_m2 * accel_sps2.abs() * TAU / self.steps_per_rev + self.friction_nm
    }

    /// Highest step rate the motor keeps while accelerating at `accel_sps2` (steps/s): where the
    /// pull-out curve meets the demand. Infinite when the demand is below the curve everywhere
    /// (never, since the curve falls to zero), zero when even the holding torque is short.
    pub fn pull_out_sps(&self, accel_sps2: f64) -> f64 {
        let need = self.demand_nm(accel_sps2);
        if need > self.holding_nm {
            0.0
        } else {
            self.corner_sps * self.holding_nm / need
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn thesis() -> Motor {
        Motor::thesis(400.0, 60.0 / 13.0)
    }

    #[test]
    fn holding_torque_is_840_oz_in() {
        // 1 oz-in = 0.00706155 N·m.
        assert!((HOLDING_TORQUE_NM - 5.9317).abs() < 1e-3);
        let m = thesis();
        assert_eq!(m.pull_out_nm(0.0), HOLDING_TORQUE_NM);
        assert_eq!(m.pull_out_nm(CORNER_SPS), HOLDING_TORQUE_NM);
        assert!((m.pull_out_nm(10_000.0) - HOLDING_TORQUE_NM / 10.0).abs() < 1e-12);
        assert!((m.pull_out_nm(-2_000.0) - HOLDING_TORQUE_NM / 2.0).abs() < 1e-12);
    }

    #[test]
    fn demand_is_inertia_times_acceleration_plus_friction() {
        let m = thesis();
        // 0.0015 + 0.05 / (60/13)² = 0.0038472 kg·m².
        assert!(
            (m.inertia_kg_m2 - 0.003_847_2).abs() < 1e-6,
            "{}",
            m.inertia_kg_m2
        );
        assert_eq!(m.demand_nm(0.0), FRICTION_NM);
        // 400 steps/s² is one rev/s², 2π rad/s².
        let want = m.inertia_kg_m2 * TAU + FRICTION_NM;
        assert!((m.demand_nm(400.0) - want).abs() < 1e-12);
        assert!((m.demand_nm(-400.0) - want).abs() < 1e-12);
    }

    #[test]
    fn pull_out_rate_is_where_curve_meets_demand() {
        let m = thesis();
        for a in [0.0, 1_000.0, 20_000.0, 60_000.0] {
            let f = m.pull_out_sps(a);
            assert!((m.pull_out_nm(f) - m.demand_nm(a)).abs() < 1e-9, "{a}: {f}");
        }
        // Friction alone: 5.93 × 1000 / 0.3 ≈ 19 772 steps/s, beyond the translator.
        assert!(m.pull_out_sps(0.0) > 10_000.0);
        // More than the holding torque: not even a start.
        assert_eq!(m.pull_out_sps(1.0e7), 0.0);
    }
}
