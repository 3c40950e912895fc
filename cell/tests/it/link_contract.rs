//! The byte-link contract (`paths::link::contract`) on the links `cell` puts around a device
//! link: the recording taps (robot and indexer) and the simulators' stop tap, each over a pipe.

use std::sync::Arc;

use asea_protocol::FrameConfig;
use cell::record::linktap::{LinkTap, RecordSlot};
use cell::run::device::{Timebase, WallClock};
use cell::sim::wiretap::{StopPattern, StopTap};
use paths::link::Pipe;
use paths::link::contract::{self, Pair};

#[test]
fn the_recording_taps_keep_the_contract() {
    let time: Arc<dyn Timebase> = Arc::new(WallClock::new());
    let (near, far) = Pipe::pair();
    let robot = LinkTap::robot(
        near,
        FrameConfig::default(),
        RecordSlot::default(),
        time.clone(),
    );
    contract::check(&mut Pair::new(robot, far));
    let (near, far) = Pipe::pair();
    let indexer = LinkTap::indexer(near, RecordSlot::default(), time);
    contract::check(&mut Pair::new(indexer, far));
}

#[test]
fn the_stop_tap_keeps_the_contract() {
    let (near, far) = Pipe::pair();
    let (tap, _) = StopTap::new(near, StopPattern::robot(&FrameConfig::default()));
    let (tap, _) = tap.with_trace();
    contract::check(&mut Pair::new(tap, far));
    let (near, far) = Pipe::pair();
    let (tap, _) = StopTap::new(near, StopPattern::IndexerStop);
    contract::check(&mut Pair::new(tap, far));
}
