//! `windcell run … --record FILE.mcap` on the simulated cell: the recording reads back, and a
//! recording cut off part-way (what `kill -9` leaves) still yields every message of every chunk
//! written before the cut (docs/operator.md, "Recovering a recording").

use crate::common;

use std::path::Path;

use common::{example, example_variant, stderr, windcell};

fn record(dir: &Path) -> std::path::PathBuf {
    let mcap = dir.join("run.mcap");
    let journal = dir.join("run.journal");
    let o = windcell(&[
        "run",
        example("cylinder.toml").to_str().unwrap(),
        "--mode",
        "fine",
        "--journal",
        journal.to_str().unwrap(),
        "--record",
        mcap.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    mcap
}

fn topics_of(bytes: &[u8]) -> Vec<String> {
    mcap::MessageStream::new(bytes)
        .unwrap()
        .map(|m| m.unwrap().channel.topic.clone())
        .collect()
}

#[test]
fn a_recorded_run_reads_back_and_a_cut_file_recovers_every_whole_chunk() {
    let dir = tempfile::tempdir().unwrap();
    let path = record(dir.path());
    let bytes = std::fs::read(&path).unwrap();
    let topics = topics_of(&bytes);
    let eye = topics.iter().filter(|t| *t == "/eye/simulated").count();
    // Fine movement, two paths of about 10 s each and the moves between them, one pose per
    // 20 ms of cell time (`RECORD_STEP_S`): never closer than that.
    assert!(eye > 1000, "{eye} eye poses");
    let times: Vec<u64> = mcap::MessageStream::new(&bytes)
        .unwrap()
        .map(Result::unwrap)
        .filter(|m| m.channel.topic == "/eye/simulated")
        .map(|m| m.log_time)
        .collect();
    let closest = times.windows(2).map(|w| w[1] - w[0]).min().unwrap();
    assert!(closest >= 20_000_000 - 1_000, "poses {closest} ns apart");
    for t in [
        "/tf",
        "/mandrel",
        "/log",
        "/sync",
        "/link/indexer",
        "/scene/mandrel",
    ] {
        assert!(topics.iter().any(|x| x == t), "no {t}");
    }
    // In fine mode every point is commanded once: the approach by its MOVE_IMMEDIATE (from the
    // telegram), each stored point when the program's move to it starts (from the robot).
    let (mut sent_points, mut commanded) = (0, 0);
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        match m.channel.topic.as_str() {
            "/link/robot" => {
                let t: serde_json::Value = serde_json::from_slice(&m.data).unwrap();
                let d = t["decoded"].as_str().unwrap();
                if t["direction"] == "sent"
                    && (d.starts_with("MoveImmediate") || d.starts_with("StorePos"))
                {
                    sent_points += 1;
                }
            }
            "/eye/commanded" => commanded += 1,
            _ => {}
        }
    }
    assert!(sent_points > 100, "{sent_points} points sent");
    assert_eq!(commanded, sent_points);
    laid_fibre_agrees_with_the_prediction(&bytes, &example("cylinder.toml"));
    // The chunks as the summary lists them: cut the file inside the middle chunk.
    let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
    let chunks = &summary.chunk_indexes;
    assert!(chunks.len() >= 3, "{} chunks", chunks.len());
    let mid = &chunks[chunks.len() / 2];
    let cut = (mid.chunk_start_offset + mid.chunk_length / 2) as usize;
    let whole: usize = chunks
        .iter()
        .filter(|c| (c.chunk_start_offset + c.chunk_length) as usize <= cut)
        .map(|c| summary.stream_chunk(&bytes, c).unwrap().count())
        .sum();
    // Recovery: read the records in order up to the cut.
    let mut recovered = Vec::new();
    for m in mcap::MessageStream::new(&bytes[..cut]).unwrap() {
        match m {
            Ok(m) => recovered.push(m.channel.topic.clone()),
            Err(_) => break,
        }
    }
    // Every message of the whole chunks, in order (the reader may also return the first messages
    // of the cut chunk, which decompress before the cut).
    assert!(recovered.len() >= whole, "{} < {whole}", recovered.len());
    assert_eq!(recovered[..], topics[..recovered.len()]);
    // Python's reference reader, when it is installed.
    let python = std::process::Command::new("python3")
        .args(["-c", "import mcap"])
        .output();
    if !python.is_ok_and(|o| o.status.success()) {
        eprintln!("skipped the Python check: python3 with the `mcap` package is not available");
        return;
    }
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scripts/check_mcap.py");
    let o = std::process::Command::new("python3")
        .arg(&script)
        .arg(&path)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let line = String::from_utf8_lossy(&o.stdout);
    assert!(
        line.starts_with(&format!("messages {} ", topics.len())),
        "{line}"
    );
    let cut_path = dir.path().join("cut.mcap");
    std::fs::write(&cut_path, &bytes[..cut]).unwrap();
    let o = std::process::Command::new("python3")
        .arg(&script)
        .arg("--recover")
        .arg(&cut_path)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let line = String::from_utf8_lossy(&o.stdout);
    let n: usize = line
        .split_whitespace()
        .nth(1)
        .and_then(|n| n.parse().ok())
        .unwrap_or(0);
    assert!(
        n >= whole && n <= topics.len(),
        "{line} (whole chunks: {whole})"
    );
}

/// The laid fibre a fine run on the simulated cell records at each path's end lies as far from
/// the desired path as `windcell predict` says it will (the same placement model over the same
/// simulated cell, reached through the run's trace instead of the prediction's own winding).
fn laid_fibre_agrees_with_the_prediction(bytes: &[u8], job: &Path) {
    use foxglove::Decode as _;
    // Per path: the desired fibre, and the laid one.
    type Fibres = (Vec<[f64; 3]>, Vec<[f64; 3]>);
    let mut laid: std::collections::BTreeMap<String, Fibres> = Default::default();
    for m in mcap::MessageStream::new(bytes).unwrap() {
        let m = m.unwrap();
        if m.channel.topic != "/scene/fibre" {
            continue;
        }
        let u = foxglove::schemas::SceneUpdate::decode(m.data.as_ref()).unwrap();
        for e in u.entities {
            let pts: Vec<[f64; 3]> = e.lines[0]
                .points
                .iter()
                .map(|p| [p.x, p.y, p.z].map(|c| c * 1000.0))
                .collect();
            let (path, kind) = e.id.split_once('/').unwrap();
            let slot = laid.entry(path.to_string()).or_default();
            if kind == "desired" {
                slot.0 = pts;
            } else if !pts.is_empty() {
                slot.1 = pts;
            }
        }
    }
    let o = windcell(&[
        "predict",
        job.to_str().unwrap(),
        "--mode",
        "fine",
        "--samples",
        "1",
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let report: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let predicted = &report["modes"][0]["paths"];
    assert_eq!(laid.len(), 2);
    for (k, (name, (desired, fibre))) in laid.iter().enumerate() {
        assert!(fibre.len() > 50, "{name}: {} laid points", fibre.len());
        // Largest distance of a laid point from the desired polyline.
        let dist = |p: &[f64; 3]| {
            desired
                .windows(2)
                .map(|w| {
                    let (a, b) = (w[0], w[1]);
                    let ab = [0, 1, 2].map(|i| b[i] - a[i]);
                    let ap = [0, 1, 2].map(|i| p[i] - a[i]);
                    let l2: f64 = ab.iter().map(|c| c * c).sum();
                    let t = if l2 > 0.0 {
                        ((0..3).map(|i| ab[i] * ap[i]).sum::<f64>() / l2).clamp(0.0, 1.0)
                    } else {
                        0.0
                    };
                    (0..3)
                        .map(|i| (ap[i] - t * ab[i]).powi(2))
                        .sum::<f64>()
                        .sqrt()
                })
                .fold(f64::INFINITY, f64::min)
        };
        let worst = fibre.iter().map(dist).fold(0.0, f64::max);
        let want = predicted[k]["max_error_mm"].as_f64().unwrap();
        assert_eq!(predicted[k]["name"], name.as_str());
        eprintln!("{name}: laid {worst:.3} mm from the desired path, predicted {want:.3} mm");
        assert!(
            (worst - want).abs() <= 0.1 * want + 0.05,
            "{name}: {worst} against {want}"
        );
    }
}

/// The simulated cell is built from the job's own drive: with the motor in quarter steps (800
/// per revolution) the mandrel turns as the plan's steps say, and the laid fibre again matches
/// the prediction (a cell simulated with the thesis's 400 steps per revolution would turn it
/// twice as far).
#[test]
fn the_simulated_cell_runs_the_jobs_own_drive() {
    let dir = tempfile::tempdir().unwrap();
    let job = example_variant(
        dir.path(),
        "cylinder.toml",
        "cylinder-800.toml",
        &[("steps_per_rev = 400", "steps_per_rev = 800")],
    );
    let mcap = dir.path().join("run.mcap");
    let o = windcell(&[
        "run",
        job.to_str().unwrap(),
        "--mode",
        "fine",
        "--journal",
        dir.path().join("run.journal").to_str().unwrap(),
        "--record",
        mcap.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    laid_fibre_agrees_with_the_prediction(&std::fs::read(&mcap).unwrap(), &job);
}

/// A discrete run's recording holds the wire and the lines as the coordinator saw them: every
/// robot telegram and indexer line decoded (none undefined on the clean simulated links), one
/// MOVE_IMMEDIATE per segment the journal confirms, each commanded pose on `/eye/commanded`
/// equal to the position the journal read back after that segment (a discrete move stops at its
/// point; both on the wire's 1/16 mm grid), the start line rising once for each segment that
/// turns the mandrel (the journal's counter moves; a path's first segment only brings the eye to
/// its start) and falling in turn, and the job's scene: the mandrel surface and each path's
/// desired fibre.
#[test]
fn a_recorded_discrete_run_holds_the_wire_the_lines_the_commanded_eye_and_the_scene() {
    use foxglove::Decode as _;
    let dir = tempfile::tempdir().unwrap();
    let mcap_path = dir.path().join("run.mcap");
    let journal = dir.path().join("run.journal");
    let o = windcell(&[
        "run",
        example("cylinder.toml").to_str().unwrap(),
        "--mode",
        "discrete",
        "--journal",
        journal.to_str().unwrap(),
        "--record",
        mcap_path.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let records: Vec<serde_json::Value> = std::fs::read_to_string(&journal)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let confirmed: Vec<[f64; 3]> = records
        .iter()
        .filter(|r| r["rec"] == "segment")
        .map(|r| {
            let p = r["robot_mm"].as_array().unwrap();
            [0, 1, 2].map(|i| p[i].as_f64().unwrap())
        })
        .collect();
    let (mut turning, mut counter) = (0, None);
    for r in &records {
        let now = r["counter"].as_i64();
        if r["rec"] == "segment" && counter.is_some() && now != counter {
            turning += 1;
        }
        if now.is_some() {
            counter = now;
        }
    }
    assert!(confirmed.len() >= 100, "{} segments", confirmed.len());
    let bytes = std::fs::read(&mcap_path).unwrap();
    let (mut moves, mut commanded, mut start) = (0, Vec::new(), Vec::new());
    let (mut surface, mut fibres) = (0, std::collections::BTreeSet::new());
    let mut lines_sent = 0;
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        let json = || serde_json::from_slice::<serde_json::Value>(&m.data).unwrap();
        match m.channel.topic.as_str() {
            "/link/robot" => {
                let t = json();
                let decoded = t["decoded"].as_str().unwrap();
                assert!(
                    !decoded.contains("undefined") && !decoded.contains("bad"),
                    "{t}"
                );
                if t["direction"] == "sent" && decoded.starts_with("MoveImmediate") {
                    moves += 1;
                }
            }
            "/link/indexer" => {
                let t = json();
                if t["direction"] == "sent" {
                    lines_sent += 1;
                    assert!(
                        t["decoded"].as_str().unwrap().starts_with("unit 1: "),
                        "{t}"
                    );
                }
            }
            "/eye/commanded" => {
                let p = foxglove::schemas::PoseInFrame::decode(m.data.as_ref()).unwrap();
                let v = p.pose.unwrap().position.unwrap();
                commanded.push([v.x, v.y, v.z].map(|c| c * 1000.0));
            }
            "/sync" => {
                let e = json();
                if e["line"] == "start" {
                    start.push(e["high"].as_bool().unwrap());
                }
            }
            "/scene/mandrel" => {
                let u = foxglove::schemas::SceneUpdate::decode(m.data.as_ref()).unwrap();
                surface += u.entities[0].triangles[0].points.len() / 3;
            }
            "/scene/fibre" => {
                let u = foxglove::schemas::SceneUpdate::decode(m.data.as_ref()).unwrap();
                fibres.extend(u.entities.into_iter().map(|e| e.id));
            }
            _ => {}
        }
    }
    assert_eq!(moves, confirmed.len(), "one MOVE_IMMEDIATE a segment");
    assert_eq!(commanded.len(), confirmed.len());
    for (k, (c, j)) in commanded.iter().zip(&confirmed).enumerate() {
        for i in 0..3 {
            assert!(
                (c[i] - j[i]).abs() < 1e-6,
                "segment {k}: {c:?} against {j:?}"
            );
        }
    }
    assert!(lines_sent > 0);
    assert!(turning > 90, "{turning} segments turn the mandrel");
    assert_eq!(start.iter().filter(|h| **h).count(), turning, "{start:?}");
    assert_eq!(start.first(), Some(&false));
    assert!(
        start.windows(2).all(|w| w[0] != w[1]),
        "start edges alternate"
    );
    assert!(surface > 1000, "{surface} triangles");
    assert_eq!(
        fibres.into_iter().collect::<Vec<_>>(),
        ["CYL_1/desired", "CYL_1/laid", "CYL_2/desired", "CYL_2/laid"]
    );
}

/// `windcell predict --record`: every mode's paths appear as desired and laid fibre, the laid one
/// growing over the timeline (the last update of each holds the whole laid path), with a log line
/// per path; the file reads back with the `mcap` crate.
#[test]
fn a_recorded_prediction_holds_every_mode_and_path() {
    let dir = tempfile::tempdir().unwrap();
    let mcap_path = dir.path().join("predict.mcap");
    let o = windcell(&[
        "predict",
        example("cylinder.toml").to_str().unwrap(),
        "--samples",
        "2",
        "--record",
        mcap_path.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let bytes = std::fs::read(&mcap_path).unwrap();
    let mut logs = 0;
    let mut fibre = 0;
    let mut ids = std::collections::BTreeSet::new();
    let mut last_time = 0u64;
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        assert!(m.log_time >= last_time, "log times out of order");
        last_time = m.log_time;
        match m.channel.topic.as_str() {
            "/log" => logs += 1,
            "/scene/fibre" => {
                fibre += 1;
                use foxglove::Decode as _;
                let update = foxglove::schemas::SceneUpdate::decode(m.data.as_ref()).unwrap();
                for e in update.entities {
                    ids.insert(e.id);
                }
            }
            _ => {}
        }
    }
    // Four modes, two paths each.
    assert_eq!(logs, 8, "{logs} log lines");
    assert_eq!(ids.len(), 16, "{ids:?}");
    for mode in ["discrete", "fine", "medium", "continuous"] {
        assert!(
            ids.iter()
                .any(|i| i.starts_with(&format!("{mode}/")) && i.ends_with("/laid"))
        );
    }
    // Growing: several updates per path.
    assert!(fibre > 8 * 3, "{fibre} fibre updates");
}
