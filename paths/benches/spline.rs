//! Spline throughput: evaluation, interpolation, least-squares fitting, arc length, equal-length
//! division and the lathe winder's uniform cubic sampling. Targets and figures are in
//! `docs/benchmarks.md` (section "Splines"). Run with
//! `cargo bench -p paths --bench spline -- --warm-up-time 1 --measurement-time 3`.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use nalgebra::{Vector2, Vector3};
use paths::{BSpline, UniformCubic};
use std::hint::black_box;

/// Two turns of a 50 mm helix rising 20 mm per radian, `count` points.
fn helix(count: usize) -> Vec<Vector3<f64>> {
    (0..count)
        .map(|i| {
            let a = 4.0 * std::f64::consts::PI * i as f64 / (count - 1) as f64;
            Vector3::new(50.0 * a.cos(), 50.0 * a.sin(), 20.0 * a)
        })
        .collect()
}

fn splines(c: &mut Criterion) {
    let points = helix(1000);
    let curve = BSpline::interpolate(&helix(200)).unwrap();

    let mut g = c.benchmark_group("spline");
    g.throughput(Throughput::Elements(1000));
    g.bench_function("eval_1000", |b| {
        b.iter(|| {
            let mut sum = Vector3::zeros();
            for i in 0..1000 {
                sum += curve.eval(black_box(i as f64 / 999.0));
            }
            sum
        })
    });
    g.bench_function("interpolate_1000_points", |b| {
        b.iter(|| BSpline::interpolate(black_box(&points)).unwrap())
    });
    g.throughput(Throughput::Elements(1));
    let circle: Vec<Vector2<f64>> = (0..361)
        .map(|i| {
            let a = 1.5 * std::f64::consts::PI * i as f64 / 360.0;
            Vector2::new(100.0 * a.cos(), 100.0 * a.sin())
        })
        .collect();
    g.bench_function("fit_circle_361_points_0.01mm", |b| {
        b.iter(|| BSpline::fit(black_box(&circle), 0.01).unwrap())
    });
    g.bench_function("max_deviation_1000_points", |b| {
        let fitted = BSpline::fit(&points, 0.05).unwrap();
        b.iter(|| fitted.max_deviation(black_box(&points)))
    });
    g.bench_function("length_helix", |b| b.iter(|| black_box(&curve).length()));
    g.bench_function("equal_length_100", |b| {
        b.iter(|| black_box(&curve).equal_length(100).unwrap())
    });
    let program: Vec<Vector3<f64>> = helix(1000);
    g.throughput(Throughput::Elements(4001 + 16));
    g.bench_function("uniform_cubic_1000_points_n4", |b| {
        b.iter(|| {
            UniformCubic::new(black_box(&program))
                .unwrap()
                .sample(4)
                .unwrap()
        })
    });
    g.finish();
}

criterion_group!(benches, splines);
criterion_main!(benches);
