//! Real sync lines on a serial port's modem-control pins (feature `hardware`).
//!
//! Needs a port wired as in docs/hardware.md, or a loop-back plug (RTS→CTS, DTR→DSR):
//! `WINDCELL_SYNC_PORT=/dev/ttyUSB0 cargo test -p mandrel-drive --features hardware -- --ignored`
#![cfg(feature = "hardware")]

use std::sync::{Arc, Mutex};
use std::time::Duration;

use mandrel_drive::sync::{ModemLine, Pin, SyncInput, SyncOutput};

fn port() -> Arc<Mutex<Box<dyn serialport::SerialPort>>> {
    let path = std::env::var("WINDCELL_SYNC_PORT").expect("set WINDCELL_SYNC_PORT");
    let port = serialport::new(path, 9600)
        .timeout(Duration::from_millis(100))
        .open()
        .expect("open the sync port");
    Arc::new(Mutex::new(port))
}

#[test]
#[ignore = "needs a serial port with a loop-back plug (RTS→CTS, DTR→DSR)"]
fn loop_back_follows_the_outputs() {
    let port = port();
    for (out_pin, in_pin) in [(Pin::Rts, Pin::Cts), (Pin::Dtr, Pin::Dsr)] {
        let mut out = ModemLine::new(port.clone(), out_pin, false);
        let mut input = ModemLine::new(port.clone(), in_pin, false);
        for level in [true, false, true] {
            out.set(level).unwrap();
            std::thread::sleep(Duration::from_millis(20));
            assert_eq!(input.level().unwrap(), level, "{out_pin:?} → {in_pin:?}");
        }
        out.set(false).unwrap();
    }
}
