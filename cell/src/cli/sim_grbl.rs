//! `windcell sim-grbl [--pty] [--log FILE] [--time-scale K]`: the multi-axis GRBL controller of the
//! lathe winder on a pseudo-terminal (docs/lathe.md, "Streaming to a GRBL controller").
//!
//! Prints the slave device path on one line, serves the simulated controller on the master side
//! in real time until SIGINT or SIGTERM, then exits 0. The log holds one JSON line per line taken
//! from the receive buffer, per overflow and per real-time command, written as they happen.

use std::io::Write as _;
use std::sync::atomic::Ordering;

use clap::Args;
use mandrel_drive::sim::winder::{Event, Winder};
use mandrel_drive::sim::{Clock as _, POLL_PERIOD, WallClock};
use paths::link::Link as _;

use super::pty::{Ptys, Signals};
use super::{Failure, print};

/// Arguments of `windcell sim-grbl`.
#[derive(Debug, Args)]
pub struct SimGrblArgs {
    /// Serve on a new pseudo-terminal and print its device path (the only transport; the flag may
    /// be given or left out).
    #[arg(long)]
    pub pty: bool,
    /// Log every line received, every overflow and every real-time command as JSON lines.
    #[arg(long, value_name = "FILE")]
    pub log: Option<std::path::PathBuf>,
    /// Motion runs this many times faster than commanded (1 = real time).
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    pub time_scale: f64,
}

fn record(event: &Event, t_s: f64) -> serde_json::Value {
    match event {
        Event::Line { n, text, rx_bytes } => {
            serde_json::json!({"t_s": t_s, "line": n, "text": text, "rx_bytes": rx_bytes})
        }
        Event::Overflow { bytes } => serde_json::json!({"t_s": t_s, "overflow_bytes": bytes}),
        Event::Realtime { what } => serde_json::json!({"t_s": t_s, "realtime": what}),
    }
}

/// Runs the simulator until SIGINT or SIGTERM.
pub fn run(args: SimGrblArgs) -> Result<(), Failure> {
    if !(args.time_scale.is_finite()
        && args.time_scale > 0.0
        && args.time_scale <= crate::cli::MAX_TIME_SCALE)
    {
        return Err(Failure::input(format!(
            "sim-grbl: --time-scale {} must be a positive number, at most {}",
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
    let signals = Signals::register("sim-grbl", false)?;
    let ptys = Ptys::open("sim-grbl", 1)?;
    print(&format!("{}\n", ptys.paths()?.join("\n")))?;
    let clock = WallClock::new();
    let mut winder = Winder::new(args.time_scale);
    let mut buf = [0u8; 512];
    ptys.serve(|masters| -> std::io::Result<()> {
        let Some(mut master) = masters.into_iter().next() else {
            return Ok(());
        };
        while !signals.stop.load(Ordering::Relaxed) {
            let n = master.read_timeout(&mut buf, POLL_PERIOD)?;
            let now = clock.now_s();
            match buf.get(..n) {
                Some(bytes) if n > 0 => winder.receive(bytes, now),
                _ => winder.poll(now),
            }
            let events = winder.take_events();
            if let Some(file) = log.as_mut()
                && !events.is_empty()
            {
                for e in &events {
                    writeln!(file, "{}", record(e, now))?;
                }
                file.flush()?;
            }
            let out = winder.take_output();
            if !out.is_empty() {
                master.write_all(&out)?;
            }
        }
        Ok(())
    })
}
