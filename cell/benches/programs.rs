//! `windcell post` and `windcell verify` of the S-bend mesh job on six-axis arms, all four formats
//! (target: under 200 ms for both paths in all four).
//! - `post_verify/sbend_all_formats`: each job (the IRB 2600 variant for RAPID, KRL and FANUC, the
//!   UR10e variant for URScript) planned and checked once, then for each format its programs
//!   written from that plan and verified against it (read back, every target checked, run on the
//!   model of the cell, the run checked and laid) with [`cell::verify::verify_with`].
//! - `post_verify/sbend_all_formats_commands`: the same as the two commands do it, one format at a
//!   time: `post` plans and checks, `verify` plans again ([`cell::verify::verify`]).
//!
//! Run with `cargo bench -p cell --features bench --bench programs`.

use std::path::Path;

use criterion::{Criterion, criterion_group, criterion_main};
use sequences::program::Format;

fn post_verify(c: &mut Criterion) {
    let examples = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples");
    let dir = tempfile::tempdir().unwrap();
    // The UR10e variant of the job (URScript needs a UR arm and a decoupled mandrel).
    let irb = examples.join("irb2600-positioner.toml");
    let text = std::fs::read_to_string(&irb)
        .unwrap()
        .replace(
            "mesh = \"sbend.stl\"",
            &format!("mesh = {:?}", examples.join("sbend.stl")),
        )
        .replace("kind = \"opw\"", "kind = \"ur\"")
        .replace("model = \"irb2600-12/1.65\"", "model = \"ur10e\"")
        .replace("drive = \"robot\"", "drive = \"indexer\"")
        .replace("movement = \"fine\"", "movement = \"discrete\"")
        .replace("[1000.0, -175.0, 700.0]", "[750.0, -175.0, 500.0]");
    let ur = dir.path().join("ursbend.toml");
    std::fs::write(&ur, text).unwrap();
    let opt = cell::predict::Options::default();
    let sync = cell::run::cellfile::DEFAULT_ROBOT_IO;
    // Plan once per job, share: the job is planned and checked once (what `post` refuses on), and
    // every format's programs are written from that plan and verified against it.
    let jobs = [
        (irb.clone(), vec![Format::Rapid, Format::Krl, Format::Fanuc]),
        (ur.clone(), vec![Format::UrScript]),
    ];
    c.bench_function("post_verify/sbend_all_formats", |b| {
        b.iter(|| {
            for (job_path, formats) in &jobs {
                let (job, text) = sequences::Job::load(job_path).unwrap();
                let checked = cell::plan::check::run(&job, &text, job_path).unwrap();
                assert!(checked.report.is_clear());
                let reference = cell::verify::Reference::of_plan(
                    &job,
                    &text,
                    job_path,
                    checked.plan.clone(),
                    &opt,
                )
                .unwrap();
                for format in formats {
                    let arm =
                        cell::plan::post::six_axis_arm(&job, &text, job_path, *format).unwrap();
                    let files =
                        cell::plan::post::program_files(&job, &checked.plan, &arm, *format, sync)
                            .unwrap();
                    let out = dir.path().join(format.name());
                    cell::plan::output::write_all(
                        &out,
                        &files,
                        job.name.get_ref(),
                        cell::plan::output::Stale::Remove,
                    )
                    .unwrap();
                    let v =
                        cell::verify::verify_with(&job, &text, job_path, &out, &reference).unwrap();
                    assert!(v.findings.is_empty());
                }
            }
        })
    });
    // As the two commands do it, one format at a time: `post` plans and checks, `verify` plans
    // again, predicts the plan and checks the run.
    let cases = [
        (Format::Rapid, irb.clone()),
        (Format::Krl, irb.clone()),
        (Format::Fanuc, irb.clone()),
        (Format::UrScript, ur),
    ];
    c.bench_function("post_verify/sbend_all_formats_commands", |b| {
        b.iter(|| {
            for (format, job_path) in &cases {
                let (job, text) = sequences::Job::load(job_path).unwrap();
                let arm = cell::plan::post::six_axis_arm(&job, &text, job_path, *format).unwrap();
                let checked = cell::plan::check::run(&job, &text, job_path).unwrap();
                let files =
                    cell::plan::post::program_files(&job, &checked.plan, &arm, *format, sync)
                        .unwrap();
                let out = dir.path().join(format.name());
                cell::plan::output::write_all(
                    &out,
                    &files,
                    job.name.get_ref(),
                    cell::plan::output::Stale::Remove,
                )
                .unwrap();
                let v = cell::verify::verify(&job, &text, job_path, &out, &opt).unwrap();
                assert!(v.findings.is_empty());
            }
        })
    });
}

criterion_group!(benches, post_verify);
criterion_main!(benches);
