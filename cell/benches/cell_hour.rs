//! Criterion: one simulated hour of the whole cell on its one virtual clock: the robot running a
//! stored program of 420 positionings (300 mm strokes at 35 mm/s, about an hour of motion) while
//! the indexer turns the mandrel continuously. The cell advances from event to event (each
//! move's end, the link's timers); for comparison, the same hour with an observer attached, which
//! polls both simulators and the sync lines every `simcell::TICK` (5 ms, 720 000 polls).
//! Target: under 100 ms.
//! `cargo bench -p cell --bench cell_hour` (docs/benchmarks.md, "Simulators").

use std::time::Duration;

use cell::run::device::Timebase as _;
use cell::sim::SimCell;
use criterion::{BatchSize, Criterion, criterion_group, criterion_main};
use mandrel_drive::sim::Frontend as _;

#[path = "../tests/it/support/strokes.rs"]
mod strokes;

const POINTS: u16 = 420;

/// A homed robot running its program (strokes at 35 mm/s) and a mandrel turning at 0.5 motor
/// rev/s, at cell time 4 s.
fn started() -> SimCell {
    strokes::stroking_cell(POINTS, 0.035, false)
}

/// As [`started`], with an observer attached: the cell is then polled every tick.
fn started_ticked() -> SimCell {
    strokes::stroking_cell(POINTS, 0.035, true)
}

fn hour(cell: SimCell) -> (u16, i64) {
    cell.timebase().sleep(Duration::from_secs(3600));
    cell.with(|p| {
        (
            p.robot.machine.status().instruction,
            p.card.machine().counter_steps(),
        )
    })
    .unwrap()
}

fn bench(c: &mut Criterion) {
    // Both devices worked through the hour: the robot is still in its program (or at its end),
    // the mandrel turned at 200 steps/s for an hour.
    let (instruction, steps) = hour(started());
    assert!(instruction > POINTS / 2, "{instruction}");
    assert!((steps - 720_000).abs() < 1_000, "{steps}");
    let mut g = c.benchmark_group("cell");
    g.sample_size(10);
    g.bench_function("one_hour_robot_and_indexer_one_clock", |b| {
        b.iter_batched(started, hour, BatchSize::PerIteration)
    });
    assert_eq!(hour(started_ticked()), hour(started()));
    g.bench_function("one_hour_polled_every_tick", |b| {
        b.iter_batched(started_ticked, hour, BatchSize::PerIteration)
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
