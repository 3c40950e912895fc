//! Taps on the coordinator's end of the device links and sync lines, for the recording and the
//! live view (`cell::record`, docs/operator.md): every robot telegram and control character on
//! `/link/robot`, every X-language line on `/link/indexer` (raw bytes and what they say), the
//! eye pose each MOVE_IMMEDIATE commands on `/eye/commanded`, and every edge of the sync lines
//! as the PC drives and reads them on `/sync`.
//!
//! A tap is put on the links when the devices are made, before any recorder exists (the run's
//! checks come first and write nothing); the recorder is handed to the taps through a
//! [`RecordSlot`] once it is open. Until then, and in a run that records nothing, a tap passes
//! the bytes through and keeps nothing. The same taps sit on a serial port and on the simulated
//! cell's in-memory links, so a recording shows the wire as the coordinator saw it either way,
//! at the time of the coordinator's own clock ([`Timebase`]).

use std::io;
use std::sync::{Arc, OnceLock};
use std::time::Duration;

use asea_protocol::frame::{self, ACK, ENQ, EOT, FrameConfig, NAK, Parsed, STX};
use asea_protocol::{Command, Reply};
use nalgebra::Point3;
use paths::link::Link;
use paths::wrist::from_components;

use crate::record::{Device, Direction, Recorder};
use crate::run::device::{DeviceResult, SyncLines, Timebase};

/// The recorder the taps write to, set once it is open.
#[derive(Debug, Clone, Default)]
pub struct RecordSlot(Arc<OnceLock<Arc<Recorder>>>);

impl RecordSlot {
    /// Hands the taps `rec`; a second call is ignored (one recorder a run).
    pub fn set(&self, rec: Arc<Recorder>) {
        let _ = self.0.set(rec);
    }

    fn get(&self) -> Option<&Arc<Recorder>> {
        self.0.get()
    }
}

/// The longest X-language line a tap holds before it records it anyway, bytes (a line is a few
/// dozen; this bounds the memory of a line that never ends).
pub const MAX_LINE_BYTES: usize = 256;

/// Cuts a link's byte stream, one direction, into what its protocol sends.
#[derive(Debug)]
enum Cutter {
    /// The robot link: single control characters and whole telegrams (docs/protocol.md §3).
    Robot { frame: FrameConfig, held: Vec<u8> },
    /// The indexer link: CR-ended lines (an LF is dropped).
    Indexer { held: Vec<u8> },
}

impl Cutter {
    /// Adds `bytes`; returns every unit they complete.
    fn push(&mut self, bytes: &[u8]) -> Vec<Vec<u8>> {
        let mut out = Vec::new();
        for &b in bytes {
            match self {
                Cutter::Robot { frame, held } => {
                    if held.is_empty() && b != STX {
                        out.push(vec![b]);
                        continue;
                    }
                    held.push(b);
                    let whole = match frame::parse(frame, held) {
                        Parsed::Incomplete => held.len() >= frame.frame_len(usize::from(u8::MAX)),
                        Parsed::Frame { .. } | Parsed::Bad(_) => true,
                    };
                    if whole {
                        out.push(std::mem::take(held));
                    }
                }
                Cutter::Indexer { held } => match b {
                    b'\r' => out.push(std::mem::take(held)),
                    b'\n' => {}
                    _ => {
                        held.push(b);
                        if held.len() >= MAX_LINE_BYTES {
                            out.push(std::mem::take(held));
                        }
                    }
                },
            }
        }
        out
    }
}

/// What one robot-link unit says: a control character by name, a telegram as the command
/// (sent) or reply (received) it decodes to, or why it does not.
pub fn robot_unit(frame_cfg: &FrameConfig, direction: Direction, bytes: &[u8]) -> String {
    decode_robot_unit(frame_cfg, direction, bytes).0
}

/// [`robot_unit`], and the command when the unit is one the host sent.
fn decode_robot_unit(
    frame_cfg: &FrameConfig,
    direction: Direction,
    bytes: &[u8],
) -> (String, Option<Command>) {
    let text = match bytes {
        [ENQ] => "ENQ".into(),
        [ACK] => "ACK".into(),
        [NAK] => "NAK".into(),
        [EOT] => "EOT".into(),
        [b] => format!("byte 0x{b:02x} outside a telegram"),
        _ => match frame::parse(frame_cfg, bytes) {
            Parsed::Frame { frame: f, .. } => match direction {
                Direction::Sent => match Command::from_frame(&f) {
                    Ok(c) => return (format!("{c:?}"), Some(c)),
                    Err(e) => format!("undefined command: {e}"),
                },
                Direction::Received => Reply::from_frame(&f)
                    .map_or_else(|e| format!("undefined reply: {e}"), |r| format!("{r:?}")),
            },
            Parsed::Bad(e) => format!("bad telegram: {e}"),
            Parsed::Incomplete => "incomplete telegram".into(),
        },
    };
    (text, None)
}

/// What one indexer line says: a command of the X-language subset (sent), or the indexer's echo,
/// status reply (`*`), refusal (`?`) or completion (an empty line).
pub fn indexer_line(direction: Direction, line: &[u8]) -> String {
    let text = String::from_utf8_lossy(line);
    match direction {
        Direction::Sent => match mandrel_drive::xlang::parse_command(&text) {
            Some((Some(a), c)) => format!("unit {a}: {c:?}"),
            Some((None, c)) => format!("every unit: {c:?}"),
            None => match mandrel_drive::grbl::parse_command(&text) {
                Some(c) => format!("GRBL: {c:?}"),
                None => format!("not in the X-language or GRBL subset: {text:?}"),
            },
        },
        Direction::Received => match line.first() {
            None => "completion".into(),
            Some(b'*') => format!("status {text}"),
            Some(b'?') => format!("refused {text}"),
            Some(b'<') => format!("GRBL status {text}"),
            _ if text == "ok" => "GRBL ok".into(),
            _ if text.starts_with("error:") || text.starts_with("ALARM:") => {
                format!("GRBL refused {text}")
            }
            Some(_) => format!("echo {text}"),
        },
    }
}

/// The mandrel position an indexer line reports, recorded as `world → mandrel`: a GRBL status
/// report's A position, or the X-language answer to `PR` (`asked` is set when `PR` goes out and
/// cleared by its answer).
fn reported_mandrel(rec: &Recorder, t_s: f64, direction: Direction, line: &[u8], asked: &mut bool) {
    use mandrel_drive::xlang::{Command as X, Reply as XReply, parse_command, parse_reply};
    let text = String::from_utf8_lossy(line);
    match direction {
        Direction::Sent => {
            if let Some((_, X::Position)) = parse_command(&text) {
                *asked = true;
            }
        }
        Direction::Received => {
            if line.first() == Some(&b'<') {
                if let Ok(mandrel_drive::grbl::Line::Status { a_deg, .. }) =
                    mandrel_drive::grbl::parse_line(line)
                {
                    rec.mandrel_reported_deg(t_s, a_deg);
                }
            } else if *asked
                && line.first() == Some(&b'*')
                && let Ok(XReply::Position(steps)) = parse_reply(&X::Position, line, None)
            {
                *asked = false;
                rec.mandrel_reported_steps(t_s, steps);
            }
        }
    }
}

/// One device link's tap: which device, the recorder slot, the clock, a cutter each way.
#[derive(Debug)]
pub struct LinkTap<L> {
    inner: L,
    device: Device,
    slot: RecordSlot,
    time: Arc<dyn Timebase>,
    sent: Cutter,
    received: Cutter,
    /// Also records the positions the device reports (serial ports: the only source of `/tf`).
    reports: bool,
    /// The X-language position request (`PR`) was sent and its answer is awaited.
    asked_position: bool,
}

impl<L> LinkTap<L> {
    /// The same tap, also recording the positions the device reports on `/tf`: the robot's
    /// position replies as `world → eye`, the indexer's step counter (X-language `PR`) or A
    /// position (GRBL status report) as `world → mandrel` ([`Recorder::mandrel_reported_deg`]).
    /// For a cell on serial ports, whose motion nothing else reports.
    pub fn reporting_positions(mut self) -> Self {
        self.reports = true;
        self
    }

    /// A tap on the robot link `inner`, whose telegrams are framed by `frame`.
    pub fn robot(inner: L, frame: FrameConfig, slot: RecordSlot, time: Arc<dyn Timebase>) -> Self {
        let cutter = || Cutter::Robot {
            frame,
            held: Vec::new(),
        };
        LinkTap {
            inner,
            device: Device::Robot,
            slot,
            time,
            sent: cutter(),
            received: cutter(),
            reports: false,
            asked_position: false,
        }
    }

    /// A tap on the indexer link `inner`.
    pub fn indexer(inner: L, slot: RecordSlot, time: Arc<dyn Timebase>) -> Self {
        let cutter = || Cutter::Indexer { held: Vec::new() };
        LinkTap {
            inner,
            device: Device::Indexer,
            slot,
            time,
            sent: cutter(),
            received: cutter(),
            reports: false,
            asked_position: false,
        }
    }

    fn note(&mut self, direction: Direction, bytes: &[u8]) {
        let Some(rec) = self.slot.get() else {
            return;
        };
        let cutter = match direction {
            Direction::Sent => &mut self.sent,
            Direction::Received => &mut self.received,
        };
        let units = cutter.push(bytes);
        if units.is_empty() {
            return;
        }
        let t = self.time.now_s();
        for u in units {
            let decoded = match cutter {
                Cutter::Robot { frame, .. } => {
                    let (text, command) = decode_robot_unit(frame, direction, &u);
                    if let Some(Command::MoveImmediate(p)) = command {
                        let eye = Point3::from(p.pose.xyz_mm());
                        rec.eye(t, &eye, &from_components(p.pose.q.wxyz()), false);
                    }
                    if self.reports
                        && direction == Direction::Received
                        && let Parsed::Frame { frame: f, .. } = frame::parse(frame, &u)
                        && let Ok(Reply::Position(pose)) = Reply::from_frame(&f)
                    {
                        let eye = Point3::from(pose.xyz_mm());
                        rec.eye(t, &eye, &from_components(pose.q.wxyz()), true);
                    }
                    text
                }
                Cutter::Indexer { .. } => {
                    if self.reports {
                        reported_mandrel(rec, t, direction, &u, &mut self.asked_position);
                    }
                    indexer_line(direction, &u)
                }
            };
            rec.telegram(t, self.device, direction, &u, &decoded);
        }
    }
}

impl<L: Link> Link for LinkTap<L> {
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.inner.write_all(bytes)?;
        self.note(Direction::Sent, bytes);
        Ok(())
    }
    fn read_timeout(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        let n = self.inner.read_timeout(buf, timeout)?;
        self.note(Direction::Received, &buf[..n]);
        Ok(n)
    }
    fn discard_input(&mut self) -> io::Result<()> {
        self.inner.discard_input()
    }
}

/// A tap on the PC's side of the sync lines: each change of the start output it drives, and
/// each change of the in-position and e-stop inputs between two of its reads (at the read that
/// saw it: the PC's view, to within its polling).
#[derive(Debug)]
pub struct SyncTap {
    inner: Box<dyn SyncLines>,
    slot: RecordSlot,
    time: Arc<dyn Timebase>,
    /// The last level of start, in position and e-stop the PC drove or read.
    last: [Option<bool>; 3],
}

impl SyncTap {
    /// A tap on `inner`.
    pub fn new(inner: Box<dyn SyncLines>, slot: RecordSlot, time: Arc<dyn Timebase>) -> Self {
        SyncTap {
            inner,
            slot,
            time,
            last: [None; 3],
        }
    }

    fn note(&mut self, line: usize, high: bool) {
        const NAMES: [&str; 3] = ["start", "in_position", "e_stop"];
        if self.last[line] == Some(high) {
            return;
        }
        self.last[line] = Some(high);
        if let Some(rec) = self.slot.get() {
            rec.sync_edge(self.time.now_s(), NAMES[line], high);
        }
    }
}

impl SyncLines for SyncTap {
    fn set_start(&mut self, on: bool) -> DeviceResult<()> {
        self.inner.set_start(on)?;
        self.note(0, on);
        Ok(())
    }
    fn in_position(&mut self) -> DeviceResult<bool> {
        let v = self.inner.in_position()?;
        self.note(1, v);
        Ok(v)
    }
    fn estop(&mut self) -> DeviceResult<bool> {
        let v = self.inner.estop()?;
        self.note(2, v);
        Ok(v)
    }
    fn wired(&self) -> bool {
        self.inner.wired()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The robot cutter gives control characters one by one and a telegram whole, however the
    /// bytes arrive; the telegram decodes to the command that was encoded.
    #[test]
    fn robot_bytes_are_cut_into_control_characters_and_whole_telegrams() {
        let cfg = FrameConfig::default();
        let stop = Command::Stop.encode(&cfg).unwrap();
        let mut wire = vec![ENQ];
        wire.extend_from_slice(&stop);
        wire.push(EOT);
        let mut c = Cutter::Robot {
            frame: cfg,
            held: Vec::new(),
        };
        let mut units = Vec::new();
        for b in &wire {
            units.extend(c.push(std::slice::from_ref(b)));
        }
        assert_eq!(units, vec![vec![ENQ], stop.clone(), vec![EOT]]);
        assert_eq!(robot_unit(&cfg, Direction::Sent, &units[1]), "Stop");
        for (b, name) in [(ENQ, "ENQ"), (ACK, "ACK"), (NAK, "NAK"), (EOT, "EOT")] {
            assert_eq!(robot_unit(&cfg, Direction::Received, &[b]), name);
        }
        assert_eq!(
            robot_unit(&cfg, Direction::Received, &[0x55]),
            "byte 0x55 outside a telegram"
        );
        // A wrong check value is still one unit, named as bad.
        let mut bad = stop.clone();
        *bad.last_mut().unwrap() ^= 0xFF;
        let units = c.push(&bad);
        assert_eq!(units, vec![bad.clone()]);
        assert!(robot_unit(&cfg, Direction::Sent, &units[0]).starts_with("bad telegram"));
    }

    /// Indexer lines end at CR (an LF dropped), and a line that never ends is cut at
    /// [`MAX_LINE_BYTES`].
    #[test]
    fn indexer_bytes_are_cut_into_lines() {
        let mut c = Cutter::Indexer { held: Vec::new() };
        assert_eq!(
            c.push(b"1A10\r1G\r\n*R"),
            vec![b"1A10".to_vec(), b"1G".to_vec()]
        );
        assert_eq!(c.push(b"\r"), vec![b"*R".to_vec()]);
        let long = vec![b'9'; MAX_LINE_BYTES + 1];
        assert_eq!(c.push(&long).len(), 1);
        assert_eq!(indexer_line(Direction::Sent, b"1G"), "unit 1: Go");
        assert_eq!(indexer_line(Direction::Received, b"*R"), "status *R");
        assert_eq!(indexer_line(Direction::Received, b""), "completion");
        assert_eq!(indexer_line(Direction::Received, b"?X"), "refused ?X");
        assert_eq!(indexer_line(Direction::Received, b"1G"), "echo 1G");
    }

    /// A link that counts the discards it is asked for.
    #[derive(Debug, Default)]
    struct Counting(u32);

    impl Link for Counting {
        fn write_all(&mut self, _: &[u8]) -> io::Result<()> {
            Ok(())
        }
        fn read_timeout(&mut self, _: &mut [u8], _: Duration) -> io::Result<usize> {
            Ok(0)
        }
        fn discard_input(&mut self) -> io::Result<()> {
            self.0 += 1;
            Ok(())
        }
    }

    /// A tap passes a discard of input through to its link (both kinds), and a sync tap says
    /// whether the lines under it are wired.
    #[test]
    fn taps_pass_discards_and_wiring_through() {
        let time: Arc<dyn Timebase> = Arc::new(crate::run::device::WallClock::new());
        let slot = RecordSlot::default();
        let mut robot = LinkTap::robot(
            Counting::default(),
            FrameConfig::default(),
            slot.clone(),
            time.clone(),
        );
        asea_protocol::Link::discard_input(&mut robot).unwrap();
        assert_eq!(robot.inner.0, 1);
        let mut indexer = LinkTap::indexer(Counting::default(), slot.clone(), time.clone());
        mandrel_drive::Link::discard_input(&mut indexer).unwrap();
        assert_eq!(indexer.inner.0, 1);
        let unwired = SyncTap::new(Box::new(crate::run::device::NoSync), slot, time);
        assert!(!unwired.wired());
    }
}
