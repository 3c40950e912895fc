//! Framing and check values (docs/protocol.md §2, §3; seed 001 §5.2).
//!
//! ```text
//! STX | CMD | LEN | DATA[LEN] | ETX | CS
//! ```
//!
//! The thesis (§5.2) gives the order: start of text, a header with the command and the telegram
//! length, the command data, end of text, then "a byte containing the sum of the message bytes".
//! Which bytes the sum spans and how wide it is are our choice ([`DEFAULT_CHECKSUM_SPAN`],
//! [`DEFAULT_CHECKSUM`]), each kept in one constant so that it can change when a real controller
//! is met.

use crate::error::{EncodeError, FrameError};

/// Start of text.
pub const STX: u8 = 0x02;
/// End of text.
pub const ETX: u8 = 0x03;
/// End of transmission.
pub const EOT: u8 = 0x04;
/// Enquiry: opens a session.
pub const ENQ: u8 = 0x05;
/// Acknowledge.
pub const ACK: u8 = 0x06;
/// Negative acknowledge: busy (to ENQ) or "retransmit" (to a telegram).
pub const NAK: u8 = 0x15;

/// Header bytes after STX: CMD and LEN.
pub const HEADER_LEN: usize = 2;

/// Which bytes the check value covers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ChecksumSpan {
    /// CMD, LEN, DATA and ETX (STX excluded), as ASTM E1381 (spec §5.3, the default).
    #[default]
    AfterStxThroughEtx,
    /// STX through ETX.
    StxThroughEtx,
    /// CMD, LEN and DATA only.
    TelegramOnly,
}

/// The check value after ETX.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Checksum {
    /// One byte: the sum of the spanned bytes mod 256 (seed 001 §5.2, spec §5.3; the default).
    /// Two corrupted bytes whose errors cancel in the sum pass undetected.
    #[default]
    Sum8,
    /// Two bytes, big-endian: CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF) over the span. Not
    /// in the thesis; an opt-in for links where both ends can be configured.
    Crc16,
}

impl Checksum {
    /// Bytes the check value takes on the wire.
    pub const fn width(self) -> usize {
        match self {
            Checksum::Sum8 => 1,
            Checksum::Crc16 => 2,
        }
    }
}

/// The check value the link uses unless configured otherwise.
pub const DEFAULT_CHECKSUM: Checksum = Checksum::Sum8;
/// The span the link uses unless configured otherwise.
pub const DEFAULT_CHECKSUM_SPAN: ChecksumSpan = ChecksumSpan::AfterStxThroughEtx;
/// The largest LEN accepted by default (the longest telegram, a read-back reply, carries 21).
pub const DEFAULT_MAX_LEN: u8 = 64;

/// Framing choices shared by both ends of a link.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameConfig {
    /// Check value.
    pub checksum: Checksum,
    /// Bytes it covers.
    pub span: ChecksumSpan,
    /// Largest LEN a receiver accepts; more is a framing error (NAK).
    pub max_len: u8,
}

impl Default for FrameConfig {
    fn default() -> Self {
        FrameConfig {
            checksum: DEFAULT_CHECKSUM,
            span: DEFAULT_CHECKSUM_SPAN,
            max_len: DEFAULT_MAX_LEN,
        }
    }
}

impl FrameConfig {
    /// Bytes on the wire for a telegram with `len` data bytes.
    pub const fn frame_len(&self, len: usize) -> usize {
        1 + HEADER_LEN + len + 1 + self.checksum.width()
    }
}

/// A framed telegram: command code and data, before typing (see [`crate::command`]).
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct Frame {
    /// The command or reply code.
    pub code: u8,
    /// The data bytes (LEN of them).
    pub data: Vec<u8>,
}

const CRC_TABLE: [u16; 256] = crc_table();

const fn crc_table() -> [u16; 256] {
    let mut table = [0u16; 256];
    let mut i = 0;
    while i < 256 {
        let mut crc = (i as u16) << 8;
        let mut bit = 0;
        while bit < 8 {
            crc = if crc & 0x8000 != 0 {
                (crc << 1) ^ 0x1021
            } else {
                crc << 1
            };
            bit += 1;
        }
        table[i] = crc;
        i += 1;
    }
    table
}

/// The digest the robot reports for the last telegram it executed ([`crate::Status::last_digest`]):
/// CRC-16/CCITT-FALSE over CMD, LEN and DATA, whatever check value the link uses. Unlike the
/// thesis's one-byte sum it sees the position of every byte, so a corrupted twin that the sum let
/// through has, but for one chance in 65 536, another digest than the telegram sent.
pub fn telegram_digest(code: u8, data: &[u8]) -> u16 {
    let cfg = FrameConfig {
        checksum: Checksum::Crc16,
        span: ChecksumSpan::TelegramOnly,
        ..FrameConfig::default()
    };
    check_value(&cfg, code, data)
}

/// Check value of `code`, `data` under `cfg` (the frame around them is implied).
pub fn check_value(cfg: &FrameConfig, code: u8, data: &[u8]) -> u16 {
    let len = data.len() as u8;
    let head: &[u8] = match cfg.span {
        ChecksumSpan::StxThroughEtx => &[STX],
        _ => &[],
    };
    let tail: &[u8] = match cfg.span {
        ChecksumSpan::TelegramOnly => &[],
        _ => &[ETX],
    };
    let parts = [head, &[code, len][..], data, tail];
    match cfg.checksum {
        Checksum::Sum8 => {
            let mut sum = 0u8;
            for part in parts {
                for &b in part {
                    sum = sum.wrapping_add(b);
                }
            }
            u16::from(sum)
        }
        Checksum::Crc16 => {
            let mut crc = 0xFFFFu16;
            for part in parts {
                for &b in part {
                    crc = (crc << 8) ^ CRC_TABLE[usize::from((crc >> 8) as u8 ^ b)];
                }
            }
            crc
        }
    }
}

/// Appends the frame of `code` + `data` to `out`.
pub fn encode_into(
    cfg: &FrameConfig,
    code: u8,
    data: &[u8],
    out: &mut Vec<u8>,
) -> Result<(), EncodeError> {
    if data.len() > usize::from(cfg.max_len) {
        return Err(EncodeError::TooLong {
            len: data.len(),
            max: usize::from(cfg.max_len),
        });
    }
    out.reserve(cfg.frame_len(data.len()));
    out.push(STX);
    out.push(code);
    out.push(data.len() as u8);
    out.extend_from_slice(data);
    out.push(ETX);
    let cs = check_value(cfg, code, data);
    match cfg.checksum {
        Checksum::Sum8 => out.push(cs as u8),
        Checksum::Crc16 => out.extend_from_slice(&cs.to_be_bytes()),
    }
    Ok(())
}

/// The frame of `code` + `data`.
pub fn encode(cfg: &FrameConfig, code: u8, data: &[u8]) -> Result<Vec<u8>, EncodeError> {
    let mut out = Vec::new();
    encode_into(cfg, code, data, &mut out)?;
    Ok(out)
}

/// Result of looking for one frame at the start of a buffer that begins with STX.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Parsed {
    /// More bytes are needed.
    Incomplete,
    /// A good frame of `used` bytes.
    Frame {
        /// The telegram.
        frame: Frame,
        /// Bytes it took.
        used: usize,
    },
    /// A bad frame.
    Bad(FrameError),
}

/// Parses the frame at the start of `buf` (which must begin with STX).
pub fn parse(cfg: &FrameConfig, buf: &[u8]) -> Parsed {
    let (Some(&code), Some(&len)) = (buf.get(1), buf.get(2)) else {
        return Parsed::Incomplete;
    };
    if len > cfg.max_len {
        return Parsed::Bad(FrameError::TooLong {
            len,
            max: cfg.max_len,
        });
    }
    let n = usize::from(len);
    let etx_at = 1 + HEADER_LEN + n;
    let total = etx_at + 1 + cfg.checksum.width();
    let Some(&etx) = buf.get(etx_at) else {
        return Parsed::Incomplete;
    };
    if etx != ETX {
        return Parsed::Bad(FrameError::MissingEtx { len, got: etx });
    }
    let Some(cs_bytes) = buf.get(etx_at + 1..total) else {
        return Parsed::Incomplete;
    };
    let data = buf.get(1 + HEADER_LEN..etx_at).unwrap_or_default();
    let received = match cs_bytes {
        [a] => u16::from(*a),
        [a, b] => u16::from_be_bytes([*a, *b]),
        _ => return Parsed::Incomplete,
    };
    let computed = check_value(cfg, code, data);
    if computed != received {
        return Parsed::Bad(FrameError::Checksum { computed, received });
    }
    Parsed::Frame {
        frame: Frame {
            code,
            data: data.to_vec(),
        },
        used: total,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// STX, CMD, LEN, the data, ETX and the check value (one byte for the sum, two for the CRC):
    /// 5 + LEN and 6 + LEN bytes, as the frames the encoder writes.
    #[test]
    fn frame_len_counts_every_byte_on_the_wire() {
        for checksum in [Checksum::Sum8, Checksum::Crc16] {
            let cfg = FrameConfig {
                checksum,
                ..FrameConfig::default()
            };
            for len in [0usize, 1, 20, 64] {
                let want = 4 + len + checksum.width();
                assert_eq!(cfg.frame_len(len), want, "{checksum:?} {len}");
                assert_eq!(encode(&cfg, 0x01, &vec![0x55; len]).unwrap().len(), want);
            }
        }
        assert_eq!(FrameConfig::default().frame_len(20), 25);
    }

    /// CRC-16/CCITT-FALSE a bit at a time (poly 0x1021, init 0xFFFF, no reflection, no final
    /// XOR), independent of the table.
    fn crc16_bitwise(bytes: &[u8]) -> u16 {
        let mut crc = 0xFFFFu16;
        for &b in bytes {
            crc ^= u16::from(b) << 8;
            for _ in 0..8 {
                crc = if crc & 0x8000 != 0 {
                    (crc << 1) ^ 0x1021
                } else {
                    crc << 1
                };
            }
        }
        crc
    }

    /// The executed telegram's digest is CRC-16/CCITT-FALSE over CMD, LEN and DATA only (not
    /// STX, not ETX), whatever the link's own check value.
    #[test]
    fn the_digest_is_the_crc_of_cmd_len_and_data() {
        assert_eq!(crc16_bitwise(b"123456789"), 0x29B1);
        assert_eq!(telegram_digest(0x0C, &[]), crc16_bitwise(&[0x0C, 0]));
        let data = [1u8, 0, 5, 0, 0x1F, 0x40, 0xF0, 0x58];
        assert_eq!(
            telegram_digest(0x01, &data),
            crc16_bitwise(&[&[0x01, 8][..], &data[..]].concat())
        );
    }

    /// A telegram of exactly the largest LEN is encoded and parsed; one byte more is refused.
    #[test]
    fn the_largest_len_is_accepted_and_one_more_refused() {
        let cfg = FrameConfig::default();
        let max = usize::from(cfg.max_len);
        let f = encode(&cfg, 0x01, &vec![0x55; max]).unwrap();
        assert!(matches!(parse(&cfg, &f), Parsed::Frame { used, .. } if used == f.len()));
        assert!(matches!(
            encode(&cfg, 0x01, &vec![0x55; max + 1]),
            Err(EncodeError::TooLong { .. })
        ));
        let mut long = f.clone();
        long[2] = cfg.max_len + 1;
        assert!(matches!(
            parse(&cfg, &long),
            Parsed::Bad(FrameError::TooLong { .. })
        ));
    }

    /// docs/protocol.md §3 golden vector: STORE_POS, CS 0x3F.
    const STORE_POS: [u8; 25] = [
        0x02, // STX
        0x01, // CMD STORE_POS
        0x14, // LEN 20
        0x01, // program 1
        0x00, 0x05, // instruction 5 (u16 BE; 0x05 is ENQ's value, harmless inside DATA)
        0x00, // flags: rectangular, absolute, fine
        0x1F, 0x40, // x = 8000 × 0.0625 = 500.0 mm
        0xF0, 0x58, // y = −4008 × 0.0625 = −250.5 mm
        0x32, 0x00, // z = 12800 × 0.0625 = 800.0 mm
        0x00, 0x00, // q1 = 0
        0x00, 0x00, // q2 = 0
        0x40, 0x00, // q3 = 16384 / 16384 = 1
        0x00, 0x00, // q4 = 0
        0x08, 0x00, // speed 2048 / 8192 = 0.25
        0x03, // ETX
        0x3F, // CS = (0x01 + 0x14 + 0x227 + 0x03) mod 256
    ];

    #[test]
    fn golden_store_pos_checksum() {
        let cfg = FrameConfig::default();
        let data = &STORE_POS[3..23];
        assert_eq!(check_value(&cfg, 0x01, data), 0x3F);
        assert_eq!(encode(&cfg, 0x01, data).unwrap(), STORE_POS);
        match parse(&cfg, &STORE_POS) {
            Parsed::Frame { frame, used } => {
                assert_eq!(used, 25);
                assert_eq!(frame.code, 0x01);
                assert_eq!(frame.data, data);
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn golden_short_vectors() {
        let cfg = FrameConfig::default();
        // RUN_PROGRAM 3: STX, CMD 0x02, LEN 1, prog 3, ETX, CS = 2+1+3+3 = 9.
        assert_eq!(
            encode(&cfg, 0x02, &[3]).unwrap(),
            [0x02, 0x02, 0x01, 0x03, 0x03, 0x09]
        );
        // ENQUIRE status: STX, CMD 0x06, LEN 1, selector 0, ETX, CS = 6+1+0+3 = 0x0A.
        assert_eq!(
            encode(&cfg, 0x06, &[0]).unwrap(),
            [0x02, 0x06, 0x01, 0x00, 0x03, 0x0A]
        );
    }

    #[test]
    fn spans_and_crc() {
        let stx = FrameConfig {
            span: ChecksumSpan::StxThroughEtx,
            ..FrameConfig::default()
        };
        assert_eq!(check_value(&stx, 0x02, &[3]), 0x0B);
        let tel = FrameConfig {
            span: ChecksumSpan::TelegramOnly,
            ..FrameConfig::default()
        };
        assert_eq!(check_value(&tel, 0x02, &[3]), 0x06);
        // CRC-16/CCITT-FALSE check value of "123456789" is 0x29B1: code '1', LEN must be
        // '2' (0x32), so 0x32 data bytes would be needed; check the table directly instead.
        let crc = {
            let mut crc = 0xFFFFu16;
            for &b in b"123456789" {
                crc = (crc << 8) ^ CRC_TABLE[usize::from((crc >> 8) as u8 ^ b)];
            }
            crc
        };
        assert_eq!(crc, 0x29B1);
        let c16 = FrameConfig {
            checksum: Checksum::Crc16,
            ..FrameConfig::default()
        };
        let f = encode(&c16, 0x02, &[3]).unwrap();
        assert_eq!(f.len(), 7);
        assert!(matches!(parse(&c16, &f), Parsed::Frame { used: 7, .. }));
    }

    #[test]
    fn bad_frames() {
        let cfg = FrameConfig::default();
        assert_eq!(parse(&cfg, &[STX, 1]), Parsed::Incomplete);
        assert_eq!(
            parse(&cfg, &[STX, 2, 1, 3, 0x99, 9]),
            Parsed::Bad(FrameError::MissingEtx { len: 1, got: 0x99 })
        );
        assert_eq!(
            parse(&cfg, &[STX, 2, 1, 3, ETX, 8]),
            Parsed::Bad(FrameError::Checksum {
                computed: 9,
                received: 8
            })
        );
        assert_eq!(
            parse(&cfg, &[STX, 2, 200]),
            Parsed::Bad(FrameError::TooLong { len: 200, max: 64 })
        );
        assert!(encode(&cfg, 1, &[0; 65]).is_err());
    }
}
