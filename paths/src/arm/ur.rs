//! Universal Robots e-Series arms: forward kinematics from UR's Denavit–Hartenberg table and
//! the eight analytic inverse-kinematics branches.
//!
//! # Model (Universal Robots, "DH parameters for calculations of kinematics and dynamics",
//! universal-robots.com, e-Series table; `docs/arms.md`)
//! Standard DH, `T_i = Rz(θ_i)·Tz(d_i)·Tx(a_i)·Rx(α_i)`, with `α = (π/2, 0, 0, π/2, −π/2, 0)`,
//! `a = (0, a2, a3, 0, 0, 0)` (a2, a3 negative in UR's table), `d = (d1, 0, 0, d4, d5, d6)`; the
//! joint angles are the controller's. Frame 6 is the flange (`tool0`).
//!
//! # Inverse kinematics
//! Axes 2, 3 and 4 are parallel to `z1 = (sin θ1, −cos θ1, 0)`, and frame 4's `y` axis is `z1`,
//! so (derived here):
//! - the wrist point `p5 = p6 − d6·z6` lies `d4` along `z1`: `ρ·sin(θ1 − ψ) = d4` with
//!   `(ρ, ψ)` the polar form of `p5`'s `x, y`: `θ1 = ψ + asin(d4/ρ)` (front) or
//!   `ψ + π − asin(d4/ρ)` (back);
//! - `cos θ5 = z6·z1`, `θ5 = ±acos` (wrist no flip / flip);
//! - `x6·z1 = sin θ5 cos θ6`, `y6·z1 = −sin θ5 sin θ6`;
//! - frame 4's origin `p4 = p5 − d5·z4` with `z4 = −(sin θ6·x6 + cos θ6·y6)`, and in the plane of
//!   axes 2–4 `p4 − (0, 0, d1) − d4·z1 = a2·(cos θ2, sin θ2) + a3·(cos θ23, sin θ23)` (in
//!   `x1 = (cos θ1, sin θ1, 0)`, `y1 = (0, 0, 1)`): a two-link triangle, `θ3 = ±acos` (elbow up /
//!   down);
//! - `θ2 + θ3 + θ4` is the angle of `x4 = cos θ5·x5 − sin θ5·z6` in that plane.

use std::f64::consts::FRAC_PI_2;

use nalgebra::{Matrix3, Point3, Vector3};

use super::{
    Config, Elbow, JointLimits6, Joints6, Pose6, Shoulder, SixAxisFault, Solutions, Wrist, atan2,
    wrap,
};
use crate::Error;

/// A UR arm's DH lengths, mm (signs as in UR's table).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ur {
    /// Base to shoulder axis (`d1_mm`).
    pub d1_mm: f64,
    /// Upper arm (`a2_mm`, negative).
    pub a2_mm: f64,
    /// Forearm (`a3_mm`, negative).
    pub a3_mm: f64,
    /// Shoulder-to-wrist lateral offset (`d4_mm`).
    pub d4_mm: f64,
    /// Wrist 1 to wrist 2 (`d5_mm`).
    pub d5_mm: f64,
    /// Wrist 2 to the flange (`d6_mm`).
    pub d6_mm: f64,
}

/// A built-in UR arm with its joint ranges and speeds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UrPreset {
    /// The name `[cell.robot] model` takes.
    pub model: &'static str,
    /// The arm as its maker names it.
    pub title: &'static str,
    /// The DH lengths.
    pub ur: Ur,
    /// Fastest joint speeds, degrees/s (UR's e-Series data sheets).
    pub joint_speed_deg_s: [f64; 6],
}

/// Every UR e-Series joint turns ±360° (UR's data sheets).
pub const UR_JOINT_RANGE_DEG: f64 = 360.0;

/// UR5e, UR10e, UR16e (UR's DH table, metres there, mm here; speeds from the data sheets).
pub const UR_PRESETS: [UrPreset; 3] = [
    UrPreset {
        model: "ur5e",
        title: "Universal Robots UR5e",
        ur: Ur {
            d1_mm: 162.5,
            a2_mm: -425.0,
            a3_mm: -392.2,
            d4_mm: 133.3,
            d5_mm: 99.7,
            d6_mm: 99.6,
        },
        joint_speed_deg_s: [180.0; 6],
    },
    UrPreset {
        model: "ur10e",
        title: "Universal Robots UR10e",
        ur: Ur {
            d1_mm: 180.7,
            a2_mm: -612.7,
            a3_mm: -571.55,
            d4_mm: 174.15,
            d5_mm: 119.85,
            d6_mm: 116.55,
        },
        joint_speed_deg_s: [120.0, 120.0, 180.0, 180.0, 180.0, 180.0],
    },
    UrPreset {
        model: "ur16e",
        title: "Universal Robots UR16e",
        ur: Ur {
            d1_mm: 180.7,
            a2_mm: -478.4,
            a3_mm: -360.0,
            d4_mm: 174.15,
            d5_mm: 119.85,
            d6_mm: 116.55,
        },
        joint_speed_deg_s: [120.0, 120.0, 180.0, 180.0, 180.0, 180.0],
    },
];

/// The built-in UR arm of that model name (case-insensitive), or `None`.
pub fn preset(model: &str) -> Option<&'static UrPreset> {
    super::presets::find(&UR_PRESETS, |p| p.model, model)
}

/// The built-in arm of that model name, or [`Error::UnknownArmModel`] listing the known ones.
pub fn named(model: &str) -> Result<&'static UrPreset, Error> {
    super::presets::named(&UR_PRESETS, |p| p.model, "ur", model)
}

/// The built-in model names, for messages.
pub fn preset_names() -> String {
    super::presets::names(&UR_PRESETS, |p| p.model)
}

impl UrPreset {
    /// ±[`UR_JOINT_RANGE_DEG`] on every joint, with the preset's speeds.
    pub fn limits(&self) -> JointLimits6 {
        JointLimits6::degrees(
            [-UR_JOINT_RANGE_DEG; 6],
            [UR_JOINT_RANGE_DEG; 6],
            Some(self.joint_speed_deg_s),
        )
    }
}

const ALPHA: [f64; 6] = [FRAC_PI_2, 0.0, 0.0, FRAC_PI_2, -FRAC_PI_2, 0.0];

impl Ur {
    /// Checks that every length is finite and within 100 m, the upper arm and forearm have length.
    pub fn validate(&self) -> Result<(), Error> {
        for (name, v) in [
            ("d1_mm", self.d1_mm),
            ("a2_mm", self.a2_mm),
            ("a3_mm", self.a3_mm),
            ("d4_mm", self.d4_mm),
            ("d5_mm", self.d5_mm),
            ("d6_mm", self.d6_mm),
        ] {
            if !(v.is_finite() && v.abs() <= 100_000.0) {
                return Err(Error::OutOfRange {
                    name,
                    value: v,
                    expected: "must be finite and within ±100 000 mm",
                });
            }
        }
        for (name, v) in [("a2_mm", self.a2_mm), ("a3_mm", self.a3_mm)] {
            if v == 0.0 {
                return Err(Error::OutOfRange {
                    name,
                    value: v,
                    expected: "must not be 0 (the upper arm and forearm have length)",
                });
            }
        }
        Ok(())
    }

    fn a(&self) -> [f64; 6] {
        [0.0, self.a2_mm, self.a3_mm, 0.0, 0.0, 0.0]
    }

    fn d(&self) -> [f64; 6] {
        [self.d1_mm, 0.0, 0.0, self.d4_mm, self.d5_mm, self.d6_mm]
    }

    /// The frames 0–6 (origins and rotations) along the DH chain.
    fn chain(&self, q: &Joints6) -> [Pose6; 7] {
        let (a, d) = (self.a(), self.d());
        let mut frames = [Pose6 {
            rotation: Matrix3::identity(),
            translation_mm: Vector3::zeros(),
        }; 7];
        for i in 0..6 {
            let (s, c) = q[i].sin_cos();
            let (sa, ca) = ALPHA[i].sin_cos();
            // Rz(θ)·Rx(α), and the origin's step (a cos θ, a sin θ, d) in the previous frame.
            let step = Matrix3::new(c, -s * ca, s * sa, s, c * ca, -c * sa, 0.0, sa, ca);
            let prev = frames[i];
            frames[i + 1] = Pose6 {
                rotation: prev.rotation * step,
                translation_mm: prev.translation_mm
                    + prev.rotation * Vector3::new(a[i] * c, a[i] * s, d[i]),
            };
        }
        frames
    }

    /// The flange in the base frame.
    pub fn forward(&self, q: &Joints6) -> Pose6 {
        self.chain(q)[6]
    }

    /// The DH frame origins 0–6: base, shoulder, elbow, wrist 1, wrist 2, wrist 3, flange.
    pub fn link_points(&self, q: &Joints6) -> [Point3<f64>; 7] {
        self.chain(q).map(|f| Point3::from(f.translation_mm))
    }

    /// The configuration the joints are in: the wrist point's side of axis 1 along `x1`, the
    /// sign of `sin θ3`, the sign of `sin θ5`.
    pub fn config_of(&self, q: &Joints6) -> Config {
        let f = self.forward(q);
        let p5 = f.translation_mm - f.rotation.column(2) * self.d6_mm;
        let (s1, c1) = q[0].sin_cos();
        Config {
            shoulder: if p5.x * c1 + p5.y * s1 >= 0.0 {
                Shoulder::Front
            } else {
                Shoulder::Back
            },
            elbow: if q[2].sin() >= 0.0 {
                Elbow::Up
            } else {
                Elbow::Down
            },
            wrist: if q[4].sin() >= 0.0 {
                Wrist::NoFlip
            } else {
                Wrist::Flip
            },
        }
    }

    /// All eight branches.
    pub fn inverse(&self, flange: &Pose6) -> Solutions {
        let mut s = Solutions {
            joints: [[0.0; 6]; 8],
            valid: [false; 8],
        };
        for (i, c) in super::Config::ALL.iter().enumerate() {
            if let Ok(q) = self.inverse_branch(flange, *c) {
                s.joints[i] = q;
                s.valid[i] = true;
            }
        }
        s
    }

    /// One branch (the derivation in the module documentation).
    pub fn inverse_branch(&self, flange: &Pose6, config: Config) -> Result<Joints6, SixAxisFault> {
        let r = &flange.rotation;
        let (x6, y6, z6) = (r.column(0), r.column(1), r.column(2));
        let p5 = flange.translation_mm - z6 * self.d6_mm;
        let rho = (p5.x * p5.x + p5.y * p5.y).sqrt();
        let (la, lb) = (self.a2_mm.abs(), self.a3_mm.abs());
        let out_of_reach = |distance_mm: f64| SixAxisFault::OutOfReach {
            config,
            distance_mm,
            min_mm: (la - lb).abs(),
            max_mm: la + lb,
        };
        if rho < self.d4_mm.abs() || rho == 0.0 {
            return Err(SixAxisFault::InsideAxisOne {
                config,
                radius_mm: rho,
                offset_mm: self.d4_mm.abs(),
            });
        }
        // θ1 = ψ + φ (front) or ψ + π − φ (back), sin φ = d4/ρ, cos φ ≥ 0: as complex numbers.
        let inv_rho = 1.0 / rho;
        let (cpsi, spsi) = (p5.x * inv_rho, p5.y * inv_rho);
        let sphi = self.d4_mm * inv_rho;
        let cphi = ((1.0 - sphi) * (1.0 + sphi)).sqrt();
        let cphi = match config.shoulder {
            Shoulder::Front => cphi,
            Shoulder::Back => -cphi,
        };
        let (c1, s1) = (cpsi * cphi - spsi * sphi, spsi * cphi + cpsi * sphi);
        let z1 = Vector3::new(s1, -c1, 0.0);
        let x1 = Vector3::new(c1, s1, 0.0);
        let c5 = z6.dot(&z1).clamp(-1.0, 1.0);
        let s5_abs = ((1.0 - c5) * (1.0 + c5)).sqrt();
        let s5 = match config.wrist {
            Wrist::NoFlip => s5_abs,
            Wrist::Flip => -s5_abs,
        };
        let (s6, c6) = if s5_abs > 1e-12 {
            // (−y6·z1, x6·z1) / s5, normalised: only the sign of s5 is needed.
            let (a, b) = (-y6.dot(&z1), x6.dot(&z1));
            let scale = (1.0 / (a * a + b * b).sqrt()).copysign(s5);
            (a * scale, b * scale)
        } else {
            (0.0, 1.0)
        };
        let x5 = x6 * c6 - y6 * s6;
        let z4 = -(x6 * s6 + y6 * c6);
        let x4 = x5 * c5 - z6 * s5;
        let p4 = p5 - z4 * self.d5_mm;
        let v = p4 - Vector3::new(0.0, 0.0, self.d1_mm) - z1 * self.d4_mm;
        let (px, py) = (v.dot(&x1), v.z);
        let (a2, a3) = (self.a2_mm, self.a3_mm);
        let c3 = (px * px + py * py - a2 * a2 - a3 * a3) * (1.0 / (2.0 * a2 * a3));
        if !(-1.0..=1.0).contains(&c3) {
            return Err(out_of_reach(px.hypot(py)));
        }
        let s3_abs = ((1.0 - c3) * (1.0 + c3)).sqrt();
        let s3 = match config.elbow {
            Elbow::Up => s3_abs,
            Elbow::Down => -s3_abs,
        };
        // θ2 = arg(px + i·py) − arg(a2 + a3 cos θ3 + i·a3 sin θ3); θ4 = arg(x4 in (x1, y1)) −
        // θ2 − θ3.
        let (tr, ti) = (a2 + a3 * c3, a3 * s3);
        let (q2r, q2i) = (px * tr + py * ti, py * tr - px * ti);
        // (cos θ23, sin θ23) times |q2| > 0: θ4 below is an argument, which no positive scale
        // changes.
        let (c23, s23) = (q2r * c3 - q2i * s3, q2i * c3 + q2r * s3);
        let (xr, xi) = (x4.dot(&x1), x4.z);
        let (q4r, q4i) = (xr * c23 + xi * s23, xi * c23 - xr * s23);
        let t1 = atan2(s1, c1);
        let t2 = atan2(q2i, q2r);
        let t3 = atan2(s3, c3);
        let t4 = atan2(q4i, q4r);
        let t5 = atan2(s5, c5);
        let t6 = atan2(s6, c6);
        Ok([t1, t2, t3, t4, t5, t6].map(wrap))
    }
}

#[cfg(test)]
mod tests {
    use std::f64::consts::PI;

    use super::*;

    #[test]
    fn presets_validate_and_are_found_by_name() {
        for p in &UR_PRESETS {
            p.ur.validate().unwrap();
            assert_eq!(preset(&p.model.to_uppercase()).unwrap().model, p.model);
        }
        assert!(preset("ur3").is_none());
        // The names a job's `model` takes, as UR names its arms.
        assert_eq!(preset_names(), "\"ur5e\", \"ur10e\", \"ur16e\"");
        assert!(
            Ur {
                a3_mm: f64::NAN,
                ..UR_PRESETS[0].ur
            }
            .validate()
            .is_err()
        );
        assert!(
            Ur {
                a2_mm: 0.0,
                ..UR_PRESETS[0].ur
            }
            .validate()
            .is_err()
        );
    }

    /// All joints zero: UR's zero pose stretches the arm along the base `x` by `a2 + a3` (both
    /// negative), offsets the wrist by `d4` and the flange by `d6` along −y and lowers it by
    /// `d5`: the flange at `(a2 + a3, −(d4 + d6), d1 − d5)` (UR's DH figure).
    #[test]
    fn zero_pose_matches_the_dh_figure() {
        let u = UR_PRESETS[0].ur;
        let f = u.forward(&[0.0; 6]);
        let expected = Vector3::new(-425.0 - 392.2, -(133.3 + 99.6), 162.5 - 99.7);
        assert!((f.translation_mm - expected).norm() < 1e-9, "{f:?}");
    }

    /// UR's flange by standard Denavit–Hartenberg, one 4×4 matrix per joint,
    /// `Rz(θ)·Tz(d)·Tx(a)·Rx(α)`, from UR's table typed here in metres (UR5e: d1 0.1625,
    /// a2 −0.425, a3 −0.3922, d4 0.1333, d5 0.0997, d6 0.0996; α = π/2, 0, 0, π/2, −π/2, 0).
    fn ur5e_dh(q: &Joints6) -> Pose6 {
        use nalgebra::Matrix4;
        let d = [0.1625, 0.0, 0.0, 0.1333, 0.0997, 0.0996].map(|v: f64| v * 1000.0);
        let a = [0.0, -0.425, -0.3922, 0.0, 0.0, 0.0].map(|v: f64| v * 1000.0);
        let alpha = [FRAC_PI_2, 0.0, 0.0, FRAC_PI_2, -FRAC_PI_2, 0.0];
        let mut t = Matrix4::identity();
        for i in 0..6 {
            let (st, ct) = q[i].sin_cos();
            let (sa, ca) = alpha[i].sin_cos();
            #[rustfmt::skip]
            let step = Matrix4::new(
                ct, -st * ca, st * sa, a[i] * ct,
                st, ct * ca, -ct * sa, a[i] * st,
                0.0, sa, ca, d[i],
                0.0, 0.0, 0.0, 1.0,
            );
            t *= step;
        }
        Pose6 {
            rotation: t.fixed_view::<3, 3>(0, 0).into_owned(),
            translation_mm: t.fixed_view::<3, 1>(0, 3).into_owned(),
        }
    }

    /// Every branch the inverse returns gives the pose again through [`ur5e_dh`].
    fn assert_branches_reproduce(pose: &Pose6, at_least: usize) {
        let s = UR_PRESETS[0].ur.inverse(pose);
        let valid = s.valid.iter().filter(|v| **v).count();
        assert!(valid >= at_least, "{valid} branches: {s:?}");
        for b in 0..8 {
            if s.valid[b] {
                let back = ur5e_dh(&s.joints[b]);
                assert!(
                    (back.translation_mm - pose.translation_mm).norm() < 1e-9
                        && (back.rotation - pose.rotation).norm() < 1e-9,
                    "branch {b}: {:?} gives {back:?}, not {pose:?}",
                    s.joints[b]
                );
            }
        }
    }

    /// The configuration of joints by its definitions, from the DH chain: the wrist point
    /// `p5 = p6 − d6·z6` ahead of axis 1 along `x1 = (cos θ1, sin θ1, 0)` or behind it, the
    /// signs of `sin θ3` and `sin θ5`.
    #[test]
    fn configurations_follow_their_definitions() {
        let u = UR_PRESETS[0].ur;
        let mut seen = [false; 8];
        for s in 0..400 {
            let q: Joints6 = std::array::from_fn(|i| {
                PI * (2.0 * (s as f64 * (0.618_033_988_75 + 0.13 * i as f64)).fract() - 1.0)
            });
            let f = ur5e_dh(&q);
            let p5 = f.translation_mm - f.rotation.column(2) * 99.6;
            let ahead = p5.x * q[0].cos() + p5.y * q[0].sin();
            let (elbow, wrist) = (q[2].sin(), q[4].sin());
            if ahead.abs() < 1e-6 || elbow.abs() < 1e-9 || wrist.abs() < 1e-9 {
                continue;
            }
            let want = super::super::config_by_signs(ahead, elbow, wrist);
            assert_eq!(u.config_of(&q), want, "{q:?}");
            seen[want.index()] = true;
        }
        assert!(seen.iter().all(|s| *s), "{seen:?}");
    }

    /// The wrist point must lie at least `d4` from axis 1 (it is `d4` along `z1` from the arm's
    /// plane through axis 1): nearer, no branch, and the fault gives its height over the
    /// shoulder `|z − d1|` and the reach `| |a2| − |a3| | .. |a2| + |a3|`; exactly `d4` away
    /// (the arm's plane through the wrist point) it is reached.
    #[test]
    fn a_wrist_point_inside_the_d4_cylinder_has_no_branch() {
        let u = UR_PRESETS[0].ur;
        let flange = |x: f64| Pose6 {
            rotation: Matrix3::identity(),
            translation_mm: Vector3::new(x, 0.0, 500.0 + 99.6),
        };
        let inside = flange(100.0);
        assert!(u.inverse(&inside).valid.iter().all(|v| !v));
        match u.inverse_branch(&inside, Config::from_index(0)) {
            Err(SixAxisFault::InsideAxisOne {
                radius_mm,
                offset_mm,
                ..
            }) => {
                assert!((radius_mm - 100.0).abs() < 1e-9, "{radius_mm}");
                assert!((offset_mm - u.d4_mm.abs()).abs() < 1e-12, "{offset_mm}");
            }
            other => panic!("{other:?}"),
        }
        assert_branches_reproduce(&flange(133.3), 4);
    }

    /// `θ5 = 0` (and π): axes 4 and 6 in line, only their sum is defined; the branches the
    /// inverse gives must still give the pose.
    #[test]
    fn a_singular_wrist_still_gives_the_pose() {
        for q5 in [0.0, PI] {
            let q = [0.3, -1.2, 1.1, 0.4, q5, -0.7];
            assert_branches_reproduce(&ur5e_dh(&q), 4);
        }
    }

    /// A finite length beyond ±100 m is refused; 100 m itself is taken.
    #[test]
    fn lengths_beyond_100_m_are_refused() {
        let good = UR_PRESETS[0].ur;
        let far = Ur {
            d6_mm: 200_000.0,
            ..good
        };
        assert!(far.validate().is_err());
        let edge = Ur {
            d1_mm: 100_000.0,
            ..good
        };
        edge.validate().unwrap();
    }
}
