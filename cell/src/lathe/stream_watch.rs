//! What `windcell lathe stream` checks before it sends and shows while it sends: every line of
//! the file checked first (an unknown word, a bad number, a line the controller cannot hold,
//! a real-time byte inside a line: `FILE:LINE:COL`, nothing sent), then progress (lines sent and
//! acknowledged, layer and circuit from the program's comments, elapsed and time left) as one
//! updating line on a terminal, a plain line every few seconds otherwise, or JSON events; a stop
//! names the line to restart from.

use std::time::{Duration, Instant};

use serde::Serialize;

/// GRBL's line buffer (`LINE_BUFFER_SIZE`, characters without spaces); Marlin holds 96 bytes
/// (`MAX_CMD_SIZE`) of which a framed line spends up to 16 on `N…` and `*…`: 80 for both.
pub const LINE_CHARS: usize = 80;

/// Word letters a lathe winder's program may use: codes, line number, feed, parameters and the
/// axes X Y Z A B C (and U V W).
pub const WORD_LETTERS: &str = "GMNFPSTLXYZABCUVWIJKR";

/// A line refused by the check: 1-based column and what is wrong.
#[derive(Debug, Clone, PartialEq)]
pub struct Refusal {
    /// 1-based column (characters).
    pub column: usize,
    /// What is wrong.
    pub message: String,
}

/// The code of a line without its comments (`( … )` and `;` to the end).
fn code_of(raw: &str) -> Vec<(usize, char)> {
    let mut code = Vec::with_capacity(raw.len());
    let mut depth = 0;
    for (i, ch) in raw.chars().enumerate() {
        match ch {
            '(' => depth += 1,
            ')' if depth > 0 => depth -= 1,
            ';' if depth == 0 => break,
            c if depth == 0 => code.push((i + 1, c)),
            _ => {}
        }
    }
    code
}

/// Checks one line of a program: words of a known letter and a finite number, no real-time
/// byte, at most [`LINE_CHARS`] characters of code without spaces.
pub fn check_line(raw: &str) -> Result<(), Refusal> {
    let code = code_of(raw);
    let mut i = 0;
    let mut chars = 0;
    while i < code.len() {
        let (col, c) = code[i];
        if c == ' ' || c == '\t' || c == '\r' || (c == '%' && code.len() == 1) {
            i += 1;
            continue;
        }
        if matches!(c, '?' | '!' | '~' | '\u{18}') {
            return Err(Refusal {
                column: col,
                message: format!(
                    "a real-time command character `{}` inside a line",
                    c.escape_default()
                ),
            });
        }
        let letter = c.to_ascii_uppercase();
        if !letter.is_ascii_alphabetic() {
            return Err(Refusal {
                column: col,
                message: format!("expected a word letter, found `{}`", c.escape_default()),
            });
        }
        if !WORD_LETTERS.contains(letter) {
            return Err(Refusal {
                column: col,
                message: format!(
                    "unknown word `{letter}` (a lathe winder's words: {WORD_LETTERS})"
                ),
            });
        }
        i += 1;
        chars += 1;
        let start = i;
        let mut number = String::new();
        while i < code.len() && matches!(code[i].1, '0'..='9' | '.' | '-' | '+') {
            number.push(code[i].1);
            i += 1;
        }
        chars += number.len();
        let ok = number.parse::<f64>().is_ok_and(f64::is_finite);
        if !ok {
            return Err(Refusal {
                column: code.get(start).map_or(col + 1, |p| p.0),
                message: format!("word {letter} has no number (`{number}`)"),
            });
        }
        if chars > LINE_CHARS {
            return Err(Refusal {
                column: col,
                message: format!(
                    "line longer than the controller's {LINE_CHARS}-character line buffer"
                ),
            });
        }
    }
    Ok(())
}

/// What the program's comments say, per line to send: the layers (windcell's `layer N KIND: C
/// circuits` and FiberPath's `Layer N of M`) and the circuits (FiberPath's `Circuit` comments),
/// and the file line of every line to send.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Outline {
    /// 1-based file line of each line to send.
    pub file_lines: Vec<usize>,
    /// Index (into the lines to send) where each layer starts, and its circuits if said.
    pub layers: Vec<(usize, Option<u64>)>,
    /// Index where each circuit starts (FiberPath's circuit comments), if any.
    pub circuits: Vec<usize>,
}

impl Outline {
    /// Reads a checked program's comments and numbers its lines; `Err((line, refusal))` at the
    /// first line the check refuses.
    pub fn of(text: &str) -> Result<Outline, (usize, Refusal)> {
        let mut o = Outline::default();
        for (n, raw) in text.lines().enumerate() {
            check_line(raw).map_err(|r| (n + 1, r))?;
            let code: String = code_of(raw).into_iter().map(|(_, c)| c).collect();
            let comment = raw
                .find(';')
                .map(|i| raw[i + 1..].trim())
                .or_else(|| {
                    raw.find('(')
                        .map(|i| raw[i + 1..].trim_end_matches(')').trim())
                })
                .unwrap_or("");
            let next = o.file_lines.len();
            let lower = comment.to_ascii_lowercase();
            if lower.starts_with("layer ") {
                let circuits = comment
                    .split_once(':')
                    .and_then(|(_, rest)| rest.split_whitespace().next())
                    .and_then(|c| c.parse().ok());
                o.layers.push((next, circuits));
            } else if lower.starts_with("circuit") {
                o.circuits.push(next);
            }
            let code = code.trim();
            if !code.is_empty() && code != "%" {
                o.file_lines.push(n + 1);
            }
        }
        Ok(o)
    }

    /// The layer (1-based, of how many) and its circuit count at line index `at`.
    pub fn layer_at(&self, at: usize) -> Option<(usize, usize, Option<u64>)> {
        let k = self.layers.iter().rposition(|&(s, _)| s <= at)?;
        Some((k + 1, self.layers.len(), self.layers[k].1))
    }

    /// The circuit (1-based, within its layer, of how many in the layer) at line index `at`,
    /// when the program marks circuits.
    pub fn circuit_at(&self, at: usize) -> Option<(usize, usize)> {
        let (layer, _, _) = self.layer_at(at)?;
        let start = self.layers[layer - 1].0;
        let end = self.layers.get(layer).map_or(usize::MAX, |l| l.0);
        let within: Vec<usize> = self
            .circuits
            .iter()
            .copied()
            .filter(|&c| c >= start && c < end)
            .collect();
        let k = within.iter().rposition(|&c| c <= at)?;
        Some((k + 1, within.len()))
    }
}

/// One progress report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Progress {
    /// Lines sent.
    pub sent: usize,
    /// Lines acknowledged.
    pub acknowledged: usize,
    /// Lines in the program.
    pub total: usize,
    /// Current layer (1-based) and layers, if the program marks layers.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub layer: Option<(usize, usize)>,
    /// Circuit within the layer and circuits in it, if the program marks them.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub circuit: Option<(usize, usize)>,
    /// Circuits of the current layer as its comment says, if it does.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub layer_circuits: Option<u64>,
    /// Seconds since the first line was sent.
    pub elapsed_s: f64,
    /// Seconds left at the rate so far, once there is a rate.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub left_s: Option<f64>,
}

impl Progress {
    /// The report at `acknowledged` of `total` lines after `elapsed`.
    pub fn at(outline: &Outline, sent: usize, acknowledged: usize, elapsed: Duration) -> Progress {
        let total = outline.file_lines.len();
        let at = acknowledged.min(total.saturating_sub(1));
        let layer = outline.layer_at(at);
        let elapsed_s = elapsed.as_secs_f64();
        let left_s = (acknowledged > 0 && elapsed_s > 0.0)
            .then(|| elapsed_s / acknowledged as f64 * (total - acknowledged) as f64);
        Progress {
            sent,
            acknowledged,
            total,
            layer: layer.map(|(l, n, _)| (l, n)),
            circuit: outline.circuit_at(at),
            layer_circuits: layer.and_then(|(_, _, c)| c),
            elapsed_s,
            left_s,
        }
    }

    /// One line of text (no newline).
    pub fn text(&self) -> String {
        let mut t = format!(
            "{}/{} lines sent, {} acknowledged ({:.0} %)",
            self.sent,
            self.total,
            self.acknowledged,
            100.0 * self.acknowledged as f64 / self.total.max(1) as f64
        );
        if let Some((l, n)) = self.layer {
            t += &format!(", layer {l}/{n}");
            if let Some((c, m)) = self.circuit {
                t += &format!(" circuit {c}/{m}");
            } else if let Some(c) = self.layer_circuits {
                t += &format!(" ({c} circuits)");
            }
        }
        t += &format!(", elapsed {}", clock(self.elapsed_s));
        if let Some(left) = self.left_s {
            t += &format!(", left {}", clock(left));
        }
        t
    }
}

/// Seconds as `h:mm:ss`.
pub fn clock(seconds: f64) -> String {
    let s = seconds.max(0.0).round() as u64;
    format!("{}:{:02}:{:02}", s / 3600, s / 60 % 60, s % 60)
}

/// Where to restart after a stop: the file line of the first line not acknowledged and the start
/// of its layer (restarting a layer from its start keeps the pattern whole).
pub fn restart_hint(outline: &Outline, file: &str, acknowledged: usize) -> String {
    let Some(&line) = outline.file_lines.get(acknowledged) else {
        return "every line was acknowledged".to_string();
    };
    let mut t = format!("restart from {file}:{line} (the first line not acknowledged)");
    if let Some((layer, _, _)) = outline.layer_at(acknowledged) {
        let start = outline.layers[layer - 1].0;
        if let Some(&l) = outline.file_lines.get(start) {
            t += &format!("; layer {layer} starts at {file}:{l}");
        }
    }
    t
}

/// How progress is shown.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Show {
    /// One line rewritten in place on a terminal, 5 times a second.
    Terminal,
    /// A plain line every so often.
    Plain(Duration),
    /// JSON events: a layer event at each layer, progress every second.
    Json,
}

/// What to print now.
#[derive(Debug, Clone, PartialEq)]
pub enum Shown {
    /// Rewrite the terminal line with this.
    Inline(String),
    /// A line of its own.
    Line(String),
    /// A JSON event.
    Event(serde_json::Value),
}

/// The progress display of one stream: cheap on every pass of the host loop (a time check and,
/// in JSON, a layer look-up), the report built only when it is shown.
#[derive(Debug)]
pub struct Watch<'a> {
    outline: &'a Outline,
    show: Show,
    started: Instant,
    last: Option<Instant>,
    layer: Option<usize>,
}

impl<'a> Watch<'a> {
    /// A display starting now.
    pub fn new(outline: &'a Outline, show: Show) -> Watch<'a> {
        let started = Instant::now();
        Watch {
            outline,
            show,
            started,
            // Plain lines begin one period in: a short stream (or one stopped at once) prints
            // only its outcome.
            last: matches!(show, Show::Plain(_)).then_some(started),
            layer: None,
        }
    }

    /// Time since the start.
    pub fn elapsed(&self) -> Duration {
        self.started.elapsed()
    }

    /// What to show after `acknowledged` of the lines are acknowledged and `sent` sent, if
    /// anything (`force`: show it whatever the time since the last).
    pub fn update(&mut self, sent: usize, acknowledged: usize, force: bool) -> Option<Shown> {
        let total = self.outline.file_lines.len();
        if self.show == Show::Json {
            let at = acknowledged.min(total.saturating_sub(1));
            let layer = self.outline.layer_at(at);
            if layer.map(|l| l.0) != self.layer {
                self.layer = layer.map(|l| l.0);
                if let Some((l, n, c)) = layer {
                    return Some(Shown::Event(
                        serde_json::json!({"event": "layer", "layer": l,
                        "layers": n, "circuits": c, "acknowledged": acknowledged}),
                    ));
                }
            }
        }
        let now = Instant::now();
        let period = match self.show {
            Show::Terminal => Duration::from_millis(200),
            Show::Plain(d) => d,
            Show::Json => Duration::from_secs(1),
        };
        if !force && self.last.is_some_and(|t| now - t < period) {
            return None;
        }
        self.last = Some(now);
        let p = Progress::at(self.outline, sent, acknowledged, now - self.started);
        Some(match self.show {
            Show::Terminal => Shown::Inline(p.text()),
            Show::Plain(_) => Shown::Line(p.text()),
            Show::Json => {
                let mut v = serde_json::to_value(&p).unwrap_or_default();
                v["event"] = "progress".into();
                Shown::Event(v)
            }
        })
    }

    /// Ends the terminal line before a message of its own.
    pub fn end_line(&self) {
        if self.show == Show::Terminal {
            eprintln!();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_lines_are_located() {
        assert!(check_line("G1 X10.5 A-3 F900 ; layer 1").is_ok());
        assert!(check_line("(comment only)").is_ok());
        assert!(check_line("%").is_ok());
        let r = check_line("G1 X10 E5").unwrap_err();
        assert_eq!(r.column, 8);
        assert!(r.message.contains("unknown word `E`"), "{}", r.message);
        let r = check_line("G1 X1.2.3").unwrap_err();
        assert_eq!(r.column, 5);
        assert!(r.message.contains("no number"), "{}", r.message);
        // Where the number should begin.
        let r = check_line("G1 X").unwrap_err();
        assert_eq!(r.column, 5);
        let r = check_line("G1 X1 ? A2").unwrap_err();
        assert_eq!(r.column, 7);
        let r = check_line("G1 X1 *12").unwrap_err();
        assert_eq!(r.column, 7);
        let long = format!("G1 X{}", "1".repeat(79));
        let r = check_line(&long).unwrap_err();
        assert!(r.message.contains("80-character"), "{}", r.message);
        // Exactly 80 characters without spaces is held.
        assert!(check_line(&format!("G1 X{}", "1".repeat(77))).is_ok());
    }

    #[test]
    fn layers_circuits_and_restart_lines_come_from_the_comments() {
        let text = "; title\nG21\n; layer 1 helical: 4 circuits, radius 50\nG1 X1\nG1 X2\n\
                    ; layer 2 hoop: 0 circuits\nG1 X3\n; Circuit 1\nG1 X4\n; Circuit 2\nG1 X5\n";
        let o = Outline::of(text).unwrap();
        assert_eq!(o.file_lines, [2, 4, 5, 7, 9, 11]);
        assert_eq!(o.layers, [(1, Some(4)), (3, Some(0))]);
        assert_eq!(o.layer_at(0), None);
        assert_eq!(o.layer_at(2), Some((1, 2, Some(4))));
        assert_eq!(o.circuit_at(5), Some((2, 2)));
        assert_eq!(
            restart_hint(&o, "p.gcode", 4),
            "restart from p.gcode:9 (the first line not acknowledged); layer 2 starts at p.gcode:7"
        );
        let p = Progress::at(&o, 5, 3, Duration::from_secs(30));
        assert_eq!(p.left_s, Some(30.0));
        assert_eq!(
            p.text(),
            "5/6 lines sent, 3 acknowledged (50 %), layer 2/2 (0 circuits), elapsed 0:00:30, left 0:00:30"
        );
        assert_eq!(Outline::of("G1 X1\nG1 Q2\n").unwrap_err().0, 2);
    }
}
