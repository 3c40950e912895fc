//! The moves every mode is made of: the robot ready and homed, an immediate move sent and
//! confirmed, a mandrel move started and confirmed, the mandrel synchronised to a path's start.

use serde_json::json;

use super::*;

impl Coordinator<'_> {
    /// Operate mode and homed (homing again if the robot lost it).
    pub(super) fn ready_robot(&mut self) -> Result<(), Step> {
        let s = self.dev.robot.state()?;
        if s.state == State::Running
            && s.instruction == HANDSHAKE_LEAD
            && !self.dev.sync.in_position()?
        {
            // A program left waiting for the start edge: it never began; cancel it and the
            // mandrel's armed move.
            self.dev.robot.stop()?;
            self.dev.mandrel.stop()?;
        }
        let s = self.dev.robot.state()?;
        if s.state == State::Running {
            // A program or move left running (a coordinator killed mid-run): let it finish, as
            // the robot computer would without us.
            self.wait("the robot's unfinished motion", MOVE_TIMEOUT_S, |d| {
                Ok(d.robot.state()?.state != State::Running)
            })?;
        }
        if self.dev.robot.state()?.state == State::Homing {
            self.phase(Phase::Homing);
            // A home synchronisation a killed run started: any command now would be refused
            // (robot error 7, busy); it is waited out.
            self.wait("the robot's home synchronisation", HOME_TIMEOUT_S, |d| {
                Ok(d.robot.state()?.state != State::Homing)
            })?;
        }
        let s = self.dev.robot.state()?;
        if !s.operate {
            self.dev.robot.set_operate(true)?;
        }
        if !s.homed {
            self.phase(Phase::Homing);
            self.dev.robot.start_home()?;
            self.journal.append(json!({"rec": "home"}))?;
            self.wait("home synchronisation", HOME_TIMEOUT_S, |d| {
                let s = d.robot.state()?;
                Ok(s.homed && s.state == State::Idle)
            })?;
        }
        Ok(())
    }

    /// Robot to `target` as an immediate move unless it is there; waits and confirms.
    pub(super) fn robot_to(&mut self, p: Positioning, target: [f64; 3]) -> Result<(), Step> {
        let here = self.dev.robot.position_mm()?;
        if self.robot_send(p, target, here)? {
            self.robot_settle(target)?;
        }
        Ok(())
    }

    /// Sends the immediate move to `target` (confirmed executed once) unless the robot, at
    /// `here`, is there already; whether it was sent.
    pub(super) fn robot_send(
        &mut self,
        p: Positioning,
        target: [f64; 3],
        here: [f64; 3],
    ) -> Result<bool, Step> {
        if distance_mm(here, target) <= POSITION_TOLERANCE_MM {
            return Ok(false);
        }
        self.dev.robot.move_immediate(p)?;
        Ok(true)
    }

    /// Waits for the robot's immediate move to `target` to end, then confirms its state (idle,
    /// no error) and its position, which it returns.
    ///
    /// The in-position line is seen through the opto-isolators' delay (App. D): right after
    /// the move's telegram and its confirming reads it may still show the level the previous
    /// move left high. The state read that follows the line tells a stale level (the robot still
    /// running) from the move's end; a stale level is waited out, low and then high again, at
    /// most [`STALE_IN_POSITION_WAITS`] times.
    pub(super) fn robot_settle(&mut self, target: [f64; 3]) -> Result<[f64; 3], Step> {
        let s = if self.dev.sync.wired() {
            let mut waits = 0;
            loop {
                self.wait("robot move", MOVE_TIMEOUT_S, |d| d.sync.in_position())?;
                let s = self.dev.robot.state()?;
                if s.state != State::Running || waits == STALE_IN_POSITION_WAITS {
                    break s;
                }
                waits += 1;
                self.wait("robot move", MOVE_TIMEOUT_S, |d| {
                    Ok(!d.sync.in_position()?)
                })?;
            }
        } else {
            self.wait("robot move", MOVE_TIMEOUT_S, |d| {
                Ok(d.robot.state()?.state != State::Running)
            })?;
            self.dev.robot.state()?
        };
        if s.state != State::Idle || s.last_error != 0 {
            return Err(Fault::NotIdleAfterMove {
                state: s.state,
                error: s.last_error,
            }
            .into());
        }
        let here = self.dev.robot.position_mm()?;
        if distance_mm(here, target) > POSITION_TOLERANCE_MM {
            return Err(Fault::OffTarget {
                at_mm: here,
                off_mm: distance_mm(here, target),
            }
            .into());
        }
        Ok(here)
    }

    /// Starts a mandrel move to counter `target` from `counter` (nothing if equal).
    pub(super) fn mandrel_start(
        &mut self,
        profile: MandrelMove,
        counter: i64,
        target: i64,
        armed: bool,
    ) -> Result<bool, Step> {
        let steps = target - counter;
        if steps == 0 {
            return Ok(false);
        }
        self.dev
            .mandrel
            .start_move(&MandrelMove { steps, ..profile }, armed)?;
        Ok(true)
    }

    pub(super) fn mandrel_finish(&mut self, target: i64) -> Result<(), Step> {
        self.wait("mandrel move", MOVE_TIMEOUT_S, |d| {
            let (busy, fault) = d.mandrel.busy()?;
            if fault {
                return Err(DeviceError::Indexer(mandrel_drive::Error::Stalled));
            }
            Ok(!busy)
        })?;
        let c = self.counter()?;
        if c != target {
            return Err(Fault::CounterMismatch {
                counter_steps: c,
                expected_steps: target,
            }
            .into());
        }
        Ok(())
    }

    /// The counter the item's sync aims at: the path's start angle (`sync_mandrel_deg`) nearest
    /// the mandrel's angle now.
    pub(super) fn sync_target(&self, batch: &Batch, k: usize, counter: i64) -> i64 {
        let per_rev = batch.drive.steps_per_mandrel_rev();
        let want = batch.items[k].rob.header.sync_mandrel_deg / 360.0 * per_rev;
        let now = counter as f64;
        let delta = (want - now).rem_euclid(per_rev);
        let delta = if delta > per_rev / 2.0 {
            delta - per_rev
        } else {
            delta
        };
        counter + delta.round() as i64
    }

    /// Sync mandrel to robot: the robot at the path's first point, the mandrel at its start angle.
    pub(super) fn sync_item(
        &mut self,
        batch: &Batch,
        k: usize,
        resume: Option<&ResumePoint>,
    ) -> Result<i64, Step> {
        let prep = &batch.prepared[k];
        let (base, max) = transfer::speeds(&batch.items[k].rob.header)
            .map_err(|e| Fault::Transfer(Arc::new(e)))?;
        if let Some(r) = resume.filter(|r| r.segments_done > 0)
            && let Some(sync) = r.sync_counter
        {
            // Mid-path: the path's start angle is behind the mandrel. It continues from where it
            // stands (checked against the journal on attach), never turned back to the start
            // and forward again.
            self.dev.robot.set_speeds(base, max)?;
            return Ok(sync);
        }
        let counter = self.counter()?;
        let target = match resume.and_then(|r| r.sync_counter) {
            Some(t) => t,
            None => {
                let t = self.sync_target(batch, k, counter);
                self.journal
                    .append(json!({"rec": "sync", "item": k, "counter": t}))?;
                t
            }
        };
        self.dev.robot.set_speeds(base, max)?;
        let moving = self.mandrel_start(prep.mandrel[0], counter, target, false)?;
        if moving {
            self.mandrel_finish(target)?;
        }
        Ok(target)
    }
}
