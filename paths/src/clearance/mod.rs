//! Clearance of the payout eye, the free fibre and the arm's links against the turning mandrel
//! and the cell's obstacles (seed 001 §5.7: "Verification of collision avoidance is important to
//! avoid damage to the equipment and for safety"; the thesis plotted tangent points, eye
//! positions, tow lines and mandrel sections and looked, Figure 5.9). No I/O.
//!
//! - [`solid`]: the mandrel as a solid with a signed distance (negative inside): the analytic tube
//!   ([`solid::TubeSolid`], closed form on straight spines) and triangle meshes
//!   ([`solid::MeshSolid`], its [`bvh`]).
//! - [`minimum`]: the certified minimum of a Lipschitz function on an interval, used both along a
//!   segment (the free fibre) and over the time of a move (the sweep between segment ends).
//! - [`sweep`]: every segment of every path of a job, and the approach and link moves between
//!   paths, with the least clearance of each pair and the first offending path, segment and time.
//!
//! # Frames
//! Mandrel queries are made in the **mandrel frame**; the eye, the arm and the obstacles live in
//! the **cell frame** and are turned into the mandrel frame at the mandrel angle of the moment:
//! `p_mandrel = R_z(−φ) (p_cell − (b, 0, h))` (see [`crate::plan`]).

pub mod bvh;
pub mod minimum;
pub mod solid;
pub mod sweep;

use nalgebra::{Point3, Vector3};

pub use crate::robot::Capsule;
pub use minimum::{Minimum, certified_min, certified_min_below};
pub use solid::{MeshSolid, Solid, TubeSolid, WalkWork};
pub use sweep::{Finding, Part, Report, SegmentClearance, sweep};

/// Depth by which the free fibre may pass inside the mandrel before it is a snag, mm.
pub const DEFAULT_SNAG_TOLERANCE_MM: f64 = 0.01;
/// Radius of the payout-eye mechanism's capsule when the cell file gives none, mm (a 20 mm eye
/// ring on a tube of the same diameter).
pub const DEFAULT_EYE_RADIUS_MM: f64 = 10.0;
/// How closely every reported minimum and every first-offence time is resolved, mm of clearance:
/// a clearance that dips below its limit by more than this between two evaluated instants is
/// always found (see [`minimum`]).
pub const RESOLUTION_MM: f64 = 0.001;

/// The payout-eye mechanism: a capsule from the eye back along the roll axis (the tool axis, away
/// from the tangent point), cell frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EyeMechanism {
    /// From the eye to the wrist, mm (`[cell.eye] length_mm`, default the cell's
    /// `eye_mechanism_length_mm`, seed 001 §5.6 f).
    pub length_mm: f64,
    /// Capsule radius, mm (`[cell.eye] radius_mm`, default [`DEFAULT_EYE_RADIUS_MM`]).
    pub radius_mm: f64,
}

/// An axis-aligned box in the cell frame: the floor, the mandrel-drive frame, a fence.
#[derive(Debug, Clone, PartialEq)]
pub struct Obstacle {
    /// What it is, for reports (`drive frame`).
    pub name: String,
    /// Least corner, mm.
    pub min_mm: Point3<f64>,
    /// Greatest corner, mm.
    pub max_mm: Point3<f64>,
}

impl Obstacle {
    /// Distance from the segment `a–b` to the box, mm; 0 when they meet.
    pub fn distance_to_segment_mm(&self, a: &Point3<f64>, b: &Point3<f64>) -> f64 {
        // The distance to a box is convex along a segment: golden-section search, then the ends.
        let d = |t: f64| {
            let p = a + (b - a) * t;
            let outside = (self.min_mm - p)
                .sup(&(p - self.max_mm))
                .sup(&Vector3::zeros());
            outside.norm()
        };
        golden_min(d, 0.0, 1.0, 1e-9).min(d(0.0)).min(d(1.0))
    }
}

/// Least value of a convex `f` on `[lo, hi]` by golden-section search to `tolerance` in the
/// argument.
pub(crate) fn golden_min(f: impl Fn(f64) -> f64, lo: f64, hi: f64, tolerance: f64) -> f64 {
    let ratio = 0.5 * (5f64.sqrt() - 1.0);
    let (mut a, mut b) = (lo, hi);
    let mut x1 = b - ratio * (b - a);
    let mut x2 = a + ratio * (b - a);
    let (mut f1, mut f2) = (f(x1), f(x2));
    while b - a > tolerance {
        if f1 < f2 {
            b = x2;
            x2 = x1;
            f2 = f1;
            x1 = b - ratio * (b - a);
            f1 = f(x1);
        } else {
            a = x1;
            x1 = x2;
            f1 = f2;
            x2 = a + ratio * (b - a);
            f2 = f(x2);
        }
    }
    f1.min(f2)
}

/// Closest parameters `(s, t)` of the segments `p1–q1` and `p2–q2` (Ericson, Real-Time Collision
/// Detection §5.1.9) and their distance.
pub fn segment_segment(
    p1: &Point3<f64>,
    q1: &Point3<f64>,
    p2: &Point3<f64>,
    q2: &Point3<f64>,
) -> (f64, f64, f64) {
    let d1 = q1 - p1;
    let d2 = q2 - p2;
    let r = p1 - p2;
    let a = d1.norm_squared();
    let e = d2.norm_squared();
    let f = d2.dot(&r);
    let eps = 1e-18;
    let (s, t) = if a <= eps && e <= eps {
        (0.0, 0.0)
    } else if a <= eps {
        (0.0, (f / e).clamp(0.0, 1.0))
    } else {
        let c = d1.dot(&r);
        if e <= eps {
            ((-c / a).clamp(0.0, 1.0), 0.0)
        } else {
            let b = d1.dot(&d2);
            let denom = a * e - b * b;
            let mut s = if denom > eps * a * e {
                ((b * f - c * e) / denom).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let mut t = (b * s + f) / e;
            if t < 0.0 {
                t = 0.0;
                s = (-c / a).clamp(0.0, 1.0);
            } else if t > 1.0 {
                t = 1.0;
                s = ((b - c) / a).clamp(0.0, 1.0);
            }
            (s, t)
        }
    };
    let distance = ((p1 + d1 * s) - (p2 + d2 * t)).norm();
    (s, t, distance)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn segment_segment_matches_dense_sampling() {
        let cases = [
            (
                Point3::new(0.0, 0.0, 0.0),
                Point3::new(10.0, 0.0, 0.0),
                Point3::new(5.0, 3.0, -4.0),
                Point3::new(5.0, 3.0, 4.0),
            ),
            (
                Point3::new(0.0, 0.0, 0.0),
                Point3::new(10.0, 0.0, 0.0),
                Point3::new(12.0, 1.0, 0.0),
                Point3::new(22.0, 1.0, 0.0),
            ),
            (
                Point3::new(1.0, 2.0, 3.0),
                Point3::new(4.0, -2.0, 7.0),
                Point3::new(2.0, 2.0, 2.0),
                Point3::new(2.0, 2.0, 2.0),
            ),
        ];
        for (p1, q1, p2, q2) in cases {
            let (_, _, d) = segment_segment(&p1, &q1, &p2, &q2);
            let mut brute = f64::INFINITY;
            for i in 0..=400 {
                for j in 0..=400 {
                    let x = p1 + (q1 - p1) * (i as f64 / 400.0);
                    let y = p2 + (q2 - p2) * (j as f64 / 400.0);
                    brute = brute.min((x - y).norm());
                }
            }
            assert!(d <= brute + 1e-12 && brute - d < 0.02, "{d} vs {brute}");
        }
        // Parallel overlapping segments: distance between the lines.
        let (_, _, d) = segment_segment(
            &Point3::new(0.0, 0.0, 0.0),
            &Point3::new(10.0, 0.0, 0.0),
            &Point3::new(2.0, 3.0, 0.0),
            &Point3::new(8.0, 3.0, 0.0),
        );
        assert!((d - 3.0).abs() < 1e-12);
    }

    #[test]
    fn box_distance_of_segments_inside_beside_and_past_a_corner() {
        let b = Obstacle {
            name: "frame".into(),
            min_mm: Point3::new(0.0, 0.0, 0.0),
            max_mm: Point3::new(10.0, 10.0, 10.0),
        };
        let d =
            |a: [f64; 3], c: [f64; 3]| b.distance_to_segment_mm(&Point3::from(a), &Point3::from(c));
        assert_eq!(d([5.0, 5.0, 5.0], [6.0, 6.0, 6.0]), 0.0);
        assert!((d([-3.0, 5.0, -1.0], [-3.0, 5.0, 20.0]) - 3.0).abs() < 1e-9);
        assert!((d([13.0, 14.0, 5.0], [13.0, 14.0, 5.0]) - 5.0).abs() < 1e-9);
        // Crossing through the box from outside to outside.
        assert!(d([-5.0, 5.0, 5.0], [15.0, 5.0, 5.0]) < 1e-9);
    }
}

/// Shared by the clearance tests.
#[cfg(test)]
pub(crate) mod test_support {
    use crate::{Spine, Tube};

    /// The S-bend of seed 001 Table 6.1, smoothed as the examples smooth it, radius 28.5 mm.
    pub(crate) fn sbend_tube() -> Tube {
        Tube::new(
            Spine::smoothing(
                &crate::spine::SBEND_TABLE_6_1_MM,
                crate::spine::SBEND_SMOOTHING_MM,
            )
            .unwrap(),
            28.5,
        )
        .unwrap()
    }

    /// A reproducible stream of numbers uniform in `[0, 1)` (xorshift64 from `seed`).
    pub(crate) fn uniform(mut seed: u64) -> impl FnMut() -> f64 {
        move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64
        }
    }
}
