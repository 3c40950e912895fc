//! Arbitrary bytes, fed in arbitrary chunks, through the decoder, the telegram parsers and both
//! session state machines: nothing may panic.
//!
//! `cd fuzz && cargo +nightly fuzz run decoder`

#![no_main]

use std::time::Duration;

use asea_protocol::frame::{Checksum, FrameConfig};
use asea_protocol::session::{Host, RobotSession, Timers};
use asea_protocol::{Command, Decoder, Reply, Token};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&mode, rest)) = data.split_first() else {
        return;
    };
    let cfg = FrameConfig {
        checksum: if mode & 1 == 0 {
            Checksum::Sum8
        } else {
            Checksum::Crc16
        },
        ..FrameConfig::default()
    };
    let chunk = usize::from(mode >> 1).max(1);
    let mut dec = Decoder::new(cfg);
    let mut robot = RobotSession::new(cfg, Timers::default());
    let mut host = Host::new(cfg, Timers::default());
    host.start(vec![0x02, 0x0C, 0x00, 0x03, 0x0F], mode & 2 != 0, Duration::ZERO);
    let mut now = Duration::ZERO;
    for part in rest.chunks(chunk) {
        now += Duration::from_millis(u64::from(part[0] % 50));
        dec.push(part);
        while let Some(t) = dec.next_token() {
            if let Token::Frame(f) = t {
                let _ = Command::from_frame(&f);
                let _ = Reply::from_frame(&f);
            }
        }
        let _ = robot.on_bytes(part, now);
        robot.on_time(now);
        let _ = robot.take_output();
        host.on_bytes(part, now);
        host.on_time(now);
        let _ = host.take_output();
        let _ = host.take_outcome();
    }
});
