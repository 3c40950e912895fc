//! Triangulated mandrels: an indexed triangle mesh, vertex welding, validation, face normals and
//! edge adjacency (seed 001 §3.1: the mandrel surface as triangles, TRIASYM).
//!
//! Edge `i` of triangle `[a, b, c]` runs from corner `i` to corner `(i + 1) % 3`: edge 0 is
//! `a → b`, edge 1 `b → c`, edge 2 `c → a`. A consistently oriented surface crosses each interior
//! edge once in each direction.

pub mod cache;
pub mod obj;
pub mod order;
pub mod resegment;
pub mod stl;
pub mod trace;
pub mod triasym;

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

use nalgebra::{Point3, Vector3};

use crate::Error;

/// Default welding tolerance, mm: vertices closer than this become one (0.1 µm, well below the
/// 32-bit float resolution of an STL file at mandrel sizes, so only true duplicates merge).
pub const DEFAULT_WELD_MM: f64 = 1e-4;

/// No neighbour across an edge (a boundary).
pub const NO_NEIGHBOUR: u32 = u32::MAX;

/// An indexed triangle mesh, mm.
#[derive(Debug, Clone, PartialEq)]
pub struct Mesh {
    vertices: Vec<Point3<f64>>,
    triangles: Vec<[u32; 3]>,
    /// Index of each triangle in the file (or the list given to [`Mesh::new`]).
    file_triangles: Vec<u32>,
}

/// Whether a mesh must be a closed surface.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Closure {
    /// Every edge must have two triangles (a watertight mandrel).
    Closed,
    /// Boundary edges are allowed (an open tube, a patch).
    Open,
}

/// Edge adjacency of a valid mesh: for each triangle and edge, the neighbouring triangle and its
/// local edge index packed as `4 · triangle + edge`, or [`NO_NEIGHBOUR`].
#[derive(Debug, Clone, PartialEq)]
pub struct Adjacency {
    /// Per triangle, per edge.
    pub across: Vec<[u32; 3]>,
    /// Number of boundary edges.
    pub boundary_edges: usize,
}

/// A small fast hasher for integer cell and edge keys (FNV-style multiply-xor).
#[derive(Debug, Default, Clone, Copy)]
struct CellHasher(u64);

impl Hasher for CellHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        // Eight bytes a round (integer keys arrive as their bytes, `[i64; 3]` as 24).
        for chunk in bytes.chunks(8) {
            let mut word = [0u8; 8];
            word[..chunk.len()].copy_from_slice(chunk);
            self.write_u64(u64::from_le_bytes(word));
        }
    }
    fn write_usize(&mut self, i: usize) {
        self.write_u64(i as u64);
    }
    fn write_u64(&mut self, i: u64) {
        self.0 = (self.0.rotate_left(5) ^ i).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
    fn write_i64(&mut self, i: i64) {
        self.write_u64(i as u64);
    }
}

type CellMap<K, V> = HashMap<K, V, BuildHasherDefault<CellHasher>>;

/// Vertex welding one point at a time, in file order: each point merges into the first kept
/// vertex within the tolerance, else is kept. A hashed grid of cells 32 tolerances wide holds the
/// kept vertices; a point looks in its own cell and, along each axis where it lies within the
/// tolerance of a cell face, in the neighbouring cells, so it meets every kept vertex within the
/// tolerance. The readers weld as they parse ([`stl::read`]), so a triangle soup is never stored.
#[derive(Debug, Clone)]
pub struct Welder {
    tolerance_mm: f64,
    cell_mm: f64,
    inv_cell: f64,
    tol2: f64,
    heads: CellMap<[i64; 3], u32>,
    next: Vec<u32>,
    kept: Vec<Point3<f64>>,
}

impl Welder {
    /// A welder at `tolerance_mm` (> 0), with room for about `expected_vertices` kept vertices.
    pub fn new(tolerance_mm: f64, expected_vertices: usize) -> Result<Welder, Error> {
        if !(tolerance_mm > 0.0 && tolerance_mm.is_finite()) {
            return Err(Error::OutOfRange {
                name: "weld_mm",
                value: tolerance_mm,
                expected: "must be > 0",
            });
        }
        let cell_mm = 32.0 * tolerance_mm;
        let mut heads = CellMap::default();
        heads.reserve(expected_vertices);
        Ok(Welder {
            tolerance_mm,
            cell_mm,
            inv_cell: 1.0 / cell_mm,
            tol2: tolerance_mm * tolerance_mm,
            heads,
            next: Vec::with_capacity(expected_vertices),
            kept: Vec::with_capacity(expected_vertices),
        })
    }

    /// The index of the kept vertex `p` merges into (a new one when none lies within the
    /// tolerance).
    pub fn add(&mut self, p: &Point3<f64>) -> u32 {
        let f = [
            p.x * self.inv_cell,
            p.y * self.inv_cell,
            p.z * self.inv_cell,
        ];
        let home = f.map(|c| c.floor() as i64);
        let mut found = self.find(&home, p);
        if found.is_none() {
            // Neighbour cells only along axes where the point lies within the tolerance of a face.
            let mut side = [0i64; 3];
            for k in 0..3 {
                let frac = f[k] - home[k] as f64;
                side[k] = if frac * self.cell_mm <= self.tolerance_mm {
                    -1
                } else if (1.0 - frac) * self.cell_mm <= self.tolerance_mm {
                    1
                } else {
                    0
                };
            }
            if side != [0, 0, 0] {
                'cells: for dx in 0..=side[0].abs() {
                    for dy in 0..=side[1].abs() {
                        for dz in 0..=side[2].abs() {
                            if dx + dy + dz == 0 {
                                continue;
                            }
                            let key = [
                                home[0] + dx * side[0],
                                home[1] + dy * side[1],
                                home[2] + dz * side[2],
                            ];
                            if let Some(at) = self.find(&key, p) {
                                found = Some(at);
                                break 'cells;
                            }
                        }
                    }
                }
            }
        }
        match found {
            Some(at) => at,
            None => {
                let at = self.kept.len() as u32;
                self.kept.push(*p);
                let head = self.heads.entry(home).or_insert(u32::MAX);
                self.next.push(*head);
                *head = at;
                at
            }
        }
    }

    fn find(&self, key: &[i64; 3], p: &Point3<f64>) -> Option<u32> {
        let mut at = *self.heads.get(key)?;
        loop {
            if (self.kept[at as usize] - p).norm_squared() <= self.tol2 {
                return Some(at);
            }
            at = self.next[at as usize];
            if at == u32::MAX {
                return None;
            }
        }
    }

    /// Number of kept vertices so far.
    pub fn len(&self) -> usize {
        self.kept.len()
    }

    /// Whether no vertex was kept yet.
    pub fn is_empty(&self) -> bool {
        self.kept.is_empty()
    }

    /// The kept vertices, in the order they were first met.
    pub fn into_vertices(self) -> Vec<Point3<f64>> {
        self.kept
    }
}

impl Mesh {
    /// A mesh from vertices and triangles. Rejects an empty mesh, a corner index out of range and a
    /// non-finite coordinate (naming the first triangle that uses it).
    pub fn new(vertices: Vec<Point3<f64>>, triangles: Vec<[u32; 3]>) -> Result<Self, Error> {
        if triangles.is_empty() {
            return Err(invalid(None, "the mesh has no triangles"));
        }
        for (t, tri) in triangles.iter().enumerate() {
            for &i in tri {
                let Some(v) = vertices.get(i as usize) else {
                    return Err(invalid(
                        Some(t),
                        format!(
                            "vertex index {i} is out of range ({} vertices)",
                            vertices.len()
                        ),
                    ));
                };
                if !(v.x.is_finite() && v.y.is_finite() && v.z.is_finite()) {
                    return Err(invalid(Some(t), "a coordinate is not finite"));
                }
            }
        }
        let file_triangles = (0..triangles.len() as u32).collect();
        Ok(Mesh {
            vertices,
            triangles,
            file_triangles,
        })
    }

    /// A mesh from a triangle soup (three corners per triangle, as STL stores them), unwelded.
    pub fn from_soup(soup: &[[Point3<f64>; 3]]) -> Result<Self, Error> {
        let vertices: Vec<Point3<f64>> = soup.iter().flatten().copied().collect();
        let triangles = (0..soup.len() as u32)
            .map(|t| [3 * t, 3 * t + 1, 3 * t + 2])
            .collect();
        Mesh::new(vertices, triangles)
    }

    /// The vertices.
    pub fn vertices(&self) -> &[Point3<f64>] {
        &self.vertices
    }

    /// The triangles (vertex indices, counter-clockwise seen from outside).
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// Where triangle `t` stood in the file (or the list given to [`Mesh::new`]); differs from `t`
    /// after [`prepare`] sorted the triangles for locality ([`order`]).
    pub fn file_triangle(&self, t: usize) -> usize {
        self.file_triangles[t] as usize
    }

    /// The three corners of triangle `t`.
    pub fn corners(&self, t: usize) -> [Point3<f64>; 3] {
        self.triangles[t].map(|i| self.vertices[i as usize])
    }

    /// Merges vertices closer than `tolerance_mm` (each to the first of its cluster in file order,
    /// by a hashed grid of cells 32 tolerances wide, so a vertex meets every vertex within the
    /// tolerance; see [`Welder`]). Unused vertices are dropped. The triangles keep their order.
    pub fn weld(&self, tolerance_mm: f64) -> Result<Mesh, Error> {
        let mut welder = Welder::new(tolerance_mm, self.vertices.len() / 2)?;
        let mut remap = vec![u32::MAX; self.vertices.len()];
        let mut used = vec![false; self.vertices.len()];
        for tri in &self.triangles {
            for &i in tri {
                used[i as usize] = true;
            }
        }
        for (i, p) in self.vertices.iter().enumerate() {
            if used[i] {
                remap[i] = welder.add(p);
            }
        }
        let triangles = self
            .triangles
            .iter()
            .map(|t| t.map(|i| remap[i as usize]))
            .collect();
        Ok(Mesh {
            vertices: welder.into_vertices(),
            triangles,
            file_triangles: self.file_triangles.clone(),
        })
    }

    /// Unit face normals (right-handed around the corners). A degenerate triangle gets a zero vector.
    pub fn face_normals(&self) -> Vec<Vector3<f64>> {
        self.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| self.vertices[i as usize]);
                (b - a)
                    .cross(&(c - a))
                    .try_normalize(0.0)
                    .unwrap_or_default()
            })
            .collect()
    }

    /// Signed enclosed volume, mm³ (positive when the normals point outward on a closed mesh).
    pub fn signed_volume_mm3(&self) -> f64 {
        self.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| self.vertices[i as usize].coords);
                a.dot(&b.cross(&c)) / 6.0
            })
            .sum()
    }

    /// Reverses every triangle (turns the normals inside out).
    pub fn flip(&mut self) {
        for t in &mut self.triangles {
            t.swap(1, 2);
        }
    }

    /// Checks that the mesh is a surface the tracer can use and returns its edge adjacency:
    /// no degenerate triangle (a repeated corner or zero area), every edge shared by at most two
    /// triangles that cross it in opposite directions, and no boundary edge when `closure` is
    /// [`Closure::Closed`]. Errors name the first offending triangle (0-based, file order).
    pub fn validate(&self, closure: Closure) -> Result<Adjacency, Error> {
        if self.triangles.is_empty() {
            return Err(invalid(None, "the mesh has no triangles"));
        }
        for (t, tri) in self.triangles.iter().enumerate() {
            let [a, b, c] = *tri;
            if a == b || b == c || c == a {
                return Err(invalid(
                    Some(t),
                    "degenerate triangle (two corners coincide after welding)",
                ));
            }
            let [pa, pb, pc] = tri.map(|i| self.vertices[i as usize]);
            let (e1, e2) = (pb - pa, pc - pa);
            let area2 = e1.cross(&e2).norm();
            let scale = e1.norm_squared().max(e2.norm_squared());
            if area2 <= 1e-12 * scale {
                return Err(invalid(
                    Some(t),
                    "degenerate triangle (zero area: its corners are collinear)",
                ));
            }
        }
        // Half-edges keyed by their undirected edge, sorted so both sides of an edge are adjacent.
        let mut half: Vec<(u64, u32)> = Vec::with_capacity(3 * self.triangles.len());
        for (t, tri) in self.triangles.iter().enumerate() {
            for e in 0..3 {
                let (a, b) = (tri[e], tri[(e + 1) % 3]);
                let key = (u64::from(a.min(b)) << 32) | u64::from(a.max(b));
                half.push((key, (t as u32) << 2 | e as u32));
            }
        }
        half.sort_unstable();
        let mut across = vec![[NO_NEIGHBOUR; 3]; self.triangles.len()];
        let mut boundary_edges = 0;
        let mut i = 0;
        while i < half.len() {
            let mut j = i + 1;
            while j < half.len() && half[j].0 == half[i].0 {
                j += 1;
            }
            let group = &half[i..j];
            let worst = group.iter().map(|h| h.1 >> 2).max().unwrap_or(0) as usize;
            let (a, b) = ((half[i].0 >> 32) as u32, half[i].0 as u32);
            match group.len() {
                1 => {
                    if closure == Closure::Closed {
                        return Err(invalid(
                            Some(worst),
                            format!(
                                "open boundary at the edge between vertices {a} and {b} where a \
                                 closed surface is required"
                            ),
                        ));
                    }
                    boundary_edges += 1;
                }
                2 => {
                    let (h0, h1) = (group[0].1, group[1].1);
                    let dir = |h: u32| {
                        let tri = &self.triangles[(h >> 2) as usize];
                        tri[(h & 3) as usize]
                    };
                    if dir(h0) == dir(h1) {
                        return Err(invalid(
                            Some(worst),
                            format!(
                                "inconsistent orientation: it runs the edge between vertices {a} \
                                 and {b} the same way as triangle {}",
                                (h0 >> 2).min(h1 >> 2)
                            ),
                        ));
                    }
                    across[(h0 >> 2) as usize][(h0 & 3) as usize] = h1;
                    across[(h1 >> 2) as usize][(h1 & 3) as usize] = h0;
                }
                n => {
                    return Err(invalid(
                        Some(worst),
                        format!(
                            "non-manifold edge between vertices {a} and {b}, shared by {n} triangles"
                        ),
                    ));
                }
            }
            i = j;
        }
        Ok(Adjacency {
            across,
            boundary_edges,
        })
    }

    /// Axis-aligned bounds `(min, max)`.
    pub fn bounds(&self) -> (Point3<f64>, Point3<f64>) {
        let mut lo = Point3::from([f64::INFINITY; 3]);
        let mut hi = Point3::from([f64::NEG_INFINITY; 3]);
        for v in &self.vertices {
            lo = lo.inf(v);
            hi = hi.sup(v);
        }
        (lo, hi)
    }
}

/// Loads a mesh the way the tracer wants it: welded at `weld_mm`, validated (errors name file
/// triangles), turned so the normals point outward when it is closed (negative enclosed volume),
/// and sorted for locality ([`order::by_locality`]; [`Mesh::file_triangle`] maps back). Returns
/// the mesh and its adjacency.
pub fn prepare(mesh: &Mesh, weld_mm: f64, closure: Closure) -> Result<(Mesh, Adjacency), Error> {
    prepare_welded(mesh.weld(weld_mm)?, closure)
}

/// [`prepare`] of a mesh that is already welded (as [`stl::read`] returns it): validated, turned
/// outward when closed, sorted for locality.
pub fn prepare_welded(mut welded: Mesh, closure: Closure) -> Result<(Mesh, Adjacency), Error> {
    let mut adjacency = welded.validate(closure)?;
    if adjacency.boundary_edges == 0 && welded.signed_volume_mm3() < 0.0 {
        welded.flip();
        adjacency = adjacency.flipped();
    }
    Ok(order::by_locality(&welded, &adjacency))
}

impl Adjacency {
    /// The adjacency of the same mesh after [`Mesh::flip`]: triangle `[a, b, c]` becomes
    /// `[a, c, b]`, so its edge `e` (`0`: a→b, `1`: b→c, `2`: c→a) becomes edge `2 − e` run the
    /// other way.
    pub fn flipped(&self) -> Adjacency {
        let turn = |h: u32| {
            if h == NO_NEIGHBOUR {
                h
            } else {
                (h & !3) | (2 - (h & 3))
            }
        };
        Adjacency {
            across: self
                .across
                .iter()
                .map(|row| [turn(row[2]), turn(row[1]), turn(row[0])])
                .collect(),
            boundary_edges: self.boundary_edges,
        }
    }
}

/// `error` with the line of its triangle, when it names one and `lines` (one per triangle, from
/// [`stl::parse_located`] or [`obj::parse_located`]) knows it: `line N: triangle T: reason`.
pub fn with_line(error: Error, lines: &[usize]) -> Error {
    match error {
        Error::MeshInvalid {
            triangle: Some(t),
            reason,
        } if t < lines.len() => Error::MeshSyntax {
            line: Some(lines[t]),
            column: None,
            byte: None,
            message: format!("triangle {t}: {reason}"),
        },
        other => other,
    }
}

pub(crate) fn invalid(triangle: Option<usize>, reason: impl Into<String>) -> Error {
    Error::MeshInvalid {
        triangle,
        reason: reason.into(),
    }
}

pub(crate) fn syntax(line: Option<usize>, message: impl Into<String>) -> Error {
    Error::MeshSyntax {
        line,
        column: None,
        byte: None,
        message: message.into(),
    }
}

/// A binary-file error at byte `byte`.
pub(crate) fn at_byte(byte: u64, message: impl Into<String>) -> Error {
    Error::MeshSyntax {
        line: None,
        column: None,
        byte: Some(byte),
        message: message.into(),
    }
}

/// Most bytes of one line of a text mesh (ASCII STL, OBJ): a vertex line is about 60 bytes, so
/// a longer line is not a mesh, and a file without line breaks cannot make a reader hold more.
pub const MAX_LINE_BYTES: usize = 1 << 16;

/// The lines of a text mesh read one at a time from a buffered reader (no copy of the file):
/// 1-based line numbers, `\n` or `\r\n` line ends, UTF-8 checked line by line.
pub(crate) struct Lines<R> {
    input: R,
    buf: Vec<u8>,
    /// Number of the line last returned.
    number: usize,
    /// Byte offset of the start of the next line.
    offset: u64,
}

impl<R: std::io::BufRead> Lines<R> {
    pub(crate) fn new(input: R) -> Self {
        Lines {
            input,
            buf: Vec::with_capacity(256),
            number: 0,
            offset: 0,
        }
    }

    /// The next line's number and text without its line end, `None` at the end of the input.
    pub(crate) fn next_line(&mut self, what: &str) -> Result<Option<(usize, &str)>, Error> {
        self.buf.clear();
        let line = self.number + 1;
        let mut seen = false;
        loop {
            let available = match self.input.fill_buf() {
                Ok(a) => a,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                Err(e) => {
                    return Err(syntax(
                        Some(line),
                        format!("the file cannot be read further: {e}"),
                    ));
                }
            };
            if available.is_empty() {
                break;
            }
            seen = true;
            let (take, done) = match available.iter().position(|&b| b == b'\n') {
                Some(i) => (i + 1, true),
                None => (available.len(), false),
            };
            self.buf.extend_from_slice(&available[..take]);
            self.input.consume(take);
            if self.buf.len() > MAX_LINE_BYTES + 2 {
                return Err(syntax(
                    Some(line),
                    format!("the line is longer than {MAX_LINE_BYTES} bytes: this is not {what}"),
                ));
            }
            if done {
                break;
            }
        }
        if !seen {
            return Ok(None);
        }
        self.number = line;
        let start = self.offset;
        self.offset += self.buf.len() as u64;
        if self.buf.last() == Some(&b'\n') {
            self.buf.pop();
            if self.buf.last() == Some(&b'\r') {
                self.buf.pop();
            }
        }
        match std::str::from_utf8(&self.buf) {
            Ok(text) => Ok(Some((line, text))),
            Err(e) => {
                let valid = std::str::from_utf8(&self.buf[..e.valid_up_to()]).unwrap_or_default();
                Err(Error::MeshSyntax {
                    line: Some(line),
                    column: Some(valid.chars().count() + 1),
                    byte: Some(start + e.valid_up_to() as u64),
                    message: format!("{what} with bytes that are not UTF-8 text"),
                })
            }
        }
    }
}

/// `error` with a column, when it names line `line` (whose text is `row`) but no column (see
/// [`with_column`]).
pub fn with_column_in_row(error: Error, line: usize, row: &str) -> Error {
    match error {
        Error::MeshSyntax {
            line: Some(l),
            column: None,
            byte,
            message,
        } if l == line => Error::MeshSyntax {
            line: Some(l),
            column: Some(column_in(&message, row)),
            byte,
            message,
        },
        other => other,
    }
}

/// `error` with a column, when it names a line of `text` but no column: the column of the first
/// word it quotes in backticks that is on that line, else of the line's first word (the
/// statement at fault).
pub fn with_column(error: Error, text: &str) -> Error {
    let Error::MeshSyntax {
        line: Some(line),
        column: None,
        byte,
        message,
    } = error
    else {
        return error;
    };
    let row = text.lines().nth(line - 1).unwrap_or_default();
    Error::MeshSyntax {
        line: Some(line),
        column: Some(column_in(&message, row)),
        byte,
        message,
    }
}

/// The column of the first word `message` quotes in backticks that is on `row`, else of the row's
/// first word.
fn column_in(message: &str, row: &str) -> usize {
    let quoted = message
        .split('`')
        .skip(1)
        .step_by(2)
        .filter(|q| !q.is_empty())
        .find_map(|q| row.find(q));
    let offset = quoted
        .or_else(|| row.find(|c: char| !c.is_whitespace()))
        .unwrap_or(0);
    row[..offset].chars().count() + 1
}

/// `error` with the byte offset of its triangle's record in a binary STL (84-byte header, 50
/// bytes per triangle) when it names a triangle.
pub fn with_byte(error: Error) -> Error {
    match error {
        Error::MeshInvalid {
            triangle: Some(t),
            reason,
        } => at_byte(84 + 50 * t as u64, format!("triangle {t}: {reason}")),
        other => other,
    }
}

/// The three finite coordinates of a vertex record on text line `line` (ASCII STL `vertex`, OBJ
/// `v`). The "is not finite" error names `triangle` where the reader knows it (STL).
pub(crate) fn coordinates<'a>(
    words: &mut impl Iterator<Item = &'a str>,
    line: usize,
    triangle: Option<usize>,
) -> Result<[f64; 3], Error> {
    let mut c = [0.0; 3];
    for (k, slot) in c.iter_mut().enumerate() {
        let w = words
            .next()
            .ok_or_else(|| syntax(Some(line), format!("vertex has {k} coordinates, needs 3")))?;
        let v: f64 = w
            .parse()
            .map_err(|_| syntax(Some(line), format!("`{w}` is not a number")))?;
        if !v.is_finite() {
            let message = match triangle {
                Some(t) => format!("coordinate `{w}` is not finite (triangle {t})"),
                None => format!("coordinate `{w}` is not finite"),
            };
            return Err(syntax(Some(line), message));
        }
        *slot = v;
    }
    Ok(c)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tetra() -> Mesh {
        let v = vec![
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
            Point3::new(0.0, 0.0, 1.0),
        ];
        Mesh::new(v, vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [2, 0, 3]]).unwrap()
    }

    #[test]
    fn tetrahedron_is_closed_with_outward_normals_and_full_adjacency() {
        let m = tetra();
        let adj = m.validate(Closure::Closed).unwrap();
        assert_eq!(adj.boundary_edges, 0);
        assert!(m.signed_volume_mm3() > 0.0);
        for (t, row) in adj.across.iter().enumerate() {
            for (e, &h) in row.iter().enumerate() {
                assert_ne!(h, NO_NEIGHBOUR);
                assert_eq!(
                    adj.across[(h >> 2) as usize][(h & 3) as usize],
                    (t as u32) << 2 | e as u32
                );
            }
        }
    }

    #[test]
    fn weld_merges_soup_corners_within_tolerance_only() {
        let m = tetra();
        let mut soup: Vec<[Point3<f64>; 3]> = (0..4).map(|t| m.corners(t)).collect();
        soup[1][0].x += 4e-5; // within 1e-4
        let welded = Mesh::from_soup(&soup)
            .unwrap()
            .weld(DEFAULT_WELD_MM)
            .unwrap();
        assert_eq!(welded.vertices().len(), 4);
        welded.validate(Closure::Closed).unwrap();
        soup[1][0].x += 1e-3; // now apart
        let apart = Mesh::from_soup(&soup)
            .unwrap()
            .weld(DEFAULT_WELD_MM)
            .unwrap();
        assert_eq!(apart.vertices().len(), 5);
        assert!(apart.validate(Closure::Closed).is_err());
    }

    #[test]
    fn weld_finds_neighbours_across_cell_faces() {
        // Points straddling a grid cell face at every scale.
        for base in [0.0, 3.2e-3, -3.2e-3, 1.0, 123.456] {
            let a = Point3::new(base - 2e-5, base + 1e-5, base);
            let b = Point3::new(base + 2e-5, base - 1e-5, base + 3e-5);
            let m = Mesh::new(
                vec![a, Point3::new(5.0, 0.0, 0.0), Point3::new(0.0, 5.0, 0.0), b],
                vec![[0, 1, 2], [3, 1, 2]],
            )
            .unwrap()
            .weld(DEFAULT_WELD_MM)
            .unwrap();
            assert_eq!(m.vertices().len(), 3, "base {base}");
        }
    }

    #[test]
    fn validation_names_the_offending_triangle() {
        let m = tetra();
        // Degenerate (collinear) triangle.
        let mut v = m.vertices().to_vec();
        v.push(Point3::new(2.0, 0.0, 0.0));
        let bad = Mesh::new(v, vec![[0, 1, 4]]).unwrap();
        assert!(matches!(
            bad.validate(Closure::Open),
            Err(Error::MeshInvalid {
                triangle: Some(0),
                ..
            })
        ));
        // Flipped triangle: inconsistent orientation.
        let mut t = m.triangles().to_vec();
        t[2].swap(1, 2);
        let e = Mesh::new(m.vertices().to_vec(), t)
            .unwrap()
            .validate(Closure::Closed);
        assert!(
            matches!(e, Err(Error::MeshInvalid { triangle: Some(2), ref reason }) if reason.contains("orientation")),
            "{e:?}"
        );
        // Open where closed is required.
        let open = Mesh::new(m.vertices().to_vec(), m.triangles()[..3].to_vec()).unwrap();
        assert!(open.validate(Closure::Open).is_ok());
        let e = open.validate(Closure::Closed).unwrap_err();
        assert!(e.to_string().contains("open boundary"), "{e}");
        // Non-manifold: a fifth triangle on edge 0–1.
        let mut v = m.vertices().to_vec();
        v.push(Point3::new(0.5, -1.0, 0.5));
        let mut t = m.triangles().to_vec();
        t.push([0, 1, 4]);
        let e = Mesh::new(v, t)
            .unwrap()
            .validate(Closure::Open)
            .unwrap_err();
        assert!(e.to_string().contains("non-manifold"), "{e}");
        // Empty, out of range, non-finite.
        assert!(Mesh::new(vec![], vec![]).is_err());
        assert!(Mesh::new(m.vertices().to_vec(), vec![[0, 1, 9]]).is_err());
        let mut v = m.vertices().to_vec();
        v[3].z = f64::NAN;
        let e = Mesh::new(v, m.triangles().to_vec()).unwrap_err();
        assert!(
            e.to_string()
                .contains("triangle 1: a coordinate is not finite"),
            "{e}"
        );
    }

    #[test]
    fn flipped_adjacency_is_the_adjacency_of_the_flipped_mesh() {
        let mut m = tetra();
        let adjacency = m.validate(Closure::Closed).unwrap();
        m.flip();
        assert_eq!(adjacency.flipped(), m.validate(Closure::Closed).unwrap());
    }

    #[test]
    fn prepare_turns_an_inside_out_mesh() {
        let mut m = tetra();
        m.flip();
        let (p, _) = prepare(&m, DEFAULT_WELD_MM, Closure::Closed).unwrap();
        assert!(p.signed_volume_mm3() > 0.0);
    }
}
