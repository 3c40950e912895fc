//! Eye-pose throughput: eq 3.7, the eye (eqs 3.8–3.14), the cell-frame transform, the arm's
//! inverse kinematics, joint-range, continuity and entry-angle checks, the App. A quaternion with
//! the base yaw, steps, trapezoid timing and the arm's speed limit for every segment end of a
//! planned path (target: at least 2 million poses per second on one core). Run with `cargo bench -p paths --bench pose`.

#[path = "common/cell.rs"]
mod cell;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use paths::geodesic::{self, Direction, PathStart};
use paths::segment::equal_length;
use paths::spine::{SBEND_SMOOTHING_MM, SBEND_TABLE_6_1_MM};
use paths::{Arm, Movement, Spine, Tube};
use std::hint::black_box;

fn poses(c: &mut Criterion) {
    let setup = cell::setup(Arm::default());
    let speeds = cell::speeds(
        // Discrete: at 10 000 segments many segments turn the mandrel by no step at all, which
        // fine movement rightly refuses (the robot cannot move in no time); discrete movement
        // paces those by the robot.
        Movement::Discrete,
    );
    let tube = Tube::new(
        Spine::smoothing(&SBEND_TABLE_6_1_MM, SBEND_SMOOTHING_MM).unwrap(),
        28.5,
    )
    .unwrap();
    let start = PathStart {
        angle_rad: std::f64::consts::FRAC_PI_2,
        wind_angle_rad: std::f64::consts::FRAC_PI_4,
        direction: Direction::Up,
    };
    let path = geodesic::trace(&tube, &start, 0.25).unwrap();
    let segments = 10_000;
    let points = equal_length(&tube, &path, segments).unwrap();
    let mut group = c.benchmark_group("pose");
    group.throughput(Throughput::Elements(points.len() as u64));
    // Clearance is a separate query (a distance to the spine); measure the pose pipeline alone.
    group.bench_function("plan_10000_segments", |b| {
        b.iter(|| paths::plan::plan(black_box(&points), |_| 1.0, &setup, &speeds).unwrap())
    });
    // The arm's share: inverse kinematics alone (eye and roll axis to joints, with the sines and
    // cosines the speed limit uses) for the same poses, measured in the same run.
    let planned = paths::plan::plan(&points, |_| 1.0, &setup, &speeds).unwrap();
    let targets: Vec<_> = std::iter::once(&planned.start)
        .chain(planned.segments.iter().map(|s| &s.pose))
        .map(|p| {
            (
                p.eye_mm,
                setup.arm.forward(p.joints.irb62().unwrap()).roll_axis,
            )
        })
        .collect();
    group.bench_function("inverse_kinematics_10001_poses", |b| {
        b.iter(|| {
            let mut sum = 0.0;
            for (eye, axis) in black_box(&targets) {
                let (j, _) = setup
                    .arm
                    .inverse_with_trig(
                        eye,
                        axis,
                        std::f64::consts::FRAC_PI_2,
                        planned.arm.elbow().unwrap(),
                    )
                    .unwrap();
                sum += j.elbow_rad;
            }
            sum
        })
    });
    group.finish();

    let mut group = c.benchmark_group("path");
    group.bench_function("sbend_geodesic_trace", |b| {
        b.iter(|| geodesic::trace(black_box(&tube), &start, 0.25).unwrap())
    });
    group.finish();
}

criterion_group!(benches, poses);
criterion_main!(benches);
