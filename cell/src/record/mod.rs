//! Recording a run as MCAP that opens in Foxglove, and serving the same channels live over
//! Foxglove's WebSocket protocol.
//!
//! Built on Foxglove's own SDK (the `foxglove` crate, TLS and cloud features off): its well-known
//! schemas (protobuf) for frames, poses, 3-D scenes and logs, and JSON with a JSON Schema for the
//! cell's own records (mandrel angle, sync-line edges, link telegrams). Every message carries the
//! run's clock as its log time: the simulated clock on the fast simulated cell, the wall clock on
//! real ports, both counted from the run's start at [`Recorder::epoch_ns`].
//!
//! # Channels
//! | topic | schema | what |
//! |---|---|---|
//! | `/tf` | `foxglove.FrameTransform` | `world → mandrel` (rotation axis, mandrel angle) and `world → eye` |
//! | `/eye/commanded`, `/eye/simulated` | `foxglove.PoseInFrame` | the eye pose in `world` (the cell frame) |
//! | `/mandrel` | `windcell.MandrelAngle` (JSON) | commanded and true mandrel angle, degrees |
//! | `/scene/mandrel` | `foxglove.SceneUpdate` | the mandrel surface as triangles, frame `mandrel` |
//! | `/scene/fibre` | `foxglove.SceneUpdate` | desired and laid fibre as lines, frame `mandrel` |
//! | `/scene/free_fibre` | `foxglove.SceneUpdate` | the free fibre from the eye to the mandrel, frame `world` |
//! | `/sync` | `windcell.SyncEdge` (JSON) | every edge of the opto-isolated lines, as the PC drives and reads them |
//! | `/link/robot`, `/link/indexer` | `windcell.Telegram` (JSON) | raw bytes (hex) and the decoded text |
//! | `/lathe/axes` | `windcell.LatheAxes` (JSON) | the lathe winder's A, X, Y: commanded, actual and following error every interrupt |
//! | `/log` | `foxglove.Log` | the run's events in words |
//!
//! Frames: `world` is the cell frame (robot base at the origin, `z` up, millimetres converted
//! to metres as Foxglove expects), `mandrel` turns with the mandrel about the rotation axis.
//!
//! # Finalising and recovery
//! [`Recorder::finish`] writes the MCAP summary and indexes; dropping a recorder does the same, so
//! a run that stops on an error or Ctrl-C still leaves a complete file. The writer closes a chunk
//! at least every [`FLUSH_INTERVAL`] of wall time, so a process killed outright (`kill -9`) loses at
//! most that much: the chunks before it are whole, and `mcap recover` (the MCAP command-line tool)
//! or any reader that scans chunks without the summary reads them (`docs/operator.md`).

pub mod linktap;
pub mod live;
pub mod scene;

use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::Mutex;
use std::time::{Duration, Instant};

use foxglove::schemas::{
    Color, FrameTransform, LinePrimitive, Log, Point3 as FgPoint3, Pose, PoseInFrame, Quaternion,
    SceneEntity, SceneUpdate, Timestamp, TriangleListPrimitive, Vector3 as FgVector3,
};
use foxglove::{Channel, Context, McapWriteOptions, PartialMetadata, RawChannel, Schema};
use nalgebra::{Point3, UnitQuaternion, Vector3};
use serde::Serialize;

use crate::Error;

/// Longest wall time between two closed chunks.
pub const FLUSH_INTERVAL: Duration = Duration::from_secs(1);

/// Millimetres to Foxglove's metres.
const M_PER_MM: f64 = 1e-3;

/// Which device a telegram belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Device {
    /// The robot link.
    Robot,
    /// The indexer link.
    Indexer,
}

/// Which way a telegram went.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Direction {
    /// From the coordinator to the device.
    Sent,
    /// From the device to the coordinator.
    Received,
}

/// Severity of a log event.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Level {
    /// Normal progress.
    Info,
    /// Something the operator should look at.
    Warning,
    /// A fault.
    Error,
}

#[derive(Serialize)]
struct MandrelAngle {
    commanded_deg: f64,
    true_deg: f64,
}

/// One interrupt of the lathe winder (seed 000): per axis the commanded (desired) position, the
/// measured (encoder) position and the following error (commanded − actual), from part zero, in
/// degrees (A) and millimetres (X, Y). Flat fields, so Foxglove's Plot panel takes
/// `/lathe/axes.x_error_mm` directly.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, serde::Deserialize)]
pub struct LatheAxes {
    /// Interrupt number from the run's start.
    pub interrupt: u64,
    /// Commanded A, degrees.
    pub a_commanded_deg: f64,
    /// Measured A, degrees.
    pub a_actual_deg: f64,
    /// A following error, degrees.
    pub a_error_deg: f64,
    /// Commanded X, mm.
    pub x_commanded_mm: f64,
    /// Measured X, mm.
    pub x_actual_mm: f64,
    /// X following error, mm.
    pub x_error_mm: f64,
    /// Commanded Y, mm.
    pub y_commanded_mm: f64,
    /// Measured Y, mm.
    pub y_actual_mm: f64,
    /// Y following error, mm.
    pub y_error_mm: f64,
}

impl LatheAxes {
    /// The record of interrupt `interrupt` from commanded and actual (A deg, X mm, Y mm).
    pub fn new(interrupt: u64, commanded: [f64; 3], actual: [f64; 3]) -> Self {
        LatheAxes {
            interrupt,
            a_commanded_deg: commanded[0],
            a_actual_deg: actual[0],
            a_error_deg: commanded[0] - actual[0],
            x_commanded_mm: commanded[1],
            x_actual_mm: actual[1],
            x_error_mm: commanded[1] - actual[1],
            y_commanded_mm: commanded[2],
            y_actual_mm: actual[2],
            y_error_mm: commanded[2] - actual[2],
        }
    }
}

#[derive(Serialize)]
struct SyncEdge<'a> {
    line: &'a str,
    high: bool,
}

#[derive(Serialize)]
struct Telegram<'a> {
    device: Device,
    direction: Direction,
    hex: String,
    decoded: &'a str,
}

const MANDREL_SCHEMA: &str = r#"{"type":"object","title":"windcell.MandrelAngle","properties":{"commanded_deg":{"type":"number","description":"mandrel angle the step count commands, degrees"},"true_deg":{"type":"number","description":"mandrel angle the simulated motor reached, degrees"}},"required":["commanded_deg","true_deg"]}"#;
const LATHE_SCHEMA: &str = r#"{"type":"object","title":"windcell.LatheAxes","description":"lathe winder axes every interrupt, from part zero; error = commanded - actual","properties":{"interrupt":{"type":"integer"},"a_commanded_deg":{"type":"number"},"a_actual_deg":{"type":"number"},"a_error_deg":{"type":"number"},"x_commanded_mm":{"type":"number"},"x_actual_mm":{"type":"number"},"x_error_mm":{"type":"number"},"y_commanded_mm":{"type":"number"},"y_actual_mm":{"type":"number"},"y_error_mm":{"type":"number"}},"required":["interrupt","a_commanded_deg","a_actual_deg","a_error_deg","x_commanded_mm","x_actual_mm","x_error_mm","y_commanded_mm","y_actual_mm","y_error_mm"]}"#;
const SYNC_SCHEMA: &str = r#"{"type":"object","title":"windcell.SyncEdge","properties":{"line":{"type":"string","description":"start, in_position or e_stop"},"high":{"type":"boolean"}},"required":["line","high"]}"#;
const TELEGRAM_SCHEMA: &str = r#"{"type":"object","title":"windcell.Telegram","properties":{"device":{"type":"string","enum":["robot","indexer"]},"direction":{"type":"string","enum":["sent","received"]},"hex":{"type":"string","description":"the bytes on the wire, two hex digits each"},"decoded":{"type":"string","description":"the telegram or command in words"}},"required":["device","direction","hex","decoded"]}"#;

/// The channels, created once per recorder in its own context (so two recorders in one process
/// never see each other's messages).
#[derive(Debug)]
struct Channels {
    tf: Channel<FrameTransform>,
    eye_commanded: Channel<PoseInFrame>,
    eye_simulated: Channel<PoseInFrame>,
    mandrel: Arc<RawChannel>,
    scene_mandrel: Channel<SceneUpdate>,
    scene_fibre: Channel<SceneUpdate>,
    scene_free_fibre: Channel<SceneUpdate>,
    sync: Arc<RawChannel>,
    link_robot: Arc<RawChannel>,
    link_indexer: Arc<RawChannel>,
    lathe: Arc<RawChannel>,
    log: Channel<Log>,
}

impl Channels {
    fn new(ctx: &Arc<Context>) -> Result<Self, foxglove::FoxgloveError> {
        let json = |topic: &str, name: &str, schema: &'static str| {
            foxglove::ChannelBuilder::new(topic)
                .context(ctx)
                .message_encoding("json")
                .schema(Schema::new(name, "jsonschema", schema.as_bytes()))
                .build_raw()
        };
        let typed = |topic: &str| foxglove::ChannelBuilder::new(topic).context(ctx);
        Ok(Channels {
            tf: typed("/tf").build(),
            eye_commanded: typed("/eye/commanded").build(),
            eye_simulated: typed("/eye/simulated").build(),
            mandrel: json("/mandrel", "windcell.MandrelAngle", MANDREL_SCHEMA)?,
            scene_mandrel: typed("/scene/mandrel").build(),
            scene_fibre: typed("/scene/fibre").build(),
            scene_free_fibre: typed("/scene/free_fibre").build(),
            sync: json("/sync", "windcell.SyncEdge", SYNC_SCHEMA)?,
            link_robot: json("/link/robot", "windcell.Telegram", TELEGRAM_SCHEMA)?,
            link_indexer: json("/link/indexer", "windcell.Telegram", TELEGRAM_SCHEMA)?,
            lathe: json("/lathe/axes", "windcell.LatheAxes", LATHE_SCHEMA)?,
            log: typed("/log").build(),
        })
    }
}

/// Where the messages go: an MCAP file, a live WebSocket server, or both.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Sinks {
    /// The MCAP file to write (created or replaced).
    pub mcap: Option<PathBuf>,
    /// The address to serve Foxglove's WebSocket protocol on (`127.0.0.1:8765` by default in the
    /// CLI; loopback unless the operator names another).
    pub live: Option<(String, u16)>,
}

/// A recording of one run.
pub struct Recorder {
    ctx: Arc<Context>,
    channels: Arc<Channels>,
    mcap: Mutex<Option<(PathBuf, foxglove::McapWriterHandle<BufWriter<File>>)>>,
    live: Option<foxglove::WebSocketServerHandle>,
    /// The operator's end of the live server (`live::Front`).
    front: Option<live::Front>,
    /// The newest state, for viewers that join late (kept only when serving live).
    latest: Option<Arc<Mutex<live::Latest>>>,
    /// The mandrel's rotation axis foot (cell frame, mm) and the drive's steps per degree, for
    /// the positions a serial indexer reports ([`Recorder::set_mandrel_axis`]).
    axis: Mutex<Option<(Vector3<f64>, f64)>>,
    epoch_ns: u64,
    last_flush: Mutex<Instant>,
}

impl std::fmt::Debug for Recorder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Recorder")
            .field("epoch_ns", &self.epoch_ns)
            .field("live", &self.live.is_some())
            .finish_non_exhaustive()
    }
}

fn record_error(path: &Path, error: impl std::fmt::Display) -> Error {
    Error::Record {
        path: path.to_path_buf(),
        message: error.to_string(),
    }
}

impl Recorder {
    /// Opens the sinks. `epoch_ns` is the run's time zero (nanoseconds since the Unix epoch);
    /// every message's log time is `epoch_ns` plus its run time.
    pub fn open(sinks: &Sinks, epoch_ns: u64) -> Result<Self, Error> {
        let ctx = Context::new();
        let channels =
            Arc::new(Channels::new(&ctx).map_err(|e| record_error(Path::new("(channels)"), e))?);
        let mcap = match &sinks.mcap {
            Some(path) => {
                let file = File::create(path).map_err(|e| record_error(path, e))?;
                let options = McapWriteOptions::new()
                    .chunk_size(Some(256 * 1024))
                    .compression(Some(foxglove::McapCompression::Lz4));
                let handle = foxglove::McapWriter::with_options(options)
                    .context(&ctx)
                    .create(BufWriter::new(file))
                    .map_err(|e| record_error(path, e))?;
                Some((path.clone(), handle))
            }
            None => None,
        };
        let (live, front, latest) = match &sinks.live {
            Some((host, port)) => {
                let place = format!("{host}:{port}");
                let latest = Arc::new(Mutex::new(live::Latest::default()));
                // The SDK's server on a loopback port behind the front, which listens where the
                // operator asked (live.rs).
                let server = foxglove::WebSocketServer::new()
                    .name("windcell")
                    .bind("127.0.0.1", 0)
                    .context(&ctx)
                    .listener(Arc::new(live::LateJoin {
                        latest: latest.clone(),
                        channels: channels.clone(),
                    }))
                    .start_blocking()
                    .map_err(|e| record_error(Path::new(&place), e))?;
                let front = live::Front::start(host, *port, server.port())
                    .map_err(|e| record_error(Path::new(&place), e))?;
                (Some(server), Some(front), Some(latest))
            }
            None => (None, None, None),
        };
        Ok(Recorder {
            ctx,
            channels,
            mcap: Mutex::new(mcap),
            live,
            front,
            latest,
            axis: Mutex::new(None),
            epoch_ns,
            last_flush: Mutex::new(Instant::now()),
        })
    }

    /// The run's time zero, nanoseconds since the Unix epoch.
    pub fn epoch_ns(&self) -> u64 {
        self.epoch_ns
    }

    /// The live server's port (useful when the operator asked for port 0), if serving.
    pub fn live_port(&self) -> Option<u16> {
        self.front.as_ref().map(live::Front::port)
    }

    /// The context the channels live in (for tests that attach their own sink).
    pub fn context(&self) -> &Arc<Context> {
        &self.ctx
    }

    fn meta(&self, t_s: f64) -> PartialMetadata {
        PartialMetadata::with_log_time(self.time_ns(t_s))
    }

    fn time_ns(&self, t_s: f64) -> u64 {
        let ns = (t_s.max(0.0) * 1e9).round();
        self.epoch_ns
            .saturating_add(if ns.is_finite() { ns as u64 } else { 0 })
    }

    fn stamp(&self, t_s: f64) -> Timestamp {
        let ns = self.time_ns(t_s);
        Timestamp::new((ns / 1_000_000_000) as u32, (ns % 1_000_000_000) as u32)
    }

    /// Keeps the newest state for viewers that join late (only when serving live).
    fn keep(&self, f: impl FnOnce(&mut live::Latest)) {
        if let Some(latest) = &self.latest {
            f(&mut latest.lock().unwrap_or_else(|p| p.into_inner()));
        }
    }

    /// Logs a transform on `/tf` and keeps it as its child frame's newest.
    fn transform(&self, t_s: f64, tf: FrameTransform) {
        self.channels.tf.log_with_meta(&tf, self.meta(t_s));
        let ns = self.time_ns(t_s);
        self.keep(|l| {
            l.tf.insert(tf.child_frame_id.clone(), (tf, ns));
        });
    }

    /// Closes a chunk when the last one is older than [`FLUSH_INTERVAL`].
    fn maybe_flush(&self) {
        let mut last = self.last_flush.lock().unwrap_or_else(|p| p.into_inner());
        if last.elapsed() >= FLUSH_INTERVAL {
            if let Some((_, handle)) = self.mcap.lock().unwrap_or_else(|p| p.into_inner()).as_ref()
            {
                // A failed flush shows again at finish(), which reports it.
                let _ = handle.flush();
            }
            *last = Instant::now();
        }
    }

    /// The mandrel frame at run time `t_s`: `world → mandrel` is the rotation axis's foot
    /// `axis_origin_mm` (cell frame) turned by `mandrel_rad` about `z` (see `paths::plan`).
    pub fn mandrel_frame(&self, t_s: f64, axis_origin_mm: &Vector3<f64>, mandrel_rad: f64) {
        let q = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), mandrel_rad);
        self.transform(
            t_s,
            FrameTransform {
                timestamp: Some(self.stamp(t_s)),
                parent_frame_id: "world".into(),
                child_frame_id: "mandrel".into(),
                translation: Some(vector(axis_origin_mm)),
                rotation: Some(quaternion(&q)),
            },
        );
        self.maybe_flush();
    }

    /// Where the mandrel's rotation axis stands (its foot in the cell frame) and the drive's steps
    /// per degree: what turns an indexer's reported position into `world → mandrel`.
    pub fn set_mandrel_axis(&self, axis_origin_mm: Vector3<f64>, steps_per_deg: f64) {
        *self.axis.lock().unwrap_or_else(|p| p.into_inner()) =
            Some((axis_origin_mm, steps_per_deg));
    }

    /// The mandrel angle an indexer reported (degrees), as `world → mandrel` (nothing before
    /// [`Recorder::set_mandrel_axis`]).
    pub fn mandrel_reported_deg(&self, t_s: f64, mandrel_deg: f64) {
        let axis = *self.axis.lock().unwrap_or_else(|p| p.into_inner());
        if let Some((origin, _)) = axis
            && mandrel_deg.is_finite()
        {
            self.mandrel_frame(t_s, &origin, mandrel_deg.to_radians());
        }
    }

    /// The step counter an indexer reported, as `world → mandrel`.
    pub fn mandrel_reported_steps(&self, t_s: f64, steps: i64) {
        let axis = *self.axis.lock().unwrap_or_else(|p| p.into_inner());
        if let Some((_, steps_per_deg)) = axis
            && steps_per_deg > 0.0
        {
            self.mandrel_reported_deg(t_s, steps as f64 / steps_per_deg);
        }
    }

    /// The eye at run time `t_s` (cell frame), commanded or as simulated; also published as the
    /// `world → eye` transform when `simulated`.
    pub fn eye(&self, t_s: f64, eye_mm: &Point3<f64>, q: &UnitQuaternion<f64>, simulated: bool) {
        let pose = PoseInFrame {
            timestamp: Some(self.stamp(t_s)),
            frame_id: "world".into(),
            pose: Some(Pose {
                position: Some(vector(&eye_mm.coords)),
                orientation: Some(quaternion(q)),
            }),
        };
        let channel = if simulated {
            self.transform(
                t_s,
                FrameTransform {
                    timestamp: Some(self.stamp(t_s)),
                    parent_frame_id: "world".into(),
                    child_frame_id: "eye".into(),
                    translation: Some(vector(&eye_mm.coords)),
                    rotation: Some(quaternion(q)),
                },
            );
            &self.channels.eye_simulated
        } else {
            &self.channels.eye_commanded
        };
        channel.log_with_meta(&pose, self.meta(t_s));
        let ns = self.time_ns(t_s);
        self.keep(|l| {
            let slot = if simulated {
                &mut l.eye_simulated
            } else {
                &mut l.eye_commanded
            };
            *slot = Some((pose, ns));
        });
        self.maybe_flush();
    }

    /// The mandrel angle the steps command and the angle the motor really reached, radians.
    pub fn mandrel_angle(&self, t_s: f64, commanded_rad: f64, true_rad: f64) {
        let record = MandrelAngle {
            commanded_deg: commanded_rad.to_degrees(),
            true_deg: true_rad.to_degrees(),
        };
        self.json(&self.channels.mandrel, t_s, &record);
        let ns = self.time_ns(t_s);
        self.keep(|l| l.mandrel = Some((serde_json::to_vec(&record).unwrap_or_default(), ns)));
    }

    /// The mandrel surface as a triangle list in the `mandrel` frame (published once, at `t_s`).
    pub fn mandrel_surface(&self, t_s: f64, triangles: &[[Point3<f64>; 3]]) {
        let points = triangles.iter().flat_map(|t| t.iter().map(point)).collect();
        let entity = SceneEntity {
            timestamp: Some(self.stamp(t_s)),
            frame_id: "mandrel".into(),
            id: "mandrel".into(),
            frame_locked: true,
            triangles: vec![TriangleListPrimitive {
                pose: Some(identity()),
                points,
                color: Some(Color {
                    r: 0.6,
                    g: 0.6,
                    b: 0.65,
                    a: 0.8,
                }),
                ..Default::default()
            }],
            ..Default::default()
        };
        let update = SceneUpdate {
            entities: vec![entity],
            ..Default::default()
        };
        self.channels
            .scene_mandrel
            .log_with_meta(&update, self.meta(t_s));
        let ns = self.time_ns(t_s);
        self.keep(|l| live::Latest::keep_entities(&mut l.scene_mandrel, &update, ns));
        self.maybe_flush();
    }

    /// The desired and the laid fibre as lines in the `mandrel` frame (green and orange).
    pub fn fibre(&self, t_s: f64, path: &str, desired: &[Point3<f64>], laid: &[Point3<f64>]) {
        let line = |points: &[Point3<f64>], color: Color| LinePrimitive {
            r#type: foxglove::schemas::line_primitive::Type::LineStrip as i32,
            pose: Some(identity()),
            thickness: 2.0,
            scale_invariant: true,
            points: points.iter().map(point).collect(),
            color: Some(color),
            ..Default::default()
        };
        let entity = |id: String, primitive: LinePrimitive| SceneEntity {
            timestamp: Some(self.stamp(t_s)),
            frame_id: "mandrel".into(),
            id,
            frame_locked: true,
            lines: vec![primitive],
            ..Default::default()
        };
        let green = Color {
            r: 0.1,
            g: 0.8,
            b: 0.2,
            a: 1.0,
        };
        let orange = Color {
            r: 1.0,
            g: 0.5,
            b: 0.0,
            a: 1.0,
        };
        let update = SceneUpdate {
            entities: vec![
                entity(format!("{path}/desired"), line(desired, green)),
                entity(format!("{path}/laid"), line(laid, orange)),
            ],
            ..Default::default()
        };
        self.channels
            .scene_fibre
            .log_with_meta(&update, self.meta(t_s));
        let ns = self.time_ns(t_s);
        self.keep(|l| live::Latest::keep_entities(&mut l.scene_fibre, &update, ns));
        self.maybe_flush();
    }

    /// The free fibre: the tow from the eye to where it meets the mandrel, both in the cell frame
    /// (mm), as a white line in `world` (entity `free` on `/scene/free_fibre`, replaced each
    /// time).
    pub fn free_fibre(&self, t_s: f64, eye_mm: &Point3<f64>, contact_mm: &Point3<f64>) {
        let update = SceneUpdate {
            entities: vec![SceneEntity {
                timestamp: Some(self.stamp(t_s)),
                frame_id: "world".into(),
                id: "free".into(),
                lines: vec![LinePrimitive {
                    r#type: foxglove::schemas::line_primitive::Type::LineStrip as i32,
                    pose: Some(identity()),
                    thickness: 2.0,
                    scale_invariant: true,
                    points: vec![point(eye_mm), point(contact_mm)],
                    color: Some(Color {
                        r: 1.0,
                        g: 1.0,
                        b: 1.0,
                        a: 1.0,
                    }),
                    ..Default::default()
                }],
                ..Default::default()
            }],
            ..Default::default()
        };
        self.channels
            .scene_free_fibre
            .log_with_meta(&update, self.meta(t_s));
        let ns = self.time_ns(t_s);
        self.keep(|l| live::Latest::keep_entities(&mut l.scene_free_fibre, &update, ns));
        self.maybe_flush();
    }

    /// An edge of a sync line (`start`, `in_position`, `e_stop`).
    pub fn sync_edge(&self, t_s: f64, line: &str, high: bool) {
        self.json(&self.channels.sync, t_s, &SyncEdge { line, high });
    }

    /// A telegram or command line on a device link: its bytes and what it says.
    pub fn telegram(
        &self,
        t_s: f64,
        device: Device,
        direction: Direction,
        bytes: &[u8],
        decoded: &str,
    ) {
        let hex = bytes.iter().map(|b| format!("{b:02x}")).collect();
        let channel = match device {
            Device::Robot => &self.channels.link_robot,
            Device::Indexer => &self.channels.link_indexer,
        };
        self.json(
            channel,
            t_s,
            &Telegram {
                device,
                direction,
                hex,
                decoded,
            },
        );
    }

    /// The lathe winder's axes at run time `t_s` (one interrupt).
    pub fn lathe_axes(&self, t_s: f64, axes: &LatheAxes) {
        self.json(&self.channels.lathe, t_s, axes);
    }

    /// An event in words.
    pub fn log(&self, t_s: f64, level: Level, message: &str) {
        let level = match level {
            Level::Info => foxglove::schemas::log::Level::Info,
            Level::Warning => foxglove::schemas::log::Level::Warning,
            Level::Error => foxglove::schemas::log::Level::Error,
        };
        self.channels.log.log_with_meta(
            &Log {
                timestamp: Some(self.stamp(t_s)),
                level: level as i32,
                message: message.to_string(),
                name: "windcell".into(),
                ..Default::default()
            },
            self.meta(t_s),
        );
        self.maybe_flush();
    }

    fn json(&self, channel: &RawChannel, t_s: f64, value: &impl Serialize) {
        // Serialising these plain records cannot fail; an empty message would show it.
        let bytes = serde_json::to_vec(value).unwrap_or_default();
        channel.log_with_meta(&bytes, self.meta(t_s));
        self.maybe_flush();
    }

    /// Writes the MCAP summary and indexes and stops the live server. Called by `Drop` too; call
    /// it to see the error.
    pub fn finish(mut self) -> Result<(), Error> {
        self.close()
    }

    fn close(&mut self) -> Result<(), Error> {
        // The front first: no new viewer is passed to a server that is stopping.
        drop(self.front.take());
        if let Some(live) = self.live.take() {
            // The shutdown handle completes in the background; the run does not wait for it.
            drop(live.stop());
        }
        let taken = self.mcap.lock().unwrap_or_else(|p| p.into_inner()).take();
        if let Some((path, handle)) = taken {
            let writer = handle.close().map_err(|e| record_error(&path, e))?;
            let file = writer
                .into_inner()
                .map_err(|e| record_error(&path, e.error()))?;
            file.sync_all().map_err(|e| record_error(&path, e))?;
        }
        Ok(())
    }
}

impl Drop for Recorder {
    fn drop(&mut self) {
        // The error cannot be returned from drop; finish() reports it.
        let _ = self.close();
    }
}

fn vector(v: &Vector3<f64>) -> FgVector3 {
    FgVector3 {
        x: v.x * M_PER_MM,
        y: v.y * M_PER_MM,
        z: v.z * M_PER_MM,
    }
}

fn point(p: &Point3<f64>) -> FgPoint3 {
    FgPoint3 {
        x: p.x * M_PER_MM,
        y: p.y * M_PER_MM,
        z: p.z * M_PER_MM,
    }
}

fn quaternion(q: &UnitQuaternion<f64>) -> Quaternion {
    Quaternion {
        x: q.i,
        y: q.j,
        z: q.k,
        w: q.w,
    }
}

fn identity() -> Pose {
    Pose {
        position: Some(FgVector3 {
            x: 0.0,
            y: 0.0,
            z: 0.0,
        }),
        orientation: Some(Quaternion {
            x: 0.0,
            y: 0.0,
            z: 0.0,
            w: 1.0,
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use foxglove::Decode;
    use std::collections::BTreeMap;

    fn read(path: &Path) -> Vec<(String, String, String, u64, Vec<u8>)> {
        let bytes = std::fs::read(path).unwrap();
        mcap::MessageStream::new(&bytes)
            .unwrap()
            .map(|m| {
                let m = m.unwrap();
                let schema = m.channel.schema.as_ref().unwrap();
                (
                    m.channel.topic.clone(),
                    schema.name.clone(),
                    m.channel.message_encoding.clone(),
                    m.log_time,
                    m.data.into_owned(),
                )
            })
            .collect()
    }

    #[test]
    fn every_channel_is_written_with_its_schema_and_decodes() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("run.mcap");
        let epoch = 1_700_000_000_000_000_000;
        let rec = Recorder::open(
            &Sinks {
                mcap: Some(path.clone()),
                live: None,
            },
            epoch,
        )
        .unwrap();
        let q = UnitQuaternion::from_euler_angles(0.1, 0.2, 0.3);
        rec.mandrel_frame(0.5, &Vector3::new(800.0, 0.0, 300.0), 1.0);
        rec.eye(0.5, &Point3::new(700.0, 10.0, 320.0), &q, false);
        rec.eye(0.75, &Point3::new(701.0, 10.0, 320.0), &q, true);
        rec.mandrel_angle(0.75, 1.0, 0.999);
        rec.mandrel_surface(
            0.0,
            &[[
                Point3::new(0.0, 0.0, 0.0),
                Point3::new(10.0, 0.0, 0.0),
                Point3::new(0.0, 10.0, 0.0),
            ]],
        );
        rec.fibre(
            1.0,
            "CYL_1",
            &[Point3::origin(), Point3::new(0.0, 0.0, 10.0)],
            &[Point3::origin()],
        );
        rec.sync_edge(1.25, "start", true);
        rec.telegram(1.5, Device::Robot, Direction::Sent, &[0x05], "ENQ");
        rec.telegram(1.5, Device::Indexer, Direction::Received, b"*R", "ready");
        rec.log(2.0, Level::Warning, "stopped at segment 7");
        rec.lathe_axes(
            2.5,
            &LatheAxes::new(500, [90.0, 12.5, -3.0], [89.5, 12.25, -3.0]),
        );
        rec.finish().unwrap();

        let messages = read(&path);
        let mut topics: BTreeMap<String, (String, String, usize)> = BTreeMap::new();
        for (topic, schema, encoding, _, _) in &messages {
            topics
                .entry(topic.clone())
                .or_insert((schema.clone(), encoding.clone(), 0))
                .2 += 1;
        }
        let expect = [
            ("/tf", "foxglove.FrameTransform", "protobuf", 2),
            ("/eye/commanded", "foxglove.PoseInFrame", "protobuf", 1),
            ("/eye/simulated", "foxglove.PoseInFrame", "protobuf", 1),
            ("/mandrel", "windcell.MandrelAngle", "json", 1),
            ("/scene/mandrel", "foxglove.SceneUpdate", "protobuf", 1),
            ("/scene/fibre", "foxglove.SceneUpdate", "protobuf", 1),
            ("/sync", "windcell.SyncEdge", "json", 1),
            ("/link/robot", "windcell.Telegram", "json", 1),
            ("/link/indexer", "windcell.Telegram", "json", 1),
            ("/log", "foxglove.Log", "protobuf", 1),
            ("/lathe/axes", "windcell.LatheAxes", "json", 1),
        ];
        assert_eq!(topics.len(), expect.len(), "{topics:?}");
        for (topic, schema, encoding, count) in expect {
            assert_eq!(
                topics.get(topic),
                Some(&(schema.to_string(), encoding.to_string(), count)),
                "{topic}"
            );
        }
        for (topic, _, encoding, log_time, data) in &messages {
            if encoding == "json" {
                let v: serde_json::Value = serde_json::from_slice(data).unwrap();
                assert!(v.is_object(), "{topic}");
            }
            match topic.as_str() {
                "/eye/commanded" => {
                    let p = PoseInFrame::decode(&data[..]).unwrap();
                    let pos = p.pose.unwrap().position.unwrap();
                    assert!((pos.x - 0.7).abs() < 1e-12 && (pos.z - 0.32).abs() < 1e-12);
                    assert_eq!(*log_time, epoch + 500_000_000);
                }
                "/mandrel" => {
                    let v: serde_json::Value = serde_json::from_slice(data).unwrap();
                    let deg = v["commanded_deg"].as_f64().unwrap();
                    assert!((deg - 1f64.to_degrees()).abs() < 1e-9);
                }
                "/lathe/axes" => {
                    let a: LatheAxes = serde_json::from_slice(data).unwrap();
                    assert_eq!(a.interrupt, 500);
                    assert_eq!(
                        (a.a_error_deg, a.x_error_mm, a.y_error_mm),
                        (0.5, 0.25, 0.0)
                    );
                    assert_eq!(*log_time, epoch + 2_500_000_000);
                }
                "/link/robot" => {
                    let v: serde_json::Value = serde_json::from_slice(data).unwrap();
                    assert_eq!(v["hex"], "05");
                    assert_eq!(v["direction"], "sent");
                }
                "/log" => {
                    let l = Log::decode(&data[..]).unwrap();
                    assert_eq!(l.message, "stopped at segment 7");
                    assert_eq!(l.level, foxglove::schemas::log::Level::Warning as i32);
                }
                "/scene/mandrel" => {
                    let s = SceneUpdate::decode(&data[..]).unwrap();
                    assert_eq!(s.entities[0].triangles[0].points.len(), 3);
                }
                _ => {}
            }
        }
    }

    #[test]
    fn a_dropped_recorder_still_finalises_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("dropped.mcap");
        {
            let rec = Recorder::open(
                &Sinks {
                    mcap: Some(path.clone()),
                    live: None,
                },
                0,
            )
            .unwrap();
            rec.log(0.0, Level::Error, "device fault");
            // Dropped here, as on an early return with `?`.
        }
        let bytes = std::fs::read(&path).unwrap();
        // A finalised MCAP ends with the magic after the footer, and its summary is readable.
        assert!(bytes.ends_with(b"\x89MCAP0\r\n"));
        let summary = mcap::Summary::read(&bytes).unwrap().expect("a summary");
        assert_eq!(summary.stats.unwrap().message_count, 1);
    }

    #[test]
    fn two_recorders_do_not_see_each_others_messages() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a.mcap"), dir.path().join("b.mcap"));
        let open = |p: &PathBuf| {
            Recorder::open(
                &Sinks {
                    mcap: Some(p.clone()),
                    live: None,
                },
                0,
            )
            .unwrap()
        };
        let (ra, rb) = (open(&a), open(&b));
        ra.log(0.0, Level::Info, "a");
        rb.log(0.0, Level::Info, "b");
        rb.log(0.1, Level::Info, "b");
        ra.finish().unwrap();
        rb.finish().unwrap();
        assert_eq!(read(&a).len(), 1);
        assert_eq!(read(&b).len(), 2);
    }

    /// A client speaking Foxglove's WebSocket protocol subscribes to `/eye/simulated` on the live
    /// server and receives the poses logged after it subscribed (binary `MessageData`: opcode 1,
    /// subscription id, log time, protobuf payload).
    #[test]
    fn a_live_client_receives_eye_poses() {
        use tungstenite::Message;
        use tungstenite::client::IntoClientRequest;
        use tungstenite::http::HeaderValue;

        let rec = Recorder::open(
            &Sinks {
                mcap: None,
                live: Some(("127.0.0.1".into(), 0)),
            },
            0,
        )
        .unwrap();
        let port = rec.live_port().unwrap();
        let mut request = format!("ws://127.0.0.1:{port}")
            .into_client_request()
            .unwrap();
        request.headers_mut().insert(
            "Sec-WebSocket-Protocol",
            HeaderValue::from_static("foxglove.sdk.v1"),
        );
        let stream = std::net::TcpStream::connect(("127.0.0.1", port)).unwrap();
        stream
            .set_read_timeout(Some(Duration::from_secs(5)))
            .unwrap();
        let (mut ws, _) = tungstenite::client(request, stream).unwrap();
        // Read the advertisements until the eye channel shows up.
        let mut channel_id = None;
        while channel_id.is_none() {
            if let Message::Text(text) = ws.read().unwrap() {
                let v: serde_json::Value = serde_json::from_str(text.as_str()).unwrap();
                if v["op"] == "advertise" {
                    for ch in v["channels"].as_array().unwrap() {
                        if ch["topic"] == "/eye/simulated" {
                            assert_eq!(ch["schemaName"], "foxglove.PoseInFrame");
                            channel_id = ch["id"].as_u64();
                        }
                    }
                }
            }
        }
        let subscribe = serde_json::json!({
            "op": "subscribe",
            "subscriptions": [{"id": 42, "channelId": channel_id.unwrap()}]
        });
        ws.send(Message::Text(subscribe.to_string().into()))
            .unwrap();
        // The subscription takes effect asynchronously: log until a pose arrives.
        let q = UnitQuaternion::identity();
        let mut received = None;
        for k in 0..500 {
            rec.eye(
                k as f64 * 0.01,
                &Point3::new(700.0, 0.0, 300.0 + k as f64),
                &q,
                true,
            );
            ws.get_mut()
                .set_read_timeout(Some(Duration::from_millis(10)))
                .unwrap();
            match ws.read() {
                Ok(Message::Binary(data)) if data.first() == Some(&1) => {
                    received = Some(data);
                    break;
                }
                _ => {}
            }
        }
        let data = received.expect("no eye pose reached the client");
        assert_eq!(u32::from_le_bytes(data[1..5].try_into().unwrap()), 42);
        let pose = PoseInFrame::decode(&data[13..]).unwrap();
        assert_eq!(pose.frame_id, "world");
        assert!((pose.pose.unwrap().position.unwrap().x - 0.7).abs() < 1e-12);
        rec.finish().unwrap();
    }
}
