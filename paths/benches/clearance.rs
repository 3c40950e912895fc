//! Clearance benchmarks: the full collision and snag check of the S-bend job on a 200 448-triangle
//! mesh (both paths, every segment, the eye mechanism, the free fibre and the arm's links), and
//! the free-fibre (tow-segment) query alone. Figures in docs/benchmarks.md ("Clearance").

#[path = "common/cell.rs"]
mod cell;

use std::hint::black_box;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use nalgebra::Point3;
use paths::clearance::sweep::Cell;
use paths::clearance::{
    DEFAULT_EYE_RADIUS_MM, DEFAULT_SNAG_TOLERANCE_MM, EyeMechanism, MeshSolid, Solid, sweep,
};
use paths::geodesic::{Direction, PathStart};
use paths::mesh::trace::{DEFAULT_CREASE_DEG, TraceOptions, Tracer};
use paths::mesh::{Closure, DEFAULT_WELD_MM, prepare, resegment, triasym};
use paths::plan::PathPlan;
use paths::robot::ElbowBranch;
use paths::spine::{SBEND_SMOOTHING_MM, SBEND_TABLE_6_1_MM};
use paths::{Arm, Movement, Setup, Spine, Tube};

/// The S-bend job of `examples/sbend-mesh.toml` on a 200 448-triangle mesh: its solid, setup and
/// the plans of its two paths.
fn sbend_job() -> (MeshSolid, Setup, Vec<PathPlan>) {
    let tube = Tube::new(
        Spine::smoothing(&SBEND_TABLE_6_1_MM, SBEND_SMOOTHING_MM).unwrap(),
        28.5,
    )
    .unwrap();
    let raw = triasym::tube(&tube, 384, 350.0 / 260.0, true).unwrap();
    let (mesh, adjacency) = prepare(&raw, DEFAULT_WELD_MM, Closure::Closed).unwrap();
    assert_eq!(mesh.triangles().len(), 200_448);
    let solid = MeshSolid::new(&mesh).unwrap();
    let tracer = Tracer::new(mesh, &adjacency, DEFAULT_CREASE_DEG).unwrap();
    let setup = cell::setup(Arm {
        eye_mechanism_mm: 150.0,
        ..Arm::default()
    });
    let speeds = cell::speeds(Movement::Fine);
    let plans = [Direction::Down, Direction::Up]
        .into_iter()
        .map(|direction| {
            let start = PathStart {
                angle_rad: 90f64.to_radians(),
                wind_angle_rad: 45f64.to_radians(),
                direction,
            };
            let (_, cut) =
                resegment::wind(&tracer, &tube, &start, 50, &TraceOptions::default()).unwrap();
            paths::plan::plan(
                &cut.points,
                |p| tube.distance_to_surface_mm(p),
                &setup,
                &speeds,
            )
            .unwrap()
        })
        .collect();
    (solid, setup, plans)
}

fn clearance(c: &mut Criterion) {
    let (solid, setup, plans) = sbend_job();
    let arm = setup.arm;
    let cell = Cell {
        setup: &setup,
        eye: EyeMechanism {
            length_mm: 150.0,
            radius_mm: DEFAULT_EYE_RADIUS_MM,
        },
        snag_tolerance_mm: DEFAULT_SNAG_TOLERANCE_MM,
        obstacles: &[],
        home_mm: None,
        approach_speed_mm_s: 100.0,
        arm: Some(paths::clearance::sweep::SweptArm::Irb62(
            &arm,
            ElbowBranch::Up,
        )),
    };
    let refs: Vec<&PathPlan> = plans.iter().collect();
    let report = sweep(&cell, &solid, &refs).unwrap();
    assert!(report.is_clear(), "{:?}", report.findings.first());
    let mut group = c.benchmark_group("clearance");
    group.sample_size(10);
    group.bench_function("check_sbend_job_200448_triangles", |b| {
        b.iter(|| black_box(sweep(&cell, &solid, &refs).unwrap()))
    });

    // Tow segments: from each tangent point toward its eye, as the sweep checks them (mandrel
    // frame, starting half the snag tolerance off the surface).
    let origin = nalgebra::Vector3::new(setup.robot_distance_mm, 0.0, setup.mandrel_height_mm);
    let tows: Vec<(Point3<f64>, Point3<f64>)> = plans
        .iter()
        .flat_map(|p| p.segments.iter().map(|s| &s.pose))
        .map(|pose| {
            let (s, c) = pose.mandrel_rad.sin_cos();
            let w = pose.eye_mm - origin;
            let eye = Point3::new(c * w.x + s * w.y, -s * w.x + c * w.y, w.z);
            let t = pose.tangent_point_mm;
            let dir = (eye - t).normalize();
            (t + dir * (0.5 * DEFAULT_SNAG_TOLERANCE_MM), eye)
        })
        .collect();
    group.throughput(Throughput::Elements(tows.len() as u64));
    group.bench_function("tow_segment_queries_sbend_200448_triangles", |b| {
        b.iter(|| {
            for (a, e) in &tows {
                black_box(solid.inside_beyond(a, e, DEFAULT_SNAG_TOLERANCE_MM));
            }
        })
    });
    group.finish();
}

criterion_group!(benches, clearance);
criterion_main!(benches);
