//! Criterion: one simulated hour of the whole cell on its one virtual clock: the robot running a
//! stored program of 420 positionings (300 mm strokes at 35 mm/s, about an hour of motion) while
//! the indexer turns the mandrel continuously. The cell advances from event to event (each
//! move's end, the link's timers); for comparison, the same hour with an observer attached, which
//! polls both simulators and the sync lines every `simcell::TICK` (5 ms, 720 000 polls).
//! Target: under 100 ms.
//! `cargo bench -p cell --bench cell_hour` (docs/benchmarks.md, "Simulators").

use std::time::Duration;

use asea_protocol::client::store_command;
use asea_protocol::command::{Control, Instruction};
use asea_protocol::frame::Frame;
use asea_protocol::{Command, Flags, FrameConfig, Pose, Positioning, Speed, Zone};
use cell::device::Timebase as _;
use cell::simcell::{Observer, SimCell, SimCellConfig};
use criterion::{BatchSize, Criterion, criterion_group, criterion_main};
use mandrel_drive::sim::Frontend as _;

const POINTS: u16 = 420;

fn frame(cmd: &Command) -> Frame {
    let bytes = cmd.encode(&FrameConfig::default()).unwrap();
    Frame {
        code: bytes[1],
        data: bytes[3..bytes.len() - 2].to_vec(),
    }
}

/// A homed robot running its program and a mandrel turning at 0.5 motor rev/s, at cell time 4 s.
fn started() -> SimCell {
    started_with(false)
}

/// As [`started`], with an observer attached: the cell is then polled every tick.
fn started_ticked() -> SimCell {
    started_with(true)
}

fn started_with(ticked: bool) -> SimCell {
    let cell = SimCell::new(&SimCellConfig::default());
    cell.with(|p| {
        if ticked {
            p.observer = Some(Observer(Box::new(|_, _, _, _| {})));
        }
        let m = &mut p.robot.machine;
        for n in 1..=POINTS {
            let z = if n % 2 == 0 { 500.0 } else { 800.0 };
            let i = Instruction::Position(Positioning {
                flags: Flags {
                    zone: Zone::Fine,
                    ..Flags::default()
                },
                pose: Pose::from_mm([900.0, 0.0, z], [1.0, 0.0, 0.0, 0.0]).unwrap(),
                speed: Speed::from_value("speed", 0.035).unwrap(),
            });
            m.execute(&frame(&store_command(1, n, &i)), 0.0);
        }
        m.execute(
            &frame(&store_command(1, POINTS + 1, &Control::End.into())),
            0.0,
        );
        m.execute(&frame(&Command::Operate), 0.0);
        m.execute(&frame(&Command::SyncHome), 0.0);
        assert_eq!(m.last_error(), 0);
    })
    .unwrap();
    let t = cell.timebase();
    t.sleep(Duration::from_secs(4));
    let now = t.now_s();
    cell.with(|p| {
        p.robot
            .machine
            .execute(&frame(&Command::RunProgram { program: 1 }), now);
        assert_eq!(p.robot.machine.last_error(), 0);
        p.card.receive(b"1A10 1MC 1H+ 1V0.5 1G\r", now);
    })
    .unwrap();
    cell
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
