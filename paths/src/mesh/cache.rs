//! A prepared mesh as bytes, for a cache file beside the mesh file: the welded, validated,
//! outward-turned and locality-sorted mesh with its adjacency ([`super::prepare`]), so preparing
//! the same mandrel again reads it instead of parsing, welding, validating and sorting.
//!
//! The bytes name what they were made from (the source file's size and checksum, the welding
//! tolerance, whether a closed surface was required) and end with a checksum of everything before
//! it. [`decode`] returns `None` for anything else (another version, another source, a changed
//! file, a torn or corrupted cache, an index out of range), never a stale or broken mesh.
//!
//! Layout (little-endian): magic `WCPREP` and format version (8 bytes); source bytes, source
//! checksum, weld tolerance (`f64` bits), closure (1 closed, 0 open), vertex count, triangle count,
//! boundary edges (`u64` each); vertices (`3 × f64`), triangles (`3 × u32`), file triangle
//! indices (`u32`), adjacency (`3 × u32`); checksum of all the bytes before it (`u64`).

use super::{Adjacency, Closure, Mesh, NO_NEIGHBOUR};

/// Magic and format version; a change of layout changes the last byte.
pub const MAGIC: [u8; 8] = *b"WCPREP\x00\x01";

/// What a cache was made from; a cache is used only when all of it matches.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Key {
    /// Size of the mesh file, bytes.
    pub source_bytes: u64,
    /// [`Checksum`] of the mesh file's bytes.
    pub source_checksum: u64,
    /// Welding tolerance, mm.
    pub weld_mm: f64,
    /// Whether a closed surface was required.
    pub closure: Closure,
}

/// A 64-bit checksum of a byte stream, fed in pieces of any size (the same bytes give the same
/// value however they are split). Four lanes of multiply–rotate over 8-byte words (in the manner
/// of xxHash), for change detection, not security.
#[derive(Debug, Clone)]
pub struct Checksum {
    lanes: [u64; 4],
    tail: [u8; 32],
    tail_len: usize,
    total: u64,
}

const P1: u64 = 0x9E37_79B1_85EB_CA87;
const P2: u64 = 0xC2B2_AE3D_27D4_EB4F;
const P3: u64 = 0x1656_67B1_9E37_79F9;

impl Default for Checksum {
    fn default() -> Self {
        Checksum {
            lanes: [P1, P2, P3, P1 ^ P2],
            tail: [0; 32],
            tail_len: 0,
            total: 0,
        }
    }
}

impl Checksum {
    #[inline(always)]
    fn block(&mut self, b: &[u8]) {
        for (k, lane) in self.lanes.iter_mut().enumerate() {
            let mut w = [0u8; 8];
            w.copy_from_slice(&b[8 * k..8 * k + 8]);
            *lane = (*lane ^ u64::from_le_bytes(w).wrapping_mul(P2))
                .rotate_left(31)
                .wrapping_mul(P1);
        }
    }

    /// Feeds `bytes`.
    pub fn update(&mut self, mut bytes: &[u8]) {
        self.total += bytes.len() as u64;
        if self.tail_len > 0 {
            let take = (32 - self.tail_len).min(bytes.len());
            self.tail[self.tail_len..self.tail_len + take].copy_from_slice(&bytes[..take]);
            self.tail_len += take;
            bytes = &bytes[take..];
            if self.tail_len < 32 {
                return;
            }
            let tail = self.tail;
            self.block(&tail);
            self.tail_len = 0;
        }
        let mut blocks = bytes.chunks_exact(32);
        for b in &mut blocks {
            self.block(b);
        }
        let rest = blocks.remainder();
        self.tail[..rest.len()].copy_from_slice(rest);
        self.tail_len = rest.len();
    }

    /// The checksum of everything fed.
    pub fn value(&self) -> u64 {
        let mut h = self.total.wrapping_mul(P3);
        for lane in self.lanes {
            h = (h ^ lane).rotate_left(27).wrapping_mul(P1).wrapping_add(P3);
        }
        for &b in &self.tail[..self.tail_len] {
            h = (h ^ u64::from(b)).wrapping_mul(P1).rotate_left(11);
        }
        h ^= h >> 33;
        h = h.wrapping_mul(P2);
        h ^ (h >> 29)
    }

    /// The checksum of `bytes`.
    pub fn of(bytes: &[u8]) -> u64 {
        let mut c = Checksum::default();
        c.update(bytes);
        c.value()
    }
}

fn closure_code(closure: Closure) -> u64 {
    match closure {
        Closure::Closed => 1,
        Closure::Open => 0,
    }
}

/// The cache bytes of a prepared mesh made from `key`.
pub fn encode(key: &Key, mesh: &Mesh, adjacency: &Adjacency) -> Vec<u8> {
    let (nv, nt) = (mesh.vertices.len(), mesh.triangles.len());
    let mut out = Vec::with_capacity(80 + 24 * nv + 28 * nt + 8);
    out.extend_from_slice(&MAGIC);
    for v in [
        key.source_bytes,
        key.source_checksum,
        key.weld_mm.to_bits(),
        closure_code(key.closure),
        nv as u64,
        nt as u64,
        adjacency.boundary_edges as u64,
    ] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    for p in &mesh.vertices {
        for c in p.iter() {
            out.extend_from_slice(&c.to_le_bytes());
        }
    }
    for t in &mesh.triangles {
        for i in t {
            out.extend_from_slice(&i.to_le_bytes());
        }
    }
    for f in &mesh.file_triangles {
        out.extend_from_slice(&f.to_le_bytes());
    }
    for row in &adjacency.across {
        for h in row {
            out.extend_from_slice(&h.to_le_bytes());
        }
    }
    let sum = Checksum::of(&out);
    out.extend_from_slice(&sum.to_le_bytes());
    out
}

/// The prepared mesh in `bytes` when they are an intact cache made from `key`, else `None`.
pub fn decode(bytes: &[u8], key: &Key) -> Option<(Mesh, Adjacency)> {
    let body_len = bytes.len().checked_sub(8)?;
    let (body, sum) = bytes.split_at(body_len);
    if body.len() < 64 || body[..8] != MAGIC {
        return None;
    }
    let word = |at: usize| -> Option<u64> {
        Some(u64::from_le_bytes(body.get(at..at + 8)?.try_into().ok()?))
    };
    let header = [8, 16, 24, 32, 40, 48, 56].map(word);
    let [
        Some(source_bytes),
        Some(source_checksum),
        Some(weld_bits),
        Some(closure),
        Some(nv),
        Some(nt),
        Some(boundary_edges),
    ] = header
    else {
        return None;
    };
    if source_bytes != key.source_bytes
        || source_checksum != key.source_checksum
        || weld_bits != key.weld_mm.to_bits()
        || closure != closure_code(key.closure)
    {
        return None;
    }
    let (nv, nt) = (usize::try_from(nv).ok()?, usize::try_from(nt).ok()?);
    let expected = 64usize
        .checked_add(nv.checked_mul(24)?)?
        .checked_add(nt.checked_mul(28)?)?;
    if body.len() != expected || u64::from_le_bytes(sum.try_into().ok()?) != Checksum::of(body) {
        return None;
    }
    if nt == 0 || nv > u32::MAX as usize || nt > (u32::MAX >> 2) as usize {
        return None;
    }
    let mut at = 64;
    let mut f64s = |n: usize| -> Vec<f64> {
        let v = body[at..at + 8 * n]
            .chunks_exact(8)
            .map(|c| f64::from_le_bytes(c.try_into().unwrap_or_default()))
            .collect();
        at += 8 * n;
        v
    };
    let coords = f64s(3 * nv);
    let mut u32s = |n: usize| -> Vec<u32> {
        let v = body[at..at + 4 * n]
            .chunks_exact(4)
            .map(|c| u32::from_le_bytes(c.try_into().unwrap_or_default()))
            .collect();
        at += 4 * n;
        v
    };
    let tri = u32s(3 * nt);
    let file = u32s(nt);
    let across = u32s(3 * nt);
    let vertices = coords
        .chunks_exact(3)
        .map(|c| nalgebra::Point3::new(c[0], c[1], c[2]))
        .collect::<Vec<_>>();
    if vertices.iter().any(|p| !p.iter().all(|c| c.is_finite())) {
        return None;
    }
    let triangles: Vec<[u32; 3]> = tri.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
    if triangles.iter().flatten().any(|&i| i as usize >= nv)
        || file.iter().any(|&f| f as usize >= nt)
        || across
            .iter()
            .any(|&h| h != NO_NEIGHBOUR && ((h >> 2) as usize >= nt || h & 3 == 3))
    {
        return None;
    }
    let across: Vec<[u32; 3]> = across.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
    Some((
        Mesh {
            vertices,
            triangles,
            file_triangles: file,
        },
        Adjacency {
            across,
            boundary_edges: usize::try_from(boundary_edges).ok()?,
        },
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{DEFAULT_WELD_MM, prepare, triasym};

    fn key() -> Key {
        Key {
            source_bytes: 1234,
            source_checksum: 99,
            weld_mm: DEFAULT_WELD_MM,
            closure: Closure::Closed,
        }
    }

    #[test]
    fn a_cache_reads_back_the_prepared_mesh_and_nothing_else() {
        let (mesh, adjacency) = prepare(
            &triasym::icosphere(50.0, 2).unwrap(),
            DEFAULT_WELD_MM,
            Closure::Closed,
        )
        .unwrap();
        let bytes = encode(&key(), &mesh, &adjacency);
        assert_eq!(decode(&bytes, &key()), Some((mesh, adjacency)));
        // Another source, tolerance or closure: not used.
        for other in [
            Key {
                source_bytes: 1235,
                ..key()
            },
            Key {
                source_checksum: 98,
                ..key()
            },
            Key {
                weld_mm: 2e-4,
                ..key()
            },
            Key {
                closure: Closure::Open,
                ..key()
            },
        ] {
            assert_eq!(decode(&bytes, &other), None);
        }
        // Any flipped bit, a torn file, a longer one: not used.
        for at in (0..bytes.len()).step_by(97) {
            let mut bad = bytes.clone();
            bad[at] ^= 0x10;
            assert_eq!(decode(&bad, &key()), None, "bit flipped at {at}");
        }
        assert_eq!(decode(&bytes[..bytes.len() - 1], &key()), None);
        assert_eq!(decode(&[], &key()), None);
        let mut longer = bytes.clone();
        longer.push(0);
        assert_eq!(decode(&longer, &key()), None);
    }

    #[test]
    fn checksum_is_independent_of_how_the_bytes_are_split() {
        let bytes: Vec<u8> = (0..1000u32).map(|i| (i * 7 + i / 13) as u8).collect();
        let whole = Checksum::of(&bytes);
        for split in [1, 3, 31, 32, 33, 64, 999] {
            let mut c = Checksum::default();
            for piece in bytes.chunks(split) {
                c.update(piece);
            }
            assert_eq!(c.value(), whole, "pieces of {split}");
        }
        let mut changed = bytes.clone();
        changed[500] ^= 1;
        assert_ne!(Checksum::of(&changed), whole);
        assert_ne!(Checksum::of(&bytes[..999]), whole);
    }
}
