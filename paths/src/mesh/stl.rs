//! STL, binary and ASCII: reading into a triangle soup and writing a mesh.
//!
//! Binary STL is an 80-byte header, a little-endian `u32` triangle count and 50 bytes per
//! triangle (normal, three corners as `f32`, a 16-bit attribute). A file whose size matches its
//! count is binary even when its header starts with `solid` (some exporters do that); any other
//! file starting with `solid` is read as ASCII. The stored normals are ignored: the corner order
//! defines the orientation.

use nalgebra::Point3;

use super::{Mesh, at_byte, coordinates, syntax};
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
    if bytes.is_empty() {
        return Err(at_byte(0, "the file is empty"));
    }
    if bytes.len() >= 84 {
        let count = u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as u64;
        if 84 + 50 * count == bytes.len() as u64 {
            return parse_binary(bytes, count as usize).map(|soup| (soup, None));
        }
    }
    let head = bytes.iter().position(|b| !b.is_ascii_whitespace());
    if head.is_some_and(|h| bytes[h..].starts_with(b"solid")) {
        let text = std::str::from_utf8(bytes).map_err(|e| {
            let line = 1 + bytes[..e.valid_up_to()]
                .iter()
                .filter(|&&b| b == b'\n')
                .count();
            syntax(Some(line), "ASCII STL with bytes that are not UTF-8 text")
        })?;
        return parse_ascii(text).map(|(soup, lines)| (soup, Some(lines)));
    }
    if bytes.len() < 84 {
        return Err(at_byte(
            bytes.len() as u64,
            format!(
                "{} bytes is too short for a binary STL (84-byte header) and it is not ASCII STL",
                bytes.len()
            ),
        ));
    }
    let count = u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as u64;
    Err(at_byte(
        80,
        format!(
            "binary STL header says {count} triangles ({} bytes) but the file has {} bytes",
            84 + 50 * count,
            bytes.len()
        ),
    ))
}

fn parse_binary(bytes: &[u8], count: usize) -> Result<Vec<[Point3<f64>; 3]>, Error> {
    if count == 0 {
        return Err(at_byte(80, "the binary STL holds no triangles"));
    }
    let mut soup = Vec::with_capacity(count);
    for (t, rec) in bytes[84..].chunks_exact(50).enumerate() {
        let f = |k: usize| {
            let o = 12 + 4 * k;
            f64::from(f32::from_le_bytes([
                rec[o],
                rec[o + 1],
                rec[o + 2],
                rec[o + 3],
            ]))
        };
        let tri = [
            Point3::new(f(0), f(1), f(2)),
            Point3::new(f(3), f(4), f(5)),
            Point3::new(f(6), f(7), f(8)),
        ];
        if let Some(k) = (0..9).find(|&k| !f(k).is_finite()) {
            return Err(at_byte(
                84 + 50 * t as u64 + 12 + 4 * k as u64,
                format!("triangle {t}: coordinate {} is not finite", f(k)),
            ));
        }
        soup.push(tri);
    }
    Ok(soup)
}

fn parse_ascii(text: &str) -> Result<(Soup, Vec<usize>), Error> {
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
    let mut soup = Vec::new();
    let mut lines = Vec::new();
    let mut facet_line = 0;
    let mut corners: Vec<Point3<f64>> = Vec::with_capacity(3);
    let mut seen_solid = false;
    let mut last_line = 0;
    for (i, line) in text.lines().enumerate() {
        let n = i + 1;
        last_line = n;
        let mut words = line.split_whitespace();
        let Some(word) = words.next() else { continue };
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
                corners.clear();
                state = State::EndLoop;
            }
            State::EndLoop => match word {
                "vertex" => {
                    if corners.len() == 3 {
                        return Err(syntax(
                            Some(n),
                            "a fourth vertex: ASCII STL facets are triangles",
                        ));
                    }
                    let c = coordinates(&mut words, n, Some(soup.len()))?;
                    if let Some(extra) = words.next() {
                        return Err(syntax(
                            Some(n),
                            format!("unexpected `{extra}` after the vertex"),
                        ));
                    }
                    corners.push(Point3::from(c));
                }
                "endloop" => {
                    if corners.len() != 3 {
                        return Err(syntax(
                            Some(n),
                            format!("facet has {} vertices, needs 3", corners.len()),
                        ));
                    }
                    soup.push([corners[0], corners[1], corners[2]]);
                    lines.push(facet_line);
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
    if soup.is_empty() {
        return Err(syntax(
            Some(last_line.max(1)),
            "the ASCII STL holds no facets",
        ));
    }
    Ok((soup, lines))
}

/// Binary STL of `mesh` (corners rounded to `f32`, normals from the corners).
pub fn write_binary(mesh: &Mesh, header: &str) -> Vec<u8> {
    let tris = mesh.triangles();
    let mut out = Vec::with_capacity(84 + 50 * tris.len());
    let mut head = [b' '; 80];
    for (slot, b) in head.iter_mut().zip(header.bytes().filter(u8::is_ascii)) {
        *slot = b;
    }
    if head.starts_with(b"solid") {
        head[..5].copy_from_slice(b"SOLID");
    }
    out.extend_from_slice(&head);
    out.extend_from_slice(&(tris.len() as u32).to_le_bytes());
    let normals = mesh.face_normals();
    for (t, n) in normals.iter().enumerate() {
        for c in n.iter() {
            out.extend_from_slice(&(*c as f32).to_le_bytes());
        }
        for p in mesh.corners(t) {
            for c in p.iter() {
                out.extend_from_slice(&(*c as f32).to_le_bytes());
            }
        }
        out.extend_from_slice(&[0, 0]);
    }
    out
}

/// ASCII STL of `mesh`.
pub fn write_ascii(mesh: &Mesh, name: &str) -> String {
    let mut out = format!("solid {name}\n");
    for (t, n) in mesh.face_normals().iter().enumerate() {
        out += &format!(
            "  facet normal {:e} {:e} {:e}\n    outer loop\n",
            n.x, n.y, n.z
        );
        for p in mesh.corners(t) {
            out += &format!("      vertex {:e} {:e} {:e}\n", p.x, p.y, p.z);
        }
        out += "    endloop\n  endfacet\n";
    }
    out += &format!("endsolid {name}\n");
    out
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
    fn errors_name_the_line_or_triangle() {
        let text = write_ascii(&tetra(), "t");
        let bad = text.replacen("vertex 1e1 0e0 0e0", "vertex 1e1 zero 0e0", 1);
        let e = parse(bad.as_bytes()).unwrap_err();
        assert_eq!(e.to_string(), "line 6: `zero` is not a number");
        let e = parse(
            text.replacen("vertex 1e1 0e0 0e0", "vertex inf 0 0", 1)
                .as_bytes(),
        )
        .unwrap_err();
        assert!(
            e.to_string()
                .starts_with("line 6: coordinate `inf` is not finite"),
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
