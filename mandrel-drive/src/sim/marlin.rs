//! A Marlin 2.1 class controller for the lathe winder (axes X Y Z linear, A B C rotary), for
//! streaming tests over a real serial port (`windcell sim-marlin`; docs/lathe.md, "Streaming to
//! a Marlin controller").
//!
//! Modelled as Marlin's host protocol works (Marlin 2.1.2 `queue.cpp`, `planner.cpp`,
//! `language.h`; the host side as the `marlin-host` library expects it):
//!
//! - **Serial input**: a 128-byte receive buffer (`RX_BUFFER_SIZE`; bytes beyond it are lost and
//!   counted), a command queue of 4 lines (`BUFSIZE`), a planner of 16 blocks
//!   (`BLOCK_BUFFER_SIZE`). A command is answered `ok` once it has been executed: a move when it
//!   has entered the planner (so `ok` waits while the planner is full), `M400` when the planner
//!   has run empty.
//! - **Line numbers and checksums**: `N<n> … *<cs>` with `cs` the XOR of the bytes before `*`.
//!   A wrong number answers `Error:Line Number is not Last Line Number+1, Last Line: <n>`, a wrong
//!   checksum `Error:checksum mismatch, Last Line: <n>`, a number without checksum `Error:No
//!   Checksum with line number, Last Line: <n>`; each is followed by `Resend: <n+1>` and `ok`, and
//!   the line is not executed. `M110 N<n>` sets the last line number. Lines without `N` are taken
//!   as they come.
//! - **Feed**: `F` in units per minute over the linear axes X, Y, Z; over the rotary axes (degrees
//!   per minute) only when no linear axis moves, as Marlin's planner does with rotational axes.
//!   `G0` runs at [`G0_PER_MIN`] (Marlin's `G0_FEEDRATE`). `G90`/`G91`, `G92`, `G20`/`G21`,
//!   `G94` (accepted, the only feed mode); `G93` and other codes answer
//!   `echo:Unknown command: "…"` and `ok`, as Marlin does.
//! - **Reports**: `M114` (the position after the last planned move), `M115` (firmware and
//!   capabilities), `echo:busy: processing` every 2 s while a command waits (`HOST_KEEPALIVE`).
//! - **Emergency stop**: `M112` is acted on as soon as its line is in the receive buffer
//!   (`EMERGENCY_PARSER`): motion stops, `Error:Printer halted. kill() called!`, nothing more is
//!   answered.
//! - **Soft limits**: targets of X, Y and Z are clamped into the travel, silently as Marlin's
//!   soft endstops do (logged here as [`Event::Clamped`]).
//!
//! Every executed line is logged once ([`Event::Executed`]), with its line number if it had one,
//! so a test can check that the machine ran a file.

use std::collections::VecDeque;

/// Marlin's serial receive buffer, bytes (`RX_BUFFER_SIZE`).
pub const RX_BUFFER: usize = 128;
/// Command queue, lines (`BUFSIZE`).
pub const COMMAND_QUEUE: usize = 4;
/// Planner blocks (`BLOCK_BUFFER_SIZE`).
pub const PLANNER_BLOCKS: usize = 16;
/// Rate of `G0` moves, units per minute (Marlin's `G0_FEEDRATE` default, 3000 mm/min).
pub const G0_PER_MIN: f64 = 3000.0;
/// The feed before any `F`, units per minute (Marlin's power-up `feedrate_mm_s`, 25 mm/s).
pub const DEFAULT_FEED_PER_MIN: f64 = 1500.0;
/// Keep-alive period while a command waits, s (`DEFAULT_KEEPALIVE_INTERVAL`).
pub const KEEPALIVE_S: f64 = 2.0;
/// Axis letters in report order; the first three are linear.
pub const AXES: [char; 6] = ['X', 'Y', 'Z', 'A', 'B', 'C'];
/// Soft-endstop travel of the linear axes X, Y, Z, mm (a winder's carriage and cross-feed).
pub const TRAVEL_MM: [(f64, f64); 3] = [(-10.0, 3000.0), (-10.0, 500.0), (-10.0, 500.0)];
/// The killed message (`STR_ERR_KILLED`).
pub const KILLED: &str = "Printer halted. kill() called!";

/// Something the simulator logs.
#[derive(Debug, Clone, PartialEq)]
pub enum Event {
    /// A line executed (1-based count of executed lines, its `N` if any, the command without
    /// line number and checksum).
    Executed {
        /// 1-based count of executed lines.
        n: usize,
        /// The line's `N`, if framed.
        line_number: Option<u64>,
        /// The command.
        text: String,
    },
    /// A line refused for a resend (the error message) — not executed.
    Rejected {
        /// The line as received.
        text: String,
        /// Marlin's error text.
        error: String,
    },
    /// A target clamped by the soft endstops.
    Clamped {
        /// Axis letter.
        axis: char,
        /// The commanded value.
        commanded: f64,
        /// The value moved to.
        to: f64,
    },
    /// Bytes lost because the receive buffer was full.
    Overflow {
        /// How many.
        bytes: usize,
    },
    /// `M112`: the controller halted.
    Killed,
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct Block {
    from: [f64; 6],
    to: [f64; 6],
    duration_s: f64,
}

/// A parsed command waiting to execute.
#[derive(Debug, Clone)]
struct Command {
    line_number: Option<u64>,
    text: String,
}

/// The simulated controller.
#[derive(Debug)]
pub struct Marlin {
    time_scale: f64,
    rx: VecDeque<u8>,
    queue: VecDeque<Command>,
    planner: VecDeque<Block>,
    running: Option<(Block, f64)>,
    position: [f64; 6],
    planned_end: [f64; 6],
    absolute: bool,
    inch: bool,
    feed_per_min: f64,
    last_line: u64,
    executed: usize,
    waiting_since_s: Option<f64>,
    last_keepalive_s: f64,
    now_s: f64,
    last_s: Option<f64>,
    killed: bool,
    out: Vec<u8>,
    events: Vec<Event>,
}

impl Marlin {
    /// A controller at rest at zero that has just printed its start-up banner; motion runs
    /// `time_scale` times faster than commanded.
    pub fn new(time_scale: f64) -> Marlin {
        Marlin {
            time_scale,
            rx: VecDeque::with_capacity(RX_BUFFER),
            queue: VecDeque::new(),
            planner: VecDeque::new(),
            running: None,
            position: [0.0; 6],
            planned_end: [0.0; 6],
            absolute: true,
            inch: false,
            feed_per_min: DEFAULT_FEED_PER_MIN,
            last_line: 0,
            executed: 0,
            waiting_since_s: None,
            last_keepalive_s: 0.0,
            now_s: 0.0,
            last_s: None,
            killed: false,
            out: b"start\necho:Marlin 2.1.2 (windcell sim-marlin)\n".to_vec(),
            events: Vec::new(),
        }
    }

    /// Bytes from the host at clock time `now_s`.
    pub fn receive(&mut self, bytes: &[u8], now_s: f64) {
        self.poll(now_s);
        if self.killed {
            return;
        }
        let mut lost = 0;
        for &b in bytes {
            if self.rx.len() >= RX_BUFFER {
                lost += 1;
            } else {
                self.rx.push_back(b);
            }
        }
        if lost > 0 {
            self.events.push(Event::Overflow { bytes: lost });
        }
        self.emergency_parser();
        self.poll(now_s);
    }

    /// Lets the clock run to `now_s`: motion advances, queued commands execute.
    pub fn poll(&mut self, now_s: f64) {
        let dt = self.last_s.map_or(0.0, |t| (now_s - t).max(0.0));
        self.last_s = Some(now_s);
        self.now_s = now_s;
        if self.killed {
            return;
        }
        self.advance(dt * self.time_scale);
        self.read_lines();
        self.execute_queue();
        self.read_lines();
        if let Some(since) = self.waiting_since_s
            && now_s - since.max(self.last_keepalive_s) >= KEEPALIVE_S
        {
            self.out.extend_from_slice(b"echo:busy: processing\n");
            self.last_keepalive_s = now_s;
        }
    }

    /// Replies to send to the host.
    pub fn take_output(&mut self) -> Vec<u8> {
        std::mem::take(&mut self.out)
    }

    /// Events since the last call.
    pub fn take_events(&mut self) -> Vec<Event> {
        std::mem::take(&mut self.events)
    }

    /// Where the axes are now.
    pub fn position(&self) -> [f64; 6] {
        self.position
    }

    /// Whether `M112` halted the controller.
    pub fn is_killed(&self) -> bool {
        self.killed
    }

    /// Blocks in the planner, the one running included.
    pub fn blocks(&self) -> usize {
        self.planner.len() + usize::from(self.running.is_some())
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
            if dt_s + 1e-9 < left {
                *elapsed += dt_s;
                let f = *elapsed / block.duration_s;
                for i in 0..6 {
                    self.position[i] = block.from[i] + (block.to[i] - block.from[i]) * f;
                }
                return;
            }
            dt_s -= left.max(0.0);
            self.position = block.to;
            self.running = None;
        }
    }

    /// `M112` anywhere in a complete line of the receive buffer acts at once.
    fn emergency_parser(&mut self) {
        let bytes: Vec<u8> = self.rx.iter().copied().collect();
        for line in bytes.split(|&b| b == b'\n' || b == b'\r') {
            let text = String::from_utf8_lossy(line).to_ascii_uppercase();
            let code = text.split(';').next().unwrap_or("");
            if code.split_whitespace().any(|w| w == "M112") {
                self.kill();
                return;
            }
        }
    }

    fn kill(&mut self) {
        self.killed = true;
        self.planner.clear();
        self.running = None;
        self.queue.clear();
        self.rx.clear();
        self.out
            .extend_from_slice(format!("Error:{KILLED}\n").as_bytes());
        self.events.push(Event::Killed);
    }

    /// Complete lines from the receive buffer into the command queue, checked for line number
    /// and checksum.
    fn read_lines(&mut self) {
        while self.queue.len() < COMMAND_QUEUE {
            let Some(end) = self.rx.iter().position(|&b| b == b'\n' || b == b'\r') else {
                return;
            };
            let raw: Vec<u8> = self.rx.drain(..=end).collect();
            let text = String::from_utf8_lossy(&raw[..end]).trim().to_string();
            // Comments are dropped as the line is read.
            let text = text.split(';').next().unwrap_or("").trim().to_string();
            if text.is_empty() {
                continue;
            }
            match self.frame(&text) {
                Ok(Some(cmd)) => self.queue.push_back(cmd),
                Ok(None) => {}
                Err(error) => {
                    let reply = format!(
                        "Error:{error}{}\nResend: {}\nok\n",
                        self.last_line,
                        self.last_line + 1
                    );
                    self.out.extend_from_slice(reply.as_bytes());
                    self.events.push(Event::Rejected { text, error });
                }
            }
        }
    }

    /// Checks a line's number and checksum; `Err` carries the error text before `Last Line`.
    fn frame(&mut self, text: &str) -> Result<Option<Command>, String> {
        let (body, checksum) = match text.rfind('*') {
            Some(star) => (&text[..star], Some(text[star + 1..].trim())),
            None => (text, None),
        };
        if !body.starts_with('N') && !body.starts_with('n') {
            if checksum.is_some() {
                return Err("No Line Number with checksum, Last Line: ".into());
            }
            return Ok(Some(Command {
                line_number: None,
                text: body.trim().to_string(),
            }));
        }
        let digits: String = body[1..]
            .chars()
            .take_while(|c| c.is_ascii_digit())
            .collect();
        let number: u64 = digits
            .parse()
            .map_err(|_| "Line Number is not Last Line Number+1, Last Line: ".to_string())?;
        let command = body[1 + digits.len()..].trim().to_string();
        let Some(cs) = checksum else {
            return Err("No Checksum with line number, Last Line: ".into());
        };
        let expected = body.bytes().fold(0u8, |a, b| a ^ b);
        if cs.parse::<u8>().ok() != Some(expected) {
            return Err("checksum mismatch, Last Line: ".into());
        }
        let is_m110 = command
            .split_whitespace()
            .next()
            .is_some_and(|w| w.eq_ignore_ascii_case("M110"));
        if !is_m110 && number != self.last_line + 1 {
            return Err("Line Number is not Last Line Number+1, Last Line: ".into());
        }
        self.last_line = number;
        Ok(Some(Command {
            line_number: Some(number),
            text: command,
        }))
    }

    /// Executes queued commands until one has to wait.
    fn execute_queue(&mut self) {
        while let Some(cmd) = self.queue.front() {
            match self.execute(&cmd.text.clone()) {
                Step::Done(reply) => {
                    let cmd = self.queue.pop_front().expect("front exists");
                    self.executed += 1;
                    self.events.push(Event::Executed {
                        n: self.executed,
                        line_number: cmd.line_number,
                        text: cmd.text,
                    });
                    self.out.extend_from_slice(reply.as_bytes());
                    self.out.extend_from_slice(b"ok\n");
                    self.waiting_since_s = None;
                }
                Step::Wait => {
                    if self.waiting_since_s.is_none() {
                        self.waiting_since_s = Some(self.now_s);
                        self.last_keepalive_s = self.now_s;
                    }
                    return;
                }
            }
            if self.killed {
                return;
            }
        }
    }

    fn execute(&mut self, text: &str) -> Step {
        let mut words: Vec<(char, f64)> = Vec::new();
        for w in text.split_whitespace() {
            let mut chars = w.chars();
            let Some(letter) = chars.next() else { continue };
            let v: f64 = chars.as_str().parse().unwrap_or(f64::NAN);
            words.push((letter.to_ascii_uppercase(), v));
        }
        let Some(&(kind, number)) = words.first() else {
            return Step::Done(String::new());
        };
        let unknown = || Step::Done(format!("echo:Unknown command: \"{text}\"\n"));
        match (kind, number) {
            ('G', n) if n == 0.0 || n == 1.0 => {
                if self.blocks() >= PLANNER_BLOCKS {
                    return Step::Wait;
                }
                self.plan_move(n == 0.0, &words[1..]);
                Step::Done(String::new())
            }
            ('G', 20.0) => {
                self.inch = true;
                Step::Done(String::new())
            }
            ('G', 21.0) => {
                self.inch = false;
                Step::Done(String::new())
            }
            ('G', 90.0) => {
                self.absolute = true;
                Step::Done(String::new())
            }
            ('G', 91.0) => {
                self.absolute = false;
                Step::Done(String::new())
            }
            ('G', 94.0) => Step::Done(String::new()),
            ('G', 92.0) => {
                // G92 waits for nothing in Marlin's model here: it resets the coordinate of the
                // planned end (the planner works in machine steps; our blocks are already
                // absolute, so the running ones are shifted too).
                for &(l, v) in &words[1..] {
                    if let Some(i) = AXES.iter().position(|&a| a == l) {
                        let v = v * self.scale(i);
                        let shift = v - self.planned_end[i];
                        self.planned_end[i] = v;
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
                Step::Done(String::new())
            }
            ('M', 400.0) => {
                if self.blocks() > 0 {
                    Step::Wait
                } else {
                    Step::Done(String::new())
                }
            }
            ('M', 110.0) => Step::Done(String::new()),
            ('M', 114.0) => {
                let p = self.planned_end;
                let s = |i: usize| p[i] / self.scale(i);
                Step::Done(format!(
                    "X:{:.2} Y:{:.2} Z:{:.2} A:{:.2} B:{:.2} C:{:.2} Count X:0 Y:0 Z:0\n",
                    s(0),
                    s(1),
                    s(2),
                    s(3),
                    s(4),
                    s(5)
                ))
            }
            ('M', 115.0) => Step::Done(
                "FIRMWARE_NAME:Marlin 2.1.2 (windcell sim-marlin) PROTOCOL_VERSION:1.0 \
                 MACHINE_TYPE:lathe winder EXTRUDER_COUNT:0 AXIS_COUNT:6\n\
                 Cap:EMERGENCY_PARSER:1\nCap:HOST_ACTION_COMMANDS:0\n"
                    .to_string(),
            ),
            ('M', 112.0) => {
                self.kill();
                Step::Done(String::new())
            }
            _ => unknown(),
        }
    }

    /// Millimetres (or degrees) per written unit of axis `i`.
    fn scale(&self, i: usize) -> f64 {
        if i < 3 && self.inch { 25.4 } else { 1.0 }
    }

    fn plan_move(&mut self, rapid: bool, words: &[(char, f64)]) {
        let mut to = self.planned_end;
        for &(l, v) in words {
            if l == 'F' {
                if v > 0.0 && v.is_finite() {
                    self.feed_per_min = v * self.scale(0);
                }
                continue;
            }
            let Some(i) = AXES.iter().position(|&a| a == l) else {
                continue;
            };
            if !v.is_finite() {
                continue;
            }
            let v = v * self.scale(i);
            to[i] = if self.absolute { v } else { to[i] + v };
        }
        for (i, &(lo, hi)) in TRAVEL_MM.iter().enumerate() {
            let c = to[i].clamp(lo, hi);
            if c != to[i] {
                self.events.push(Event::Clamped {
                    axis: AXES[i],
                    commanded: to[i],
                    to: c,
                });
                to[i] = c;
            }
        }
        let d: [f64; 6] = std::array::from_fn(|i| to[i] - self.planned_end[i]);
        let linear = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let length = if linear > 0.0 {
            linear
        } else {
            (d[3] * d[3] + d[4] * d[4] + d[5] * d[5]).sqrt()
        };
        let rate = if rapid { G0_PER_MIN } else { self.feed_per_min };
        let duration_s = length / rate * 60.0;
        let from = self.planned_end;
        self.planned_end = to;
        if length > 0.0 {
            self.planner.push_back(Block {
                from,
                to,
                duration_s,
            });
        }
    }
}

enum Step {
    /// Executed; the text before `ok`.
    Done(String),
    /// Must wait (planner full, `M400` with moves left).
    Wait,
}

/// `N<n> <command>*<cs>`: a line framed as a Marlin host sends it.
pub fn framed(number: u64, command: &str) -> String {
    let body = format!("N{number} {command}");
    let cs = body.bytes().fold(0u8, |a, b| a ^ b);
    format!("{body}*{cs}\n")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn replies(m: &mut Marlin) -> Vec<String> {
        String::from_utf8(m.take_output())
            .unwrap()
            .lines()
            .map(str::to_string)
            .collect()
    }

    #[test]
    fn framing_errors_ask_for_the_right_line_and_execute_nothing() {
        let mut m = Marlin::new(1.0);
        m.take_output();
        m.receive(framed(0, "M110").as_bytes(), 0.0);
        m.receive(framed(1, "G1 X10 F600").as_bytes(), 0.0);
        // Line 3 where 2 is due.
        m.receive(framed(3, "G1 X20").as_bytes(), 0.0);
        // Line 2 with a checksum off by one.
        let mut bad = framed(2, "G1 X20");
        bad = bad.replace('*', "*1");
        m.receive(bad.as_bytes(), 0.0);
        m.receive(b"N2 G1 X20\n", 0.0);
        m.receive(framed(2, "G1 X20").as_bytes(), 0.0);
        let r = replies(&mut m);
        assert_eq!(
            r,
            [
                "ok",
                "ok",
                "Error:Line Number is not Last Line Number+1, Last Line: 1",
                "Resend: 2",
                "ok",
                "Error:checksum mismatch, Last Line: 1",
                "Resend: 2",
                "ok",
                "Error:No Checksum with line number, Last Line: 1",
                "Resend: 2",
                "ok",
                "ok",
            ]
        );
        let executed: Vec<(Option<u64>, String)> = m
            .take_events()
            .into_iter()
            .filter_map(|e| match e {
                Event::Executed {
                    line_number, text, ..
                } => Some((line_number, text)),
                _ => None,
            })
            .collect();
        assert_eq!(
            executed,
            [
                (Some(0), "M110".to_string()),
                (Some(1), "G1 X10 F600".to_string()),
                (Some(2), "G1 X20".to_string())
            ]
        );
    }

    #[test]
    fn feed_applies_to_the_linear_axes_unless_only_rotary_axes_move() {
        let mut m = Marlin::new(1.0);
        // 30 mm of X with 3600° of A at 600 mm/min: 3 s (the A words do not lengthen it).
        m.receive(b"G1 X30 A3600 F600\n", 0.0);
        m.poll(2.999);
        assert!(m.position()[0] < 30.0);
        m.poll(3.0001);
        assert_eq!(m.position()[0], 30.0);
        assert_eq!(m.position()[3], 3600.0);
        // A alone at 600 °/min: 360° in 36 s.
        m.receive(b"G1 A3960\n", 3.0001);
        m.poll(3.0001 + 35.99);
        assert!(m.position()[3] < 3960.0);
        m.poll(3.0001 + 36.01);
        assert_eq!(m.position()[3], 3960.0);
    }

    #[test]
    fn a_full_planner_holds_the_ok_and_m400_waits_for_the_last_move() {
        let mut m = Marlin::new(1.0);
        m.take_output();
        // Each move 1 s (10 mm at 600 mm/min).
        for k in 1..=PLANNER_BLOCKS + 1 {
            m.receive(format!("G1 X{} F600\n", 10 * k).as_bytes(), 0.0);
        }
        let oks = replies(&mut m).iter().filter(|r| *r == "ok").count();
        assert_eq!(oks, PLANNER_BLOCKS);
        m.poll(1.001);
        assert_eq!(replies(&mut m), ["ok"]);
        m.receive(b"M400\n", 1.001);
        assert!(replies(&mut m).is_empty());
        // Busy keep-alive every 2 s while M400 waits, then ok when the planner is empty.
        m.poll(3.01);
        assert_eq!(replies(&mut m), ["echo:busy: processing"]);
        m.poll(17.5);
        assert_eq!(m.position()[0], 170.0);
        let r = replies(&mut m);
        assert_eq!(r.last().map(String::as_str), Some("ok"), "{r:?}");
        m.receive(b"M114\n", 17.5);
        assert_eq!(
            replies(&mut m),
            [
                "X:170.00 Y:0.00 Z:0.00 A:0.00 B:0.00 C:0.00 Count X:0 Y:0 Z:0",
                "ok"
            ]
        );
    }

    #[test]
    fn m112_halts_at_once_and_soft_limits_clamp() {
        let mut m = Marlin::new(1.0);
        m.take_output();
        m.receive(b"G1 X5000 F6000\n", 0.0);
        assert!(m.take_events().iter().any(|e| matches!(
            e,
            Event::Clamped { axis: 'X', to, .. } if *to == TRAVEL_MM[0].1
        )));
        m.receive(b"G1 X10\nM112\n", 0.1);
        assert!(m.is_killed());
        let r = replies(&mut m);
        assert_eq!(r.last().unwrap(), &format!("Error:{KILLED}"));
        m.receive(b"G1 X20\n", 0.2);
        assert!(m.take_output().is_empty());
        // Unknown codes are echoed and acknowledged.
        let mut m = Marlin::new(1.0);
        m.take_output();
        m.receive(b"G93\n", 0.0);
        assert_eq!(replies(&mut m), ["echo:Unknown command: \"G93\"", "ok"]);
    }
}
