//! Mesh mandrels from files: STL (binary or ASCII) or OBJ, chosen by the file extension, welded,
//! validated and prepared for tracing. Every error names the file, and the line or triangle.

use std::path::Path;

use paths::mesh::trace::Tracer;
use paths::mesh::{Closure, Mesh, obj, prepare, stl, with_line};

use crate::Error;

/// Reads a mesh file (`.stl` or `.obj`, any case) without welding or validating it.
pub fn read(file: &Path) -> Result<Mesh, Error> {
    read_located(file).map(|(mesh, _)| mesh)
}

/// Like [`read`], with the line of each triangle for the text formats (empty for binary STL).
fn read_located(file: &Path) -> Result<(Mesh, Vec<usize>), Error> {
    let mesh_error = |source| Error::Mesh {
        file: file.to_path_buf(),
        source,
    };
    let ext = file
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let bytes = sequences::source::read_bytes(file, sequences::source::MAX_MESH_BYTES)?;
    match ext.as_str() {
        "stl" => {
            let (soup, lines) = stl::parse_located(&bytes).map_err(mesh_error)?;
            let lines = lines.unwrap_or_default();
            let mesh = Mesh::from_soup(&soup).map_err(|e| mesh_error(with_line(e, &lines)))?;
            Ok((mesh, lines))
        }
        "obj" => {
            let text = std::str::from_utf8(&bytes).map_err(|e| {
                let line = 1 + bytes[..e.valid_up_to()]
                    .iter()
                    .filter(|&&b| b == b'\n')
                    .count();
                mesh_error(paths::Error::MeshSyntax {
                    line: Some(line),
                    message: "OBJ with bytes that are not UTF-8 text".into(),
                })
            })?;
            obj::parse_located(text).map_err(mesh_error)
        }
        _ => Err(mesh_error(paths::Error::MeshSyntax {
            line: None,
            message: format!("unknown mesh format `.{ext}` (expected .stl or .obj)"),
        })),
    }
}

/// Reads, welds at `weld_mm`, validates (closed when `closure` says so) and prepares a mesh for
/// tracing with edges sharper than `crease_deg` as boundaries.
pub fn load(file: &Path, weld_mm: f64, closure: Closure, crease_deg: f64) -> Result<Tracer, Error> {
    let mesh_error = |source| Error::Mesh {
        file: file.to_path_buf(),
        source,
    };
    let (mesh, lines) = read_located(file)?;
    let (mesh, adjacency) =
        prepare(&mesh, weld_mm, closure).map_err(|e| mesh_error(with_line(e, &lines)))?;
    Tracer::new(mesh, &adjacency, crease_deg).map_err(mesh_error)
}
