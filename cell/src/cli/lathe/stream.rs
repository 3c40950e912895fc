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
fn load(path: &std::path::Path) -> Result<(Program, Outline), Failure> {
    // A device, FIFO or folder is refused before it is opened, and the size is capped: a
    // program the controller can take is far below the robot-program cap.
    let text = sequences::source::read_text(path, sequences::source::MAX_PROGRAM_BYTES)
        .map_err(Failure::input)?;
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

/// Streams the program until every line is acknowledged: arguments → the whole file checked →
/// the port opened → the stream → the report.
pub fn run(args: LatheStreamArgs) -> Result<(), Failure> {
    check_args(&args)?;
    let (program, outline) = load(&args.file)?;
    let flow = match args.flow {
        FlowArg::Counting => Flow::CharacterCounting {
            rx_buffer: GRBL_RX_BUFFER,
        },
        FlowArg::OkPerLine => Flow::OkPerLine,
    };
    let stop = stop_on_signals()?;
    let port = open_port(&args)?;
    let console = operator_console();
    let mut stream = Stream::new(&args, &outline, program, flow, port);
    stream.send_all(&stop, &console)?;
    stream.finish();
    Ok(())
}

/// The longest `--silence-s` and `--progress-every-s`, s: an hour (a longer silence is no
/// watch at all, and a duration of 1e308 s cannot be made).
const MAX_WAIT_S: f64 = 3600.0;

/// Baud rates a serial port can be asked for (50 … 4 000 000, the range Linux's termios offers).
const BAUD_RANGE: std::ops::RangeInclusive<u32> = 50..=4_000_000;

fn check_args(args: &LatheStreamArgs) -> Result<(), Failure> {
    for (flag, value) in [
        ("--silence-s", args.silence_s),
        ("--progress-every-s", args.progress_every_s),
    ] {
        if !(value.is_finite() && value > 0.0 && value <= MAX_WAIT_S) {
            return Err(Failure::input(format!(
                "lathe stream: {flag} {} must be a positive number of seconds, at most {MAX_WAIT_S}",
                sequences::error::shown(value)
            )));
        }
    }
    if !BAUD_RANGE.contains(&args.baud) {
        return Err(Failure::input(format!(
            "lathe stream: --baud {} is outside {} … {}",
            args.baud,
            BAUD_RANGE.start(),
            BAUD_RANGE.end()
        )));
    }
    Ok(())
}

/// A flag Ctrl-C (and SIGTERM) raises.
fn stop_on_signals() -> Result<Arc<AtomicBool>, Failure> {
    let stop = Arc::new(AtomicBool::new(false));
    for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register(signal, stop.clone())
            .map_err(|e| Failure::runtime(format!("lathe stream: signal handler: {e}")))?;
    }
    Ok(stop)
}

/// The controller's serial port.
type Port = mandrel_drive::link::SerialLink<Box<dyn serialport::SerialPort>>;

/// The controller's serial port, its stale input discarded.
fn open_port(args: &LatheStreamArgs) -> Result<Port, Failure> {
    let mut port = serialport::new(&args.port, args.baud)
        .timeout(Duration::from_millis(10))
        .open()
        .map(mandrel_drive::link::SerialLink)
        // A port that does not exist, is not a terminal or is busy is bad input: nothing has
        // been sent (docs/file-formats.md, "Cell file").
        .map_err(|e| Failure::input(format!("--port {}: {e}", args.port)))?;
    port.discard_input()
        .map_err(|e| Failure::runtime(format!("{}: {e}", args.port)))?;
    Ok(port)
}

/// Operator console on standard input: `p` pause at the next layer, `r` resume (the first
/// character of each line).
fn operator_console() -> mpsc::Receiver<char> {
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
    console
}

/// A stream under way: the program's streamer, the port, the progress display.
struct Stream<'a> {
    args: &'a LatheStreamArgs,
    outline: &'a Outline,
    /// The file's name as shown.
    file: String,
    /// Lines to send.
    total: usize,
    /// The lines that start a layer.
    layer_starts: Vec<usize>,
    streamer: Streamer,
    port: Port,
    watch: Watch<'a>,
    announced_pause: bool,
}

impl<'a> Stream<'a> {
    /// Announces the start (`--json`).
    fn new(
        args: &'a LatheStreamArgs,
        outline: &'a Outline,
        program: Program,
        flow: Flow,
        port: Port,
    ) -> Self {
        let watch = Watch::new(
            outline,
            if args.json {
                Show::Json
            } else if std::io::stderr().is_terminal() {
                Show::Terminal
            } else {
                Show::Plain(Duration::from_secs_f64(args.progress_every_s))
            },
        );
        let stream = Stream {
            args,
            outline,
            file: args.file.display().to_string(),
            total: program.lines.len(),
            layer_starts: program.layer_starts.clone(),
            streamer: Streamer::new(program, flow),
            port,
            watch,
            announced_pause: false,
        };
        if args.json {
            show(Some(Shown::Event(
                serde_json::json!({"event": "start", "file": stream.file,
                    "lines": stream.total, "layers": outline.layers.len()}),
            )));
        }
        stream
    }

    /// Where to restart after a stop now.
    fn restart(&self) -> String {
        restart_hint(self.outline, &self.file, self.streamer.acknowledged())
    }

    /// A failure that ends the stream: what went wrong, then the line to restart from.
    fn fail(&mut self, what: String) -> Failure {
        self.watch.end_line();
        Failure::runtime(format!("{what}; {}", self.restart()))
    }

    /// Sends, listens and shows progress until every line is acknowledged; every failure names
    /// the line to restart from.
    fn send_all(
        &mut self,
        stop: &AtomicBool,
        console: &mpsc::Receiver<char>,
    ) -> Result<(), Failure> {
        let mut buf = [0u8; 512];
        let mut replies = ReplyLines::new();
        let mut last_heard = Instant::now();
        let mut last_status = Instant::now();
        while !self.streamer.is_done() {
            if stop.load(Ordering::Relaxed) {
                return Err(self.interrupted());
            }
            show(
                self.watch
                    .update(self.streamer.sent(), self.streamer.acknowledged(), false),
            );
            self.obey(console);
            self.send_ready()?;
            self.announce_pause();
            // `?` is GRBL's real-time status request; a Marlin controller (one line per `ok`)
            // would take it as part of the next line.
            if self.args.flow == FlowArg::Counting && last_status.elapsed() >= STATUS_PERIOD {
                if let Err(e) = self.port.write_all(&[STATUS]) {
                    return Err(self.fail(format!("{}: {e}", self.args.port)));
                }
                last_status = Instant::now();
            }
            let n = match self.port.read_timeout(&mut buf, Duration::from_millis(5)) {
                Ok(n) => n,
                Err(e) => return Err(self.fail(format!("{}: {e}", self.args.port))),
            };
            if n > 0 {
                last_heard = Instant::now();
            } else if last_heard.elapsed() > Duration::from_secs_f64(self.args.silence_s) {
                return Err(self.fail(format!(
                    "{}: no reply from the controller in {} s after {} of {} lines",
                    self.args.port,
                    self.args.silence_s,
                    self.streamer.sent(),
                    self.total
                )));
            }
            for &b in buf.get(..n).unwrap_or_default() {
                if let Some(text) = replies.push(b)
                    && let Err(e) = self.streamer.on_reply(&text)
                {
                    return Err(self.fail(format!("{}: {e}", self.args.file.display())));
                }
            }
        }
        Ok(())
    }

    /// Ctrl-C: feed hold and soft reset sent, the stop reported, exit 130.
    fn interrupted(&mut self) -> Failure {
        let bytes = self.streamer.stop();
        self.watch.end_line();
        let sent = self.port.write_all(&bytes);
        let message = format!(
            "lathe stream: interrupted after {} of {} lines: feed hold and reset {}; {}",
            self.streamer.sent(),
            self.total,
            if sent.is_ok() {
                "sent"
            } else {
                "could not be sent"
            },
            self.restart()
        );
        if self.args.json {
            show(Some(Shown::Event(serde_json::json!({"event": "stopped",
                    "reason": "interrupted", "acknowledged": self.streamer.acknowledged(),
                    "restart": self.restart()}))));
        }
        Failure {
            message,
            exit_code: EXIT_INTERRUPTED,
        }
    }

    /// The operator's `p` (pause at the next layer) and `r` (resume).
    fn obey(&mut self, console: &mpsc::Receiver<char>) {
        while let Ok(c) = console.try_recv() {
            match c {
                'p' => self.streamer.request_pause(),
                'r' => {
                    self.streamer.resume();
                    self.announced_pause = false;
                    eprintln!("lathe stream: resumed");
                }
                _ => {}
            }
        }
    }

    /// Writes every line the flow control lets go now.
    fn send_ready(&mut self) -> Result<(), Failure> {
        while let Some(line) = self.streamer.poll_send() {
            let line = line.to_string();
            if let Err(e) = self.port.write_all(line.as_bytes()) {
                return Err(self.fail(format!("{}: {e}", self.args.port)));
            }
        }
        Ok(())
    }

    /// Says once where a requested pause took hold.
    fn announce_pause(&mut self) {
        if let Some(at) = self.streamer.paused_at()
            && !self.announced_pause
        {
            let layer = self
                .layer_starts
                .iter()
                .position(|&s| s == at)
                .map_or(0, |i| i + 1);
            self.watch.end_line();
            eprintln!(
                "lathe stream: paused before layer {layer} (line {} of {}); `r` resumes",
                at + 1,
                self.total
            );
            self.announced_pause = true;
        }
    }

    /// The last progress, the `done` event, the closing line.
    fn finish(&mut self) {
        show(
            self.watch
                .update(self.streamer.sent(), self.streamer.acknowledged(), true),
        );
        self.watch.end_line();
        if self.args.json {
            show(Some(Shown::Event(
                serde_json::json!({"event": "done", "lines": self.total,
                    "elapsed_s": self.watch.elapsed().as_secs_f64()}),
            )));
        }
        eprintln!("lathe stream: {} lines sent and acknowledged", self.total);
    }
}
