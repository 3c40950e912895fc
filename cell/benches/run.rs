//! Criterion: a whole S-bend batch (both paths) wound by the coordinator on the simulated cell's
//! fast clock, in each mode; and the stop latency of a real-time discrete run.
//! `cargo bench -p cell --bench run` (docs/benchmarks.md, "Coordinator").

use std::hint::black_box;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use cell::plan::tool;
use cell::run::batch;
use cell::run::coordinator::{
    Batch, Coordinator, Devices, Event, Reach, ResumePoint, RunMode, StopRequest,
};
use cell::run::device::{NoSync, ProtocolRobot, WallClock, XIndexer};
use cell::run::journal::Journal;
use cell::sim::wiretap::{StopPattern, StopTap, unix_now_s};
use cell::sim::{SimCell, SimCellConfig};
use criterion::{Criterion, criterion_group, criterion_main};
use mandrel_drive::Drive;
use sequences::Job;

fn batch(mode: RunMode) -> Batch {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/sbend.toml");
    let (job, text) = Job::load(&path).unwrap();
    let plan = tool::plan(&job, &text, &path).unwrap();
    let files = batch::files_of_job(&cell::plan::files::control_files(&job, &plan).unwrap());
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
    // The same batches timed by the winding thread's CPU time: on a machine shared with other
    // builds the wall time above counts the time the thread waited for a core; the CPU time is
    // what the batch costs.
    let mut g = c.benchmark_group("sbend_batch_cpu");
    g.sample_size(10);
    for mode in [RunMode::Discrete, RunMode::Fine, RunMode::Medium] {
        let b = batch(mode);
        g.bench_function(mode.keyword(), |bench| {
            bench.iter_custom(|iters| {
                let mut total = Duration::ZERO;
                for _ in 0..iters {
                    let t0 = thread_cpu();
                    black_box(wind(&b, &journal));
                    total += thread_cpu().saturating_sub(t0);
                }
                total
            })
        });
    }
    g.finish();
}

/// CPU time of this thread.
fn thread_cpu() -> Duration {
    nix::time::clock_gettime(nix::time::ClockId::CLOCK_THREAD_CPUTIME_ID)
        .map_or(Duration::ZERO, Duration::from)
}

/// Real time: both simulators served on in-memory serial lines by their own threads (as
/// `sim-robot --pty` and `sim-indexer --pty` serve a pty); a discrete run stopped 0.5 s in; the
/// time from the stop request (what the Ctrl-C handler makes) until both stop commands have
/// arrived at the simulators' ends of the lines (`cell::sim::wiretap`).
fn stop_latency(c: &mut Criterion) {
    let b = batch(RunMode::Discrete);
    let dir = tempfile::tempdir().unwrap();
    let journal = dir.path().join("stop.journal");
    let mut g = c.benchmark_group("stop_latency");
    g.sample_size(10);
    g.bench_function("discrete_real_time", |bench| {
        bench.iter_custom(|iters| {
            let mut total = Duration::ZERO;
            for _ in 0..iters {
                let (robot_host, robot_dev) = asea_protocol::link::Pipe::pair();
                let (x_host, x_dev) = mandrel_drive::Pipe::pair();
                let halt = Arc::new(AtomicBool::new(false));
                let robot = Arc::new(Mutex::new(asea_protocol::sim::Robot::new(
                    asea_protocol::FrameConfig::default(),
                    asea_protocol::Timers::default(),
                    asea_protocol::sim::MotionParams {
                        home_s: 0.05,
                        ..Default::default()
                    },
                )));
                let card = Arc::new(Mutex::new(mandrel_drive::sim::xlang::Card::new(
                    mandrel_drive::sim::Machine::new(
                        Drive::default(),
                        mandrel_drive::sim::machine::PULL_IN_SPS,
                    ),
                    1,
                )));
                let (robot_dev, robot_seen) = StopTap::new(
                    robot_dev,
                    StopPattern::robot(&asea_protocol::FrameConfig::default()),
                );
                let (x_dev, x_seen) = StopTap::new(x_dev, StopPattern::IndexerStop);
                let (h1, r1) = (halt.clone(), robot.clone());
                let t1 = std::thread::spawn(move || {
                    let clock = asea_protocol::clock::WallClock::new();
                    let _ = asea_protocol::sim::serve(robot_dev, &r1, &clock, &h1);
                });
                let (h2, c2) = (halt.clone(), card.clone());
                let t2 = std::thread::spawn(move || {
                    let clock = mandrel_drive::sim::WallClock::new();
                    let _ = mandrel_drive::sim::serve(x_dev, &c2, &clock, &h2);
                });
                let setup = cell::run::transfer::IndexerSetup {
                    drive: Drive::default(),
                    start_velocity_command: true,
                };
                let dev = Devices {
                    robot: Box::new(ProtocolRobot::new(asea_protocol::Client::new(
                        robot_host,
                        asea_protocol::ClientConfig::default(),
                    ))),
                    mandrel: Box::new(XIndexer::new(
                        mandrel_drive::XClient::new(
                            x_host,
                            mandrel_drive::IndexerConfig {
                                start_velocity_command: true,
                                device_id: false,
                                ..Default::default()
                            },
                        ),
                        setup,
                    )),
                    sync: Box::new(NoSync),
                    time: Arc::new(WallClock::new()),
                };
                let stop = StopRequest::new(&dev);
                let flag = stop.clone();
                let (b2, j2) = (b.clone(), journal.clone());
                let run = std::thread::spawn(move || {
                    let mut sink = |_e: Event| {};
                    let mut c =
                        Coordinator::with_stop(dev, flag, Journal::create(&j2).unwrap(), &mut sink);
                    c.run(&b2, &ResumePoint::default(), true, false, false)
                        .is_err()
                });
                std::thread::sleep(Duration::from_millis(500));
                let t0 = unix_now_s();
                stop.request("bench");
                assert!(run.join().unwrap(), "the run was not stopped");
                let robot_t = robot_seen.lock().unwrap()[0];
                let x_t = x_seen.lock().unwrap()[0];
                total += Duration::from_secs_f64(robot_t.max(x_t) - t0);
                if std::env::var_os("WINDCELL_STOP_DETAIL").is_some() {
                    eprintln!(
                        "robot STOP after {:.2} ms, indexer S after {:.2} ms",
                        (robot_t - t0) * 1e3,
                        (x_t - t0) * 1e3
                    );
                }
                halt.store(true, Ordering::Relaxed);
                t1.join().unwrap();
                t2.join().unwrap();
            }
            total
        })
    });
    g.finish();
}

criterion_group!(benches, bench, stop_latency);
criterion_main!(benches);
