//! One hour of simulated mandrel motion on the virtual clock (target: < 50 ms), and the X
//! client's cancel latency: from the token being set to a blocked wait returning (the stop path
//! counts on about a millisecond, docs/ARCHITECTURE.md).
//!
//! `cargo bench -p mandrel-drive --features bench --bench sim -- --warm-up-time 1 --measurement-time 3`

use criterion::{Criterion, criterion_group, criterion_main};
use mandrel_drive::Drive;
use mandrel_drive::profile::StepProfile;
use mandrel_drive::sim::Machine;
use mandrel_drive::sim::machine::PULL_IN_SPS;

/// An hour of winding-like motion: preset moves of 1–3 mandrel turns at the thesis drive's
/// speeds, a constant-velocity stretch, back and forth, sampled every 10 ms of simulated time.
fn one_hour() -> i64 {
    let drive = Drive::default();
    let mut m = Machine::new(drive, PULL_IN_SPS);
    m.profile = StepProfile {
        v0_sps: 400.0,
        vmax_sps: 8_000.0,
        accel_sps2: 20_000.0,
    };
    let dt = 0.01;
    let mut t = 0.0;
    let mut k = 0i64;
    let mut checksum = 0i64;
    while t < 3600.0 {
        if !m.is_moving() {
            k += 1;
            if k % 50 == 0 {
                let _ = m.start_continuous(if k % 100 == 0 { 1 } else { -1 });
            } else {
                let _ = m.start_preset((1 + k % 3) * 1846 * if k % 2 == 0 { 1 } else { -1 });
            }
        } else if k % 50 == 0 && m.rate_sps() >= 8_000.0 {
            m.stop();
        }
        t += dt;
        m.advance(t);
        checksum = checksum.wrapping_add(m.motor_steps());
    }
    checksum
}

fn bench(c: &mut Criterion) {
    c.bench_function("sim_one_hour_virtual_clock", |b| b.iter(one_hour));
}

/// An X client waiting for a move's completion on a pipe whose card is silent, cancelled from
/// this thread 2 ms after the wait began: the time from `cancel` until the waiting thread has
/// returned (the join included).
fn cancel_latency(c: &mut Criterion) {
    use mandrel_drive::{Error, IndexerConfig, Pipe, XClient};
    c.bench_function("cancel_latency/x_client_wait", |b| {
        b.iter_custom(|iters| {
            paths::link::contract::time_cancels(iters, || {
                let (host, card) = Pipe::pair();
                let mut x = XClient::new(host, IndexerConfig::default());
                let token = x.cancel_token();
                let wait = move || {
                    let _card = card;
                    matches!(
                        x.wait_complete(std::time::Duration::from_secs(30)),
                        Err(Error::Cancelled)
                    )
                };
                (token, wait)
            })
        })
    });
}

criterion_group!(benches, bench, cancel_latency);
criterion_main!(benches);
