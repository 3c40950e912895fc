//! Wavefront OBJ: `v` vertices and `f` faces (polygons fanned into triangles, `v`, `v/vt`,
//! `v/vt/vn` and `v//vn` corners, negative indices counted back from the last vertex). Every other
//! statement (`vn`, `vt`, `o`, `g`, `s`, `usemtl`, `mtllib`, comments) is skipped.

use std::fmt::Write as _;
use std::io::BufRead;

use nalgebra::Point3;

use super::{Lines, Mesh, coordinates, syntax, with_column_in_row};
use crate::Error;

/// Reads OBJ text into an indexed mesh (not yet welded or validated).
pub fn parse(text: &str) -> Result<Mesh, Error> {
    parse_located(text).map(|(mesh, _)| mesh)
}

/// Like [`parse`], with the 1-based line of the `f` statement each triangle came from.
pub fn parse_located(text: &str) -> Result<(Mesh, Vec<usize>), Error> {
    read(text.as_bytes(), usize::MAX)
}

/// Reads OBJ text line by line from `input` (no copy of the file), with the line of each
/// triangle's `f` statement. More than `max_triangles` triangles, or more than three vertices
/// per allowed triangle, is an error at the line that brings one too many. Syntax errors name
/// their line and column.
pub fn read(input: impl BufRead, max_triangles: usize) -> Result<(Mesh, Vec<usize>), Error> {
    let max_vertices = max_triangles.saturating_mul(3);
    let mut vertices: Vec<Point3<f64>> = Vec::new();
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    let mut lines: Vec<usize> = Vec::new();
    let mut corners: Vec<u32> = Vec::with_capacity(8);
    let mut input = Lines::new(input);
    while let Some((n, row)) = input.next_line("OBJ")? {
        let mut step = || -> Result<(), Error> {
            let line = row.split('#').next().unwrap_or("");
            let mut words = line.split_whitespace();
            match words.next() {
                Some("v") => {
                    let c = coordinates(&mut words, n, None)?;
                    if let Err(e) = crate::limits::at_most(
                        "vertex count",
                        (vertices.len() + 1) as f64,
                        max_vertices as f64,
                    ) {
                        return Err(syntax(Some(n), e.to_string()));
                    }
                    vertices.push(Point3::from(c));
                }
                Some("f") => {
                    corners.clear();
                    for w in words {
                        let first = w.split('/').next().unwrap_or("");
                        let index: i64 = first.parse().map_err(|_| {
                            syntax(Some(n), format!("`{w}` is not a vertex reference"))
                        })?;
                        let count = vertices.len() as i64;
                        let resolved = if index > 0 { index - 1 } else { count + index };
                        if index == 0 || resolved < 0 || resolved >= count {
                            return Err(syntax(
                                Some(n),
                                format!(
                                    "`{w}`: vertex {index} does not exist ({count} vertices so far)"
                                ),
                            ));
                        }
                        corners.push(resolved as u32);
                    }
                    if corners.len() < 3 {
                        return Err(syntax(
                            Some(n),
                            format!("a face needs 3 vertices, this one has {}", corners.len()),
                        ));
                    }
                    if let Err(e) = crate::limits::at_most(
                        "triangle count",
                        (triangles.len() + corners.len() - 2) as f64,
                        max_triangles as f64,
                    ) {
                        return Err(syntax(Some(n), e.to_string()));
                    }
                    for k in 1..corners.len() - 1 {
                        triangles.push([corners[0], corners[k], corners[k + 1]]);
                        lines.push(n);
                    }
                }
                _ => {}
            }
            Ok(())
        };
        step().map_err(|e| with_column_in_row(e, n, row))?;
    }
    if triangles.is_empty() {
        return Err(syntax(None, "the OBJ file holds no faces"));
    }
    let mesh = Mesh::new(vertices, triangles).map_err(|e| super::with_line(e, &lines))?;
    Ok((mesh, lines))
}

/// OBJ text of `mesh`.
pub fn write(mesh: &Mesh) -> String {
    let mut out = String::with_capacity(40 * (mesh.vertices().len() + mesh.triangles().len()));
    for v in mesh.vertices() {
        let _ = writeln!(out, "v {} {} {}", v.x, v.y, v.z);
    }
    for t in mesh.triangles() {
        let _ = writeln!(out, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::Closure;

    #[test]
    fn reads_polygons_and_index_forms_and_round_trips() {
        let text = "# a cube\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n\
                    vn 0 0 1\nf 1 4 3 2\nf 5/1 6/2 7/3 8/4\nf 1//1 2//1 6//1 5//1\nf 2 3 7 6\n\
                    f -5 -1 -2 -6\nf 4 1 5 8\n";
        let m = parse(text).unwrap();
        assert_eq!(m.triangles().len(), 12);
        m.validate(Closure::Closed).unwrap();
        assert!((m.signed_volume_mm3() - 1.0).abs() < 1e-12);
        assert_eq!(parse(&write(&m)).unwrap(), m);
    }

    #[test]
    fn limits_stop_the_reader_at_the_line_that_breaks_them() {
        let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\nf 1 3 4\n";
        assert_eq!(read(text.as_bytes(), 3).unwrap().0.triangles().len(), 3);
        let e = read(text.as_bytes(), 2).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("line 7, column 1: triangle count = 3 exceeds the limit of 2"),
            "{e}"
        );
        // Three vertices per allowed triangle: the fourth `v` of a one-triangle limit.
        let e = read(text.as_bytes(), 1).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("line 4, column 1: vertex count = 4 exceeds the limit of 3"),
            "{e}"
        );
        // A line longer than the reader holds.
        let long = format!("v 0 0 0 {}\n", "0".repeat(crate::mesh::MAX_LINE_BYTES));
        assert!(
            read(long.as_bytes(), 10)
                .unwrap_err()
                .to_string()
                .starts_with("line 1: the line is longer than 65536 bytes")
        );
    }

    #[test]
    fn errors_name_the_line() {
        let e = parse("v 0 0 0\nv 1 0 0\nf 1 2 3\n").unwrap_err();
        assert_eq!(
            e.to_string(),
            "line 3, column 7: `3`: vertex 3 does not exist (2 vertices so far)"
        );
        let e = parse("v 0 0\n").unwrap_err();
        assert_eq!(
            e.to_string(),
            "line 1, column 1: vertex has 2 coordinates, needs 3"
        );
        let e = parse("v 0 0 0\nv 1 nan 0\n").unwrap_err();
        assert_eq!(
            e.to_string(),
            "line 2, column 5: coordinate `nan` is not finite"
        );
        let e = parse("v 0 0 0\nf 1 1\n").unwrap_err();
        assert_eq!(
            e.to_string(),
            "line 2, column 1: a face needs 3 vertices, this one has 2"
        );
        assert_eq!(
            parse("").unwrap_err().to_string(),
            "the OBJ file holds no faces"
        );
        let e = parse("v 0 0 0\nf 1 x 1\n").unwrap_err();
        assert_eq!(
            e.to_string(),
            "line 2, column 5: `x` is not a vertex reference"
        );
    }
}
