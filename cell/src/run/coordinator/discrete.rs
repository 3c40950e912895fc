//! Discrete mode (file control, seed 001 §5.6.4): one robot and one mandrel instruction at a
//! time, both confirmed, each segment journaled.

use serde_json::json;

use super::*;

impl Coordinator<'_> {
    pub(super) fn discrete_item(
        &mut self,
        batch: &Batch,
        k: usize,
        resume: Option<&ResumePoint>,
    ) -> Result<(), Step> {
        let prep = &batch.prepared[k];
        let item = &batch.items[k];
        let from = resume.map_or(0, |r| r.segments_done);
        if from == 0 {
            self.phase(Phase::Approach { item: k + 1 });
        }
        let base = self.sync_item(batch, k, resume)?;
        self.segments_done = from;
        let n = prep.targets_mm.len();
        // Where the robot is: read before the first segment, then what each segment confirmed.
        let mut here = None;
        if from > 0 && from < n && !resume.is_some_and(|r| r.rereference) {
            // A resume mid-path: the arm is the second witness. It stands on the move from the
            // last confirmed point to the next one, or the run stops before anything moves.
            let at = self.dev.robot.position_mm()?;
            let confirmed = prep.targets_mm[from - 1];
            let off_mm = distance_to_segment_mm(at, confirmed, prep.targets_mm[from]);
            if off_mm > ARM_WITNESS_MM {
                return Err(Fault::ArmUnreferenced(Box::new(ArmWitness {
                    at_mm: at,
                    confirmed_mm: confirmed,
                    off_mm,
                    segment: from + 1,
                }))
                .into());
            }
            here = Some(at);
        }
        if from > 0 {
            self.phase(Phase::Winding { item: k + 1 });
        }
        for s in from..n {
            self.check()?;
            let target = base + prep.cumulative_steps[s + 1];
            // Send both, then wait for both (seed 001 §5.3.3).
            let counter = if s == from {
                self.counter()?
            } else {
                base + prep.cumulative_steps[s]
            };
            // With the sync lines wired the mandrel's move waits for the start line, raised once
            // the robot's move is confirmed: both devices start together, where the indexer's
            // command and the robot's confirmation would otherwise put the mandrel 0.1–0.2 s
            // ahead of the arm on every segment.
            let wired = self.dev.sync.wired();
            let moving = self.mandrel_start(prep.mandrel[s], counter, target, wired)?;
            let at = match here {
                Some(p) => p,
                None => self.dev.robot.position_mm()?,
            };
            let sent = self.robot_send(prep.immediate[s], prep.targets_mm[s], at)?;
            // The mandrel's shorter move is confirmed while the arm still moves (its reads are
            // on the indexer's link, which does not hold the arm).
            if moving {
                if wired {
                    self.dev.sync.set_start(true)?;
                }
                self.mandrel_finish(target)?;
                if wired {
                    self.dev.sync.set_start(false)?;
                }
            }
            here = Some(if sent {
                self.robot_settle(prep.targets_mm[s])?
            } else {
                at
            });
            self.segments_done = s + 1;
            self.journal.append(json!({
                "rec": "segment", "item": k, "segment": s + 1,
                "robot_mm": prep.targets_mm[s], "counter": target,
                "t_s": self.dev.time.now_s(),
            }))?;
            // Instruction 1 is the approach to the path's first point; the plan's segments
            // are the instructions after it.
            if s == 0 {
                self.phase(Phase::Winding { item: k + 1 });
            } else {
                (self.events)(Event::Segment {
                    item: k + 1,
                    program: item.rob.header.program,
                    path: item.name.clone(),
                    segment: s,
                    segments: n - 1,
                    witness: Witness::Both,
                    time_s: self.dev.time.now_s(),
                });
            }
        }
        Ok(())
    }
}
