//! The byte-link contract (`paths::link::contract`) on this crate's serial link, and the X
//! client on the shared plumbing: its timeouts run on its clock (a virtual clock drives them),
//! and a cancelled exchange ends within one poll period.

use std::io;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use mandrel_drive::link::{Cancel, Link, Pipe, SerialLink, VirtualClock};
use mandrel_drive::xlang::Command;
use mandrel_drive::{Error, Indexer, IndexerConfig, XClient};
use paths::link::contract::{self, Pair};
use paths::link::{Clock as _, POLL_PERIOD};

/// The serial link on a pseudo-terminal pair: the slave end checked, the master its far end.
#[cfg(unix)]
#[test]
fn the_serial_link_keeps_the_contract_on_a_pseudo_terminal() {
    let (master, slave) = SerialLink::pty_pair().unwrap();
    contract::check(&mut Pair::new(slave, master).with_arrival(Box::new(|near| near.waiting())));
}

/// A quiet line in virtual time: nothing ever arrives, a read lets its timeout pass on the
/// clock, and the armed cancel token is set when the clock reaches its time.
#[derive(Debug)]
struct QuietLine {
    clock: VirtualClock,
    cancel_at: Arc<Mutex<Option<(Duration, Cancel)>>>,
}

impl Link for QuietLine {
    fn write_all(&mut self, _: &[u8]) -> io::Result<()> {
        Ok(())
    }
    fn read_timeout(&mut self, _: &mut [u8], timeout: Duration) -> io::Result<usize> {
        let end = self.clock.now() + timeout;
        let mut armed = self.cancel_at.lock().unwrap();
        if let Some((at, cancel)) = armed.as_ref()
            && *at <= end
        {
            self.clock.advance_to(*at);
            cancel.cancel();
            *armed = None;
        }
        self.clock.advance_to(end);
        Ok(0)
    }
    fn discard_input(&mut self) -> io::Result<()> {
        Ok(())
    }
}

/// An X client on a quiet line on `clock`, and the slot that arms its cancel token.
type Armed = Arc<Mutex<Option<(Duration, Cancel)>>>;

fn quiet_client(clock: &VirtualClock) -> (XClient<QuietLine, VirtualClock>, Armed) {
    let armed = Armed::default();
    let line = QuietLine {
        clock: clock.clone(),
        cancel_at: armed.clone(),
    };
    (
        XClient::with_clock(line, clock.clone(), IndexerConfig::default()),
        armed,
    )
}

/// On a virtual clock the X client's reply timeout (500 ms by default) and a move's wait are
/// virtual time: each ends exactly when its time has passed on the clock, at once in wall time.
#[test]
fn the_x_client_times_out_on_its_clock() {
    let clock = VirtualClock::new();
    let (mut c, _) = quiet_client(&clock);
    let t0 = Instant::now();
    let reply = IndexerConfig::default().reply_timeout;
    let e = c.send(&Command::Status).unwrap_err();
    assert!(matches!(e, Error::Timeout { waited_ms: 500, .. }), "{e:?}");
    assert_eq!(clock.now(), reply);
    let e = c.wait_complete(Duration::from_secs(3600)).unwrap_err();
    assert!(
        matches!(
            e,
            Error::MoveTimeout {
                waited_ms: 3_600_000
            }
        ),
        "{e:?}"
    );
    assert_eq!(clock.now(), reply + Duration::from_secs(3600));
    // A pause (the reset wait of `init`, the polls of `wait_idle`) is on the clock as well.
    c.pause(Duration::from_millis(250)).unwrap();
    assert_eq!(clock.now(), reply + Duration::from_millis(3_600_250));
    assert!(t0.elapsed() < Duration::from_secs(10), "{:?}", t0.elapsed());
}

/// A wait cancelled at 5 ms of the client's clock ends by the end of the poll period in which
/// the token was set.
#[test]
fn a_cancelled_x_exchange_ends_within_a_poll_period_of_its_clock() {
    let clock = VirtualClock::new();
    let (mut c, armed) = quiet_client(&clock);
    let at = Duration::from_micros(5_300);
    *armed.lock().unwrap() = Some((at, c.cancel_token()));
    let e = c.wait_complete(Duration::from_secs(30)).unwrap_err();
    assert!(matches!(e, Error::Cancelled), "{e:?}");
    let late = clock.now() - at;
    assert!(late <= POLL_PERIOD, "{late:?}");
}

/// The X client on a pipe whose card is silent, cancelled from another thread: the wait ends
/// within a poll period of the token being set, the rest being the threads' scheduling (20 ms
/// allowed on a loaded machine); the stop still goes out while the token is set.
#[test]
fn a_blocked_x_wait_is_cancelled_from_another_thread() {
    let (host, mut card) = Pipe::pair();
    let mut c = XClient::new(host, IndexerConfig::default());
    let token = c.cancel_token();
    let canceller = std::thread::spawn(move || {
        std::thread::sleep(Duration::from_millis(50));
        let at = Instant::now();
        token.cancel();
        (at, token)
    });
    let e = c.wait_complete(Duration::from_secs(30)).unwrap_err();
    let done = Instant::now();
    let (at, token) = canceller.join().unwrap();
    assert!(matches!(e, Error::Cancelled), "{e:?}");
    let took = done.duration_since(at);
    assert!(took <= POLL_PERIOD + Duration::from_millis(20), "{took:?}");
    c.stop_on_wire().unwrap();
    let mut buf = [0u8; 8];
    let n = card
        .read_timeout(&mut buf, Duration::from_millis(100))
        .unwrap();
    assert_eq!(&buf[..n], b"1S\r");
    token.reset();
}
