//! `windcell lathe stream FILE --port PATH [--baud B] [--flow counting|ok-per-line] [--json]`:
//! streams a planned G-code program to a GRBL-class or Marlin controller over a serial port
//! (docs/lathe.md, "Streaming to a GRBL controller", "Watching a stream"): the whole file checked
//! first, progress shown while it streams, the line to restart from after a stop.
//!
//! Character counting keeps the controller's 128-byte receive buffer full; `ok-per-line` (Marlin,
//! and the fallback) waits for each `ok`. Ctrl-C sends feed hold and soft reset and exits 130.
//! On standard input, `p` asks to pause at the next layer boundary (a `layer` comment in the
//! program) and `r` resumes. A refused line or a silent link ends the stream with exit 1.

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use cell::lathe::stream_watch::{Outline, Show, Shown, Watch, restart_hint};
use clap::{Args, ValueEnum};
use mandrel_drive::Link as _;
use mandrel_drive::grbl::STATUS;
use mandrel_drive::stream::{Flow, GRBL_RX_BUFFER, Program, ReplyLines, Streamer};
use std::io::IsTerminal as _;

use super::super::Failure;
use super::super::run::EXIT_INTERRUPTED;

/// How lines are paced.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum FlowArg {
    /// GRBL character counting (fill the 128-byte receive buffer).
    Counting,
    /// One line per `ok` (Marlin; the fallback).
    OkPerLine,
}

/// Arguments of `windcell lathe stream`.
#[derive(Debug, Args)]
pub struct LatheStreamArgs {
    /// The G-code program (from `windcell lathe plan --dialect grbl` or `marlin`).
    pub file: PathBuf,
    /// Serial port of the controller.
    #[arg(long)]
    pub port: String,
    /// Baud rate.
    #[arg(long, default_value_t = 115_200, allow_negative_numbers = true)]
    pub baud: u32,
    /// Flow control.
    #[arg(long, value_enum, default_value = "counting")]
    pub flow: FlowArg,
    /// Seconds without any byte from the controller (it is asked for status every 0.25 s) after
    /// which the link counts as lost.
    #[arg(long, default_value_t = 5.0, allow_negative_numbers = true)]
    pub silence_s: f64,
    /// Progress as JSON events on standard output (one per line: start, layer, progress every
    /// second, done or stopped with the line to restart from).
    #[arg(long)]
    pub json: bool,
    /// Seconds between plain progress lines when standard error is not a terminal.
    #[arg(
        long,
        default_value_t = 5.0,
        allow_negative_numbers = true,
        value_name = "S"
    )]
    pub progress_every_s: f64,
}

/// How often a status report is asked for (also the link's heartbeat).
const STATUS_PERIOD: Duration = Duration::from_millis(250);

/// Reads and checks the whole program before anything is sent: every line must be one the
/// controller can hold ([`cell::lathe::stream_watch::check_line`]) and fit the receive buffer.
fn load(path: &PathBuf) -> Result<(Program, Outline), Failure> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| Failure::input(format!("{}: {e}", path.display())))?;
    let outline = Outline::of(&text).map_err(|(line, r)| {
        Failure::input(format!(
            "{}:{line}:{}: {}",
            path.display(),
            r.column,
            r.message
        ))
    })?;
    for (i, raw) in text.lines().enumerate() {
        let code = Program::from_gcode(raw);
        if let Some(line) = code.lines.first()
            && line.len() > GRBL_RX_BUFFER
        {
            return Err(Failure::input(format!(
                "{}:{}:1: line of {} bytes does not fit the controller's {GRBL_RX_BUFFER}-byte receive buffer",
                path.display(),
                i + 1,
                line.len()
            )));
        }
    }
    let program = Program::from_gcode(&text);
    if program.lines.is_empty() {
        return Err(Failure::input(format!(
            "{}:1:1: no G-code lines to send",
            path.display()
        )));
    }
    Ok((program, outline))
}

/// Prints what the progress display says.
fn show(out: Option<Shown>) {
    match out {
        Some(Shown::Inline(t)) => eprint!("\r{t}\x1b[K"),
        Some(Shown::Line(t)) => eprintln!("lathe stream: {t}"),
        Some(Shown::Event(v)) => {
            let _ = crate::cli::print(&format!("{v}\n"));
        }
        None => {}
    }
}

/// Streams the program until every line is acknowledged.
pub fn run(args: LatheStreamArgs) -> Result<(), Failure> {
    if !(args.silence_s.is_finite() && args.silence_s > 0.0) {
        return Err(Failure::input(format!(
            "lathe stream: --silence-s {} must be a positive number",
            args.silence_s
        )));
    }
    if !(args.progress_every_s.is_finite() && args.progress_every_s > 0.0) {
        return Err(Failure::input(format!(
            "lathe stream: --progress-every-s {} must be a positive number",
            sequences::error::shown(args.progress_every_s)
        )));
    }
    let (program, outline) = load(&args.file)?;
    let total = program.lines.len();
    let file = args.file.display().to_string();
    let layers = program.layer_starts.clone();
    let flow = match args.flow {
        FlowArg::Counting => Flow::CharacterCounting {
            rx_buffer: GRBL_RX_BUFFER,
        },
        FlowArg::OkPerLine => Flow::OkPerLine,
    };
    let mut streamer = Streamer::new(program, flow);

    let stop = Arc::new(AtomicBool::new(false));
    for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register(signal, stop.clone())
            .map_err(|e| Failure::runtime(format!("lathe stream: signal handler: {e}")))?;
    }
    let mut port = serialport::new(&args.port, args.baud)
        .timeout(Duration::from_millis(10))
        .open()
        .map(mandrel_drive::link::SerialLink)
        .map_err(|e| Failure::runtime(format!("{}: {e}", args.port)))?;
    let link_failure = |e: std::io::Error| Failure::runtime(format!("{}: {e}", args.port));
    port.discard_input().map_err(link_failure)?;

    // Operator console on standard input: `p` pause at the next layer, `r` resume.
    let (tx, console) = mpsc::channel::<char>();
    std::thread::spawn(move || {
        let mut line = String::new();
        while std::io::stdin().read_line(&mut line).is_ok_and(|n| n > 0) {
            if let Some(c) = line.trim().chars().next()
                && tx.send(c).is_err()
            {
                return;
            }
            line.clear();
        }
    });

    let mut watch = Watch::new(
        &outline,
        if args.json {
            Show::Json
        } else if std::io::stderr().is_terminal() {
            Show::Terminal
        } else {
            Show::Plain(Duration::from_secs_f64(args.progress_every_s))
        },
    );
    if args.json {
        show(Some(Shown::Event(
            serde_json::json!({"event": "start", "file": file,
                "lines": total, "layers": outline.layers.len()}),
        )));
    }
    // Every failure from here names the line to restart from.
    let restart = |streamer: &Streamer| restart_hint(&outline, &file, streamer.acknowledged());
    let mut replies = ReplyLines::new();
    let mut buf = [0u8; 512];
    let mut last_heard = Instant::now();
    let mut last_status = Instant::now();
    let mut announced_pause = false;
    let silence = Duration::from_secs_f64(args.silence_s);
    while !streamer.is_done() {
        if stop.load(Ordering::Relaxed) {
            let bytes = streamer.stop();
            watch.end_line();
            let sent = port.write_all(&bytes);
            let message = format!(
                "lathe stream: interrupted after {} of {total} lines: feed hold and reset {}; {}",
                streamer.sent(),
                if sent.is_ok() {
                    "sent"
                } else {
                    "could not be sent"
                },
                restart(&streamer)
            );
            if args.json {
                show(Some(Shown::Event(serde_json::json!({"event": "stopped",
                        "reason": "interrupted", "acknowledged": streamer.acknowledged(),
                        "restart": restart(&streamer)}))));
            }
            return Err(Failure {
                message,
                exit_code: EXIT_INTERRUPTED,
            });
        }
        let out = watch.update(streamer.sent(), streamer.acknowledged(), false);
        show(out);
        while let Ok(c) = console.try_recv() {
            match c {
                'p' => streamer.request_pause(),
                'r' => {
                    streamer.resume();
                    announced_pause = false;
                    eprintln!("lathe stream: resumed");
                }
                _ => {}
            }
        }
        while let Some(line) = streamer.poll_send() {
            let line = line.to_string();
            if let Err(e) = port.write_all(line.as_bytes()) {
                watch.end_line();
                return Err(Failure::runtime(format!(
                    "{}: {e}; {}",
                    args.port,
                    restart(&streamer)
                )));
            }
        }
        if let Some(at) = streamer.paused_at()
            && !announced_pause
        {
            let layer = layers.iter().position(|&s| s == at).map_or(0, |i| i + 1);
            watch.end_line();
            eprintln!(
                "lathe stream: paused before layer {layer} (line {} of {total}); `r` resumes",
                at + 1
            );
            announced_pause = true;
        }
        // `?` is GRBL's real-time status request; a Marlin controller (one line per `ok`) would
        // take it as part of the next line.
        if args.flow == FlowArg::Counting && last_status.elapsed() >= STATUS_PERIOD {
            if let Err(e) = port.write_all(&[STATUS]) {
                watch.end_line();
                return Err(Failure::runtime(format!(
                    "{}: {e}; {}",
                    args.port,
                    restart(&streamer)
                )));
            }
            last_status = Instant::now();
        }
        let n = match port.read_timeout(&mut buf, Duration::from_millis(5)) {
            Ok(n) => n,
            Err(e) => {
                watch.end_line();
                return Err(Failure::runtime(format!(
                    "{}: {e}; {}",
                    args.port,
                    restart(&streamer)
                )));
            }
        };
        if n > 0 {
            last_heard = Instant::now();
        } else if last_heard.elapsed() > silence {
            watch.end_line();
            return Err(Failure::runtime(format!(
                "{}: no reply from the controller in {} s after {} of {total} lines; {}",
                args.port,
                args.silence_s,
                streamer.sent(),
                restart(&streamer)
            )));
        }
        for &b in buf.get(..n).unwrap_or_default() {
            if let Some(text) = replies.push(b)
                && let Err(e) = streamer.on_reply(&text)
            {
                watch.end_line();
                return Err(Failure::runtime(format!(
                    "{}: {e}; {}",
                    args.file.display(),
                    restart(&streamer)
                )));
            }
        }
    }
    let out = watch.update(streamer.sent(), streamer.acknowledged(), true);
    show(out);
    watch.end_line();
    if args.json {
        show(Some(Shown::Event(
            serde_json::json!({"event": "done", "lines": total,
                "elapsed_s": watch.elapsed().as_secs_f64()}),
        )));
    }
    eprintln!("lathe stream: {total} lines sent and acknowledged");
    Ok(())
}
