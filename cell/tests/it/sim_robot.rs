//! `windcell sim-robot --pty`: the binary prints its pty path, a client uploads, reads back and
//! runs a program over it as over a serial port, and SIGTERM ends it with exit code 0.

use crate::common;

use asea_protocol::link::SerialLink;

use std::time::Duration;

use asea_protocol::{
    Client, ClientConfig, Control, Flags, Instruction, Pose, Positioning, Speed, State, Zone,
};

#[test]
fn serves_a_client_and_stops_on_sigterm() {
    let (child, path) = common::serve_on_pty(&["sim-robot", "--pty", "--home-s", "0.2"]);

    let port = SerialLink(Box::new(
        serialport::new(&path, 9600)
            .timeout(Duration::from_millis(100))
            .open_native()
            .expect("open pty"),
    ));
    let mut c = Client::new(port, ClientConfig::default());
    let p = |z: f64| {
        Instruction::Position(Positioning {
            flags: Flags {
                zone: Zone::Medium,
                ..Flags::default()
            },
            pose: Pose::from_mm([900.0, 0.0, z], [1.0, 0.0, 0.0, 0.0]).unwrap(),
            speed: Speed::from_value("speed", 1.0).unwrap(),
        })
    };
    let prog = [
        p(800.0),
        p(802.0),
        Instruction::Control(Control::SetOutput { line: 1, on: true }),
        Instruction::Control(Control::End),
    ];
    c.upload(3, &prog).unwrap();
    assert_eq!(c.verify(3, &prog).unwrap().restored, 0);
    c.operate().unwrap();
    c.sync_home().unwrap();
    // Home synchronisation takes 0.2 s here (--home-s).
    std::thread::sleep(Duration::from_millis(300));
    assert!(c.check_status().unwrap().homed);
    c.run_program(3).unwrap();
    let s = c.check_status().unwrap();
    assert_eq!((s.state, s.program), (State::Running, 3));

    common::stop_cleanly(child);
}

#[test]
fn serves_on_a_pty_without_the_flag_too() {
    // The pseudo-terminal is the only transport, so it is the default.
    let (child, path) = common::serve_on_pty(&["sim-robot"]);
    assert!(std::path::Path::new(&path).exists(), "{path}");
    common::stop_cleanly(child);
}
