//! The run journal: one JSON object per line, each synced to disk before the run goes on, so that
//! a stop, a device fault or `kill -9` leaves a record of everything confirmed
//! (docs/file-formats.md, "Run journal").
//!
//! Every line carries `chain`, a 64-bit FNV-1a hash of the previous line's chain and this line's
//! other fields: a journal edited by hand, truncated in the middle or belonging to another job is
//! refused on `--resume` (bad input).

use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};

use serde_json::{Map, Value};

/// FNV-1a, 64 bits.
pub fn fnv1a(seed: u64, bytes: &[u8]) -> u64 {
    let mut h = seed;
    for &b in bytes {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

/// FNV-1a's offset basis.
pub const FNV_BASIS: u64 = 0xcbf2_9ce4_8422_2325;

/// A journal problem.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum JournalError {
    /// The journal could not be written or read.
    #[error("{}: {source}", path.display())]
    Io {
        /// The journal file.
        path: PathBuf,
        /// The system's error.
        source: std::io::Error,
    },
    /// The journal is not a regular file, is larger than the limit, or is not UTF-8.
    #[error(transparent)]
    Unreadable(#[from] sequences::Error),
    /// A line is not a journal record, or its chain does not match (edited by hand).
    #[error("{}:{line}:1: {message}", path.display())]
    Corrupt {
        /// The journal file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// What is wrong.
        message: String,
    },
}

/// An open journal, appending.
#[derive(Debug)]
pub struct Journal {
    file: Option<File>,
    path: PathBuf,
    chain: u64,
    /// The file's length after its last whole record: a failed write is cut back to it.
    len: u64,
}

/// The text before `,"chain":"…"}` at the end of a journal line.
const CHAIN_KEY: &str = ",\"chain\":\"";

impl Journal {
    /// Creates (or truncates) a journal at `path`.
    pub fn create(path: &Path) -> Result<Self, JournalError> {
        let io = |source| JournalError::Io {
            path: path.to_path_buf(),
            source,
        };
        let file = File::create(path).map_err(io)?;
        Ok(Journal {
            file: Some(file),
            path: path.to_path_buf(),
            chain: FNV_BASIS,
            len: 0,
        })
    }

    /// Reads every record of the journal at `path`, checking the chain, and opens it for
    /// appending after them.
    pub fn resume(path: &Path) -> Result<(Self, Vec<Map<String, Value>>), JournalError> {
        let records = read(path)?;
        let chain = records
            .last()
            .and_then(|r| r.get("chain"))
            .and_then(Value::as_str)
            .and_then(|s| u64::from_str_radix(s, 16).ok())
            .unwrap_or(FNV_BASIS);
        let file = OpenOptions::new()
            .append(true)
            .open(path)
            .map_err(|source| JournalError::Io {
                path: path.to_path_buf(),
                source,
            })?;
        let len = file
            .metadata()
            .map_err(|source| JournalError::Io {
                path: path.to_path_buf(),
                source,
            })?
            .len();
        Ok((
            Journal {
                file: Some(file),
                path: path.to_path_buf(),
                chain,
                len,
            },
            records,
        ))
    }

    /// A journal that keeps nothing (manual moves, `windcell jog`).
    pub fn none() -> Self {
        Journal {
            file: None,
            path: PathBuf::new(),
            chain: FNV_BASIS,
            len: 0,
        }
    }

    /// The journal's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Appends `record` (a JSON object; `chain` is added) and syncs it to disk: a whole record or
    /// nothing. The line is made in one buffer and written; a write that fails or is cut short (a
    /// full disk, `ENOSPC`; the file-size limit, `EFBIG`, with `SIGXFSZ` ignored) is cut back to
    /// the journal's length before it, so that the journal stays whole and resumable and the
    /// system's error is reported.
    pub fn append(&mut self, record: Value) -> Result<(), JournalError> {
        let mut map = match record {
            Value::Object(m) => m,
            other => {
                let mut m = Map::new();
                m.insert("value".into(), other);
                m
            }
        };
        map.remove("chain");
        let body = Value::Object(map).to_string();
        // The hash covers the text as written (a float read back need not print the same).
        let body = body.strip_suffix('}').unwrap_or(&body);
        let chain = fnv1a(self.chain, body.as_bytes());
        let line = format!("{body}{CHAIN_KEY}{chain:016x}\"}}");
        let io = |source| JournalError::Io {
            path: self.path.clone(),
            source,
        };
        if let Some(file) = self.file.as_mut() {
            let bytes = format!("{line}\n").into_bytes();
            // One buffer, written whole (a write cut short is followed by one for the rest,
            // which brings the system's error: EFBIG, ENOSPC).
            let written = file.write_all(&bytes).and_then(|()| file.sync_data());
            if let Err(e) = written {
                // Cut back to the last whole record (the append position follows the length).
                let _ = file.set_len(self.len);
                let _ = file.sync_data();
                return Err(io(e));
            }
            self.len += bytes.len() as u64;
        }
        self.chain = chain;
        Ok(())
    }
}

/// A record's kind: its `rec` field (`begin`, `segment`, `item_done`, `done`, …).
pub fn kind(record: &Map<String, Value>) -> Option<&str> {
    record.get("rec").and_then(Value::as_str)
}

/// True when the journal's last record says the batch is done.
pub fn batch_done(records: &[Map<String, Value>]) -> bool {
    records.last().and_then(kind) == Some("done")
}

/// Reads and checks every record of a journal.
pub fn read(path: &Path) -> Result<Vec<Map<String, Value>>, JournalError> {
    let text = sequences::source::read_text(path, sequences::source::MAX_JOURNAL_BYTES)?;
    let mut prev = FNV_BASIS;
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let corrupt = |message: String| JournalError::Corrupt {
            path: path.to_path_buf(),
            line: i + 1,
            message,
        };
        if line.len() > 1 << 20 {
            return Err(corrupt("line too long for a journal record".into()));
        }
        let map = match serde_json::from_str::<Value>(line) {
            Ok(Value::Object(m)) => m,
            _ => return Err(corrupt("not a journal record".into())),
        };
        let body = line.rfind(CHAIN_KEY).map_or("", |at| &line[..at]);
        let want = fnv1a(prev, body.as_bytes());
        let got = map
            .get("chain")
            .and_then(Value::as_str)
            .and_then(|s| u64::from_str_radix(s, 16).ok());
        if got != Some(want) {
            return Err(corrupt(
                "the record's chain does not match: the journal was edited or is damaged".into(),
            ));
        }
        prev = want;
        out.push(map);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn fnv1a_matches_the_reference_vectors() {
        // FNV-1a 64 test vectors (Fowler, Noll, Vo: "a" and "foobar").
        assert_eq!(fnv1a(FNV_BASIS, b""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv1a(FNV_BASIS, b"a"), 0xaf63_dc4c_8601_ec8c);
        assert_eq!(fnv1a(FNV_BASIS, b"foobar"), 0x8594_4171_f739_67e8);
    }

    #[test]
    fn records_round_trip_and_edits_are_found() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("J.journal");
        let mut j = Journal::create(&path).unwrap();
        j.append(json!({"rec": "begin", "job": "abc"})).unwrap();
        j.append(json!({"rec": "segment", "item": 0, "segment": 1}))
            .unwrap();
        drop(j);
        let (mut j, recs) = Journal::resume(&path).unwrap();
        assert_eq!(recs.len(), 2);
        assert_eq!(recs[1]["segment"], 1);
        j.append(json!({"rec": "segment", "item": 0, "segment": 2}))
            .unwrap();
        assert_eq!(read(&path).unwrap().len(), 3);
        // One digit changed by hand.
        let text = std::fs::read_to_string(&path).unwrap();
        std::fs::write(&path, text.replacen("\"segment\":2", "\"segment\":3", 1)).unwrap();
        let err = read(&path).unwrap_err();
        assert!(
            matches!(err, JournalError::Corrupt { line: 3, .. }),
            "{err}"
        );
    }

    #[test]
    fn a_device_or_an_oversized_file_is_refused_before_it_is_read() {
        let err = read(Path::new("/dev/zero")).unwrap_err();
        assert!(
            matches!(
                err,
                JournalError::Unreadable(sequences::Error::NotRegularFile { .. })
            ),
            "{err}"
        );
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("big.journal");
        let file = File::create(&path).unwrap();
        file.set_len(sequences::source::MAX_JOURNAL_BYTES + 1)
            .unwrap();
        let err = read(&path).unwrap_err();
        assert!(
            matches!(
                err,
                JournalError::Unreadable(sequences::Error::FileTooLarge { .. })
            ),
            "{err}"
        );
    }

    #[test]
    fn a_record_line_of_exactly_one_mebibyte_reads_and_one_byte_more_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let line_len = |pad: usize| -> usize {
            let p = dir.path().join(format!("len{pad}.journal"));
            let mut j = Journal::create(&p).unwrap();
            j.append(json!({"rec": "note", "pad": "x".repeat(pad)}))
                .unwrap();
            drop(j);
            std::fs::read_to_string(&p)
                .unwrap()
                .lines()
                .next()
                .unwrap()
                .len()
        };
        let base = line_len(0);
        let limit = 1usize << 20;
        let p = dir.path().join("exact.journal");
        let mut j = Journal::create(&p).unwrap();
        j.append(json!({"rec": "note", "pad": "x".repeat(limit - base)}))
            .unwrap();
        drop(j);
        assert_eq!(
            std::fs::read_to_string(&p)
                .unwrap()
                .lines()
                .next()
                .unwrap()
                .len(),
            limit
        );
        assert_eq!(read(&p).unwrap().len(), 1);
        let p = dir.path().join("over.journal");
        let mut j = Journal::create(&p).unwrap();
        j.append(json!({"rec": "note", "pad": "x".repeat(limit - base + 1)}))
            .unwrap();
        drop(j);
        let e = read(&p).unwrap_err().to_string();
        assert!(e.contains("line too long"), "{e}");
    }
}
