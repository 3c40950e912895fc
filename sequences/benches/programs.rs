//! Writing and reading robot programs (`sequences::program`): two paths of 51 targets (the
//! S-bend's two paths of 50 segments) in each of the four formats, decoupled with a sync at every
//! segment (the discrete mode), on the IRB 2600 / KR 16 / M-20iA / UR10e presets.
//!
//! `cargo bench -p sequences --features bench --bench programs`

use criterion::{Criterion, criterion_group, criterion_main};
use paths::arm::{SixAxisArm, Tool};
use sequences::program::{
    self, Format, Frame, MandrelCoupling, ProgramPath, ProgramTarget, SyncSignals, WriteOptions,
};

fn arm(format: Format) -> SixAxisArm {
    let tool = Tool {
        tcp_mm: [20.0, 0.0, 180.0],
        rpy_deg: [0.0, 25.0, 0.0],
    };
    match format {
        Format::Rapid => SixAxisArm::opw_preset("irb2600-12/1.65", tool),
        Format::Krl => SixAxisArm::opw_preset("kr16-2", tool),
        Format::Fanuc => SixAxisArm::opw_preset("m-20ia", tool),
        Format::UrScript => SixAxisArm::ur_preset("ur10e", tool),
    }
    .expect("preset")
}

/// A path of `n` targets along a smooth joint sweep, poses from the arm's own kinematics.
fn path(arm: &SixAxisArm, n: usize, name: &str) -> ProgramPath {
    let targets = (0..n)
        .map(|i| {
            let s = i as f64 / n as f64;
            let j = [
                -30.0 + 60.0 * s,
                10.0,
                -20.0 + 10.0 * s,
                30.0,
                45.0 - 20.0 * s,
                100.0 * s,
            ];
            let f = arm.tool_frame(&j.map(f64::to_radians));
            let q = f.quaternion();
            ProgramTarget {
                position_mm: [f.translation_mm.x, f.translation_mm.y, f.translation_mm.z],
                orientation: [q.w, q.i, q.j, q.k],
                joints_deg: j,
                external_deg: None,
                duration_s: if i == 0 { 0.0 } else { 0.6 },
                speed_mm_s: 120.0,
                zone_mm: 1.0,
                sync: i > 0,
            }
        })
        .collect();
    ProgramPath {
        name: name.into(),
        tool: Frame {
            position_mm: [20.0, 0.0, 180.0],
            orientation: [1.0, 0.0, 0.0, 0.0],
        },
        work: Frame::IDENTITY,
        mandrel: MandrelCoupling::Decoupled {
            sync: SyncSignals {
                start_output: 5,
                in_position_input: 7,
            },
        },
        targets,
    }
}

fn bench(c: &mut Criterion) {
    let cases: Vec<(Format, SixAxisArm, Vec<ProgramPath>)> = Format::ALL
        .into_iter()
        .map(|f| {
            let a = arm(f);
            let paths = vec![path(&a, 51, "SBEND_1"), path(&a, 51, "SBEND_2")];
            (f, a, paths)
        })
        .collect();
    let run = |cases: &[(Format, SixAxisArm, Vec<ProgramPath>)]| {
        let mut steps = 0;
        for (f, a, paths) in cases {
            for p in paths {
                let files = program::write(*f, p, a, WriteOptions::default()).expect("write");
                let read = program::read(*f, &files, None).expect("read");
                steps += read.steps.len();
            }
        }
        steps
    };
    c.bench_function(
        "write and read, 2 paths x 51 targets, all four formats",
        |b| b.iter(|| run(&cases)),
    );
    for case in &cases {
        let one = std::slice::from_ref(case);
        c.bench_function(
            &format!("write and read, 2 paths x 51 targets, {}", case.0),
            |b| b.iter(|| run(one)),
        );
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
