//! Lathe winding plans to G-code: a 40-layer helical tube of 1.46 m plans in under 0.1 s,
//! and G-code streams to a file at 1 million lines/s or more with bounded memory; a cone and
//! polar layers for their planning cost.
//! Run with `cargo bench -p cell --bench gcode`.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use paths::motion::{AxisLimit, AxisSet, Estimate, Limits};
use paths::vessel::{Job, Layer, Machine, Mandrel, Tow, TubeHelical};
use sequences::gcode::Dialect;

/// A 1.46 m tube of 70 mm diameter, 40 helical layers at ±45° (24 circuits each, 8 moves per
/// circuit), on a 4-axis machine.
fn tube_40_layers() -> Job {
    let linear = AxisLimit {
        velocity: 100.0,
        acceleration: 1000.0,
    };
    Job {
        mandrel: Mandrel::Tube {
            radius_mm: 35.0,
            length_mm: 1460.0,
        },
        tow: Tow {
            band_mm: 6.5,
            thickness_mm: 0.25,
        },
        machine: Machine {
            axes: AxisSet::Four,
            eye_radius_mm: 80.0,
            limits: Limits {
                axes: [
                    AxisLimit {
                        velocity: 720.0,
                        acceleration: 3600.0,
                    },
                    linear,
                    linear,
                    AxisLimit {
                        velocity: 360.0,
                        acceleration: 3600.0,
                    },
                ],
                junction_deviation: 0.01,
            },
            dome_steps: 10,
        },
        layers: vec![
            Layer::TubeHelical(TubeHelical {
                wind_angle_deg: 45.0,
                pattern_number: 3,
                skip_index: 1,
                lock_deg: 720.0,
                lead_in_mm: 10.0,
                lead_out_deg: 10.0,
                initial_lock: true,
                friction_lambda: 0.0,
            });
            40
        ],
        build_up: false,
    }
}

fn lathe(c: &mut Criterion) {
    let job = tube_40_layers();
    let mut group = c.benchmark_group("lathe");
    group.bench_function("plan_tube_40_layers_1460mm", |b| {
        b.iter(|| {
            let plan = job.check().unwrap();
            let mut e = Estimate::new(plan.limits(), plan.start());
            plan.emit(&mut e).unwrap();
            std::hint::black_box(e.time_s())
        })
    });
    // A vessel of many dome layers for line volume: seed 002's casing, 20 helical layers.
    let mut vessel = job.clone();
    vessel.mandrel = Mandrel::Vessel {
        cylinder_radius_mm: 60.0,
        cylinder_length_mm: 160.0,
        polar_radius_mm: 21.0,
    };
    vessel.machine.eye_radius_mm = 90.0;
    vessel.tow.thickness_mm = 0.21;
    vessel.layers = vec![Layer::Helical(Default::default()); 20];
    let plan = vessel.check().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("casing.nc");
    let (_, lines) = {
        let f = std::fs::File::create(&path).unwrap();
        let (s, _) = cell::lathe::gcode::write_program(
            &plan,
            AxisSet::Four,
            Dialect::Grbl,
            "casing",
            std::io::BufWriter::new(f),
        )
        .unwrap();
        ((), s.lines)
    };
    // FiberPath's cone (98 → 54 mm over 120 mm, 30° at the large end, 45 circuits), 40 layers:
    // every pass a geodesic of stations 0.01 mm from the curve.
    let mut cone = job.clone();
    cone.mandrel = Mandrel::Cone {
        large_radius_mm: 49.0,
        small_radius_mm: 27.0,
        length_mm: 120.0,
    };
    cone.tow.band_mm = 6.0;
    cone.layers = vec![
        Layer::TubeHelical(TubeHelical {
            wind_angle_deg: 30.0,
            pattern_number: 3,
            skip_index: 1,
            lock_deg: 180.0,
            lead_in_mm: 5.0,
            lead_out_deg: 15.0,
            initial_lock: true,
            friction_lambda: 0.0,
        });
        40
    ];
    group.bench_function("plan_cone_40_layers_120mm", |b| {
        b.iter(|| {
            let plan = cone.check().unwrap();
            let mut e = Estimate::new(plan.limits(), plan.start());
            plan.emit(&mut e).unwrap();
            std::hint::black_box(e.time_s())
        })
    });
    // Seed 002's casing, 20 polar layers with build-up (93 circuits each).
    let mut polar = vessel.clone();
    polar.mandrel = Mandrel::Vessel {
        cylinder_radius_mm: 60.0,
        cylinder_length_mm: 84.1,
        polar_radius_mm: 21.0,
    };
    polar.layers = vec![
        Layer::Polar {
            slip_limit: paths::vessel::POLAR_SLIP_LIMIT,
        };
        20
    ];
    let (polar_summary, _) = cell::lathe::gcode::write_program(
        &polar.check().unwrap(),
        AxisSet::Four,
        Dialect::Grbl,
        "polar",
        std::io::sink(),
    )
    .unwrap();
    group.throughput(Throughput::Elements(polar_summary.lines));
    group.bench_function("plan_and_write_grbl_polar_20_layers_to_sink", |b| {
        b.iter(|| {
            let plan = polar.check().unwrap();
            let (s, _) = cell::lathe::gcode::write_program(
                &plan,
                AxisSet::Four,
                Dialect::Grbl,
                "polar",
                std::io::sink(),
            )
            .unwrap();
            std::hint::black_box(s.lines)
        })
    });
    group.throughput(Throughput::Elements(lines));
    group.bench_function("estimate_casing_20_layers", |b| {
        b.iter(|| {
            let mut e = Estimate::new(plan.limits(), plan.start());
            plan.emit(&mut e).unwrap();
            std::hint::black_box(e.time_s())
        })
    });
    group.bench_function("write_grbl_casing_20_layers_to_sink", |b| {
        b.iter(|| {
            let (s, _) = cell::lathe::gcode::write_program(
                &plan,
                AxisSet::Four,
                Dialect::Grbl,
                "casing",
                std::io::sink(),
            )
            .unwrap();
            std::hint::black_box(s.lines)
        })
    });
    for dialect in [Dialect::Grbl, Dialect::Mach3] {
        group.bench_function(
            format!("write_{}_casing_20_layers_to_file", dialect.name()),
            |b| {
                b.iter(|| {
                    let f = std::fs::File::create(&path).unwrap();
                    let (s, _) = cell::lathe::gcode::write_program(
                        &plan,
                        AxisSet::Four,
                        dialect,
                        "casing",
                        std::io::BufWriter::with_capacity(1 << 16, f),
                    )
                    .unwrap();
                    std::hint::black_box(s.lines)
                })
            },
        );
    }
    group.finish();
}

criterion_group!(benches, lathe);
criterion_main!(benches);
