//! The check's scene for Foxglove's 3-D panel: plain MCAP, one `foxglove.SceneUpdate` (JSON
//! encoding, JSON-schema) per segment end on `/check/scene`, in the mandrel frame (`frame_id`
//! `mandrel`), metres as Foxglove expects.
//!
//! The first message holds what does not move: the mandrel's sections at every tangent point, the
//! spine, each path's eye path and tow lines, and every finding as a red sphere. Each later
//! message replaces the `pose` entity: the tow line, the eye mechanism and the arm's links at that
//! segment end, at the plan's time (paths follow each other with a one-second gap).

use std::collections::BTreeMap;
use std::io::Cursor;

use nalgebra::{Point3, Vector3};
use serde_json::{Value, json};

use crate::Error;
use crate::plan::check::Checked;

/// The topic.
pub const TOPIC: &str = "/check/scene";

/// A compact JSON schema of the `foxglove.SceneUpdate` fields written here.
const SCHEMA: &str = r#"{"title":"foxglove.SceneUpdate","type":"object","properties":{"deletions":{"type":"array"},"entities":{"type":"array","items":{"type":"object","properties":{"timestamp":{"type":"object"},"frame_id":{"type":"string"},"id":{"type":"string"},"lifetime":{"type":"object"},"frame_locked":{"type":"boolean"},"metadata":{"type":"array"},"arrows":{"type":"array"},"cubes":{"type":"array"},"spheres":{"type":"array"},"cylinders":{"type":"array"},"lines":{"type":"array"},"triangles":{"type":"array"},"texts":{"type":"array"},"models":{"type":"array"}}}}}}"#;

fn m(p: &Point3<f64>) -> Value {
    json!({"x": p.x / 1000.0, "y": p.y / 1000.0, "z": p.z / 1000.0})
}

fn colour(r: f64, g: f64, b: f64, a: f64) -> Value {
    json!({"r": r, "g": g, "b": b, "a": a})
}

fn identity() -> Value {
    json!({"position": {"x": 0.0, "y": 0.0, "z": 0.0}, "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}})
}

fn time(ns: u64) -> Value {
    json!({"sec": ns / 1_000_000_000, "nsec": ns % 1_000_000_000})
}

/// A line list (pairs of points) of one colour and thickness (px).
fn lines(points: Vec<Value>, c: Value, thickness_px: f64) -> Value {
    json!({
        "type": 2, "pose": identity(), "thickness": thickness_px, "scale_invariant": true,
        "points": points, "color": c, "colors": [], "indices": []
    })
}

fn entity(id: &str, ns: u64, lines_: Vec<Value>, spheres: Vec<Value>) -> Value {
    json!({
        "timestamp": time(ns), "frame_id": "mandrel", "id": id, "lifetime": time(0),
        "frame_locked": false, "metadata": [], "arrows": [], "cubes": [], "spheres": spheres,
        "cylinders": [], "lines": lines_, "triangles": [], "texts": [], "models": []
    })
}

fn to_mandrel(checked: &Checked, p: &Point3<f64>, phi: f64) -> Point3<f64> {
    checked.to_mandrel(p, phi)
}

/// The scene as MCAP bytes.
pub fn mcap(checked: &Checked) -> Result<Vec<u8>, Error> {
    let fail = |e: mcap::McapError| Error::Record {
        path: std::path::PathBuf::from("(check scene)"),
        message: e.to_string(),
    };
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
    let tube = &checked.tube;
    let r = tube.radius_mm();
    // What does not move.
    let mut sections = Vec::new();
    let mut tows = Vec::new();
    let mut eyes = Vec::new();
    for p in &checked.plan.paths {
        let poses: Vec<&paths::Pose> = std::iter::once(&p.plan.start)
            .chain(p.plan.segments.iter().map(|s| &s.pose))
            .collect();
        for pair in poses.windows(2) {
            eyes.push(m(&pair[0].eye_mandrel_mm));
            eyes.push(m(&pair[1].eye_mandrel_mm));
        }
        for pose in &poses {
            tows.push(m(&pose.tangent_point_mm));
            tows.push(m(&pose.eye_mandrel_mm));
            let z = pose.tangent_point_mm.z;
            let c = tube.section(z).centroid_mm;
            for i in 0..24 {
                let a = |k: usize| {
                    let t = std::f64::consts::TAU * k as f64 / 24.0;
                    Point3::new(c.x + r * t.cos(), c.y + r * t.sin(), z)
                };
                sections.push(m(&a(i)));
                sections.push(m(&a(i + 1)));
            }
        }
    }
    let findings: Vec<Value> = checked
        .report
        .findings
        .iter()
        .map(|f| {
            let p = to_mandrel(checked, &f.eye_mm, f.mandrel_rad);
            json!({"pose": {"position": m(&p), "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}},
                   "size": {"x": 0.015, "y": 0.015, "z": 0.015}, "color": colour(0.84, 0.15, 0.16, 1.0)})
        })
        .collect();
    let first = json!({"deletions": [], "entities": [
        entity("mandrel", 0, vec![lines(sections, colour(0.6, 0.6, 0.6, 0.6), 1.0)], vec![]),
        entity("paths", 0, vec![lines(eyes, colour(0.12, 0.47, 0.71, 1.0), 2.0),
                                lines(tows, colour(1.0, 0.5, 0.05, 0.6), 1.0)], vec![]),
        entity("findings", 0, vec![], findings),
    ]});
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
    write(&mut writer, 0, &first)?;
    // The moving pose at every segment end.
    let mut offset_s = 0.0;
    for p in &checked.plan.paths {
        let mut t = 0.0;
        let poses = std::iter::once((&p.plan.start, 0.0))
            .chain(p.plan.segments.iter().map(|s| (&s.pose, s.duration_s)));
        for (pose, duration) in poses {
            t += duration;
            let phi = pose.mandrel_rad;
            let axis = (pose.tangent_point_mm - pose.eye_mandrel_mm).normalize();
            let mut parts = vec![
                m(&pose.tangent_point_mm),
                m(&pose.eye_mandrel_mm),
                m(&pose.eye_mandrel_mm),
                m(&(pose.eye_mandrel_mm - axis * checked.eye.length_mm)),
            ];
            let joints = match pose.joints {
                paths::ArmJoints::SixAxis { joints, .. } => Some(joints),
                paths::ArmJoints::Irb62(_) => None,
            };
            for link in checked.links_at(
                &pose.eye_mm,
                &(pose.wrist_q * Vector3::x()),
                joints.as_ref(),
            ) {
                parts.push(m(&to_mandrel(checked, &link.a, phi)));
                parts.push(m(&to_mandrel(checked, &link.b, phi)));
            }
            let ns = ((offset_s + t) * 1e9).round().max(0.0) as u64;
            let update = json!({"deletions": [], "entities": [
                entity("pose", ns, vec![lines(parts, colour(0.3, 0.3, 0.3, 1.0), 3.0)], vec![])
            ]});
            write(&mut writer, ns, &update)?;
        }
        offset_s += t + 1.0;
    }
    writer.finish().map_err(fail)?;
    Ok(writer.into_inner().into_inner())
}
