//! What an operator's day does to a run's records and ports: a file-size limit mid-batch (the
//! journal's writes are whole records or nothing), a second `windcell` on a port the first holds
//! (an advisory lock that dies with its process).

use crate::common;

use std::process::Command;

use cell::run::journal;
use common::{example, stderr, windcell};

/// `windcell run ARGS` under a file-size limit of `kib` KiB (bash's `ulimit -f`, 1024-byte
/// blocks).
fn windcell_limited(kib: u64, args: &[&str]) -> std::process::Output {
    let mut line = format!("ulimit -f {kib}; exec \"$0\"");
    for (k, _) in args.iter().enumerate() {
        line += &format!(" \"${}\"", k + 1);
    }
    Command::new("bash")
        .arg("-c")
        .arg(line)
        .arg(env!("CARGO_BIN_EXE_windcell"))
        .args(args)
        .output()
        .expect("bash runs")
}

/// The (item, segment) of every segment record of a journal, in order.
fn segments(records: &[serde_json::Map<String, serde_json::Value>]) -> Vec<(u64, u64)> {
    records
        .iter()
        .filter(|r| journal::kind(r) == Some("segment"))
        .map(|r| (r["item"].as_u64().unwrap(), r["segment"].as_u64().unwrap()))
        .collect()
}

/// The S-bend in discrete mode journals a record per segment, 102 of them, about 200 bytes
/// each: with a file-size limit of 8 KiB the journal's write fails mid-batch. The process is not
/// killed by SIGXFSZ: the write comes back as EFBIG, the journal is cut back to its last whole
/// record, both devices are told to stop and one line says so with the resume command; the
/// resume (without the limit) finishes the batch, every segment journaled once.
#[test]
fn a_file_size_limit_ends_in_a_clean_stop_and_a_resumable_journal() {
    const LIMIT_KIB: u64 = 8;
    let dir = tempfile::tempdir().unwrap();
    let jp = dir.path().join("SBEND.journal");
    let job = example("sbend.toml");
    let args = [
        "run",
        job.to_str().unwrap(),
        "--mode",
        "discrete",
        "--journal",
        jp.to_str().unwrap(),
    ];
    let o = windcell_limited(LIMIT_KIB, &args);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(
        err.contains("File too large")
            && err.contains("both axes told to stop")
            && err.contains("--resume"),
        "{err}"
    );
    // Whole records only: every line a record whose chain holds, within the limit.
    let text = std::fs::read_to_string(&jp).unwrap();
    assert!(text.ends_with('\n'));
    assert!(text.len() as u64 <= LIMIT_KIB * 1024, "{}", text.len());
    let before = journal::read(&jp).unwrap();
    let first = segments(&before);
    assert!(!first.is_empty() && first.len() < 102, "{}", first.len());
    // The resume the line names, without the limit.
    let mut resume = args.to_vec();
    resume.truncate(4);
    let jp_s = jp.to_str().unwrap();
    resume.extend(["--resume", jp_s]);
    let o = windcell(&resume);
    assert!(o.status.success(), "{}", stderr(&o));
    let after = journal::read(&jp).unwrap();
    assert_eq!(journal::kind(after.last().unwrap()), Some("done"));
    let want: Vec<(u64, u64)> = (0..2).flat_map(|i| (1..=51).map(move |s| (i, s))).collect();
    assert_eq!(segments(&after), want);
}
