//! The host's work per line while `windcell lathe stream` streams, with the progress display
//! (`cell::lathe::stream_watch`), and the layup drawing of `windcell lathe plan --svg`.
//! Run with `cargo bench -p cell --bench stream`.
//!
//! The program is a 1.46 m, 152 mm tube with three helical layers at 45° (the size of
//! FiberPath's CarbonMotorTube example, written here), planned for Marlin.

use std::time::Duration;

use cell::lathe::stream_watch::{Outline, Show, Watch};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use mandrel_drive::stream::{Flow, Program, ReplyLines, Streamer};

const TUBE: &str = r#"{
  "mandrelParameters": { "diameter": 152, "windLength": 1460 },
  "towParameters": { "width": 8.2, "thickness": 0.5 },
  "defaultFeedRate": 10000,
  "layers": [
    { "windType": "helical", "windAngle": 45, "patternNumber": 7, "skipIndex": 3,
      "lockDegrees": 540, "leadInMM": 80, "leadOutDegrees": 45 },
    { "windType": "helical", "windAngle": 45, "patternNumber": 7, "skipIndex": 3,
      "lockDegrees": 540, "leadInMM": 80, "leadOutDegrees": 45 },
    { "windType": "helical", "windAngle": 45, "patternNumber": 7, "skipIndex": 3,
      "lockDegrees": 540, "leadInMM": 80, "leadOutDegrees": 45 }
  ]
}"#;

fn plan() -> (paths::vessel::Job, paths::vessel::Plan) {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("tube.wind");
    std::fs::write(&path, TUBE).expect("write");
    let (job, _) = sequences::wind::WindFile::load(&path).expect("loads");
    let plan = job.check().expect("plans");
    (job, plan)
}

fn program_text() -> String {
    let (job, plan) = plan();
    let (_, out) = cell::lathe::gcode::write_program(
        &plan,
        job.machine.axes,
        sequences::gcode::Dialect::Marlin,
        "tube",
        Vec::new(),
    )
    .expect("writes");
    String::from_utf8(out).expect("text")
}

fn streaming(c: &mut Criterion) {
    let text = program_text();
    let outline = Outline::of(&text).expect("checks");
    let program = Program::from_gcode(&text);
    let lines = program.lines.len();
    let mut g = c.benchmark_group("lathe_stream");
    g.throughput(Throughput::Elements(lines as u64));
    // Per line: hand out the line (copied, as the driver does before writing it), split the
    // controller's `ok\n` out of the bytes, take it, and ask the display whether to show.
    for (name, show) in [
        ("host_loop_plain", Show::Plain(Duration::from_secs(5))),
        ("host_loop_json", Show::Json),
        ("host_loop_terminal", Show::Terminal),
    ] {
        g.bench_function(name, |b| {
            b.iter(|| {
                let mut s = Streamer::new(program.clone(), Flow::OkPerLine);
                let mut watch = Watch::new(&outline, show);
                let mut replies = ReplyLines::new();
                let mut shown = 0usize;
                while !s.is_done() {
                    if let Some(line) = s.poll_send() {
                        let line = line.to_string();
                        std::hint::black_box(&line);
                    }
                    for &byte in b"ok\n" {
                        if let Some(reply) = replies.push(byte) {
                            s.on_reply(&reply).expect("ok");
                        }
                    }
                    if watch.update(s.sent(), s.acknowledged(), false).is_some() {
                        shown += 1;
                    }
                }
                std::hint::black_box(shown)
            })
        });
    }
    // The whole-file check before the first line is sent.
    g.bench_function("check_whole_file", |b| {
        b.iter(|| Outline::of(std::hint::black_box(&text)).expect("checks"))
    });
    g.finish();
}

fn layup_svg(c: &mut Criterion) {
    let (job, plan) = plan();
    let start = -(1460.0 / 2.0);
    let mut g = c.benchmark_group("lathe_plan_svg");
    // The whole drawing: the plan emitted again, every pass cut where it wraps, the thickness
    // at 401 stations, the text.
    g.bench_function("carbon_motor_tube_size", |b| {
        b.iter(|| {
            cell::lathe::layup_svg::draw(&job, &plan, start, "tube")
                .0
                .len()
        })
    });
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20).measurement_time(Duration::from_secs(3));
    targets = streaming, layup_svg
}
criterion_main!(benches);
