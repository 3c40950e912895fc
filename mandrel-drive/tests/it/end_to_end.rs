//! Client ↔ simulator over a pseudo-terminal for both dialects, and scripted bad replies over the
//! in-memory pipe.

use std::f64::consts::TAU;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread;
use std::time::Duration;

use mandrel_drive::link::SerialLink;
use mandrel_drive::sim::machine::PULL_IN_SPS;
use mandrel_drive::sim::{Frontend, Machine, WallClock, grbl::Controller, serve, xlang::Card};
use mandrel_drive::xlang::Command;
use mandrel_drive::{
    Direction, Drive, Error, GrblClient, Indexer, IndexerConfig, Link, Pipe, PosMode, Profile,
    StopKind, XClient,
};

/// A pseudo-terminal end as a link.
type Pty = SerialLink<Box<serialport::TTYPort>>;

/// Pseudo-terminal tests run one at a time.
static PTY: Mutex<()> = Mutex::new(());

struct Served<F: Frontend + 'static> {
    front: Arc<Mutex<F>>,
    stop: Arc<AtomicBool>,
    thread: Option<thread::JoinHandle<()>>,
}

impl<F: Frontend + 'static> Served<F> {
    fn start(front: F, link: Pty) -> Self {
        let front = Arc::new(Mutex::new(front));
        let stop = Arc::new(AtomicBool::new(false));
        let (f, s) = (front.clone(), stop.clone());
        let thread = thread::spawn(move || {
            let clock = WallClock::new();
            serve(link, &f, &clock, &s).unwrap();
        });
        Served {
            front,
            stop,
            thread: Some(thread),
        }
    }
}

impl<F: Frontend + 'static> Drop for Served<F> {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

fn config() -> IndexerConfig {
    IndexerConfig {
        reset_wait: Duration::from_millis(300),
        start_velocity_command: true,
        ..IndexerConfig::default()
    }
}

#[test]
fn xlang_over_pty() {
    let _guard = PTY.lock().unwrap_or_else(|e| e.into_inner());
    let (master, slave) = SerialLink::pty_pair().expect("pty pair");
    let drive = Drive::default();
    let mut card = Card::new(Machine::new(drive, PULL_IN_SPS), 1);
    card.reset_busy_s = 0.25;
    let sim = Served::start(card, master);
    let mut client = XClient::new(slave, config());

    client.init().unwrap();
    let profile = Profile {
        accel_rps2: 4.0,
        start_rps: 0.1,
        max_rps: 2.0,
    };
    client.set_profile(profile).unwrap();
    let steps = drive.steps_from_deg(360.0);
    client.move_to(steps, PosMode::Incremental).unwrap();
    assert!(client.status().unwrap().busy);
    client.wait_complete(Duration::from_secs(5)).unwrap();
    let s = client.wait_idle(Duration::from_secs(5)).unwrap();
    assert_eq!(s.position_steps, Some(1846));
    assert_eq!(client.move_steps().unwrap(), 1846);
    {
        let f = sim.front.lock().unwrap();
        assert_eq!(f.machine().motor_steps(), 1846);
        let angle = f.machine().mandrel_angle_rad();
        assert!((angle - 1846.0 / drive.steps_per_mandrel_rev() * TAU).abs() < 1e-9);
    }

    // Absolute move back to 0.
    client.move_to(0, PosMode::Absolute).unwrap();
    client.wait_complete(Duration::from_secs(5)).unwrap();
    assert_eq!(client.status().unwrap().position_steps, Some(0));

    // Constant velocity, then a decelerating stop.
    client.run_constant(0.5, Direction::Negative).unwrap();
    thread::sleep(Duration::from_millis(300));
    assert!(client.status().unwrap().busy);
    client.stop(StopKind::Decelerate).unwrap();
    let s = client.wait_idle(Duration::from_secs(5)).unwrap();
    assert!(s.position_steps.unwrap() < -100, "{s:?}");

    // Alternating twice between two positions ends on the second.
    client.alternate(200, -200, Some(2)).unwrap();
    let s = client.wait_idle(Duration::from_secs(10)).unwrap();
    assert_eq!(s.position_steps, Some(-200));

    // The pulse limit: refused by the client; a raw command over it runs on the card as on a
    // real one (the translator loses the excess pulses without a word).
    let over = Profile {
        max_rps: 6.0,
        ..profile
    };
    let e = client.set_profile(over).unwrap_err();
    assert!(matches!(e, Error::PulseRate { .. }), "{e}");
    client.send(&Command::Velocity(30.0)).unwrap(); // 12 000 pulses/s at MR400
    client.move_to(100, PosMode::Incremental).unwrap();
    client.wait_complete(Duration::from_secs(5)).unwrap();
    assert!(!client.status().unwrap().fault);

    // A start velocity above the pull-in rate stalls the motor and the move fails.
    let stalling = Profile {
        accel_rps2: 4.0,
        start_rps: 0.8, // 1477 steps/s > 1000
        max_rps: 2.0,
    };
    client.set_profile(stalling).unwrap();
    let e = client.move_to(500, PosMode::Incremental).unwrap_err();
    assert!(matches!(e, Error::Stalled), "{e}");

    // Reset clears everything.
    client.init().unwrap();
    let s = client.status().unwrap();
    assert!(!s.busy && !s.fault);
    assert_eq!(s.position_steps, Some(0));
}

#[test]
fn grbl_over_pty() {
    let _guard = PTY.lock().unwrap_or_else(|e| e.into_inner());
    let (master, slave) = SerialLink::pty_pair().expect("pty pair");
    let drive = Drive::default();
    let sim = Served::start(Controller::new(Machine::new(drive, PULL_IN_SPS)), master);
    let mut client = GrblClient::new(slave, config());

    client.init().unwrap();
    let with_start = Profile {
        accel_rps2: 4.0,
        start_rps: 0.1,
        max_rps: 2.0,
    };
    assert!(matches!(
        client.set_profile(with_start),
        Err(Error::Unsupported { .. })
    ));
    client
        .set_profile(Profile {
            start_rps: 0.0,
            ..with_start
        })
        .unwrap();
    client.move_to(1846, PosMode::Absolute).unwrap();
    assert!(client.status().unwrap().busy);
    let s = client.wait_idle(Duration::from_secs(5)).unwrap();
    assert_eq!(s.position_steps, Some(1846));
    assert_eq!(sim.front.lock().unwrap().machine().motor_steps(), 1846);

    client.run_constant(0.5, Direction::Positive).unwrap();
    thread::sleep(Duration::from_millis(300));
    assert!(client.status().unwrap().busy);
    client.stop(StopKind::Decelerate).unwrap();
    let s = client.wait_idle(Duration::from_secs(5)).unwrap();
    assert!(s.position_steps.unwrap() > 1846 + 100, "{s:?}");

    client.alternate(100, 300, Some(2)).unwrap();
    let s = client.wait_idle(Duration::from_secs(10)).unwrap();
    assert_eq!(s.position_steps, Some(300));

    assert!(matches!(
        client.set_profile(Profile {
            start_rps: 0.0,
            ..Profile {
                max_rps: 6.0,
                ..with_start
            }
        }),
        Err(Error::PulseRate { .. })
    ));
    let e = client
        .send(&mandrel_drive::grbl::Command::MaxRate(6.0 * 21_600.0))
        .unwrap_err();
    assert!(e.to_string().contains("10000 pulses/s"), "{e}");

    client.init().unwrap();
    assert!(!client.status().unwrap().busy);
}

fn scripted(reply: &[u8]) -> XClient<Pipe> {
    let (near, mut far) = Pipe::pair();
    far.write_all(reply).unwrap();
    // Keep the far end alive inside a leaked clone so the pipe stays open for the test.
    std::mem::forget(far);
    XClient::new(
        near,
        IndexerConfig {
            reply_timeout: Duration::from_millis(50),
            ..IndexerConfig::default()
        },
    )
}

#[test]
fn bad_replies_are_typed_errors() {
    // echo "1R" CR, then garbage CR
    let mut c = scripted(b"1R\r#?!\r");
    assert!(matches!(
        c.send(&Command::Status),
        Err(Error::BadReply { .. })
    ));
    // echo, then a reply without its CR: truncated, times out
    let mut c = scripted(b"1PR\r*+00000");
    assert!(matches!(
        c.send(&Command::Position),
        Err(Error::Timeout { .. })
    ));
    // nothing at all
    let mut c = scripted(b"");
    assert!(matches!(
        c.send(&Command::Status),
        Err(Error::Timeout { .. })
    ));
    // wrong echo
    let mut c = scripted(b"2R\r");
    assert!(matches!(c.send(&Command::Status), Err(Error::Echo { .. })));
    // SSD1 echo, then R echo and a reply from device 002
    let mut c = scripted(b"1SSD1\r1R\r*002R\r");
    c.send(&Command::DeviceId(true)).unwrap();
    assert!(matches!(
        c.send(&Command::Status),
        Err(Error::WrongAddress {
            expected: 1,
            got: 2
        })
    ));
    // a good exchange, with a move-complete notification in front of the reply
    let mut c = scripted(b"\r\n1W3\r*FFFF9E58\r");
    assert_eq!(c.move_steps().unwrap(), -25_000);
    // endless noise without a CR
    let mut c = scripted(&[b'x'; 600]);
    assert!(matches!(
        c.send(&Command::Status),
        Err(Error::BadReply { .. })
    ));
}

/// A restarted coordinator attaches without zeroing, arms a move on the start line that waits
/// until the line rises, and cancels a blocked wait from another thread; the stop still goes
/// through the cancelled client.
#[test]
fn attach_arm_on_trigger_and_cancel() {
    use mandrel_drive::client::POLL_PERIOD;
    use mandrel_drive::sim::Clock;
    use mandrel_drive::sync::Wire;
    let _guard = PTY.lock().unwrap_or_else(|e| e.into_inner());
    let (master, slave) = SerialLink::pty_pair().expect("pty pair");
    let wire_clock: Arc<dyn Clock> = Arc::new(WallClock::new());
    let start = Wire::new(wire_clock, 0.0);
    let mut card = Card::new(Machine::new(Drive::default(), PULL_IN_SPS), 1)
        .with_trigger(Box::new(start.clone()));
    card.reset_busy_s = 0.2;
    let sim = Served::start(card, master);
    let mut client = XClient::new(slave, config());
    client.init().unwrap();
    client
        .set_profile(Profile {
            accel_rps2: 4.0,
            start_rps: 0.0,
            max_rps: 1.0,
        })
        .unwrap();
    client.move_to(300, PosMode::Incremental).unwrap();
    client.wait_complete(Duration::from_secs(5)).unwrap();

    // Attach: the counter keeps the mandrel's 300 steps.
    let s = client.attach().unwrap();
    assert_eq!(
        (s.busy, s.fault, s.position_steps),
        (false, false, Some(300))
    );

    // Armed on the start line: nothing moves until it rises.
    client.arm_move(100, PosMode::Incremental).unwrap();
    thread::sleep(Duration::from_millis(200));
    assert_eq!(sim.front.lock().unwrap().machine().counter_steps(), 300);
    assert!(client.status().unwrap().busy);
    start.drive(true).unwrap();
    let s = client.wait_idle(Duration::from_secs(5)).unwrap();
    assert_eq!(s.position_steps, Some(400));
    start.drive(false).unwrap();

    // Cancel a wait that would block for 30 s.
    let token = client.cancel_token();
    let canceller = {
        let token = token.clone();
        thread::spawn(move || {
            thread::sleep(Duration::from_millis(100));
            let at = std::time::Instant::now();
            token.cancel();
            at
        })
    };
    let e = client.wait_complete(Duration::from_secs(30)).unwrap_err();
    let cancelled_at = canceller.join().unwrap();
    assert!(matches!(e, Error::Cancelled), "{e}");
    // Seen within a few polls (1 ms each), far inside the 50 ms a slower poll would take; the
    // margin is for a loaded machine, where a thread can wait a few milliseconds to be run.
    assert!(
        cancelled_at.elapsed() <= 20 * POLL_PERIOD,
        "{:?}",
        cancelled_at.elapsed()
    );
    assert!(matches!(client.status(), Err(Error::Cancelled)));
    client.stop(StopKind::Decelerate).unwrap();
    token.reset();
    assert!(!client.status().unwrap().busy);
}

/// A card whose reset outlasts the client's wait (a loaded host, a `Z` that reaches the card
/// late): the client polls the status until the card is ready before it sends `SSD1`, so the
/// device-ID prefix is on from the first reply that is checked for it. Sent during the reset,
/// `SSD1` would sit in the card's buffer and the next status reply would come without the prefix
/// ("truncated device id").
#[test]
fn init_waits_for_the_reset_to_finish() {
    let _guard = PTY.lock().unwrap_or_else(|e| e.into_inner());
    let (master, slave) = SerialLink::pty_pair().expect("pty pair");
    let mut card = Card::new(Machine::new(Drive::default(), PULL_IN_SPS), 1);
    card.reset_busy_s = 0.6;
    let sim = Served::start(card, master);
    let cfg = IndexerConfig {
        reset_wait: Duration::from_millis(20),
        ..config()
    };
    let mut client = XClient::new(slave, cfg);
    client.init().unwrap();
    let s = client.status().unwrap();
    assert!(!s.busy && !s.fault, "{s:?}");
    assert_eq!(s.position_steps, Some(0));
    let f = sim.front.lock().unwrap();
    assert!(f.machine().now_s() >= f.machine().reset_until_s);
}
