//! STL, binary and ASCII: reading into a triangle soup and writing a mesh.
//!
//! Binary STL is an 80-byte header, a little-endian `u32` triangle count and 50 bytes per
//! triangle (normal, three corners as `f32`, a 16-bit attribute). A file whose size matches its
//! count is binary even when its header starts with `solid` (some exporters do that); any other
//! file starting with `solid` is read as ASCII. The stored normals are ignored: the corner order
//! defines the orientation.

use std::io::{BufRead, Read, Write};

use nalgebra::{Point3, Vector3};

use super::{Lines, Mesh, Welder, at_byte, coordinates, syntax, with_column_in_row};
use crate::Error;

/// A triangle soup: three corners per triangle, mm.
pub type Soup = Vec<[Point3<f64>; 3]>;

/// Reads an STL file's bytes (binary or ASCII) into a triangle soup.
pub fn parse(bytes: &[u8]) -> Result<Soup, Error> {
    parse_located(bytes).map(|(soup, _)| soup)
}

/// Like [`parse`], with the 1-based line of each triangle's `facet` for ASCII STL (`None` for
/// binary), so later errors about a triangle can name its line.
pub fn parse_located(bytes: &[u8]) -> Result<(Soup, Option<Vec<usize>>), Error> {
    let mut soup = Vec::new();
    let mut lines = Vec::new();
    let binary = stream(bytes, bytes.len() as u64, usize::MAX, |tri, line| {
        soup.push(tri);
        if let Some(line) = line {
            lines.push(line);
        }
    })?;
    Ok((soup, (!binary).then_some(lines)))
}

/// An STL file read and welded in one pass: the mesh (welded at `weld_mm`, triangles in file
/// order, not yet validated) and, for ASCII STL, the 1-based line of each triangle's `facet`.
#[derive(Debug, Clone)]
pub struct Welded {
    /// The welded mesh.
    pub mesh: Mesh,
    /// Line of each triangle (ASCII STL), `None` for binary STL.
    pub lines: Option<Vec<usize>>,
}

/// Reads an STL file of `len` bytes from `input` (binary or ASCII, told apart as [`parse`] does)
/// and welds its corners at `weld_mm` as they come, so the triangle soup is never stored: memory
/// is the welded mesh (about 36 bytes per triangle) and the welding grid. More than
/// `max_triangles` triangles is an error before they are stored (binary STL: at the header's
/// count, byte 80; ASCII: at the `facet` line of the first triangle too many). ASCII syntax
/// errors name their line and column.
pub fn read(
    input: impl BufRead,
    len: u64,
    weld_mm: f64,
    max_triangles: usize,
) -> Result<Welded, Error> {
    // Closed meshes have about half as many vertices as triangles.
    let estimate = if len >= 84 { (len - 84) / 50 } else { 0 }.min(max_triangles as u64) as usize;
    let mut welder = Welder::new(weld_mm, estimate / 2 + 16)?;
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    let mut lines = Vec::new();
    let binary = stream(input, len, max_triangles, |tri, line| {
        if triangles.capacity() == 0 {
            triangles.reserve(estimate.max(16));
        }
        triangles.push(tri.map(|p| welder.add(&p)));
        if let Some(line) = line {
            lines.push(line);
        }
    })?;
    let file_triangles = (0..triangles.len() as u32).collect();
    let mesh = Mesh {
        vertices: welder.into_vertices(),
        triangles,
        file_triangles,
    };
    Ok(Welded {
        mesh,
        lines: (!binary).then_some(lines),
    })
}

/// The triangle-count limit as a located error.
fn over_limit(count: u64, max_triangles: usize) -> Option<String> {
    crate::limits::at_most("triangle count", count as f64, max_triangles as f64)
        .err()
        .map(|e| e.to_string())
}

/// Streams the triangles of an STL file of `len` bytes to `each` (with the `facet` line for
/// ASCII). Returns whether the file is binary.
fn stream(
    mut input: impl BufRead,
    len: u64,
    max_triangles: usize,
    mut each: impl FnMut([Point3<f64>; 3], Option<usize>),
) -> Result<bool, Error> {
    if len == 0 {
        return Err(at_byte(0, "the file is empty"));
    }
    let mut header = Vec::with_capacity(84);
    (&mut input)
        .take(84)
        .read_to_end(&mut header)
        .map_err(|e| at_byte(0, format!("the file cannot be read: {e}")))?;
    if header.len() == 84 {
        let count = u32::from_le_bytes([header[80], header[81], header[82], header[83]]) as u64;
        if 84 + 50 * count == len {
            if let Some(message) = over_limit(count, max_triangles) {
                return Err(at_byte(80, message));
            }
            stream_binary(input, count as usize, each)?;
            return Ok(true);
        }
    }
    let head = header.iter().position(|b| !b.is_ascii_whitespace());
    let ascii = match head {
        Some(h) => {
            let rest = &header[h..];
            let n = rest.len().min(5);
            rest[..n] == b"solid"[..n]
        }
        None => len > header.len() as u64,
    };
    if ascii {
        stream_ascii(
            std::io::Cursor::new(header).chain(input),
            max_triangles,
            |t, l| each(t, Some(l)),
        )?;
        return Ok(false);
    }
    if len < 84 {
        return Err(at_byte(
            len,
            format!(
                "{len} bytes is too short for a binary STL (84-byte header) and it is not ASCII STL"
            ),
        ));
    }
    let count = u32::from_le_bytes([header[80], header[81], header[82], header[83]]) as u64;
    Err(at_byte(
        80,
        format!(
            "binary STL header says {count} triangles ({} bytes) but the file has {len} bytes",
            84 + 50 * count,
        ),
    ))
}

/// Records per read of a binary STL (200 KB).
const RECORDS_PER_READ: usize = 4096;

fn stream_binary(
    mut input: impl Read,
    count: usize,
    mut each: impl FnMut([Point3<f64>; 3], Option<usize>),
) -> Result<(), Error> {
    if count == 0 {
        return Err(at_byte(80, "the binary STL holds no triangles"));
    }
    let mut block = vec![0u8; 50 * RECORDS_PER_READ.min(count)];
    let mut t = 0usize;
    while t < count {
        let n = RECORDS_PER_READ.min(count - t);
        let bytes = &mut block[..50 * n];
        input
            .read_exact(bytes)
            .map_err(|e| at_byte(84 + 50 * t as u64, format!("the file cannot be read: {e}")))?;
        for rec in bytes.chunks_exact(50) {
            let f = |k: usize| {
                let o = 12 + 4 * k;
                f64::from(f32::from_le_bytes([
                    rec[o],
                    rec[o + 1],
                    rec[o + 2],
                    rec[o + 3],
                ]))
            };
            if let Some(k) = (0..9).find(|&k| !f(k).is_finite()) {
                return Err(at_byte(
                    84 + 50 * t as u64 + 12 + 4 * k as u64,
                    format!("triangle {t}: coordinate {} is not finite", f(k)),
                ));
            }
            each(
                [
                    Point3::new(f(0), f(1), f(2)),
                    Point3::new(f(3), f(4), f(5)),
                    Point3::new(f(6), f(7), f(8)),
                ],
                None,
            );
            t += 1;
        }
    }
    Ok(())
}

fn stream_ascii(
    input: impl BufRead,
    max_triangles: usize,
    mut each: impl FnMut([Point3<f64>; 3], usize),
) -> Result<(), Error> {
    #[derive(PartialEq)]
    enum State {
        Solid,
        Facet,
        Loop,
        EndLoop,
        EndFacet,
        Done,
    }
    let mut state = State::Solid;
    let mut count = 0usize;
    let mut facet_line = 0;
    let mut corners: [Point3<f64>; 3] = [Point3::origin(); 3];
    let mut have = 0usize;
    let mut seen_solid = false;
    let mut last_line = 0;
    let mut lines = Lines::new(input);
    while let Some((n, line)) = lines.next_line("ASCII STL")? {
        last_line = n;
        let mut step = || -> Result<(), Error> {
            let mut words = line.split_whitespace();
            let Some(word) = words.next() else {
                return Ok(());
            };
            let expected = |what: &str| syntax(Some(n), format!("expected {what}, found `{word}`"));
            match state {
                State::Solid => {
                    if word != "solid" {
                        return Err(expected("`solid`"));
                    }
                    seen_solid = true;
                    state = State::Facet;
                }
                State::Facet => match word {
                    "facet" => {
                        if words.next() != Some("normal") {
                            return Err(syntax(Some(n), "expected `facet normal nx ny nz`"));
                        }
                        if let Some(message) = over_limit(count as u64 + 1, max_triangles) {
                            return Err(syntax(Some(n), message));
                        }
                        facet_line = n;
                        state = State::Loop;
                    }
                    "endsolid" => state = State::Done,
                    _ => return Err(expected("`facet` or `endsolid`")),
                },
                State::Loop => {
                    if word != "outer" || words.next() != Some("loop") {
                        return Err(syntax(
                            Some(n),
                            format!("expected `outer loop`, found `{word}`"),
                        ));
                    }
                    have = 0;
                    state = State::EndLoop;
                }
                State::EndLoop => match word {
                    "vertex" => {
                        if have == 3 {
                            return Err(syntax(
                                Some(n),
                                "a fourth vertex: ASCII STL facets are triangles",
                            ));
                        }
                        let c = coordinates(&mut words, n, Some(count))?;
                        if let Some(extra) = words.next() {
                            return Err(syntax(
                                Some(n),
                                format!("unexpected `{extra}` after the vertex"),
                            ));
                        }
                        corners[have] = Point3::from(c);
                        have += 1;
                    }
                    "endloop" => {
                        if have != 3 {
                            return Err(syntax(
                                Some(n),
                                format!("facet has {have} vertices, needs 3"),
                            ));
                        }
                        each(corners, facet_line);
                        count += 1;
                        state = State::EndFacet;
                    }
                    _ => return Err(expected("`vertex` or `endloop`")),
                },
                State::EndFacet => {
                    if word != "endfacet" {
                        return Err(expected("`endfacet`"));
                    }
                    state = State::Facet;
                }
                State::Done => {
                    // Several solids may follow one another.
                    if word != "solid" {
                        return Err(expected("`solid` or the end of the file"));
                    }
                    state = State::Facet;
                }
            }
            Ok(())
        };
        step().map_err(|e| with_column_in_row(e, n, line))?;
    }
    if !seen_solid {
        return Err(syntax(None, "the file is empty"));
    }
    if state != State::Done {
        return Err(syntax(
            Some(last_line.max(1)),
            "the file ends inside a solid (missing `endsolid`)",
        ));
    }
    if count == 0 {
        return Err(syntax(
            Some(last_line.max(1)),
            "the ASCII STL holds no facets",
        ));
    }
    Ok(())
}

/// Binary STL of `mesh` (corners rounded to `f32`, normals from the corners).
pub fn write_binary(mesh: &Mesh, header: &str) -> Vec<u8> {
    let mut out = Vec::with_capacity(84 + 50 * mesh.triangles().len());
    write_binary_to(mesh, header, &mut out).unwrap_or_default();
    out
}

/// [`write_binary`] into `out`, record by record.
pub fn write_binary_to(mesh: &Mesh, header: &str, out: &mut impl Write) -> std::io::Result<()> {
    let tris = mesh.triangles();
    let mut head = [b' '; 80];
    for (slot, b) in head.iter_mut().zip(header.bytes().filter(u8::is_ascii)) {
        *slot = b;
    }
    if head.starts_with(b"solid") {
        head[..5].copy_from_slice(b"SOLID");
    }
    out.write_all(&head)?;
    out.write_all(&(tris.len() as u32).to_le_bytes())?;
    let mut rec = [0u8; 50];
    for t in 0..tris.len() {
        let (corners, n) = facet(mesh, t);
        let values = n.iter().chain(corners.iter().flat_map(|p| p.coords.iter()));
        for (k, v) in values.enumerate() {
            rec[4 * k..4 * k + 4].copy_from_slice(&(*v as f32).to_le_bytes());
        }
        out.write_all(&rec)?;
    }
    Ok(())
}

/// Triangle `t`'s corners and its unit normal by the right-hand rule (zero for a degenerate
/// triangle), as an STL facet carries them.
fn facet(mesh: &Mesh, t: usize) -> ([Point3<f64>; 3], Vector3<f64>) {
    let corners = mesh.corners(t);
    let [a, b, c] = corners;
    let n = (b - a)
        .cross(&(c - a))
        .try_normalize(0.0)
        .unwrap_or_default();
    (corners, n)
}

/// ASCII STL of `mesh`.
pub fn write_ascii(mesh: &Mesh, name: &str) -> String {
    let mut out = Vec::new();
    write_ascii_to(mesh, name, &mut out).unwrap_or_default();
    String::from_utf8(out).unwrap_or_default()
}

/// [`write_ascii`] into `out`, facet by facet.
pub fn write_ascii_to(mesh: &Mesh, name: &str, out: &mut impl Write) -> std::io::Result<()> {
    writeln!(out, "solid {name}")?;
    for t in 0..mesh.triangles().len() {
        let (corners, n) = facet(mesh, t);
        write!(
            out,
            "  facet normal {:e} {:e} {:e}\n    outer loop\n",
            n.x, n.y, n.z
        )?;
        for p in corners {
            writeln!(out, "      vertex {:e} {:e} {:e}", p.x, p.y, p.z)?;
        }
        out.write_all(b"    endloop\n  endfacet\n")?;
    }
    writeln!(out, "endsolid {name}")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{Closure, DEFAULT_WELD_MM};

    fn tetra() -> Mesh {
        let v = vec![
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(10.0, 0.0, 0.0),
            Point3::new(0.0, 10.0, 0.0),
            Point3::new(0.0, 0.0, 10.0),
        ];
        Mesh::new(v, vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [2, 0, 3]]).unwrap()
    }

    #[test]
    fn binary_and_ascii_round_trip() {
        let m = tetra();
        for soup in [
            parse(&write_binary(&m, "solid tetra")).unwrap(),
            parse(write_ascii(&m, "tetra").as_bytes()).unwrap(),
        ] {
            let back = Mesh::from_soup(&soup)
                .unwrap()
                .weld(DEFAULT_WELD_MM)
                .unwrap();
            assert_eq!(back.vertices().len(), 4);
            for (t, tri) in soup.iter().enumerate() {
                assert_eq!(*tri, m.corners(t));
            }
            back.validate(Closure::Closed).unwrap();
        }
    }

    #[test]
    fn the_streamed_reader_welds_and_stops_at_the_triangle_limit() {
        let m = tetra();
        let ascii = write_ascii(&m, "t");
        let binary = write_binary(&m, "t");
        for bytes in [ascii.as_bytes(), &binary[..]] {
            let welded = read(bytes, bytes.len() as u64, DEFAULT_WELD_MM, 4).unwrap();
            assert_eq!(welded.mesh.vertices().len(), 4);
            for t in 0..4 {
                assert_eq!(welded.mesh.corners(t), m.corners(t));
            }
        }
        // ASCII: at the `facet` line of the fourth triangle (line 2 + 3 × 7).
        let e = read(ascii.as_bytes(), ascii.len() as u64, DEFAULT_WELD_MM, 3).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("line 23, column 3: triangle count = 4 exceeds the limit of 3"),
            "{e}"
        );
        // Binary: at the header's count, before any triangle is read.
        let e = read(&binary[..], binary.len() as u64, DEFAULT_WELD_MM, 3).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("byte 80: triangle count = 4 exceeds the limit of 3"),
            "{e}"
        );
    }

    #[test]
    fn errors_name_the_line_or_triangle() {
        let text = write_ascii(&tetra(), "t");
        let bad = text.replacen("vertex 1e1 0e0 0e0", "vertex 1e1 zero 0e0", 1);
        let e = parse(bad.as_bytes()).unwrap_err();
        assert_eq!(e.to_string(), "line 6, column 18: `zero` is not a number");
        let e = parse(
            text.replacen("vertex 1e1 0e0 0e0", "vertex inf 0 0", 1)
                .as_bytes(),
        )
        .unwrap_err();
        assert!(
            e.to_string()
                .starts_with("line 6, column 14: coordinate `inf` is not finite"),
            "{e}"
        );
        let cut: String = text.lines().take(9).map(|l| format!("{l}\n")).collect();
        let e = parse(cut.as_bytes()).unwrap_err();
        assert!(e.to_string().contains("missing `endsolid`"), "{e}");
        assert_eq!(
            parse(b"").unwrap_err().to_string(),
            "byte 0: the file is empty"
        );
        assert!(
            parse(
                b"  
"
            )
            .unwrap_err()
            .to_string()
            .contains("too short")
        );
        let mut bin = write_binary(&tetra(), "");
        bin.pop();
        assert!(
            parse(&bin)
                .unwrap_err()
                .to_string()
                .starts_with("byte 80: binary STL header says 4 triangles")
        );
        let mut bin = write_binary(&tetra(), "");
        bin[84 + 50 + 12..84 + 50 + 16].copy_from_slice(&f32::NAN.to_le_bytes());
        assert_eq!(
            parse(&bin).unwrap_err().to_string(),
            "byte 146: triangle 1: coordinate NaN is not finite"
        );
        let mut empty = vec![0u8; 84];
        empty[..5].copy_from_slice(b"SOLID");
        assert!(
            parse(&empty)
                .unwrap_err()
                .to_string()
                .contains("no triangles")
        );
        assert!(
            parse(b"solid x\nendsolid x\n")
                .unwrap_err()
                .to_string()
                .contains("no facets")
        );
    }
}
