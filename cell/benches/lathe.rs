//! One hour of 3-axis lathe winding at 200 Hz, interpolated and simulated (issue target: under
//! 0.5 s): Fig 9-1's circuit repeated 324 times (≈ 3600 s at feed 30 with the B-spline, ≈ 2990 s
//! linear), planned and run on the PD-controlled simulated axes in simulated time.
//! Run with `cargo bench -p cell --bench lathe`.

use std::path::Path;

use cell::lathe::{Setup, simulate};
use criterion::{Criterion, criterion_group, criterion_main};
use paths::trajectory::Interpolation;
use sequences::PartProgram;

fn one_hour(c: &mut Criterion) {
    let text = include_str!("../../examples/cone-dome-cylinder.prg").replace("L 3", "L 324");
    let program = PartProgram::parse(&text).unwrap();
    let mut group = c.benchmark_group("lathe_one_hour");
    group.sample_size(10);
    for (name, interpolation) in [
        (
            "bspline",
            Interpolation::BSpline {
                knots_per_segment: 4,
            },
        ),
        ("linear", Interpolation::Linear),
    ] {
        let setup = Setup {
            interpolation,
            feed: 30.0,
            ..Setup::default()
        };
        let (report, _) = simulate(&program, Path::new("bench.prg"), &setup, 0).unwrap();
        eprintln!("{name}: {:.0} s of winding", report.completion_time_s);
        group.bench_function(name, |b| {
            b.iter(|| simulate(&program, Path::new("bench.prg"), &setup, 0).unwrap())
        });
    }
    group.finish();
}

criterion_group!(benches, one_hour);
criterion_main!(benches);
