//! The sequence file (seed 001 §5.6.3): control-file names without extension, one per line, in
//! winding order; repeats allowed (`SBEND_1`, `SBEND_2`, `SBEND_3`, `SBEND_2`). Discrete mode winds
//! them in order; program mode loads each named robot control file once.

use crate::Error;
use crate::syntax::records;

/// The names in winding order.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct SequenceFile {
    /// Control-file names without extension.
    pub names: Vec<String>,
}

/// The most paths a sequence or run file may list: each is checked before a batch starts (about
/// a millisecond a path), and seed 001's batches have a handful.
pub const MAX_ITEMS: usize = 1000;

/// True for a name of letters, digits, `_` and `-` (a portable file-name stem).
pub fn is_valid_name(name: &str) -> bool {
    !name.is_empty()
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
}

impl SequenceFile {
    /// Parses the text of a sequence file.
    pub fn parse(text: &str) -> Result<Self, Error> {
        let mut names = Vec::new();
        for rec in records(text) {
            rec.expect_len(1, "")?;
            let name = rec.head();
            if !is_valid_name(name.text) || name.text.chars().count() > crate::job::MAX_NAME_CHARS {
                let shown: String = name.text.chars().take(crate::job::MAX_NAME_CHARS).collect();
                let more = if shown.len() < name.text.len() {
                    "…"
                } else {
                    ""
                };
                return Err(name.error(format!(
                    "`{shown}{more}` is not a control-file name (letters, digits, `_`, `-`, at \
                     most {} characters)",
                    crate::job::MAX_NAME_CHARS
                )));
            }
            if names.len() == MAX_ITEMS {
                return Err(name.error(format!(
                    "more than {MAX_ITEMS} paths in one batch (docs/ARCHITECTURE.md, \"Limits\")"
                )));
            }
            names.push(name.text.to_string());
        }
        if names.is_empty() {
            return Err(Error::at(1, 1, "the sequence file names no control file"));
        }
        Ok(SequenceFile { names })
    }

    /// Writes one name per line. Refuses ([`Error::Unwritable`]) an empty sequence and a name
    /// that is not letters, digits, `_` and `-`.
    pub fn write(&self) -> Result<String, Error> {
        let text = self.names.iter().map(|n| format!("{n}\n")).collect();
        crate::error::written("sequence file", self, text, SequenceFile::parse)
    }

    /// Each distinct name once, in order of first appearance.
    pub fn distinct(&self) -> Vec<&str> {
        let mut seen = Vec::new();
        for n in &self.names {
            if !seen.contains(&n.as_str()) {
                seen.push(n.as_str());
            }
        }
        seen
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thesis_example_round_trips() {
        let text = "SBEND_1\nSBEND_2\nSBEND_3\nSBEND_2\n";
        let seq = SequenceFile::parse(text).unwrap();
        assert_eq!(seq.names.len(), 4);
        assert_eq!(seq.distinct(), vec!["SBEND_1", "SBEND_2", "SBEND_3"]);
        assert_eq!(seq.write().unwrap(), text);
        assert_eq!(SequenceFile::parse(&seq.write().unwrap()).unwrap(), seq);
    }

    #[test]
    fn comments_and_blank_lines_are_allowed_bad_names_are_not() {
        assert_eq!(
            SequenceFile::parse("# x\n\nA_1  # first\n").unwrap().names,
            vec!["A_1"]
        );
        let err = SequenceFile::parse("A_1\nB/2\n").unwrap_err().to_string();
        assert!(err.starts_with("2:1:"), "{err}");
        let err = SequenceFile::parse("A_1 B_2\n").unwrap_err().to_string();
        assert!(err.starts_with("1:5:"), "{err}");
        assert!(SequenceFile::parse("# nothing\n").is_err());
    }
}
