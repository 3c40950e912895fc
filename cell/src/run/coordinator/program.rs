//! Program mode (fine, medium, continuous; seed 001 §5.6.4, App. D): the batch's programs
//! uploaded and read back, each path run as a stored program on the start and in-position lines.

use serde_json::json;

use super::*;

impl Coordinator<'_> {
    /// Uploads every program of the batch (verified stores), reads them all back, and runs each
    /// in standby first when asked (seed 001 §5.3.1).
    pub(super) fn upload(&mut self, batch: &Batch, standby: bool) -> Result<(), Step> {
        let mut programs: Vec<(u8, &Vec<Instruction>)> = Vec::new();
        for (item, prep) in batch.items.iter().zip(&batch.prepared) {
            let p = item.rob.header.program;
            if let Some(list) = &prep.program
                && !programs.iter().any(|(q, _)| *q == p)
            {
                programs.push((p, list));
            }
        }
        for (p, list) in &programs {
            self.check()?;
            self.dev.robot.delete_program(*p)?;
            self.dev.robot.upload(*p, list)?;
        }
        for (p, list) in &programs {
            self.check()?;
            self.dev.robot.read_back(*p, list)?;
        }
        if standby {
            self.dev.robot.set_operate(false)?;
            for (p, _) in &programs {
                self.dev.robot.run_program(*p)?;
            }
            self.dev.robot.set_operate(true)?;
        }
        let nums: Vec<u8> = programs.iter().map(|(p, _)| *p).collect();
        self.journal
            .append(json!({"rec": "uploaded", "programs": nums, "standby": standby}))?;
        (self.events)(Event::Uploaded { programs: nums });
        Ok(())
    }

    pub(super) fn program_item(
        &mut self,
        batch: &Batch,
        k: usize,
        resume: Option<&ResumePoint>,
    ) -> Result<(), Step> {
        let prep = &batch.prepared[k];
        let item = &batch.items[k];
        let n = prep.targets_mm.len();
        let last = prep.targets_mm[n - 1];
        let mut program = item.rob.header.program;
        let mut base = None;
        let ind = item
            .ind
            .as_ref()
            .map(|f| f.path_move)
            .unwrap_or(prep.mandrel[0]);
        if let Some(r) = resume.filter(|r| r.program_started)
            && let Some(sync) = r.sync_counter
        {
            // The program was started: ask the devices what they finished.
            let end = sync + prep.cumulative_steps[n];
            let s = self.dev.robot.state()?;
            let here = self.dev.robot.position_mm()?;
            // A move still turning (the devices ran on after `kill -9`) finishes (an armed
            // move that never saw its start edge was cancelled before the attach).
            self.wait("mandrel move", MOVE_TIMEOUT_S, |d| Ok(!d.mandrel.busy()?.0))?;
            let counter = self.counter()?;
            if distance_mm(here, last) <= POSITION_TOLERANCE_MM && counter == end {
                return Ok(());
            }
            // The robot's instruction when it stopped; before the first position: start again.
            let reached = usize::from(s.instruction.saturating_sub(HANDSHAKE_LEAD));
            if reached >= 1 && counter != sync {
                let rest: Vec<Instruction> = prep
                    .program
                    .iter()
                    .flatten()
                    .filter(|i| matches!(i, Instruction::Position(_)))
                    .skip(reached - 1)
                    .copied()
                    .collect();
                let list = handshake_program(&rest);
                self.dev.robot.delete_program(RESUME_PROGRAM)?;
                self.dev.robot.upload(RESUME_PROGRAM, &list)?;
                self.dev.robot.read_back(RESUME_PROGRAM, &list)?;
                self.journal.append(json!({
                    "rec": "resume_program", "item": k, "program": RESUME_PROGRAM,
                    "from_instruction": reached,
                }))?;
                program = RESUME_PROGRAM;
                base = Some((sync, counter));
            }
        }
        let (sync, counter) = match base {
            Some(b) => b,
            None => {
                let sync = self.sync_item(batch, k, resume)?;
                // The approach: robot at the first point before the start edge.
                self.robot_to(prep.immediate[0], prep.targets_mm[0])?;
                (sync, sync)
            }
        };
        let end = sync + prep.cumulative_steps[n];
        self.journal
            .append(json!({"rec": "program", "item": k, "program": program}))?;
        (self.events)(Event::Program {
            item: k + 1,
            program,
            path: item.name.clone(),
            done: false,
            time_s: self.dev.time.now_s(),
        });
        // Handshake (App. D): run; the program lowers "in position" and waits for start.
        self.dev.robot.run_program(program)?;
        self.wait("the robot's handshake", MOVE_TIMEOUT_S, |d| {
            Ok(!d.sync.in_position()?)
        })?;
        // The mandrel's move, armed on the start line.
        let armed = self.mandrel_start(ind, counter, end, true)?;
        // While the program flies nothing is said to the robot: the robot computer holds the
        // arm while it serves the link (seed 001 §4.1.2), so every status read would stall the
        // eye against the turning mandrel (a read every half second put the eye 0.06 s per
        // second behind, timing drift of 7–14 mm on the S-bend). The start and in-position lines
        // pace the program, as in the thesis's program control (§5.6.4); the stop request and
        // the e-stop input are still looked at every control tick. A program that overruns its
        // mandrel move by half again plus a second is then read for errors.
        let mandrel_s = MandrelProfile {
            accel_rps2: ind.accel_rps2,
            start_stop_rps: ind.start_stop_rps,
            max_rps: ind.max_rps,
        }
        .duration_s(
            (end - counter).unsigned_abs(),
            batch.drive.steps_per_mandrel_rev(),
        );
        self.dev.sync.set_start(true)?;
        let quiet_until_s =
            self.dev.time.now_s() + PROGRAM_QUIET_FACTOR * mandrel_s + PROGRAM_QUIET_MARGIN_S;
        let mut polls = 0u32;
        self.wait("the robot's program", MOVE_TIMEOUT_S, |d| {
            if d.time.now_s() < quiet_until_s {
                return d.sync.in_position();
            }
            polls += 1;
            if polls.is_multiple_of(PROGRAM_POLL_TICKS) {
                let s = d.robot.state()?;
                if s.state == State::Error || s.last_error != 0 {
                    return Err(DeviceError::RobotState {
                        what: format!("error {} at instruction {}", s.last_error, s.instruction),
                    });
                }
            }
            d.sync.in_position()
        })?;
        // The program's end: one status read (the arm is at rest now) for an error shown
        // while it ran.
        let s = self.dev.robot.state()?;
        if s.state == State::Error || s.last_error != 0 {
            return Err(Fault::ProgramError {
                error: s.last_error,
                instruction: s.instruction,
                program,
            }
            .into());
        }
        self.dev.sync.set_start(false)?;
        if armed {
            self.mandrel_finish(end)?;
        }
        let here = self.dev.robot.position_mm()?;
        if distance_mm(here, last) > POSITION_TOLERANCE_MM {
            return Err(Fault::ProgramEndedOff {
                program,
                off_mm: distance_mm(here, last),
            }
            .into());
        }
        self.segments_done = n;
        (self.events)(Event::Program {
            item: k + 1,
            program,
            path: item.name.clone(),
            done: true,
            time_s: self.dev.time.now_s(),
        });
        Ok(())
    }
}
