//! A tap on a simulator's end of a device link: it notes the wall-clock time at which a stop
//! command arrives (the robot's STOP telegram, the indexer's `S`), so that the time from an
//! operator's stop to the stop commands on the wire can be measured from outside the coordinator
//! (docs/benchmarks.md, "Stop latency"). Bytes pass through unchanged.

use std::io;
use std::sync::{Arc, Mutex};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use paths::link::Link;

/// What the tap looks for.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum StopPattern {
    /// These exact bytes (the robot's encoded STOP telegram).
    Telegram(Vec<u8>),
    /// A CR-terminated X-language line that is `S`, with or without a device address (`1S`).
    IndexerStop,
}

impl StopPattern {
    /// The robot's STOP telegram as `frame` encodes it.
    pub fn robot(frame: &asea_protocol::FrameConfig) -> Self {
        StopPattern::Telegram(
            asea_protocol::Command::Stop
                .encode(frame)
                .unwrap_or_default(),
        )
    }
}

/// Seconds since the Unix epoch now (the clock both a coordinator and a simulator process see).
pub fn unix_now_s() -> f64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64())
}

/// The times (Unix seconds) at which a tap saw its stop command.
pub type StopTimes = Arc<Mutex<Vec<f64>>>;

/// One passage of bytes through a tap: when (Unix seconds), which way, what.
#[derive(Debug, Clone, PartialEq)]
pub struct WireEvent {
    /// Unix seconds when the read returned or the write finished.
    pub unix_s: f64,
    /// True for bytes from the peer (the coordinator), false for the simulator's own.
    pub inbound: bool,
    /// The bytes.
    pub bytes: Vec<u8>,
}

impl WireEvent {
    /// As a JSON value: `[unix_s, "in"|"out", "hex bytes"]`.
    pub fn json(&self) -> serde_json::Value {
        let hex: Vec<String> = self.bytes.iter().map(|b| format!("{b:02x}")).collect();
        serde_json::json!([
            self.unix_s,
            if self.inbound { "in" } else { "out" },
            hex.join(" ")
        ])
    }
}

/// The wire's last events before each stop command, one list per stop seen
/// ([`StopTap::with_trace`]).
pub type StopTraces = Arc<Mutex<Vec<Vec<WireEvent>>>>;

/// How many passages of bytes the trace keeps before a stop command.
pub const TRACE_EVENTS: usize = 48;

/// A link that notes when a stop command passes through it (in the reading direction).
#[derive(Debug)]
pub struct StopTap<L> {
    inner: L,
    pattern: StopPattern,
    /// Bytes read and not yet ruled out (the tail of a telegram, the current line).
    window: Vec<u8>,
    seen: StopTimes,
    /// The last [`TRACE_EVENTS`] passages both ways, when tracing.
    recent: Option<std::collections::VecDeque<WireEvent>>,
    traces: StopTraces,
}

/// Longest tail kept while looking for a pattern.
const MAX_WINDOW: usize = 256;

impl<L> StopTap<L> {
    /// Taps `inner` for `pattern`; the times go to the returned list as well.
    pub fn new(inner: L, pattern: StopPattern) -> (Self, StopTimes) {
        let seen = StopTimes::default();
        (
            StopTap {
                inner,
                pattern,
                window: Vec::new(),
                seen: seen.clone(),
                recent: None,
                traces: StopTraces::default(),
            },
            seen,
        )
    }

    /// Also keeps the bytes passing both ways, and at each stop command seen hands the last
    /// [`TRACE_EVENTS`] of them (the stop's own bytes last) to the returned list: what was on
    /// the line when the stop came (`sim-robot --log-wire`, docs/benchmarks.md "Stop latency").
    pub fn with_trace(mut self) -> (Self, StopTraces) {
        self.recent = Some(std::collections::VecDeque::with_capacity(TRACE_EVENTS));
        let traces = self.traces.clone();
        (self, traces)
    }

    fn note(&mut self, inbound: bool, bytes: &[u8], unix_s: f64) {
        if let Some(r) = self.recent.as_mut() {
            if r.len() == TRACE_EVENTS {
                r.pop_front();
            }
            r.push_back(WireEvent {
                unix_s,
                inbound,
                bytes: bytes.to_vec(),
            });
        }
    }

    fn saw(&mut self, bytes: &[u8]) {
        let t = unix_now_s();
        self.note(true, bytes, t);
        let mut hits = 0;
        match &self.pattern {
            StopPattern::Telegram(p) => {
                self.window.extend_from_slice(bytes);
                if !p.is_empty() {
                    while let Some(i) = self.window.windows(p.len()).position(|w| w == p.as_slice())
                    {
                        hits += 1;
                        self.window.drain(..i + p.len());
                    }
                    let keep = p.len().saturating_sub(1);
                    if self.window.len() > keep {
                        self.window.drain(..self.window.len() - keep);
                    }
                }
            }
            StopPattern::IndexerStop => {
                for &b in bytes {
                    if b == b'\r' {
                        let line: Vec<u8> = self.window.drain(..).filter(|c| *c != b'\n').collect();
                        if let Some((last, address)) = line.split_last()
                            && *last == b'S'
                            && address.iter().all(u8::is_ascii_digit)
                        {
                            hits += 1;
                        }
                    } else if self.window.len() < MAX_WINDOW {
                        self.window.push(b);
                    }
                }
            }
        }
        if hits > 0
            && let Ok(mut s) = self.seen.lock()
        {
            s.extend(std::iter::repeat_n(t, hits));
        }
        if hits > 0
            && let Some(r) = self.recent.as_ref()
            && let Ok(mut traces) = self.traces.lock()
        {
            traces.push(r.iter().cloned().collect());
        }
    }

    fn sent(&mut self, bytes: &[u8]) {
        if !bytes.is_empty() && self.recent.is_some() {
            self.note(false, bytes, unix_now_s());
        }
    }
}

impl<L: Link> Link for StopTap<L> {
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.inner.write_all(bytes)?;
        self.sent(bytes);
        Ok(())
    }
    fn read_timeout(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        let n = self.inner.read_timeout(buf, timeout)?;
        if let Some(b) = buf.get(..n) {
            self.saw(b);
        }
        Ok(n)
    }
    fn discard_input(&mut self) -> io::Result<()> {
        self.inner.discard_input()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_the_stop_telegram_split_across_reads_and_the_indexer_stop_line() {
        let frame = asea_protocol::FrameConfig::default();
        let stop = asea_protocol::Command::Stop.encode(&frame).unwrap();
        let other = asea_protocol::Command::Standby.encode(&frame).unwrap();
        assert_ne!(stop, other);
        let (mut tap, seen) = StopTap::new((), StopPattern::robot(&frame));
        tap.saw(&other);
        tap.saw(&stop[..2]);
        assert!(seen.lock().unwrap().is_empty());
        tap.saw(&stop[2..]);
        tap.saw(&other);
        assert_eq!(seen.lock().unwrap().len(), 1);

        let (mut tap, seen) = StopTap::new((), StopPattern::IndexerStop);
        tap.saw(b"1MN\r1VS0.5\r1D-65\r1G\r1R\r");
        assert!(seen.lock().unwrap().is_empty());
        tap.saw(b"1");
        tap.saw(b"S\r\nS\r");
        assert_eq!(seen.lock().unwrap().len(), 2);
    }

    /// Bytes that are no stop telegram are not kept beyond what could still begin one (the
    /// telegram's length less one), however many come and in whatever reads.
    #[test]
    fn the_window_keeps_only_a_possible_telegram_start() {
        let frame = asea_protocol::FrameConfig::default();
        let stop = asea_protocol::Command::Stop.encode(&frame).unwrap();
        let (mut tap, seen) = StopTap::new((), StopPattern::robot(&frame));
        let noise = [0x41u8; 100];
        for _ in 0..50 {
            tap.saw(&noise);
            assert!(tap.window.len() < stop.len(), "{}", tap.window.len());
        }
        tap.saw(&stop);
        assert_eq!(seen.lock().unwrap().len(), 1);
    }

    #[test]
    fn unix_time_is_now_and_moves_on() {
        // 2026-01-01 and 2100-01-01 in Unix seconds.
        let t = unix_now_s();
        assert!((1_767_225_600.0..4_102_444_800.0).contains(&t), "{t}");
        std::thread::sleep(Duration::from_millis(5));
        let dt = unix_now_s() - t;
        assert!((0.004..1.0).contains(&dt), "{dt}");
    }

    #[test]
    fn a_trace_keeps_the_last_passages_both_ways_up_to_each_stop() {
        let frame = asea_protocol::FrameConfig::default();
        let stop = asea_protocol::Command::Stop.encode(&frame).unwrap();
        // Without tracing nothing is kept.
        let (mut plain, _) = StopTap::new((), StopPattern::robot(&frame));
        plain.sent(&[0x06]);
        plain.saw(&stop);
        assert!(plain.recent.is_none() && plain.traces.lock().unwrap().is_empty());

        let (tap, _) = StopTap::new((), StopPattern::robot(&frame));
        let (mut tap, traces) = tap.with_trace();
        for k in 0..TRACE_EVENTS as u8 {
            tap.saw(&[0x05, k]);
            tap.sent(&[0x06]);
        }
        tap.sent(&[]);
        assert!(traces.lock().unwrap().is_empty(), "no stop yet");
        tap.saw(&stop[..3]);
        tap.saw(&stop[3..]);
        let t = traces.lock().unwrap().clone();
        assert_eq!(t.len(), 1);
        let w = &t[0];
        // The last TRACE_EVENTS passages, oldest first, the STOP's bytes last; an empty write
        // is not a passage.
        assert_eq!(w.len(), TRACE_EVENTS);
        assert_eq!(w[TRACE_EVENTS - 1].bytes, stop[3..].to_vec());
        assert_eq!(w[TRACE_EVENTS - 2].bytes, stop[..3].to_vec());
        assert!(w[TRACE_EVENTS - 1].inbound && w[TRACE_EVENTS - 2].inbound);
        assert_eq!(
            (w[TRACE_EVENTS - 3].inbound, &w[TRACE_EVENTS - 3].bytes[..]),
            (false, &[0x06][..])
        );
        assert_eq!(
            w[TRACE_EVENTS - 4].bytes,
            vec![0x05, TRACE_EVENTS as u8 - 1]
        );
        assert!(w.windows(2).all(|p| p[0].unix_s <= p[1].unix_s));
        assert_eq!(
            w[TRACE_EVENTS - 3].json().as_array().unwrap()[1..],
            [serde_json::json!("out"), serde_json::json!("06")]
        );
        assert_eq!(w[TRACE_EVENTS - 4].json()[2], serde_json::json!("05 2f"));
    }
}
