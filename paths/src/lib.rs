//! Mandrel geometry and motion maths for windcell: analytic mandrels, fibre paths, equal-length
//! segmentation, the tangent angle (seed 001 eq 3.7), payout-eye poses (eqs 3.8–3.14), wrist
//! quaternions (App. A), the five-axis arm's kinematics and limits, six-axis arms (OPW and UR
//! kinematics, the winding pose search, the mandrel axis in the robot base frame: [`arm`]),
//! mandrel step planning and timing, and the cell's calibration; and [`link`], the byte-link
//! contract and the clocks both device crates share. No I/O.
//!
//! Millimetres and radians throughout; degrees appear only at file and command-line edges.

pub mod arm;
pub mod calibration;
pub mod clearance;
pub mod control;
pub mod delivery;
pub mod error;
pub mod eye;
pub mod geodesic;
pub mod limits;
pub mod link;
pub mod mandrel;
pub mod mesh;
pub mod motion;
pub mod pattern;
pub mod placement;
pub mod plan;
pub mod robot;
pub mod segment;
pub mod spine;
pub mod spline;
pub mod step;
pub mod tangent;
pub mod timing;
pub mod trajectory;
pub mod vessel;
pub mod wrist;

pub use calibration::Calibration;
pub use error::Error;
pub use geodesic::{Direction, PathStart, SurfacePath};
pub use mandrel::{Section, Tube};
pub use mesh::Mesh;
pub use plan::{ArmJoints, Movement, PathArm, PathPlan, Pose, Segment, Setup, SixAxisCell, Speeds};
pub use robot::{Arm, ArmFault, ArmPose, Capsule, ElbowBranch, Joint, Joints};
pub use segment::SurfacePoint;
pub use spine::Spine;
pub use spline::{BSpline, UniformCubic};
pub use step::Gearing;
pub use timing::MandrelProfile;
