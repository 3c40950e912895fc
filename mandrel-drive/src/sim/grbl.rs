//! The GRBL front end of the simulator: a GRBL 1.1 class controller with the mandrel on its A
//! axis (docs/mandrel-drive.md).
//!
//! Lines are answered `ok` when planned or `error:N`; motion lines run one after the other from
//! rest (GRBL has no start velocity); `?` reports `<State|MPos:x,y,z,a|FS:f,0>`; `!` holds with
//! deceleration and `~` resumes; `0x85` cancels a jog; `0x18` resets and prints the banner. A
//! `$113` whose pulse rate exceeds the translator's limit is refused with a `[MSG:…]` naming the
//! limit and `error:20` (our convention: real GRBL would accept it and lose steps).

use std::collections::VecDeque;

use crate::grbl::{CYCLE_START, Command, FEED_HOLD, JOG_CANCEL, SOFT_RESET, STATUS, parse_command};
use crate::profile::StepProfile;
use crate::sim::Frontend;
use crate::sim::machine::Machine;

/// Error code for an unsupported or refused line (GRBL `error:20`).
pub const ERROR_UNSUPPORTED: u16 = 20;
/// Error code for a line longer than the input buffer (GRBL `error:14`).
pub const ERROR_OVERFLOW: u16 = 14;
/// The line buffer length of a classic GRBL.
const LINE_MAX: usize = 128;
/// The start-up banner.
pub const BANNER: &str = "Grbl 1.1h ['$' for help]";

#[derive(Debug, Clone, Copy, PartialEq)]
struct Block {
    target_steps: i64,
    feed_deg_per_min: f64,
    jog: bool,
}

/// A simulated GRBL controller.
#[derive(Debug)]
pub struct Controller {
    /// The simulated hardware behind the controller.
    pub machine: Machine,
    steps_per_deg: f64,
    max_rate_deg_per_min: f64,
    accel_deg_s2: f64,
    line: Vec<u8>,
    overflow: bool,
    queue: VecDeque<Block>,
    running: Option<Block>,
    hold: bool,
    out: Vec<u8>,
}

impl Controller {
    /// A controller at its defaults for `machine`'s drive: 1 rev/s, 1 rev/s².
    pub fn new(machine: Machine) -> Self {
        let steps_per_deg = machine.drive.steps_per_deg();
        Controller {
            machine,
            steps_per_deg,
            max_rate_deg_per_min: 21_600.0,
            accel_deg_s2: 360.0,
            line: Vec::new(),
            overflow: false,
            queue: VecDeque::new(),
            running: None,
            hold: false,
            out: Vec::new(),
        }
    }

    fn send(&mut self, text: &str) {
        self.out.extend_from_slice(text.as_bytes());
        self.out.extend_from_slice(b"\r\n");
    }

    fn position_deg(&self) -> f64 {
        self.machine.counter_steps() as f64 / self.steps_per_deg
    }

    fn state(&self) -> &'static str {
        if self.machine.is_stalled() {
            "Alarm"
        } else if self.hold {
            "Hold:0"
        } else if self.running.is_some_and(|b| b.jog) {
            "Jog"
        } else if self.running.is_some() || !self.queue.is_empty() {
            "Run"
        } else {
            "Idle"
        }
    }

    fn realtime(&mut self, byte: u8) {
        match byte {
            STATUS => {
                let feed = self.machine.rate_sps() / self.steps_per_deg * 60.0;
                let report = format!(
                    "<{}|MPos:0.000,0.000,0.000,{:.3}|FS:{feed:.0},0>",
                    self.state(),
                    self.position_deg()
                );
                self.send(&report);
            }
            FEED_HOLD if self.running.is_some() => {
                self.hold = true;
                self.machine.stop();
            }
            CYCLE_START if self.hold => {
                self.hold = false;
                if let Some(b) = self.running {
                    self.start(b);
                }
            }
            JOG_CANCEL if self.running.is_some_and(|b| b.jog) => {
                self.machine.stop();
                self.running = self.running.map(|b| Block {
                    target_steps: i64::MAX,
                    ..b
                });
                self.queue.retain(|b| !b.jog);
            }
            SOFT_RESET => {
                self.machine.kill();
                self.queue.clear();
                self.running = None;
                self.hold = false;
                self.line.clear();
                self.overflow = false;
                self.out.extend_from_slice(b"\r\n");
                self.send(BANNER);
            }
            _ => {}
        }
    }

    fn line(&mut self) {
        let line = std::mem::take(&mut self.line);
        if std::mem::take(&mut self.overflow) {
            self.send(&format!("error:{ERROR_OVERFLOW}"));
            return;
        }
        let Ok(text) = std::str::from_utf8(&line) else {
            self.send(&format!("error:{ERROR_UNSUPPORTED}"));
            return;
        };
        if text.trim().is_empty() {
            return;
        }
        let Some(cmd) = parse_command(text) else {
            self.send(&format!("error:{ERROR_UNSUPPORTED}"));
            return;
        };
        let limit = self.machine.drive.pulse_limit_pps;
        let ok = match cmd {
            Command::StepsPerDeg(v) if v > 0.0 => {
                self.steps_per_deg = v;
                true
            }
            Command::MaxRate(v) if v > 0.0 => {
                let pps = v / 60.0 * self.steps_per_deg;
                if pps > limit {
                    self.send(&format!(
                        "[MSG:{pps:.0} pulses/s exceeds the translator limit of {limit:.0} pulses/s]"
                    ));
                    false
                } else {
                    self.max_rate_deg_per_min = v;
                    true
                }
            }
            Command::Accel(v) if v > 0.0 => {
                self.accel_deg_s2 = v;
                true
            }
            Command::RotaryMask(_) | Command::MaxTravel(_) => true,
            Command::Move {
                absolute,
                a_deg,
                feed_deg_per_min,
            } if feed_deg_per_min > 0.0 => {
                let base = self
                    .queue
                    .back()
                    .or(self.running.as_ref())
                    .map_or(self.machine.counter_steps(), |b| b.target_steps);
                let target = if absolute {
                    (a_deg * self.steps_per_deg).round() as i64
                } else {
                    base.saturating_add((a_deg * self.steps_per_deg).round() as i64)
                };
                self.queue.push_back(Block {
                    target_steps: target,
                    feed_deg_per_min,
                    jog: false,
                });
                true
            }
            Command::Jog {
                a_deg,
                feed_deg_per_min,
            } if feed_deg_per_min > 0.0 => {
                let target =
                    self.machine.counter_steps() + (a_deg * self.steps_per_deg).round() as i64;
                self.queue.push_back(Block {
                    target_steps: target,
                    feed_deg_per_min,
                    jog: true,
                });
                true
            }
            Command::ZeroA if self.running.is_none() && self.queue.is_empty() => {
                self.machine.zero();
                true
            }
            _ => false,
        };
        if ok {
            self.send("ok");
        } else {
            self.send(&format!("error:{ERROR_UNSUPPORTED}"));
        }
    }

    fn start(&mut self, block: Block) {
        let feed = block.feed_deg_per_min.min(self.max_rate_deg_per_min);
        self.machine.profile = StepProfile {
            v0_sps: 0.0,
            vmax_sps: feed / 60.0 * self.steps_per_deg,
            accel_sps2: self.accel_deg_s2 * self.steps_per_deg,
        };
        let steps = block
            .target_steps
            .saturating_sub(self.machine.counter_steps());
        match self.machine.start_preset(steps) {
            Ok(()) => self.running = Some(block),
            Err(e) => {
                self.send(&format!("[MSG:{e}]"));
                self.running = None;
                self.queue.clear();
            }
        }
    }
}

impl Frontend for Controller {
    fn receive(&mut self, bytes: &[u8], now_s: f64) {
        self.machine.advance(now_s);
        for &b in bytes {
            match b {
                STATUS | FEED_HOLD | CYCLE_START | SOFT_RESET | JOG_CANCEL => self.realtime(b),
                b'\n' | b'\r' => self.line(),
                _ if self.line.len() < LINE_MAX => self.line.push(b),
                _ => self.overflow = true,
            }
        }
        self.poll(now_s);
    }

    fn poll(&mut self, now_s: f64) {
        self.machine.advance(now_s);
        if self.machine.is_moving() || self.hold {
            return;
        }
        self.running = None;
        if let Some(next) = self.queue.pop_front() {
            self.start(next);
        }
    }

    fn take_output(&mut self) -> Vec<u8> {
        std::mem::take(&mut self.out)
    }

    fn machine(&self) -> &Machine {
        &self.machine
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::machine::PULL_IN_SPS;
    use crate::units::Drive;

    fn say(c: &mut Controller, text: &[u8], t: f64) -> String {
        c.receive(text, t);
        String::from_utf8_lossy(&c.take_output()).into_owned()
    }

    #[test]
    fn move_status_and_reset() {
        let mut c = Controller::new(Machine::new(Drive::default(), PULL_IN_SPS));
        assert_eq!(say(&mut c, b"$123=720\n", 0.0), "ok\r\n");
        assert_eq!(say(&mut c, b"G90 G1 A360 F21600\n", 0.0), "ok\r\n");
        assert!(say(&mut c, b"?", 0.2).starts_with("<Run|MPos:0.000,0.000,0.000,"));
        c.poll(5.0);
        assert_eq!(
            say(&mut c, b"?", 5.0),
            "<Idle|MPos:0.000,0.000,0.000,359.970|FS:0,0>\r\n" // 1846 steps at 5.1282 steps/deg
        );
        assert_eq!(c.machine.counter_steps(), 1846);
        assert_eq!(say(&mut c, b"G1 X5\n", 5.0), "error:20\r\n");
        assert_eq!(
            say(&mut c, &[SOFT_RESET], 5.0),
            "\r\nGrbl 1.1h ['$' for help]\r\n"
        );
    }

    #[test]
    fn jog_and_cancel() {
        let mut c = Controller::new(Machine::new(Drive::default(), PULL_IN_SPS));
        assert_eq!(say(&mut c, b"$J=G91 A100000 F10800\n", 0.0), "ok\r\n");
        c.poll(2.0);
        assert!(say(&mut c, b"?", 2.0).starts_with("<Jog|"));
        say(&mut c, &[JOG_CANCEL], 2.0);
        c.poll(4.0);
        assert!(say(&mut c, b"?", 4.0).starts_with("<Idle|"));
        assert!(c.machine.counter_steps() > 1000); // about 1.5 s at 923 steps/s
    }

    #[test]
    fn max_rate_over_the_translator_limit_is_refused() {
        let mut c = Controller::new(Machine::new(Drive::default(), PULL_IN_SPS));
        let out = say(&mut c, b"$113=130000\n", 0.0); // 11 111 pulses/s
        assert!(
            out.contains("exceeds the translator limit of 10000 pulses/s"),
            "{out}"
        );
        assert!(out.ends_with("error:20\r\n"));
        assert_eq!(say(&mut c, &[b'x'; 200], 0.0), "");
        assert_eq!(say(&mut c, b"\n", 0.0), "error:14\r\n");
    }

    proptest::proptest! {
        #[test]
        fn arbitrary_input_never_panics(chunks in proptest::collection::vec(proptest::collection::vec(proptest::prelude::any::<u8>(), 0..40), 0..8)) {
            let mut c = Controller::new(Machine::new(Drive::default(), PULL_IN_SPS));
            let mut t = 0.0;
            for chunk in &chunks {
                t += 0.05;
                c.receive(chunk, t);
                c.poll(t);
                let _ = c.take_output();
            }
        }
    }
}
