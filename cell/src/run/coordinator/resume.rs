//! Where a run resumes: the journal's records read back against the batch they claim to be.

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
                .to_string(),
            run: batch.mode.keyword(),
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
                    value: r.get(k).map(|v| v.to_string()).unwrap_or_default(),
                    min,
                    max,
                })),
            }
        };
        let current = p.items_done.min(batch.items.len().saturating_sub(1));
        match journal::kind(r) {
            Some("item") => {
                p.sync_counter = None;
                p.segments_done = 0;
                p.program_started = false;
            }
            Some("sync") => p.sync_counter = Some(field("counter", -counter_max, counter_max)?),
            Some("segment") => {
                field("item", p.items_done as i64, p.items_done as i64)?;
                let segments = batch.prepared[current].targets_mm.len() as i64;
                p.segments_done = field("segment", 1, segments)? as usize;
            }
            Some("program") => p.program_started = true,
            Some("item_done") => {
                let next = p.items_done as i64 + 1;
                p.items_done = field("item", next, next)? as usize;
                p.sync_counter = None;
                p.segments_done = 0;
                p.program_started = false;
            }
            _ => {}
        }
    }
    Ok(p)
}
