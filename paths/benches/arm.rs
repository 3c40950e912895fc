//! Six-axis pose throughput: for every pose of a winding path, the inverse kinematics of the
//! path's configuration with the choice of the turn about the tow line (joint limits, wrist
//! margin, joint continuity, least joint time), as `SixAxisArm::solve_path` does it (target: at
//! least 2 million poses per second on one core). Also the eight-branch inverse alone.
//! Run with `cargo bench -p paths --bench arm`.

use std::f64::consts::TAU;
use std::hint::black_box;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use nalgebra::{Point3, Unit, Vector3};
use paths::arm::{EyeTarget, SixAxisArm, Tool};

/// A winding cell's eye poses: the tangent point on a 60 mm mandrel at `centre` swinging ±35°
/// about the side facing the robot while it climbs, the wind angle from 30° to 60°, the eye
/// 80 mm back along the fibre.
fn winding(centre: Point3<f64>, swings: f64, height_mm: f64, n: usize) -> Vec<EyeTarget> {
    let facing = (-centre.y).atan2(-centre.x);
    (0..n)
        .map(|i| {
            let s = i as f64 / (n - 1) as f64;
            let phi = facing + 35f64.to_radians() * (TAU * swings * s).sin();
            let wind = (30.0 + 30.0 * s).to_radians();
            let (sp, cp) = phi.sin_cos();
            let tangent_point = Point3::new(centre.x, centre.y, centre.z + height_mm * s)
                + Vector3::new(cp, sp, 0.0) * 60.0;
            let along = Vector3::new(-sp, cp, 0.0) * wind.sin() + Vector3::z() * wind.cos();
            let eye = tangent_point - along * 80.0;
            EyeTarget {
                eye_mm: eye,
                tow: Unit::new_normalize(tangent_point - eye),
            }
        })
        .collect()
}

fn arm(c: &mut Criterion) {
    let n = 10_000;
    let cases = [
        (
            "irb2600",
            SixAxisArm::opw_preset(
                "irb2600-12/1.65",
                Tool {
                    tcp_mm: [0.0, 0.0, 150.0],
                    rpy_deg: [0.0, 90.0, 0.0],
                },
            )
            .unwrap(),
            winding(Point3::new(1000.0, 0.0, 500.0), 20.0, 400.0, n),
        ),
        (
            "ur10e",
            SixAxisArm::ur_preset(
                "ur10e",
                Tool {
                    tcp_mm: [0.0, 50.0, 120.0],
                    rpy_deg: [20.0, 0.0, 0.0],
                },
            )
            .unwrap(),
            winding(Point3::new(700.0, 200.0, 100.0), 15.0, 300.0, n),
        ),
    ];
    let mut group = c.benchmark_group("arm");
    group.throughput(Throughput::Elements(n as u64));
    for (name, arm, targets) in &cases {
        group.bench_function(format!("solve_path_{name}_10000_poses"), |b| {
            b.iter(|| arm.solve_path(black_box(targets), None).unwrap())
        });
    }
    for (name, arm, targets) in &cases {
        let solved = arm.solve_path(targets, None).unwrap();
        let flanges: Vec<_> = solved.joints.iter().map(|q| arm.kind.forward(q)).collect();
        group.bench_function(format!("inverse_8_branches_{name}_10000_poses"), |b| {
            b.iter(|| {
                let mut sum = 0.0;
                for f in black_box(&flanges) {
                    sum += arm.kind.inverse(f).joints[0][0];
                }
                sum
            })
        });
    }
    group.finish();
    // A 50-segment path as a job plans it: the configuration ranking and the first pose's
    // search are paid once per path.
    let mut group = c.benchmark_group("arm_short");
    let (_, irb, _) = &cases[0];
    let short = winding(Point3::new(1000.0, 0.0, 500.0), 1.0, 400.0, 51);
    group.throughput(Throughput::Elements(short.len() as u64));
    group.bench_function("solve_path_irb2600_51_poses", |b| {
        b.iter(|| irb.solve_path(black_box(&short), None).unwrap())
    });
    group.finish();
}

criterion_group!(benches, arm);
criterion_main!(benches);
