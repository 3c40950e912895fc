//! Streaming a G-code program to a GRBL-class controller: character-counting flow control (keep
//! the controller's 128-byte receive buffer full; send a line as soon as the bytes of the lines
//! not yet acknowledged plus its own fit), or one line per `ok` (Marlin, and the fallback);
//! pause at the next layer boundary, resume, stop.
//!
//! Sans-IO: [`Streamer::poll_send`] hands out the next line when flow control allows,
//! [`Streamer::on_reply`] takes the controller's replies ([`ReplyLines`] cuts them out of the
//! bytes). A driver moves the bytes over a serial port (`windcell lathe stream`);
//! [`crate::sim::serial::stream`] moves them over a simulated serial line on virtual time to the
//! GRBL simulator ([`crate::sim::winder::Winder`]).

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
        // GRBL's `error:N` and `ALARM:N`; Marlin's `Error:` (a halt: this streamer sends no line
        // numbers, so Marlin has no resend to ask for).
        if reply.starts_with("error:") || reply.starts_with("ALARM:") || reply.starts_with("Error:")
        {
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

    /// Lines acknowledged so far (sent and no longer in flight).
    pub fn acknowledged(&self) -> usize {
        self.next - self.in_flight.len()
    }

    /// Every line sent and acknowledged.
    pub fn is_done(&self) -> bool {
        self.next >= self.program.lines.len() && self.in_flight.is_empty()
    }
}

/// Splits the controller's bytes into reply lines: `\r` or `\n` ends one (GRBL ends its replies
/// with `\r\n`, so a reply is known at its `\r`); empty lines are skipped.
#[derive(Debug, Clone, Default)]
pub struct ReplyLines {
    line: Vec<u8>,
}

impl ReplyLines {
    /// A splitter with nothing pending.
    pub fn new() -> ReplyLines {
        ReplyLines::default()
    }

    /// Takes one byte; returns the reply it completes, if any.
    pub fn push(&mut self, byte: u8) -> Option<String> {
        if byte == b'\n' || byte == b'\r' {
            if self.line.is_empty() {
                return None;
            }
            let text = String::from_utf8_lossy(&self.line).into_owned();
            self.line.clear();
            return Some(text);
        }
        self.line.push(byte);
        None
    }
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

    #[test]
    fn replies_end_at_a_carriage_return_or_a_newline() {
        let mut r = ReplyLines::new();
        let got: Vec<String> = b"ok\r\n\r\nerror:20\n<Idle|MPos:0>\rok"
            .iter()
            .filter_map(|&b| r.push(b))
            .collect();
        assert_eq!(got, vec!["ok", "error:20", "<Idle|MPos:0>"]);
        assert_eq!(r.push(b'\r').as_deref(), Some("ok"));
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
