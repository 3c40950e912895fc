//! `windcell run --live` on the built-in simulated cell at the real cell's pace: a viewer that
//! joins late gets the scene, the transforms and the eye at once, and a real-clock run lasts the
//! cell's time divided by the speed factor.

use crate::common;

use std::io::{BufRead, BufReader, Read};
use std::net::TcpStream;
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use foxglove::Decode;
use foxglove::schemas::{FrameTransform, SceneUpdate};
use tungstenite::Message;
use tungstenite::client::IntoClientRequest;
use tungstenite::http::HeaderValue;

use common::example;

/// Starts `windcell run JOB --live 127.0.0.1:0 EXTRA…` in `dir`; returns the process, the port it
/// serves on (from its `serving the run live … on port N` line) and when it started.
fn start_live(dir: &Path, job: &Path, extra: &[&str]) -> (Child, u16, Instant) {
    let t0 = Instant::now();
    let mut child = Command::new(env!("CARGO_BIN_EXE_windcell"))
        .current_dir(dir)
        .arg("run")
        .arg(job)
        .args(["--live", "127.0.0.1:0"])
        .args(extra)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("windcell runs");
    let mut out = BufReader::new(child.stdout.take().unwrap());
    let mut line = String::new();
    let port = loop {
        line.clear();
        if out.read_line(&mut line).unwrap() == 0 {
            let mut err = String::new();
            child
                .stderr
                .take()
                .unwrap()
                .read_to_string(&mut err)
                .unwrap();
            panic!("no port line; stderr: {err}");
        }
        if let Some(p) = line
            .trim()
            .strip_prefix("serving the run live for Foxglove on port ")
        {
            break p.parse::<u16>().unwrap();
        }
    };
    // The rest of the output is drained so that the run never blocks on a full pipe.
    std::thread::spawn(move || {
        let mut sink = String::new();
        let _ = out.read_to_string(&mut sink);
    });
    (child, port, t0)
}

type Ws = tungstenite::WebSocket<TcpStream>;

/// Connects offering `subprotocol`; returns the socket and the subprotocol the server chose.
fn connect(port: u16, subprotocol: &'static str) -> (Ws, String) {
    let mut request = format!("ws://127.0.0.1:{port}")
        .into_client_request()
        .unwrap();
    request.headers_mut().insert(
        "Sec-WebSocket-Protocol",
        HeaderValue::from_static(subprotocol),
    );
    let stream = TcpStream::connect(("127.0.0.1", port)).unwrap();
    stream
        .set_read_timeout(Some(Duration::from_secs(5)))
        .unwrap();
    let (ws, response) = tungstenite::client(request, stream).unwrap();
    let chosen = response
        .headers()
        .get("Sec-WebSocket-Protocol")
        .map(|v| v.to_str().unwrap().to_string())
        .unwrap_or_default();
    (ws, chosen)
}

/// Reads the advertisements until every topic of `topics` has a channel; subscribes to them
/// (subscription id = index + 1) and returns when it did.
fn subscribe(ws: &mut Ws, topics: &[&str]) -> Instant {
    let mut ids = vec![None; topics.len()];
    let deadline = Instant::now() + Duration::from_secs(5);
    while ids.iter().any(Option::is_none) {
        assert!(
            Instant::now() < deadline,
            "advertised: {ids:?} of {topics:?}"
        );
        if let Message::Text(text) = ws.read().unwrap() {
            let v: serde_json::Value = serde_json::from_str(text.as_str()).unwrap();
            if v["op"] == "advertise" {
                for ch in v["channels"].as_array().unwrap() {
                    if let Some(k) = topics.iter().position(|t| ch["topic"] == *t) {
                        ids[k] = ch["id"].as_u64();
                    }
                }
            }
        }
    }
    let subscriptions: Vec<serde_json::Value> = ids
        .iter()
        .enumerate()
        .map(|(k, id)| serde_json::json!({"id": k + 1, "channelId": id.unwrap()}))
        .collect();
    let msg = serde_json::json!({"op": "subscribe", "subscriptions": subscriptions});
    ws.send(Message::Text(msg.to_string().into())).unwrap();
    Instant::now()
}

/// What a viewer received: per subscription (index of its topic), the payloads and when.
fn receive(ws: &mut Ws, topics: usize, within: Duration) -> Vec<Vec<(Duration, Vec<u8>)>> {
    let t0 = Instant::now();
    let mut got = vec![Vec::new(); topics];
    while t0.elapsed() < within {
        ws.get_mut()
            .set_read_timeout(Some(
                (within.saturating_sub(t0.elapsed())).max(Duration::from_millis(1)),
            ))
            .unwrap();
        match ws.read() {
            // MessageData: opcode 1, subscription id (u32 LE), log time (u64 LE), payload.
            Ok(Message::Binary(data)) if data.first() == Some(&1) => {
                let sub = u32::from_le_bytes(data[1..5].try_into().unwrap()) as usize;
                if (1..=topics).contains(&sub) {
                    got[sub - 1].push((t0.elapsed(), data[13..].to_vec()));
                }
            }
            Ok(_) => {}
            Err(_) => break,
        }
    }
    got
}

fn entity_ids(updates: &[(Duration, Vec<u8>)]) -> Vec<String> {
    updates
        .iter()
        .flat_map(|(_, d)| SceneUpdate::decode(&d[..]).unwrap().entities)
        .map(|e| e.id)
        .collect()
}

/// The operator issue's target: a viewer joining 3 s into a real-clock run of the S-bend (the
/// first path's program upload under way) receives, within one second of subscribing, the
/// mandrel surface, the desired fibre of both paths and the mandrel and eye transforms, and the
/// transforms keep coming at the cell's pace: their log times advance by about the wall time
/// (the real clock at speed 1), where the fast clock would have ended the whole 108 s batch in a
/// fraction of a second. The viewer offers `foxglove.websocket.v1`, the name the older Foxglove
/// clients use.
#[test]
fn a_viewer_joining_three_seconds_in_sees_the_scene_and_moving_transforms_within_a_second() {
    let dir = tempfile::tempdir().unwrap();
    let (mut child, port, t0) = start_live(dir.path(), &example("sbend.toml"), &[]);
    std::thread::sleep(Duration::from_secs(3).saturating_sub(t0.elapsed()));
    let (mut ws, chosen) = connect(port, "foxglove.websocket.v1");
    assert_eq!(chosen, "foxglove.websocket.v1");
    let topics = ["/scene/mandrel", "/scene/fibre", "/tf"];
    subscribe(&mut ws, &topics);
    let got = receive(&mut ws, topics.len(), Duration::from_secs(1));
    assert!(
        child.try_wait().unwrap().is_none(),
        "the run ended before the viewer looked"
    );
    child.kill().unwrap();
    child.wait().unwrap();
    let mandrel = entity_ids(&got[0]);
    assert!(mandrel.iter().any(|id| id == "mandrel"), "{mandrel:?}");
    let fibre = entity_ids(&got[1]);
    for id in ["SBEND_1/desired", "SBEND_2/desired"] {
        assert!(fibre.iter().any(|f| f == id), "{id} not in {fibre:?}");
    }
    let tf: Vec<(Duration, FrameTransform)> = got[2]
        .iter()
        .map(|(t, d)| (*t, FrameTransform::decode(&d[..]).unwrap()))
        .collect();
    let stamp_s = |f: &FrameTransform| {
        let t = f.timestamp.unwrap();
        f64::from(t.sec()) + f64::from(t.nsec()) * 1e-9
    };
    for frame in ["mandrel", "eye"] {
        let of: Vec<&(Duration, FrameTransform)> = tf
            .iter()
            .filter(|(_, f)| f.child_frame_id == frame)
            .collect();
        // Transforms keep coming: about ten a second at the cell's pace; at least five arrive
        // whatever the scheduling (nine were seen once on the two-core machine), and the pace
        // itself is checked from their log times below.
        assert!(
            of.len() >= 5,
            "{frame}: {} transforms in a second",
            of.len()
        );
        // The first within a second of subscribing is the newest kept for late joiners.
        assert!(
            of[0].0 < Duration::from_millis(500),
            "{frame} first at {:?}",
            of[0].0
        );
        // Cell time advances at the wall clock's pace (speed 1): over the second, the log
        // times advance by the wall time between the first and the last, within 0.25 s.
        let (first, last) = (of[0], of[of.len() - 1]);
        let cell_s = stamp_s(&last.1) - stamp_s(&first.1);
        let wall_s = (last.0 - first.0).as_secs_f64();
        assert!(
            (cell_s - wall_s).abs() < 0.25 && cell_s > 0.5,
            "{frame}: cell {cell_s:.3} s over wall {wall_s:.3} s"
        );
    }
}

/// The cell time `windcell run` reports on its last line (`… 108.0 s of simulated cell time in …`).
fn cell_time_s(stdout: &[u8]) -> f64 {
    let text = String::from_utf8_lossy(stdout);
    let line = text
        .lines()
        .find(|l| l.starts_with("batch done:"))
        .unwrap_or_else(|| panic!("no batch line in {text}"));
    let before = line.split(" s of simulated cell time").next().unwrap();
    before.rsplit(' ').next().unwrap().parse().unwrap()
}

/// The real clock at `--speed 40` winds the S-bend in its cell time divided by 40 of wall time
/// (from below: no faster than the pace allows; from above: within the start-up's planning and
/// check plus a second), with the same cell time as the fast clock, which takes a small part of
/// that (the README's "well under a second"). A bad factor is one line, exit code 2.
#[test]
fn a_real_clock_run_lasts_its_cell_time_over_the_speed_factor() {
    let dir = tempfile::tempdir().unwrap();
    let job = example("sbend.toml");
    let run = |extra: &[&str]| {
        let t0 = Instant::now();
        let o = Command::new(env!("CARGO_BIN_EXE_windcell"))
            .current_dir(dir.path())
            .arg("run")
            .arg(&job)
            .args(["--restart"])
            .args(extra)
            .stdin(Stdio::null())
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", common::stderr(&o));
        (cell_time_s(&o.stdout), t0.elapsed().as_secs_f64())
    };
    let (fast_cell_s, fast_wall_s) = run(&["--clock", "fast"]);
    let speed = 40.0;
    let (cell_s, wall_s) = run(&["--speed", "40"]);
    assert!(
        (cell_s - fast_cell_s).abs() < 0.5,
        "{cell_s} against {fast_cell_s}"
    );
    let paced_s = cell_s / speed;
    assert!(
        wall_s >= paced_s * 0.98 && wall_s <= paced_s + fast_wall_s + 1.0,
        "{cell_s} s of cell time at speed {speed} took {wall_s:.2} s (paced {paced_s:.2} s, the fast clock {fast_wall_s:.2} s)"
    );
    assert!(fast_wall_s < paced_s / 2.0, "fast clock {fast_wall_s:.2} s");
    for (args, expect) in [
        (vec!["--speed", "0"], "--speed"),
        (vec!["--speed", "nan"], "--speed"),
        (vec!["--speed", "5000"], "--speed"),
        (vec!["--clock", "fast", "--speed", "2"], "--speed 2"),
    ] {
        let o = Command::new(env!("CARGO_BIN_EXE_windcell"))
            .current_dir(dir.path())
            .arg("run")
            .arg(&job)
            .args(&args)
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(2), "{args:?}");
        let err = common::stderr(&o);
        assert_eq!(err.trim().lines().count(), 1, "{args:?}: {err}");
        assert!(err.contains(expect), "{args:?}: {err}");
    }
}

/// The free fibre (`free` on `/scene/free_fibre`, frame `world`) runs from the eye to the mandrel:
/// while the S-bend's programs wind (between each `program started` and `done` on `/log`), its
/// length is the job's tow distance, 100 mm (`offset_mm`, seed 001 §6.4), within the few
/// millimetres the eye travels between two planned poses (the line ends at the nearest pose's
/// tangent point). Its first point is the eye: the `world → eye` transform of the same time.
#[test]
fn the_free_fibre_spans_the_tow_distance_while_winding() {
    let dir = tempfile::tempdir().unwrap();
    let mcap_path = dir.path().join("free.mcap");
    let o = Command::new(env!("CARGO_BIN_EXE_windcell"))
        .current_dir(dir.path())
        .arg("run")
        .arg(example("sbend.toml"))
        .arg("--record")
        .arg(&mcap_path)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", common::stderr(&o));
    let bytes = std::fs::read(&mcap_path).unwrap();
    let mut windows: Vec<(u64, Option<u64>)> = Vec::new();
    let mut free: Vec<(u64, f64, [f64; 3])> = Vec::new();
    let mut eye: std::collections::BTreeMap<u64, [f64; 3]> = Default::default();
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        match m.channel.topic.as_str() {
            "/log" => {
                let l = foxglove::schemas::Log::decode(&m.data[..]).unwrap();
                if l.message.contains("started at") {
                    windows.push((m.log_time, None));
                } else if l.message.contains("done at")
                    && let Some(w) = windows.last_mut()
                {
                    w.1 = Some(m.log_time);
                }
            }
            "/scene/free_fibre" => {
                for e in SceneUpdate::decode(&m.data[..]).unwrap().entities {
                    if e.id == "free" {
                        assert_eq!(e.frame_id, "world");
                        let p = &e.lines[0].points;
                        assert_eq!(p.len(), 2);
                        let d = ((p[0].x - p[1].x).powi(2)
                            + (p[0].y - p[1].y).powi(2)
                            + (p[0].z - p[1].z).powi(2))
                        .sqrt();
                        free.push((m.log_time, d * 1000.0, [p[0].x, p[0].y, p[0].z]));
                    }
                }
            }
            "/tf" => {
                let f = FrameTransform::decode(&m.data[..]).unwrap();
                if f.child_frame_id == "eye" {
                    let t = f.translation.unwrap();
                    eye.insert(m.log_time, [t.x, t.y, t.z]);
                }
            }
            _ => {}
        }
    }
    assert_eq!(windows.len(), 2, "{windows:?}");
    let mut lengths: Vec<f64> = free
        .iter()
        .filter(|(t, ..)| {
            windows
                .iter()
                .any(|(a, b)| *t >= *a && b.is_some_and(|b| *t <= b))
        })
        .map(|(_, d, _)| *d)
        .collect();
    assert!(
        lengths.len() > 100,
        "{} free fibres while winding",
        lengths.len()
    );
    lengths.sort_by(f64::total_cmp);
    let median = lengths[lengths.len() / 2];
    assert!(
        (median - 100.0).abs() < 5.0,
        "median free fibre {median:.2} mm"
    );
    let (lo, hi) = (
        lengths[lengths.len() / 20],
        lengths[lengths.len() * 19 / 20],
    );
    assert!(
        lo > 85.0 && hi < 115.0,
        "5–95 % of the free fibre {lo:.1}–{hi:.1} mm"
    );
    for (t, _, start) in &free {
        let e = eye
            .get(t)
            .expect("an eye transform at each free fibre's time");
        assert!(start.iter().zip(e).all(|(a, b)| (a - b).abs() < 1e-12));
    }
}
