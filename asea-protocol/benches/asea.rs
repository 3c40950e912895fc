//! Codec throughput (target: ≥ 2 million telegrams encoded + decoded per second on one core) and
//! the upload of a full 470-instruction program over a 9600-baud link paced in virtual time
//! (target: ≤ 2 % above the wire time of its bytes plus the specified gaps), and the client's
//! cancel latency (the stop path counts on about a millisecond, docs/ARCHITECTURE.md).
//!
//! `cargo bench -p asea-protocol --features bench --bench asea -- --warm-up-time 1 --measurement-time 3`

use std::hint::black_box;
use std::time::Duration;

use asea_protocol::clock::{Clock, VirtualClock};
use asea_protocol::link::Paced;
use asea_protocol::session::{T_GAP, Timers};
use asea_protocol::sim::{MotionParams, Robot};
use asea_protocol::{
    Client, ClientConfig, Command, Decoder, Flags, FrameConfig, Instruction, Pose, Positioning,
    Speed, Token, Zone,
};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};

fn positioning(k: u16) -> Positioning {
    Positioning {
        flags: Flags {
            zone: Zone::Medium,
            ..Flags::default()
        },
        pose: Pose::from_mm([500.0 + f64::from(k), -250.5, 800.0], [0.0, 0.0, 1.0, 0.0]).unwrap(),
        speed: Speed::from_value("speed", 0.25).unwrap(),
    }
}

fn codec(c: &mut Criterion) {
    let cfg = FrameConfig::default();
    let cmd = Command::StorePos {
        program: 1,
        instruction: 5,
        positioning: positioning(0),
    };
    let mut group = c.benchmark_group("codec");
    group.throughput(Throughput::Elements(1));
    let mut buf = Vec::with_capacity(64);
    let mut dec = Decoder::new(cfg);
    group.bench_function("store_pos_encode_decode", |b| {
        b.iter(|| {
            buf.clear();
            black_box(&cmd).encode_into(&cfg, &mut buf).unwrap();
            dec.push(&buf);
            match dec.next_token() {
                Some(Token::Frame(f)) => black_box(Command::from_frame(&f).unwrap()),
                other => panic!("{other:?}"),
            }
        })
    });
    group.finish();
}

/// Uploads 470 positioning instructions; returns (virtual seconds, wire + gaps seconds).
fn upload_470() -> (f64, f64) {
    let cfg = FrameConfig::default();
    let clock = VirtualClock::new();
    let robot = Robot::new(cfg, Timers::default(), MotionParams::default());
    let mut client = Client::with_clock(
        Paced::new(clock.clone(), 9600, robot),
        clock.clone(),
        ClientConfig::default(),
    );
    for n in 1..=470u16 {
        client
            .store(1, n, &Instruction::Position(positioning(n)))
            .unwrap();
    }
    let byte_s = 10.0 / 9600.0;
    // Per session: ENQ, ACK, telegram (25), ACK, EOT; T_GAP between sessions.
    let reference = 470.0 * 29.0 * byte_s + 469.0 * T_GAP.as_secs_f64();
    (clock.now().as_secs_f64(), reference)
}

fn upload(c: &mut Criterion) {
    let (took, reference) = upload_470();
    println!(
        "upload 470 instructions at 9600 baud: {took:.4} s virtual, wire + gaps {reference:.4} s, ratio {:.4}",
        took / reference
    );
    let mut group = c.benchmark_group("upload");
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(3));
    group.bench_function("470_instructions_9600_baud_virtual_time", |b| {
        b.iter(|| black_box(upload_470()))
    });
    group.finish();
}

/// A robot client in a status exchange with a silent robot on a pipe, cancelled from this thread
/// 2 ms after the exchange began: the time from `cancel` until the waiting thread has returned
/// (the join included).
fn cancel_latency(c: &mut Criterion) {
    c.bench_function("cancel_latency/robot_client_status", |b| {
        b.iter_custom(|iters| {
            paths::link::contract::time_cancels(iters, || {
                let (host, robot) = asea_protocol::link::Pipe::pair();
                let mut client = Client::new(host, ClientConfig::default());
                let token = client.cancel_token();
                (token, move || {
                    let _robot = robot;
                    matches!(client.status(), Err(asea_protocol::Error::Cancelled))
                })
            })
        })
    });
}

criterion_group!(benches, codec, upload, cancel_latency);
criterion_main!(benches);
