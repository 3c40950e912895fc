//! The run file (seed 001 §5.6.3): program numbers, one per line, in the order program mode runs
//! them (`1`, `2`, `3`, `2`).

use crate::Error;
use crate::syntax::records;

/// Program numbers in run order.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct RunFile {
    /// Program numbers 1–255.
    pub programs: Vec<u8>,
}

impl RunFile {
    /// Parses the text of a run file.
    pub fn parse(text: &str) -> Result<Self, Error> {
        let mut programs = Vec::new();
        for rec in records(text) {
            rec.expect_len(1, "")?;
            if programs.len() == crate::sequence::MAX_ITEMS {
                return Err(rec.head().error(format!(
                    "more than {} programs in one batch (docs/ARCHITECTURE.md, \"Limits\")",
                    crate::sequence::MAX_ITEMS
                )));
            }
            programs.push(rec.head().int_in(1..=255)? as u8);
        }
        if programs.is_empty() {
            return Err(Error::at(1, 1, "the run file names no program"));
        }
        Ok(RunFile { programs })
    }

    /// Writes one number per line. Refuses ([`Error::Unwritable`]) an empty run and program 0.
    pub fn write(&self) -> Result<String, Error> {
        let text = self.programs.iter().map(|p| format!("{p}\n")).collect();
        crate::error::written("run file", self, text, RunFile::parse)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thesis_example_round_trips() {
        let run = RunFile::parse("1\n2\n3\n2\n").unwrap();
        assert_eq!(run.programs, vec![1, 2, 3, 2]);
        assert_eq!(RunFile::parse(&run.write().unwrap()).unwrap(), run);
    }

    #[test]
    fn bad_numbers_are_located() {
        assert!(
            RunFile::parse("1\n256\n")
                .unwrap_err()
                .to_string()
                .starts_with("2:1:")
        );
        assert!(
            RunFile::parse("1\n  x\n")
                .unwrap_err()
                .to_string()
                .starts_with("2:3:")
        );
        assert!(RunFile::parse("").is_err());
    }
}
