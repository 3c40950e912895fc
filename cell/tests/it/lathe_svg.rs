//! `windcell lathe plan … --svg FILE`: the picture of the layup. Expected figures from the
//! `.wind` file: passes = 2 × circuits of a helical layer (⌈π·D·cos α / b⌉ circuits), two per
//! non-terminal hoop layer; a helical layer lays two plies (±α) and a hoop pass one over a tube,
//! so the middle of the tube is as thick as that many tow thicknesses (a helical layer a little
//! more, its whole circuits covering slightly more than the circumference).

use crate::common;

use common::lathe::{lathe_plan, lathe_plan_summary, refused_in_one_line, tube};
use common::{example, stderr};

#[test]
fn the_layup_is_drawn_with_every_pass_and_its_thickness() {
    let dir = tempfile::tempdir().unwrap();
    let svg = dir.path().join("tube.svg");
    let s = lathe_plan_summary(
        &tube(),
        &dir.path().join("out"),
        "marlin",
        &["--svg", svg.to_str().unwrap()],
    );
    // ⌈π·70·cos 45° / 6.5⌉ = ⌈23.92⌉ = 24 circuits, 48 passes; the hoop out and back.
    let circuits = (std::f64::consts::PI * 70.0 * 45f64.to_radians().cos() / 6.5).ceil();
    assert_eq!(circuits, 24.0);
    assert_eq!(s["svg"]["passes"], serde_json::json!([2, 48]));
    // Middle of the tube: 2 hoop plies + 2 helical plies × 24/23.92.
    let exact = std::f64::consts::PI * 70.0 * 45f64.to_radians().cos() / 6.5;
    let expected = 0.25 * (2.0 + 2.0 * circuits / exact);
    let mid = s["svg"]["thickness_middle_mm"].as_f64().unwrap();
    assert!(
        (mid - expected).abs() < 0.01 * expected,
        "{mid} vs {expected}"
    );
    let text = std::fs::read_to_string(&svg).unwrap();
    assert!(text.starts_with("<svg"), "{}", &text[..80]);
    assert!(text.trim_end().ends_with("</svg>"));
    // One legend line per layer, naming its passes.
    assert!(text.contains("layer 1 hoop"), "legend");
    assert!(text.contains("layer 2 helical: 45.000°, 24 circuits, 48 passes"));
    assert!(text.contains("laminate thickness"));
    // Every path coordinate inside the drawing.
    for d in text.split("d=\"").skip(1) {
        let d = d.split('"').next().unwrap();
        for n in d
            .split(|c: char| c.is_ascii_alphabetic() || c == ' ')
            .filter(|t| !t.is_empty())
        {
            let v: f64 = n.parse().unwrap();
            assert!((0.0..=1200.0).contains(&v), "{v}");
        }
    }
}

#[test]
fn a_vessel_is_thickest_toward_its_openings() {
    let dir = tempfile::tempdir().unwrap();
    let svg = dir.path().join("v.svg");
    let s = lathe_plan_summary(
        &example("seed002-vessel.toml"),
        &dir.path().join("out"),
        "grbl",
        &["--svg", svg.to_str().unwrap()],
    );
    let t: Vec<(f64, f64)> = s["svg"]["thickness_mm"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| (p[0].as_f64().unwrap(), p[1].as_f64().unwrap()))
        .collect();
    let mid = t[t.len() / 2].1;
    // Seed 002's flat solution: the dome is thicker than the cylinder, most at the opening.
    assert!(t[0].1 > 2.0 * mid, "{:?} {mid}", t[0]);
    assert!(t[t.len() - 1].1 > 2.0 * mid);
}

#[test]
fn a_bad_svg_path_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("out");
    for (svg, expect) in [
        (dir.path().join("missing/x.svg"), "does not exist"),
        (dir.path().to_path_buf(), "is a folder"),
    ] {
        let out = lathe_plan(
            &example("seed002-vessel.toml"),
            &out_dir,
            "grbl",
            &["--svg", svg.to_str().unwrap()],
        );
        refused_in_one_line(&out, expect, &out_dir);
    }
}

#[test]
fn the_layup_is_recorded_in_3d_on_the_mandrels_surface() {
    let dir = tempfile::tempdir().unwrap();
    let record = dir.path().join("tube.mcap");
    let out = lathe_plan(
        &tube(),
        &dir.path().join("out"),
        "marlin",
        &["--record", record.to_str().unwrap()],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let bytes = std::fs::read(&record).unwrap();
    let messages: Vec<_> = mcap::MessageStream::new(&bytes)
        .unwrap()
        .map(|m| m.unwrap())
        .collect();
    // The mandrel, then one message per layer, in time order.
    assert_eq!(messages.len(), 3);
    let mut last = 0;
    for (k, m) in messages.iter().enumerate() {
        assert_eq!(m.channel.topic, "/lathe/layup");
        assert!(m.log_time >= last);
        last = m.log_time;
        let v: serde_json::Value = serde_json::from_slice(&m.data).unwrap();
        let entity = &v["entities"][0];
        assert_eq!(entity["frame_id"], "mandrel");
        if k > 0 {
            assert_eq!(entity["id"], format!("layer {k}"));
        }
        // Every point on the 70 mm mandrel between its ends, in metres.
        for p in entity["lines"][0]["points"].as_array().unwrap() {
            let (x, y, z) = (
                p["x"].as_f64().unwrap(),
                p["y"].as_f64().unwrap(),
                p["z"].as_f64().unwrap(),
            );
            assert!((x.hypot(y) - 0.035).abs() < 1e-9, "{p}");
            assert!((-1e-9..=0.5 + 1e-9).contains(&z), "{p}");
        }
    }
    assert!(messages[2].log_time > 0);
}
