//! `windcell lathe run | home | gear | tune`: the recording of the axes as MCAP, the machine
//! routines of seed 003 (machine zero, single block, layer counter, 16-bit counter rollover,
//! electronic gearing, Eq. 8 with the Routh check) as the operator reaches them.

use crate::common;

use std::io::Write;
use std::path::Path;
use std::process::{Command, Stdio};

use common::{example, stderr, windcell, windcell_json};
use serde_json::Value;

fn fig_9_1() -> String {
    example("cone-dome-cylinder.prg").display().to_string()
}

/// Fig 9-1 with one circuit, written to `dir`.
fn one_circuit(dir: &Path) -> String {
    let text = std::fs::read_to_string(fig_9_1())
        .unwrap()
        .replace("L 3", "L 1");
    let path = dir.join("one.prg");
    std::fs::write(&path, text).unwrap();
    path.display().to_string()
}

#[test]
fn record_writes_every_interrupt_of_the_axes_as_mcap() {
    let dir = tempfile::tempdir().unwrap();
    let prg = one_circuit(dir.path());
    let mcap_path = dir.path().join("run.mcap");
    let report = windcell_json(&[
        "lathe",
        "run",
        &prg,
        "--interp",
        "bspline",
        "--feed",
        "30",
        "--json",
        "--record",
        mcap_path.to_str().unwrap(),
    ]);
    let interrupts = report["interrupts"].as_u64().unwrap();
    let bytes = std::fs::read(&mcap_path).unwrap();
    let mut axes = Vec::new();
    let mut logs = Vec::new();
    let mut first_time = None;
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        let schema = m.channel.schema.as_ref().unwrap();
        match m.channel.topic.as_str() {
            "/lathe/axes" => {
                assert_eq!(schema.name, "windcell.LatheAxes");
                assert_eq!(m.channel.message_encoding, "json");
                let v: Value = serde_json::from_slice(&m.data).unwrap();
                let k = v["interrupt"].as_u64().unwrap();
                let t0 = *first_time.get_or_insert(m.log_time - 5_000_000 * k);
                // 200 Hz: interrupt k is logged 5 ms × k after the run's start.
                assert_eq!(m.log_time - t0, 5_000_000 * k);
                axes.push(v);
            }
            "/log" => {
                use foxglove::Decode;
                logs.push(foxglove::schemas::Log::decode(&m.data[..]).unwrap().message);
            }
            other => panic!("unexpected topic {other}"),
        }
    }
    assert_eq!(axes.len() as u64, interrupts);
    assert!(
        logs.iter().any(|l| l == "circuit 1/1 wound, layer 1 of 1"),
        "{logs:?}"
    );
    // Following error = commanded − actual, and its largest magnitude is the report's.
    for (i, (axis, unit)) in [("a", "deg"), ("x", "mm"), ("y", "mm")].iter().enumerate() {
        let mut worst = 0.0f64;
        for v in &axes {
            let c = v[format!("{axis}_commanded_{unit}")].as_f64().unwrap();
            let a = v[format!("{axis}_actual_{unit}")].as_f64().unwrap();
            let e = v[format!("{axis}_error_{unit}")].as_f64().unwrap();
            assert!((c - a - e).abs() < 1e-12);
            worst = worst.max(e.abs());
        }
        let reported = report["axes"][i]["max_following_error"].as_f64().unwrap();
        assert!(
            (worst - reported).abs() < 1e-9 * reported.max(1.0),
            "{axis}: {worst} {reported}"
        );
        assert!(worst > 0.0);
    }
    // The circuit returns X and Y to part zero and turns A 480.98° (Fig 9-1).
    let last = axes.last().unwrap();
    assert!((last["a_commanded_deg"].as_f64().unwrap() - 480.98).abs() < 1e-6);
    assert!(last["x_commanded_mm"].as_f64().unwrap().abs() < 1e-6);
}

#[test]
fn counters_that_wrap_mid_move_give_the_same_run() {
    let dir = tempfile::tempdir().unwrap();
    let prg = one_circuit(dir.path());
    let run = |start: &str| {
        windcell_json(&[
            "lathe",
            "run",
            &prg,
            "--feed",
            "20",
            "--json",
            "--counter-start",
            start,
        ])
    };
    let plain = run("0");
    // Every axis's counter starts 200 counts below 65 535: A and X wrap upward early in the
    // circuit, and X and Y wrap back when they return.
    let wrapped = run("65335");
    assert_eq!(plain["axes"], wrapped["axes"]);
    assert_eq!(plain["interrupts"], wrapped["interrupts"]);
    let out = windcell(&["lathe", "run", &prg, "--counter-start", "65536"]);
    assert_eq!(out.status.code(), Some(2));
}

#[test]
fn machine_zero_search_ends_at_the_same_encoder_count_from_any_start() {
    let mut ends = Vec::new();
    for (from, counter) in [("3,5", "0"), ("57.3,150", "65500"), ("611.1,42", "1234")] {
        let v = windcell_json(&[
            "lathe",
            "home",
            "--from",
            from,
            "--counter-start",
            counter,
            "--json",
        ]);
        let axes = v["axes"].as_array().unwrap();
        assert_eq!(axes[0]["axis"], "X");
        assert_eq!(axes[1]["axis"], "Y");
        ends.push((
            axes[0]["machine_zero_count"].as_i64().unwrap(),
            axes[1]["machine_zero_count"].as_i64().unwrap(),
        ));
    }
    assert!(ends.iter().all(|e| *e == ends[0]), "{ends:?}");
    // The home switch is made at −1 mm: X −55.358 counts, Y −62.294; the first count read with
    // it released is the floor, and machine zero is 100 pulses beyond (±1 count of settling).
    let (x, y) = ends[0];
    assert!((x - (-56 + 100)).abs() <= 1, "{x}");
    assert!((y - (-63 + 100)).abs() <= 1, "{y}");
    let out = windcell(&["lathe", "home", "--from", "-7,5"]);
    assert_eq!(out.status.code(), Some(2));
    assert_eq!(stderr(&out).lines().count(), 1, "{}", stderr(&out));
}

#[test]
fn electronic_gearing_holds_the_carriage_at_the_ratio() {
    for (ratio, turns) in [("0.2", "2"), ("-0.1", "1")] {
        let v = windcell_json(&[
            "lathe", "gear", "--ratio", ratio, "--turns", turns, "--json",
        ]);
        let r: f64 = ratio.parse().unwrap();
        let angle = 360.0 * turns.parse::<f64>().unwrap();
        let a = v["mandrel_deg"].as_f64().unwrap();
        let x = v["carriage_mm"].as_f64().unwrap();
        // One A count is 0.028°, one X count 0.018 mm.
        assert!((a - angle).abs() < 0.1, "{v}");
        assert!((x - r * a).abs() < 0.05, "{v}");
        let worst = v["worst_error_mm"].as_f64().unwrap();
        assert!(worst > 0.0 && worst < 0.5, "{v}");
    }
    // 2 mm/° over two turns from part zero X 150 mm leaves the 1000 mm travel.
    let out = windcell(&["lathe", "gear", "--ratio", "2", "--turns", "2"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        stderr(&out).contains("beyond the limit switches"),
        "{}",
        stderr(&out)
    );
}

/// `windcell lathe run three.prg --single-block` with `input` on standard input: three blocks
/// (at lines 3, 4 and 5) of a relative program.
fn single_block(input: &[u8]) -> std::process::Output {
    let dir = tempfile::tempdir().unwrap();
    let prg = dir.path().join("three.prg");
    std::fs::write(
        &prg,
        "%\nO 1 G91;\nN 10 X 10;\nN 20 Y 5 A 90;\nN 30 X -10 Y -5;\nM30;\n",
    )
    .unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_windcell"))
        .args(["lathe", "run", prg.to_str().unwrap(), "--single-block"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    child.stdin.take().unwrap().write_all(input).unwrap();
    child.wait_with_output().unwrap()
}

#[test]
fn single_block_waits_for_the_operator_before_every_block() {
    let out = single_block(b"\n\n\n");
    assert!(out.status.success(), "{}", stderr(&out));
    let err = stderr(&out);
    let prompts: Vec<&str> = err.split("press Enter").collect();
    assert_eq!(prompts.len() - 1, 3, "{err}");
    for (n, line) in [(1, 3), (2, 4), (3, 5)] {
        assert!(
            err.contains(&format!("three.prg:{line}:")),
            "block {n}: {err}"
        );
    }
}

#[test]
fn single_block_stops_when_standard_input_closes() {
    // One Enter, then end of input: the first block runs, the second is not started.
    let out = single_block(b"\n");
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    let err = stderr(&out);
    assert_eq!(err.matches("press Enter").count(), 2, "{err}");
    let last = err.lines().last().unwrap();
    assert!(
        last.contains("three.prg:4:") && last.contains("standard input closed"),
        "{err}"
    );
    assert!(last.contains("1 of 3 blocks run"), "{err}");
    assert!(out.stdout.is_empty());
}

#[test]
fn progress_counts_layers() {
    let out = windcell(&[
        "lathe",
        "run",
        &fig_9_1(),
        "--feed",
        "40",
        "--circuits-per-layer",
        "2",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let err = stderr(&out);
    let lines: Vec<&str> = err.lines().collect();
    assert_eq!(
        lines,
        [
            "circuit 1/3 wound, layer 1 of 2",
            "circuit 2/3 wound, layer 1 of 2",
            "circuit 3/3 wound, layer 2 of 2",
            "M00 program stop",
        ]
    );
}

#[test]
fn tune_reports_the_eq8_gain_and_refuses_what_routh_refuses() {
    // τ = 1 s and T/τ = π/2: seed 003's worked value K = 0.4569.
    let rate = format!("{}", 2.0 / std::f64::consts::PI);
    let v = windcell_json(&["lathe", "tune", "--tau", "1", "--rate", &rate, "--json"]);
    assert!(
        (v["eq8_gain_per_s"].as_f64().unwrap() - 0.4569).abs() < 5e-5,
        "{v}"
    );
    assert_eq!(v["stable"], true);
    // X of the seed 000 plant at 200 Hz: a loop gain K gives K_p = K·46.7/(1772·0.45).
    let v = windcell_json(&["lathe", "tune", "--json"]);
    let k = v["eq8_gain_per_s"].as_f64().unwrap();
    let kp = v["kp_dac_codes_per_count"].as_f64().unwrap();
    assert!((kp - k * 46.7 / (1772.0 * 0.45)).abs() < 1e-9, "{v}");
    for tau in ["0", "-1"] {
        let out = windcell(&["lathe", "tune", &format!("--tau={tau}")]);
        assert_eq!(out.status.code(), Some(2), "{tau}");
        assert_eq!(stderr(&out).lines().count(), 1);
    }
}
