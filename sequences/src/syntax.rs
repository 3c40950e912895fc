//! The line syntax shared by the text control files (.ROB, .IND, sequence, run): one record per
//! line, `#` starts a comment, blank lines are ignored, fields are separated by spaces, a field is
//! a bare word or `key=value`. Every token remembers its line and column for errors.

use crate::Error;

/// A token of a record.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Token<'a> {
    /// The text.
    pub text: &'a str,
    /// 1-based line.
    pub line: usize,
    /// 1-based character column.
    pub column: usize,
}

impl<'a> Token<'a> {
    /// An error pointing at this token.
    pub fn error(&self, message: impl Into<String>) -> Error {
        Error::at(self.line, self.column, message)
    }

    /// Splits `key=value`; the value keeps its own column.
    pub fn key_value(&self) -> Result<(&'a str, Token<'a>), Error> {
        let (key, value) = self
            .text
            .split_once('=')
            .ok_or_else(|| self.error(format!("expected key=value, found `{}`", self.text)))?;
        let column = self.column + key.chars().count() + 1;
        Ok((
            key,
            Token {
                text: value,
                line: self.line,
                column,
            },
        ))
    }

    /// The token as a finite number.
    pub fn f64(&self) -> Result<f64, Error> {
        match self.text.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            _ => Err(self.error(format!("expected a number, found `{}`", self.text))),
        }
    }

    /// The token as an integer.
    pub fn i64(&self) -> Result<i64, Error> {
        self.text
            .parse::<i64>()
            .map_err(|_| self.error(format!("expected an integer, found `{}`", self.text)))
    }

    /// The token as an integer in `range`.
    pub fn int_in(&self, range: std::ops::RangeInclusive<i64>) -> Result<i64, Error> {
        let v = self.i64()?;
        if range.contains(&v) {
            Ok(v)
        } else {
            Err(self.error(format!(
                "{v} is out of range {}..={}",
                range.start(),
                range.end()
            )))
        }
    }

    /// Comma-separated numbers, exactly `N` of them.
    pub fn f64s<const N: usize>(&self) -> Result<[f64; N], Error> {
        let mut out = [0.0; N];
        let mut count = 0;
        let mut column = self.column;
        for part in self.text.split(',') {
            if count == N {
                return Err(self.error(format!("expected {N} comma-separated numbers")));
            }
            let token = Token {
                text: part,
                line: self.line,
                column,
            };
            out[count] = token.f64()?;
            count += 1;
            column += part.chars().count() + 1;
        }
        if count != N {
            return Err(self.error(format!("expected {N} comma-separated numbers")));
        }
        Ok(out)
    }
}

/// One non-blank line's tokens (comments removed).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Record<'a> {
    /// 1-based line number.
    pub line: usize,
    /// The tokens, at least one.
    pub tokens: Vec<Token<'a>>,
}

impl<'a> Record<'a> {
    /// The first token (the record's keyword).
    pub fn head(&self) -> Token<'a> {
        self.tokens[0]
    }

    /// An error at the end of the line (something is missing).
    pub fn missing(&self, what: &str) -> Error {
        let last = self.tokens[self.tokens.len() - 1];
        Error::at(
            self.line,
            last.column + last.text.chars().count(),
            format!("missing {what}"),
        )
    }

    /// Exactly `n` tokens, or an error naming the extra or missing one.
    pub fn expect_len(&self, n: usize, what: &str) -> Result<(), Error> {
        match self.tokens.len().cmp(&n) {
            std::cmp::Ordering::Equal => Ok(()),
            std::cmp::Ordering::Less => Err(self.missing(what)),
            std::cmp::Ordering::Greater => {
                Err(self.tokens[n].error(format!("unexpected `{}`", self.tokens[n].text)))
            }
        }
    }

    /// The `key=value` fields after the keyword and `skip` positional tokens, looked up by key:
    /// each key in `keys` must appear exactly once, and no other key may.
    pub fn fields<const N: usize>(
        &self,
        skip: usize,
        keys: [&str; N],
    ) -> Result<[Token<'a>; N], Error> {
        let mut found: [Option<Token<'a>>; N] = [None; N];
        for token in &self.tokens[1 + skip..] {
            let (key, value) = token.key_value()?;
            let Some(index) = keys.iter().position(|k| *k == key) else {
                return Err(token.error(format!("unknown field `{key}`")));
            };
            if found[index].replace(value).is_some() {
                return Err(token.error(format!("field `{key}` given twice")));
            }
        }
        let mut out = [self.tokens[0]; N];
        for (i, slot) in found.into_iter().enumerate() {
            out[i] = slot.ok_or_else(|| self.missing(&format!("field `{}=`", keys[i])))?;
        }
        Ok(out)
    }
}

/// Splits `text` into records.
pub fn records(text: &str) -> Vec<Record<'_>> {
    text.lines()
        .enumerate()
        .filter_map(|(i, raw)| {
            let content = raw.split('#').next().unwrap_or("");
            let mut tokens = Vec::new();
            let mut chars = content.char_indices().peekable();
            let mut column = 1;
            while let Some(&(start, c)) = chars.peek() {
                if c.is_whitespace() {
                    chars.next();
                    column += 1;
                    continue;
                }
                let token_column = column;
                let mut end = start;
                while let Some(&(j, c)) = chars.peek() {
                    if c.is_whitespace() {
                        break;
                    }
                    end = j + c.len_utf8();
                    chars.next();
                    column += 1;
                }
                tokens.push(Token {
                    text: &content[start..end],
                    line: i + 1,
                    column: token_column,
                });
            }
            (!tokens.is_empty()).then_some(Record {
                line: i + 1,
                tokens,
            })
        })
        .collect()
}

/// Formats a number so that parsing gives back the same `f64`.
pub fn number(v: f64) -> String {
    format!("{v}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tokens_know_their_columns() {
        let recs = records("# comment\n\n  move a=1  b=2,3 # tail\n");
        assert_eq!(recs.len(), 1);
        let r = &recs[0];
        assert_eq!(r.line, 3);
        assert_eq!(
            r.tokens.iter().map(|t| t.column).collect::<Vec<_>>(),
            vec![3, 8, 13]
        );
        let (key, value) = r.tokens[2].key_value().unwrap();
        assert_eq!((key, value.text, value.column), ("b", "2,3", 15));
        let err = value.f64s::<3>().unwrap_err();
        assert!(err.to_string().starts_with("3:15:"), "{err}");
    }

    #[test]
    fn fields_must_be_complete_and_unique() {
        let recs = records("x a=1 b=2\ny a=1 a=2 b=3\nz a=1\nw a=1 b=2 c=3\n");
        assert!(recs[0].fields(0, ["a", "b"]).is_ok());
        assert!(
            recs[1]
                .fields(0, ["a", "b"])
                .unwrap_err()
                .to_string()
                .contains("twice")
        );
        assert!(
            recs[2]
                .fields(0, ["a", "b"])
                .unwrap_err()
                .to_string()
                .contains("missing field `b=`")
        );
        assert!(
            recs[3]
                .fields(0, ["a", "b"])
                .unwrap_err()
                .to_string()
                .contains("unknown field `c`")
        );
    }

    #[test]
    fn numbers_round_trip() {
        for v in [0.1, -31.75, 1e-7, 123456.789, 0.0] {
            assert_eq!(number(v).parse::<f64>().unwrap(), v);
        }
    }
}

/// A 1-based line and character column in a file's text.
pub type Place = (usize, usize);

/// Where a control file's values were read ([`crate::RobotFile::parse_placed`],
/// [`crate::MandrelFile::parse_placed`]): the place of each value's own token, so that a value the
/// devices refuse after reading (out of the telegram's range, beyond the indexer's) is reported
/// at its line and column. File-level values (a `.ROB` header's, a `.IND` move's) by field name,
/// and each instruction's by its number and field name; a list value (`pos_mm=x,y,z`) keeps the
/// place of each of its parts.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Places {
    fields: Vec<Value>,
    instructions: Vec<Vec<Value>>,
}

/// One value's name, its place, and the column of each comma-separated part after the first.
#[derive(Debug, Clone, PartialEq, Eq)]
struct Value {
    name: &'static str,
    place: Place,
    part_columns: Vec<usize>,
}

impl Value {
    fn of(name: &'static str, token: &Token<'_>) -> Value {
        let mut part_columns = Vec::new();
        let mut column = token.column;
        for c in token.text.chars() {
            column += 1;
            if c == ',' {
                part_columns.push(column);
            }
        }
        Value {
            name,
            place: (token.line, token.column),
            part_columns,
        }
    }

    /// The place of part `part` (0 = the value's start).
    fn part(&self, part: usize) -> Option<Place> {
        match part {
            0 => Some(self.place),
            k => self
                .part_columns
                .get(k - 1)
                .map(|&column| (self.place.0, column)),
        }
    }
}

impl Places {
    /// The place of the file-level value `field` (`base_speed_mm_s`, `steps`, …).
    pub fn field(&self, field: &str) -> Option<Place> {
        self.fields
            .iter()
            .find(|v| v.name == field)
            .map(|v| v.place)
    }

    /// The place of `field` (`speed_pct`, `pos_mm`, `accel_rps2`, …) of instruction `number`
    /// (1-based); of its part `part` (0-based, comma-separated) for a list value.
    pub fn instruction(&self, number: u16, field: &str, part: usize) -> Option<Place> {
        let index = usize::from(number).checked_sub(1)?;
        self.instructions
            .get(index)?
            .iter()
            .find(|v| v.name == field)?
            .part(part)
    }

    pub(crate) fn add_field(&mut self, name: &'static str, token: &Token<'_>) {
        self.fields.push(Value::of(name, token));
    }

    pub(crate) fn add_instruction(&mut self, names: &[&'static str], tokens: &[Token<'_>]) {
        self.instructions.push(
            names
                .iter()
                .zip(tokens)
                .map(|(&name, t)| Value::of(name, t))
                .collect(),
        );
    }
}
