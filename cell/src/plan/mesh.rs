//! Mesh mandrels from files: STL (binary or ASCII) or OBJ, chosen by the file extension, welded,
//! validated and prepared for tracing. Every error names the file, and the line or triangle.

use std::path::Path;

use paths::mesh::trace::Tracer;
use paths::mesh::{Closure, Mesh, obj, prepare, stl, with_byte, with_column, with_line};

use crate::Error;

/// Reads a mesh file (`.stl` or `.obj`, any case) without welding or validating it.
pub fn read(file: &Path) -> Result<Mesh, Error> {
    read_located(file).map(|(mesh, _)| mesh)
}

/// Where a mesh file's triangles are: the line of each for the text formats (with the text, for
/// columns), nothing for binary STL (its records are at fixed byte offsets).
#[derive(Debug, Default)]
struct Places {
    lines: Option<Vec<usize>>,
    text: String,
}

impl Places {
    /// `error` at its line and column (text) or byte offset (binary), where it names a triangle
    /// or a line.
    fn locate(&self, error: paths::Error) -> paths::Error {
        match &self.lines {
            Some(lines) => with_column(with_line(error, lines), &self.text),
            None => with_byte(error),
        }
    }
}

/// Like [`read`], with the places of its triangles.
fn read_located(file: &Path) -> Result<(Mesh, Places), Error> {
    let mesh_error = |source| Error::Mesh {
        file: file.to_path_buf(),
        source,
    };
    let ext = file
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let bytes = sequences::source::read_bytes(file, sequences::source::MAX_MESH_BYTES)?;
    // A binary STL's header gives its triangle count: checked before the triangles are read.
    let too_many = |count: usize, place: Option<u64>| {
        paths::limits::at_most(
            "triangle count",
            count as f64,
            paths::limits::MAX_TRIANGLES as f64,
        )
        .map_err(|e| match place {
            Some(byte) => mesh_error(paths::Error::MeshSyntax {
                line: None,
                column: None,
                byte: Some(byte),
                message: e.to_string(),
            }),
            None => mesh_error(e),
        })
    };
    if ext == "stl" && bytes.len() >= 84 {
        let count = u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as usize;
        if 84 + 50 * count as u64 == bytes.len() as u64 {
            too_many(count, Some(80))?;
        }
    }
    let not_utf8 = |e: std::str::Utf8Error, what: &str| {
        let valid = &bytes[..e.valid_up_to()];
        let line = 1 + valid.iter().filter(|&&b| b == b'\n').count();
        let line_start = valid.iter().rposition(|&b| b == b'\n').map_or(0, |i| i + 1);
        let column = 1 + String::from_utf8_lossy(&valid[line_start..])
            .chars()
            .count();
        mesh_error(paths::Error::MeshSyntax {
            line: Some(line),
            column: Some(column),
            byte: Some(e.valid_up_to() as u64),
            message: format!("{what} with bytes that are not UTF-8 text"),
        })
    };
    match ext.as_str() {
        "stl" => {
            let text = || std::str::from_utf8(&bytes).unwrap_or_default().to_string();
            let (soup, lines) = stl::parse_located(&bytes).map_err(|e| {
                let places = Places {
                    lines: Some(Vec::new()),
                    text: text(),
                };
                mesh_error(places.locate(e))
            })?;
            let places = Places {
                text: if lines.is_some() {
                    text()
                } else {
                    String::new()
                },
                lines,
            };
            too_many(soup.len(), None)?;
            let mesh = Mesh::from_soup(&soup).map_err(|e| mesh_error(places.locate(e)))?;
            Ok((mesh, places))
        }
        "obj" => {
            let text = std::str::from_utf8(&bytes).map_err(|e| not_utf8(e, "OBJ"))?;
            let (mesh, lines) =
                obj::parse_located(text).map_err(|e| mesh_error(with_column(e, text)))?;
            too_many(mesh.triangles().len(), None)?;
            Ok((
                mesh,
                Places {
                    lines: Some(lines),
                    text: text.to_string(),
                },
            ))
        }
        _ => Err(mesh_error(paths::Error::MeshSyntax {
            line: None,
            column: None,
            byte: None,
            message: format!("unknown mesh format `.{ext}` (expected .stl or .obj)"),
        })),
    }
}

/// Reads, welds at `weld_mm`, validates (closed when `closure` says so) and prepares a mesh for
/// tracing with edges sharper than `crease_deg` as boundaries.
pub fn load(file: &Path, weld_mm: f64, closure: Closure, crease_deg: f64) -> Result<Tracer, Error> {
    let (mesh, adjacency) = load_prepared(file, weld_mm, closure)?;
    Tracer::new(mesh, &adjacency, crease_deg).map_err(|source| Error::Mesh {
        file: file.to_path_buf(),
        source,
    })
}

/// Reads, welds at `weld_mm` and validates (closed when `closure` says so) a mesh: the mesh and
/// its adjacency, ready for [`Tracer::new`] and the collision check's solid.
pub fn load_prepared(
    file: &Path,
    weld_mm: f64,
    closure: Closure,
) -> Result<(Mesh, paths::mesh::Adjacency), Error> {
    let (mesh, places) = read_located(file)?;
    prepare(&mesh, weld_mm, closure).map_err(|e| Error::Mesh {
        file: file.to_path_buf(),
        source: places.locate(e),
    })
}
