//! The X-language front end of the simulator: an indexer card on a serial line
//! (docs/mandrel-drive.md; seed 001 §4.1.8).
//!
//! Echo on by default, `*` replies (with a 3-digit device ID after `SSD1`), a command buffer in
//! which `G` in preset mode holds the following commands until the move is done, `CR` sending
//! CR LF when reached (the move-complete notification), loops `L`…`N`, trigger waits `TR` on the
//! start line, immediate `R`, `RA`, `W3`, `S`, `K`, `Z` (busy for 1000 ms). A move the hardware
//! refuses (pulse limit) is answered `?` + reason + CR, our convention, and sets attention.

use crate::sim::Frontend;
use crate::sim::machine::Machine;
use crate::sync::SyncInput;
use crate::xlang::{Command, format_move_steps, format_position, parse_command};

/// Power-up reset busy time (`Z`), OEM guide.
pub const RESET_BUSY_S: f64 = 1.0;
/// Longest command token the card accepts; longer input is dropped.
const MAX_TOKEN: usize = 64;

#[derive(Debug, Clone, PartialEq)]
enum Wait {
    None,
    Move,
    Trigger(String),
}

/// A simulated indexer card speaking the X-language.
#[derive(Debug)]
pub struct Card {
    /// The simulated hardware behind the card.
    pub machine: Machine,
    /// Device address (1–255).
    pub address: u8,
    /// Reset busy time (s); 1 s on the real card.
    pub reset_busy_s: f64,
    echo: bool,
    device_id: bool,
    token: Vec<u8>,
    buffer: Vec<Command>,
    pc: usize,
    loops: Vec<(usize, Option<u16>)>,
    wait: Wait,
    continuous: bool,
    absolute: bool,
    ccw: bool,
    distance: i64,
    resolution: u32,
    accel_rps2: f64,
    velocity_rps: f64,
    start_rps: f64,
    attention: bool,
    trigger: Option<Box<dyn SyncInput>>,
    out: Vec<u8>,
}

impl Card {
    /// A card at `address` in front of `machine`, at power-up defaults.
    pub fn new(machine: Machine, address: u8) -> Self {
        let resolution = machine.drive.gearing.steps_per_motor_rev;
        let mut card = Card {
            machine,
            address,
            reset_busy_s: RESET_BUSY_S,
            echo: true,
            device_id: false,
            token: Vec::new(),
            buffer: Vec::new(),
            pc: 0,
            loops: Vec::new(),
            wait: Wait::None,
            continuous: false,
            absolute: false,
            ccw: true,
            distance: 25_000,
            resolution,
            accel_rps2: 100.0,
            velocity_rps: 1.0,
            start_rps: 0.0,
            attention: false,
            trigger: None,
            out: Vec::new(),
        };
        card.apply_profile();
        card
    }

    /// Connects trigger input 1 to a sync line (the "start" wire of seed 001 App. D).
    pub fn with_trigger(mut self, input: Box<dyn SyncInput>) -> Self {
        self.trigger = Some(input);
        self
    }

    fn apply_profile(&mut self) {
        let r = f64::from(self.resolution);
        self.machine.profile = crate::profile::StepProfile {
            v0_sps: self.start_rps * r,
            vmax_sps: self.velocity_rps * r,
            accel_sps2: self.accel_rps2 * r,
        };
    }

    fn reply(&mut self, payload: &str) {
        self.out.push(b'*');
        if self.device_id {
            self.out
                .extend_from_slice(format!("{:03}", self.address).as_bytes());
        }
        self.out.extend_from_slice(payload.as_bytes());
        self.out.push(b'\r');
    }

    fn refuse(&mut self, reason: impl std::fmt::Display) {
        self.attention = true;
        self.out
            .extend_from_slice(format!("?{reason}\r").as_bytes());
    }

    fn token(&mut self, now_s: f64) {
        let token = std::mem::take(&mut self.token);
        let Ok(text) = std::str::from_utf8(&token) else {
            return;
        };
        if text.is_empty() {
            return;
        }
        let Some((addr, cmd)) = parse_command(text) else {
            return; // the card ignores what it does not know
        };
        if addr.is_some_and(|a| a != self.address) {
            return;
        }
        self.machine.advance(now_s);
        if cmd.is_immediate() {
            self.immediate(cmd);
        } else {
            self.buffer.push(cmd);
        }
        self.run_buffer();
    }

    fn immediate(&mut self, cmd: Command) {
        match cmd {
            Command::Status => {
                let busy = self.machine.is_busy() || self.wait != Wait::None;
                let attention = self.attention || self.machine.is_stalled();
                let c = match (busy, attention) {
                    (false, false) => "R",
                    (false, true) => "S",
                    (true, false) => "B",
                    (true, true) => "C",
                };
                self.reply(c);
            }
            Command::LimitStatus => self.reply("@"),
            Command::MoveSteps => {
                let s = format_move_steps(self.machine.steps_since_move_start());
                self.reply(&s);
            }
            Command::Stop => {
                self.machine.stop();
                self.clear_buffer();
            }
            Command::Kill => {
                self.machine.kill();
                self.clear_buffer();
            }
            Command::Reset => {
                self.machine.reset(self.reset_busy_s);
                self.clear_buffer();
                let (machine, address, busy, trigger) = (
                    self.machine.clone(),
                    self.address,
                    self.reset_busy_s,
                    self.trigger.take(),
                );
                *self = Card::new(machine, address);
                self.reset_busy_s = busy;
                self.trigger = trigger;
            }
            _ => {}
        }
    }

    fn clear_buffer(&mut self) {
        self.buffer.clear();
        self.pc = 0;
        self.loops.clear();
        self.wait = Wait::None;
    }

    fn trigger_met(&mut self, pattern: &str) -> bool {
        let level = match self.trigger.as_mut() {
            Some(t) => t.level().unwrap_or(false),
            None => false,
        };
        match pattern.as_bytes().first() {
            Some(b'1') => level,
            Some(b'0') => !level,
            _ => true,
        }
    }

    fn run_buffer(&mut self) {
        loop {
            if self.machine.now_s() < self.machine.reset_until_s {
                return;
            }
            match self.wait.clone() {
                Wait::Move if self.machine.is_moving() => return,
                Wait::Trigger(p) if !self.trigger_met(&p) => return,
                _ => self.wait = Wait::None,
            }
            let Some(cmd) = self.buffer.get(self.pc).cloned() else {
                if self.loops.is_empty() {
                    self.buffer.clear();
                    self.pc = 0;
                }
                return;
            };
            self.pc += 1;
            self.execute(cmd);
        }
    }

    fn execute(&mut self, cmd: Command) {
        match cmd {
            // Values outside the guide's ranges are ignored, as the unit does.
            Command::Accel(v) if (0.01..=999.0).contains(&v) => {
                self.accel_rps2 = v;
                self.apply_profile();
            }
            Command::Velocity(v) if (0.0..=50.0).contains(&v) => {
                self.velocity_rps = v;
                self.apply_profile();
            }
            Command::StartVelocity(v) if (0.0..=50.0).contains(&v) => {
                self.start_rps = v;
                self.apply_profile();
            }
            Command::Distance(d) => self.distance = d,
            Command::Preset => self.continuous = false,
            Command::Continuous => self.continuous = true,
            Command::Absolute => self.absolute = true,
            Command::Incremental => self.absolute = false,
            Command::Direction(d) => self.ccw = d.unwrap_or(!self.ccw),
            Command::Resolution(r) if r > 0 => {
                self.resolution = r;
                self.apply_profile();
            }
            Command::Go => self.go(),
            Command::Loop(n) => self.loops.push((self.pc, (n > 0).then_some(n))),
            Command::EndLoop => match self.loops.last_mut() {
                Some((start, None)) => self.pc = *start,
                Some((start, Some(left))) if *left > 1 => {
                    *left -= 1;
                    self.pc = *start;
                }
                Some(_) => {
                    self.loops.pop();
                }
                None => {}
            },
            Command::Position => {
                let s = format_position(self.machine.counter_steps());
                self.reply(&s);
            }
            Command::Zero => self.machine.zero(),
            Command::Notify => self.out.extend_from_slice(b"\r\n"),
            Command::Echo(on) => self.echo = on,
            Command::DeviceId(on) => self.device_id = on,
            Command::Trigger(p) => self.wait = Wait::Trigger(p),
            _ => {}
        }
    }

    fn go(&mut self) {
        let dir = if self.ccw { 1 } else { -1 };
        let result = if self.continuous {
            if self.velocity_rps <= 0.0 {
                self.machine.stop();
                Ok(())
            } else {
                self.machine.start_continuous(dir)
            }
        } else {
            let steps = if self.absolute {
                self.distance.saturating_sub(self.machine.counter_steps())
            } else {
                self.distance
            };
            self.machine.start_preset(steps)
        };
        match result {
            Ok(()) => {
                self.attention = false;
                if !self.continuous {
                    self.wait = Wait::Move;
                }
            }
            Err(e) => self.refuse(e),
        }
    }
}

impl Frontend for Card {
    fn receive(&mut self, bytes: &[u8], now_s: f64) {
        for &b in bytes {
            if self.echo {
                self.out.push(b);
            }
            match b {
                b'\r' | b'\n' | b' ' => self.token(now_s),
                _ if self.token.len() < MAX_TOKEN => self.token.push(b),
                _ => {}
            }
        }
    }

    fn poll(&mut self, now_s: f64) {
        self.machine.advance(now_s);
        self.run_buffer();
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
    use crate::profile::StepProfile;
    use crate::sim::machine::PULL_IN_SPS;
    use crate::sim::{Clock, VirtualClock};
    use crate::sync::{SyncOutput, Wire};
    use crate::units::Drive;
    use std::sync::Arc;

    fn card() -> Card {
        Card::new(Machine::new(Drive::default(), PULL_IN_SPS), 1)
    }

    /// Lets the card's clock run from `from_s` to `to_s`, polled every `step_s`.
    fn run(c: &mut Card, from_s: f64, to_s: f64, step_s: f64) {
        let mut t = from_s;
        while t < to_s {
            t += step_s;
            c.poll(t);
        }
    }

    fn say(c: &mut Card, text: &str, t: f64) -> String {
        c.receive(text.as_bytes(), t);
        String::from_utf8_lossy(&c.take_output()).into_owned()
    }

    #[test]
    fn echo_reply_and_completion() {
        let mut c = card();
        // echo of "1R" CR, then "*R" CR
        assert_eq!(say(&mut c, "1R\r", 0.0), "1R\r*R\r");
        assert_eq!(say(&mut c, "1SSA1\r", 0.0), "1SSA1\r");
        assert_eq!(say(&mut c, "1SSD1\r1R\r", 0.0), "*001R\r");
        say(&mut c, "1A10 1V2 1MPI 1D400 1G 1CR 1PR\r", 0.0);
        assert_eq!(say(&mut c, "1R\r", 0.1), "*001B\r");
        c.poll(5.0);
        // CR LF at completion, then the buffered PR
        assert_eq!(
            String::from_utf8_lossy(&c.take_output()),
            "\r\n*001+0000000400\r"
        );
        assert_eq!(say(&mut c, "1W3\r", 5.0), "*00100000190\r");
        // another device's command is ignored
        assert_eq!(say(&mut c, "2R\r", 5.0), "");
    }

    /// `PZ` zeroes the absolute position where the mandrel stands: the counter and the
    /// simulator's truth alike, without a move.
    #[test]
    fn pz_zeroes_the_position_where_the_mandrel_stands() {
        let mut c = card();
        say(&mut c, "1A10 1V2 1MPI 1D400 1G\r", 0.0);
        c.poll(5.0);
        assert_eq!(c.machine.counter_steps(), 400);
        assert_eq!(c.machine.motor_steps(), 400);
        say(&mut c, "1SSA1\r", 5.0);
        assert_eq!(say(&mut c, "1PZ 1PR\r", 5.0), "*+0000000000\r");
        assert_eq!(c.machine.motor_steps(), 0);
        assert!(!c.machine.is_moving());
    }

    /// `MPA`/`MPI` choose absolute or incremental distances: 300 absolute, then 100 more. `H`
    /// turns a continuous run round.
    #[test]
    fn position_modes_and_direction() {
        let mut c = card();
        say(&mut c, "1A10 1V2 1MPA 1D300 1G\r", 0.0);
        run(&mut c, 0.0, 5.0, 0.01);
        assert_eq!(c.machine.counter_steps(), 300);
        say(&mut c, "1MPI 1D100 1G\r", 5.0);
        run(&mut c, 5.0, 10.0, 0.01);
        assert_eq!(c.machine.counter_steps(), 400);
        say(&mut c, "1MC 1G\r", 10.0);
        run(&mut c, 10.0, 11.0, 0.01);
        let forward = c.machine.counter_steps();
        assert!(forward > 400, "{forward}");
        say(&mut c, "1K\r", 11.0);
        say(&mut c, "1H 1G\r", 11.0);
        run(&mut c, 11.0, 12.0, 0.01);
        assert!(
            c.machine.counter_steps() < forward,
            "{}",
            c.machine.counter_steps()
        );
    }

    /// `L n … N` runs its body n times; `L0` runs it until stopped.
    #[test]
    fn loops_run_their_count_and_l0_until_stopped() {
        let mut c = card();
        say(&mut c, "1A10 1V2 1MPI 1L3 1D100 1G 1N\r", 0.0);
        run(&mut c, 0.0, 10.0, 0.01);
        assert_eq!(c.machine.counter_steps(), 300);
        let mut c = card();
        say(&mut c, "1A10 1V2 1MPI 1L0 1D100 1G 1N\r", 0.0);
        run(&mut c, 0.0, 20.0, 0.05);
        assert!(
            c.machine.counter_steps() > 1000,
            "{}",
            c.machine.counter_steps()
        );
    }

    /// Values outside the guide's ranges are ignored (A 0.01–999 rev/s², V and VS 0–50 rev/s, MR
    /// above 0): the profile keeps the last good ones, in steps at the motor resolution.
    #[test]
    fn values_outside_the_ranges_are_ignored() {
        let mut c = card();
        say(&mut c, "1MR400 1A10 1V2 1VS0.5\r", 0.0);
        let want = StepProfile {
            v0_sps: 200.0,
            vmax_sps: 800.0,
            accel_sps2: 4000.0,
        };
        assert_eq!(c.machine.profile, want);
        say(&mut c, "1A1000 1A0.001 1V60 1VS51 1MR0\r", 0.0);
        assert_eq!(c.machine.profile, want);
        say(&mut c, "1MR800\r", 0.0);
        assert_eq!(c.machine.profile.vmax_sps, 1600.0);
    }

    #[test]
    fn reset_is_busy_for_one_second() {
        let mut c = card();
        say(&mut c, "1MPI 1D100 1G\r", 0.0);
        say(&mut c, "1Z\r", 0.05);
        assert_eq!(say(&mut c, "1R\r", 0.5), "1R\r*B\r");
        assert_eq!(say(&mut c, "1R\r", 1.06), "1R\r*R\r");
        assert_eq!(c.machine.counter_steps(), 0);
    }

    #[test]
    fn loops_alternate_between_two_positions() {
        let mut c = card();
        say(
            &mut c,
            "1SSA1\r1A50 1V5 1MN 1MPA 1L3 1D300 1G 1D-300 1G 1N 1PR\r",
            0.0,
        );
        let mut t = 0.0;
        let mut seen_positive = 0;
        while t < 20.0 {
            t += 0.01;
            c.poll(t);
            if c.machine.counter_steps() == 300 {
                seen_positive += 1;
            }
        }
        assert!(seen_positive > 0);
        assert_eq!(String::from_utf8_lossy(&c.take_output()), "*-0000000300\r");
    }

    /// Above the translator's 10 000 pulses/s the card still runs the move and reports it done
    /// and ready, as a real indexer would: the lost steps show only in the simulator's truth.
    #[test]
    fn over_the_limit_steps_are_lost_without_a_word() {
        let mut c = card();
        say(&mut c, "1SSA1\r", 0.0);
        // 30 rev/s × 400 = 12 000 pulses/s, on a ramp of 10 rev/s² (4000 steps/s²) that the
        // motor follows up to the translator's 10 000 (sim::motor: a steeper one stalls it).
        let out = say(&mut c, "1A10 1V30 1D80000 1G\r", 0.0);
        assert!(!out.contains('?'), "{out}");
        run(&mut c, 0.0, 14.0, 0.001);
        assert_eq!(say(&mut c, "1R\r", 14.0), "*R\r");
        assert_eq!(c.machine.counter_steps(), 80_000);
        assert!(c.machine.lost_steps() > 5_000, "{}", c.machine.lost_steps());
        assert_eq!(
            c.machine.motor_steps() + c.machine.lost_steps() as i64,
            80_000
        );
    }

    #[test]
    fn trigger_waits_for_the_start_wire() {
        let clock = VirtualClock::new();
        let start = Wire::new(Arc::new(clock.clone()), 0.001);
        let mut pc = start.clone();
        let mut c = card().with_trigger(Box::new(start));
        say(&mut c, "1SSA1\r1MPI 1D50 1TR1 1G\r", 0.0);
        c.poll(0.5);
        assert_eq!(c.machine.counter_steps(), 0);
        clock.advance_s(0.5);
        pc.set(true).unwrap();
        clock.advance_s(0.002);
        c.poll(clock.now_s());
        c.poll(2.0);
        assert_eq!(c.machine.counter_steps(), 50);
    }

    #[test]
    fn continuous_runs_until_stopped() {
        let mut c = card();
        say(&mut c, "1SSA1\r1A20 1MC 1H- 1V2 1G\r", 0.0);
        c.poll(3.0);
        assert!(c.machine.is_moving());
        assert!(c.machine.counter_steps() < -1000);
        say(&mut c, "1S\r", 3.0);
        c.poll(4.0);
        assert!(!c.machine.is_moving());
    }

    proptest::proptest! {
        #[test]
        fn arbitrary_input_never_panics(chunks in proptest::collection::vec(proptest::collection::vec(proptest::prelude::any::<u8>(), 0..40), 0..8)) {
            let mut c = card();
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
