//! The byte link to an indexer: a serial port, or an in-memory duplex pipe.

use std::collections::VecDeque;
use std::io::{self, Write};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

/// A byte link: write, read with a timeout, discard stale input.
pub trait Link: Send {
    /// Writes all of `bytes`.
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()>;
    /// Reads at least one byte into `buf` within `timeout`; `Ok(0)` on timeout.
    fn read_timeout(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize>;
    /// Drops any input received and not yet read.
    fn discard_input(&mut self) -> io::Result<()>;
}

fn serial_read<P: serialport::SerialPort + ?Sized>(
    port: &mut P,
    buf: &mut [u8],
    timeout: Duration,
) -> io::Result<usize> {
    port.set_timeout(timeout.max(Duration::from_millis(1)))
        .map_err(io::Error::from)?;
    match port.read(buf) {
        Ok(n) => Ok(n),
        // A signal arriving during the wait is a short read, not a failure.
        Err(e)
            if matches!(
                e.kind(),
                io::ErrorKind::TimedOut | io::ErrorKind::WouldBlock | io::ErrorKind::Interrupted
            ) =>
        {
            Ok(0)
        }
        Err(e) => Err(e),
    }
}

impl Link for Box<dyn serialport::SerialPort> {
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        Write::write_all(self, bytes)?;
        self.flush()
    }
    fn read_timeout(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        serial_read(self.as_mut(), buf, timeout)
    }
    fn discard_input(&mut self) -> io::Result<()> {
        self.clear(serialport::ClearBuffer::Input)
            .map_err(io::Error::from)
    }
}

#[cfg(unix)]
impl Link for serialport::TTYPort {
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        Write::write_all(self, bytes)?;
        self.flush()
    }
    fn read_timeout(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        serial_read(self, buf, timeout)
    }
    fn discard_input(&mut self) -> io::Result<()> {
        // Drain what has arrived; tcflush is not reliable on every pty implementation.
        let mut scratch = [0u8; 256];
        while serial_read(self, &mut scratch, Duration::from_millis(1))? > 0 {}
        Ok(())
    }
}

#[derive(Debug, Default)]
struct Queue {
    bytes: Mutex<VecDeque<u8>>,
    ready: Condvar,
}

/// One end of an in-memory duplex byte pipe.
#[derive(Debug, Clone)]
pub struct Pipe {
    rx: Arc<Queue>,
    tx: Arc<Queue>,
}

impl Pipe {
    /// Two connected ends.
    pub fn pair() -> (Pipe, Pipe) {
        let a = Arc::new(Queue::default());
        let b = Arc::new(Queue::default());
        (
            Pipe {
                rx: a.clone(),
                tx: b.clone(),
            },
            Pipe { rx: b, tx: a },
        )
    }
}

fn poisoned() -> io::Error {
    io::Error::other("pipe lock poisoned")
}

impl Link for Pipe {
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.tx
            .bytes
            .lock()
            .map_err(|_| poisoned())?
            .extend(bytes.iter().copied());
        self.tx.ready.notify_all();
        Ok(())
    }

    fn read_timeout(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        let deadline = Instant::now() + timeout;
        let mut q = self.rx.bytes.lock().map_err(|_| poisoned())?;
        while q.is_empty() {
            let now = Instant::now();
            if now >= deadline {
                return Ok(0);
            }
            q = self
                .rx
                .ready
                .wait_timeout(q, deadline - now)
                .map_err(|_| poisoned())?
                .0;
        }
        let n = buf.len().min(q.len());
        for (slot, byte) in buf.iter_mut().zip(q.drain(..n)) {
            *slot = byte;
        }
        Ok(n)
    }

    fn discard_input(&mut self) -> io::Result<()> {
        self.rx.bytes.lock().map_err(|_| poisoned())?.clear();
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pipe_carries_bytes_both_ways() {
        let (mut a, mut b) = Pipe::pair();
        a.write_all(b"1R\r").unwrap();
        let mut buf = [0u8; 8];
        assert_eq!(
            b.read_timeout(&mut buf, Duration::from_millis(10)).unwrap(),
            3
        );
        assert_eq!(&buf[..3], b"1R\r");
        assert_eq!(
            a.read_timeout(&mut buf, Duration::from_millis(1)).unwrap(),
            0
        );
        b.write_all(b"junk").unwrap();
        a.discard_input().unwrap();
        assert_eq!(
            a.read_timeout(&mut buf, Duration::from_millis(1)).unwrap(),
            0
        );
    }

    /// Reads from `link` until `n` bytes have come (or a second has passed).
    fn read_all(link: &mut dyn Link, n: usize) -> Vec<u8> {
        let mut got = Vec::new();
        let t0 = Instant::now();
        let mut buf = [0u8; 16];
        while got.len() < n && t0.elapsed() < Duration::from_secs(1) {
            let k = link
                .read_timeout(&mut buf, Duration::from_millis(20))
                .unwrap();
            got.extend_from_slice(&buf[..k]);
        }
        got
    }

    /// Waits until input is waiting on `port` (a pty delivers a write a moment later).
    #[cfg(unix)]
    fn wait_for_input(port: &dyn serialport::SerialPort) {
        let t0 = Instant::now();
        while port.bytes_to_read().unwrap() == 0 && t0.elapsed() < Duration::from_secs(1) {
            std::thread::sleep(Duration::from_millis(1));
        }
        assert!(port.bytes_to_read().unwrap() > 0, "nothing arrived");
    }

    /// The serial-port links on a pseudo-terminal pair (no hardware): bytes written on one end
    /// are read on the other, a read with nothing waiting times out as 0 bytes, and input
    /// waiting is discarded, on the port itself and boxed (as `open_serial` returns it).
    #[cfg(unix)]
    #[test]
    fn serial_ports_carry_bytes_time_out_and_discard_input() {
        let (mut a, mut b) = serialport::TTYPort::pair().unwrap();
        Link::write_all(&mut a, b"1R\r").unwrap();
        assert_eq!(read_all(&mut b, 3), b"1R\r");
        let mut buf = [0u8; 8];
        assert_eq!(
            b.read_timeout(&mut buf, Duration::from_millis(20)).unwrap(),
            0
        );
        // More than one read's worth (256 bytes) waiting: every byte of it goes.
        Link::write_all(&mut a, &[b'x'; 600]).unwrap();
        let t0 = Instant::now();
        while serialport::SerialPort::bytes_to_read(&b).unwrap() < 600
            && t0.elapsed() < Duration::from_secs(1)
        {
            std::thread::sleep(Duration::from_millis(1));
        }
        assert_eq!(serialport::SerialPort::bytes_to_read(&b).unwrap(), 600);
        b.discard_input().unwrap();
        assert_eq!(
            b.read_timeout(&mut buf, Duration::from_millis(50)).unwrap(),
            0
        );

        let (mut a, b) = serialport::TTYPort::pair().unwrap();
        let mut boxed: Box<dyn serialport::SerialPort> = Box::new(b);
        Link::write_all(&mut boxed, b"1G\r").unwrap();
        assert_eq!(read_all(&mut a, 3), b"1G\r");
        Link::write_all(&mut a, b"*\r").unwrap();
        assert_eq!(read_all(&mut boxed, 2), b"*\r");
        Link::write_all(&mut a, b"stale").unwrap();
        wait_for_input(boxed.as_ref());
        Link::discard_input(&mut boxed).unwrap();
        assert_eq!(
            boxed
                .read_timeout(&mut buf, Duration::from_millis(50))
                .unwrap(),
            0
        );
    }

    /// A port whose other end has gone is an error, not a quiet line.
    #[cfg(unix)]
    #[test]
    fn a_serial_port_whose_other_end_closed_is_an_error() {
        let (a, mut b) = serialport::TTYPort::pair().unwrap();
        drop(a);
        let mut buf = [0u8; 8];
        assert!(b.read_timeout(&mut buf, Duration::from_millis(50)).is_err());
    }
}
