//! Where a run resumes: the journal's records read back against the batch they claim to be.

use serde_json::json;

use super::*;
use crate::error::JournalMismatch;
use crate::run::journal;

/// Where to resume: from the journal.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ResumePoint {
    /// Items already finished.
    pub items_done: usize,
    /// The indexer counter the current item's sync aimed at, if its sync was journaled.
    pub sync_counter: Option<i64>,
    /// Segments confirmed in the current item (discrete).
    pub segments_done: usize,
    /// The current item's program was started (program mode).
    pub program_started: bool,
    /// The journal holds the batch's `mandrel_zero`: the counter's frame is the batch's.
    pub zeroed: bool,
    /// The batch's counter where the last confirmed step left the mandrel (the zero, a sync, a
    /// segment's or a program's destination), if the journal says.
    pub counter_confirmed: Option<i64>,
    /// The destination of the step that may have been under way after it (a sync started, the
    /// next segment, a program started): the mandrel stands between the two, never outside.
    pub counter_next: Option<i64>,
    /// The indexer's counter minus the batch's counter, from the last re-reference (0 before
    /// any).
    pub offset_steps: i64,
    /// The run before stopped on a stall of the mandrel motor: its counter counted steps the
    /// motor did not make, so it is no witness until the mandrel is re-referenced.
    pub stalled: bool,
    /// The operator confirms that the cell stands where the journal's last confirmed step left
    /// it, the mandrel at that step's angle and the arm at its point (`windcell run --resume …
    /// --rereference`; implied on the built-in simulated cell, which a new process powers up
    /// anew): the counter is re-referenced to it and the arm is not checked against it.
    pub rereference: bool,
}

/// Reads a journal's records into a resume point, checking it belongs to `batch`.
pub fn resume_point(
    batch: &Batch,
    records: &[serde_json::Map<String, serde_json::Value>],
) -> Result<ResumePoint, Error> {
    let begin = records
        .first()
        .filter(|r| journal::kind(r) == Some("begin"))
        .ok_or(Error::JournalMismatch(JournalMismatch::NoBegin))?;
    if begin.get("job").and_then(|v| v.as_str()) != Some(batch.job_id.as_str()) {
        return Err(Error::JournalMismatch(JournalMismatch::OtherJob));
    }
    if begin.get("mode").and_then(|v| v.as_str()) != Some(batch.mode.keyword()) {
        return Err(Error::JournalMismatch(JournalMismatch::OtherMode {
            journal: begin
                .get("mode")
                .and_then(|v| v.as_str())
                .unwrap_or("?")
                .chars()
                .filter(|c| !c.is_control())
                .take(20)
                .collect(),
            run: batch.mode.keyword(),
        }));
    }
    let names: Vec<&str> = batch.items.iter().map(|i| i.name.as_str()).collect();
    let items = begin.get("items").and_then(|v| v.as_array());
    // Every journal windcell writes names its paths; where it does, they must be the batch's.
    if items.is_some_and(|v| {
        v.iter()
            .map(|n| n.as_str())
            .ne(names.iter().map(|n| Some(*n)))
    }) {
        let journal = begin
            .get("items")
            .map(|v| v.to_string())
            .unwrap_or_default();
        let mut journal: String = journal
            .chars()
            .filter(|c| !c.is_control())
            .take(80)
            .collect();
        if journal.is_empty() {
            journal = "none".into();
        }
        return Err(Error::JournalMismatch(JournalMismatch::OtherItems {
            journal,
            batch: names.join(", "),
        }));
    }
    // Every number is held to the batch it claims to be: a journal is data, not trust.
    let per_rev = batch.drive.steps_per_mandrel_rev().ceil() as i64;
    let travel: i64 = batch
        .prepared
        .iter()
        .map(|p| {
            p.cumulative_steps
                .iter()
                .map(|s| s.abs())
                .max()
                .unwrap_or(0)
        })
        .sum();
    let counter_max = travel + per_rev * (batch.items.len() as i64 + 1);
    let mut p = ResumePoint::default();
    for (index, r) in records.iter().enumerate() {
        let field = |k: &'static str, min: i64, max: i64| -> Result<i64, Error> {
            let value = r.get(k).and_then(serde_json::Value::as_i64);
            match value {
                Some(v) if (min..=max).contains(&v) => Ok(v),
                _ => Err(Error::JournalMismatch(JournalMismatch::OutOfRange {
                    record: index + 1,
                    field: k,
                    value: r
                        .get(k)
                        .map(|v| match v.as_f64() {
                            Some(x) if !v.is_i64() => sequences::error::shown(x),
                            _ => v.to_string().chars().take(40).collect(),
                        })
                        .unwrap_or_default(),
                    min,
                    max,
                })),
            }
        };
        let current = p.items_done.min(batch.items.len().saturating_sub(1));
        let cumulative = &batch.prepared[current].cumulative_steps;
        match journal::kind(r) {
            Some("mandrel_zero") => {
                p.zeroed = true;
                p.counter_confirmed = Some(0);
                p.counter_next = None;
            }
            Some("rereference") => {
                p.offset_steps = field("offset", -i64::from(i32::MAX), i64::from(i32::MAX))?;
                p.stalled = false;
            }
            Some("item") => {
                field("item", p.items_done as i64, p.items_done as i64)?;
                p.sync_counter = None;
                p.segments_done = 0;
                p.program_started = false;
            }
            Some("sync") => {
                field("item", p.items_done as i64, p.items_done as i64)?;
                let t = field("counter", -counter_max, counter_max)?;
                p.sync_counter = Some(t);
                p.counter_next = Some(t);
            }
            Some("segment") => {
                field("item", p.items_done as i64, p.items_done as i64)?;
                let segments = batch.prepared[current].targets_mm.len() as i64;
                p.segments_done = field("segment", 1, segments)? as usize;
                let c = field("counter", -counter_max, counter_max)?;
                p.counter_confirmed = Some(c);
                p.counter_next = p
                    .sync_counter
                    .zip(cumulative.get(p.segments_done + 1))
                    .map(|(sync, steps)| sync + steps);
            }
            Some("resume") => {
                field("items_done", p.items_done as i64, p.items_done as i64)?;
            }
            Some("program") => {
                field("item", p.items_done as i64, p.items_done as i64)?;
                p.program_started = true;
                if let (Some(sync), Some(steps)) = (p.sync_counter, cumulative.last()) {
                    p.counter_confirmed = Some(sync);
                    p.counter_next = Some(sync + steps);
                }
            }
            Some("item_done") => {
                let next = p.items_done as i64 + 1;
                p.items_done = field("item", next, next)? as usize;
                p.sync_counter = None;
                p.segments_done = 0;
                p.program_started = false;
                if let Some(n) = p.counter_next.take() {
                    p.counter_confirmed = Some(n);
                }
            }
            Some("stopped")
                if r.get("stall").and_then(serde_json::Value::as_bool) == Some(true) =>
            {
                p.stalled = true;
            }
            _ => {}
        }
    }
    Ok(p)
}

/// How far the arm may stand from the chord between the last confirmed point and the next one
/// on a discrete resume, mm: a stop mid-segment leaves it on that move (the robot's joint-like
/// interpolation bulges a few tenths of a millimetre from the chord over a path's segments of a
/// few millimetres), where an arm homed again or moved by hand stands hundreds of millimetres away.
pub const ARM_WITNESS_MM: f64 = 5.0;

/// The distance from `p` to the segment from `a` to `b`, mm.
pub fn distance_to_segment_mm(p: [f64; 3], a: [f64; 3], b: [f64; 3]) -> f64 {
    let ab = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let ap = [p[0] - a[0], p[1] - a[1], p[2] - a[2]];
    let len2 = ab[0] * ab[0] + ab[1] * ab[1] + ab[2] * ab[2];
    let t = if len2 > 0.0 {
        ((ap[0] * ab[0] + ap[1] * ab[1] + ap[2] * ab[2]) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    distance_mm(p, [a[0] + t * ab[0], a[1] + t * ab[1], a[2] + t * ab[2]])
}

impl Coordinator<'_> {
    /// The mandrel's witnesses on a resume, cross-checked before anything turns: the indexer's
    /// counter (`counter`, as attached) must stand between the journal's last confirmed
    /// destination and the destination of the step that may have been under way, in the batch's
    /// frame (the offset of the last re-reference taken off). A power-cycled indexer (its counter
    /// at 0), a journal cut short (the devices further on than it says), a counter moved by
    /// another program, or a stall of the run before (steps counted that the motor never made)
    /// stop the run with [`Fault::MandrelUnreferenced`], which says how to re-reference. With the
    /// operator's confirmation ([`ResumePoint::rereference`]) the counter is re-referenced to the
    /// last confirmed step instead, and journaled. A journal without its `mandrel_zero` (a run
    /// killed before it zeroed: nothing had turned) zeroes now.
    pub(super) fn reconcile_mandrel(
        &mut self,
        batch: &Batch,
        from: &ResumePoint,
        counter: i64,
    ) -> Result<(), Step> {
        let Some(confirmed) = from.counter_confirmed.filter(|_| from.zeroed) else {
            self.dev.mandrel.zero()?;
            self.journal
                .append(json!({"rec": "mandrel_zero", "counter_before": counter}))?;
            self.offset_steps = 0;
            return Ok(());
        };
        if from.rereference {
            let offset = counter - confirmed;
            self.journal.append(json!({
                "rec": "rereference", "counter_before": counter, "counter": confirmed,
                "offset": offset,
            }))?;
            self.offset_steps = offset;
            return Ok(());
        }
        let batch_counter = counter - from.offset_steps;
        let next = from.counter_next.unwrap_or(confirmed);
        let (lo, hi) = (confirmed.min(next), confirmed.max(next));
        let cause = if from.stalled {
            Some(Disagreement::Stalled)
        } else if !(lo..=hi).contains(&batch_counter) {
            Some(Disagreement::Counter)
        } else {
            None
        };
        if let Some(cause) = cause {
            return Err(Fault::MandrelUnreferenced {
                cause,
                counter_steps: batch_counter,
                confirmed_steps: confirmed,
                next_steps: from.counter_next.filter(|n| *n != confirmed),
                confirmed_deg: confirmed as f64 * 360.0 / batch.drive.steps_per_mandrel_rev(),
            }
            .into());
        }
        self.offset_steps = from.offset_steps;
        Ok(())
    }
}
