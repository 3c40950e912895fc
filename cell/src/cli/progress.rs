//! What `windcell run` shows while it winds: `--json` events, a progress bar on a terminal, or
//! plain lines. Every mode numbers a path's segments 1..N as the plan does (the approach to the
//! first point is a phase, not a segment); the phases that wind nothing (homing, the upload, each
//! approach) are named; the time left is the plan's (the mandrel's moves, which set the robot's
//! speed, seed 001 §5.6.2), and the upload's own from its rate so far.

use std::cell::Cell;

use cell::run::coordinator::{Batch, Event, Phase, ResumePoint, RunMode};
use serde_json::json;

/// Where the display stands (for the stop line, which names the segment as the events did).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Position {
    /// Batch item, from 1 (0 before the first).
    pub item: usize,
    /// The last segment reported wound in it (0 before the first).
    pub segment: usize,
}

/// The run's display.
pub struct Display {
    /// `--json`: one event per line.
    pub json: bool,
    bar: Option<indicatif::ProgressBar>,
    /// Items in the batch.
    items: usize,
    /// Plan segments of each item (its instructions less the approach).
    segments: Vec<usize>,
    /// The planned time of each item's instructions, s (`Batch::planned_times_s`).
    planned_s: Vec<Vec<f64>>,
    /// Cell time and exchanges done at the upload's first event.
    upload_from: Cell<Option<(f64, usize)>>,
    position: Cell<Position>,
    /// The last segment event's item, segment and cell time.
    last_segment: Cell<Option<(usize, usize, f64)>>,
    /// Cell time and planned time of the segments wound in this run, each timed from the one
    /// before it in the same path, s.
    pace: Cell<(f64, f64)>,
    /// Per item: cell time of its approach's start and of its winding's start, s.
    starts_s: std::cell::RefCell<Vec<(Option<f64>, Option<f64>)>>,
}

impl Display {
    /// The display of `batch`, resumed at `from`.
    pub fn new(json: bool, terminal: bool, batch: &Batch, from: &ResumePoint) -> Self {
        let segments: Vec<usize> = batch
            .items
            .iter()
            .map(|i| i.rob.instructions.len().saturating_sub(1))
            .collect();
        let planned_s = (0..batch.items.len())
            .map(|k| batch.planned_times_s(k))
            .collect();
        let done_in_item = if batch.mode == RunMode::Discrete {
            from.segments_done.saturating_sub(1)
        } else {
            0
        };
        let position = Position {
            item: from.items_done + 1,
            segment: done_in_item,
        };
        let bar = (terminal && !json).then(|| {
            let total: usize = segments.iter().sum();
            let done: usize = segments.iter().take(from.items_done).sum::<usize>() + done_in_item;
            let bar = indicatif::ProgressBar::with_draw_target(
                Some(total as u64),
                indicatif::ProgressDrawTarget::stdout(),
            );
            bar.set_style(
                indicatif::ProgressStyle::with_template(
                    "{prefix} [{bar:24}] {msg}  {elapsed} elapsed",
                )
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
                .progress_chars("=> "),
            );
            bar.set_position(done as u64);
            bar.set_message("connecting to the cell");
            bar
        });
        Display {
            json,
            bar,
            items: batch.items.len(),
            segments,
            planned_s,
            upload_from: Cell::new(None),
            position: Cell::new(position),
            last_segment: Cell::new(None),
            pace: Cell::new((0.0, 0.0)),
            starts_s: std::cell::RefCell::new(vec![(None, None); batch.items.len()]),
        }
    }

    /// Of item `item` (from 1) that took `path_s` from its approach's start to its end: the
    /// approach's time and the winding's (segments or program), s, when both phases were seen.
    pub fn split_s(&self, item: usize, path_s: f64) -> Option<(f64, f64)> {
        let starts = self.starts_s.borrow();
        match starts.get(item.wrapping_sub(1)) {
            Some(&(Some(approach), Some(winding))) => {
                let approach_s = (winding - approach).max(0.0);
                Some((approach_s, (path_s - approach_s).max(0.0)))
            }
            _ => None,
        }
    }

    /// Where the display stands.
    pub fn position(&self) -> Position {
        self.position.get()
    }

    /// Plan segments of item `item` (from 1).
    pub fn segments_of(&self, item: usize) -> usize {
        self.segments
            .get(item.wrapping_sub(1))
            .copied()
            .unwrap_or(0)
    }

    /// A line above the bar (or on its own).
    pub fn line(&self, text: &str) {
        match &self.bar {
            Some(bar) if !bar.is_finished() => bar.println(text),
            _ => {
                let _ = super::print(&format!("{text}\n"));
            }
        }
    }

    /// Ends the progress bar (before the summary).
    pub fn finish(&self) {
        if let Some(bar) = &self.bar {
            bar.finish_and_clear();
        }
    }

    /// The winding time the plan has left after segment `segment` of item `item` (both from
    /// 1), s.
    fn planned_left_s(&self, item: usize, segment: usize) -> f64 {
        let k = item.saturating_sub(1);
        let this: f64 = self
            .planned_s
            .get(k)
            .map_or(0.0, |t| t.iter().skip(segment + 1).sum());
        let later: f64 = self
            .planned_s
            .iter()
            .skip(k + 1)
            .map(|t| t.iter().sum::<f64>())
            .sum();
        this + later
    }

    /// The time left after segment `segment` of item `item`: the plan's, scaled by the pace of
    /// this run so far (cell time over planned time of the segments wound; 1 before any), s.
    /// The plan's mandrel times leave out what a segment costs beyond its moves (the discrete
    /// mode's exchanges, the robot's settling), which the pace measures.
    fn left_s(&self, item: usize, segment: usize) -> f64 {
        let (actual, planned) = self.pace.get();
        let pace = if planned > 0.0 && actual > 0.0 {
            actual / planned
        } else {
            1.0
        };
        self.planned_left_s(item, segment) * pace
    }

    /// Adds segment `segment` of item `item`, wound at `time_s`, to the pace.
    fn note_pace(&self, item: usize, segment: usize, time_s: f64) {
        if let Some((i, s, t)) = self.last_segment.get()
            && i == item
            && segment > s
        {
            let planned: f64 = self
                .planned_s
                .get(item.saturating_sub(1))
                .map_or(0.0, |p| p.iter().skip(s + 1).take(segment - s).sum());
            let (a, p) = self.pace.get();
            self.pace.set((a + (time_s - t).max(0.0), p + planned));
        }
        self.last_segment.set(Some((item, segment, time_s)));
    }

    fn bar_to(&self, item: usize, path: &str, segment: usize, what: String) {
        if let Some(bar) = &self.bar {
            let before: usize = self.segments.iter().take(item.saturating_sub(1)).sum();
            bar.set_prefix(format!("path {item}/{} {path}", self.items));
            bar.set_message(what);
            bar.set_position((before + segment) as u64);
        }
    }

    fn bar_message(&self, what: String) {
        if let Some(bar) = &self.bar {
            bar.set_message(what);
        }
    }

    /// Shows one event.
    pub fn event(&self, e: &Event) {
        match e {
            Event::Started { .. } | Event::Uploaded { .. } | Event::PathDone { .. } => {}
            Event::Phase { phase, time_s } => self.phase(*phase, *time_s),
            Event::Upload {
                done,
                total,
                time_s,
            } => self.upload(*done, *total, *time_s),
            Event::Segment {
                item,
                program,
                path,
                segment,
                segments,
                witness,
                time_s,
            } => {
                self.position.set(Position {
                    item: *item,
                    segment: *segment,
                });
                self.note_pace(*item, *segment, *time_s);
                let planned_left_s = self.planned_left_s(*item, *segment);
                let left_s = self.left_s(*item, *segment);
                if self.json {
                    self.line(
                        &json!({"event": "segment", "item": item, "program": program,
                            "path": path, "segment": segment, "segments": segments,
                            "witness": witness.keyword(), "time_s": time_s,
                            "planned_left_s": planned_left_s, "left_s": left_s})
                        .to_string(),
                    );
                } else if self.bar.is_some() {
                    self.bar_to(
                        *item,
                        path,
                        *segment,
                        format!(
                            "segment {segment}/{segments}, t = {time_s:.1} s, ≈ {} left",
                            duration(left_s)
                        ),
                    );
                } else if segment == segments || segment % 10 == 0 {
                    self.line(&format!(
                        "  path {item}/{} {path}: segment {segment}/{segments}, t = {time_s:.1} s, ≈ {} left",
                        self.items,
                        duration(left_s)
                    ));
                }
            }
            Event::Program {
                item,
                program,
                path,
                done,
                time_s,
            } => {
                if self.json {
                    self.line(
                        &json!({"event": "program", "item": item, "program": program,
                            "path": path, "done": done, "time_s": time_s})
                        .to_string(),
                    );
                } else {
                    let segment = if *done { self.segments_of(*item) } else { 0 };
                    self.bar_to(
                        *item,
                        path,
                        segment,
                        format!(
                            "program {program} {}, t = {time_s:.1} s, ≈ {} left",
                            if *done { "done" } else { "running" },
                            duration(self.left_s(*item, segment))
                        ),
                    );
                    self.line(&format!("  {e}"));
                }
            }
        }
    }

    fn phase(&self, phase: Phase, time_s: f64) {
        match phase {
            Phase::Upload => self.upload_from.set(None),
            Phase::Approach { item } => {
                if let Some(s) = self.starts_s.borrow_mut().get_mut(item.wrapping_sub(1)) {
                    *s = (Some(time_s), None);
                }
            }
            Phase::Winding { item } => {
                if let Some(s) = self.starts_s.borrow_mut().get_mut(item.wrapping_sub(1)) {
                    s.1 = Some(time_s);
                }
            }
            Phase::Homing => {}
        }
        if self.json {
            let mut event = json!({"event": "phase", "phase": phase.keyword(), "time_s": time_s});
            if let Phase::Approach { item } | Phase::Winding { item } = phase {
                event["item"] = json!(item);
            }
            self.line(&event.to_string());
            return;
        }
        let words = match phase {
            Phase::Homing => "homing the robot (home synchronisation)".to_string(),
            Phase::Upload => "uploading the programs to the robot computer".to_string(),
            Phase::Approach { item } => {
                self.position.set(Position { item, segment: 0 });
                format!(
                    "path {item}: to its start (mandrel to the start angle, arm to the first point)"
                )
            }
            Phase::Winding { item } => format!("path {item}: winding"),
        };
        if self.bar.is_some() {
            self.bar_message(words);
        } else if !matches!(phase, Phase::Approach { .. } | Phase::Winding { .. }) {
            self.line(&format!("  {words}"));
        }
    }

    fn upload(&self, done: usize, total: usize, time_s: f64) {
        let from = match self.upload_from.get() {
            Some(f) => f,
            None => {
                // The first event comes after its first exchange: the rate counts from there.
                let f = (time_s, done);
                self.upload_from.set(Some(f));
                f
            }
        };
        let left_s = (done > from.1 && done < total)
            .then(|| (time_s - from.0) / (done - from.1) as f64 * (total - done) as f64);
        if self.json {
            self.line(
                &json!({"event": "upload", "done": done, "total": total, "time_s": time_s,
                    "left_s": left_s})
                .to_string(),
            );
            return;
        }
        let left = left_s.map_or(String::new(), |s| format!(", {} left", duration(s)));
        let words = format!("upload: {done}/{total} exchanges{left}");
        if self.bar.is_some() {
            self.bar_message(words);
        } else if done == total || (done * 4 / total) != ((done - 1) * 4 / total) {
            self.line(&format!("  {words}"));
        }
    }
}

/// A time as the operator reads it: `42 s`, `3 min 05 s`, `1 h 02 min`.
pub fn duration(seconds: f64) -> String {
    let s = seconds.max(0.0).round() as u64;
    if s < 60 {
        format!("{s} s")
    } else if s < 3600 {
        format!("{} min {:02} s", s / 60, s % 60)
    } else {
        format!("{} h {:02} min", s / 3600, (s % 3600) / 60)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn durations_read_as_an_operator_reads_them() {
        assert_eq!(duration(0.4), "0 s");
        assert_eq!(duration(42.0), "42 s");
        assert_eq!(duration(185.0), "3 min 05 s");
        assert_eq!(duration(3720.0), "1 h 02 min");
        assert_eq!(duration(-3.0), "0 s");
    }
}
