//! The one error type of the `sequences` crate.

use std::path::PathBuf;

use thiserror::Error;

/// A file that could not be read, parsed or written.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum Error {
    /// The text is malformed or a value is out of range. `file` is set once the text came from a
    /// file (see [`Error::in_file`]); `line` and `column` are 1-based, the column counted in
    /// characters.
    #[error("{}{line}:{column}: {message}", file.as_ref().map(|f| format!("{}:", f.display())).unwrap_or_default())]
    Parse {
        /// The file, when known.
        file: Option<PathBuf>,
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// What is wrong, in lower case.
        message: String,
    },
    /// The file parsed but does not hold what is asked of it (a DXF drawing without a path, a
    /// drawing that cannot be written). `file` is set as for [`Error::Parse`].
    #[error("{}{message}", file.as_ref().map(|f| format!("{}: ", f.display())).unwrap_or_default())]
    Content {
        /// The file, when known.
        file: Option<PathBuf>,
        /// What is wrong, in lower case.
        message: String,
    },
    /// A value the writer refuses because its reader would refuse the text written, or read it
    /// back as a different value (an empty sequence, program 0, a speed above the maximum, a
    /// non-finite number). `line` and `column` are where the written text would be refused.
    #[error("cannot write the {format}: line {line}, column {column} of its text: {message}")]
    Unwritable {
        /// Which file format (`robot control file`, `run file`, …).
        format: &'static str,
        /// 1-based line of the written text.
        line: usize,
        /// 1-based column of the written text.
        column: usize,
        /// What the reader says, in lower case.
        message: String,
    },
    /// A file to read is a device, FIFO, socket or folder (refused without reading it).
    #[error("{}: is {kind}, not a regular file", file.display())]
    NotRegularFile {
        /// The path.
        file: PathBuf,
        /// What it is (`a character device`, `a folder`).
        kind: &'static str,
    },
    /// A file to read is larger than the limit for its kind (docs/ARCHITECTURE.md, "Limits").
    #[error("{}: {bytes} bytes, more than the limit of {limit_bytes} bytes", file.display())]
    FileTooLarge {
        /// The file.
        file: PathBuf,
        /// Its size (or what was read of it before reading stopped).
        bytes: u64,
        /// The limit.
        limit_bytes: u64,
    },
    /// Reading or writing a file failed.
    #[error("{}: {source}", file.display())]
    Io {
        /// The file.
        file: PathBuf,
        /// The system's error.
        source: std::io::Error,
    },
}

impl Error {
    /// A parse error at a 1-based line and column.
    pub fn at(line: usize, column: usize, message: impl Into<String>) -> Self {
        Error::Parse {
            file: None,
            line,
            column,
            message: message.into(),
        }
    }

    /// A parse error at byte offset `offset` of `text`.
    pub fn at_offset(text: &str, offset: usize, message: impl Into<String>) -> Self {
        let (line, column) = line_column(text, offset);
        Error::at(line, column, message)
    }

    /// A content error (see [`Error::Content`]).
    pub fn content(message: impl Into<String>) -> Self {
        Error::Content {
            file: None,
            message: message.into(),
        }
    }

    /// The same error, naming the file it came from.
    pub fn in_file(self, path: impl Into<PathBuf>) -> Self {
        match self {
            Error::Parse {
                line,
                column,
                message,
                ..
            } => Error::Parse {
                file: Some(path.into()),
                line,
                column,
                message,
            },
            Error::Content { message, .. } => Error::Content {
                file: Some(path.into()),
                message,
            },
            other => other,
        }
    }
}

/// `text`, the written form of `value`, if `parse` reads it back as `value`; otherwise the
/// reader's complaint as [`Error::Unwritable`]. Every writer goes through this, so a file
/// windcell writes is always one it reads.
pub(crate) fn written<T: PartialEq>(
    format: &'static str,
    value: &T,
    text: String,
    parse: impl FnOnce(&str) -> Result<T, Error>,
) -> Result<String, Error> {
    match parse(&text) {
        Ok(back) if back == *value => Ok(text),
        Ok(_) => Err(Error::Unwritable {
            format,
            line: 1,
            column: 1,
            message: "the text reads back as a different value".into(),
        }),
        Err(Error::Parse {
            line,
            column,
            message,
            ..
        }) => Err(Error::Unwritable {
            format,
            line,
            column,
            message,
        }),
        Err(other) => Err(other),
    }
}

/// How a number reads in a message: plain between 1e-4 and 1e9, with at most 9 significant digits
/// and 6 decimals (trailing zeros dropped), else in exponent form with 6 significant digits (no
/// 300-digit numbers). The same rule as `paths::limits::shown`.
pub fn shown(value: f64) -> String {
    if !value.is_finite() || value == 0.0 {
        return format!("{value}");
    }
    let trim = |t: String| -> String {
        if t.contains('.') {
            t.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            t
        }
    };
    if (1e-4..1e9).contains(&value.abs()) {
        let decimals = (8 - value.abs().log10().floor() as i32).clamp(0, 6) as usize;
        trim(format!("{value:.decimals$}"))
    } else {
        let e = format!("{value:.5e}");
        let (mantissa, exponent) = e.split_once('e').unwrap_or((&e, "0"));
        format!("{}e{exponent}", trim(mantissa.to_string()))
    }
}

/// Where a TOML reader's refusal points (byte offset, the start of the file when it names no
/// place) and its message, trimmed, with long quoted numbers shortened ([`short_numbers`]): the
/// one reading of a TOML error for every file windcell parses as TOML.
pub fn toml_refusal(e: &toml::de::Error) -> (usize, String) {
    (
        e.span().map_or(0, |s| s.start),
        short_numbers(e.message().trim()),
    )
}

/// A parser's message with every back-quoted number longer than 20 characters written as
/// [`shown`] writes it: the TOML reader quotes a value it refuses in full
/// (`` invalid type: floating point `1000…000` ``, 309 digits for 1e308).
pub fn short_numbers(message: &str) -> String {
    let mut out = String::with_capacity(message.len());
    let mut parts = message.split('`');
    if let Some(first) = parts.next() {
        out.push_str(first);
    }
    for (k, part) in parts.enumerate() {
        out.push('`');
        // Odd pieces (k even here) lie between a pair of back quotes.
        match part.parse::<f64>() {
            Ok(v) if k % 2 == 0 && part.len() > 20 => out.push_str(&shown(v)),
            _ => out.push_str(part),
        }
    }
    out
}

/// 1-based line and character column of byte `offset` in `text`.
pub fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let mut offset = offset.min(text.len());
    while !text.is_char_boundary(offset) {
        offset -= 1;
    }
    let before = &text[..offset];
    let line = before.matches('\n').count() + 1;
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    (line, before[line_start..].chars().count() + 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Long quoted numbers are shortened; short ones, words and text outside the quotes are
    /// kept as they are.
    #[test]
    fn long_quoted_numbers_are_shortened() {
        let big = format!("1{}", "0".repeat(308));
        let m = format!("invalid type: floating point `{big}`, expected u32");
        assert_eq!(
            short_numbers(&m),
            "invalid type: floating point `1e308`, expected u32"
        );
        let tiny = format!("0.{}1", "0".repeat(299));
        assert_eq!(short_numbers(&format!("`{tiny}`")), "`1e-300`");
        let kept = "unknown field `drive`, expected `12345678901234567890` or `1.5`";
        assert_eq!(short_numbers(kept), kept);
        // Digits outside a pair of quotes are not touched.
        let outside = format!("{big} `x` {big}");
        assert_eq!(short_numbers(&outside), outside);
        // Nor those between two quoted words: only every other piece lies inside a pair.
        let between = format!("`x`{big}`y`");
        assert_eq!(short_numbers(&between), between);
    }

    #[test]
    fn offsets_map_to_lines_and_columns() {
        let text = "a = 1\nbé = 2\n";
        assert_eq!(line_column(text, 0), (1, 1));
        assert_eq!(line_column(text, 6), (2, 1));
        assert_eq!(line_column(text, 9), (2, 3));
        assert_eq!(line_column(text, 1000), (3, 1));
    }

    #[test]
    fn numbers_read_short() {
        assert_eq!(shown(1e308), "1e308");
        assert_eq!(shown(-2.5e-7), "-2.5e-7");
        assert_eq!(shown(2000.0), "2000");
        assert_eq!(shown(63.5), "63.5");
        assert_eq!(shown(101_986_487.528_729), "101986488");
        assert_eq!(shown(f64::NAN), "NaN");
    }

    #[test]
    fn display_names_file_line_and_column() {
        let e = Error::at(3, 7, "bad value").in_file("jobs/cyl.toml");
        assert_eq!(e.to_string(), "jobs/cyl.toml:3:7: bad value");
        assert_eq!(Error::at(1, 2, "x").to_string(), "1:2: x");
    }
}
