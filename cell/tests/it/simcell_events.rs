//! The simulated cell advances from event to event (a move's end, a byte, an edge, a timer)
//! rather than at every `TICK`. Left alone for a long sleep, it must do what it does when polled
//! every tick (as it is while an observer watches): the same moves, the same steps, each move
//! logged no later than the tick polling logs it.

use std::time::Duration;

use cell::run::device::Timebase as _;
use cell::sim::{LogRecord, TICK};
use mandrel_drive::sim::Frontend as _;

#[path = "support/strokes.rs"]
mod strokes;

const POINTS: u16 = 40;

/// A robot running a stored program of 300 mm strokes at 200 mm/s and the mandrel turning
/// continuously, then a preset mandrel move, all in one sleep of the cell's clock.
fn wind(ticked: bool) -> (Vec<LogRecord>, u16, i64, f64) {
    let cell = strokes::stroking_cell(POINTS, 0.2, ticked);
    let t = cell.timebase();
    t.sleep(Duration::from_secs(30));
    let now = t.now_s();
    cell.with(|p| p.card.receive(b"1S\r", now)).unwrap();
    t.sleep(Duration::from_secs(5));
    let now = t.now_s();
    cell.with(|p| p.card.receive(b"1MN 1D-1846 1G\r", now))
        .unwrap();
    t.sleep(Duration::from_secs(60));
    cell.with(|p| {
        (
            p.log.clone(),
            p.robot.machine.status().instruction,
            p.card.machine().counter_steps(),
            p.card.machine().completed_s().unwrap_or(f64::NAN),
        )
    })
    .unwrap()
}

fn time(r: &LogRecord) -> f64 {
    match r {
        LogRecord::Robot { t_s, .. } | LogRecord::Indexer { t_s, .. } => *t_s,
    }
}

fn untimed(r: &LogRecord) -> LogRecord {
    let mut r = r.clone();
    match &mut r {
        LogRecord::Robot { t_s, .. } | LogRecord::Indexer { t_s, .. } => *t_s = 0.0,
    }
    r
}

#[test]
fn a_long_sleep_gives_what_polling_every_tick_gives() {
    let (evented, e_instr, e_steps, e_done) = wind(false);
    let (ticked, k_instr, k_steps, k_done) = wind(true);
    // Every stroke ran (the program ended) and the mandrel stopped after its preset move.
    let robot_moves = evented
        .iter()
        .filter(|r| {
            matches!(
                r,
                LogRecord::Robot {
                    completed: true,
                    ..
                }
            )
        })
        .count();
    assert_eq!(robot_moves, POINTS as usize, "{evented:?}");
    assert_eq!((e_instr, e_steps), (k_instr, k_steps));
    assert!(e_done.is_finite());
    assert!((e_done - k_done).abs() < 1e-9, "{e_done} vs {k_done}");
    assert_eq!(evented.len(), ticked.len(), "{evented:?}\n{ticked:?}");
    for (e, k) in evented.iter().zip(&ticked) {
        assert_eq!(untimed(e), untimed(k));
        let late = time(k) - time(e);
        assert!(
            (-1e-6..=TICK.as_secs_f64() + 1e-6).contains(&late),
            "{e:?} logged {late} s after the ticked run's"
        );
    }
}
