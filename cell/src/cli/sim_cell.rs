//! `windcell sim-cell --pty`: the simulated cell (both simulators and their sync lines, one clock)
//! served in real time on two pseudo-terminals, with the PC's side of the sync lines on a local
//! socket (pseudo-terminals carry no modem lines). Prints the robot's pty, the indexer's pty and
//! the socket, one per line.
//!
//! Socket protocol (one line each way, docs/file-formats.md "sim-cell sync socket"): `start 1` /
//! `start 0` drive the start output and answer `ok`; `lines` answers
//! `in_position <0|1> estop <0|1>`.

use std::io::{BufRead, BufReader, Write};
use std::os::unix::net::{UnixListener, UnixStream};
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use asea_protocol::sim::MotionParams;
use cell::run::device::{SyncLines, Timebase};
use cell::sim::{SimCell, SimCellConfig, SimSync};
use clap::Args;
use paths::link::{Clock as _, Link};

use super::pty::{Ptys, Signals};
use super::{Failure, print};

/// Arguments of `windcell sim-cell`.
#[derive(Debug, Args)]
pub struct SimCellArgs {
    /// Serve on new pseudo-terminals and print their paths and the sync socket.
    #[arg(long)]
    pub pty: bool,
    /// Where to put the sync socket (default: a new temporary directory).
    #[arg(long, value_name = "PATH")]
    pub socket: Option<PathBuf>,
    /// Log every executed instruction as a JSON line.
    #[arg(long, value_name = "FILE")]
    pub log: Option<PathBuf>,
    /// Duration of the robot's home synchronisation, seconds.
    #[arg(long, default_value_t = MotionParams::default().home_s, allow_negative_numbers = true)]
    pub home_s: f64,
}

fn serve_sync(stream: UnixStream, mut sync: SimSync, stop: Arc<AtomicBool>) {
    let Ok(mut out) = stream.try_clone() else {
        return;
    };
    let reader = BufReader::new(stream);
    for line in reader.lines() {
        let Ok(line) = line else { return };
        if stop.load(Ordering::Relaxed) {
            return;
        }
        let reply = match line.trim() {
            "start 1" => sync.set_start(true).map(|()| "ok".to_string()),
            "start 0" => sync.set_start(false).map(|()| "ok".to_string()),
            "lines" => sync.in_position().and_then(|i| {
                sync.estop()
                    .map(|e| format!("in_position {} estop {}", u8::from(i), u8::from(e)))
            }),
            other => Ok(format!("? {other}")),
        };
        let text = reply.unwrap_or_else(|e| format!("? {e}"));
        if writeln!(out, "{text}").is_err() {
            return;
        }
    }
}

/// Runs the simulated cell until SIGINT or SIGTERM.
pub fn run(args: SimCellArgs) -> Result<(), Failure> {
    if !args.pty {
        return Err(Failure::input(
            "sim-cell: --pty is required (the cell serves on pseudo-terminals)",
        ));
    }
    if !(args.home_s.is_finite() && (0.0..=crate::cli::MAX_SIM_SECONDS).contains(&args.home_s)) {
        return Err(Failure::input(format!(
            "sim-cell: --home-s {}: expected a time of 0 … {} s",
            sequences::error::shown(args.home_s),
            crate::cli::MAX_SIM_SECONDS
        )));
    }
    let stop = Signals::register("sim-cell", false)?.stop;
    let cell = SimCell::new(&SimCellConfig {
        robot: MotionParams {
            home_s: args.home_s,
            ..MotionParams::default()
        },
        ..SimCellConfig::default()
    });
    if let Some(p) = &args.log {
        let f = std::fs::File::create(p)
            .map_err(|e| Failure::input(format!("{}: {e}", p.display())))?;
        cell.log_to(f).map_err(Failure::runtime)?;
    }
    let ptys = Ptys::open("sim-cell", 2)?;
    let socket = args.socket.clone().unwrap_or_else(|| {
        std::env::temp_dir().join(format!("windcell-sim-cell-{}.sock", std::process::id()))
    });
    let listener = UnixListener::bind(&socket)
        .map_err(|e| Failure::input(format!("{}: {e}", socket.display())))?;
    listener.set_nonblocking(true).map_err(Failure::runtime)?;
    let paths = ptys.paths()?;
    print(&format!("{}\n{}\n", paths.join("\n"), socket.display()))?;
    let mut robot_link = cell.robot_link();
    let mut x_link = cell.indexer_link();
    let time = cell.timebase();
    let epoch = Instant::now();
    let mut buf = [0u8; 256];
    let poll = Duration::from_millis(1);
    let result = ptys.serve(|masters| -> Result<(), std::io::Error> {
        let [mut robot_master, mut x_master] = <[_; 2]>::try_from(masters)
            .map_err(|_| std::io::Error::other("two pseudo-terminals"))?;
        while !stop.load(Ordering::Relaxed) {
            if let Ok((stream, _)) = listener.accept() {
                stream.set_nonblocking(false)?;
                let (sync, stop) = (cell.sync_lines(), stop.clone());
                std::thread::spawn(move || serve_sync(stream, sync, stop));
            }
            // Host bytes to the devices (the cell paces them at the line's baud rate).
            for (master, link) in [
                (&mut robot_master, &mut robot_link as &mut dyn Link),
                (&mut x_master, &mut x_link),
            ] {
                let n = master.read_timeout(&mut buf, poll)?;
                if n > 0 {
                    link.write_all(&buf[..n])?;
                }
            }
            // The cell's clock follows the wall clock.
            let behind = epoch.elapsed().saturating_sub(cell.clock().now());
            if !behind.is_zero() {
                time.sleep(behind);
            }
            for (master, link) in [
                (&mut robot_master, &mut robot_link as &mut dyn Link),
                (&mut x_master, &mut x_link),
            ] {
                let n = link.read_timeout(&mut buf, Duration::ZERO)?;
                if n > 0 {
                    std::io::Write::write_all(&mut ***master, &buf[..n])?;
                }
            }
        }
        Ok(())
    });
    let _ = std::fs::remove_file(&socket);
    result
}
