//! The live server's two additions to Foxglove's SDK server: what a viewer that joins late is
//! sent at once, and the subprotocol names Foxglove clients offer.
//!
//! **Late join.** The scene (`/scene/mandrel`, `/scene/fibre`) is published when it changes, which
//! may be once at the run's start, and a viewer joining later would never see it. [`Latest`] keeps
//! the newest message of every topic that describes the cell's state (each transform by child
//! frame, each scene entity by id (`/scene/free_fibre` too), the eye poses, the mandrel angle); the server's listener
//! ([`LateJoin`]) sends them to a client the moment it subscribes to their channel, to that
//! client only (the SDK's per-sink log), before the next live message.
//!
//! **Subprotocols.** The SDK's server negotiates `foxglove.sdk.v1` (and `v1.1`); Foxglove clients
//! built on the older `foxglove/ws-protocol` offer `foxglove.websocket.v1`, the same protocol under
//! its earlier name (its spec, `docs/spec.md` of `foxglove/ws-protocol`: the same `serverInfo`,
//! `advertise`, `subscribe` and binary `MessageData` opcode 1). [`Front`] listens on the operator's
//! address and passes each connection to the SDK's server on a loopback port; when a client
//! offers only `foxglove.websocket.v1`, the front renames it to `foxglove.sdk.v1` in the upgrade
//! request and back in the server's answer, and passes every later byte unchanged. The WebSocket
//! accept key depends only on the client's key (RFC 6455 §4.2.2), so the rename keeps the
//! handshake valid.

use std::collections::BTreeMap;
use std::io::{self, Read, Write};
use std::net::{Shutdown, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use foxglove::PartialMetadata;
use foxglove::schemas::{FrameTransform, PoseInFrame, SceneEntity, SceneUpdate};
use foxglove::websocket::{ChannelView, Client, ServerListener};

/// The subprotocol name Foxglove's SDK server negotiates.
pub const SDK_SUBPROTOCOL: &str = "foxglove.sdk.v1";
/// The subprotocol name of `foxglove/ws-protocol` clients, accepted as [`SDK_SUBPROTOCOL`].
pub const WS_PROTOCOL_SUBPROTOCOL: &str = "foxglove.websocket.v1";
/// Most connections the front passes at once (two threads each).
pub const MAX_CONNECTIONS: usize = 16;
/// Longest HTTP upgrade request or answer the front reads, bytes.
const MAX_HEAD_BYTES: usize = 16 * 1024;
/// How long the front waits for an upgrade request or answer.
const HEAD_TIMEOUT: Duration = Duration::from_secs(5);

/// A message with its log time, nanoseconds since the Unix epoch.
type Stamped<T> = (T, u64);

/// The newest state of the cell as the live channels last said it.
#[derive(Debug, Default)]
pub struct Latest {
    /// Each transform by its child frame.
    pub tf: BTreeMap<String, Stamped<FrameTransform>>,
    /// The commanded eye pose.
    pub eye_commanded: Option<Stamped<PoseInFrame>>,
    /// The simulated (or reported) eye pose.
    pub eye_simulated: Option<Stamped<PoseInFrame>>,
    /// The mandrel angle record (JSON).
    pub mandrel: Option<Stamped<Vec<u8>>>,
    /// The mandrel surface's entities by id.
    pub scene_mandrel: BTreeMap<String, Stamped<SceneEntity>>,
    /// The fibre entities (desired and laid, per path) by id.
    pub scene_fibre: BTreeMap<String, Stamped<SceneEntity>>,
    /// The free fibre's entity.
    pub scene_free_fibre: BTreeMap<String, Stamped<SceneEntity>>,
}

impl Latest {
    /// Keeps each entity of `update` as the newest of its id (an entity of the same id replaces
    /// the old one, as in Foxglove's 3-D panel).
    pub fn keep_entities(
        map: &mut BTreeMap<String, Stamped<SceneEntity>>,
        update: &SceneUpdate,
        log_time_ns: u64,
    ) {
        for e in &update.entities {
            map.insert(e.id.clone(), (e.clone(), log_time_ns));
        }
    }
}

/// The server's listener: a new subscriber of a state topic gets its newest messages at once.
#[derive(Debug)]
pub struct LateJoin {
    /// The newest state.
    pub latest: Arc<Mutex<Latest>>,
    /// Where it is sent.
    pub(super) channels: Arc<super::Channels>,
}

fn scene_of(map: &BTreeMap<String, Stamped<SceneEntity>>) -> Option<(SceneUpdate, u64)> {
    let t = map.values().map(|(_, t)| *t).max()?;
    Some((
        SceneUpdate {
            entities: map.values().map(|(e, _)| e.clone()).collect(),
            ..Default::default()
        },
        t,
    ))
}

impl ServerListener for LateJoin {
    fn on_subscribe(&self, client: Client, channel: ChannelView<'_>) {
        let sink = client.sink_id();
        let meta = PartialMetadata::with_log_time;
        let c = &self.channels;
        // Copies taken under the lock, sent after it: the recorder is never held up by a send.
        let latest = self.latest.lock().unwrap_or_else(|p| p.into_inner());
        match channel.topic() {
            "/tf" => {
                let tf: Vec<_> = latest.tf.values().cloned().collect();
                drop(latest);
                for (m, t) in tf {
                    c.tf.log_with_meta_to_sink(&m, meta(t), sink);
                }
            }
            "/eye/commanded" => {
                if let Some((m, t)) = latest.eye_commanded.clone() {
                    drop(latest);
                    c.eye_commanded.log_with_meta_to_sink(&m, meta(t), sink);
                }
            }
            "/eye/simulated" => {
                if let Some((m, t)) = latest.eye_simulated.clone() {
                    drop(latest);
                    c.eye_simulated.log_with_meta_to_sink(&m, meta(t), sink);
                }
            }
            "/mandrel" => {
                if let Some((m, t)) = latest.mandrel.clone() {
                    drop(latest);
                    c.mandrel.log_with_meta_to_sink(&m, meta(t), sink);
                }
            }
            topic @ ("/scene/mandrel" | "/scene/fibre" | "/scene/free_fibre") => {
                let (map, ch) = match topic {
                    "/scene/mandrel" => (&latest.scene_mandrel, &c.scene_mandrel),
                    "/scene/fibre" => (&latest.scene_fibre, &c.scene_fibre),
                    _ => (&latest.scene_free_fibre, &c.scene_free_fibre),
                };
                if let Some((m, t)) = scene_of(map) {
                    drop(latest);
                    ch.log_with_meta_to_sink(&m, meta(t), sink);
                }
            }
            _ => {}
        }
    }
}

/// The listening end the operator connects to, in front of the SDK's server.
#[derive(Debug)]
pub struct Front {
    port: u16,
    stop: Arc<AtomicBool>,
    accept: Option<JoinHandle<()>>,
}

impl Front {
    /// Listens on `host:port` (port 0: any free port) and passes connections to the server on
    /// `127.0.0.1:inner_port`.
    pub fn start(host: &str, port: u16, inner_port: u16) -> io::Result<Front> {
        let listener = TcpListener::bind((host, port))?;
        let port = listener.local_addr()?.port();
        listener.set_nonblocking(true)?;
        let stop = Arc::new(AtomicBool::new(false));
        let open = Arc::new(AtomicUsize::new(0));
        let s = stop.clone();
        let accept = std::thread::Builder::new()
            .name("live-front".into())
            .spawn(move || {
                while !s.load(Ordering::Relaxed) {
                    match listener.accept() {
                        Ok((client, _)) => {
                            if open.load(Ordering::Relaxed) >= MAX_CONNECTIONS {
                                continue; // dropped: closed at once
                            }
                            open.fetch_add(1, Ordering::Relaxed);
                            let counter = open.clone();
                            let spawned = std::thread::Builder::new()
                                .name("live-conn".into())
                                .spawn(move || {
                                    // A connection that fails is the viewer's to retry.
                                    let _ = pass(client, inner_port);
                                    counter.fetch_sub(1, Ordering::Relaxed);
                                });
                            if spawned.is_err() {
                                open.fetch_sub(1, Ordering::Relaxed);
                            }
                        }
                        Err(e) if e.kind() == io::ErrorKind::WouldBlock => {
                            std::thread::sleep(Duration::from_millis(10));
                        }
                        Err(_) => std::thread::sleep(Duration::from_millis(10)),
                    }
                }
            })?;
        Ok(Front {
            port,
            stop,
            accept: Some(accept),
        })
    }

    /// The port it listens on.
    pub fn port(&self) -> u16 {
        self.port
    }
}

impl Drop for Front {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.accept.take() {
            let _ = t.join();
        }
    }
}

/// Reads an HTTP head (up to the blank line) from `s`; returns it and any bytes read past it.
fn read_head(s: &mut TcpStream) -> io::Result<(Vec<u8>, Vec<u8>)> {
    let mut buf = Vec::new();
    let mut chunk = [0u8; 2048];
    loop {
        if let Some(end) = buf.windows(4).position(|w| w == b"\r\n\r\n") {
            let rest = buf.split_off(end + 4);
            return Ok((buf, rest));
        }
        if buf.len() > MAX_HEAD_BYTES {
            return Err(io::Error::other("HTTP head too long"));
        }
        let n = s.read(&mut chunk)?;
        if n == 0 {
            return Err(io::ErrorKind::UnexpectedEof.into());
        }
        buf.extend_from_slice(&chunk[..n]);
    }
}

/// The subprotocols a head's `Sec-WebSocket-Protocol` headers offer, trimmed.
pub fn offered(head: &str) -> Vec<String> {
    head.lines()
        .filter_map(|l| l.split_once(':'))
        .filter(|(k, _)| k.trim().eq_ignore_ascii_case("sec-websocket-protocol"))
        .flat_map(|(_, v)| v.split(',').map(|p| p.trim().to_string()))
        .filter(|p| !p.is_empty())
        .collect()
}

/// `head` with its `Sec-WebSocket-Protocol` headers replaced by one naming `name`.
pub fn with_subprotocol(head: &str, name: &str) -> String {
    let mut out = String::with_capacity(head.len());
    let mut done = false;
    for line in head.split_inclusive("\r\n") {
        let is_protocol = line
            .split_once(':')
            .is_some_and(|(k, _)| k.trim().eq_ignore_ascii_case("sec-websocket-protocol"));
        if is_protocol {
            if !done {
                out += &format!("Sec-WebSocket-Protocol: {name}\r\n");
                done = true;
            }
        } else {
            out += line;
        }
    }
    out
}

/// One connection: the upgrade request (renamed if it offers only the ws-protocol name), the
/// server's answer (renamed back), then bytes both ways until either end closes.
fn pass(mut client: TcpStream, inner_port: u16) -> io::Result<()> {
    client.set_nonblocking(false)?;
    client.set_read_timeout(Some(HEAD_TIMEOUT))?;
    let (head, rest) = read_head(&mut client)?;
    let text = String::from_utf8_lossy(&head).into_owned();
    let names = offered(&text);
    let rename = !names
        .iter()
        .any(|n| n == SDK_SUBPROTOCOL || n == "foxglove.sdk.v1.1")
        && names.iter().any(|n| n == WS_PROTOCOL_SUBPROTOCOL);
    let mut server = TcpStream::connect(("127.0.0.1", inner_port))?;
    server.set_nodelay(true)?;
    client.set_nodelay(true)?;
    if rename {
        server.write_all(with_subprotocol(&text, SDK_SUBPROTOCOL).as_bytes())?;
    } else {
        server.write_all(&head)?;
    }
    server.write_all(&rest)?;
    if rename {
        server.set_read_timeout(Some(HEAD_TIMEOUT))?;
        let (answer, rest) = read_head(&mut server)?;
        let answer = String::from_utf8_lossy(&answer).into_owned();
        let answer = if offered(&answer).iter().any(|n| n == SDK_SUBPROTOCOL) {
            with_subprotocol(&answer, WS_PROTOCOL_SUBPROTOCOL)
        } else {
            answer
        };
        client.write_all(answer.as_bytes())?;
        client.write_all(&rest)?;
    }
    client.set_read_timeout(None)?;
    server.set_read_timeout(None)?;
    let (mut c2, mut s2) = (client.try_clone()?, server.try_clone()?);
    let up = std::thread::Builder::new()
        .name("live-up".into())
        .spawn(move || {
            let _ = io::copy(&mut c2, &mut s2);
            let _ = s2.shutdown(Shutdown::Write);
        })?;
    let _ = io::copy(&mut server, &mut client);
    let _ = client.shutdown(Shutdown::Both);
    let _ = up.join();
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The offered names are read from every `Sec-WebSocket-Protocol` header, any case, comma
    /// separated; the rename leaves one header and every other line as it was.
    #[test]
    fn subprotocol_headers_are_read_and_renamed() {
        let head = "GET / HTTP/1.1\r\nHost: x\r\nsec-websocket-protocol: foxglove.websocket.v1, other\r\nSec-WebSocket-Protocol: third\r\nUpgrade: websocket\r\n\r\n";
        assert_eq!(
            offered(head),
            ["foxglove.websocket.v1", "other", "third"].map(String::from)
        );
        let renamed = with_subprotocol(head, SDK_SUBPROTOCOL);
        assert_eq!(
            renamed,
            "GET / HTTP/1.1\r\nHost: x\r\nSec-WebSocket-Protocol: foxglove.sdk.v1\r\nUpgrade: websocket\r\n\r\n"
        );
        assert_eq!(offered(&renamed), [SDK_SUBPROTOCOL]);
    }
}
