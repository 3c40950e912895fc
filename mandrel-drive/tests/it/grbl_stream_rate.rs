//! Streaming throughput to the GRBL simulator over a simulated 115 200-baud serial line, on
//! virtual time (docs/lathe.md, "Streaming to a GRBL controller"; docs/benchmarks.md).
//!
//! `cargo test -p mandrel-drive --test grbl_stream_rate -- --nocapture` prints the table.
//!
//! The real `Streamer` (character counting against the 128-byte receive buffer, and one line per
//! `ok`) drives the real `Winder` through `mandrel_drive::sim::serial`. The programs are short
//! `G93` moves of 1 ms each at time scale 1: an 18-byte line takes 1.56 ms of wire and a 27-byte
//! line 2.34 ms, so the 15-block planner drains faster than lines arrive and the link and the
//! flow control set the pace. Every figure is checked against the one worked out from the bytes
//! and latencies alone.

use mandrel_drive::sim::serial::{LineTiming, StreamRun, USB_LATENCY_S, stream};
use mandrel_drive::sim::winder::{Event, PLANNER_BLOCKS, Winder};
use mandrel_drive::stream::{Flow, GRBL_RX_BUFFER, Program, Streamer};

const BAUD: f64 = 115_200.0;
/// Moves per program.
const MOVES: usize = 2_000;
/// The reply the host acts on: `ok\r` (the `\n` follows on the wire).
const REPLY_BYTES: f64 = 3.0;

/// `G21 G90 G93` then `MOVES` inverse-time moves of `block_ms` each, every line `len` bytes
/// (18: the mandrel alone, `G1 A12.345 F60000`; 27: carriage and mandrel,
/// `G1 X12.345 A123.456 F60000`).
fn program(len: usize, feed: u32) -> Program {
    let mut lines = vec!["G21 G90 G93\n".to_string()];
    for i in 0..MOVES {
        let step = (i % 8000) as f64;
        let line = match len {
            18 => format!("G1 A{:06.3} F{feed}\n", 10.0 + step * 0.01),
            27 => format!(
                "G1 X{:06.3} A{:07.3} F{feed}\n",
                10.0 + step * 0.01,
                100.0 + step * 0.1
            ),
            _ => unreachable!("18 or 27 bytes"),
        };
        assert_eq!(line.len(), len, "{line}");
        lines.push(line);
    }
    Program {
        lines,
        layer_starts: vec![],
    }
}

fn counting() -> Flow {
    Flow::CharacterCounting {
        rx_buffer: GRBL_RX_BUFFER,
    }
}

/// Streams `program` with `flow`; checks that the controller lost no byte, never held more than
/// its buffer, and took every line once and in order.
fn run(program: &Program, flow: Flow, latency_s: f64) -> (StreamRun, usize) {
    let mut streamer = Streamer::new(program.clone(), flow);
    let mut winder = Winder::new(1.0);
    let timing = LineTiming {
        baud: BAUD,
        latency_s,
    };
    let run = stream(&mut streamer, &mut winder, timing).expect("every line acknowledged");
    assert!(streamer.is_done());
    assert_eq!(run.lines, program.lines.len());
    assert_eq!(winder.overflow_bytes(), 0, "{flow:?}");
    assert!(winder.max_rx_bytes() <= GRBL_RX_BUFFER);
    let taken: Vec<String> = winder
        .take_events()
        .into_iter()
        .filter_map(|e| match e {
            Event::Line { text, .. } => Some(text + "\n"),
            _ => None,
        })
        .collect();
    assert!(
        taken == program.lines,
        "every line once, in order ({flow:?})"
    );
    (run, winder.max_rx_bytes())
}

/// Lines per second worked out from the bytes alone, for lines of `len` bytes with `window`
/// lines allowed in flight: the host→controller wire is busy back to back unless a line's `ok`
/// (its last byte's trip, `ok\r` back, and the latency each way) comes back after the wire has
/// sent the `window - 1` lines behind it; then `window` lines go per round trip.
fn expected_lines_per_s(len: usize, window: usize, latency_s: f64) -> f64 {
    let byte_s = 10.0 / BAUD;
    let line_s = len as f64 * byte_s;
    let round_trip_s = line_s + REPLY_BYTES * byte_s + 2.0 * latency_s;
    window as f64 / (window as f64 * line_s).max(round_trip_s)
}

/// Lines in flight character counting allows for lines of `len` bytes.
fn window(flow: Flow, len: usize) -> usize {
    match flow {
        Flow::CharacterCounting { rx_buffer } => rx_buffer / len,
        Flow::OkPerLine => 1,
    }
}

fn name(flow: Flow) -> &'static str {
    match flow {
        Flow::CharacterCounting { .. } => "character counting",
        Flow::OkPerLine => "ok per line",
    }
}

#[test]
fn grbl_stream_rate() {
    println!(
        "| flow | line, bytes | one-way latency | lines/s | % of wire rate | worked out, lines/s | RX buffer peak, bytes |"
    );
    println!("|---|---|---|---|---|---|---|");
    for len in [18, 27] {
        let program = program(len, 60_000);
        for latency_s in [0.0, USB_LATENCY_S, 0.005] {
            for flow in [counting(), Flow::OkPerLine] {
                let (r, peak) = run(&program, flow, latency_s);
                let expected = expected_lines_per_s(len, window(flow, len), latency_s);
                println!(
                    "| {} | {len} | {} ms | {:.1} | {:.1} % | {expected:.1} | {peak} |",
                    name(flow),
                    latency_s * 1e3,
                    r.lines_per_s(),
                    100.0 * r.wire_fraction(),
                );
                // The header line and the first and last round trips: within 0.5 %.
                let off = r.lines_per_s() / expected - 1.0;
                assert!(
                    off.abs() < 0.005,
                    "{flow:?} {len} B {latency_s} s: {r:?} vs {expected}"
                );
                // The motion (1 ms blocks) is never the limit.
                assert!(r.lines_per_s() < 1_000.0 * 0.95);
                if latency_s <= USB_LATENCY_S {
                    match flow {
                        Flow::CharacterCounting { .. } => {
                            assert!(r.wire_fraction() >= 0.95, "{r:?}");
                            assert!(
                                (r.to_controller_busy_s / r.elapsed_s) >= 0.95,
                                "the wire is busy: {r:?}"
                            );
                        }
                        Flow::OkPerLine => assert!(r.wire_fraction() < 0.9, "{r:?}"),
                    }
                }
            }
        }
    }
}

#[test]
fn one_line_per_ok_matches_its_round_trip_to_the_microsecond() {
    // Every line waits for the one before: the run's time is the sum of the round trips.
    for latency_s in [0.0, USB_LATENCY_S] {
        let program = program(27, 60_000);
        let (r, peak) = run(&program, Flow::OkPerLine, latency_s);
        let byte_s = 10.0 / BAUD;
        let want: f64 = program
            .lines
            .iter()
            .map(|l| (l.len() as f64 + REPLY_BYTES) * byte_s + 2.0 * latency_s)
            .sum();
        assert!((r.elapsed_s - want).abs() < 1e-6, "{r:?} vs {want}");
        assert_eq!(peak, 27, "one line at a time");
    }
}

#[test]
fn counting_keeps_the_wire_busy_to_the_last_line() {
    // Back to back: the run is the program's bytes on the wire plus the last line's `ok` trip.
    for latency_s in [0.0, USB_LATENCY_S] {
        let program = program(27, 60_000);
        let (r, _) = run(&program, counting(), latency_s);
        let byte_s = 10.0 / BAUD;
        let bytes: usize = program.lines.iter().map(String::len).sum();
        let want = (bytes as f64 + REPLY_BYTES) * byte_s + 2.0 * latency_s;
        assert!((r.elapsed_s - want).abs() < 1e-6, "{r:?} vs {want}");
        assert!((r.to_controller_busy_s - bytes as f64 * byte_s).abs() < 1e-9);
    }
}

#[test]
fn slower_motion_sets_the_pace_and_fills_the_receive_buffer() {
    // 2 ms blocks (G93 F30000) behind 18-byte lines that the wire carries every 1.56 ms: the
    // planner fills, lines wait in the receive buffer for a block to end, and counting runs at
    // the motion's 500 lines/s with the buffer several lines ahead and nothing lost.
    let program = program(18, 30_000);
    let (r, peak) = run(&program, counting(), USB_LATENCY_S);
    // The last `ok` comes as the last line enters the planner, 15 blocks before motion ends.
    let want_s = (MOVES - PLANNER_BLOCKS) as f64 * 0.002;
    assert!(
        (r.elapsed_s / want_s - 1.0).abs() < 0.005,
        "{r:?} vs {want_s}"
    );
    // The 128 bytes of credit, less the lines whose bytes or `ok` are still on the wire.
    assert!(peak >= 100, "{peak}");
    // One line per ok is still the slower.
    let (one, _) = run(&program, Flow::OkPerLine, USB_LATENCY_S);
    assert!(one.lines_per_s() < 0.8 * r.lines_per_s(), "{one:?}");
}
