//! Criterion: `windcell predict` of the S-bend job (both paths), its default four modes
//! (discrete, fine, medium, continuous) and 200 Monte Carlo samples of the setup error per path,
//! as the command runs it.
//! `cargo bench -p cell --bench predict` (docs/benchmarks.md, "Prediction").

use std::hint::black_box;
use std::path::Path;

use cell::predict::{self, Options};
use cell::run::cellfile::Cell;
use criterion::{Criterion, criterion_group, criterion_main};
use sequences::Job;

fn bench(c: &mut Criterion) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/sbend.toml");
    let (job, text) = Job::load(&path).unwrap();
    let cell = Cell::of_job(&job, &path).unwrap();
    let opt = Options::default();
    assert_eq!((opt.samples, opt.modes.len()), (200, 4));
    let mut g = c.benchmark_group("predict");
    g.sample_size(10);
    g.bench_function("sbend_four_modes_200_samples", |b| {
        b.iter(|| black_box(predict::predict(&job, &text, &path, &cell, &opt).unwrap()))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
