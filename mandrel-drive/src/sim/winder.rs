//! A multi-axis GRBL 1.1 class controller for the lathe winder (axes X Y Z A B C), for streaming
//! tests over a real serial port (docs/lathe.md, "Streaming to a GRBL controller").
//!
//! The host side is modelled as GRBL does it: a 128-byte serial receive buffer, a line buffer of
//! 80 characters (spaces dropped), a planner of 15 blocks. A line leaves the receive buffer when
//! the planner takes it and is answered `ok` (or `error:N`) at that moment; motion then runs at the
//! commanded feed (`G93` inverse time: the block takes `1/F` min; `G94`: distance over `F`;
//! `G0`: distance over the rapid rate), scaled by a time factor so tests run fast. Bytes arriving
//! while the receive buffer is full are lost and counted: a host that sends more than the buffer
//! holds is caught, which is what character counting must never do.
//!
//! Real-time bytes are acted on at once and never buffered: `?` status report, `!` feed hold
//! (this model stops at once, without the deceleration ramp), `~` cycle start, `0x18` soft reset
//! (flushes the buffers and the planner, keeps the position, prints the banner).

use std::collections::VecDeque;

use crate::grbl::{CYCLE_START, FEED_HOLD, SOFT_RESET, STATUS};
use crate::stream::GRBL_RX_BUFFER;

/// GRBL's line buffer after whitespace is stripped, characters (`LINE_BUFFER_SIZE`).
pub const LINE_BUFFER: usize = 80;
/// Planner blocks GRBL can hold (`BLOCK_BUFFER_SIZE` 16, one kept free).
pub const PLANNER_BLOCKS: usize = 15;
/// Rapid (`G0`) rate, units/min.
pub const RAPID_PER_MIN: f64 = 5_000.0;
/// The start-up banner.
pub const BANNER: &str = "Grbl 1.1h ['$' for help]";
/// Axis letters in report order.
pub const AXES: [char; 6] = ['X', 'Y', 'Z', 'A', 'B', 'C'];

/// A block whose remaining time is within this of the time that passed counts as finished, so
/// that a poll at [`Winder::next_event_s`] ends the block despite rounding, s of motion.
pub const BLOCK_END_TOLERANCE_S: f64 = 1e-9;

/// GRBL `error:1`: a word without a letter.
pub const ERROR_LETTER: u16 = 1;
/// GRBL `error:2`: a value that is not a number.
pub const ERROR_NUMBER: u16 = 2;
/// GRBL `error:14`: the line is longer than the line buffer.
pub const ERROR_LINE_LENGTH: u16 = 14;
/// GRBL `error:20`: unsupported command.
pub const ERROR_UNSUPPORTED: u16 = 20;
/// GRBL `error:22`: feed rate undefined (or, in `G93`, missing from a `G1` line).
pub const ERROR_FEED: u16 = 22;

/// Something the simulator logs.
#[derive(Debug, Clone, PartialEq)]
pub enum Event {
    /// A line taken from the receive buffer (1-based count since start, the text without `\n`,
    /// the receive buffer's fill in bytes just before it was taken).
    Line {
        /// 1-based count of lines received since start.
        n: usize,
        /// The line as received.
        text: String,
        /// Receive-buffer fill, bytes, including this line.
        rx_bytes: usize,
    },
    /// Bytes lost because the receive buffer was full.
    Overflow {
        /// How many bytes were lost.
        bytes: usize,
    },
    /// A real-time byte (`?` excluded).
    Realtime {
        /// `feed_hold`, `cycle_start` or `reset`.
        what: &'static str,
    },
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct Block {
    from: [f64; 6],
    to: [f64; 6],
    duration_s: f64,
}

/// The simulated controller.
#[derive(Debug)]
pub struct Winder {
    time_scale: f64,
    rx: VecDeque<u8>,
    planner: VecDeque<Block>,
    running: Option<(Block, f64)>,
    position: [f64; 6],
    planned_end: [f64; 6],
    /// Modal motion: 0 (`G0`, GRBL's power-up mode) or 1 (`G1`).
    motion: u8,
    absolute: bool,
    inverse_time: bool,
    inch: bool,
    feed: Option<f64>,
    hold: bool,
    last_s: Option<f64>,
    lines: usize,
    overflow_bytes: usize,
    max_rx_bytes: usize,
    out: Vec<u8>,
    events: Vec<Event>,
}

impl Winder {
    /// A controller at rest at zero; motion runs `time_scale` times faster than commanded.
    pub fn new(time_scale: f64) -> Winder {
        Winder {
            time_scale,
            rx: VecDeque::with_capacity(GRBL_RX_BUFFER),
            planner: VecDeque::new(),
            running: None,
            position: [0.0; 6],
            planned_end: [0.0; 6],
            motion: 0,
            absolute: true,
            inverse_time: false,
            inch: false,
            feed: None,
            hold: false,
            last_s: None,
            lines: 0,
            overflow_bytes: 0,
            max_rx_bytes: 0,
            out: Vec::new(),
            events: Vec::new(),
        }
    }

    /// Bytes from the host at clock time `now_s`.
    pub fn receive(&mut self, bytes: &[u8], now_s: f64) {
        self.poll(now_s);
        let mut lost = 0;
        for &b in bytes {
            match b {
                STATUS => self.status(),
                FEED_HOLD => {
                    self.hold = true;
                    self.events.push(Event::Realtime { what: "feed_hold" });
                }
                CYCLE_START => {
                    self.hold = false;
                    self.events.push(Event::Realtime {
                        what: "cycle_start",
                    });
                }
                SOFT_RESET => self.reset(),
                _ if self.rx.len() >= GRBL_RX_BUFFER => lost += 1,
                _ => self.rx.push_back(b),
            }
            self.max_rx_bytes = self.max_rx_bytes.max(self.rx.len());
        }
        if lost > 0 {
            self.overflow_bytes += lost;
            self.events.push(Event::Overflow { bytes: lost });
        }
        self.poll(now_s);
    }

    /// Lets the clock run to `now_s`: motion advances, the planner takes lines.
    pub fn poll(&mut self, now_s: f64) {
        let dt = self.last_s.map_or(0.0, |t| (now_s - t).max(0.0));
        self.last_s = Some(now_s);
        if !self.hold {
            self.advance(dt * self.time_scale);
        }
        self.take_lines();
    }

    fn advance(&mut self, mut dt_s: f64) {
        loop {
            if self.running.is_none() {
                match self.planner.pop_front() {
                    Some(b) => self.running = Some((b, 0.0)),
                    None => return,
                }
            }
            let Some((block, elapsed)) = self.running.as_mut() else {
                return;
            };
            let left = block.duration_s - *elapsed;
            if dt_s + BLOCK_END_TOLERANCE_S < left {
                *elapsed += dt_s;
                let f = *elapsed / block.duration_s;
                for i in 0..6 {
                    self.position[i] = block.from[i] + (block.to[i] - block.from[i]) * f;
                }
                return;
            }
            dt_s -= left;
            self.position = block.to;
            self.running = None;
        }
    }

    fn take_lines(&mut self) {
        // The block being executed still holds its planner slot, as in GRBL.
        while self.blocks() < PLANNER_BLOCKS {
            let Some(end) = self.rx.iter().position(|&b| b == b'\n' || b == b'\r') else {
                return;
            };
            let raw: Vec<u8> = self.rx.drain(..=end).collect();
            let text = String::from_utf8_lossy(&raw[..end]).into_owned();
            if text.trim().is_empty() {
                continue;
            }
            self.lines += 1;
            self.events.push(Event::Line {
                n: self.lines,
                text: text.clone(),
                rx_bytes: raw.len() + self.rx.len(),
            });
            let reply = match self.execute(&text) {
                Ok(()) => "ok\r\n".to_string(),
                Err(code) => format!("error:{code}\r\n"),
            };
            self.out.extend_from_slice(reply.as_bytes());
        }
    }

    /// Interprets one line (the subset of GRBL 1.1 our `grbl` dialect emits, plus `G91`, `G94`
    /// and `G20`).
    fn execute(&mut self, text: &str) -> Result<(), u16> {
        let mut code = String::new();
        let mut depth = 0;
        for ch in text.chars() {
            match ch {
                '(' => depth += 1,
                ')' if depth > 0 => depth -= 1,
                ';' if depth == 0 => break,
                c if depth == 0 && !c.is_whitespace() => code.push(c.to_ascii_uppercase()),
                _ => {}
            }
        }
        if code.len() > LINE_BUFFER {
            return Err(ERROR_LINE_LENGTH);
        }
        let mut words: Vec<(char, f64)> = Vec::new();
        let mut chars = code.chars().peekable();
        while let Some(letter) = chars.next() {
            if !letter.is_ascii_alphabetic() {
                return Err(ERROR_LETTER);
            }
            let mut num = String::new();
            while let Some(&c) = chars.peek() {
                if c.is_ascii_digit() || c == '.' || c == '-' || c == '+' {
                    num.push(c);
                    chars.next();
                } else {
                    break;
                }
            }
            let v: f64 = num.parse().map_err(|_| ERROR_NUMBER)?;
            if !v.is_finite() {
                return Err(ERROR_NUMBER);
            }
            words.push((letter, v));
        }
        let mut motion: Option<u8> = None;
        let mut set_origin = false;
        let mut absolute = self.absolute;
        let mut inverse_time = self.inverse_time;
        let mut inch = self.inch;
        let mut feed = None;
        let mut axes: [Option<f64>; 6] = [None; 6];
        for &(letter, v) in &words {
            match letter {
                'G' => match v {
                    0.0 => motion = Some(0),
                    1.0 => motion = Some(1),
                    92.0 => set_origin = true,
                    90.0 => absolute = true,
                    91.0 => absolute = false,
                    93.0 => inverse_time = true,
                    94.0 => inverse_time = false,
                    20.0 => inch = true,
                    21.0 => inch = false,
                    17.0 | 18.0 | 19.0 => {}
                    _ => return Err(ERROR_UNSUPPORTED),
                },
                'M' => match v {
                    0.0 | 2.0 | 30.0 | 3.0 | 5.0 => {}
                    _ => return Err(ERROR_UNSUPPORTED),
                },
                'F' if v > 0.0 => feed = Some(v),
                'F' => return Err(ERROR_FEED),
                'N' => {}
                l => match AXES.iter().position(|&a| a == l) {
                    Some(i) => axes[i] = Some(v),
                    None => return Err(ERROR_UNSUPPORTED),
                },
            }
        }
        let unit = if inch { 25.4 } else { 1.0 };
        if set_origin {
            // G92: the current (planned) position takes the given coordinates; this model keeps
            // machine and work coordinates as one, so the offset simply renames the position.
            for (i, a) in axes.iter().enumerate() {
                if let Some(v) = a {
                    let shift = v * unit - self.planned_end[i];
                    self.planned_end[i] += shift;
                    self.position[i] += shift;
                    for b in self.planner.iter_mut() {
                        b.from[i] += shift;
                        b.to[i] += shift;
                    }
                    if let Some((b, _)) = self.running.as_mut() {
                        b.from[i] += shift;
                        b.to[i] += shift;
                    }
                }
            }
            self.commit_modes(absolute, inverse_time, inch, feed);
            return Ok(());
        }
        // The motion mode is modal (GRBL's group 1): a line of axis words alone moves as the
        // last G0 or G1 did.
        let motion = motion.unwrap_or(self.motion);
        if !axes.iter().any(Option::is_some) {
            self.motion = motion;
            self.commit_modes(absolute, inverse_time, inch, feed);
            return Ok(());
        }
        let mut to = self.planned_end;
        for (i, a) in axes.iter().enumerate() {
            if let Some(v) = a {
                to[i] = if absolute { v * unit } else { to[i] + v * unit };
            }
        }
        let dist = to
            .iter()
            .zip(self.planned_end)
            .map(|(a, b)| (a - b).powi(2))
            .sum::<f64>()
            .sqrt();
        let minutes = if motion == 0 {
            dist / RAPID_PER_MIN
        } else if inverse_time {
            1.0 / feed.ok_or(ERROR_FEED)?
        } else {
            dist / (feed.or(self.feed).ok_or(ERROR_FEED)? * unit)
        };
        self.motion = motion;
        self.commit_modes(absolute, inverse_time, inch, feed);
        let block = Block {
            from: self.planned_end,
            to,
            duration_s: minutes * 60.0,
        };
        self.planned_end = to;
        self.planner.push_back(block);
        Ok(())
    }

    fn blocks(&self) -> usize {
        self.planner.len() + usize::from(self.running.is_some())
    }

    fn commit_modes(&mut self, absolute: bool, inverse_time: bool, inch: bool, feed: Option<f64>) {
        self.absolute = absolute;
        self.inverse_time = inverse_time;
        self.inch = inch;
        if feed.is_some() {
            self.feed = feed;
        }
    }

    fn status(&mut self) {
        let state = if self.hold {
            "Hold:0"
        } else if self.running.is_some() || !self.planner.is_empty() {
            "Run"
        } else {
            "Idle"
        };
        let pos: Vec<String> = self.position.iter().map(|p| format!("{p:.3}")).collect();
        let report = format!(
            "<{state}|MPos:{}|Bf:{},{}|FS:{},0>\r\n",
            pos.join(","),
            PLANNER_BLOCKS - self.blocks(),
            GRBL_RX_BUFFER - self.rx.len(),
            self.feed.unwrap_or(0.0)
        );
        self.out.extend_from_slice(report.as_bytes());
    }

    fn reset(&mut self) {
        self.rx.clear();
        self.planner.clear();
        self.running = None;
        self.planned_end = self.position;
        self.hold = false;
        self.events.push(Event::Realtime { what: "reset" });
        self.out
            .extend_from_slice(format!("\r\n{BANNER}\r\n").as_bytes());
    }

    /// When the controller next needs [`Winder::poll`] (clock time, s): the end of the block
    /// being executed, when the planner is full and a whole line waits in the receive buffer for
    /// its slot. `None` when only bytes from the host can change what it answers (and when held).
    pub fn next_event_s(&self) -> Option<f64> {
        // Every receive and poll moves whole lines into the planner while it has room, so a whole
        // line waits only behind a full planner.
        let waiting = self.rx.iter().any(|&b| b == b'\n' || b == b'\r');
        if self.hold || !waiting || self.time_scale <= 0.0 {
            return None;
        }
        let left = match &self.running {
            Some((block, elapsed)) => block.duration_s - elapsed,
            // Queued blocks start at the last poll.
            None => self.planner.front()?.duration_s,
        };
        Some(self.last_s? + left.max(0.0) / self.time_scale)
    }

    /// Bytes to send to the host.
    pub fn take_output(&mut self) -> Vec<u8> {
        std::mem::take(&mut self.out)
    }

    /// What happened since the last call.
    pub fn take_events(&mut self) -> Vec<Event> {
        std::mem::take(&mut self.events)
    }

    /// Axis positions X Y Z A B C (work units: mm or degrees).
    pub fn position(&self) -> [f64; 6] {
        self.position
    }

    /// Bytes lost to a full receive buffer since start.
    pub fn overflow_bytes(&self) -> usize {
        self.overflow_bytes
    }

    /// The most the receive buffer has held, bytes.
    pub fn max_rx_bytes(&self) -> usize {
        self.max_rx_bytes
    }

    /// Nothing queued, nothing moving.
    pub fn is_idle(&self) -> bool {
        self.running.is_none() && self.planner.is_empty() && self.rx.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn replies(w: &mut Winder) -> String {
        String::from_utf8(w.take_output()).unwrap()
    }

    #[test]
    fn a_burst_beyond_the_receive_buffer_is_counted_as_lost() {
        let mut w = Winder::new(1.0);
        // Fill the planner with long moves so that lines stay in the receive buffer.
        for _ in 0..PLANNER_BLOCKS {
            w.receive(b"G1 X100 F1\n", 0.0);
        }
        assert_eq!(w.overflow_bytes(), 0);
        let burst = vec![b'X'; GRBL_RX_BUFFER + 5];
        w.receive(&burst, 0.0);
        assert_eq!(w.overflow_bytes(), 5);
        assert_eq!(w.max_rx_bytes(), GRBL_RX_BUFFER);
        assert!(w.take_events().contains(&Event::Overflow { bytes: 5 }));
    }

    #[test]
    fn the_planner_takes_fifteen_blocks_and_the_log_counts_lines_and_buffer_fill() {
        let mut w = Winder::new(1.0);
        // 20 moves of 10 min each, 11 bytes per line, two at once then one at a time: 15 are
        // planned and answered, 5 wait in the receive buffer.
        w.receive("G1 X100 F1\n".repeat(2).as_bytes(), 0.0);
        for _ in 2..20 {
            w.receive(b"G1 X100 F1\n", 0.0);
        }
        assert_eq!(replies(&mut w).matches("ok").count(), PLANNER_BLOCKS);
        let events = w.take_events();
        assert!(!events.iter().any(|e| matches!(e, Event::Overflow { .. })));
        let lines: Vec<(usize, usize)> = events
            .iter()
            .filter_map(|e| match e {
                Event::Line { n, rx_bytes, .. } => Some((*n, *rx_bytes)),
                _ => None,
            })
            .collect();
        // The first line is taken with the second behind it; the others alone.
        let mut want: Vec<(usize, usize)> = (1..=PLANNER_BLOCKS).map(|n| (n, 11)).collect();
        want[0].1 = 22;
        assert_eq!(lines, want);
        assert_eq!(w.max_rx_bytes(), 5 * 11);
    }

    #[test]
    fn a_waiting_line_is_due_when_the_running_block_ends() {
        let mut w = Winder::new(2.0);
        // 15 relative moves of 1 min (30 s at time scale 2) fill the planner; the 16th line waits.
        for _ in 0..PLANNER_BLOCKS {
            w.receive(b"G91 G94 G1 X10 F10\n", 0.0);
            assert_eq!(w.next_event_s(), None, "nothing waits");
        }
        w.receive(b"G1 X0\n", 1.0);
        assert_eq!(replies(&mut w).matches("ok").count(), PLANNER_BLOCKS);
        // The first block started at 0: it ends at 30 s.
        assert_eq!(w.next_event_s(), Some(30.0));
        w.poll(10.0);
        assert_eq!(w.next_event_s(), Some(30.0));
        w.receive(b"!", 12.0);
        assert_eq!(w.next_event_s(), None, "held");
        w.receive(b"~", 14.0);
        // Held 2 s: the block ends 2 s later.
        assert_eq!(w.next_event_s(), Some(32.0));
        w.poll(32.0);
        assert_eq!(replies(&mut w), "ok\r\n");
        assert_eq!(w.next_event_s(), None);
        // A partial line does not wait for a slot; a line ended by `\r` does.
        w.receive(b"G1 X5", 32.0);
        assert_eq!(w.next_event_s(), None);
        w.receive(b"\r", 32.0);
        assert_eq!(w.next_event_s(), Some(62.0));
    }

    #[test]
    fn blocks_queued_at_the_last_poll_run_from_it() {
        let mut w = Winder::new(1.0);
        // Sixteen 1 s moves in one read (128 bytes): fifteen are queued (none running yet), one
        // waits.
        w.receive(b"G91 G94\n", 5.0);
        w.receive("G1X1F60\n".repeat(16).as_bytes(), 5.0);
        assert_eq!(replies(&mut w).matches("ok").count(), PLANNER_BLOCKS + 1);
        assert_eq!(w.overflow_bytes(), 0);
        assert_eq!(w.next_event_s(), Some(6.0));
        w.poll(6.0);
        assert_eq!(replies(&mut w), "ok\r\n");
        // Stopped motion never frees a slot.
        let mut w = Winder::new(0.0);
        w.receive(b"G91 G94\n", 0.0);
        w.receive("G1X1F60\n".repeat(16).as_bytes(), 0.0);
        assert_eq!(w.next_event_s(), None);
    }

    #[test]
    fn one_poll_runs_through_several_blocks() {
        let mut w = Winder::new(1.0);
        // Two 1 s moves; at 1.5 s the second is half done.
        w.receive(b"G94 G1 X1 F60\nG1 X3 F120\n", 0.0);
        w.poll(1.5);
        assert!((w.position()[0] - 2.0).abs() < 1e-9, "{:?}", w.position());
    }

    #[test]
    fn comments_are_ignored_but_not_the_code_after_them() {
        let mut w = Winder::new(1.0);
        w.receive(
            b"(a (nested) note; G5) G94 G1 X2 (mid) F60 ; G5 tail\n",
            0.0,
        );
        assert_eq!(replies(&mut w), "ok\r\n");
        w.poll(1.0);
        assert!((w.position()[0] - 1.0).abs() < 1e-9, "{:?}", w.position());
    }

    #[test]
    fn inverse_time_block_takes_one_over_f_minutes() {
        let mut w = Winder::new(1.0);
        w.receive(b"G93\nG1 X10 A90 F2\n", 0.0);
        assert_eq!(replies(&mut w), "ok\r\nok\r\n");
        // F2 in G93: 0.5 min = 30 s. Half way at 15 s.
        w.poll(15.0);
        let p = w.position();
        assert!(
            (p[0] - 5.0).abs() < 1e-9 && (p[3] - 45.0).abs() < 1e-9,
            "{p:?}"
        );
        w.poll(30.0);
        assert_eq!(w.position()[0], 10.0);
        assert!(w.is_idle());
    }

    #[test]
    fn units_per_minute_feed_and_time_scale() {
        let mut w = Winder::new(10.0);
        w.receive(b"G94 G1 X3 Y4 F60\n", 0.0);
        // 5 mm at 60 mm/min = 5 s, ten times faster: 0.5 s.
        w.poll(0.25);
        assert!((w.position()[0] - 1.5).abs() < 1e-9);
        w.poll(0.5);
        assert!(w.is_idle());
    }

    #[test]
    fn hold_stops_motion_and_resume_continues() {
        let mut w = Winder::new(1.0);
        w.receive(b"G94 G1 X10 F60\n", 0.0);
        w.receive(b"!", 2.0);
        w.poll(5.0);
        assert!((w.position()[0] - 2.0).abs() < 1e-9);
        w.receive(b"?", 5.0);
        assert!(replies(&mut w).contains("<Hold:0|MPos:2.000,"));
        w.receive(b"~", 5.0);
        w.poll(6.0);
        assert!((w.position()[0] - 3.0).abs() < 1e-9);
    }

    #[test]
    fn reset_flushes_buffers_and_prints_the_banner() {
        let mut w = Winder::new(1.0);
        for _ in 0..PLANNER_BLOCKS + 3 {
            w.receive(b"G1 X100 F1\n", 0.0);
        }
        w.take_output();
        w.receive(&[SOFT_RESET], 1.0);
        assert!(replies(&mut w).contains(BANNER));
        assert!(w.is_idle());
        let x = w.position()[0];
        w.poll(100.0);
        assert_eq!(w.position()[0], x);
    }

    #[test]
    fn errors_are_numbered_as_grbl_numbers_them() {
        let mut w = Winder::new(1.0);
        w.receive(b"G93\nG1 X1\nG5 X1\nQ1\nG1 X1.2.3 F1\n", 0.0);
        w.receive(
            format!("G1 X{} F1\n", "1".repeat(LINE_BUFFER)).as_bytes(),
            0.0,
        );
        assert_eq!(
            replies(&mut w),
            "ok\r\nerror:22\r\nerror:20\r\nerror:20\r\nerror:2\r\nerror:14\r\n"
        );
    }

    #[test]
    fn g92_renames_the_position() {
        let mut w = Winder::new(1.0);
        w.receive(b"G94 G1 A360 F3600\n", 0.0);
        w.poll(10.0);
        w.receive(b"G92 A0\nG1 A90 F3600\n", 10.0);
        w.poll(20.0);
        assert!((w.position()[3] - 90.0).abs() < 1e-9);
    }

    /// Feeds `lines` at t = 0 and returns the replies.
    fn feed_lines(w: &mut Winder, lines: &str) -> String {
        w.receive(lines.as_bytes(), 0.0);
        replies(w)
    }

    /// The modal words GRBL 1.1 keeps between lines, each checked by where the axis ends and
    /// when: distance mode (`G90`/`G91`), units (`G21`/`G20`: 25.4 mm an inch, the feed in
    /// inches a minute), motion (`G0` at the rapid rate, `G1` at the feed; an axis-only line
    /// moves as the last of them). Times from distance ÷ rate, by hand.
    #[test]
    fn distance_units_and_motion_are_modal() {
        let mut w = Winder::new(1.0);
        // G1 X10 at 600 mm/min: 1 s. Then G91: X5 more (0.5 s), then G90 back to X0 (1.5 s).
        let r = feed_lines(&mut w, "G21 G90 G94 G1 X10 F600\nG91 G1 X5\nG90 G1 X0\n");
        assert_eq!(r, "ok\r\n".repeat(3));
        w.poll(1.0);
        assert!((w.position()[0] - 10.0).abs() < 1e-9, "{:?}", w.position());
        w.poll(1.5);
        assert!((w.position()[0] - 15.0).abs() < 1e-9, "{:?}", w.position());
        w.poll(3.0);
        assert!(w.position()[0].abs() < 1e-9, "{:?}", w.position());

        // G20: X1 is 25.4 mm, F60 is 60 in/min = 1524 mm/min, so 1 s; G21 then takes Y in mm.
        let mut w = Winder::new(1.0);
        let r = feed_lines(&mut w, "G20 G94 G1 X1 F60\nG21 G1 Y25.4 F1524\n");
        assert_eq!(r, "ok\r\n".repeat(2));
        w.poll(0.5);
        assert!((w.position()[0] - 12.7).abs() < 1e-9, "{:?}", w.position());
        w.poll(1.5);
        assert!((w.position()[1] - 12.7).abs() < 1e-9, "{:?}", w.position());
        w.poll(2.0);
        assert_eq!(w.position()[..2], [25.4, 25.4]);
        // Relative inches: G91 X1 is 25.4 mm more (1 s at F60 in/min).
        let r = feed_lines(&mut w, "G20 G91 G1 X1\n");
        assert_eq!(r, "ok\r\n");
        w.poll(3.0);
        assert!((w.position()[0] - 50.8).abs() < 1e-9, "{:?}", w.position());

        // G0: 50 mm at the rapid rate, 5000 mm/min: 0.6 s, whatever F says. An axis-only line
        // after it is a rapid too (0.6 s for the 50 mm back), and after a G1 a feed move.
        let mut w = Winder::new(1.0);
        let r = feed_lines(&mut w, "G94 F60\nG0 X50\nX0\nG1 X1\nX2\n");
        assert_eq!(r, "ok\r\n".repeat(5));
        w.poll(0.3);
        assert!((w.position()[0] - 25.0).abs() < 1e-9, "{:?}", w.position());
        w.poll(0.9);
        assert!((w.position()[0] - 25.0).abs() < 1e-9, "{:?}", w.position());
        // Then 1 mm at 60 mm/min: 1 s each.
        w.poll(1.7);
        assert!((w.position()[0] - 0.5).abs() < 1e-9, "{:?}", w.position());
        w.poll(2.7);
        assert!((w.position()[0] - 1.5).abs() < 1e-9, "{:?}", w.position());
    }

    /// A number may carry a `+` sign. Words GRBL takes without a motion of their own (planes,
    /// spindle and program ends) are answered `ok`; a zero feed is `error:22`; a line of exactly the line buffer's 80
    /// characters (spaces dropped) is taken and one more is `error:14`; a `)` outside a comment is
    /// no letter (`error:1`).
    #[test]
    fn accepted_words_feed_and_line_limits() {
        let mut w = Winder::new(1.0);
        // A signed number: X+5 is X5.
        let r = feed_lines(&mut w, "G94 G1 X+5 F600\n");
        assert_eq!(r, "ok\r\n");
        w.poll(1.0);
        assert!((w.position()[0] - 5.0).abs() < 1e-9, "{:?}", w.position());
        let r = feed_lines(&mut w, "G17\nG18\nG19\nM3\nM5\nM0\nM2\nM30\n");
        assert_eq!(r, "ok\r\n".repeat(8));
        assert!(w.is_idle());
        assert_eq!(feed_lines(&mut w, "G94 G1 X1 F0\n"), "error:22\r\n");
        assert!(w.is_idle());
        assert_eq!(feed_lines(&mut w, "F60\n"), "ok\r\n");
        // "G1X" + 77 digits = 80 characters; spaces do not count.
        let exact = format!("G1 X{}\n", "0".repeat(LINE_BUFFER - 3));
        assert_eq!(feed_lines(&mut w, &exact), "ok\r\n");
        let long = format!("G1 X{}\n", "0".repeat(LINE_BUFFER - 2));
        assert_eq!(feed_lines(&mut w, &long), "error:14\r\n");
        assert_eq!(feed_lines(&mut w, "G1 X1 F60 )\n"), "error:1\r\n");
    }

    /// `G92` renames the planned end while blocks are queued and running: every block is shifted
    /// with it, so the motion itself does not change. Two 1 s moves of A (100° each at
    /// 6000 °/min); at 0.5 s, A = 50 and the planned end is 200; `G92 A0` makes it 0 (shift
    /// −200), so A reads −150 then, −100 at 1 s and 0 at 2 s. In inches the given value is
    /// scaled: `G20 G92 X1` puts X at 25.4 mm.
    #[test]
    fn g92_shifts_the_queued_and_running_blocks() {
        let mut w = Winder::new(1.0);
        w.receive(b"G94 G1 A100 F6000\nG1 A200\n", 0.0);
        w.poll(0.5);
        w.receive(b"G92 A0\n", 0.5);
        assert!((w.position()[3] + 150.0).abs() < 1e-9, "{:?}", w.position());
        // Mid-way through each block, its shifted ends: −200 → −100, then −100 → 0.
        w.poll(0.75);
        assert!((w.position()[3] + 125.0).abs() < 1e-9, "{:?}", w.position());
        w.poll(1.0);
        assert!((w.position()[3] + 100.0).abs() < 1e-9, "{:?}", w.position());
        w.poll(1.5);
        assert!((w.position()[3] + 50.0).abs() < 1e-9, "{:?}", w.position());
        w.poll(2.0);
        assert!(w.position()[3].abs() < 1e-9, "{:?}", w.position());
        assert!(w.is_idle());
        w.receive(b"G20 G92 X1\n", 2.0);
        assert!((w.position()[0] - 25.4).abs() < 1e-9, "{:?}", w.position());
    }
}
