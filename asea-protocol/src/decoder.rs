//! The incremental decoder: bytes in, tokens out; framed by LEN, resynchronising after noise
//! (docs/protocol.md §3).
//!
//! Outside a frame, ENQ, ACK, NAK and EOT are control tokens, STX opens a frame and any other byte
//! is stray. Inside a frame every byte is data: the frame ends after LEN data bytes, ETX and the
//! check value. A bad frame drops only its STX and the bytes after it are scanned again, so a
//! garbage prefix never hides the good frame that follows.

use crate::error::FrameError;
use crate::frame::{self, ACK, ENQ, EOT, Frame, FrameConfig, NAK, Parsed, STX};

/// One decoded unit of the byte stream.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Token {
    /// ENQ, ACK, NAK or EOT outside a frame.
    Control(u8),
    /// A good frame.
    Frame(Frame),
    /// A bad frame (answer NAK).
    Bad(FrameError),
    /// Any other byte outside a frame.
    Stray(u8),
}

/// Incremental, length-framed decoder.
#[derive(Debug, Clone, Default)]
pub struct Decoder {
    cfg: FrameConfig,
    buf: Vec<u8>,
    start: usize,
}

impl Decoder {
    /// A decoder for frames under `cfg`.
    pub fn new(cfg: FrameConfig) -> Self {
        Decoder {
            cfg,
            buf: Vec::with_capacity(64),
            start: 0,
        }
    }

    /// Appends received bytes.
    pub fn push(&mut self, bytes: &[u8]) {
        if self.start > 0 && self.start == self.buf.len() {
            self.buf.clear();
            self.start = 0;
        } else if self.start > 4096 {
            self.buf.drain(..self.start);
            self.start = 0;
        }
        self.buf.extend_from_slice(bytes);
    }

    /// True while a frame has started and is not complete.
    pub fn in_frame(&self) -> bool {
        self.buf.get(self.start) == Some(&STX)
    }

    /// Bytes buffered and not yet decoded.
    pub fn pending(&self) -> usize {
        self.buf.len() - self.start
    }

    /// Drops everything buffered.
    pub fn clear(&mut self) {
        self.buf.clear();
        self.start = 0;
    }

    /// The next token, or `None` when more bytes are needed.
    pub fn next_token(&mut self) -> Option<Token> {
        let rest = self.buf.get(self.start..)?;
        let &first = rest.first()?;
        if first != STX {
            self.start += 1;
            return Some(match first {
                ENQ | ACK | NAK | EOT => Token::Control(first),
                other => Token::Stray(other),
            });
        }
        match frame::parse(&self.cfg, rest) {
            Parsed::Incomplete => None,
            Parsed::Frame { frame, used } => {
                self.start += used;
                Some(Token::Frame(frame))
            }
            Parsed::Bad(e) => {
                // Resync: drop the STX only and rescan what followed it.
                self.start += 1;
                Some(Token::Bad(e))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::{ETX, encode};

    fn all(d: &mut Decoder) -> Vec<Token> {
        std::iter::from_fn(|| d.next_token()).collect()
    }

    #[test]
    fn byte_by_byte_and_controls() {
        let cfg = FrameConfig::default();
        let mut d = Decoder::new(cfg);
        let f = encode(&cfg, 0x02, &[3]).unwrap();
        d.push(&[ENQ, 0x41]);
        assert_eq!(all(&mut d), [Token::Control(ENQ), Token::Stray(0x41)]);
        for (i, b) in f.iter().enumerate() {
            d.push(&[*b]);
            let t = all(&mut d);
            if i + 1 < f.len() {
                assert!(t.is_empty());
                assert!(d.in_frame());
            } else {
                assert_eq!(
                    t,
                    [Token::Frame(Frame {
                        code: 2,
                        data: vec![3]
                    })]
                );
            }
        }
        assert_eq!(d.pending(), 0);
    }

    /// The buffer is emptied once everything in it is decoded and compacted once more than
    /// 4096 decoded bytes lie before an unfinished frame, and neither loses the unfinished frame.
    #[test]
    fn memory_stays_bounded_and_a_partial_frame_survives() {
        let cfg = FrameConfig::default();
        let f = encode(&cfg, 0x02, &[3]).unwrap();
        let mut d = Decoder::new(cfg);
        // An ENQ, then the first three bytes of a frame.
        d.push(&[ENQ]);
        d.push(&f[..3]);
        assert_eq!(d.next_token(), Some(Token::Control(ENQ)));
        assert_eq!(d.next_token(), None);
        assert_eq!(d.pending(), 3);
        d.push(&f[3..]);
        assert_eq!(
            all(&mut d),
            [Token::Frame(Frame {
                code: 2,
                data: vec![3]
            })]
        );
        assert_eq!(d.pending(), 0);
        // Everything decoded: the next bytes start an empty buffer.
        d.push(&[EOT]);
        assert_eq!(d.buf.len(), 1);
        assert_eq!(all(&mut d), [Token::Control(EOT)]);

        // 5000 stray bytes decoded ahead of an unfinished frame: the next push drops them.
        d.clear();
        d.push(&[0x41; 5000]);
        d.push(&f[..2]);
        assert_eq!(all(&mut d).len(), 5000);
        assert_eq!(d.pending(), 2);
        d.push(&f[2..4]);
        assert_eq!(d.buf.len(), 4);
        assert_eq!(d.pending(), 4);
        d.push(&f[4..]);
        assert_eq!(
            all(&mut d),
            [Token::Frame(Frame {
                code: 2,
                data: vec![3]
            })]
        );
    }

    #[test]
    fn resyncs_after_bogus_stx() {
        let cfg = FrameConfig::default();
        let mut d = Decoder::new(cfg);
        // A bogus STX whose "LEN" (0x30) swallows the real frame; then the real frame.
        d.push(&[STX, 0x01, 0x30, 0x55]);
        d.push(&encode(&cfg, 0x06, &[0]).unwrap());
        d.push(&[0u8; 0x30]);
        let t = all(&mut d);
        assert!(matches!(t.first(), Some(Token::Bad(_))), "{t:?}");
        assert!(t.contains(&Token::Frame(Frame {
            code: 6,
            data: vec![0]
        })));
        // A frame whose ETX is missing.
        d.clear();
        d.push(&[STX, 2, 1, 3, 0x00, 9, ETX]);
        assert!(matches!(
            d.next_token(),
            Some(Token::Bad(FrameError::MissingEtx { .. }))
        ));
    }
}
