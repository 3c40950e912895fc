//! The whole TOOL step for each example job, through the library path `windcell plan` takes
//! (`sequences::Job::load`, `cell::plan::tool::plan`, `cell::plan::files::control_files`,
//! `cell::run::batch::admit` for the IRB 6/2, `cell::plan::check::check`,
//! `cell::plan::output::write_all`): `plan/NAME` parses, traces, segments, plans
//! (the arm's inverse kinematics, limits and speeds included), checks the job for collisions and
//! snags, and writes the control files, as `windcell plan` does; `plan_only/NAME` stops after
//! planning (target: under 50 ms each; a six-axis job, `irb2600-positioner` (the S-bend mesh on
//! an IRB 2600) and `ur10e-cylinder`, planned and checked under 100 ms). Run with `cargo bench -p cell --bench plan`.

use std::path::Path;

use criterion::{Criterion, criterion_group, criterion_main};

fn plan_examples(c: &mut Criterion) {
    let examples = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples");
    let names = [
        "cylinder",
        "offset-1r",
        "offset-2r",
        "offset-3r",
        "tilted-1r",
        "tilted-2r",
        "sbend",
        "sbend-dxf",
        "sbend-mesh",
        "irb2600-positioner",
        "ur10e-cylinder",
    ];
    let mut group = c.benchmark_group("plan_only");
    for name in names {
        let job_path = examples.join(format!("{name}.toml"));
        group.bench_function(name, |b| {
            b.iter(|| {
                // As a fresh `windcell plan` process: no mesh kept from the last iteration.
                cell::plan::mesh::forget_ready();
                let (job, text) = sequences::Job::load(&job_path).unwrap();
                cell::plan::tool::plan(&job, &text, &job_path).unwrap()
            })
        });
    }
    group.finish();
    let mut group = c.benchmark_group("plan");
    for name in names {
        let job_path = examples.join(format!("{name}.toml"));
        let out = tempfile::tempdir().unwrap();
        group.bench_function(name, |b| {
            b.iter(|| {
                // As a fresh `windcell plan` process: no mesh kept from the last iteration.
                cell::plan::mesh::forget_ready();
                let (job, text) = sequences::Job::load(&job_path).unwrap();
                let plan = cell::plan::tool::plan(&job, &text, &job_path).unwrap();
                let files = cell::plan::files::control_files(&job, &plan).unwrap();
                // What `run` would refuse (an IRB 6/2 job's pre-run check), as `plan` does.
                if job.robot_kind() == sequences::job::RobotKind::Irb6 {
                    cell::run::batch::admit(&job, &text, &job_path, &files, None).unwrap();
                }
                let checked = cell::plan::check::check(&job, &text, &job_path, plan).unwrap();
                assert!(checked.report.is_clear());
                cell::plan::output::write_all(
                    &out.path().join("plan"),
                    &files,
                    job.name.get_ref(),
                    cell::plan::output::Stale::Refuse,
                )
                .unwrap();
            })
        });
    }
    group.finish();
}

criterion_group!(benches, plan_examples);
criterion_main!(benches);
