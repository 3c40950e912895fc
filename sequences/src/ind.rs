//! The mandrel control file `NAME_<prog>.IND` (seed 001 §5.6.2): initialise the indexer, one move
//! for the whole path, reset. Needed in program mode.
//!
//! ```text
//! ind 1
//! init
//! move accel_rps2=1 start_rps=0.05 max_rps=0.1 steps=-1846
//! reset
//! ```

use crate::Error;
use crate::syntax::{Places, Token, number, records};

/// The format version written on the first line.
pub const VERSION: i64 = 1;

/// A mandrel instruction (seed 001 §5.3.2): angular acceleration, start/stop velocity, maximum
/// velocity and the angle in motor steps. Speeds are at the mandrel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MandrelMove {
    /// Angular acceleration (and deceleration), mandrel rev/s².
    pub accel_rps2: f64,
    /// Start/stop velocity: the speed the stepper jumps to from rest, mandrel rev/s.
    pub start_stop_rps: f64,
    /// Maximum velocity, mandrel rev/s.
    pub max_rps: f64,
    /// Signed motor steps.
    pub steps: i64,
}

impl MandrelMove {
    /// The `key=value` fields as written in .ROB and .IND files.
    pub fn fields(&self) -> String {
        format!(
            "accel_rps2={} start_rps={} max_rps={} steps={}",
            number(self.accel_rps2),
            number(self.start_stop_rps),
            number(self.max_rps),
            self.steps
        )
    }

    pub(crate) fn from_tokens(
        accel: Token<'_>,
        start: Token<'_>,
        max: Token<'_>,
        steps: Token<'_>,
    ) -> Result<Self, Error> {
        let accel_rps2 = accel.f64()?;
        if accel_rps2 <= 0.0 {
            return Err(accel.error("accel_rps2 must be > 0"));
        }
        let start_stop_rps = start.f64()?;
        if start_stop_rps < 0.0 {
            return Err(start.error("start_rps must be ≥ 0"));
        }
        let max_rps = max.f64()?;
        if max_rps <= 0.0 {
            return Err(max.error("max_rps must be > 0"));
        }
        if start_stop_rps > max_rps {
            return Err(start.error("start_rps exceeds max_rps"));
        }
        Ok(MandrelMove {
            accel_rps2,
            start_stop_rps,
            max_rps,
            steps: steps.i64()?,
        })
    }
}

/// A whole mandrel control file: init, one move, reset.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MandrelFile {
    /// The move for the whole path.
    pub path_move: MandrelMove,
}

impl MandrelFile {
    /// Parses the text of a .IND file.
    pub fn parse(text: &str) -> Result<Self, Error> {
        Self::parse_placed(text).map(|(file, _)| file)
    }

    /// [`MandrelFile::parse`], keeping where the move's values were read (`accel_rps2`,
    /// `start_rps`, `max_rps`, `steps`, as file-level fields).
    pub fn parse_placed(text: &str) -> Result<(Self, Places), Error> {
        let recs = records(text);
        let expected = ["ind", "init", "move", "reset"];
        for (i, keyword) in expected.iter().enumerate() {
            let Some(rec) = recs.get(i) else {
                let (line, column) = recs.last().map_or((1, 1), |r| {
                    let t = r.tokens[r.tokens.len() - 1];
                    (r.line, t.column + t.text.chars().count())
                });
                return Err(Error::at(line, column, format!("missing `{keyword}` line")));
            };
            if rec.head().text != *keyword {
                return Err(rec
                    .head()
                    .error(format!("expected `{keyword}`, found `{}`", rec.head().text)));
            }
        }
        if let Some(extra) = recs.get(4) {
            return Err(extra.head().error("text after `reset`"));
        }
        recs[0].expect_len(2, "format version")?;
        let version = recs[0].tokens[1].i64()?;
        if version != VERSION {
            return Err(recs[0].tokens[1].error(format!("unsupported .IND version {version}")));
        }
        recs[1].expect_len(1, "")?;
        recs[3].expect_len(1, "")?;
        let names = ["accel_rps2", "start_rps", "max_rps", "steps"];
        let tokens = recs[2].fields(0, names)?;
        let mut places = Places::default();
        for (name, token) in names.into_iter().zip(&tokens) {
            places.add_field(name, token);
        }
        let [accel, start, max, steps] = tokens;
        let file = MandrelFile {
            path_move: MandrelMove::from_tokens(accel, start, max, steps)?,
        };
        Ok((file, places))
    }

    /// Writes the canonical text. Refuses ([`Error::Unwritable`]) a move that
    /// [`MandrelFile::parse`] would refuse: acceleration or maximum velocity not above 0, a
    /// negative start/stop velocity or one above the maximum, a non-finite number.
    pub fn write(&self) -> Result<String, Error> {
        crate::error::written(
            "mandrel control file",
            self,
            self.text(),
            MandrelFile::parse,
        )
    }

    fn text(&self) -> String {
        format!(
            "# windcell mandrel control file (seed 001 §5.6.2)\nind {VERSION}\ninit\nmove {}\nreset\n",
            self.path_move.fields()
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> MandrelFile {
        MandrelFile {
            path_move: MandrelMove {
                accel_rps2: 1.5,
                start_stop_rps: 0.05,
                max_rps: 0.1,
                steps: -1846,
            },
        }
    }

    #[test]
    fn round_trips_exactly() {
        let text = sample().write().unwrap();
        let parsed = MandrelFile::parse(&text).unwrap();
        assert_eq!(parsed, sample());
        assert_eq!(parsed.write().unwrap(), text);
    }

    #[test]
    fn errors_name_line_and_column() {
        let text = sample().write().unwrap();
        let cases = [
            (text.replace("reset\n", ""), "missing `reset`"),
            (text.replace("init", "start"), "3:1: expected `init`"),
            (
                text.replace("max_rps=0.1", "max_rps=0.01"),
                "start_rps exceeds max_rps",
            ),
            (text.replace("accel_rps2=1.5", "accel_rps2=-1"), "4:17:"),
            (format!("{text}move\n"), "6:1: text after"),
        ];
        for (bad, expected) in cases {
            let err = MandrelFile::parse(&bad).unwrap_err().to_string();
            assert!(err.contains(expected), "{err} should contain {expected}");
        }
    }

    /// The move's values at their own columns, counted by hand ("move accel_rps2=" is 16
    /// characters).
    #[test]
    fn parse_placed_keeps_the_moves_places() {
        let text = "ind 1\ninit\nmove accel_rps2=1 start_rps=0.05 max_rps=0.1 steps=-74\nreset\n";
        let (file, places) = MandrelFile::parse_placed(text).unwrap();
        assert_eq!(file, MandrelFile::parse(text).unwrap());
        assert_eq!(places.field("accel_rps2"), Some((3, 17)));
        assert_eq!(places.field("start_rps"), Some((3, 29)));
        assert_eq!(places.field("max_rps"), Some((3, 42)));
        assert_eq!(places.field("steps"), Some((3, 52)));
        assert_eq!(places.field("program"), None);
    }
}
