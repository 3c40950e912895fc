//! The TOOL step for one path (seed 001 §5.6): from equal-length surface points to robot poses,
//! mandrel angles, step counts and robot speeds.
//!
//! # Frames
//! - **mandrel frame**: fixed to the mandrel (see [`crate::mandrel`]).
//! - **drive frame**: the mandrel frame turned by the mandrel angle `φ` about `z` (see
//!   [`crate::tangent`]); the robot pedestal stands at `(−b, 0)`.
//! - **cell frame**: the robot base at the origin, `z` up, the rotation axis vertical through
//!   `(b, 0)`, the mandrel frame's origin at height `mandrel_height_mm`:
//!   `p_cell = (b, 0, h) + R_z(φ) p_mandrel`.
//!
//! The eye is placed for the **commanded** (step-quantised) mandrel angle, so that robot and
//! mandrel agree on where the fibre is; tangency with the robot line is then exact to within half a
//! step of mandrel rotation.

use std::f64::consts::TAU;

use nalgebra::{Point3, Unit, UnitQuaternion, Vector2, Vector3};

use crate::segment::SurfacePoint;
use crate::step::{Gearing, RemainderCarrier};
use crate::tangent::{self, Flank};
use crate::{Error, Robot, eye, wrist};

/// Where the robot and mandrel stand and how the eye is carried.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Setup {
    /// `b`: robot pedestal to the mandrel drive's rotation axis (seed 001 §3.2, §5.6 c).
    pub robot_distance_mm: f64,
    /// Height of the mandrel frame's origin above the robot base (seed 001 §5.6 d, the start height).
    pub mandrel_height_mm: f64,
    /// Tow distance from the tangent point to the eye (100 mm in the experiments, §6.4).
    pub offset_mm: f64,
    /// Length of the payout-eye mechanism from the wrist to the eye (§5.6 f).
    pub eye_mechanism_length_mm: f64,
    /// The robot's working range.
    pub robot: Robot,
    /// The mandrel drive train.
    pub gearing: Gearing,
}

/// Winding speeds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Speeds {
    /// Mandrel speed, rev/s (§5.6 e).
    pub mandrel_rps: f64,
    /// The robot's base speed; instruction speeds are percentages of it (§5.4.1).
    pub base_speed_mm_s: f64,
    /// The robot's maximum speed; no instruction asks for more.
    pub max_speed_mm_s: f64,
}

impl Setup {
    /// Checks every length.
    pub fn validate(&self) -> Result<(), Error> {
        positive("robot_distance_mm", self.robot_distance_mm)?;
        positive("offset_mm", self.offset_mm)?;
        non_negative("eye_mechanism_length_mm", self.eye_mechanism_length_mm)?;
        finite("mandrel_height_mm", self.mandrel_height_mm)?;
        self.gearing.validate()
    }
}

impl Speeds {
    /// Checks every speed.
    pub fn validate(&self) -> Result<(), Error> {
        positive("mandrel_speed_rps", self.mandrel_rps)?;
        positive("base_speed_mm_s", self.base_speed_mm_s)?;
        positive("max_speed_mm_s", self.max_speed_mm_s)
    }
}

fn finite(name: &'static str, value: f64) -> Result<(), Error> {
    if value.is_finite() {
        Ok(())
    } else {
        Err(Error::OutOfRange {
            name,
            value,
            expected: "must be finite",
        })
    }
}

fn positive(name: &'static str, value: f64) -> Result<(), Error> {
    if value > 0.0 && value.is_finite() {
        Ok(())
    } else {
        Err(Error::OutOfRange {
            name,
            value,
            expected: "must be > 0",
        })
    }
}

fn non_negative(name: &'static str, value: f64) -> Result<(), Error> {
    if value >= 0.0 && value.is_finite() {
        Ok(())
    } else {
        Err(Error::OutOfRange {
            name,
            value,
            expected: "must be ≥ 0",
        })
    }
}

/// The robot and mandrel pose at one segment end.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    /// Tangent point, mandrel frame.
    pub tangent_point_mm: Point3<f64>,
    /// Outward unit surface normal at the tangent point, mandrel frame.
    pub normal: Vector3<f64>,
    /// The eye, mandrel frame.
    pub eye_mandrel_mm: Point3<f64>,
    /// The eye, cell frame (at the commanded mandrel angle).
    pub eye_mm: Point3<f64>,
    /// Wrist orientation (tool `z` from the eye to the tangent point), sign-continuous; its pitch
    /// and roll are [`wrist::pitch_roll`].
    pub wrist_q: UnitQuaternion<f64>,
    /// Eq 3.7 mandrel angle, unwrapped along the path.
    pub ideal_mandrel_rad: f64,
    /// Commanded mandrel angle: the start angle plus the commanded steps.
    pub mandrel_rad: f64,
}

/// One segment: its end pose and what the robot and mandrel are told to do to get there.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Segment {
    /// The pose at the segment's end.
    pub pose: Pose,
    /// Motor steps for this segment.
    pub steps: i64,
    /// Time the mandrel takes for the segment at the mandrel speed, s.
    pub duration_s: f64,
    /// Robot speed as a percentage of the base speed.
    pub speed_pct: f64,
    /// True when the eye would have to move faster than the maximum speed to keep pace.
    pub speed_limited: bool,
}

/// The plan for one path.
#[derive(Debug, Clone, PartialEq)]
pub struct PathPlan {
    /// The pose at the path's first point (where the mandrel is synchronised to the robot).
    pub start: Pose,
    /// One entry per segment.
    pub segments: Vec<Segment>,
    /// Worst |commanded − ideal| mandrel angle over the segment ends.
    pub max_drift_rad: f64,
    /// Least distance from the eye to the mandrel surface.
    pub min_eye_clearance_mm: f64,
}

/// Plans one path through `points` (equal-length segment ends on the mandrel, mandrel frame).
/// `clearance_mm` gives a point's distance to the mandrel surface.
pub fn plan(
    points: &[SurfacePoint],
    clearance_mm: impl Fn(&Point3<f64>) -> f64,
    setup: &Setup,
    speeds: &Speeds,
) -> Result<PathPlan, Error> {
    setup.validate()?;
    speeds.validate()?;
    if points.len() < 2 {
        return Err(Error::OutOfRange {
            name: "segments",
            value: points.len().saturating_sub(1) as f64,
            expected: "must be at least 1",
        });
    }
    let b = setup.robot_distance_mm;

    // The flank that keeps the eye between the robot and the mandrel: the fibre must travel toward
    // the robot, i.e. along the counter-clockwise horizontal tangent on the left flank.
    let n0 = points[0].normal;
    let chord = points[1].point - points[0].point;
    let flank = if chord.x * -n0.y + chord.y * n0.x >= 0.0 {
        Flank::Left
    } else {
        Flank::Right
    };

    // Pass 1: the eye in the mandrel frame (eqs 3.8–3.14; the start eye lies along the first
    // chord) and eq 3.7's angle at every point, unwrapped so the mandrel turns continuously.
    let mut prepared: Vec<Prepared> = Vec::with_capacity(points.len());
    for (k, p) in points.iter().enumerate() {
        let (from, to) = if k == 0 { (0, 1) } else { (k - 1, k) };
        let eye = eye::position(&points[from].point, &points[to].point, setup.offset_mm)
            .ok_or(Error::DegenerateSegment { segment: k.max(1) })?;
        let eye = if k == 0 {
            points[0].point + (eye - points[1].point)
        } else {
            eye
        };
        let point_xy = Vector2::new(p.point.x, p.point.y);
        let normal_xy = Vector2::new(p.normal.x, p.normal.y);
        let angle = tangent::solve(point_xy, normal_xy, b, flank).map_err(|argument| {
            Error::TangentUndefined {
                robot_distance_mm: b,
                segment: k,
                argument: argument.abs(),
            }
        })?;
        let mut ideal = angle.rad;
        if let Some(previous) = prepared.last() {
            ideal += TAU * ((previous.ideal - ideal) / TAU).round();
        }
        prepared.push(Prepared {
            eye,
            cos: angle.cos,
            sin: angle.sin,
            ideal,
        });
    }

    // Pass 2: steps (remainder carried), the commanded angle, the cell-frame pose, the speed.
    let origin = Vector3::new(b, 0.0, setup.mandrel_height_mm);
    let step_angle = setup.gearing.step_angle_rad();
    let max_speed = speeds.max_speed_mm_s.min(setup.robot.max_speed_mm_s);
    let phi0 = prepared[0].ideal;
    let mut min_clearance = f64::INFINITY;
    let mut pose_at = |k: usize, commanded: f64, previous_q: Option<&UnitQuaternion<f64>>| {
        let prep = &prepared[k];
        // R_z(commanded) = R_z(ideal) R_z(δ), |δ| ≤ half a step: sin δ, cos δ by their series
        // (the next terms are below 1e-17 for a step of 0.2°).
        let delta = commanded - prep.ideal;
        let d2 = delta * delta;
        let (sin_d, cos_d) = (delta * (1.0 - d2 / 6.0), 1.0 - d2 / 2.0 + d2 * d2 / 24.0);
        let (c, s) = (
            prep.cos * cos_d - prep.sin * sin_d,
            prep.sin * cos_d + prep.cos * sin_d,
        );
        let rotate =
            |p: &Point3<f64>| Point3::new(c * p.x - s * p.y, s * p.x + c * p.y, p.z) + origin;
        let eye_mm = rotate(&prep.eye);
        let tow = Unit::new_normalize(rotate(&points[k].point) - eye_mm);
        let wrist_q = match previous_q {
            Some(prev) => wrist::continuous(wrist::toward(&tow), prev),
            None => wrist::toward(&tow),
        };
        setup.robot.check(&eye_mm, k)?;
        setup.robot.check(
            &(eye_mm - tow.into_inner() * setup.eye_mechanism_length_mm),
            k,
        )?;
        min_clearance = min_clearance.min(clearance_mm(&prep.eye));
        Ok::<Pose, Error>(Pose {
            tangent_point_mm: points[k].point,
            normal: points[k].normal,
            eye_mandrel_mm: prep.eye,
            eye_mm,
            wrist_q,
            ideal_mandrel_rad: prep.ideal,
            mandrel_rad: commanded,
        })
    };
    let start = pose_at(0, phi0, None)?;
    let mut carrier = RemainderCarrier::default();
    let mut max_drift_rad = 0.0f64;
    let mut segments: Vec<Segment> = Vec::with_capacity(points.len() - 1);
    for (k, prep) in prepared.iter().enumerate().skip(1) {
        let steps = carrier.next(setup.gearing.steps(prep.ideal - phi0));
        let commanded = phi0 + carrier.commanded as f64 * step_angle;
        max_drift_rad = max_drift_rad.max((commanded - prep.ideal).abs());
        let prev = segments.last().map_or(&start, |s| &s.pose);
        let pose = pose_at(k, commanded, Some(&prev.wrist_q))?;
        let travel = (pose.eye_mm - prev.eye_mm).norm();
        let duration_s = (commanded - prev.mandrel_rad).abs() / (TAU * speeds.mandrel_rps);
        let wanted = if travel < 1e-9 {
            // Nothing to travel: any speed arrives at once; ask for the base speed.
            speeds.base_speed_mm_s
        } else if duration_s > 0.0 {
            travel / duration_s
        } else {
            f64::INFINITY
        };
        let speed = wanted.min(max_speed);
        segments.push(Segment {
            pose,
            steps,
            duration_s,
            speed_pct: 100.0 * speed / speeds.base_speed_mm_s,
            speed_limited: wanted > max_speed,
        });
    }
    Ok(PathPlan {
        start,
        segments,
        max_drift_rad,
        min_eye_clearance_mm: min_clearance,
    })
}

/// Per-point results of the first pass.
#[derive(Debug, Clone, Copy)]
struct Prepared {
    eye: Point3<f64>,
    cos: f64,
    sin: f64,
    ideal: f64,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geodesic::{self, Direction, PathStart};
    use crate::segment::equal_length;
    use crate::spine::{SBEND_SMOOTHING_MM, SBEND_TABLE_6_1_MM};
    use crate::{Spine, Tube};
    use approx::assert_abs_diff_eq;
    use nalgebra::Rotation3;
    use std::f64::consts::PI;

    fn setup() -> Setup {
        Setup {
            robot_distance_mm: 800.0,
            mandrel_height_mm: 300.0,
            offset_mm: 100.0,
            eye_mechanism_length_mm: 150.0,
            robot: Robot::default(),
            gearing: Gearing::default(),
        }
    }

    fn speeds() -> Speeds {
        Speeds {
            mandrel_rps: 0.1,
            base_speed_mm_s: 1000.0,
            max_speed_mm_s: 2000.0,
        }
    }

    fn plan_tube(tube: &Tube, start: PathStart) -> PathPlan {
        let path = geodesic::trace(tube, &start, 0.25).unwrap();
        let points = equal_length(tube, &path, 50).unwrap();
        plan(
            &points,
            |p| tube.distance_to_surface_mm(p),
            &setup(),
            &speeds(),
        )
        .unwrap()
    }

    fn cylinder_start(direction: Direction) -> PathStart {
        PathStart {
            angle_rad: 0.0,
            wind_angle_rad: 48.3f64.to_radians(),
            direction,
        }
    }

    #[test]
    fn every_pose_is_tangent_and_the_eye_faces_the_robot() {
        let r = 31.75;
        let tubes = [
            Tube::cylinder(63.5, 178.0, 0.0, 0.0).unwrap(),
            Tube::cylinder(63.5, 178.0, 3.0 * r, 3.0 * r).unwrap(),
            Tube::cylinder(63.5, 178.0, r, 3.0 * r).unwrap(),
            Tube::new(
                Spine::smoothing(&SBEND_TABLE_6_1_MM, SBEND_SMOOTHING_MM).unwrap(),
                28.5,
            )
            .unwrap(),
        ];
        for tube in &tubes {
            for dir in [Direction::Down, Direction::Up] {
                let p = plan_tube(tube, cylinder_start(dir));
                for pose in std::iter::once(&p.start).chain(p.segments.iter().map(|s| &s.pose)) {
                    // Tangent: the horizontal line from the pedestal to the point is ⟂ the normal.
                    let rot =
                        Rotation3::from_axis_angle(&Vector3::z_axis(), pose.ideal_mandrel_rad);
                    let pt = rot * pose.tangent_point_mm;
                    let n = rot * pose.normal;
                    let line = Vector2::new(pt.x + 800.0, pt.y);
                    let nh = Vector2::new(n.x, n.y).normalize();
                    assert_abs_diff_eq!(line.dot(&nh) / line.norm(), 0.0, epsilon = 1e-9);
                    // The eye is nearer the robot than the tangent point, and 100 mm from it.
                    let tangent_cell =
                        Rotation3::from_axis_angle(&Vector3::z_axis(), pose.mandrel_rad)
                            * pose.tangent_point_mm;
                    assert!(pose.eye_mm.x < tangent_cell.x + 800.0);
                    assert_abs_diff_eq!(
                        (pose.eye_mandrel_mm - pose.tangent_point_mm).norm(),
                        100.0,
                        epsilon = 1e-9
                    );
                }
                assert!(p.max_drift_rad <= 0.5 * Gearing::default().step_angle_rad() + 1e-12);
                assert!(p.min_eye_clearance_mm > 0.0);
            }
        }
    }

    #[test]
    fn quaternions_never_flip_and_steps_sum_to_the_rotation() {
        let tube = Tube::cylinder(63.5, 178.0, 0.0, 0.0).unwrap();
        let p = plan_tube(&tube, cylinder_start(Direction::Down));
        let mut prev = p.start.wrist_q;
        for s in &p.segments {
            assert!(s.pose.wrist_q.coords.dot(&prev.coords) >= 0.0);
            prev = s.pose.wrist_q;
        }
        let total: i64 = p.segments.iter().map(|s| s.steps).sum();
        // One turn of the path is one turn of the mandrel on the axis (R = 0), clockwise.
        assert!((total as f64 + 1846.15).abs() < 20.0, "{total}");
        assert!(p.segments.iter().all(|s| s.steps < 0));
    }

    #[test]
    fn speed_follows_the_mandrel_and_is_capped_at_the_maximum() {
        let r = 31.75;
        let tube = Tube::cylinder(63.5, 178.0, 3.0 * r, 3.0 * r).unwrap();
        let path = geodesic::helix(&tube, &cylinder_start(Direction::Down), 1.0).unwrap();
        let points = equal_length(&tube, &path, 50).unwrap();
        let slow = plan(
            &points,
            |p| tube.distance_to_surface_mm(p),
            &setup(),
            &speeds(),
        )
        .unwrap();
        let fast_speeds = Speeds {
            mandrel_rps: 5.0,
            ..speeds()
        };
        let fast = plan(
            &points,
            |p| tube.distance_to_surface_mm(p),
            &setup(),
            &fast_speeds,
        )
        .unwrap();
        for (a, b) in slow.segments.iter().zip(&fast.segments) {
            let travel = (a.pose.eye_mm - fast.start.eye_mm).norm();
            let _ = travel;
            assert!(!a.speed_limited);
            assert!(b.speed_pct <= 200.0 + 1e-9);
            assert!(b.speed_pct >= a.speed_pct);
        }
        assert!(fast.segments.iter().any(|s| s.speed_limited));
        let s = &slow.segments[10];
        let prev = &slow.segments[9];
        let v = (s.pose.eye_mm - prev.pose.eye_mm).norm() / s.duration_s;
        assert_abs_diff_eq!(s.speed_pct, v / 10.0, epsilon = 1e-9);
    }

    #[test]
    fn robot_too_close_gives_tangent_undefined() {
        let r = 31.75;
        let tube = Tube::cylinder(63.5, 178.0, 3.0 * r, 3.0 * r).unwrap();
        let path = geodesic::helix(&tube, &cylinder_start(Direction::Up), 1.0).unwrap();
        let points = equal_length(&tube, &path, 50).unwrap();
        let close = Setup {
            robot_distance_mm: 60.0,
            ..setup()
        };
        let err = plan(
            &points,
            |p| tube.distance_to_surface_mm(p),
            &close,
            &speeds(),
        )
        .unwrap_err();
        assert!(matches!(err, Error::TangentUndefined { .. }), "{err}");
    }

    #[test]
    fn sbend_start_is_at_90_deg_and_45_deg_to_the_spine() {
        let tube = Tube::new(
            Spine::smoothing(&SBEND_TABLE_6_1_MM, SBEND_SMOOTHING_MM).unwrap(),
            28.5,
        )
        .unwrap();
        let start = PathStart {
            angle_rad: PI / 2.0,
            wind_angle_rad: PI / 4.0,
            direction: Direction::Up,
        };
        let p = plan_tube(&tube, start);
        assert_abs_diff_eq!(p.start.tangent_point_mm.y, 28.5, epsilon = 1e-9);
        assert_eq!(p.segments.len(), 50);
    }
}
