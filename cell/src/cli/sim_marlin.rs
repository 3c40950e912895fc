//! `windcell sim-marlin [--pty | --tcp ADDR] [--log FILE] [--time-scale K]`: a Marlin 2.1
//! controller of the lathe winder on a pseudo-terminal or a TCP socket
//! (`mandrel_drive::sim::marlin`; docs/lathe.md, "Streaming to a Marlin controller").
//!
//! The socket is for hosts that pulse DTR to reset the board when they open the port (pyserial
//! hosts such as `fiberpath stream`): a pseudo-terminal refuses that ioctl, a `socket://` URL
//! ignores it. With `--tcp` the first line printed is `socket://HOST:PORT`; connections are
//! served one after the other, the controller's state kept between them.
//!
//! Prints the slave device path (or the URL) on one line, serves the simulated controller on the master side
//! in real time until SIGINT or SIGTERM, then exits 0. The log holds one JSON line per executed
//! line (each once), per refused line, per clamped target, per overflow and for `M112`.

use std::io::Write as _;
use std::sync::atomic::{AtomicBool, Ordering};

use clap::Args;
use mandrel_drive::sim::marlin::{Event, Marlin};
use mandrel_drive::sim::{Clock as _, POLL_PERIOD, WallClock};
use paths::link::Link as _;

use super::{Failure, print};

/// Arguments of `windcell sim-marlin`.
#[derive(Debug, Args)]
pub struct SimMarlinArgs {
    /// Serve on a new pseudo-terminal and print its device path (the only transport; the flag may
    /// be given or left out).
    #[arg(long, conflicts_with = "tcp")]
    pub pty: bool,
    /// Serve on a TCP socket at this address (`127.0.0.1:0` picks a free port) instead, and print
    /// its `socket://HOST:PORT` URL.
    #[arg(long, value_name = "ADDR")]
    pub tcp: Option<String>,
    /// Log every executed line (once), refusal, clamp and halt as JSON lines.
    #[arg(long, value_name = "FILE")]
    pub log: Option<std::path::PathBuf>,
    /// Motion runs this many times faster than commanded (1 = real time).
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    pub time_scale: f64,
}

fn record(event: &Event, t_s: f64) -> serde_json::Value {
    match event {
        Event::Executed {
            n,
            line_number,
            text,
        } => serde_json::json!({"t_s": t_s, "executed": n, "N": line_number, "text": text}),
        Event::Rejected { text, error } => {
            serde_json::json!({"t_s": t_s, "rejected": text, "error": error})
        }
        Event::Clamped {
            axis,
            commanded,
            to,
        } => {
            serde_json::json!({"t_s": t_s, "clamped": axis.to_string(), "commanded": commanded, "to": to})
        }
        Event::Overflow { bytes } => serde_json::json!({"t_s": t_s, "overflow_bytes": bytes}),
        Event::Killed => serde_json::json!({"t_s": t_s, "killed": true}),
    }
}

/// Runs the simulator until SIGINT or SIGTERM.
pub fn run(args: SimMarlinArgs) -> Result<(), Failure> {
    if !(args.time_scale.is_finite()
        && args.time_scale > 0.0
        && args.time_scale <= crate::cli::MAX_TIME_SCALE)
    {
        return Err(Failure::input(format!(
            "sim-marlin: --time-scale {} must be a positive number, at most {}",
            sequences::error::shown(args.time_scale),
            crate::cli::MAX_TIME_SCALE
        )));
    }
    let mut log = match &args.log {
        Some(p) => Some(std::io::BufWriter::new(
            std::fs::File::create(p)
                .map_err(|e| Failure::input(format!("{}: {e}", p.display())))?,
        )),
        None => None,
    };
    let stop = super::pty::Signals::register("sim-marlin", false)?.stop;
    let mut marlin = Marlin::new(args.time_scale);
    let mut session = Session {
        marlin: &mut marlin,
        log: log.as_mut(),
        clock: WallClock::new(),
        stop: &stop,
    };
    if let Some(addr) = &args.tcp {
        let listener = std::net::TcpListener::bind(addr)
            .map_err(|e| Failure::input(format!("sim-marlin: --tcp {addr}: {e}")))?;
        let local = listener.local_addr().map_err(failure)?;
        print(&format!("socket://{local}\n"))?;
        listener.set_nonblocking(true).map_err(failure)?;
        while !stop.load(Ordering::Relaxed) {
            match listener.accept() {
                Ok((stream, _)) => {
                    stream.set_nonblocking(false).map_err(failure)?;
                    stream
                        .set_read_timeout(Some(POLL_PERIOD))
                        .map_err(failure)?;
                    session.serve_tcp(stream)?;
                }
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                    session.idle();
                    std::thread::sleep(POLL_PERIOD);
                }
                Err(e) => return Err(failure(e)),
            }
        }
        return Ok(());
    }
    let ptys = super::pty::Ptys::open("sim-marlin", 1)?;
    print(&format!("{}\n", ptys.paths()?.join("\n")))?;
    ptys.serve_failing(|masters| {
        let Some(mut master) = masters.into_iter().next() else {
            return Ok(());
        };
        // The start-up banner waits in the pseudo-terminal until a host opens it.
        let banner = session.marlin.take_output();
        master.write_all(&banner).map_err(failure)?;
        let mut buf = [0u8; 512];
        while !stop.load(Ordering::Relaxed) {
            let n = master
                .read_timeout(&mut buf, POLL_PERIOD)
                .map_err(failure)?;
            let out = session.step(buf.get(..n).unwrap_or_default())?;
            if !out.is_empty() {
                master.write_all(&out).map_err(failure)?;
            }
        }
        Ok(())
    })
}

fn failure(e: std::io::Error) -> Failure {
    Failure::runtime(format!("sim-marlin: {e}"))
}

/// The controller, its log and its clock, whichever transport carries the bytes.
struct Session<'a> {
    marlin: &'a mut Marlin,
    log: Option<&'a mut std::io::BufWriter<std::fs::File>>,
    clock: WallClock,
    stop: &'a AtomicBool,
}

impl Session<'_> {
    /// Takes the host's bytes (or none: time passes) and returns the replies.
    fn step(&mut self, bytes: &[u8]) -> Result<Vec<u8>, Failure> {
        let now = self.clock.now_s();
        if bytes.is_empty() {
            self.marlin.poll(now);
        } else {
            self.marlin.receive(bytes, now);
        }
        let events = self.marlin.take_events();
        if let Some(file) = self.log.as_mut()
            && !events.is_empty()
        {
            for e in &events {
                writeln!(file, "{}", record(e, now)).map_err(failure)?;
            }
            file.flush().map_err(failure)?;
        }
        Ok(self.marlin.take_output())
    }

    /// Motion goes on with no host connected; replies are dropped.
    fn idle(&mut self) {
        let _ = self.step(&[]);
    }

    /// Serves one TCP connection until the host closes it or a stop is asked for.
    fn serve_tcp(&mut self, mut stream: std::net::TcpStream) -> Result<(), Failure> {
        use std::io::Read as _;
        let mut buf = [0u8; 512];
        while !self.stop.load(Ordering::Relaxed) {
            let n = match stream.read(&mut buf) {
                Ok(0) => return Ok(()),
                Ok(n) => n,
                Err(e)
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                    ) =>
                {
                    0
                }
                Err(_) => return Ok(()),
            };
            let out = self.step(&buf[..n])?;
            if !out.is_empty() && stream.write_all(&out).is_err() {
                return Ok(());
            }
        }
        Ok(())
    }
}
