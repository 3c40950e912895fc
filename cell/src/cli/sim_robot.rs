//! `windcell sim-robot [--pty] [--checksum sum8|crc16] [--nak-malformed]`: the ASEA robot-computer
//! simulator on a pseudo-terminal (seed 001 §5.2; docs/protocol.md).
//!
//! Prints the slave device path on one line, serves the simulated robot computer on the master
//! side in real time until SIGINT or SIGTERM, then exits 0.
//!
//! Fault injection: SIGUSR1 starts a NAK storm (every ACK the robot computer sends reaches the
//! line as NAK, so the host sees every ENQ and telegram refused, as with a line whose noise
//! hits every acknowledgement); SIGUSR2 ends it. To make the robot fall silent, stop the process
//! (SIGSTOP) and continue it (SIGCONT).

use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};

use asea_protocol::session::Timers;
use asea_protocol::sim::{Malformed, MotionParams, Robot, serve};
use asea_protocol::{Checksum, FrameConfig};
use clap::{Args, ValueEnum};
use paths::link::{Clock as _, Link, WallClock};

use super::pty::{Ptys, Signals, stop_records};
use super::{Failure, print};

/// The check value after ETX (both ends must agree).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum CheckValue {
    /// One-byte sum (the thesis' choice; the default).
    Sum8,
    /// CRC-16/CCITT-FALSE, two bytes.
    Crc16,
}

/// Arguments of `windcell sim-robot`.
#[derive(Debug, Args)]
#[command(allow_negative_numbers = true)]
pub struct SimRobotArgs {
    /// Serve on a new pseudo-terminal and print its device path. This is the only transport and
    /// the default: the flag may be given or left out.
    #[arg(long)]
    pub pty: bool,
    /// Check value after ETX.
    #[arg(long, value_enum, default_value = "sum8")]
    pub checksum: CheckValue,
    /// Refuse (NAK) telegrams that do not parse instead of acknowledging them with an error code.
    #[arg(long)]
    pub nak_malformed: bool,
    /// Log every move the robot finishes as a JSON line (docs/file-formats.md, "Simulator logs").
    #[arg(long, value_name = "FILE")]
    pub log: Option<std::path::PathBuf>,
    /// With `--log`: at each STOP telegram, also log the last bytes that crossed the line both
    /// ways before it, with their times (a `wire_before_stop` record; for studying stop latency).
    #[arg(long, requires = "log")]
    pub log_wire: bool,
    /// Duration of a home synchronisation, seconds.
    #[arg(long, default_value_t = MotionParams::default().home_s, allow_negative_numbers = true)]
    pub home_s: f64,
}

/// Runs the simulator until SIGINT or SIGTERM.
pub fn run(args: SimRobotArgs) -> Result<(), Failure> {
    if !(args.home_s.is_finite() && (0.0..=crate::cli::MAX_SIM_SECONDS).contains(&args.home_s)) {
        return Err(Failure::input(format!(
            "sim-robot: --home-s {} must be a number of seconds, 0 … {}",
            sequences::error::shown(args.home_s),
            crate::cli::MAX_SIM_SECONDS
        )));
    }
    // The log is created before the pseudo-terminal is offered: a log that cannot be written
    // is refused with nothing printed.
    let log = match &args.log {
        Some(p) => Some(
            std::fs::File::create(p)
                .map_err(|e| Failure::input(format!("{}: {e}", p.display())))?,
        ),
        None => None,
    };
    let signals = Signals::register("sim-robot", true)?;
    let ptys = Ptys::open("sim-robot", 1)?;
    print(&format!("{}\n", ptys.paths()?.join("\n")))?;
    let frame = FrameConfig {
        checksum: match args.checksum {
            CheckValue::Sum8 => Checksum::Sum8,
            CheckValue::Crc16 => Checksum::Crc16,
        },
        ..FrameConfig::default()
    };
    let malformed = if args.nak_malformed {
        Malformed::Nak
    } else {
        Malformed::AckWithError
    };
    let robot = Mutex::new(
        Robot::new(
            frame,
            Timers::default(),
            MotionParams {
                home_s: args.home_s,
                ..MotionParams::default()
            },
        )
        .with_malformed(malformed),
    );
    let clock = WallClock::new();
    let stop = &signals.stop;
    ptys.serve(|masters| {
        let Some(master) = masters.into_iter().next() else {
            return Ok(());
        };
        // The log notes when each STOP telegram arrives (wall clock), for the stop latency.
        let (master, stops) = cell::sim::wiretap::StopTap::new(
            master,
            cell::sim::wiretap::StopPattern::robot(&frame),
        );
        let (master, traces) = if args.log_wire {
            let (m, t) = master.with_trace();
            (m, Some(t))
        } else {
            (master, None)
        };
        let master = NakStorm {
            inner: master,
            on: signals.usr1.clone(),
            off: signals.usr2.clone(),
            storming: false,
        };
        std::thread::scope(|scope| {
            if let Some(mut file) = log {
                let (robot, clock, stops, traces) = (&robot, &clock, &stops, &traces);
                scope.spawn(move || {
                    use std::io::Write as _;
                    let mut watch = cell::sim::RobotWatch::default();
                    while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                        let records = match robot.lock() {
                            Ok(r) => watch.watch(&r.machine, clock.now_s()),
                            Err(_) => return,
                        };
                        for r in records {
                            let _ = writeln!(file, "{}", r.json());
                        }
                        for r in stop_records("robot", stops, clock.now_s()) {
                            let _ = writeln!(file, "{r}");
                        }
                        let wire: Vec<Vec<cell::sim::wiretap::WireEvent>> = traces
                            .as_ref()
                            .and_then(|t| t.lock().ok().map(|mut t| t.drain(..).collect()))
                            .unwrap_or_default();
                        for w in wire {
                            let events: Vec<serde_json::Value> =
                                w.iter().map(cell::sim::wiretap::WireEvent::json).collect();
                            let _ = writeln!(
                                file,
                                "{}",
                                serde_json::json!({"device": "robot", "wire_before_stop": events})
                            );
                        }
                        std::thread::sleep(std::time::Duration::from_millis(1));
                    }
                });
            }
            serve(master, &robot, &clock, stop)
        })
    })
}

/// The robot's end of the line with a NAK storm that signals switch on and off: while it
/// storms, every ACK written becomes NAK.
struct NakStorm<L> {
    inner: L,
    /// Set by SIGUSR1.
    on: Arc<AtomicBool>,
    /// Set by SIGUSR2.
    off: Arc<AtomicBool>,
    storming: bool,
}

impl<L: Link> Link for NakStorm<L> {
    fn write_all(&mut self, bytes: &[u8]) -> std::io::Result<()> {
        use std::sync::atomic::Ordering::Relaxed;
        if self.on.swap(false, Relaxed) {
            self.storming = true;
        }
        if self.off.swap(false, Relaxed) {
            self.storming = false;
        }
        if !self.storming {
            return self.inner.write_all(bytes);
        }
        let stormed: Vec<u8> = bytes
            .iter()
            .map(|&b| {
                if b == asea_protocol::frame::ACK {
                    asea_protocol::frame::NAK
                } else {
                    b
                }
            })
            .collect();
        self.inner.write_all(&stormed)
    }
    fn read_timeout(
        &mut self,
        buf: &mut [u8],
        timeout: std::time::Duration,
    ) -> std::io::Result<usize> {
        self.inner.read_timeout(buf, timeout)
    }
    fn discard_input(&mut self) -> std::io::Result<()> {
        self.inner.discard_input()
    }
}
