//! `windcell post` and `windcell verify` of the S-bend mesh job on six-axis arms, all four formats
//! (target: under 200 ms for both paths in all four). `post_verify/sbend_all_formats` posts (plans,
//! checks and writes the programs) and verifies (reads them back, checks every target, runs them on
//! the model of the cell, checks and lays the run) through the library calls the commands make.
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
    let cases = [
        (Format::Rapid, irb.clone()),
        (Format::Krl, irb.clone()),
        (Format::Fanuc, irb.clone()),
        (Format::UrScript, ur),
    ];
    let opt = cell::predict::Options::default();
    let sync = cell::run::cellfile::DEFAULT_ROBOT_IO;
    c.bench_function("post_verify/sbend_all_formats", |b| {
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
