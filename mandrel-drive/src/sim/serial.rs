//! A serial line on virtual time, and a G-code stream over it to the GRBL simulator: how much of
//! the wire a flow control uses (docs/lathe.md, "Streaming to a GRBL controller").
//!
//! Each direction of the line ([`Wire`]) is serialised on its own (full duplex): a byte takes
//! [`BITS_PER_BYTE`] bit times (8N1: start, 8 data, stop; 86.806 µs at 115 200 baud), bytes leave
//! one after the other as soon as the sender has written them and the line is free, and each is
//! delivered a fixed latency after its stop bit (a USB serial adapter's latency timer; putting the
//! delay before the UART instead gives the same arrival times). [`stream`] drives the real
//! [`Streamer`] against the real [`Winder`] through two wires, one event at a time: every byte
//! reaches the controller's 128-byte receive buffer at its own arrival time, the controller's
//! replies (`ok\r\n`, four bytes) take their own wire time back, and the controller's motion runs
//! on the same clock (its planner takes a waiting line when a block ends).

use std::collections::VecDeque;

use crate::sim::winder::Winder;
use crate::stream::{ReplyLines, StreamError, Streamer};

/// Bit times per byte on an 8N1 line.
pub const BITS_PER_BYTE: f64 = 10.0;

/// A USB serial adapter's one-way latency, s: 1 ms, a full-speed USB frame (an FTDI adapter's
/// latency timer set to 1 ms; its default of 16 ms is far worse, see docs/lathe.md).
pub const USB_LATENCY_S: f64 = 0.001;

/// A serial line's timing.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LineTiming {
    /// Baud rate, bits per second.
    pub baud: f64,
    /// One-way latency added to every byte after its stop bit, s.
    pub latency_s: f64,
}

impl LineTiming {
    /// `baud` with no latency (a UART wired to the controller).
    pub fn direct(baud: f64) -> LineTiming {
        LineTiming {
            baud,
            latency_s: 0.0,
        }
    }

    /// `baud` behind a USB serial adapter ([`USB_LATENCY_S`]).
    pub fn usb(baud: f64) -> LineTiming {
        LineTiming {
            baud,
            latency_s: USB_LATENCY_S,
        }
    }

    /// Time one byte takes on the line, s.
    pub fn byte_s(&self) -> f64 {
        BITS_PER_BYTE / self.baud
    }

    /// Bytes per second the line carries back to back.
    pub fn bytes_per_s(&self) -> f64 {
        self.baud / BITS_PER_BYTE
    }
}

/// One direction of a serial line: bytes in transit with their arrival times.
#[derive(Debug, Clone)]
pub struct Wire {
    timing: LineTiming,
    free_s: f64,
    busy_s: f64,
    in_transit: VecDeque<(f64, u8)>,
}

impl Wire {
    /// An idle wire.
    pub fn new(timing: LineTiming) -> Wire {
        Wire {
            timing,
            free_s: 0.0,
            busy_s: 0.0,
            in_transit: VecDeque::new(),
        }
    }

    /// The sender writes `bytes` at `now_s`: they go out after whatever is still being sent.
    pub fn send(&mut self, bytes: &[u8], now_s: f64) {
        if bytes.is_empty() {
            return;
        }
        let byte_s = self.timing.byte_s();
        let start = self.free_s.max(now_s);
        for (i, &b) in bytes.iter().enumerate() {
            let stop_bit = start + (i + 1) as f64 * byte_s;
            self.in_transit
                .push_back((stop_bit + self.timing.latency_s, b));
        }
        self.free_s = start + bytes.len() as f64 * byte_s;
        self.busy_s += self.free_s - start;
    }

    /// When the next byte arrives at the far end.
    pub fn next_arrival_s(&self) -> Option<f64> {
        self.in_transit.front().map(|&(t, _)| t)
    }

    /// The next byte, if it has arrived by `now_s`.
    pub fn receive(&mut self, now_s: f64) -> Option<u8> {
        if self.next_arrival_s()? <= now_s {
            return self.in_transit.pop_front().map(|(_, b)| b);
        }
        None
    }

    /// Total time the line has carried (or is booked to carry) bytes, s.
    pub fn busy_s(&self) -> f64 {
        self.busy_s
    }
}

/// What a [`stream`] measured.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StreamRun {
    /// The line's timing.
    pub timing: LineTiming,
    /// Lines sent and acknowledged.
    pub lines: usize,
    /// Bytes of those lines, newlines included.
    pub bytes: usize,
    /// Virtual time from the first byte written to the last `ok` read, s.
    pub elapsed_s: f64,
    /// Time the host→controller direction carried bytes, s.
    pub to_controller_busy_s: f64,
}

impl StreamRun {
    /// Lines acknowledged per second.
    pub fn lines_per_s(&self) -> f64 {
        self.lines as f64 / self.elapsed_s
    }

    /// Mean bytes per line, newline included.
    pub fn bytes_per_line(&self) -> f64 {
        self.bytes as f64 / self.lines as f64
    }

    /// Lines per second the wire carries back to back: bytes per second over the mean line.
    pub fn wire_lines_per_s(&self) -> f64 {
        self.timing.bytes_per_s() / self.bytes_per_line()
    }

    /// Achieved over the wire's line rate.
    pub fn wire_fraction(&self) -> f64 {
        self.lines_per_s() / self.wire_lines_per_s()
    }
}

/// Why a simulated stream ended early.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SerialStreamError {
    /// The controller refused a line (or a reply broke the flow control).
    #[error(transparent)]
    Stream(#[from] StreamError),
    /// Nothing left in transit or due at the controller with lines still unacknowledged (bytes
    /// lost to an overrun receive buffer, or motion that never ends).
    #[error("the line went quiet after {sent} lines sent")]
    Stalled {
        /// Lines sent when it went quiet.
        sent: usize,
    },
}

/// Streams `streamer`'s program to `winder` over a serial line with `timing`, on virtual time
/// starting at 0 (the controller's clock must not be past 0), until every line is acknowledged.
/// The host sends whatever the flow control allows the moment it reads a reply; the controller
/// takes each byte when it arrives. Status requests (`?`) are not sent.
pub fn stream(
    streamer: &mut Streamer,
    winder: &mut Winder,
    timing: LineTiming,
) -> Result<StreamRun, SerialStreamError> {
    let mut to_controller = Wire::new(timing);
    let mut to_host = Wire::new(timing);
    let mut replies = ReplyLines::new();
    let mut now = 0.0f64;
    let mut lines = 0usize;
    let mut bytes = 0usize;
    winder.poll(now);
    loop {
        while let Some(line) = streamer.poll_send() {
            lines += 1;
            bytes += line.len();
            to_controller.send(line.as_bytes(), now);
        }
        if streamer.is_done() {
            break;
        }
        let at_controller = to_controller.next_arrival_s();
        let motion = winder.next_event_s();
        let at_host = to_host.next_arrival_s();
        let next = [at_controller, motion, at_host]
            .into_iter()
            .flatten()
            .min_by(f64::total_cmp)
            .ok_or(SerialStreamError::Stalled {
                sent: streamer.sent(),
            })?;
        now = now.max(next);
        if at_controller == Some(next) {
            if let Some(b) = to_controller.receive(now) {
                winder.receive(&[b], now);
            }
            to_host.send(&winder.take_output(), now);
        } else if motion == Some(next) {
            winder.poll(now);
            to_host.send(&winder.take_output(), now);
        } else if let Some(text) = to_host.receive(now).and_then(|b| replies.push(b)) {
            streamer.on_reply(&text)?;
        }
    }
    Ok(StreamRun {
        timing,
        lines,
        bytes,
        elapsed_s: now,
        to_controller_busy_s: to_controller.busy_s(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stream::{Flow, GRBL_RX_BUFFER, Program};

    const BAUD: f64 = 115_200.0;

    #[test]
    fn a_byte_takes_ten_bit_times_and_the_latency() {
        let t = LineTiming {
            baud: BAUD,
            latency_s: 0.001,
        };
        assert_eq!(t.byte_s(), 10.0 / 115_200.0);
        assert!((t.byte_s() - 86.806e-6).abs() < 1e-9);
        assert_eq!(t.bytes_per_s(), 11_520.0);
        let mut w = Wire::new(t);
        assert_eq!(w.next_arrival_s(), None);
        w.send(b"ab", 0.5);
        // The second write queues behind the first.
        w.send(b"c", 0.5);
        assert_eq!(w.next_arrival_s(), Some(0.5 + t.byte_s() + 0.001));
        assert_eq!(w.receive(0.5), None, "not there yet");
        let mut got = Vec::new();
        let mut last = 0.0;
        while let Some(at) = w.next_arrival_s() {
            got.push(w.receive(at).unwrap());
            last = at;
        }
        assert_eq!(got, b"abc");
        assert!((last - (0.5 + 3.0 * t.byte_s() + 0.001)).abs() < 1e-12);
        assert!((w.busy_s() - 3.0 * t.byte_s()).abs() < 1e-15);
        // An idle line starts at once; nothing written books no time.
        w.send(b"", 2.0);
        assert_eq!(w.next_arrival_s(), None);
        w.send(b"d", 2.0);
        assert_eq!(w.next_arrival_s(), Some(2.0 + t.byte_s() + 0.001));
        assert!((w.busy_s() - 4.0 * t.byte_s()).abs() < 1e-15);
        assert_eq!(LineTiming::direct(BAUD).latency_s, 0.0);
        assert_eq!(LineTiming::usb(BAUD).latency_s, USB_LATENCY_S);
    }

    fn program(lines: &[&str]) -> Program {
        Program {
            lines: lines.iter().map(|l| format!("{l}\n")).collect(),
            layer_starts: vec![],
        }
    }

    #[test]
    fn one_line_per_ok_pays_the_line_the_reply_and_both_latencies() {
        // Two 10-byte lines, one at a time: each is 10 bytes out, `ok\r` back (the host has its
        // reply at the `\r`), and the latency each way.
        let timing = LineTiming {
            baud: BAUD,
            latency_s: 0.002,
        };
        let mut s = Streamer::new(program(&["G1 X1 F60", "G1 X2 F60"]), Flow::OkPerLine);
        let mut w = Winder::new(1.0);
        let run = stream(&mut s, &mut w, timing).unwrap();
        let b = timing.byte_s();
        let want = 2.0 * (10.0 * b + 3.0 * b + 2.0 * 0.002);
        assert!((run.elapsed_s - want).abs() < 1e-12, "{run:?}");
        assert_eq!((run.lines, run.bytes), (2, 20));
        assert!((run.to_controller_busy_s - 20.0 * b).abs() < 1e-12);
        assert_eq!(run.bytes_per_line(), 10.0);
        assert_eq!(run.wire_lines_per_s(), 1_152.0);
        assert!((run.lines_per_s() - 2.0 / want).abs() < 1e-9);
        assert!((run.wire_fraction() - 10.0 / (13.0 + 0.004 / b)).abs() < 1e-9);
        // Counting sends both at once: the second `ok` follows the last byte.
        let mut s = Streamer::new(
            program(&["G1 X1 F60", "G1 X2 F60"]),
            Flow::CharacterCounting {
                rx_buffer: GRBL_RX_BUFFER,
            },
        );
        let mut w = Winder::new(1.0);
        let run = stream(&mut s, &mut w, timing).unwrap();
        assert!(
            (run.elapsed_s - (23.0 * b + 0.004)).abs() < 1e-12,
            "{run:?}"
        );
    }

    #[test]
    fn a_refusal_ends_the_stream_and_lost_bytes_stall_it() {
        let mut s = Streamer::new(program(&["G93", "G5 X1", "G1 X1 F9"]), Flow::OkPerLine);
        let e = stream(&mut s, &mut Winder::new(1.0), LineTiming::usb(BAUD)).unwrap_err();
        assert!(
            matches!(
                &e,
                SerialStreamError::Stream(StreamError::Refused { line: 1, .. })
            ),
            "{e}"
        );
        // A host that believes the buffer is larger overruns it while motion (stopped here)
        // holds the planner: the lines waiting and lost never get their `ok`.
        let lines: Vec<String> = (0..40)
            .map(|i| format!("G91 G94 G1 X1 F1 N{i:03}"))
            .collect();
        let lines: Vec<&str> = lines.iter().map(String::as_str).collect();
        let mut s = Streamer::new(
            program(&lines),
            Flow::CharacterCounting { rx_buffer: 10_000 },
        );
        let mut w = Winder::new(0.0);
        let e = stream(&mut s, &mut w, LineTiming::direct(BAUD)).unwrap_err();
        assert_eq!(e, SerialStreamError::Stalled { sent: 40 });
        assert!(w.overflow_bytes() > 0);
    }
}
