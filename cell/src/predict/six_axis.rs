//! Predicting a six-axis arm's winding from its plan: the motion its controller and the mandrel's
//! drive are told to make, laid by the placement model ([`paths::placement`]).
//!
//! The IRB 6/2 cell is predicted by winding it on the simulated cell (the robot computer's
//! interpretation, its zones, the link's timing). A six-axis arm's controller runs its own program
//! (`windcell post`), so its motion is modelled from the plan: each segment's move lasts the
//! plan's segment time with the eye on the straight line between the segment's ends at constant
//! speed (a time-based linear move), and the mandrel
//! - **coupled** (`drive = "robot"`): interpolated by the controller with the eye, linear in time
//!   within each segment between its commanded angles (the external axis of a coordinated move);
//! - **indexer**: turning as windcell's indexer turns it, step by step on its trapezoid
//!   ([`paths::MandrelProfile::time_at_step_s`]): one move through the whole path in fine, medium
//!   and continuous movement, one move per segment (its own profile) in discrete movement.
//!
//! The sources, as for the IRB 6/2: **segment chords** (the ideal angles), **step quantisation**
//! (the commanded angles) and **timing drift** (the indexer's ramps against the arm's constant
//! speed; 0 when coupled). Not modelled, and reported as 0: the controller's zone blending and
//! servo lag (its corners), lost steps, and the setup's spread (no Monte Carlo).
//!
//! The model works in the thesis cell's frame: only the eye's motion relative to the mandrel
//! lays the fibre, and a rigid change of frame that takes the mandrel axis onto the thesis axis
//! keeps straight lines straight and turns about the axis as they were.

use nalgebra::Point3;
use paths::placement::{self, SampledEye};
use paths::{Calibration, Tube};

use super::{Options, PathPrediction, Sources, chord_errors, eye_cell, run_error, segment_of};
use crate::Error;
use crate::plan::tool::PlannedPath;

/// Samples of the model motion per second (at least [`MODEL_STEPS_PER_SEGMENT`] per segment).
const SAMPLES_PER_S: f64 = 200.0;

/// One path's prediction from its plan.
pub fn predict_path(
    path: &PlannedPath,
    tube: &Tube,
    setup: &paths::Setup,
    speeds: &paths::Speeds,
    coupled: bool,
    opt: &Options,
) -> Result<PathPrediction, Error> {
    let transform =
        Calibration::default().transform(setup.robot_distance_mm, setup.mandrel_height_mm);
    let plan = &path.plan;
    let start = plan.start.tangent_point_mm;
    let desired = &path.desired_mm;
    let poses: Vec<&paths::Pose> = std::iter::once(&plan.start)
        .chain(plan.segments.iter().map(|s| &s.pose))
        .collect();
    let (chords, quantised) = chord_errors(path, tube, &transform)?;

    // The timed motion: the eye linear in time within each segment, the mandrel as its drive
    // turns it.
    let mut eye: Vec<(f64, [f64; 3])> = Vec::new();
    let mut mandrel: Vec<(f64, f64)> = Vec::new();
    let steps_per_rev = setup.gearing.steps_per_mandrel_rev();
    let step_rad = setup.gearing.step_angle_rad();
    let phi0 = plan.start.mandrel_rad;
    let total_steps: u64 = plan.segments.iter().map(|s| s.steps.unsigned_abs()).sum();
    let mut t0 = 0.0;
    let mut covered = 0u64;
    let mut angle_before = phi0;
    let mut previous = &plan.start;
    for s in &plan.segments {
        let n = s.steps.unsigned_abs();
        let samples = ((s.duration_s * SAMPLES_PER_S).ceil() as usize).max(8);
        let from = eye_cell(&transform, &previous.eye_mandrel_mm, previous.mandrel_rad);
        let to = eye_cell(&transform, &s.pose.eye_mandrel_mm, s.pose.mandrel_rad);
        for i in 0..samples {
            let f = i as f64 / samples as f64;
            eye.push((
                t0 + f * s.duration_s,
                std::array::from_fn(|j| from[j] + (to[j] - from[j]) * f),
            ));
        }
        if coupled || n == 0 {
            for i in 0..samples {
                let f = i as f64 / samples as f64;
                mandrel.push((
                    t0 + f * s.duration_s,
                    angle_before + (s.pose.mandrel_rad - angle_before) * f,
                ));
            }
        } else {
            let direction = (s.pose.mandrel_rad - angle_before).signum();
            for k in 0..n {
                let t = match speeds.movement {
                    paths::Movement::Discrete => s.mandrel.time_at_step_s(k, n, steps_per_rev),
                    _ => {
                        speeds
                            .mandrel
                            .time_at_step_s(covered + k, total_steps, steps_per_rev)
                            - speeds
                                .mandrel
                                .time_at_step_s(covered, total_steps, steps_per_rev)
                    }
                };
                mandrel.push((t0 + t, angle_before + direction * k as f64 * step_rad));
            }
        }
        covered += n;
        t0 += s.duration_s;
        angle_before = s.pose.mandrel_rad;
        previous = &s.pose;
    }
    let last = poses.last().copied().unwrap_or(&plan.start);
    eye.push((
        t0,
        eye_cell(&transform, &last.eye_mandrel_mm, last.mandrel_rad),
    ));
    mandrel.push((t0, last.mandrel_rad));
    let track = SampledEye::new(&eye, &mandrel, &transform);
    let laid = placement::lay_on_tube(tube, &track, &start, 0.0, t0, opt.step_s)
        .map_err(|e| run_error(format!("{}: placement model: {e}", path.name)))?;
    let pts: Vec<Point3<f64>> = laid.points.iter().map(|p| p.1).collect();
    let error_mm = placement::distances(&pts, desired);
    let (k_max, e_max) = error_mm
        .iter()
        .enumerate()
        .fold((0, 0.0f64), |a, (k, &e)| if e > a.1 { (k, e) } else { a });
    let at = pts.get(k_max).copied().unwrap_or(start);
    Ok(PathPrediction {
        name: path.name.clone(),
        program: path.program,
        time_s: t0,
        max_error_mm: e_max,
        at_segment: segment_of(path, &at),
        at_height_mm: at.z,
        sources: Sources {
            chords_mm: chords,
            quantisation_mm: quantised - chords,
            corners_mm: 0.0,
            timing_mm: e_max - quantised,
            lost_steps: 0,
            setup_mm: None,
        },
        setup_median_mm: None,
        setup_p95_mm: None,
        left_mandrel_at_s: laid.left_at_s,
        bridged_s: laid.bridged_s,
        desired_mm: desired.clone(),
        laid: laid.points.clone(),
        error_mm,
    })
}
