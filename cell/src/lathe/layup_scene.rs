//! The layup in 3-D for Foxglove (`windcell lathe plan … --record FILE.mcap`): plain MCAP, one
//! `foxglove.SceneUpdate` (JSON encoding, JSON schema, as `cell::record::scene`) per layer on
//! `/lathe/layup`, in the mandrel's frame (`frame_id` `mandrel`, z along the mandrel from its
//! start, metres): first the mandrel (rings every tenth of its length and its meridians), then each
//! layer's tow path as a line list in its colour, logged at the plan's time when the layer starts,
//! so that playing the file lays the layers one after the other.
//!
//! A move's tow lies on the surface at the carriage's position and the mandrel's angle (tubes,
//! cones and noses; on a vessel's domes the eye's path, as in [`crate::lathe::layup_svg`]); a move is cut
//! into pieces of at most 10° of mandrel turn so that the helix is drawn round.

use std::collections::BTreeMap;
use std::io::Cursor;

use paths::motion::{LayerMark, MotionSink, Move, MoveKind};
use paths::vessel::{Job, Plan};
use serde_json::{Value, json};

use crate::Error;
use crate::lathe::layup_svg::radius_at;

/// The topic.
pub const TOPIC: &str = "/lathe/layup";

const SCHEMA: &str = r#"{"title":"foxglove.SceneUpdate","type":"object","properties":{"deletions":{"type":"array"},"entities":{"type":"array"}}}"#;

const COLOURS: [(f64, f64, f64); 8] = [
    (0.12, 0.47, 0.71),
    (0.84, 0.15, 0.16),
    (0.17, 0.63, 0.17),
    (0.58, 0.40, 0.74),
    (1.0, 0.5, 0.05),
    (0.09, 0.75, 0.81),
    (0.55, 0.34, 0.29),
    (0.89, 0.47, 0.76),
];

fn time(ns: u64) -> Value {
    json!({"sec": ns / 1_000_000_000, "nsec": ns % 1_000_000_000})
}

fn line_list(points: Vec<Value>, (r, g, b): (f64, f64, f64), a: f64, px: f64) -> Value {
    json!({
        "type": 2, "thickness": px, "scale_invariant": true, "points": points,
        "color": {"r": r, "g": g, "b": b, "a": a}, "colors": [], "indices": [],
        "pose": {"position": {"x": 0.0, "y": 0.0, "z": 0.0},
                 "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}
    })
}

fn entity(id: &str, ns: u64, lines: Vec<Value>) -> Value {
    json!({
        "timestamp": time(ns), "frame_id": "mandrel", "id": id, "lifetime": time(0),
        "frame_locked": false, "metadata": [], "arrows": [], "cubes": [], "spheres": [],
        "cylinders": [], "lines": lines, "triangles": [], "texts": [], "models": []
    })
}

/// A point on the surface at `x_mm` from the mandrel's start and mandrel angle `deg`, metres.
fn surface(job: &Job, x_mm: f64, deg: f64) -> Value {
    let r = radius_at(&job.mandrel, x_mm);
    let (s, c) = deg.to_radians().sin_cos();
    json!({"x": r * c / 1000.0, "y": r * s / 1000.0, "z": x_mm / 1000.0})
}

#[derive(Default)]
struct Layers {
    marks: Vec<LayerMark>,
    moves: Vec<Vec<Move>>,
    starts_s: Vec<f64>,
    last: Option<Move>,
    before: Vec<Option<Move>>,
    t_s: f64,
}

impl MotionSink for Layers {
    type Error = std::convert::Infallible;
    fn layer(&mut self, mark: &LayerMark) -> Result<(), Self::Error> {
        self.marks.push(*mark);
        self.moves.push(Vec::new());
        self.starts_s.push(self.t_s);
        self.before.push(self.last);
        Ok(())
    }
    fn motion(&mut self, m: &Move) -> Result<(), Self::Error> {
        self.t_s += m.duration_s;
        if let Some(l) = self.moves.last_mut() {
            l.push(*m);
        }
        self.last = Some(*m);
        Ok(())
    }
}

/// The scene as MCAP bytes; `start_mm` is where the mandrel starts in the planner's frame.
pub fn mcap(job: &Job, plan: &Plan, start_mm: f64) -> Result<Vec<u8>, Error> {
    let fail = |e: mcap::McapError| Error::Record {
        path: std::path::PathBuf::from("(layup scene)"),
        message: e.to_string(),
    };
    let mut layers = Layers::default();
    let Ok(()) = plan.emit(&mut layers);
    let length = -2.0 * start_mm;
    let mut writer = mcap::WriteOptions::new()
        .compression(None)
        .create(Cursor::new(Vec::new()))
        .map_err(fail)?;
    let schema = writer
        .add_schema("foxglove.SceneUpdate", "jsonschema", SCHEMA.as_bytes())
        .map_err(fail)?;
    let channel = writer
        .add_channel(schema, TOPIC, "json", &BTreeMap::new())
        .map_err(fail)?;
    let mut sequence = 0u32;
    let mut write = |writer: &mut mcap::Writer<Cursor<Vec<u8>>>, ns: u64, value: &Value| {
        sequence += 1;
        writer
            .write_to_known_channel(
                &mcap::records::MessageHeader {
                    channel_id: channel,
                    sequence,
                    log_time: ns,
                    publish_time: ns,
                },
                value.to_string().as_bytes(),
            )
            .map_err(fail)
    };
    // The mandrel: rings every tenth of its length, 12 meridians.
    let mut frame = Vec::new();
    for k in 0..=10 {
        let x = length * k as f64 / 10.0;
        for i in 0..48 {
            frame.push(surface(job, x, 7.5 * i as f64));
            frame.push(surface(job, x, 7.5 * (i + 1) as f64));
        }
    }
    for i in 0..12 {
        for k in 0..40 {
            frame.push(surface(job, length * k as f64 / 40.0, 30.0 * i as f64));
            frame.push(surface(
                job,
                length * (k + 1) as f64 / 40.0,
                30.0 * i as f64,
            ));
        }
    }
    let first = json!({"deletions": [], "entities": [
        entity("mandrel", 0, vec![line_list(frame, (0.6, 0.6, 0.6), 0.5, 1.0)])
    ]});
    write(&mut writer, 0, &first)?;
    for (i, moves) in layers.moves.iter().enumerate() {
        let mut points = Vec::new();
        let mut prev = layers.before[i].map_or(plan.start(), |m| m.to);
        for m in moves {
            let (x0, a0) = (prev.carriage_mm - start_mm, prev.mandrel_deg);
            let (x1, a1) = (m.to.carriage_mm - start_mm, m.to.mandrel_deg);
            prev = m.to;
            if m.kind == MoveKind::Rapid {
                continue;
            }
            let pieces = ((a1 - a0).abs() / 10.0).ceil().max(1.0) as usize;
            for k in 0..pieces {
                let f0 = k as f64 / pieces as f64;
                let f1 = (k + 1) as f64 / pieces as f64;
                points.push(surface(job, x0 + (x1 - x0) * f0, a0 + (a1 - a0) * f0));
                points.push(surface(job, x0 + (x1 - x0) * f1, a0 + (a1 - a0) * f1));
            }
        }
        let ns = (layers.starts_s[i] * 1e9).round().max(0.0) as u64;
        let id = format!("layer {}", layers.marks[i].number);
        let update = json!({"deletions": [], "entities": [
            entity(&id, ns, vec![line_list(points, COLOURS[i % COLOURS.len()], 0.8, 1.5)])
        ]});
        write(&mut writer, ns, &update)?;
    }
    writer.finish().map_err(fail)?;
    Ok(writer.into_inner().into_inner())
}
