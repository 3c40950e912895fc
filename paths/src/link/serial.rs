//! The serial-port link, written once and instantiated in each device crate
//! ([`crate::serial_link`]): `paths` does no device I/O and does not depend on the serial-port
//! library; the device crates do, and each states its own line settings.

/// Defines `SerialLink<P>`, a serial port (the `serialport` library's boxed port, or a
/// pseudo-terminal end `serialport::TTYPort` on Unix) as a [`crate::link::Link`], in the crate
/// that invokes it (which depends on `serialport`). Writing waits until the bytes are handed to
/// the line; a read waits at least a millisecond (the port's resolution), a quiet line being 0
/// bytes ([`crate::link::quiet_as_zero`]); stale input is what the port counts as waiting, read
/// and dropped without waiting (tcflush is not reliable on every pty implementation, and a wait
/// would swallow a prompt answer).
#[macro_export]
macro_rules! serial_link {
    () => {
        /// A serial port as a [`Link`](paths::link::Link): a boxed port or a pseudo-terminal end
        /// (`serialport::TTYPort`). It dereferences to the port.
        #[derive(Debug)]
        pub struct SerialLink<P>(pub P);

        impl<P> ::std::ops::Deref for SerialLink<P> {
            type Target = P;
            fn deref(&self) -> &P {
                &self.0
            }
        }

        impl<P> ::std::ops::DerefMut for SerialLink<P> {
            fn deref_mut(&mut self) -> &mut P {
                &mut self.0
            }
        }

        impl<P: ::serialport::SerialPort + ?Sized> SerialLink<Box<P>> {
            /// Bytes waiting to be read.
            pub fn waiting(&self) -> ::std::io::Result<usize> {
                self.0
                    .bytes_to_read()
                    .map(|n| n as usize)
                    .map_err(::std::io::Error::from)
            }
        }

        impl<P: ::serialport::SerialPort + ?Sized> $crate::link::Link for SerialLink<Box<P>> {
            fn write_all(&mut self, bytes: &[u8]) -> ::std::io::Result<()> {
                ::std::io::Write::write_all(&mut self.0, bytes)?;
                ::std::io::Write::flush(&mut self.0)
            }
            fn read_timeout(
                &mut self,
                buf: &mut [u8],
                timeout: ::std::time::Duration,
            ) -> ::std::io::Result<usize> {
                self.0
                    .set_timeout(timeout.max(::std::time::Duration::from_millis(1)))
                    .map_err(::std::io::Error::from)?;
                $crate::link::quiet_as_zero(::std::io::Read::read(&mut self.0, buf))
            }
            fn discard_input(&mut self) -> ::std::io::Result<()> {
                let mut scratch = [0u8; 256];
                loop {
                    let n = self.waiting()?.min(scratch.len());
                    if n == 0
                        || ::std::io::Read::read(
                            &mut self.0,
                            scratch.get_mut(..n).unwrap_or_default(),
                        )? == 0
                    {
                        return Ok(());
                    }
                }
            }
        }

        #[cfg(unix)]
        impl SerialLink<Box<::serialport::TTYPort>> {
            /// Both ends of a new pseudo-terminal pair, (master, slave).
            pub fn pty_pair() -> ::std::result::Result<(Self, Self), ::serialport::Error> {
                let (master, slave) = ::serialport::TTYPort::pair()?;
                Ok((SerialLink(Box::new(master)), SerialLink(Box::new(slave))))
            }
        }
    };
}
