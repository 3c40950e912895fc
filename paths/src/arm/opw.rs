//! Ortho-parallel 6R arms with a spherical wrist: forward and inverse kinematics in closed form
//! (M. Brandstötter, A. Angerer, M. Hofbaur, "An analytical solution of the inverse kinematics
//! problem of industrial serial manipulators with an ortho-parallel basis and a spherical
//! wrist", Austrian Robotics Workshop 2014; "the paper" below).
//!
//! # Parameters (the paper's Fig. 1; ROS-Industrial `opw_kinematics` convention)
//! With every model angle zero the arm stands upright: axis 1 is the base `z`; axis 2 runs along
//! `y` through `(a1, ·, c1)`; axis 3 along `y` at `c2` above it; the forearm's offset `a2` (along
//! `x`) and lateral offset `b` (along `y`) lead to the wrist centre `(a1 + a2, b, c1 + c2 + c3)`;
//! axes 4 and 6 are vertical through it, axis 5 along `y`; the flange is `c4` above the wrist
//! centre with the base's axes. The model angle of axis `i` is `q_i = sign_i · joint_i −
//! offset_i`, `joint_i` the controller's angle.
//!
//! # Branches
//! Two shoulder sides (the paper's θ1,i and θ1,ii), two elbow bends per side (± the arccosine
//! of the elbow triangle) and two wrist solutions (`q5` and `−q5` with `q4`, `q6` turned by π):
//! eight, as [`Config::index`] orders them.

use std::f64::consts::PI;

use nalgebra::{Matrix3, Point3, Vector3};

use super::{Config, Elbow, JointLimits6, Joints6, Pose6, Shoulder, SixAxisFault, Solutions};
use super::{Wrist, atan2, wrap};
use crate::Error;

/// The geometry of an OPW arm, mm and rad.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Opw {
    /// Axis 2's offset from axis 1, along the arm (`a1_mm`).
    pub a1_mm: f64,
    /// The forearm's offset from axis 3, across the forearm (`a2_mm`; negative for most arms).
    pub a2_mm: f64,
    /// The lateral offset of the wrist centre from the arm plane (`b_mm`).
    pub b_mm: f64,
    /// Height of axis 2 above the base (`c1_mm`).
    pub c1_mm: f64,
    /// Axis 2 to axis 3, the upper arm (`c2_mm`).
    pub c2_mm: f64,
    /// Axis 3 to the wrist centre along the forearm (`c3_mm`).
    pub c3_mm: f64,
    /// Wrist centre to the flange (`c4_mm`).
    pub c4_mm: f64,
    /// Model angle offsets, rad (`offsets_deg`).
    pub offsets_rad: [f64; 6],
    /// Sign corrections, each +1 or −1 (`signs`).
    pub signs: [i8; 6],
}

/// A built-in arm: its OPW geometry, joint ranges and speeds, and where they come from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OpwPreset {
    /// The name `[cell.robot] model` takes.
    pub model: &'static str,
    /// The arm as its maker names it.
    pub title: &'static str,
    /// The geometry.
    pub opw: Opw,
    /// Least joint angles, degrees.
    pub joint_min_deg: [f64; 6],
    /// Greatest joint angles, degrees.
    pub joint_max_deg: [f64; 6],
    /// Fastest joint speeds, degrees/s.
    pub joint_speed_deg_s: [f64; 6],
}

impl OpwPreset {
    /// The joint limits in radians.
    pub fn limits(&self) -> JointLimits6 {
        JointLimits6::degrees(
            self.joint_min_deg,
            self.joint_max_deg,
            Some(self.joint_speed_deg_s),
        )
    }
}

const fn deg(d: f64) -> f64 {
    d * (PI / 180.0)
}

/// The built-in OPW arms (sources in `docs/arms.md`): geometry from ROS-Industrial's published
/// `opw_parameters_*.yaml` files (in mm here), ranges and speeds from the makers' data sheets
/// (FANUC: ROS-Industrial's URDF, whose axis 3 is the controller's J3 + J2).
pub const OPW_PRESETS: [OpwPreset; 4] = [
    OpwPreset {
        model: "irb2600-12/1.65",
        title: "ABB IRB 2600-12/1.65",
        opw: Opw {
            a1_mm: 150.0,
            a2_mm: -115.0,
            b_mm: 0.0,
            c1_mm: 445.0,
            c2_mm: 700.0,
            c3_mm: 795.0,
            c4_mm: 85.0,
            offsets_rad: [0.0, 0.0, deg(-90.0), 0.0, 0.0, 0.0],
            signs: [1, 1, 1, 1, 1, 1],
        },
        joint_min_deg: [-180.0, -95.0, -180.0, -400.0, -120.0, -400.0],
        joint_max_deg: [180.0, 155.0, 75.0, 400.0, 120.0, 400.0],
        joint_speed_deg_s: [175.0, 175.0, 175.0, 360.0, 360.0, 510.0],
    },
    OpwPreset {
        model: "irb4600-60/2.05",
        title: "ABB IRB 4600-60/2.05",
        opw: Opw {
            a1_mm: 175.0,
            a2_mm: -175.0,
            b_mm: 0.0,
            c1_mm: 495.0,
            c2_mm: 900.0,
            c3_mm: 960.0,
            c4_mm: 135.0,
            offsets_rad: [0.0, 0.0, deg(-90.0), 0.0, 0.0, 0.0],
            signs: [1, 1, 1, 1, 1, 1],
        },
        joint_min_deg: [-180.0, -90.0, -180.0, -400.0, -125.0, -400.0],
        joint_max_deg: [180.0, 150.0, 75.0, 400.0, 120.0, 400.0],
        joint_speed_deg_s: [175.0, 175.0, 175.0, 250.0, 250.0, 360.0],
    },
    OpwPreset {
        model: "kr16-2",
        title: "KUKA KR 16-2",
        opw: Opw {
            a1_mm: 260.0,
            a2_mm: 35.0,
            b_mm: 0.0,
            c1_mm: 675.0,
            c2_mm: 680.0,
            c3_mm: 670.0,
            c4_mm: 158.0,
            offsets_rad: [0.0, deg(-90.0), 0.0, 0.0, 0.0, 0.0],
            signs: [-1, 1, 1, -1, 1, -1],
        },
        joint_min_deg: [-185.0, -155.0, -130.0, -350.0, -130.0, -350.0],
        joint_max_deg: [185.0, 35.0, 154.0, 350.0, 130.0, 350.0],
        joint_speed_deg_s: [156.0, 156.0, 156.0, 330.0, 330.0, 615.0],
    },
    OpwPreset {
        model: "m-20ia",
        title: "FANUC M-20iA",
        opw: Opw {
            a1_mm: 150.0,
            a2_mm: -250.0,
            b_mm: 0.0,
            c1_mm: 525.0,
            c2_mm: 790.0,
            c3_mm: 835.0,
            c4_mm: 100.0,
            offsets_rad: [0.0, 0.0, deg(-90.0), 0.0, 0.0, deg(180.0)],
            signs: [1, 1, -1, -1, -1, -1],
        },
        joint_min_deg: [-170.0, -100.0, -185.0, -200.0, -140.0, -270.0],
        joint_max_deg: [170.0, 160.0, 273.0, 200.0, 140.0, 270.0],
        joint_speed_deg_s: [195.0, 175.0, 180.0, 360.0, 360.0, 550.0],
    },
];

/// The built-in arm of that model name (case-insensitive), or `None`.
pub fn preset(model: &str) -> Option<&'static OpwPreset> {
    super::presets::find(&OPW_PRESETS, |p| p.model, model)
}

/// The built-in arm of that model name, or [`Error::UnknownArmModel`] listing the known ones.
pub fn named(model: &str) -> Result<&'static OpwPreset, Error> {
    super::presets::named(&OPW_PRESETS, |p| p.model, "opw", model)
}

/// The built-in model names, for messages.
pub fn preset_names() -> String {
    super::presets::names(&OPW_PRESETS, |p| p.model)
}

/// The rotation `Rz(a)`.
fn rot_z(s: f64, c: f64) -> Matrix3<f64> {
    Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)
}

/// The rotation `Ry(a)`.
fn rot_y(s: f64, c: f64) -> Matrix3<f64> {
    Matrix3::new(c, 0.0, s, 0.0, 1.0, 0.0, -s, 0.0, c)
}

impl Opw {
    /// Checks that every length and offset is finite, the upper arm and forearm have length,
    /// the lengths lie within 100 m and every sign is ±1.
    pub fn validate(&self) -> Result<(), Error> {
        for (name, v) in [
            ("a1_mm", self.a1_mm),
            ("a2_mm", self.a2_mm),
            ("b_mm", self.b_mm),
            ("c1_mm", self.c1_mm),
            ("c2_mm", self.c2_mm),
            ("c3_mm", self.c3_mm),
            ("c4_mm", self.c4_mm),
        ] {
            if !(v.is_finite() && v.abs() <= 100_000.0) {
                return Err(Error::OutOfRange {
                    name,
                    value: v,
                    expected: "must be finite and within ±100 000 mm",
                });
            }
        }
        if self.c2_mm.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            return Err(Error::OutOfRange {
                name: "c2_mm",
                value: self.c2_mm,
                expected: "must be > 0 (the upper arm)",
            });
        }
        if self.a2_mm.hypot(self.c3_mm) <= 0.0 {
            return Err(Error::OutOfRange {
                name: "c3_mm",
                value: self.c3_mm,
                expected: "a2_mm and c3_mm must not both be 0 (the forearm)",
            });
        }
        for o in self.offsets_rad {
            if !(o.is_finite() && o.abs() <= 2.0 * std::f64::consts::TAU) {
                return Err(Error::OutOfRange {
                    name: "offsets_deg",
                    value: o.to_degrees(),
                    expected: "must be finite and within ±720°",
                });
            }
        }
        for s in self.signs {
            if s != 1 && s != -1 {
                return Err(Error::OutOfRange {
                    name: "signs",
                    value: f64::from(s),
                    expected: "must be 1 or -1",
                });
            }
        }
        Ok(())
    }

    /// The model angle of axis `i` (0-based): `sign · joint − offset`.
    pub fn model_angle(&self, q: &Joints6, i: usize) -> f64 {
        f64::from(self.signs[i]) * q[i] - self.offsets_rad[i]
    }

    fn model(&self, q: &Joints6) -> Joints6 {
        std::array::from_fn(|i| self.model_angle(q, i))
    }

    /// The controller's angle from a model angle, wrapped into (−π, π].
    fn joint(&self, model: f64, i: usize) -> f64 {
        wrap((model + self.offsets_rad[i]) * f64::from(self.signs[i]))
    }

    /// `k = √(a2² + c3²)` and `ψ3 = atan2(a2, c3)`: the forearm as one link from axis 3 to the
    /// wrist centre.
    fn forearm(&self) -> (f64, f64) {
        (self.a2_mm.hypot(self.c3_mm), self.a2_mm.atan2(self.c3_mm))
    }

    /// The flange in the base frame (the paper's forward kinematics): wrist centre
    /// `c = Rz(q1)·(a1 + c2 sin q2 + k sin(q2 + q3 + ψ3), b, c2 cos q2 + k cos(q2 + q3 + ψ3)) +
    /// (0, 0, c1)`, orientation `Rz(q1)·Ry(q2 + q3)·Rz(q4)·Ry(q5)·Rz(q6)`, flange `c + c4·z`.
    pub fn forward(&self, q: &Joints6) -> Pose6 {
        let m = self.model(q);
        let (k, psi3) = self.forearm();
        let (s1, c1) = m[0].sin_cos();
        let (s2, c2) = m[1].sin_cos();
        let q23 = m[1] + m[2];
        let (sk, ck) = (q23 + psi3).sin_cos();
        let cx1 = self.a1_mm + self.c2_mm * s2 + k * sk;
        let cz1 = self.c2_mm * c2 + k * ck;
        let wrist = Vector3::new(
            cx1 * c1 - self.b_mm * s1,
            cx1 * s1 + self.b_mm * c1,
            cz1 + self.c1_mm,
        );
        let (s23, c23) = q23.sin_cos();
        let (s4, c4) = m[3].sin_cos();
        let (s5, c5) = m[4].sin_cos();
        let (s6, c6) = m[5].sin_cos();
        let r = rot_z(s1, c1) * rot_y(s23, c23) * rot_z(s4, c4) * rot_y(s5, c5) * rot_z(s6, c6);
        Pose6 {
            translation_mm: wrist + r.column(2) * self.c4_mm,
            rotation: r,
        }
    }

    /// The joint origins the link capsules join: base, top of axis 1's column (`c1`), shoulder
    /// (axis 2), elbow (axis 3), the forearm's start past the offsets `a2`, `b`, the wrist centre
    /// and the flange.
    pub fn link_points(&self, q: &Joints6) -> [Point3<f64>; 7] {
        let m = self.model(q);
        let (s1, c1) = m[0].sin_cos();
        let (s2, c2) = m[1].sin_cos();
        let (s23, c23) = (m[1] + m[2]).sin_cos();
        let yaw = rot_z(s1, c1);
        let column = Vector3::new(0.0, 0.0, self.c1_mm);
        let shoulder = column + yaw * Vector3::new(self.a1_mm, 0.0, 0.0);
        let elbow = shoulder + yaw * Vector3::new(self.c2_mm * s2, 0.0, self.c2_mm * c2);
        let fore = yaw * rot_y(s23, c23);
        let start = elbow + fore * Vector3::new(self.a2_mm, self.b_mm, 0.0);
        let wrist = start + fore * Vector3::new(0.0, 0.0, self.c3_mm);
        let flange = self.forward(q).translation_mm;
        [
            Point3::origin(),
            Point3::from(column),
            Point3::from(shoulder),
            Point3::from(elbow),
            Point3::from(start),
            Point3::from(wrist),
            Point3::from(flange),
        ]
    }

    /// The configuration the joints are in: the side of axis 1 the wrist centre lies on in the
    /// arm's own frame, the sign of the elbow bend `sin(q3 + ψ3)`, the sign of `sin q5`.
    pub fn config_of(&self, q: &Joints6) -> Config {
        let m = self.model(q);
        let (k, psi3) = self.forearm();
        let cx1 = self.a1_mm + self.c2_mm * m[1].sin() + k * (m[1] + m[2] + psi3).sin();
        Config {
            shoulder: if cx1 >= 0.0 {
                Shoulder::Front
            } else {
                Shoulder::Back
            },
            elbow: if (m[2] + psi3).sin() >= 0.0 {
                Elbow::Up
            } else {
                Elbow::Down
            },
            wrist: if m[4].sin() >= 0.0 {
                Wrist::NoFlip
            } else {
                Wrist::Flip
            },
        }
    }

    /// All eight branches (the paper's Eqs. for θ1–θ6, with the wrist angles from the
    /// `z–y–z` decomposition of `Ry(q2 + q3)ᵀ·Rz(q1)ᵀ·R`).
    pub fn inverse(&self, flange: &Pose6) -> Solutions {
        let mut s = Solutions {
            joints: [[0.0; 6]; 8],
            valid: [false; 8],
        };
        for c in [0, 2, 4, 6] {
            let config = super::Config::from_index(c);
            if let Ok(m) = self.model_solution(flange, config) {
                s.joints[c] = self.joints(&m);
                s.joints[c + 1] = self.joints(&flipped(&m));
                s.valid[c] = true;
                s.valid[c + 1] = true;
            }
        }
        s
    }

    /// One branch.
    pub fn inverse_branch(&self, flange: &Pose6, config: Config) -> Result<Joints6, SixAxisFault> {
        let m = self.model_solution(flange, config)?;
        Ok(match config.wrist {
            Wrist::NoFlip => self.joints(&m),
            Wrist::Flip => self.joints(&flipped(&m)),
        })
    }

    /// The controller's angles from model angles, each wrapped into (−π, π].
    fn joints(&self, m: &Joints6) -> Joints6 {
        std::array::from_fn(|i| self.joint(m[i], i))
    }

    /// The model angles of the configuration's shoulder and elbow with the wrist's no-flip
    /// solution (`q5 ∈ [0, π]`). Sines and cosines are carried as unit complex numbers (sums of
    /// angles as products), so that each angle costs one arctangent.
    fn model_solution(&self, flange: &Pose6, config: Config) -> Result<Joints6, SixAxisFault> {
        let r = &flange.rotation;
        let z = r.column(2);
        let c = flange.translation_mm - z * self.c4_mm;
        let k = (self.a2_mm * self.a2_mm + self.c3_mm * self.c3_mm).sqrt();
        let rho2 = c.x * c.x + c.y * c.y - self.b_mm * self.b_mm;
        let cz1 = c.z - self.c1_mm;
        let out_of_reach = |distance_mm: f64| SixAxisFault::OutOfReach {
            config,
            distance_mm,
            min_mm: (self.c2_mm - k).abs(),
            max_mm: self.c2_mm + k,
        };
        if rho2 < 0.0 || (rho2 == 0.0 && self.b_mm == 0.0) {
            // The wrist centre lies inside the cylinder of radius |b| about axis 1 (or on axis
            // 1, where q1 is undefined).
            return Err(SixAxisFault::InsideAxisOne {
                config,
                radius_mm: (c.x * c.x + c.y * c.y).sqrt(),
                offset_mm: self.b_mm.abs(),
            });
        }
        let rho = rho2.sqrt();
        // Rz(q1)·(±ρ, b) = (cx, cy): (cos q1, sin q1) = (cx, cy)·(±ρ, −b) / (ρ² + b²).
        let (sign, x) = match config.shoulder {
            Shoulder::Front => (1.0, rho - self.a1_mm),
            Shoulder::Back => (-1.0, -rho - self.a1_mm),
        };
        // Sines and cosines below are carried unnormalised where only their ratios matter:
        // (cos q1, sin q1)·n1 and (cos q23, sin q23)·n23 with n1, n23 > 0 scale every entry of
        // M below by n1·n23, which no arctangent sees (a square root and two divisions off the
        // dependent chain).
        let (ux, uy) = (sign * rho, self.b_mm);
        let (c1, s1) = (c.x * ux + c.y * uy, c.y * ux - c.x * uy);
        let s2 = x * x + cz1 * cz1;
        let cos_b = (s2 - self.c2_mm * self.c2_mm - k * k) * (1.0 / (2.0 * self.c2_mm * k));
        if !(-1.0..=1.0).contains(&cos_b) {
            return Err(out_of_reach(s2.sqrt()));
        }
        let sin_b = match config.elbow {
            Elbow::Up => ((1.0 - cos_b) * (1.0 + cos_b)).sqrt(),
            Elbow::Down => -((1.0 - cos_b) * (1.0 + cos_b)).sqrt(),
        };
        // β = q3 + ψ3, the forearm's turn from the upper arm's line (ψ3 = atan2(a2, c3)); the
        // wrist direction from axis 2, measured from z toward x, is q2 + atan2(k sin β,
        // c2 + k cos β): q2 = arg(cz1 + i·x) − arg(c2 + k cos β + i·k sin β).
        let (sp, cp) = (self.a2_mm / k, self.c3_mm / k);
        let (s3, c3) = (sin_b * cp - cos_b * sp, cos_b * cp + sin_b * sp);
        let (wr, wi) = (cz1, x);
        let (tr, ti) = (self.c2_mm + k * cos_b, k * sin_b);
        let (q2r, q2i) = (wr * tr + wi * ti, wi * tr - wr * ti);
        let (c23, s23) = (q2r * c3 - q2i * s3, q2i * c3 + q2r * s3);
        // M = (Rz(q1)·Ry(q23))ᵀ·R (times n1·n23): its third column and third row give the
        // wrist angles.
        // |(c1, s1)| = |c_xy|·|u| = ρ² + b² = n1; |(c23, s23)| = |q2| = n23.
        let n1 = rho2 + self.b_mm * self.b_mm;
        let n23 = (q2r * q2r + q2i * q2i).sqrt();
        let col1 = Vector3::new(c1 * c23, s1 * c23, -s23 * n1);
        let col2 = Vector3::new(-s1, c1, 0.0) * n23;
        let col3 = Vector3::new(c1 * s23, s1 * s23, c23 * n1);
        let m13 = col1.dot(&z);
        let m23 = col2.dot(&z);
        let m33 = col3.dot(&z);
        let m31 = col3.dot(&r.column(0));
        let m32 = col3.dot(&r.column(1));
        let sin5 = (m13 * m13 + m23 * m23).sqrt();
        let scale = n1 * n23;
        let (q4, q5, q6) = if sin5 > 1e-12 * scale {
            (atan2(m23, m13), atan2(sin5, m33), atan2(m32, -m31))
        } else {
            // Axes 4 and 6 in line: only q4 ± q6 is defined; q4 = 0.
            let m11 = col1.dot(&r.column(0));
            let m21 = col2.dot(&r.column(0));
            if m33 > 0.0 {
                (0.0, 0.0, atan2(m21, m11))
            } else {
                (0.0, PI, atan2(m21, -m11))
            }
        };
        Ok([atan2(s1, c1), atan2(q2i, q2r), atan2(s3, c3), q4, q5, q6])
    }
}

/// The wrist's other solution: `q4 + π, −q5, q6 + π`.
fn flipped(m: &Joints6) -> Joints6 {
    [m[0], m[1], m[2], m[3] + PI, -m[4], m[5] + PI]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_validate_and_are_found_by_name() {
        for p in &OPW_PRESETS {
            p.opw.validate().unwrap();
            p.limits().validate().unwrap();
            assert_eq!(preset(&p.model.to_uppercase()).unwrap().model, p.model);
        }
        assert!(preset("kr1000").is_none());
        assert!(preset_names().contains("\"kr16-2\""));
    }

    #[test]
    fn bad_parameters_are_refused() {
        let good = OPW_PRESETS[0].opw;
        for bad in [
            Opw {
                a1_mm: f64::NAN,
                ..good
            },
            Opw {
                c4_mm: f64::INFINITY,
                ..good
            },
            Opw { c2_mm: 0.0, ..good },
            Opw {
                a2_mm: 0.0,
                c3_mm: 0.0,
                ..good
            },
            Opw {
                signs: [1, 1, 0, 1, 1, 1],
                ..good
            },
            Opw {
                signs: [1, 2, 1, 1, 1, 1],
                ..good
            },
            Opw {
                offsets_rad: [0.0, f64::NAN, 0.0, 0.0, 0.0, 0.0],
                ..good
            },
        ] {
            assert!(bad.validate().is_err(), "{bad:?}");
        }
    }

    /// The upright pose of the parameter figure: every model angle zero puts the wrist centre at
    /// `(a1 + a2, b, c1 + c2 + c3)` and the flange `c4` above it, base axes.
    #[test]
    fn zero_pose_is_the_parameter_figure() {
        let o = Opw {
            b_mm: 30.0,
            ..OPW_PRESETS[0].opw
        };
        // Controller angles for model angles 0: joint = offset · sign.
        let q: Joints6 = std::array::from_fn(|i| o.offsets_rad[i] * f64::from(o.signs[i]));
        let f = o.forward(&q);
        let expected = Vector3::new(150.0 - 115.0, 30.0, 445.0 + 700.0 + 795.0 + 85.0);
        assert!((f.translation_mm - expected).norm() < 1e-9, "{f:?}");
        assert!((f.rotation - Matrix3::identity()).norm() < 1e-12);
    }

    /// The controller's zero is each arm's calibration position and lies inside every range
    /// (the makers' data sheets give each range as a negative and a positive end).
    #[test]
    fn the_controllers_zero_is_inside_every_range() {
        for p in &OPW_PRESETS {
            for i in 0..6 {
                assert!(
                    p.joint_min_deg[i] < 0.0 && 0.0 < p.joint_max_deg[i],
                    "{} axis {}: {}..{}",
                    p.model,
                    i + 1,
                    p.joint_min_deg[i],
                    p.joint_max_deg[i]
                );
            }
        }
    }

    /// One revolute joint of a ROS-Industrial URDF: its origin in the parent link (mm; every
    /// `rpy` of these arms' revolute joints is zero) and its axis.
    type UrdfJoint = ([f64; 3], [f64; 3]);

    /// The fixed joint to `tool0`: its origin (mm) and `rpy` (rad).
    type Tool0 = ([f64; 3], [f64; 3]);

    /// The flange (`tool0`) of a URDF chain written here from the joint list:
    /// `Π Trans(origin_i)·Rot(axis_i, joint_i)`, then the fixed `tool0` joint (origin, `rpy` =
    /// `Rz(yaw)·Ry(pitch)·Rx(roll)`).
    fn urdf_flange(chain: &[UrdfJoint; 6], tool0: Tool0, q: &Joints6) -> Pose6 {
        use nalgebra::{Isometry3, Translation3, Unit, UnitQuaternion};
        let mut t = Isometry3::identity();
        for ((origin, axis), angle) in chain.iter().zip(q) {
            let axis = Unit::new_normalize(Vector3::from(*axis));
            t = t
                * Translation3::from(Vector3::from(*origin))
                * UnitQuaternion::from_axis_angle(&axis, *angle);
        }
        let [r, p, y] = tool0.1;
        t = t
            * Translation3::from(Vector3::from(tool0.0))
            * UnitQuaternion::from_euler_angles(r, p, y);
        Pose6 {
            rotation: *t.rotation.to_rotation_matrix().matrix(),
            translation_mm: t.translation.vector,
        }
    }

    /// Each preset against the arm's URDF in ROS-Industrial's support package (joint origins
    /// and axes of `abb_irb2600_support/urdf/irb2600_12_165_macro.xacro`,
    /// `abb_irb4600_support/urdf/irb4600_60_205_macro.xacro`,
    /// `kuka_kr16_support/urdf/kr16_2_macro.xacro`, `fanuc_m20ia_support/urdf/m20ia_macro.xacro`,
    /// metres there, mm here): a description made for the arm's meshes, independent of the
    /// OPW parameter set, with each axis's sense (`0 0 -1` for KUKA's A1, `-1 0 0` for its A4
    /// and A6, FANUC's J3 to J6 negative) and the flange frame at the joints' zero. Over joint
    /// vectors spread through each arm's ranges the flange must agree within 1e-9 mm and rad.
    #[test]
    fn presets_turn_as_the_makers_urdf_chains_do() {
        let x = [1.0, 0.0, 0.0];
        let y = [0.0, 1.0, 0.0];
        let z = [0.0, 0.0, 1.0];
        let neg = |a: [f64; 3]| a.map(|v| -v);
        let half_pi = PI / 2.0;
        let chains: [(&str, [UrdfJoint; 6], Tool0, bool); 4] = [
            (
                "irb2600-12/1.65",
                [
                    ([0.0, 0.0, 445.0], z),
                    ([150.0, 0.0, 0.0], y),
                    ([0.0, 0.0, 700.0], y),
                    ([0.0, 0.0, 115.0], x),
                    ([795.0, 0.0, 0.0], y),
                    ([85.0, 0.0, 0.0], x),
                ],
                ([0.0; 3], [0.0, half_pi, 0.0]),
                true,
            ),
            (
                "irb4600-60/2.05",
                [
                    ([0.0, 0.0, 495.0], z),
                    ([175.0, 0.0, 0.0], y),
                    ([0.0, 0.0, 900.0], y),
                    ([0.0, 0.0, 175.0], x),
                    ([960.0, 0.0, 0.0], y),
                    ([135.0, 0.0, 0.0], x),
                ],
                ([0.0; 3], [0.0, half_pi, 0.0]),
                true,
            ),
            (
                "kr16-2",
                [
                    ([0.0, 0.0, 675.0], neg(z)),
                    ([260.0, 0.0, 0.0], y),
                    ([680.0, 0.0, 0.0], y),
                    ([670.0, 0.0, -35.0], neg(x)),
                    ([0.0; 3], y),
                    ([0.0; 3], neg(x)),
                ],
                ([158.0, 0.0, 0.0], [0.0, half_pi, 0.0]),
                true,
            ),
            (
                "m-20ia",
                [
                    ([0.0, 0.0, 525.0], z),
                    ([150.0, 0.0, 0.0], y),
                    ([0.0, 0.0, 790.0], neg(y)),
                    ([0.0, 0.0, 250.0], neg(x)),
                    ([835.0, 0.0, 0.0], neg(y)),
                    ([100.0, 0.0, 0.0], neg(x)),
                ],
                ([0.0; 3], [PI, -half_pi, 0.0]),
                true,
            ),
        ];
        for (model, chain, tool0, position) in chains {
            let p = preset(model).unwrap();
            // Joint vectors through the ranges (a Weyl sequence per axis), the zero among them.
            for s in 0..200 {
                let q: Joints6 = std::array::from_fn(|i| {
                    let f = (s as f64 * (0.618_033_988_75 + 0.1 * i as f64)).fract();
                    let deg = p.joint_min_deg[i] + (p.joint_max_deg[i] - p.joint_min_deg[i]) * f;
                    if s == 0 { 0.0 } else { deg.to_radians() }
                });
                let want = urdf_flange(&chain, tool0, &q);
                let got = p.opw.forward(&q);
                assert!(
                    (got.rotation - want.rotation).norm() < 1e-9,
                    "{model} {q:?}: {} vs {}",
                    got.rotation,
                    want.rotation
                );
                if position {
                    assert!(
                        (got.translation_mm - want.translation_mm).norm() < 1e-9,
                        "{model} {q:?}: {} vs {}",
                        got.translation_mm,
                        want.translation_mm
                    );
                }
            }
        }
    }

    /// The flange as the product of rotations about the six joint axes where the parameter
    /// figure (the paper's Fig. 1, module documentation) places them with every model angle
    /// zero: written here from the figure, not from [`Opw::forward`]'s closed form.
    fn figure_fk(o: &Opw, q: &Joints6) -> Pose6 {
        use nalgebra::{Isometry3, Translation3, Unit, UnitQuaternion};
        let m: Joints6 = std::array::from_fn(|i| f64::from(o.signs[i]) * q[i] - o.offsets_rad[i]);
        let centre = Vector3::new(o.a1_mm + o.a2_mm, o.b_mm, o.c1_mm + o.c2_mm + o.c3_mm);
        let axes = [
            (Vector3::zeros(), Vector3::z()),
            (Vector3::new(o.a1_mm, 0.0, o.c1_mm), Vector3::y()),
            (Vector3::new(o.a1_mm, 0.0, o.c1_mm + o.c2_mm), Vector3::y()),
            (Vector3::new(o.a1_mm + o.a2_mm, o.b_mm, 0.0), Vector3::z()),
            (centre, Vector3::y()),
            (centre, Vector3::z()),
        ];
        let mut t = Isometry3::identity();
        for ((p, a), angle) in axes.iter().zip(m) {
            t = t
                * Translation3::from(*p)
                * UnitQuaternion::from_axis_angle(&Unit::new_normalize(*a), angle)
                * Translation3::from(-*p);
        }
        t *= Translation3::from(centre + Vector3::z() * o.c4_mm);
        Pose6 {
            rotation: *t.rotation.to_rotation_matrix().matrix(),
            translation_mm: t.translation.vector,
        }
    }

    /// Every branch the inverse returns gives the pose again through [`figure_fk`].
    fn assert_branches_reproduce(o: &Opw, pose: &Pose6, at_least: usize) {
        let s = o.inverse(pose);
        let valid = s.valid.iter().filter(|v| **v).count();
        assert!(valid >= at_least, "{valid} branches: {s:?}");
        for b in 0..8 {
            if s.valid[b] {
                let back = figure_fk(o, &s.joints[b]);
                assert!(
                    (back.translation_mm - pose.translation_mm).norm() < 1e-9
                        && (back.rotation - pose.rotation).norm() < 1e-9,
                    "branch {b}: {:?} gives {back:?}, not {pose:?}",
                    s.joints[b]
                );
            }
        }
    }

    /// A small arm with a lateral offset, for the cylinder of radius `b` about axis 1.
    fn offset_arm() -> Opw {
        Opw {
            a1_mm: 100.0,
            a2_mm: -50.0,
            b_mm: 35.0,
            c1_mm: 400.0,
            c2_mm: 500.0,
            c3_mm: 450.0,
            c4_mm: 80.0,
            offsets_rad: [0.0; 6],
            signs: [1; 6],
        }
    }

    /// Lengths beyond ±100 m and offsets beyond ±720° are refused though finite; the ends
    /// themselves are taken.
    #[test]
    fn parameters_beyond_their_bounds_are_refused_and_the_bounds_taken() {
        let good = OPW_PRESETS[0].opw;
        let mut offsets = [0.0; 6];
        offsets[5] = 800f64.to_radians();
        for bad in [
            Opw {
                a1_mm: 200_000.0,
                ..good
            },
            Opw {
                offsets_rad: offsets,
                ..good
            },
        ] {
            assert!(bad.validate().is_err(), "{bad:?}");
        }
        offsets[5] = -700f64.to_radians();
        let edge = Opw {
            c4_mm: 100_000.0,
            offsets_rad: offsets,
            ..good
        };
        edge.validate().unwrap();
    }

    /// A wrist centre nearer axis 1 than the lateral offset `b`, or on axis 1 when `b` is 0,
    /// has no branch; the fault gives the centre's distance from axis 1 and the offset.
    /// A centre exactly `b` from axis 1 is reached (the wrist straight over `y`) by all eight.
    #[test]
    fn a_wrist_centre_inside_the_offset_cylinder_has_no_branch() {
        let o = offset_arm();
        let flange = |x: f64, y: f64| Pose6 {
            rotation: Matrix3::identity(),
            translation_mm: Vector3::new(x, y, 900.0 + o.c4_mm),
        };
        let inside = flange(10.0, 0.0);
        assert!(o.inverse(&inside).valid.iter().all(|v| !v));
        match o.inverse_branch(&inside, Config::from_index(0)) {
            Err(SixAxisFault::InsideAxisOne {
                radius_mm,
                offset_mm,
                ..
            }) => {
                assert!((radius_mm - 10.0).abs() < 1e-9, "{radius_mm}");
                assert!((offset_mm - o.b_mm.abs()).abs() < 1e-12, "{offset_mm}");
            }
            other => panic!("{other:?}"),
        }
        assert_branches_reproduce(&o, &flange(0.0, 35.0), 8);
        // b = 0: the wrist centre on axis 1 leaves q1 undefined.
        let p = OPW_PRESETS[0].opw;
        let on_axis = Pose6 {
            rotation: Matrix3::identity(),
            translation_mm: Vector3::new(0.0, 0.0, 1500.0 + p.c4_mm),
        };
        let s = p.inverse(&on_axis);
        assert!(s.valid.iter().all(|v| !v), "{s:?}");
        match p.inverse_branch(&on_axis, Config::from_index(0)) {
            Err(f @ SixAxisFault::InsideAxisOne { radius_mm, .. }) => {
                assert_eq!(radius_mm, 0.0);
                assert!(f.to_string().contains("0.0 mm from axis 1"), "{f}");
            }
            other => panic!("{other:?}"),
        }
    }

    /// Axes 4 and 6 in line (`q5 = 0`, and `q5 = π`, the wrist folded back): only `q4 ± q6` is
    /// defined; the branches the inverse gives must still give the pose.
    #[test]
    fn a_straight_or_folded_wrist_still_gives_the_pose() {
        let o = OPW_PRESETS[0].opw;
        for q5 in [0.0, PI] {
            let q = [0.3, 0.2, -0.4, 0.5, q5, -0.7];
            assert_branches_reproduce(&o, &figure_fk(&o, &q), 4);
        }
    }

    /// The configuration of joints by its definitions, from the figure: the wrist centre ahead
    /// of axis 1 along the arm's heading `(cos q1, sin q1)` or behind it, the sign of the
    /// forearm's turn from the upper arm's line `sin(q3 + atan2(a2, c3))`, the sign of `sin q5`.
    #[test]
    fn configurations_follow_their_definitions() {
        for o in [OPW_PRESETS[0].opw, OPW_PRESETS[3].opw, offset_arm()] {
            let mut seen = [false; 8];
            for s in 0..400 {
                let q: Joints6 = std::array::from_fn(|i| {
                    PI * (2.0 * (s as f64 * (0.618_033_988_75 + 0.13 * i as f64)).fract() - 1.0)
                });
                let m: Joints6 =
                    std::array::from_fn(|i| f64::from(o.signs[i]) * q[i] - o.offsets_rad[i]);
                let f = figure_fk(&o, &q);
                let centre = f.translation_mm - f.rotation.column(2) * o.c4_mm;
                let ahead = centre.x * m[0].cos() + centre.y * m[0].sin();
                let bend = (m[2] + o.a2_mm.atan2(o.c3_mm)).sin();
                let wrist = m[4].sin();
                if ahead.abs() < 1e-6 || bend.abs() < 1e-9 || wrist.abs() < 1e-9 {
                    continue;
                }
                let want = super::super::config_by_signs(ahead, bend, wrist);
                assert_eq!(o.config_of(&q), want, "{q:?}");
                seen[want.index()] = true;
            }
            assert!(seen.iter().all(|s| *s), "{seen:?}");
        }
    }

    /// The closed-form forward kinematics against the figure's product of rotations, on arms
    /// with a lateral offset `b`, offsets and mixed signs (the presets have `b = 0`).
    #[test]
    fn forward_is_the_figures_product_of_rotations() {
        let mixed = Opw {
            offsets_rad: [0.1, -0.3, -PI / 2.0, 0.2, 0.0, PI],
            signs: [-1, 1, -1, 1, -1, 1],
            ..offset_arm()
        };
        for o in [offset_arm(), mixed] {
            for s in 0..200 {
                let q: Joints6 = std::array::from_fn(|i| {
                    PI * (2.0 * (s as f64 * (0.618_033_988_75 + 0.13 * i as f64)).fract() - 1.0)
                });
                let (got, want) = (o.forward(&q), figure_fk(&o, &q));
                assert!(
                    (got.translation_mm - want.translation_mm).norm() < 1e-9,
                    "{q:?}"
                );
                assert!((got.rotation - want.rotation).norm() < 1e-12, "{q:?}");
            }
        }
    }
}
