//! Streaming a G-code program to a GRBL-class controller: character-counting flow control (keep
//! the controller's 128-byte receive buffer full; send a line as soon as the bytes of the lines
//! not yet acknowledged plus its own fit), or one line per `ok` (Marlin, and the fallback);
//! pause at the next layer boundary, resume, stop.
//!
//! Sans-IO: [`Streamer::poll_send`] hands out the next line when flow control allows,
//! [`Streamer::on_reply`] takes the controller's replies. A driver moves the bytes over a serial
//! port; [`simulate_link`] moves them over a simulated serial link on a virtual clock.

use std::collections::VecDeque;

use crate::grbl::{FEED_HOLD, SOFT_RESET};

/// GRBL's serial receive buffer, bytes.
pub const GRBL_RX_BUFFER: usize = 128;

/// How the host paces lines.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Flow {
    /// Character counting: as many lines in flight as fit in the receive buffer.
    CharacterCounting {
        /// The controller's receive buffer, bytes.
        rx_buffer: usize,
    },
    /// Send one line, wait for its `ok` (Marlin; the safe fallback).
    OkPerLine,
}

/// A program ready to stream: the lines to send (comments and blank lines dropped, each ending
/// in `\n`) and where each layer starts.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Program {
    /// Lines to send.
    pub lines: Vec<String>,
    /// Index of the first line of each layer (from the `(layer N …)` / `; layer N …` comments).
    pub layer_starts: Vec<usize>,
}

impl Program {
    /// Prepares G-code text: comments are not sent; a `layer` comment marks a boundary.
    pub fn from_gcode(text: &str) -> Program {
        let mut p = Program::default();
        for raw in text.lines() {
            let mut code = String::with_capacity(raw.len());
            let mut comment = String::new();
            let mut depth = 0;
            for ch in raw.chars() {
                match ch {
                    '(' => depth += 1,
                    ')' if depth > 0 => depth -= 1,
                    ';' if depth == 0 => {
                        comment.push_str(&raw[raw.find(';').unwrap_or(0) + 1..]);
                        break;
                    }
                    c if depth > 0 => comment.push(c),
                    c => code.push(c),
                }
            }
            if comment.trim_start().starts_with("layer ") {
                p.layer_starts.push(p.lines.len());
            }
            let code = code.trim();
            if !code.is_empty() && code != "%" {
                p.lines.push(format!("{code}\n"));
            }
        }
        p
    }
}

/// Why a stream ended early.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum StreamError {
    /// The controller refused a line.
    #[error("line {line} `{text}` refused: {reply}")]
    Refused {
        /// 0-based index of the refused line in the program.
        line: usize,
        /// The line.
        text: String,
        /// The controller's reply (`error:N`, `ALARM:N`).
        reply: String,
    },
    /// An `ok` arrived with no line in flight.
    #[error("an unexpected `ok` arrived (no line in flight)")]
    UnexpectedOk,
}

/// The streaming state machine.
#[derive(Debug, Clone)]
pub struct Streamer {
    program: Program,
    flow: Flow,
    next: usize,
    in_flight: VecDeque<usize>,
    in_flight_bytes: usize,
    pause_requested: bool,
    paused_at: Option<usize>,
    stopped: bool,
}

impl Streamer {
    /// A streamer for `program` with `flow`.
    pub fn new(program: Program, flow: Flow) -> Streamer {
        Streamer {
            program,
            flow,
            next: 0,
            in_flight: VecDeque::new(),
            in_flight_bytes: 0,
            pause_requested: false,
            paused_at: None,
            stopped: false,
        }
    }

    /// The next line to send now, or `None` if flow control, a pause or the end holds it back.
    /// The line counts as sent.
    pub fn poll_send(&mut self) -> Option<&str> {
        if self.stopped || self.next >= self.program.lines.len() {
            return None;
        }
        if self.pause_requested && self.program.layer_starts.contains(&self.next) && self.next > 0 {
            self.paused_at = Some(self.next);
            return None;
        }
        if self.paused_at.is_some() {
            return None;
        }
        let len = self.program.lines[self.next].len();
        let fits = match self.flow {
            Flow::CharacterCounting { rx_buffer } => {
                self.in_flight_bytes + len <= rx_buffer || self.in_flight.is_empty()
            }
            Flow::OkPerLine => self.in_flight.is_empty(),
        };
        if !fits {
            return None;
        }
        let i = self.next;
        self.next += 1;
        self.in_flight.push_back(i);
        self.in_flight_bytes += len;
        Some(&self.program.lines[i])
    }

    /// Takes one reply line from the controller. `ok` frees the oldest line in flight; `error:`
    /// and `ALARM:` end the stream; status reports and messages are ignored.
    pub fn on_reply(&mut self, reply: &str) -> Result<(), StreamError> {
        let reply = reply.trim();
        if reply == "ok" {
            let i = self
                .in_flight
                .pop_front()
                .ok_or(StreamError::UnexpectedOk)?;
            self.in_flight_bytes -= self.program.lines[i].len();
            return Ok(());
        }
        if reply.starts_with("error:") || reply.starts_with("ALARM:") {
            let line = self.in_flight.front().copied().unwrap_or(self.next);
            self.stopped = true;
            return Err(StreamError::Refused {
                line,
                text: self
                    .program
                    .lines
                    .get(line)
                    .map(|l| l.trim_end().to_string())
                    .unwrap_or_default(),
                reply: reply.to_string(),
            });
        }
        Ok(())
    }

    /// Asks to stop sending at the next layer boundary (lines in flight still complete).
    pub fn request_pause(&mut self) {
        self.pause_requested = true;
    }

    /// The line index of the layer boundary the stream is paused at, once it has got there.
    pub fn paused_at(&self) -> Option<usize> {
        self.paused_at
    }

    /// Continues after a pause.
    pub fn resume(&mut self) {
        self.pause_requested = false;
        self.paused_at = None;
    }

    /// Stops now: nothing more is sent; returns the real-time bytes that halt the controller
    /// (feed hold, then soft reset, which also flushes its buffers).
    pub fn stop(&mut self) -> [u8; 2] {
        self.stopped = true;
        [FEED_HOLD, SOFT_RESET]
    }

    /// Bytes sent and not yet acknowledged.
    pub fn in_flight_bytes(&self) -> usize {
        self.in_flight_bytes
    }

    /// Lines sent so far.
    pub fn sent(&self) -> usize {
        self.next
    }

    /// Every line sent and acknowledged.
    pub fn is_done(&self) -> bool {
        self.next >= self.program.lines.len() && self.in_flight.is_empty()
    }
}

/// A serial link and controller on a virtual clock, for measuring flow control.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinkModel {
    /// Baud rate (10 bits per byte: start, 8 data, stop).
    pub baud: f64,
    /// One-way latency added to every transfer (USB serial adapters: about 1 ms).
    pub latency_s: f64,
    /// Time the controller takes to parse a line and queue its block before answering `ok`.
    pub parse_s: f64,
}

/// What [`simulate_link`] measured.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinkReport {
    /// Virtual time to the last `ok`.
    pub elapsed_s: f64,
    /// Lines per second achieved.
    pub lines_per_s: f64,
    /// Lines per second the wire carries back to back (bytes per second / mean line length).
    pub wire_lines_per_s: f64,
    /// The largest number of bytes waiting in the controller's receive buffer.
    pub max_rx_bytes: usize,
}

impl LinkReport {
    /// Achieved over wire rate.
    pub fn efficiency(&self) -> f64 {
        self.lines_per_s / self.wire_lines_per_s
    }
}

/// Streams `program` through `streamer`'s flow control over a simulated link and controller on a
/// virtual clock: bytes leave the host one after the other at the baud rate, the controller takes
/// a line out of its receive buffer `parse_s` after its last byte arrived and answers `ok`
/// (4 bytes back over the wire); both directions add `latency_s`. The controller's planner is
/// never full (short lines of short moves), so the wire and the flow control set the pace.
pub fn simulate_link(mut streamer: Streamer, link: LinkModel) -> Result<LinkReport, StreamError> {
    let byte_s = 10.0 / link.baud;
    let mut now = 0.0f64;
    let mut wire_free = 0.0f64;
    let mut controller_free = 0.0f64;
    let mut back_wire_free = 0.0f64;
    // (time the ok reaches the host, line length) in order.
    let mut oks: VecDeque<f64> = VecDeque::new();
    // Controller receive buffer: (arrival of last byte, processed at, length) of lines in it.
    let mut rx: VecDeque<(f64, f64, usize)> = VecDeque::new();
    let mut max_rx = 0usize;
    let mut total_bytes = 0usize;
    let mut lines = 0usize;
    loop {
        while let Some(line) = streamer.poll_send() {
            let len = line.len();
            total_bytes += len;
            lines += 1;
            let start = (now + link.latency_s).max(wire_free);
            let arrived = start + len as f64 * byte_s;
            wire_free = arrived;
            let processed = arrived.max(controller_free) + link.parse_s;
            controller_free = processed;
            // Bytes in the receive buffer when this line has fully arrived.
            while rx.front().is_some_and(|&(_, done, _)| done <= start) {
                rx.pop_front();
            }
            rx.push_back((arrived, processed, len));
            max_rx = max_rx.max(rx.iter().map(|&(_, _, l)| l).sum());
            let ok_start = processed.max(back_wire_free);
            back_wire_free = ok_start + 4.0 * byte_s;
            oks.push_back(back_wire_free + link.latency_s);
        }
        if streamer.is_done() {
            break;
        }
        let Some(t) = oks.pop_front() else { break };
        now = now.max(t);
        streamer.on_reply("ok")?;
    }
    let elapsed_s = now;
    Ok(LinkReport {
        elapsed_s,
        lines_per_s: lines as f64 / elapsed_s,
        wire_lines_per_s: 1.0 / (total_bytes as f64 / lines as f64 * byte_s),
        max_rx_bytes: max_rx,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn short_lines(n: usize) -> Program {
        // Short feed lines as a 4-axis plan writes them (12–16 bytes).
        let lines = (0..n)
            .map(|i| format!("G1 X{}.{} A{} F900\n", i % 100, i % 7, i % 13))
            .collect();
        Program {
            lines,
            layer_starts: vec![0, n / 2],
        }
    }

    const LINK: LinkModel = LinkModel {
        baud: 115_200.0,
        latency_s: 0.001,
        parse_s: 0.000_05,
    };

    #[test]
    fn character_counting_keeps_the_wire_busy_and_one_per_ok_does_not() {
        let counting = simulate_link(
            Streamer::new(
                short_lines(5000),
                Flow::CharacterCounting {
                    rx_buffer: GRBL_RX_BUFFER,
                },
            ),
            LINK,
        )
        .unwrap();
        let one = simulate_link(Streamer::new(short_lines(5000), Flow::OkPerLine), LINK).unwrap();
        println!("character counting: {counting:?}\none line per ok: {one:?}");
        assert!(counting.efficiency() >= 0.95, "{counting:?}");
        assert!(counting.max_rx_bytes <= GRBL_RX_BUFFER, "{counting:?}");
        assert!(one.efficiency() < 0.5, "{one:?}");
        // Without adapter latency the ping-pong still loses the ok's return and the parse.
        let direct = LinkModel {
            latency_s: 0.0,
            ..LINK
        };
        let one = simulate_link(Streamer::new(short_lines(5000), Flow::OkPerLine), direct).unwrap();
        println!("one line per ok, no latency: {one:?}");
        assert!(one.efficiency() < 0.8, "{one:?}");
    }

    #[test]
    fn counting_never_overfills_the_buffer() {
        let mut s = Streamer::new(short_lines(100), Flow::CharacterCounting { rx_buffer: 128 });
        let mut sent = 0;
        while s.poll_send().is_some() {
            sent += 1;
        }
        assert!(s.in_flight_bytes() <= 128);
        assert!(
            s.in_flight_bytes() + 17 > 128,
            "the buffer is filled: {}",
            s.in_flight_bytes()
        );
        s.on_reply("ok").unwrap();
        assert!(s.poll_send().is_some());
        assert_eq!(s.sent(), sent + 1);
        // One per ok: one line in flight.
        let mut s = Streamer::new(short_lines(10), Flow::OkPerLine);
        assert!(s.poll_send().is_some());
        assert!(s.poll_send().is_none());
        s.on_reply("<Idle|MPos:0,0,0>").unwrap();
        assert!(s.poll_send().is_none());
        s.on_reply("ok").unwrap();
        assert!(s.poll_send().is_some());
    }

    #[test]
    fn pause_waits_for_the_next_layer_boundary() {
        let mut s = Streamer::new(short_lines(20), Flow::OkPerLine);
        s.poll_send().unwrap();
        s.request_pause();
        for _ in 0..9 {
            s.on_reply("ok").unwrap();
            assert!(s.poll_send().is_some());
        }
        s.on_reply("ok").unwrap();
        assert_eq!(s.sent(), 10);
        assert!(s.poll_send().is_none());
        assert_eq!(s.paused_at(), Some(10));
        s.resume();
        assert!(s.poll_send().is_some());
    }

    #[test]
    fn errors_and_stop_end_the_stream() {
        let mut s = Streamer::new(short_lines(10), Flow::OkPerLine);
        s.poll_send().unwrap();
        let e = s.on_reply("error:20").unwrap_err();
        assert!(matches!(e, StreamError::Refused { line: 0, .. }), "{e}");
        assert!(s.poll_send().is_none());
        let mut s = Streamer::new(short_lines(10), Flow::OkPerLine);
        assert_eq!(s.on_reply("ok"), Err(StreamError::UnexpectedOk));
        assert_eq!(s.stop(), [b'!', 0x18]);
        assert!(s.poll_send().is_none());
    }

    #[test]
    fn programs_drop_comments_and_mark_layers() {
        let p = Program::from_gcode(
            "(windcell)\nG21 G90 G93\n(layer 1 helical: 3 circuits)\nG0 X1\nG1 X2 F10\n\
             (layer 2 hoop: 0 circuits)\nG1 X3 F10 (end)\n%\n",
        );
        assert_eq!(
            p.lines,
            vec!["G21 G90 G93\n", "G0 X1\n", "G1 X2 F10\n", "G1 X3 F10\n"]
        );
        assert_eq!(p.layer_starts, vec![1, 3]);
        let m = Program::from_gcode("; layer 1 helical: 2 circuits\nG1 X1 F5 ; note\n");
        assert_eq!(m.lines, vec!["G1 X1 F5\n"]);
        assert_eq!(m.layer_starts, vec![0]);
    }
}
