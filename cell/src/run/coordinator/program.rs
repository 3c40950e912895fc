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
        self.phase(Phase::Upload);
        // Each instruction is stored, verified and read back: three exchanges.
        let total = 3 * programs.iter().map(|(_, l)| l.len()).sum::<usize>();
        let mut done = 0;
        let time = self.dev.time.clone();
        for (p, list) in &programs {
            self.check()?;
            self.dev.robot.delete_program(*p)?;
            let events = &mut *self.events;
            self.dev.robot.upload(*p, list, &mut || {
                upload_progress(events, &mut done, total, time.now_s());
            })?;
        }
        for (p, list) in &programs {
            self.check()?;
            let events = &mut *self.events;
            self.dev.robot.read_back(*p, list, &mut || {
                upload_progress(events, &mut done, total, time.now_s());
            })?;
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

    /// A resumed item whose program was started: what the devices finished. The path done
    /// (the arm at its last point, the counter at its end), to start again (stopped before the
    /// first position, or the mandrel never left the sync), or to go on from where the arm
    /// stopped with the rest of its positions stored as [`RESUME_PROGRAM`].
    fn resume_started(&mut self, batch: &Batch, k: usize, sync: i64) -> Result<Started, Step> {
        let prep = &batch.prepared[k];
        let n = prep.targets_mm.len();
        let last = prep.targets_mm[n - 1];
        let end = sync + prep.cumulative_steps[n];
        let s = self.dev.robot.state()?;
        let here = self.dev.robot.position_mm()?;
        // A move still turning (the devices ran on after `kill -9`) finishes (an armed move
        // that never saw its start edge was cancelled before the attach).
        self.wait("mandrel move", MOVE_TIMEOUT_S, |d| Ok(!d.mandrel.busy()?.0))?;
        let counter = self.counter()?;
        if distance_mm(here, last) <= POSITION_TOLERANCE_MM && counter == end {
            return Ok(Started::Finished);
        }
        // The robot's instruction when it stopped; before the first position: start again.
        let reached = usize::from(s.instruction.saturating_sub(HANDSHAKE_LEAD));
        if reached < 1 || counter == sync {
            return Ok(Started::Again);
        }
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
        self.phase(Phase::Upload);
        let (total, mut done, time) = (3 * list.len(), 0, self.dev.time.clone());
        let events = &mut *self.events;
        let mut progress = || upload_progress(events, &mut done, total, time.now_s());
        self.dev
            .robot
            .upload(RESUME_PROGRAM, &list, &mut progress)?;
        self.dev
            .robot
            .read_back(RESUME_PROGRAM, &list, &mut progress)?;
        self.journal.append(json!({
            "rec": "resume_program", "item": k, "program": RESUME_PROGRAM,
            "from_instruction": reached,
        }))?;
        Ok(Started::From { counter })
    }

    /// The stored program flies: the start line raised, the robot left alone until it raises
    /// "in position", the indexer asked for its progress every [`PROGRESS_POLL_S`] (segments
    /// reported through `passed`), the robot read for errors only once the program overruns
    /// its mandrel move (`mandrel_s`) by half again plus a second.
    fn fly(
        &mut self,
        batch: &Batch,
        k: usize,
        mandrel_s: f64,
        counter: i64,
        armed: bool,
        passed: &mut Passed<'_>,
    ) -> Result<(), Step> {
        self.dev.sync.set_start(true)?;
        let quiet_until_s =
            self.dev.time.now_s() + PROGRAM_QUIET_FACTOR * mandrel_s + PROGRAM_QUIET_MARGIN_S;
        let mut polls = 0u32;
        let mut next_poll_s = self.dev.time.now_s() + PROGRESS_POLL_S;
        let mut under_way = false;
        let item = &batch.items[k];
        let n = batch.prepared[k].targets_mm.len();
        let path = item.name.clone();
        let header_program = item.rob.header.program;
        self.wait_reporting("the robot's program", MOVE_TIMEOUT_S, |d, events| {
            if armed && d.time.now_s() >= next_poll_s {
                next_poll_s += PROGRESS_POLL_S;
                let (busy, _) = d.mandrel.busy()?;
                under_way |= busy;
                if under_way {
                    let at = counter + d.mandrel.move_steps()?;
                    for segment in passed.take(at) {
                        events(Event::Segment {
                            item: k + 1,
                            program: header_program,
                            path: path.clone(),
                            segment,
                            segments: n - 1,
                            witness: Witness::Indexer,
                            time_s: d.time.now_s(),
                        });
                    }
                }
            }
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
            match self.resume_started(batch, k, sync)? {
                Started::Finished => return Ok(()),
                Started::Again => {}
                Started::From { counter } => {
                    program = RESUME_PROGRAM;
                    base = Some((sync, counter));
                }
            }
        }
        let (sync, counter) = match base {
            Some(b) => b,
            None => {
                self.phase(Phase::Approach { item: k + 1 });
                let sync = self.sync_item(batch, k, resume)?;
                // The approach: robot at the first point before the start edge.
                self.robot_to(prep.immediate[0], prep.targets_mm[0])?;
                (sync, sync)
            }
        };
        let end = sync + prep.cumulative_steps[n];
        self.journal
            .append(json!({"rec": "program", "item": k, "program": program}))?;
        self.phase(Phase::Winding { item: k + 1 });
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
        // Progress from the indexer, which can be asked while the program runs: its steps
        // through the path's one move, once the card shows the move under way (before that,
        // `W3` still counts the move before).
        let mut passed = Passed {
            sync,
            start: counter,
            cumulative: &prep.cumulative_steps,
            reported: 0,
        };
        // A resumed program: what the run before wound is not reported again.
        if base.is_some() {
            passed.reported = passed.count(counter);
        }
        self.fly(batch, k, mandrel_s, counter, armed, &mut passed)?;
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
        // The rest, confirmed now by both: the arm at the path's last point, the counter at its
        // end.
        let time_s = self.dev.time.now_s();
        for segment in passed.take_all() {
            (self.events)(Event::Segment {
                item: k + 1,
                program: item.rob.header.program,
                path: item.name.clone(),
                segment,
                segments: n - 1,
                witness: Witness::Both,
                time_s,
            });
        }
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

/// One exchange of the upload done: an [`Event::Upload`] at each whole percent and at the end (a
/// 9600-baud upload takes minutes; an event per exchange would be hundreds).
fn upload_progress(events: &mut dyn FnMut(Event), done: &mut usize, total: usize, time_s: f64) {
    *done += 1;
    if *done * 100 / total != (*done - 1) * 100 / total || *done == total {
        events(Event::Upload {
            done: *done,
            total,
            time_s,
        });
    }
}

/// How often the indexer is asked for its progress while a program runs, s (two exchanges of
/// a few milliseconds each on the indexer's own link).
const PROGRESS_POLL_S: f64 = 0.5;

/// The segments of a program-mode path that the mandrel's steps have passed.
struct Passed<'p> {
    /// The counter the path's sync aimed at (its cumulative steps count from there).
    sync: i64,
    /// The counter where the path's move started.
    start: i64,
    /// Steps at the end of each instruction, from the sync (instruction 1, the approach, first).
    cumulative: &'p [i64],
    /// Segments reported so far.
    reported: usize,
}

impl Passed<'_> {
    /// Segments (1..N, the approach not one) whose end the counter `at` has reached, moving from
    /// `start` towards the path's end.
    fn count(&self, at: i64) -> usize {
        let end = self.sync + self.cumulative.last().copied().unwrap_or(0);
        let direction = (end - self.start).signum();
        if direction == 0 {
            return 0;
        }
        // Segment k ends at `cumulative[k + 1]`.
        (1..self.cumulative.len().saturating_sub(1))
            .take_while(|&k| direction * (at - (self.sync + self.cumulative[k + 1])) >= 0)
            .count()
    }

    /// The segments newly passed at `at`, in order (never one twice, never back).
    fn take(&mut self, at: i64) -> std::ops::RangeInclusive<usize> {
        let now = self.count(at).max(self.reported);
        let new = self.reported + 1..=now;
        self.reported = now;
        new
    }

    /// Every segment not reported yet.
    fn take_all(&mut self) -> std::ops::RangeInclusive<usize> {
        let all = self.cumulative.len().saturating_sub(2);
        let new = self.reported + 1..=all;
        self.reported = all;
        new
    }
}

/// What a resumed item's started program left ([`Coordinator::resume_started`]).
enum Started {
    /// The path is wound.
    Finished,
    /// Nothing of it was wound: the item starts again from its sync.
    Again,
    /// Part of it: the rest is stored as the resume program, the mandrel at `counter`.
    From {
        /// The indexer's counter where the mandrel stands.
        counter: i64,
    },
}
