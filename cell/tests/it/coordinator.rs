//! The coordinator on the simulated cell (virtual time): the App. D handshake on one start edge,
//! whole S-bend batches in discrete, fine and medium mode, and stop + resume with the simulators'
//! logs showing every instruction executed exactly once.

use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use asea_protocol::clock::Clock as _;
use asea_protocol::command::IN_POSITION_OUTPUT;
use asea_protocol::{Client, ClientConfig, Instruction, State};
use cell::plan::tool;
use cell::run::batch::{self, Loaded};
use cell::run::coordinator::{
    Batch, Coordinator, Event, Fault, Halt, Reach, ResumePoint, RunMode, handshake_program,
    resume_point,
};
use cell::run::device::{DeviceError, MandrelDevice, SyncLines, XIndexer};
use cell::run::journal::{self, Journal};
use cell::run::transfer;
use cell::sim::{LogRecord, SimCell, SimCellConfig};
use mandrel_drive::sim::Frontend;
use mandrel_drive::sync::OPTO_DELAY_S;
use mandrel_drive::{Drive, IndexerConfig, XClient};
use sequences::{Job, MandrelMove};

/// The S-bend job's control files (planned for continuous movement when that is the mode: its
/// timing is the plan's), loaded in `mode`.
fn sbend(mode: Option<RunMode>) -> Loaded {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/sbend.toml");
    let (mut job, text) = Job::load(&path).unwrap();
    if mode == Some(RunMode::Continuous) {
        let span = job.cell.movement.span();
        job.cell.movement = toml::Spanned::new(span, RunMode::Continuous.movement());
    }
    let plan = tool::plan(&job, &text, &path).unwrap();
    let files = batch::files_of_job(&cell::plan::files::control_files(&job, &plan).unwrap());
    batch::from_files(&files, mode, Path::new("."), Path::new("SBEND.RUN")).unwrap()
}

fn checked(l: &Loaded) -> Batch {
    Batch::new(
        l.items.clone(),
        l.mode,
        l.job_id.clone(),
        Drive::default(),
        Reach::default(),
    )
    .unwrap()
}

/// Robot positions completed (program, instruction, target) and indexer steps completed.
fn completed(cell: &SimCell) -> (Vec<[f64; 3]>, Vec<i64>, Vec<i64>) {
    cell.with(|p| {
        let mut robot = Vec::new();
        let mut done = Vec::new();
        let mut partial = Vec::new();
        for r in &p.log {
            match r {
                LogRecord::Robot {
                    target_mm,
                    completed: true,
                    ..
                } => robot.push(*target_mm),
                LogRecord::Indexer {
                    steps, completed, ..
                } => {
                    if *completed {
                        done.push(*steps)
                    } else {
                        partial.push(*steps)
                    }
                }
                _ => {}
            }
        }
        (robot, done, partial)
    })
    .unwrap()
}

fn near(a: [f64; 3], b: [f64; 3]) -> bool {
    (0..3).all(|i| (a[i] - b[i]).abs() <= 0.05)
}

#[test]
fn one_start_edge_starts_the_program_and_the_armed_move_within_the_opto_delay() {
    let cell = SimCell::new(&SimCellConfig::default());
    let clock = cell.clock().clone();
    let mut robot = Client::with_clock(cell.robot_link(), clock.clone(), ClientConfig::default());
    robot.operate().unwrap();
    robot.sync_home().unwrap();
    cell.timebase_sleep(Duration::from_secs(4));
    assert!(robot.check_status().unwrap().homed);
    // A three-point program from the S-bend's first path, with the handshake.
    let l = sbend(Some(RunMode::Fine));
    let prog = transfer::robot_program(&l.items[0].rob).unwrap();
    let positions: Vec<Instruction> = prog.instructions[1..4].to_vec();
    let list = handshake_program(&positions);
    robot.set_base_speed(prog.base_speed).unwrap();
    robot.set_max_speed(prog.max_speed).unwrap();
    robot.upload_verified(7, &list).unwrap();
    let drive = Drive::default();
    let mut x = XIndexer::new(
        XClient::new(
            cell.indexer_link(),
            IndexerConfig {
                drive,
                start_velocity_command: true,
                device_id: false,
                ..IndexerConfig::default()
            },
        ),
        transfer::IndexerSetup {
            drive,
            start_velocity_command: true,
        },
    );
    let mut sync = cell.sync_lines();
    robot.run_program(7).unwrap();
    cell.timebase_sleep(Duration::from_millis(20));
    // The program lowered "in position" and waits for the start input.
    assert!(!sync.in_position().unwrap());
    let waiting = cell.with(|p| p.robot.machine.status()).unwrap();
    assert_eq!((waiting.state, waiting.instruction), (State::Running, 2));
    x.start_move(
        &MandrelMove {
            accel_rps2: 1.0,
            start_stop_rps: 0.05,
            max_rps: 0.1,
            steps: -200,
        },
        true,
    )
    .unwrap();
    cell.timebase_sleep(Duration::from_millis(50));
    assert!(!cell.with(|p| p.card.machine().is_moving()).unwrap());
    let robot_pose = cell.with(|p| p.robot.machine.pose().xyz_mm).unwrap();
    // One edge.
    let t0 = clock.now_s();
    sync.set_start(true).unwrap();
    let (mut robot_start, mut indexer_start) = (None, None);
    let step = Duration::from_micros(2);
    for _ in 0..200 {
        cell.timebase_sleep(step);
        let (pose, moving, instr) = cell
            .with(|p| {
                (
                    p.robot.machine.pose().xyz_mm,
                    p.card.machine().is_moving(),
                    p.robot.machine.status().instruction,
                )
            })
            .unwrap();
        let t = clock.now_s();
        if robot_start.is_none() && (pose != robot_pose || instr > 2) {
            robot_start = Some(t);
        }
        if indexer_start.is_none() && moving {
            indexer_start = Some(t);
        }
    }
    let (r, i) = (robot_start.unwrap() - t0, indexer_start.unwrap() - t0);
    assert!(
        (OPTO_DELAY_S..=OPTO_DELAY_S + 5e-6).contains(&r),
        "robot began {r} s after the edge"
    );
    assert!(
        (OPTO_DELAY_S..=OPTO_DELAY_S + 5e-6).contains(&i),
        "indexer began {i} s after the edge"
    );
    // In position rises only at the last point.
    let last = positions.len() as u16 + 2;
    loop {
        let (instr, state, out) = cell
            .with(|p| {
                let s = p.robot.machine.status();
                (
                    s.instruction,
                    s.state,
                    p.robot.machine.io().output(IN_POSITION_OUTPUT),
                )
            })
            .unwrap();
        assert!(
            !out || instr > last,
            "in position raised at instruction {instr}"
        );
        if state == State::Idle {
            assert!(out);
            break;
        }
        cell.timebase_sleep(Duration::from_millis(1));
        assert!(clock.now_s() < t0 + 60.0, "program never ended");
    }
}

/// Runs `batch` on `cell` from `from` with a journal at `path`; `stop_after` segment (the plan's
/// segments, numbered after the approach, which is instruction 1) or program
/// events sets the stop request.
fn wind(
    cell: &SimCell,
    b: &Batch,
    journal: Journal,
    from: &ResumePoint,
    fresh: bool,
    stop_after: Option<usize>,
) -> Result<Vec<Event>, cell::run::coordinator::Stopped> {
    let stop = Arc::new(AtomicBool::new(false));
    let mut events = Vec::new();
    let flag = stop.clone();
    let mut sink = |e: Event| {
        if matches!(
            e,
            Event::Segment { .. } | Event::Program { done: false, .. }
        ) {
            let n = events
                .iter()
                .filter(|e| {
                    matches!(
                        e,
                        Event::Segment { .. } | Event::Program { done: false, .. }
                    )
                })
                .count()
                + 1;
            if stop_after == Some(n) {
                flag.store(true, Ordering::Relaxed);
            }
        }
        events.push(e);
    };
    let mut c = Coordinator::new(cell.devices(Drive::default()), stop, journal, &mut sink);
    c.run(b, from, fresh, false, false)?;
    drop(c);
    Ok(events)
}

fn expected_targets(b: &Batch) -> Vec<[f64; 3]> {
    b.items
        .iter()
        .flat_map(|i| i.rob.instructions.iter().map(|n| n.position_mm))
        .collect()
}

/// Every planned target reached exactly once, in order (robot moves of zero length excepted:
/// the first point of a path in program mode is the approach's target).
fn check_each_once(cell: &SimCell, b: &Batch) {
    let (robot, _, _) = completed(cell);
    let want = expected_targets(b);
    let firsts: Vec<[f64; 3]> = b
        .items
        .iter()
        .map(|i| i.rob.instructions[0].position_mm)
        .collect();
    let mut k = 0;
    let mut prev: Option<[f64; 3]> = None;
    for t in &robot {
        // A path's first point: the approach (an immediate move) and the program's first
        // instruction (no motion) both reach it.
        let approach = prev.is_some_and(|p| near(p, *t)) && firsts.iter().any(|f| near(*f, *t));
        prev = Some(*t);
        if approach {
            continue;
        }
        if k < want.len() && near(*t, want[k]) {
            k += 1;
        } else {
            assert!(
                k > 0 && near(*t, want[k - 1]),
                "robot target {t:?} out of order (expected {:?})",
                want.get(k)
            );
            panic!("target {t:?} reached twice");
        }
    }
    assert_eq!(k, want.len(), "not every target reached");
}

#[test]
fn discrete_batch_winds_every_segment_once_and_resumes_after_a_stop() {
    let l = sbend(Some(RunMode::Discrete));
    let b = checked(&l);
    let dir = tempfile::tempdir().unwrap();
    let jp = dir.path().join("SBEND.journal");
    let cell = SimCell::new(&SimCellConfig::default());
    let stopped = wind(
        &cell,
        &b,
        Journal::create(&jp).unwrap(),
        &ResumePoint::default(),
        true,
        // 29 segment events: the approach and 29 segments, 30 instructions confirmed.
        Some(29),
    )
    .unwrap_err();
    assert!(matches!(stopped.halt, Halt::Interrupted { .. }));
    assert_eq!((stopped.item, stopped.segments_done), (1, 30));
    // Both axes stopped.
    let (r, m) = cell
        .with(|p| (p.robot.machine.status().state, p.card.machine().is_moving()))
        .unwrap();
    // STOP leaves the robot in its own STOPPED state (not idle, not in position).
    assert_eq!(r, State::Stopped);
    cell.timebase_sleep(Duration::from_secs(2));
    assert!(!m || !cell.with(|p| p.card.machine().is_moving()).unwrap());
    let (journal, records) = Journal::resume(&jp).unwrap();
    let from = resume_point(&b, &records).unwrap();
    assert_eq!(from.segments_done, 30);
    let events = wind(&cell, &b, journal, &from, false, None).unwrap();
    assert!(
        events
            .iter()
            .any(|e| matches!(e, Event::PathDone { item: 2, .. }))
    );
    // The robot's log: every instruction completed once, in order; the mandrel's steps add up.
    let want: Vec<[f64; 3]> = expected_targets(&b);
    let (robot, _, _) = completed(&cell);
    // Discrete moves of zero length are not sent: count distinct consecutive targets.
    let mut k = 0;
    for t in &robot {
        while k < want.len() && !near(*t, want[k]) {
            // A target equal to the previous one needs no move.
            assert!(
                k > 0 && near(want[k], want[k - 1]),
                "target {:?} skipped",
                want[k]
            );
            k += 1;
        }
        assert!(k < want.len(), "extra robot move to {t:?}");
        k += 1;
    }
    assert_eq!(k, want.len());
    let counter = cell.with(|p| p.card.machine().counter_steps()).unwrap();
    let total: i64 = b
        .items
        .iter()
        .map(|i| {
            i.rob
                .instructions
                .iter()
                .map(|n| n.mandrel.steps)
                .sum::<i64>()
        })
        .sum();
    // Counter = syncs + every segment's steps; the journal knows the syncs.
    let recs = journal::read(&jp).unwrap();
    let syncs: Vec<i64> = recs
        .iter()
        .filter(|r| r["rec"] == "sync")
        .map(|r| r["counter"].as_i64().unwrap())
        .collect();
    assert_eq!(syncs.len(), 2);
    let path2: i64 = b.items[1]
        .rob
        .instructions
        .iter()
        .map(|n| n.mandrel.steps)
        .sum();
    assert_eq!(counter, syncs[1] + path2, "total {total}");
    // The mandrel never turned back: the steps of every move it made (the one the stop cut
    // and its remainder included), taken without their sign, add up to the plan's travel, the
    // two syncs and every segment once. A resume that turned the mandrel back to the path's
    // start angle and forward again would add twice the 30 segments' steps.
    let (_, done, partial) = completed(&cell);
    let turned: i64 = done.iter().chain(&partial).map(|s| s.abs()).sum();
    assert_eq!(turned, plan_travel(&b, &syncs));
}

/// An indexer that lost power mid-batch comes back with its counter at 0 where the journal
/// leaves the mandrel 30 segments into path 1: the resume believes neither witness alone, stops
/// before anything turns (no move after the power loss), says how to re-reference the mandrel,
/// and does so again on the next try; nothing of the journal's record of the batch is lost.
#[test]
fn a_power_cycled_indexer_is_refused_with_the_rereference_line() {
    let b = checked(&sbend(Some(RunMode::Discrete)));
    let dir = tempfile::tempdir().unwrap();
    let jp = dir.path().join("J.journal");
    let cell = SimCell::new(&SimCellConfig::default());
    let journal = Journal::create(&jp).unwrap();
    // The approach and 29 segments: 30 instructions confirmed.
    wind(&cell, &b, journal, &ResumePoint::default(), true, Some(29)).unwrap_err();
    cell.timebase_sleep(Duration::from_secs(2));
    // The power loss: the card's counter and state as at power-up.
    cell.with(|p| p.card.machine.reset(0.0)).unwrap();
    let moves_before = cell
        .with(|p| {
            p.log
                .iter()
                .filter(|r| matches!(r, LogRecord::Indexer { .. }))
                .count()
        })
        .unwrap();
    for _ in 0..2 {
        let (journal, records) = Journal::resume(&jp).unwrap();
        let from = resume_point(&b, &records).unwrap();
        let confirmed = from.sync_counter.unwrap() + plan_steps(&b, 0, 30);
        assert_eq!(from.counter_confirmed, Some(confirmed));
        let refused = wind(&cell, &b, journal, &from, false, None).unwrap_err();
        match refused.halt.fault() {
            Some(Fault::MandrelUnreferenced {
                cause: cell::run::coordinator::Disagreement::Counter,
                counter_steps: 0,
                confirmed_steps,
                ..
            }) => assert_eq!(*confirmed_steps, confirmed),
            other => panic!("{other:?}"),
        }
        let line = refused.halt.reason();
        assert!(
            line.contains("re-reference") && line.contains(&format!("step {confirmed}")),
            "{line}"
        );
        assert_eq!(line.lines().count(), 1);
    }
    let moves_after = cell
        .with(|p| {
            p.log
                .iter()
                .filter(|r| matches!(r, LogRecord::Indexer { .. }))
                .count()
        })
        .unwrap();
    assert_eq!(
        moves_after, moves_before,
        "the mandrel turned after the power loss"
    );
    let recs = journal::read(&jp).unwrap();
    assert_eq!(
        recs.iter().filter(|r| r["rec"] == "segment").count(),
        30,
        "the journal's segments"
    );
}

/// The mandrel's travel the plan asks for, steps without sign: each path's sync from where the
/// one before left the mandrel (the zero for the first), then every instruction's move.
fn plan_travel(b: &Batch, syncs: &[i64]) -> i64 {
    let mut at = 0;
    let mut travel = 0;
    for (item, sync) in b.items.iter().zip(syncs) {
        travel += (sync - at).abs();
        let steps: Vec<i64> = item
            .rob
            .instructions
            .iter()
            .map(|i| i.mandrel.steps)
            .collect();
        travel += steps.iter().map(|s| s.abs()).sum::<i64>();
        at = sync + steps.iter().sum::<i64>();
    }
    travel
}

/// Sync lines that press "stop" `polls` in-position polls after the start edge.
#[derive(Debug)]
struct StopMidProgram {
    inner: Box<dyn SyncLines>,
    left: Option<i64>,
    polls: i64,
    flag: Arc<AtomicBool>,
}

impl SyncLines for StopMidProgram {
    fn set_start(&mut self, on: bool) -> cell::run::device::DeviceResult<()> {
        if on && self.left.is_none() {
            self.left = Some(self.polls);
        }
        self.inner.set_start(on)
    }
    fn in_position(&mut self) -> cell::run::device::DeviceResult<bool> {
        if let Some(n) = self.left.as_mut() {
            *n -= 1;
            if *n == 0 {
                self.flag.store(true, Ordering::Relaxed);
            }
        }
        self.inner.in_position()
    }
    fn estop(&mut self) -> cell::run::device::DeviceResult<bool> {
        self.inner.estop()
    }
}

#[test]
fn fine_and_medium_batches_run_with_the_handshake_and_resume_after_a_stop_mid_program() {
    for mode in [RunMode::Fine, RunMode::Medium, RunMode::Continuous] {
        let l = sbend(Some(mode));
        let b = checked(&l);
        let dir = tempfile::tempdir().unwrap();
        let jp = dir.path().join("SBEND.journal");
        // Whole batch.
        let cell = SimCell::new(&SimCellConfig::default());
        let events = wind(
            &cell,
            &b,
            Journal::create(&jp).unwrap(),
            &ResumePoint::default(),
            true,
            None,
        )
        .unwrap();
        check_each_once(&cell, &b);
        // One program event as each path starts and one as it ends, the paths numbered from 1.
        let items = |done: bool| -> Vec<usize> {
            events
                .iter()
                .filter_map(|e| match e {
                    Event::Program { item, done: d, .. } if *d == done => Some(*item),
                    _ => None,
                })
                .collect()
        };
        let paths: Vec<usize> = (1..=b.items.len()).collect();
        assert_eq!(items(false), paths, "{mode:?}: started");
        assert_eq!(items(true), paths, "{mode:?}: done");
        let t = cell.clock().now_s();
        assert!(t < 120.0, "{mode:?}: {t} s of cell time");
        // Stopped 8 s into the first program, then resumed with the remaining instructions.
        let cell = SimCell::new(&SimCellConfig::default());
        let stop = Arc::new(AtomicBool::new(false));
        let mut d = cell.devices(Drive::default());
        d.sync = Box::new(StopMidProgram {
            inner: d.sync,
            left: None,
            polls: 800,
            flag: stop.clone(),
        });
        let mut sink = |_e: Event| {};
        let mut c = Coordinator::new(d, stop, Journal::create(&jp).unwrap(), &mut sink);
        let stopped = c
            .run(&b, &ResumePoint::default(), true, false, false)
            .unwrap_err();
        drop(c);
        assert!(matches!(stopped.halt, Halt::Interrupted { .. }));
        assert!(stopped.stop_errors.is_empty());
        let (state, instruction) = cell
            .with(|p| {
                let s = p.robot.machine.status();
                (s.state, s.instruction)
            })
            .unwrap();
        assert_ne!(state, State::Running);
        assert!(instruction > 10, "stopped at instruction {instruction}");
        resume(&cell, &b, &jp);
        check_each_once(&cell, &b);
        let recs = journal::read(&jp).unwrap();
        assert!(recs.iter().any(|r| r["rec"] == "resume_program"));
    }
}

trait Sleep {
    fn timebase_sleep(&self, dt: Duration);
}

impl Sleep for SimCell {
    fn timebase_sleep(&self, dt: Duration) {
        use cell::run::device::Timebase;
        self.timebase().sleep(dt);
    }
}

/// A device seen through a PC that can die (`kill -9`): after a number of robot or indexer calls,
/// or at a time of the cell's clock (a stored program runs unwatched, so a death mid-program
/// is a time), every call fails without reaching the device, stop commands included, so the
/// devices run on by themselves.
#[derive(Debug, Clone)]
struct Life {
    calls: Arc<std::sync::atomic::AtomicI64>,
    deadline_s: Arc<std::sync::Mutex<f64>>,
    clock: Option<asea_protocol::clock::VirtualClock>,
}

/// When the coordinator process dies.
#[derive(Debug, Clone, Copy)]
enum Death {
    /// After this many robot or indexer calls.
    Calls(i64),
    /// This long (cell time) after the event.
    After(f64),
}

impl Life {
    /// A life counted in calls only.
    fn new() -> Self {
        Life {
            calls: Arc::new(std::sync::atomic::AtomicI64::new(i64::MAX)),
            deadline_s: Arc::new(std::sync::Mutex::new(f64::INFINITY)),
            clock: None,
        }
    }
    /// A life that can also end at a time of `clock`.
    fn with_clock(clock: asea_protocol::clock::VirtualClock) -> Self {
        Life {
            clock: Some(clock),
            ..Life::new()
        }
    }
    fn die_after(&self, calls: i64) {
        self.die(Death::Calls(calls));
    }
    fn die(&self, death: Death) {
        match death {
            Death::Calls(n) => self.calls.store(n, Ordering::Relaxed),
            Death::After(s) => {
                let now = self.clock.as_ref().expect("a life with a clock").now_s();
                *self.deadline_s.lock().unwrap() = now + s;
            }
        }
    }
    fn gone() -> cell::run::device::DeviceError {
        cell::run::device::DeviceError::RobotState {
            what: "the coordinator process is gone".into(),
        }
    }
    fn past_deadline(&self) -> bool {
        self.clock
            .as_ref()
            .is_some_and(|c| c.now_s() >= *self.deadline_s.lock().unwrap())
    }
    /// A robot or indexer call: counts (the last call allowed brings the count to 0).
    fn alive(&self) -> Result<(), cell::run::device::DeviceError> {
        if self.calls.fetch_sub(1, Ordering::Relaxed) <= 0 || self.past_deadline() {
            return Err(Self::gone());
        }
        Ok(())
    }
    /// A sync-line call: does not count, but a dead process (no call left) makes none.
    fn still(&self) -> Result<(), cell::run::device::DeviceError> {
        if self.calls.load(Ordering::Relaxed) <= 0 || self.past_deadline() {
            return Err(Self::gone());
        }
        Ok(())
    }
}

impl SyncLines for Mortal<Box<dyn SyncLines>> {
    fn set_start(&mut self, on: bool) -> cell::run::device::DeviceResult<()> {
        self.life.still()?;
        self.inner.set_start(on)
    }
    fn in_position(&mut self) -> cell::run::device::DeviceResult<bool> {
        self.life.still()?;
        self.inner.in_position()
    }
    fn estop(&mut self) -> cell::run::device::DeviceResult<bool> {
        self.life.still()?;
        self.inner.estop()
    }
}

impl std::fmt::Debug for Mortal<Box<dyn SyncLines>> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Mortal(sync)")
    }
}

/// Also a robot whose position reads `misread_mm` off in x (a robot that ends its moves off
/// target, as far as the coordinator can tell), and whose status shows error `latch` (0: none),
/// each from the moment `onset` says.
struct Mortal<T> {
    inner: T,
    life: Life,
    misread_mm: f64,
    latch: u8,
    onset: Onset,
}

/// When a [`Mortal`] robot starts to misread its position or show its error.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Onset {
    /// From the start.
    Start,
    /// From its first immediate move.
    Move,
    /// From its first program run.
    Program,
    /// Not yet (set when the event comes).
    Now,
}

impl<T> Mortal<T> {
    fn new(inner: T, life: Life) -> Self {
        Mortal {
            inner,
            life,
            misread_mm: 0.0,
            latch: 0,
            onset: Onset::Start,
        }
    }
    fn on(&self) -> bool {
        matches!(self.onset, Onset::Start | Onset::Now)
    }
    fn event(&mut self, what: Onset) {
        if self.onset == what {
            self.onset = Onset::Now;
        }
    }
}

impl cell::run::device::RobotDevice for Mortal<Box<dyn cell::run::device::RobotDevice>> {
    fn state(&mut self) -> cell::run::device::DeviceResult<cell::run::device::RobotState> {
        self.life.alive()?;
        let mut s = self.inner.state()?;
        if self.on() && self.latch != 0 {
            s.last_error = self.latch;
        }
        Ok(s)
    }
    fn position_mm(&mut self) -> cell::run::device::DeviceResult<[f64; 3]> {
        self.life.alive()?;
        let [x, y, z] = self.inner.position_mm()?;
        let off = if self.on() { self.misread_mm } else { 0.0 };
        Ok([x + off, y, z])
    }
    fn set_speeds(
        &mut self,
        b: asea_protocol::Speed,
        m: asea_protocol::Speed,
    ) -> cell::run::device::DeviceResult<()> {
        self.life.alive()?;
        self.inner.set_speeds(b, m)
    }
    fn set_operate(&mut self, on: bool) -> cell::run::device::DeviceResult<()> {
        self.life.alive()?;
        self.inner.set_operate(on)
    }
    fn start_home(&mut self) -> cell::run::device::DeviceResult<()> {
        self.life.alive()?;
        self.inner.start_home()
    }
    fn move_immediate(
        &mut self,
        p: asea_protocol::Positioning,
    ) -> cell::run::device::DeviceResult<()> {
        self.life.alive()?;
        self.event(Onset::Move);
        self.inner.move_immediate(p)
    }
    fn delete_program(&mut self, p: u8) -> cell::run::device::DeviceResult<()> {
        self.life.alive()?;
        self.inner.delete_program(p)
    }
    fn upload(
        &mut self,
        p: u8,
        i: &[Instruction],
        progress: &mut dyn FnMut(),
    ) -> cell::run::device::DeviceResult<()> {
        self.life.alive()?;
        self.inner.upload(p, i, progress)
    }
    fn read_back(
        &mut self,
        p: u8,
        i: &[Instruction],
        progress: &mut dyn FnMut(),
    ) -> cell::run::device::DeviceResult<()> {
        self.life.alive()?;
        self.inner.read_back(p, i, progress)
    }
    fn run_program(&mut self, p: u8) -> cell::run::device::DeviceResult<()> {
        self.life.alive()?;
        self.event(Onset::Program);
        self.inner.run_program(p)
    }
    fn stop(&mut self) -> cell::run::device::DeviceResult<()> {
        self.life.alive()?;
        self.inner.stop()
    }
}

impl MandrelDevice for Mortal<Box<dyn MandrelDevice>> {
    fn attach(&mut self) -> cell::run::device::DeviceResult<i64> {
        self.life.alive()?;
        self.inner.attach()
    }
    fn zero(&mut self) -> cell::run::device::DeviceResult<()> {
        self.life.alive()?;
        self.inner.zero()
    }
    fn start_move(&mut self, mv: &MandrelMove, armed: bool) -> cell::run::device::DeviceResult<()> {
        self.life.alive()?;
        self.inner.start_move(mv, armed)
    }
    fn busy(&mut self) -> cell::run::device::DeviceResult<(bool, bool)> {
        self.life.alive()?;
        self.inner.busy()
    }
    fn counter_steps(&mut self) -> cell::run::device::DeviceResult<i64> {
        self.life.alive()?;
        self.inner.counter_steps()
    }
    fn move_steps(&mut self) -> cell::run::device::DeviceResult<i64> {
        self.life.alive()?;
        self.inner.move_steps()
    }
    fn stop(&mut self) -> cell::run::device::DeviceResult<()> {
        self.life.alive()?;
        self.inner.stop()
    }
}

/// Winds until the PC "dies" (`death`) after the `at`-th segment or program event; nothing
/// stops the devices.
fn wind_until_killed(cell: &SimCell, b: &Batch, jp: &Path, at: usize, death: Death) {
    let life = Life::with_clock(cell.clock().clone());
    let d = cell.devices(Drive::default());
    let dev = cell::run::coordinator::Devices {
        robot: Box::new(Mortal::new(d.robot, life.clone())),
        mandrel: Box::new(Mortal::new(d.mandrel, life.clone())),
        sync: Box::new(Mortal::new(d.sync, life.clone())),
        time: d.time,
    };
    let mut n = 0;
    let l2 = life.clone();
    let mut sink = |e: Event| {
        if matches!(
            e,
            Event::Segment { .. } | Event::Program { done: false, .. }
        ) {
            n += 1;
            if n == at {
                l2.die(death);
            }
        }
    };
    let stop = Arc::new(AtomicBool::new(false));
    let mut c = Coordinator::new(dev, stop, Journal::create(jp).unwrap(), &mut sink);
    let r = c.run(b, &ResumePoint::default(), true, false, false);
    let stopped = r.unwrap_err();
    assert!(matches!(stopped.halt, Halt::Fault(_)), "{stopped:?}");
}

fn resume(cell: &SimCell, b: &Batch, jp: &Path) {
    let (journal, records) = Journal::resume(jp).unwrap();
    let from = resume_point(b, &records).unwrap();
    wind(cell, b, journal, &from, false, None).unwrap();
}

/// Also resumed at once, with the devices still at it: a program killed mid-run (5 s or 12 s
/// into it; it is checked still running) is let finish (no robot move cut by a STOP), and one
/// killed one call after its RUN_PROGRAM, still waiting at its handshake for the start edge that
/// never came, is cancelled (a STOP that cuts no move) and run again (without that, the resume
/// would wait for a program that cannot end).
#[test]
fn after_kill_9_the_devices_finish_and_resume_completes_without_doubling() {
    for (mode, at, death, run_on_s) in [
        (RunMode::Discrete, 20, Death::Calls(3), 60),
        (RunMode::Fine, 1, Death::After(5.0), 60),
        (RunMode::Medium, 2, Death::After(12.0), 60),
        (RunMode::Fine, 1, Death::After(5.0), 0),
        (RunMode::Fine, 1, Death::Calls(1), 0),
        (RunMode::Continuous, 2, Death::After(9.0), 60),
        (RunMode::Continuous, 1, Death::After(4.0), 0),
    ] {
        let calls = format!("{death:?}");
        let b = checked(&sbend(Some(mode)));
        let dir = tempfile::tempdir().unwrap();
        let jp = dir.path().join("J.journal");
        let cell = SimCell::new(&SimCellConfig::default());
        wind_until_killed(&cell, &b, &jp, at, death);
        if let Death::After(_) = death {
            let s = cell.with(|p| p.robot.machine.status()).unwrap();
            assert_eq!(
                s.state,
                State::Running,
                "{mode:?} {calls}: killed mid-program"
            );
            assert!(s.instruction > 3, "{mode:?} {calls}: {s:?}");
        }
        // Nobody stops the devices: a stored program runs to its end, the indexer finishes.
        cell.timebase_sleep(Duration::from_secs(run_on_s));
        resume(&cell, &b, &jp);
        check_each_once(&cell, &b);
        let (_, _, partial) = completed(&cell);
        assert!(
            partial.is_empty(),
            "{mode:?} {calls} {run_on_s}: a mandrel move was cut: {partial:?}"
        );
        // A STOP that ends the wait at the handshake cuts no move: its record has no target.
        let cut: Vec<[f64; 3]> = cell
            .with(|p| {
                p.log
                    .iter()
                    .filter_map(|r| match r {
                        LogRecord::Robot {
                            completed: false,
                            target_mm,
                            ..
                        } if target_mm.iter().all(|v| v.is_finite()) => Some(*target_mm),
                        _ => None,
                    })
                    .collect()
            })
            .unwrap();
        assert!(
            cut.is_empty(),
            "{mode:?} {calls} {run_on_s}: robot moves cut: {cut:?}"
        );
    }
}

#[test]
fn a_robot_that_stops_answering_stops_the_indexer_and_resume_completes() {
    let b = checked(&sbend(Some(RunMode::Discrete)));
    let dir = tempfile::tempdir().unwrap();
    let jp = dir.path().join("J.journal");
    let cell = SimCell::new(&SimCellConfig::default());
    let c2 = cell.clone();
    let stop = Arc::new(AtomicBool::new(false));
    let mut n = 0;
    let mut sink = |e: Event| {
        if matches!(e, Event::Segment { .. }) {
            n += 1;
            // The 11th segment after the approach: 12 instructions confirmed.
            if n == 11 {
                c2.with(|p| p.robot_silent = true).unwrap();
            }
        }
    };
    let mut c = Coordinator::new(
        cell.devices(Drive::default()),
        stop,
        Journal::create(&jp).unwrap(),
        &mut sink,
    );
    let stopped = c
        .run(&b, &ResumePoint::default(), true, false, false)
        .unwrap_err();
    drop(c);
    // The robot's link gave up: the fault keeps the robot's error.
    assert!(
        matches!(
            stopped.halt.fault().and_then(Fault::device_error),
            Some(DeviceError::Robot(_))
        ),
        "{stopped:?}"
    );
    assert_eq!(stopped.segments_done, 12);
    // The indexer was told to stop (its stop went through; the robot's could not).
    assert_eq!(stopped.stop_errors.len(), 1, "{:?}", stopped.stop_errors);
    cell.timebase_sleep(Duration::from_secs(5));
    assert!(!cell.with(|p| p.card.machine().is_moving()).unwrap());
    cell.with(|p| p.robot_silent = false).unwrap();
    resume(&cell, &b, &jp);
    let (robot, _, _) = completed(&cell);
    assert_eq!(robot.len(), expected_targets(&b).len());
}

#[test]
fn an_indexer_stall_stops_the_robot_and_resume_completes() {
    let b = checked(&sbend(Some(RunMode::Discrete)));
    let dir = tempfile::tempdir().unwrap();
    let jp = dir.path().join("J.journal");
    let cell = SimCell::new(&SimCellConfig::default());
    let c2 = cell.clone();
    let stop = Arc::new(AtomicBool::new(false));
    let mut n = 0;
    let mut sink = |e: Event| {
        if matches!(e, Event::Segment { .. }) {
            n += 1;
            if n == 7 {
                // The motor can no longer pull in at the start/stop velocity.
                c2.with(|p| p.card.machine.pull_in_sps = 1.0).unwrap();
            }
        }
    };
    let mut c = Coordinator::new(
        cell.devices(Drive::default()),
        stop,
        Journal::create(&jp).unwrap(),
        &mut sink,
    );
    let stopped = c
        .run(&b, &ResumePoint::default(), true, false, false)
        .unwrap_err();
    drop(c);
    // The indexer's stall, kept as the indexer's own error.
    assert!(
        stopped.halt.fault().is_some_and(Fault::is_stall),
        "{stopped:?}"
    );
    assert!(stopped.halt.reason().contains("stall"), "{stopped:?}");
    assert!(stopped.stop_errors.is_empty());
    assert_ne!(
        cell.with(|p| p.robot.machine.status().state).unwrap(),
        State::Running
    );
    cell.with(|p| p.card.machine.pull_in_sps = mandrel_drive::sim::machine::PULL_IN_SPS)
        .unwrap();
    // The stall's counter counted steps the motor never made: it is no witness, and the resume
    // stops before anything turns, saying how to re-reference the mandrel.
    let (journal, records) = Journal::resume(&jp).unwrap();
    let from = resume_point(&b, &records).unwrap();
    assert!(from.stalled);
    let refused = wind(&cell, &b, journal, &from, false, None).unwrap_err();
    assert!(
        matches!(
            refused.halt.fault(),
            Some(Fault::MandrelUnreferenced {
                cause: cell::run::coordinator::Disagreement::Stalled,
                ..
            })
        ),
        "{refused:?}"
    );
    assert!(
        refused.halt.reason().contains("--rereference"),
        "{refused:?}"
    );
    // The operator turns the mandrel to the last confirmed step and confirms: the counter is
    // re-referenced to that step's destination (the path's sync plus the plan's steps of the
    // confirmed segments) and the batch completes.
    let (journal, records) = Journal::resume(&jp).unwrap();
    let from = ResumePoint {
        rereference: true,
        ..resume_point(&b, &records).unwrap()
    };
    let confirmed = from.sync_counter.unwrap() + plan_steps(&b, 0, from.segments_done);
    wind(&cell, &b, journal, &from, false, None).unwrap();
    let recs = journal::read(&jp).unwrap();
    let re = recs.iter().find(|r| r["rec"] == "rereference").unwrap();
    assert_eq!(re["counter"].as_i64(), Some(confirmed));
    assert_eq!(
        re["offset"].as_i64(),
        Some(re["counter_before"].as_i64().unwrap() - confirmed)
    );
    assert_eq!(recs.last().unwrap()["rec"], "done");
}

#[test]
fn a_nak_storm_stops_the_indexer_the_robot_comes_to_rest_and_resume_completes() {
    for (mode, at) in [(RunMode::Discrete, 9), (RunMode::Fine, 1)] {
        let b = checked(&sbend(Some(mode)));
        let dir = tempfile::tempdir().unwrap();
        let jp = dir.path().join("J.journal");
        let cell = SimCell::new(&SimCellConfig::default());
        let c2 = cell.clone();
        let stop = Arc::new(AtomicBool::new(false));
        let mut n = 0;
        let mut sink = |e: Event| {
            if matches!(
                e,
                Event::Segment { .. } | Event::Program { done: false, .. }
            ) {
                n += 1;
                if n == at {
                    // From now on the robot computer's every ACK arrives as NAK.
                    c2.with(|p| p.robot_nak_storm = true).unwrap();
                }
            }
        };
        let mut c = Coordinator::new(
            cell.devices(Drive::default()),
            stop,
            Journal::create(&jp).unwrap(),
            &mut sink,
        );
        let stopped = c
            .run(&b, &ResumePoint::default(), true, false, false)
            .unwrap_err();
        drop(c);
        assert!(
            matches!(
                stopped.halt.fault().and_then(Fault::device_error),
                Some(DeviceError::Robot(_))
            ),
            "{mode:?}: {stopped:?}"
        );
        // The indexer's stop went through; the robot's STOP could not pass the storm.
        assert_eq!(stopped.stop_errors.len(), 1, "{:?}", stopped.stop_errors);
        assert!(matches!(*stopped.stop_errors[0], DeviceError::Robot(_)));
        // The journal is intact: whole records, the last one the stop.
        let recs = journal::read(&jp).unwrap();
        assert_eq!(recs.last().unwrap()["rec"], "stopped");
        // Both axes come to rest: the indexer stopped, the robot ends its move or program.
        cell.timebase_sleep(Duration::from_secs(60));
        assert!(!cell.with(|p| p.card.machine().is_moving()).unwrap());
        assert_ne!(
            cell.with(|p| p.robot.machine.status().state).unwrap(),
            State::Running
        );
        cell.with(|p| p.robot_nak_storm = false).unwrap();
        resume(&cell, &b, &jp);
        check_each_once(&cell, &b);
    }
}

#[test]
fn a_stop_request_stops_both_devices_with_its_reason_and_resume_completes() {
    let b = checked(&sbend(Some(RunMode::Discrete)));
    let dir = tempfile::tempdir().unwrap();
    let jp = dir.path().join("J.journal");
    let cell = SimCell::new(&SimCellConfig::default());
    let dev = cell.devices(Drive::default());
    let request = cell::run::coordinator::StopRequest::new(&dev);
    let r2 = request.clone();
    let mut n = 0;
    let mut sink = |e: Event| {
        if matches!(e, Event::Segment { .. }) {
            n += 1;
            // The 16th segment after the approach: 17 instructions confirmed.
            if n == 16 {
                // What the Ctrl-C handler does: the next exchange on either link is abandoned.
                r2.request("Ctrl-C");
            }
        }
    };
    let mut c = Coordinator::with_stop(dev, request, Journal::create(&jp).unwrap(), &mut sink);
    let stopped = c
        .run(&b, &ResumePoint::default(), true, false, false)
        .unwrap_err();
    // The links are usable after the stop: the cancel tokens were cleared.
    let mut d = c.into_devices();
    assert_eq!(d.robot.state().unwrap().state, State::Stopped);
    assert!(!d.mandrel.busy().unwrap().0);
    drop(d);
    assert!(
        matches!(&stopped.halt, Halt::Interrupted { reason } if reason == "Ctrl-C"),
        "{:?}",
        stopped.halt
    );
    assert_eq!(stopped.segments_done, 17);
    assert!(stopped.stop_errors.is_empty(), "{:?}", stopped.stop_errors);
    assert!(!cell.with(|p| p.card.machine().is_moving()).unwrap());
    assert_ne!(
        cell.with(|p| p.robot.machine.status().state).unwrap(),
        State::Running
    );
    resume(&cell, &b, &jp);
    check_each_once(&cell, &b);
}

#[test]
fn an_interrupted_link_refuses_its_exchanges_but_the_stops_go_through() {
    let cell = SimCell::new(&SimCellConfig::default());
    let mut d = cell.devices(Drive::default());
    d.mandrel.attach().unwrap();
    let interrupters = d.interrupters();
    assert_eq!(interrupters.len(), 2);
    for i in &interrupters {
        i.interrupt();
    }
    assert!(cell::run::device::is_interrupted(
        &d.robot.state().unwrap_err()
    ));
    assert!(cell::run::device::is_interrupted(
        &d.mandrel.busy().unwrap_err()
    ));
    // The stops pass a cancelled link (what the coordinator sends after a stop request).
    d.mandrel.stop().unwrap();
    d.robot.stop().unwrap();
    for i in &interrupters {
        i.clear();
    }
    assert_eq!(d.robot.state().unwrap().state, State::Stopped);
    assert!(!d.mandrel.busy().unwrap().0);
}

/// The simulated cell polls its devices only when something can change (a move's end, a byte,
/// an edge, a link timer). Polled besides at every `TICK` (as it is while an observer watches),
/// the same batch gives the same moves in the same order, and each within a few ticks of the
/// same time: the events a tick would find late are found on time.
#[test]
fn event_driven_polling_winds_as_polling_every_tick_does() {
    let l = sbend(Some(RunMode::Fine));
    let b = checked(&l);
    let dir = tempfile::tempdir().unwrap();
    let run = |ticked: bool| {
        let cell = SimCell::new(&SimCellConfig::default());
        if ticked {
            cell.with(|p| p.observer = Some(cell::sim::Observer(Box::new(|_| {}))))
                .unwrap();
        }
        let jp = dir.path().join(format!("SBEND{ticked}.journal"));
        wind(
            &cell,
            &b,
            Journal::create(&jp).unwrap(),
            &ResumePoint::default(),
            true,
            None,
        )
        .unwrap();
        let log = cell.with(|p| p.log.clone()).unwrap();
        (log, cell.clock().now_s())
    };
    let (evented, evented_end) = run(false);
    let (ticked, ticked_end) = run(true);
    assert_eq!(evented.len(), ticked.len());
    let t = |r: &LogRecord| match r {
        LogRecord::Robot { t_s, .. } | LogRecord::Indexer { t_s, .. } => *t_s,
    };
    let mut worst: f64 = 0.0;
    for (e, k) in evented.iter().zip(&ticked) {
        match (e, k) {
            (
                LogRecord::Robot {
                    program: p1,
                    instruction: i1,
                    target_mm: m1,
                    completed: c1,
                    ..
                },
                LogRecord::Robot {
                    program: p2,
                    instruction: i2,
                    target_mm: m2,
                    completed: c2,
                    ..
                },
            ) => assert_eq!((p1, i1, m1, c1), (p2, i2, m2, c2)),
            (
                LogRecord::Indexer {
                    steps: s1,
                    completed: c1,
                    ..
                },
                LogRecord::Indexer {
                    steps: s2,
                    completed: c2,
                    ..
                },
            ) => assert_eq!((s1, c1), (s2, c2)),
            _ => panic!("{e:?} vs {k:?}"),
        }
        worst = worst.max((t(e) - t(k)).abs());
    }
    eprintln!(
        "{} records, worst time difference {worst:.4} s, ends {evented_end:.3} vs {ticked_end:.3} s",
        evented.len()
    );
    assert!(worst < 0.05, "worst time difference {worst} s");
}

/// Manual control (seed 001 §5.3.2): a relative jog adds its offset to the robot's position on
/// every axis and its steps to the indexer's counter, and its wrist (App. A pitch 30°, in the
/// arm's vertical plane) is turned by the base yaw to face the target: the roll axis keeps its
/// elevation and its horizontal part points along the target's (x, y). The jog's target is held to the working
/// range with every bound inclusive: with the range shrunk to one point (radius and height both
/// exactly those of the robot's home pose) a jog to that point is taken, and one LSB (0.0625 mm)
/// beyond any of the four bounds is refused before anything moves.
#[test]
fn a_relative_jog_adds_its_offset_on_every_axis_and_the_reach_bounds_are_inclusive() {
    use asea_protocol::{Flags, Pose, Positioning, Speed, Zone};
    let cell = SimCell::new(&SimCellConfig::default());
    let mut dev = cell.devices(Drive::default());
    let counter0 = dev.mandrel.attach().unwrap();
    let home = dev.robot.position_mm().unwrap();
    let mut sink = |_e: Event| {};
    let mut c = Coordinator::new(
        dev,
        Arc::new(AtomicBool::new(false)),
        Journal::none(),
        &mut sink,
    );
    let speeds = (
        Speed::from_value("base", 1.0).unwrap(),
        Speed::from_value("max", 2.0).unwrap(),
    );
    let pitched = paths::wrist::from_pitch_roll(30f64.to_radians(), 0.0);
    let with = |xyz: [f64; 3], q: [f64; 4]| Positioning {
        flags: Flags {
            zone: Zone::Fine,
            ..Flags::default()
        },
        pose: Pose::from_mm(xyz, q).unwrap(),
        speed: Speed::from_value("speed", 0.1).unwrap(),
    };
    let at = |xyz: [f64; 3]| with(xyz, [1.0, 0.0, 0.0, 0.0]);
    let steps = 120;
    let mandrel = MandrelMove {
        accel_rps2: 1.0,
        start_stop_rps: 0.05,
        max_rps: 0.1,
        steps,
    };
    let offset = [30.0, -40.0, 50.0];
    let (pos, counter) = c
        .jog(
            speeds,
            with(offset, paths::wrist::components(&pitched)),
            true,
            Some(mandrel),
            Reach::default(),
        )
        .unwrap();
    let want = [home[0] + 30.0, home[1] - 40.0, home[2] + 50.0];
    assert!(
        (0..3).all(|i| (pos[i] - want[i]).abs() <= 0.0625),
        "{pos:?} against {want:?}"
    );
    assert_eq!(counter, counter0 + steps);
    let [w, x, y, z] = cell.with(|p| p.robot.machine.pose().q).unwrap();
    let roll = nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(w, x, y, z))
        * nalgebra::Vector3::x();
    let wanted = pitched * nalgebra::Vector3::x();
    assert!(
        (roll.z - wanted.z).abs() < 2e-3,
        "{roll:?} against {wanted:?}"
    );
    let across = roll.x * want[1] - roll.y * want[0];
    let along = roll.x * want[0] + roll.y * want[1];
    assert!(
        across.abs() < 2e-3 * want[0].hypot(want[1]) && along > 0.0,
        "{roll:?} at {want:?}"
    );

    // The range shrunk to the home pose's radius and height (home is on the x axis).
    assert_eq!(home[1], 0.0);
    let point = Reach {
        max_radius_mm: home[0],
        min_radius_mm: home[0],
        z_range_mm: (home[2], home[2]),
        arm: None,
    };
    let (pos, _) = c.jog(speeds, at(home), false, None, point).unwrap();
    assert!(
        (0..3).all(|i| (pos[i] - home[i]).abs() <= 0.0625),
        "{pos:?}"
    );
    let lsb = 0.0625;
    for outside in [
        [home[0] + lsb, 0.0, home[2]],
        [home[0] - lsb, 0.0, home[2]],
        [home[0], 0.0, home[2] + lsb],
        [home[0], 0.0, home[2] - lsb],
    ] {
        let e = c.jog(speeds, at(outside), false, None, point).unwrap_err();
        assert!(
            matches!(&e.halt, Halt::Fault(Fault::OutOfReach { eye_mm })
                if (0..3).all(|i| (eye_mm[i] - outside[i]).abs() <= 0.0625)),
            "{outside:?}: {:?}",
            e.halt
        );
    }
    drop(c);
    let robot = cell.with(|p| p.robot.machine.pose().xyz_mm).unwrap();
    assert!(
        (0..3).all(|i| (robot[i] - home[i]).abs() <= 0.0625),
        "the refused jogs moved the robot to {robot:?}"
    );
}

/// A cell without sync lines (`NoSync`: robot and indexer on their serial links only, as over
/// two pseudo-terminals) winds a discrete batch: each immediate move is awaited by polling the
/// robot's state until it leaves RUNNING, then confirmed idle at its target. Every target is
/// reached once, in order, with one segment event each after the approach (instruction 1),
/// numbered from 1 within its path as the plan numbers them.
#[test]
fn discrete_batch_on_a_cell_without_sync_lines_winds_every_segment_once() {
    let b = checked(&sbend(Some(RunMode::Discrete)));
    let cell = SimCell::new(&SimCellConfig::default());
    let mut dev = cell.devices(Drive::default());
    dev.sync = Box::new(cell::run::device::NoSync);
    let mut events = Vec::new();
    let mut sink = |e: Event| {
        if let Event::Segment {
            item,
            segment,
            segments,
            ..
        } = e
        {
            events.push((item, segment, segments));
        }
    };
    let mut c = Coordinator::new(
        dev,
        Arc::new(AtomicBool::new(false)),
        Journal::none(),
        &mut sink,
    );
    c.run(&b, &ResumePoint::default(), true, false, false)
        .unwrap();
    drop(c);
    check_each_once(&cell, &b);
    // One event per plan segment (the S-bend's paths have 50, `plan` says so), numbered from 1
    // within each path, paths numbered from 1.
    let want: Vec<(usize, usize, usize)> = (1..=2)
        .flat_map(|i| (1..=50).map(move |s| (i, s, 50)))
        .collect();
    assert_eq!(events, want);
}

/// Program mode tells the truth about its progress: the phases in order (homing, the upload,
/// each path's approach and its winding); upload events that rise to
/// three exchanges per stored instruction (store, verify, read back) of the two handshake
/// programs (App. D: two control instructions before the positions, two after); and segment
/// events 1..50 per path, in order, each only once the simulated card's counter has passed
/// that segment's end (the plan's steps from the path's start), within the program's run.
#[test]
fn program_mode_reports_phases_upload_and_every_segment_from_the_indexer() {
    use cell::run::coordinator::{Phase, Witness};
    let b = checked(&sbend(Some(RunMode::Fine)));
    let cell = SimCell::new(&SimCellConfig::default());
    // Each event with the card's counter at the moment it was reported.
    let mut seen: Vec<(Event, i64)> = Vec::new();
    let mut sink = |e: Event| {
        let counter = cell.with(|p| p.card.machine().counter_steps()).unwrap();
        seen.push((e, counter));
    };
    let mut c = Coordinator::new(
        cell.devices(Drive::default()),
        Arc::new(AtomicBool::new(false)),
        Journal::none(),
        &mut sink,
    );
    c.run(&b, &ResumePoint::default(), true, false, false)
        .unwrap();
    drop(c);
    check_each_once(&cell, &b);
    let phases: Vec<Phase> = seen
        .iter()
        .filter_map(|(e, _)| match e {
            Event::Phase { phase, .. } => Some(*phase),
            _ => None,
        })
        .collect();
    assert_eq!(
        phases,
        [
            Phase::Homing,
            Phase::Upload,
            Phase::Approach { item: 1 },
            Phase::Winding { item: 1 },
            Phase::Approach { item: 2 },
            Phase::Winding { item: 2 },
        ]
    );
    // The upload: between its phase and the first approach, rising to its total.
    let total: usize = b
        .items
        .iter()
        .map(|i| 3 * (i.rob.instructions.len() + 4))
        .sum();
    let upload_at = seen
        .iter()
        .position(|(e, _)| {
            matches!(
                e,
                Event::Phase {
                    phase: Phase::Upload,
                    ..
                }
            )
        })
        .unwrap();
    let approach_at = seen
        .iter()
        .position(|(e, _)| {
            matches!(
                e,
                Event::Phase {
                    phase: Phase::Approach { .. },
                    ..
                }
            )
        })
        .unwrap();
    let uploads: Vec<(usize, usize, usize)> = seen
        .iter()
        .enumerate()
        .filter_map(|(at, (e, _))| match e {
            Event::Upload { done, total, .. } => Some((at, *done, *total)),
            _ => None,
        })
        .collect();
    assert!(uploads.len() >= 50, "{} upload events", uploads.len());
    assert!(
        uploads
            .iter()
            .all(|&(at, _, t)| at > upload_at && at < approach_at && t == total)
    );
    assert!(uploads.windows(2).all(|w| w[1].1 > w[0].1));
    assert_eq!(uploads.last().unwrap().1, total);
    // Segments: per path 1..50 in order, between the program's start and its end, never before
    // the card has passed the segment's end.
    for (k, item) in b.items.iter().enumerate() {
        let start = seen
            .iter()
            .position(
                |(e, _)| matches!(e, Event::Program { item, done: false, .. } if *item == k + 1),
            )
            .unwrap();
        let end = seen
            .iter()
            .position(
                |(e, _)| matches!(e, Event::Program { item, done: true, .. } if *item == k + 1),
            )
            .unwrap();
        let sync = seen[start].1;
        let path_steps = plan_steps(&b, k, item.rob.instructions.len());
        let direction = path_steps.signum();
        assert_ne!(direction, 0);
        let mut numbers = Vec::new();
        let mut by_indexer = 0;
        for (at, (e, counter)) in seen.iter().enumerate() {
            if let Event::Segment {
                item: i,
                segment,
                segments,
                witness,
                ..
            } = e
                && *i == k + 1
            {
                assert!(
                    at > start && at < end,
                    "segment {segment} outside its program"
                );
                assert_eq!(*segments, 50);
                // Segment s is instruction s + 1: its end is the steps of instructions 1..=s+1.
                let end_steps = sync + plan_steps(&b, k, segment + 1);
                assert!(
                    direction * (counter - end_steps) >= 0,
                    "path {} segment {segment} reported at counter {counter}, its end is {end_steps}",
                    k + 1
                );
                by_indexer += usize::from(*witness == Witness::Indexer);
                numbers.push(*segment);
            }
        }
        assert_eq!(numbers, (1..=50).collect::<Vec<_>>(), "path {}", k + 1);
        // Most are seen while the program runs, not all at its end.
        assert!(
            by_indexer >= 40,
            "path {}: {by_indexer} by the indexer",
            k + 1
        );
    }
}

/// After each immediate move the coordinator reads the robot's position back: a robot that
/// reads more than `POSITION_TOLERANCE_MM` (0.125 mm) off its target halts the batch with a
/// fault naming the distance before anything else is sent; one that reads within it winds on.
#[test]
fn a_robot_that_ends_a_move_off_its_target_halts_the_batch() {
    let b = checked(&sbend(Some(RunMode::Discrete)));
    for (misread_mm, halts) in [(0.2, true), (0.1, false)] {
        let cell = SimCell::new(&SimCellConfig::default());
        let r = wind_with(&cell, &b, |r| Mortal {
            misread_mm,
            ..Mortal::new(r, Life::new())
        });
        if halts {
            let stopped = r.unwrap_err();
            assert!(
                matches!(&stopped.halt, Halt::Fault(Fault::OffTarget { off_mm, .. }) if (off_mm - 0.20).abs() < 0.005),
                "{:?}",
                stopped.halt
            );
            assert_eq!(stopped.segments_done, 0);
            let (robot, _, _) = completed(&cell);
            assert_eq!(robot.len(), 1, "one move, then the halt: {robot:?}");
        } else {
            r.unwrap();
            check_each_once(&cell, &b);
        }
    }
}

/// Sync mandrel to robot (seed 001 §5.6.4): the mandrel turns to the path's start angle
/// (`sync_mandrel_deg`) by the shorter way, to the counter nearest its own among those that put
/// the mandrel at that angle (`angle / 360° · steps per revolution + k · steps per revolution`).
/// From counter 0: 90° is a quarter turn forward, 300° a sixth of a turn back.
#[test]
fn the_sync_turns_the_mandrel_to_the_start_angle_by_the_shorter_way() {
    let per_rev = Drive::default().steps_per_mandrel_rev();
    for deg in [90.0, 300.0] {
        let mut l = sbend(Some(RunMode::Discrete));
        l.items[0].rob.header.sync_mandrel_deg = deg;
        let b = checked(&l);
        let dir = tempfile::tempdir().unwrap();
        let jp = dir.path().join("J.journal");
        let cell = SimCell::new(&SimCellConfig::default());
        wind(
            &cell,
            &b,
            Journal::create(&jp).unwrap(),
            &ResumePoint::default(),
            true,
            Some(1),
        )
        .unwrap_err();
        let (_, records) = Journal::resume(&jp).unwrap();
        let sync = records
            .iter()
            .find(|r| r["rec"] == "sync")
            .and_then(|r| r["counter"].as_i64())
            .unwrap();
        let nearest = (-2..=2)
            .map(|k| deg / 360.0 * per_rev + f64::from(k) * per_rev)
            .min_by(|a, c| a.abs().total_cmp(&c.abs()))
            .unwrap()
            .round() as i64;
        assert_eq!(sync, nearest, "{deg}°");
        let (_, done, _) = completed(&cell);
        assert_eq!(done.first(), Some(&nearest), "{deg}°: the sync move");
    }
}

/// Runs `b` fresh on `cell` through `robot` (a wrapper around the cell's robot: a [`Mortal`],
/// a [`Watched`]); the result.
fn wind_with<R: cell::run::device::RobotDevice + 'static>(
    cell: &SimCell,
    b: &Batch,
    robot: impl FnOnce(Box<dyn cell::run::device::RobotDevice>) -> R,
) -> Result<(), cell::run::coordinator::Stopped> {
    let d = cell.devices(Drive::default());
    let dev = cell::run::coordinator::Devices {
        robot: Box::new(robot(d.robot)),
        mandrel: d.mandrel,
        sync: d.sync,
        time: d.time,
    };
    let mut sink = |_e: Event| {};
    let mut c = Coordinator::new(
        dev,
        Arc::new(AtomicBool::new(false)),
        Journal::none(),
        &mut sink,
    );
    c.run(b, &ResumePoint::default(), true, false, false)
}

/// After an immediate move the robot must be idle with no error: one at rest, idle but showing
/// error 3 (a telegram refused during the move), halts the batch after that move, naming the
/// error.
#[test]
fn a_robot_idle_with_an_error_after_a_move_halts_the_batch() {
    let b = checked(&sbend(Some(RunMode::Discrete)));
    let cell = SimCell::new(&SimCellConfig::default());
    let stopped = wind_with(&cell, &b, |r| Mortal {
        latch: 3,
        onset: Onset::Move,
        ..Mortal::new(r, Life::new())
    })
    .unwrap_err();
    assert!(
        matches!(
            &stopped.halt,
            Halt::Fault(Fault::NotIdleAfterMove {
                state: State::Idle,
                error: 3
            })
        ),
        "{:?}",
        stopped.halt
    );
    assert_eq!(stopped.segments_done, 0);
    let (robot, _, _) = completed(&cell);
    assert_eq!(robot.len(), 1, "one move, then the halt: {robot:?}");
}

/// In program mode the coordinator reads the robot's status when the program ends (and, once
/// it overruns its quiet time, every 50 polls of "in position"): an error code shown during
/// the program (a telegram refused while it ran) halts the batch there, naming the error and
/// the instruction, before the next path's approach.
#[test]
fn an_error_shown_while_a_program_runs_halts_the_batch() {
    let b = checked(&sbend(Some(RunMode::Fine)));
    let cell = SimCell::new(&SimCellConfig::default());
    let stopped = wind_with(&cell, &b, |r| Mortal {
        latch: 3,
        onset: Onset::Program,
        ..Mortal::new(r, Life::new())
    })
    .unwrap_err();
    assert!(
        matches!(
            &stopped.halt,
            Halt::Fault(Fault::ProgramError { error: 3, .. })
        ),
        "{:?}",
        stopped.halt
    );
}

/// A program must end on its path's last point: a robot whose position reads 0.2 mm off (more
/// than `POSITION_TOLERANCE_MM`, 0.125 mm) once its program has run halts the batch at the
/// program's end, naming the distance.
#[test]
fn a_program_that_ends_off_its_last_point_halts_the_batch() {
    let b = checked(&sbend(Some(RunMode::Fine)));
    let cell = SimCell::new(&SimCellConfig::default());
    let stopped = wind_with(&cell, &b, |r| Mortal {
        misread_mm: 0.2,
        onset: Onset::Program,
        ..Mortal::new(r, Life::new())
    })
    .unwrap_err();
    assert!(
        matches!(&stopped.halt, Halt::Fault(Fault::ProgramEndedOff { program: 1, off_mm }) if (off_mm - 0.20).abs() < 0.005),
        "{:?}",
        stopped.halt
    );
}

/// The second path's sync starts where the first path left the mandrel: it turns to the
/// counter nearest that one among those at the path's start angle (`angle / 360° · steps per
/// revolution + k · steps per revolution`), worked out here from the journal's last segment.
#[test]
fn the_second_paths_sync_starts_from_where_the_first_left_the_mandrel() {
    let per_rev = Drive::default().steps_per_mandrel_rev();
    let mut l = sbend(Some(RunMode::Discrete));
    assert!(
        l.items.len() >= 2,
        "the example has {} paths",
        l.items.len()
    );
    let deg = 90.0;
    l.items[1].rob.header.sync_mandrel_deg = deg;
    let b = checked(&l);
    let first = b.items[0].rob.instructions.len();
    let dir = tempfile::tempdir().unwrap();
    let jp = dir.path().join("J.journal");
    let cell = SimCell::new(&SimCellConfig::default());
    wind(
        &cell,
        &b,
        Journal::create(&jp).unwrap(),
        &ResumePoint::default(),
        true,
        Some(first + 1),
    )
    .unwrap_err();
    let (_, records) = Journal::resume(&jp).unwrap();
    let at = records
        .iter()
        .position(|r| r["rec"] == "sync" && r["item"] == 1)
        .expect("the second path's sync");
    let before = records[..at]
        .iter()
        .rev()
        .find(|r| r["rec"] == "segment")
        .and_then(|r| r["counter"].as_i64())
        .unwrap();
    assert_ne!(before, 0, "the first path turned the mandrel");
    let nearest = (-20..=20)
        .map(|k| deg / 360.0 * per_rev + f64::from(k) * per_rev)
        .min_by(|a, c| {
            (a - before as f64)
                .abs()
                .total_cmp(&(c - before as f64).abs())
        })
        .unwrap()
        .round() as i64;
    assert_eq!(
        records[at]["counter"].as_i64(),
        Some(nearest),
        "from {before}"
    );
}

/// Killed while a program ran (5 s into it), the devices left to finish it: on resume the robot is at the
/// path's last point and the mandrel's counter at the path's end, so that path is done and
/// nothing of it is sent again (no sync, no program, no resume program for it).
#[test]
fn a_program_that_finished_after_a_kill_is_not_run_again_on_resume() {
    let b = checked(&sbend(Some(RunMode::Fine)));
    let dir = tempfile::tempdir().unwrap();
    let jp = dir.path().join("J.journal");
    let cell = SimCell::new(&SimCellConfig::default());
    wind_until_killed(&cell, &b, &jp, 1, Death::After(5.0));
    cell.timebase_sleep(Duration::from_secs(60));
    resume(&cell, &b, &jp);
    check_each_once(&cell, &b);
    let recs = journal::read(&jp).unwrap();
    let resumed = recs.iter().rposition(|r| r["rec"] == "resume").unwrap();
    let again: Vec<_> = recs[resumed..]
        .iter()
        .filter(|r| {
            ["sync", "program", "resume_program"].contains(&r["rec"].as_str().unwrap_or(""))
                && r["item"] == 0
        })
        .collect();
    assert!(again.is_empty(), "{again:?}");
    assert!(
        recs[resumed..]
            .iter()
            .any(|r| r["rec"] == "item_done" && r["item"] == 1)
    );
}

/// Sync lines that stop working with the PC (`kill -9`): the start output is a call like any.
#[derive(Debug)]
struct MortalStart {
    inner: Box<dyn SyncLines>,
    life: Life,
}

impl SyncLines for MortalStart {
    fn set_start(&mut self, on: bool) -> cell::run::device::DeviceResult<()> {
        self.life.alive()?;
        self.inner.set_start(on)
    }
    fn in_position(&mut self) -> cell::run::device::DeviceResult<bool> {
        // A dead PC reads no input either (the count is not used up by reading).
        self.life.still()?;
        self.inner.in_position()
    }
    fn estop(&mut self) -> cell::run::device::DeviceResult<bool> {
        self.inner.estop()
    }
}

/// Winds `b` in program mode until the PC "dies" `calls` device calls after the first program's
/// event (the sync lines' start output counts as a call); nothing stops the devices.
fn killed_after_the_first_program_event(cell: &SimCell, b: &Batch, jp: &Path, calls: i64) {
    let life = Life::new();
    let d = cell.devices(Drive::default());
    let dev = cell::run::coordinator::Devices {
        robot: Box::new(Mortal::new(d.robot, life.clone())),
        mandrel: Box::new(Mortal::new(d.mandrel, life.clone())),
        sync: Box::new(MortalStart {
            inner: d.sync,
            life: life.clone(),
        }),
        time: d.time,
    };
    let mut sink = |e: Event| {
        if matches!(e, Event::Program { done: false, .. }) {
            life.die_after(calls);
        }
    };
    let mut c = Coordinator::new(
        dev,
        Arc::new(AtomicBool::new(false)),
        Journal::create(jp).unwrap(),
        &mut sink,
    );
    c.run(b, &ResumePoint::default(), true, false, false)
        .unwrap_err();
}

/// Killed after the program started and the mandrel's move was armed on the start line, before
/// the start edge; then the robot is stopped at its own controls. On resume the robot is not
/// waiting at the handshake (whose cancel would stop the indexer too), but the indexer still
/// holds the armed move, which never turned and holds its command buffer: it is cancelled
/// before the attach asks for the counter, and the path is wound again, every target once.
#[test]
fn an_armed_mandrel_move_that_never_started_is_cancelled_on_resume() {
    let b = checked(&sbend(Some(RunMode::Fine)));
    let dir = tempfile::tempdir().unwrap();
    let jp = dir.path().join("J.journal");
    let cell = SimCell::new(&SimCellConfig::default());
    // After the first program's event: RUN_PROGRAM and the armed move go out, the start edge
    // does not.
    killed_after_the_first_program_event(&cell, &b, &jp, 2);
    cell.timebase_sleep(Duration::from_secs(5));
    // The operator stops the robot at its controls (a STOP telegram's effect).
    let stop = asea_protocol::Frame {
        code: 0x0C,
        data: Vec::new(),
    };
    let now = cell.clock().now_s();
    cell.with(|p| p.robot.machine.execute(&stop, now)).unwrap();
    resume(&cell, &b, &jp);
    check_each_once(&cell, &b);
}

/// The run's first event says whether it resumes a journal: not for a fresh batch, and so for
/// the run that resumes it.
#[test]
fn the_started_event_says_whether_the_run_resumes() {
    let b = checked(&sbend(Some(RunMode::Discrete)));
    let dir = tempfile::tempdir().unwrap();
    let jp = dir.path().join("J.journal");
    let cell = SimCell::new(&SimCellConfig::default());
    let resumed = |events: &[Event]| match events.first() {
        Some(Event::Started { resumed, .. }) => *resumed,
        e => panic!("the first event: {e:?}"),
    };
    let mut events = Vec::new();
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    let mut sink = |e: Event| {
        if matches!(e, Event::Segment { .. }) {
            flag.store(true, Ordering::Relaxed);
        }
        events.push(e);
    };
    let mut c = Coordinator::new(
        cell.devices(Drive::default()),
        stop,
        Journal::create(&jp).unwrap(),
        &mut sink,
    );
    c.run(&b, &ResumePoint::default(), true, false, false)
        .unwrap_err();
    drop(c);
    assert!(!resumed(&events));
    let (journal, records) = Journal::resume(&jp).unwrap();
    let from = resume_point(&b, &records).unwrap();
    let events = wind(&cell, &b, journal, &from, false, None).unwrap();
    assert!(resumed(&events));
}

/// Killed just after the first program's start edge; the indexer is then stopped at its own
/// controls (its move cut short) while the robot runs its program to the end. On resume the
/// robot is at the path's last point but the mandrel is short of the path's end: the path is
/// not done, and the rest of the mandrel's turn goes out with a resume program (a path is done
/// only when both the robot and the mandrel are at its end).
#[test]
fn a_program_the_robot_finished_but_the_mandrel_did_not_is_resumed() {
    let b = checked(&sbend(Some(RunMode::Fine)));
    let dir = tempfile::tempdir().unwrap();
    let jp = dir.path().join("J.journal");
    let cell = SimCell::new(&SimCellConfig::default());
    let life = Life::new();
    let d = cell.devices(Drive::default());
    let dev = cell::run::coordinator::Devices {
        robot: Box::new(Mortal::new(d.robot, life.clone())),
        mandrel: Box::new(Mortal::new(d.mandrel, life.clone())),
        sync: Box::new(MortalStart {
            inner: d.sync,
            life: life.clone(),
        }),
        time: d.time,
    };
    let l2 = life.clone();
    let mut once = false;
    // After the first program's event: RUN_PROGRAM, the armed move and the start edge go out,
    // then the PC is gone.
    let mut sink = |e: Event| {
        if matches!(e, Event::Program { done: false, .. }) && !once {
            once = true;
            l2.die_after(3);
        }
    };
    let mut c = Coordinator::new(
        dev,
        Arc::new(AtomicBool::new(false)),
        Journal::create(&jp).unwrap(),
        &mut sink,
    );
    c.run(&b, &ResumePoint::default(), true, false, false)
        .unwrap_err();
    drop(c);
    // Half a second later, with both devices under way, the operator stops the indexer.
    cell.timebase_sleep(Duration::from_millis(500));
    assert!(cell.with(|p| p.card.machine().is_moving()).unwrap());
    cell.with(|p| p.card.machine.stop()).unwrap();
    cell.timebase_sleep(Duration::from_secs(60));
    let (robot, _, _) = completed(&cell);
    let last = b.items[0].rob.instructions.last().unwrap().position_mm;
    assert!(
        near(*robot.last().unwrap(), last),
        "the robot finished its program"
    );
    resume(&cell, &b, &jp);
    let recs = journal::read(&jp).unwrap();
    let resumed = recs.iter().rposition(|r| r["rec"] == "resume").unwrap();
    assert!(
        recs[resumed..]
            .iter()
            .any(|r| r["rec"] == "resume_program" && r["item"] == 0),
        "{:?}",
        &recs[resumed..]
    );
    assert_eq!(recs.last().unwrap()["rec"], "done");
}

/// A stored program runs unwatched: the robot computer holds the arm while it serves the link
/// (seed 001 §4.1.2), so a status read during the program would put the eye behind the mandrel.
/// Each program of the S-bend batch, from its start event to its end event, takes the mandrel
/// move's trapezoid time (computed here in closed form from the `.IND` move) plus the robot's
/// first, zero-length instruction (its interpretation time), the settling of its last, stopping
/// move (the zone's overhead) and the link's exchanges around the program (under 0.5 s), and no
/// more: a status read every half second during the program made each take 1.1 s longer.
#[test]
fn a_stored_program_runs_in_the_mandrels_time_without_status_reads() {
    use asea_protocol::command::INTERPRETATION_S;
    use asea_protocol::sim::motion::MotionParams;
    let settle_s = MotionParams::default().overhead_s;
    for (mode, zone) in [(RunMode::Fine, 0), (RunMode::Medium, 1)] {
        let l = sbend(Some(mode));
        let b = checked(&l);
        let cell = SimCell::new(&SimCellConfig::default());
        let events = wind(
            &cell,
            &b,
            Journal::none(),
            &ResumePoint::default(),
            true,
            None,
        )
        .unwrap();
        let mut starts = Vec::new();
        let mut ends = Vec::new();
        let mut path_s = Vec::new();
        for e in &events {
            if let Event::PathDone { time_s, .. } = e {
                path_s.push(*time_s);
            }
            if let Event::Program { done, time_s, .. } = e {
                if *done {
                    ends.push(*time_s)
                } else {
                    starts.push(*time_s)
                }
            }
        }
        assert_eq!((starts.len(), ends.len()), (2, 2), "{mode:?}");
        for (k, item) in l.items.iter().enumerate() {
            let m = item.ind.as_ref().unwrap().path_move;
            let spr = Drive::default().steps_per_mandrel_rev();
            let n = m.steps.unsigned_abs() as f64;
            // The indexer's trapezoid in closed form: jump to v0, ramp at a to vmax, cruise,
            // ramp down (continuous approximation of the step rule: within a step's time).
            let (a, v0, vm) = (m.accel_rps2 * spr, m.start_stop_rps * spr, m.max_rps * spr);
            let ramp_steps = (vm * vm - v0 * v0) / (2.0 * a);
            let mandrel_s = if 2.0 * ramp_steps <= n {
                2.0 * (vm - v0) / a + (n - 2.0 * ramp_steps) / vm
            } else {
                2.0 * ((v0 * v0 + a * n).sqrt() - v0) / a
            };
            let took = ends[k] - starts[k];
            // The path's time holds its program and the sync and approach before it (a few
            // seconds of mandrel and robot moves), no more.
            assert!(
                path_s[k] >= took && path_s[k] < took + 10.0,
                "{mode:?} path {}: {} s for a {took} s program",
                k + 1,
                path_s[k]
            );
            let over = took - mandrel_s - INTERPRETATION_S[zone] - settle_s[zone];
            eprintln!(
                "{mode:?} program {k}: {took:.3} s, mandrel {mandrel_s:.3} s, over {over:.3}"
            );
            assert!(
                (0.0..0.5).contains(&over),
                "{mode:?} program {}: {took:.3} s for a {mandrel_s:.3} s mandrel move",
                k + 1
            );
        }
    }
}

/// A robot whose status reads are timed on the cell's clock and, once `faulty` is set, report
/// an error code (`as_state`: the error state instead, with no code), and which notes its
/// position reads (`p`) and immediate moves (`m`) in order in `calls`; and sync lines that note
/// the start edge and, after it, never show "in position" (a program that hangs).
struct Watched {
    inner: Box<dyn cell::run::device::RobotDevice>,
    clock: asea_protocol::clock::VirtualClock,
    reads_s: Arc<std::sync::Mutex<Vec<f64>>>,
    calls: Arc<std::sync::Mutex<Vec<char>>>,
    faulty: Arc<AtomicBool>,
    as_state: bool,
}

impl Watched {
    /// Watches `inner` on `cell`'s clock, never faulty.
    fn new(inner: Box<dyn cell::run::device::RobotDevice>, cell: &SimCell) -> Self {
        Watched {
            inner,
            clock: cell.clock().clone(),
            reads_s: Arc::default(),
            calls: Arc::default(),
            faulty: Arc::default(),
            as_state: false,
        }
    }
}

impl cell::run::device::RobotDevice for Watched {
    fn state(&mut self) -> cell::run::device::DeviceResult<cell::run::device::RobotState> {
        self.reads_s.lock().unwrap().push(self.clock.now_s());
        let mut s = self.inner.state()?;
        if self.faulty.load(Ordering::Relaxed) {
            if self.as_state {
                s.state = State::Error;
            } else {
                s.last_error = 7;
            }
        }
        Ok(s)
    }
    fn position_mm(&mut self) -> cell::run::device::DeviceResult<[f64; 3]> {
        self.calls.lock().unwrap().push('p');
        self.inner.position_mm()
    }
    fn set_speeds(
        &mut self,
        b: asea_protocol::Speed,
        m: asea_protocol::Speed,
    ) -> cell::run::device::DeviceResult<()> {
        self.inner.set_speeds(b, m)
    }
    fn set_operate(&mut self, on: bool) -> cell::run::device::DeviceResult<()> {
        self.inner.set_operate(on)
    }
    fn start_home(&mut self) -> cell::run::device::DeviceResult<()> {
        self.inner.start_home()
    }
    fn move_immediate(
        &mut self,
        p: asea_protocol::Positioning,
    ) -> cell::run::device::DeviceResult<()> {
        self.calls.lock().unwrap().push('m');
        self.inner.move_immediate(p)
    }
    fn delete_program(&mut self, p: u8) -> cell::run::device::DeviceResult<()> {
        self.inner.delete_program(p)
    }
    fn upload(
        &mut self,
        p: u8,
        i: &[Instruction],
        progress: &mut dyn FnMut(),
    ) -> cell::run::device::DeviceResult<()> {
        self.inner.upload(p, i, progress)
    }
    fn read_back(
        &mut self,
        p: u8,
        i: &[Instruction],
        progress: &mut dyn FnMut(),
    ) -> cell::run::device::DeviceResult<()> {
        self.inner.read_back(p, i, progress)
    }
    fn run_program(&mut self, p: u8) -> cell::run::device::DeviceResult<()> {
        self.inner.run_program(p)
    }
    fn stop(&mut self) -> cell::run::device::DeviceResult<()> {
        self.inner.stop()
    }
}

#[derive(Debug)]
struct Hanging {
    inner: Box<dyn SyncLines>,
    clock: asea_protocol::clock::VirtualClock,
    edge_s: Arc<std::sync::Mutex<Option<f64>>>,
    faulty: Arc<AtomicBool>,
}

impl SyncLines for Hanging {
    fn set_start(&mut self, on: bool) -> cell::run::device::DeviceResult<()> {
        if on {
            *self.edge_s.lock().unwrap() = Some(self.clock.now_s());
            self.faulty.store(true, Ordering::Relaxed);
        }
        self.inner.set_start(on)
    }
    fn in_position(&mut self) -> cell::run::device::DeviceResult<bool> {
        let started = self.edge_s.lock().unwrap().is_some();
        Ok(self.inner.in_position()? && !started)
    }
    fn estop(&mut self) -> cell::run::device::DeviceResult<bool> {
        self.inner.estop()
    }
}

/// A program is read for errors only once it has overrun its mandrel move by half again plus a
/// second, then every `PROGRAM_POLL_TICKS` control ticks: with a program that never raises "in
/// position" and a robot that reports an error code (or the error state), the first status
/// read after the start edge comes one poll period after 1.5 × the move's closed-form time +
/// 1 s (within a tick and one exchange), none before, and the error halts the batch.
#[test]
fn a_hung_program_is_read_for_errors_after_its_quiet_time_and_halts() {
    for as_state in [false, true] {
        hung_program(as_state);
    }
}

fn hung_program(as_state: bool) {
    use cell::run::coordinator::{
        CONTROL_TICK, PROGRAM_POLL_TICKS, PROGRAM_QUIET_FACTOR, PROGRAM_QUIET_MARGIN_S,
    };
    let l = sbend(Some(RunMode::Medium));
    let b = checked(&l);
    let cell = SimCell::new(&SimCellConfig::default());
    let d = cell.devices(Drive::default());
    let reads_s = Arc::new(std::sync::Mutex::new(Vec::new()));
    let edge_s = Arc::new(std::sync::Mutex::new(None));
    let faulty = Arc::new(AtomicBool::new(false));
    let dev = cell::run::coordinator::Devices {
        robot: Box::new(Watched {
            reads_s: reads_s.clone(),
            faulty: faulty.clone(),
            as_state,
            ..Watched::new(d.robot, &cell)
        }),
        mandrel: d.mandrel,
        sync: Box::new(Hanging {
            inner: d.sync,
            clock: cell.clock().clone(),
            edge_s: edge_s.clone(),
            faulty,
        }),
        time: d.time,
    };
    let mut sink = |_e: Event| {};
    let mut c = Coordinator::new(
        dev,
        Arc::new(AtomicBool::new(false)),
        Journal::none(),
        &mut sink,
    );
    let stopped = c
        .run(&b, &ResumePoint::default(), true, false, false)
        .unwrap_err();
    drop(c);
    match &stopped.halt {
        // Read while the program ran (the device layer's report of the robot's state), or at
        // its end (the program's error code).
        Halt::Fault(Fault::Device(e)) if !as_state => {
            assert!(
                matches!(&**e, DeviceError::RobotState { what } if what.contains("error 7")),
                "{e:?}"
            )
        }
        Halt::Fault(fault) => {
            let want = if as_state { "error 0" } else { "error 7" };
            assert!(fault.to_string().contains(want), "{fault:?}")
        }
        other => panic!("{other:?}"),
    }
    let edge = edge_s.lock().unwrap().unwrap();
    let first = reads_s
        .lock()
        .unwrap()
        .iter()
        .copied()
        .find(|&t| t > edge)
        .unwrap();
    // The path move in closed form (as in the test above).
    let m = l.items[0].ind.as_ref().unwrap().path_move;
    let spr = Drive::default().steps_per_mandrel_rev();
    let n = m.steps.unsigned_abs() as f64;
    let (a, v0, vm) = (m.accel_rps2 * spr, m.start_stop_rps * spr, m.max_rps * spr);
    let ramp_steps = (vm * vm - v0 * v0) / (2.0 * a);
    assert!(2.0 * ramp_steps <= n);
    let mandrel_s = 2.0 * (vm - v0) / a + (n - 2.0 * ramp_steps) / vm;
    let quiet_s = PROGRAM_QUIET_FACTOR * mandrel_s + PROGRAM_QUIET_MARGIN_S;
    let period_s = f64::from(PROGRAM_POLL_TICKS) * CONTROL_TICK.as_secs_f64();
    let waited = first - edge;
    assert!(
        // The count starts at the first tick past the quiet time: the read comes at the
        // period's last tick, 49 to 50 ticks after the quiet time ends.
        waited >= quiet_s + period_s - CONTROL_TICK.as_secs_f64() - 0.01
            && waited <= quiet_s + period_s + 0.1,
        "first read {waited:.3} s after the edge; quiet time {quiet_s:.3} s"
    );
}

/// A mandrel that presses "stop" as its first move (the first path's sync) goes out: the run
/// stops after the sync is journaled and before the first segment.
struct StopAtFirstMove {
    inner: Box<dyn MandrelDevice>,
    flag: Arc<AtomicBool>,
    pressed: bool,
}

impl MandrelDevice for StopAtFirstMove {
    fn attach(&mut self) -> cell::run::device::DeviceResult<i64> {
        self.inner.attach()
    }
    fn zero(&mut self) -> cell::run::device::DeviceResult<()> {
        self.inner.zero()
    }
    fn start_move(&mut self, mv: &MandrelMove, armed: bool) -> cell::run::device::DeviceResult<()> {
        if !self.pressed {
            self.pressed = true;
            self.flag.store(true, Ordering::Relaxed);
        }
        self.inner.start_move(mv, armed)
    }
    fn busy(&mut self) -> cell::run::device::DeviceResult<(bool, bool)> {
        self.inner.busy()
    }
    fn counter_steps(&mut self) -> cell::run::device::DeviceResult<i64> {
        self.inner.counter_steps()
    }
    fn move_steps(&mut self) -> cell::run::device::DeviceResult<i64> {
        self.inner.move_steps()
    }
    fn stop(&mut self) -> cell::run::device::DeviceResult<()> {
        self.inner.stop()
    }
}

/// Stop → resume → stop → resume (docs/testing.md, `run_inner`'s `item` record): stopped
/// between the first path's sync and its first segment, resumed and stopped again after five
/// segments, resumed to the end. A resumed item that is already synced must not be journaled as
/// a new item (its `item` record would clear the journaled sync, and the second resume would
/// sync the mandrel again from mid-path). Every robot target once, one sync per path, and the
/// mandrel where the first sync plus the path's steps put it.
#[test]
fn stop_resume_stop_resume_syncs_each_path_once() {
    let b = checked(&sbend(Some(RunMode::Discrete)));
    let dir = tempfile::tempdir().unwrap();
    let jp = dir.path().join("J.journal");
    let cell = SimCell::new(&SimCellConfig::default());
    // 1: stopped at the first path's sync.
    let flag = Arc::new(AtomicBool::new(false));
    let d = cell.devices(Drive::default());
    let dev = cell::run::coordinator::Devices {
        robot: d.robot,
        mandrel: Box::new(StopAtFirstMove {
            inner: d.mandrel,
            flag: flag.clone(),
            pressed: false,
        }),
        sync: d.sync,
        time: d.time,
    };
    let mut sink = |_e: Event| {};
    let mut c = Coordinator::new(dev, flag, Journal::create(&jp).unwrap(), &mut sink);
    let stopped = c
        .run(&b, &ResumePoint::default(), true, false, false)
        .unwrap_err();
    drop(c);
    assert!(
        matches!(stopped.halt, Halt::Interrupted { .. }),
        "{stopped:?}"
    );
    assert_eq!((stopped.item, stopped.segments_done), (1, 0));
    let recs = journal::read(&jp).unwrap();
    let last: Vec<&str> = recs[recs.len() - 2..]
        .iter()
        .map(|r| r["rec"].as_str().unwrap())
        .collect();
    assert_eq!(
        last,
        ["sync", "stopped"],
        "the first stop must come after the sync record: {recs:?}"
    );
    cell.timebase_sleep(Duration::from_secs(2));
    // 2: resumed, stopped after five segments.
    let (journal, records) = Journal::resume(&jp).unwrap();
    let from = resume_point(&b, &records).unwrap();
    assert!(
        from.sync_counter.is_some() && from.segments_done == 0,
        "{from:?}"
    );
    // The approach and 4 segments: 5 instructions confirmed.
    let stopped = wind(&cell, &b, journal, &from, false, Some(4)).unwrap_err();
    assert_eq!((stopped.item, stopped.segments_done), (1, 5));
    cell.timebase_sleep(Duration::from_secs(2));
    let (journal, records) = Journal::resume(&jp).unwrap();
    let from = resume_point(&b, &records).unwrap();
    assert_eq!(from.segments_done, 5);
    assert!(
        from.sync_counter.is_some(),
        "the journaled sync was lost: {from:?}"
    );
    // 3: resumed to the end.
    wind(&cell, &b, journal, &from, false, None).unwrap();
    check_each_once(&cell, &b);
    let recs = journal::read(&jp).unwrap();
    let count = |rec: &str, item: i64| {
        recs.iter()
            .filter(|r| r["rec"] == rec && r["item"] == item)
            .count()
    };
    assert_eq!(
        (count("item", 0), count("sync", 0), count("sync", 1)),
        (1, 1, 1),
        "one item record and one sync per path"
    );
    // The first path's last segment ends where its one sync plus its steps put the mandrel.
    let sync0 = recs
        .iter()
        .find(|r| r["rec"] == "sync" && r["item"] == 0)
        .unwrap()["counter"]
        .as_i64()
        .unwrap();
    let path0: i64 = b.items[0]
        .rob
        .instructions
        .iter()
        .map(|n| n.mandrel.steps)
        .sum();
    let done0 = recs
        .iter()
        .rfind(|r| r["rec"] == "segment" && r["item"] == 0)
        .unwrap()["counter"]
        .as_i64()
        .unwrap();
    assert_eq!(done0, sync0 + path0);
    let counter = cell.with(|p| p.card.machine().counter_steps()).unwrap();
    let sync1 = recs
        .iter()
        .find(|r| r["rec"] == "sync" && r["item"] == 1)
        .unwrap()["counter"]
        .as_i64()
        .unwrap();
    let path1: i64 = b.items[1]
        .rob
        .instructions
        .iter()
        .map(|n| n.mandrel.steps)
        .sum();
    assert_eq!(counter, sync1 + path1);
}

/// Killed just after the start edge went out, and the robot stopped at its controls before the
/// edge reached it (still at the handshake, before its first position), while the indexer,
/// armed on the same line, saw the edge and turned the whole path. On resume the robot has
/// reached no position and the mandrel has turned: the path is started again (the mandrel
/// synced back, the whole program run), not resumed from a robot instruction that was never
/// reached, and every robot target is reached once.
#[test]
fn a_robot_stopped_at_its_handshake_while_the_mandrel_turned_starts_the_path_again() {
    let b = checked(&sbend(Some(RunMode::Fine)));
    let dir = tempfile::tempdir().unwrap();
    let jp = dir.path().join("J.journal");
    let cell = SimCell::new(&SimCellConfig::default());
    // RUN_PROGRAM, the armed move and the start edge go out; nothing after.
    killed_after_the_first_program_event(&cell, &b, &jp, 3);
    // The operator's STOP reaches the robot within the opto-coupler's delay of the edge.
    let stop = asea_protocol::Frame {
        code: 0x0C,
        data: Vec::new(),
    };
    let now = cell.clock().now_s();
    let s = cell
        .with(|p| {
            p.robot.machine.execute(&stop, now);
            p.robot.machine.status()
        })
        .unwrap();
    assert!(
        s.instruction <= cell::run::coordinator::HANDSHAKE_LEAD,
        "the robot must be stopped before its first position: {s:?}"
    );
    cell.timebase_sleep(Duration::from_secs(60));
    let (_, turned, _) = completed(&cell);
    let path0: i64 = b.items[0]
        .rob
        .instructions
        .iter()
        .map(|n| n.mandrel.steps)
        .sum();
    assert!(
        turned.contains(&path0),
        "the armed move turned the whole path: {turned:?}"
    );
    resume(&cell, &b, &jp);
    check_each_once(&cell, &b);
    let recs = journal::read(&jp).unwrap();
    assert!(
        !recs.iter().any(|r| r["rec"] == "resume_program"),
        "no resume program from a position never reached"
    );
    // The first path wound again: its program recorded twice, the second after the resume.
    let resumed = recs.iter().position(|r| r["rec"] == "resume").unwrap();
    assert!(
        recs[resumed..]
            .iter()
            .any(|r| r["rec"] == "program" && r["item"] == 0)
    );
}

/// Times at which a sampled motion starts: the first sample that differs from the one before
/// after at least `rest_s` without change.
fn motion_starts<T: Copy>(
    series: &[(f64, T)],
    moved: impl Fn(T, T) -> bool,
    rest_s: f64,
) -> Vec<f64> {
    let mut starts = Vec::new();
    let mut still_since = series.first().map_or(0.0, |s| s.0);
    for w in series.windows(2) {
        let ((t0, a), (t1, b)) = (w[0], w[1]);
        if moved(a, b) {
            if t0 - still_since >= rest_s {
                starts.push(t0);
            }
            still_since = t1;
        }
    }
    starts
}

/// Discrete movement with the sync lines wired: the mandrel's move of each segment waits for
/// the start line, raised as soon as the robot's move is confirmed executed, so the mandrel
/// starts no earlier than the arm and no later than the confirmation's two status exchanges
/// after it (at 9600 baud, under 0.15 s; the arm is held while the robot computer serves them,
/// seed 001 §4.1.2). Sending the indexer's move first and then the robot's put the mandrel
/// 0.1–0.2 s ahead of the arm on every segment; a mandrel that turns before the robot's move
/// is confirmed could also turn under an arm that never moves.
#[test]
fn discrete_segments_start_the_mandrel_with_the_arm_on_the_start_line() {
    let b = checked(&sbend(Some(RunMode::Discrete)));
    let segments: usize = b.items.iter().map(|i| i.rob.instructions.len()).sum();
    let cell = SimCell::new(&SimCellConfig::default());
    cell.with(|p| p.trace = Some(cell::sim::Trace::default()))
        .unwrap();
    wind(
        &cell,
        &b,
        Journal::none(),
        &ResumePoint::default(),
        true,
        None,
    )
    .unwrap();
    let trace = cell.with(|p| p.trace.take().unwrap()).unwrap();
    let eye = motion_starts(&trace.eye_mm, |a, b| a != b, 0.02);
    let drive = motion_starts(&trace.drive_rad, |a, b| a != b, 0.02);
    // Each mandrel start against the arm's start nearest to it. A path's sync turns the
    // mandrel alone, before the arm's approach to the path's first point (which turns no
    // mandrel): one per path, with no arm start in the 0.15 s before it.
    let nearest: Vec<f64> = drive
        .iter()
        .map(|&m| {
            eye.iter()
                .map(|&e| m - e)
                .min_by(|x, y| x.abs().total_cmp(&y.abs()))
                .unwrap()
        })
        .collect();
    let (lags, syncs): (Vec<f64>, Vec<f64>) = nearest
        .iter()
        .partition(|&&lag| (-0.15..0.5).contains(&lag));
    assert_eq!(syncs.len(), b.items.len(), "syncs {syncs:?}");
    assert_eq!(lags.len(), segments - b.items.len());
    for (k, lag) in lags.iter().enumerate() {
        assert!(
            (0.0..0.15).contains(lag),
            "segment {}: the mandrel starts {:.1} ms after the arm",
            k + 1,
            lag * 1e3
        );
    }
}

/// Each discrete move's position is read back once, after the move, and that reading is where
/// the next segment starts: between two moves of a path exactly one position read (each read
/// holds the arm for an exchange, seed 001 §4.1.2); between paths, the last move's read-back
/// and the next path's first reading; one read-back after the last move.
#[test]
fn a_discrete_move_is_read_back_once_and_not_read_before() {
    let b = checked(&sbend(Some(RunMode::Discrete)));
    let cell = SimCell::new(&SimCellConfig::default());
    let calls = Arc::new(std::sync::Mutex::new(Vec::new()));
    wind_with(&cell, &b, |r| Watched {
        calls: calls.clone(),
        ..Watched::new(r, &cell)
    })
    .unwrap();
    check_each_once(&cell, &b);
    let calls: String = calls.lock().unwrap().iter().collect();
    let first = calls.find('m').unwrap();
    let last = calls.rfind('m').unwrap();
    // Reads between consecutive moves.
    let gaps: Vec<usize> = calls[first + 1..last].split('m').map(|g| g.len()).collect();
    let moves = calls.matches('m').count();
    assert_eq!(gaps.len(), moves - 1);
    let paths = b.items.len();
    assert_eq!(
        gaps.iter().filter(|&&g| g == 2).count(),
        paths - 1,
        "{calls}"
    );
    assert_eq!(
        gaps.iter().filter(|&&g| g == 1).count(),
        moves - paths,
        "{calls}"
    );
    assert!(calls[last..].starts_with("mp"), "{}", &calls[last..]);
}

/// A journal is data, not trust: every number `--resume` reads is held to the batch it claims to
/// be. The S-bend's discrete batch has 2 paths of 51 instructions each (the start point and 50
/// segments; discrete mode journals each instruction); a journal naming instruction 52, path 3
/// done, a counter a thousand revolutions away or a record out of order is refused, naming
/// the record (its line) and the range that fits.
/// The mandrel steps of the first `segments` instructions of path `item`, from its .ROB (each
/// discrete segment is one instruction: its eye point and its mandrel move).
fn plan_steps(b: &Batch, item: usize, segments: usize) -> i64 {
    b.items[item].rob.instructions[..segments]
        .iter()
        .map(|i| i.mandrel.steps)
        .sum()
}

fn refused_counter(r: &Result<ResumePoint, cell::Error>) {
    assert!(
        matches!(
            r,
            Err(cell::Error::JournalMismatch(
                cell::error::JournalMismatch::OutOfRange {
                    record: 2,
                    field: "counter",
                    ..
                }
            ))
        ),
        "{r:?}"
    );
}

#[test]
fn a_journal_that_does_not_fit_its_batch_is_refused() {
    use cell::error::JournalMismatch;
    let l = sbend(Some(RunMode::Discrete));
    let b = checked(&l);
    let rec = |v: serde_json::Value| v.as_object().unwrap().clone();
    let begin = rec(serde_json::json!({"rec": "begin", "job": b.job_id, "mode": "discrete"}));
    let fits = |extra: Vec<serde_json::Value>| {
        let mut records = vec![begin.clone()];
        records.extend(extra.into_iter().map(rec));
        resume_point(&b, &records)
    };
    // What fits: path 1 done, 50 segments of path 2 (the 50th's destination is the sync plus
    // the plan's steps of the first 50 instructions; the 51st, the path's last, may be under way).
    let end = -3262 + plan_steps(&b, 1, 50);
    let last = -3262 + plan_steps(&b, 1, 51);
    let p = fits(vec![
        serde_json::json!({"rec": "item_done", "item": 1}),
        serde_json::json!({"rec": "sync", "item": 1, "counter": -3262}),
        serde_json::json!({"rec": "segment", "item": 1, "segment": 50, "counter": end}),
    ])
    .unwrap();
    assert_eq!((p.items_done, p.segments_done), (1, 50));
    assert_eq!(p.sync_counter, Some(-3262));
    assert_eq!(
        (p.counter_confirmed, p.counter_next),
        (Some(end), Some(last))
    );
    // A segment record without its counter does not fit: the counter is a witness.
    refused_counter(&fits(vec![
        serde_json::json!({"rec": "segment", "item": 0, "segment": 1}),
    ]));
    let refused = |extra: Vec<serde_json::Value>, field: &str, line: usize| match fits(extra) {
        Err(cell::Error::JournalMismatch(JournalMismatch::OutOfRange {
            record, field: f, ..
        })) => {
            assert_eq!((record, f), (line, field));
        }
        other => panic!("{field}: {other:?}"),
    };
    refused(
        vec![serde_json::json!({"rec": "segment", "item": 0, "segment": 52})],
        "segment",
        2,
    );
    refused(
        vec![serde_json::json!({"rec": "segment", "item": 0, "segment": 0})],
        "segment",
        2,
    );
    refused(
        vec![serde_json::json!({"rec": "segment", "item": 1, "segment": 3})],
        "item",
        2,
    );
    refused(
        vec![
            serde_json::json!({"rec": "item_done", "item": 1}),
            serde_json::json!({"rec": "item_done", "item": 3}),
        ],
        "item",
        3,
    );
    refused(
        vec![serde_json::json!({"rec": "sync", "item": 0, "counter": 1_000 * 1846})],
        "counter",
        2,
    );
    refused(
        vec![serde_json::json!({"rec": "segment", "item": 0})],
        "segment",
        2,
    );
}
