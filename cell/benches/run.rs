//! Criterion: a whole S-bend batch (both paths) wound by the coordinator on the simulated cell's
//! fast clock, in each mode; and the coordinator's own CPU time per discrete segment.
//! `cargo bench -p cell --bench run` (docs/benchmarks.md, "Coordinator").

use std::hint::black_box;
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use cell::batch;
use cell::coordinator::{Batch, Coordinator, Event, Reach, ResumePoint, RunMode};
use cell::journal::Journal;
use cell::simcell::{SimCell, SimCellConfig};
use cell::tool;
use criterion::{Criterion, criterion_group, criterion_main};
use mandrel_drive::Drive;
use sequences::Job;

fn batch(mode: RunMode) -> Batch {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/sbend.toml");
    let (job, text) = Job::load(&path).unwrap();
    let plan = tool::plan(&job, &text, &path).unwrap();
    let files = batch::files_of_job(&tool::control_files(&job, &plan));
    let l = batch::from_files(&files, Some(mode), Path::new("."), Path::new("R")).unwrap();
    Batch::new(
        l.items,
        l.mode,
        l.job_id,
        Drive::default(),
        Reach::default(),
    )
    .unwrap()
}

/// Winds `b` on a fresh simulated cell; returns the cell's clock at the end, s.
fn wind(b: &Batch, journal: &Path) -> f64 {
    use asea_protocol::clock::Clock as _;
    let cell = SimCell::new(&SimCellConfig::default());
    let mut sink = |_e: Event| {};
    let mut c = Coordinator::new(
        cell.devices(Drive::default()),
        Arc::new(AtomicBool::new(false)),
        Journal::create(journal).unwrap(),
        &mut sink,
    );
    c.run(b, &ResumePoint::default(), true, false, false)
        .unwrap();
    cell.clock().now_s()
}

fn bench(c: &mut Criterion) {
    let dir = tempfile::tempdir().unwrap();
    let journal = dir.path().join("bench.journal");
    let mut g = c.benchmark_group("sbend_batch");
    g.sample_size(10);
    for mode in [RunMode::Discrete, RunMode::Fine, RunMode::Medium] {
        let b = batch(mode);
        let cell_s = wind(&b, &journal);
        println!("{}: {cell_s:.1} s of cell time per batch", mode.keyword());
        g.bench_function(mode.keyword(), |bench| {
            bench.iter(|| black_box(wind(&b, &journal)))
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
