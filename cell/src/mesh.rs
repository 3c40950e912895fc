//! Mesh mandrels from files: STL (binary or ASCII) or OBJ, chosen by the file extension, welded,
//! validated and prepared for tracing. Every error names the file, and the line or triangle.

use std::path::Path;

use paths::mesh::trace::Tracer;
use paths::mesh::{Closure, Mesh, obj, prepare, stl};

use crate::Error;

/// Reads a mesh file (`.stl` or `.obj`, any case) without welding or validating it.
pub fn read(file: &Path) -> Result<Mesh, Error> {
    let mesh_error = |source| Error::Mesh {
        file: file.to_path_buf(),
        source,
    };
    let ext = file
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let bytes = std::fs::read(file).map_err(|source| Error::Read {
        file: file.to_path_buf(),
        source,
    })?;
    match ext.as_str() {
        "stl" => Mesh::from_soup(&stl::parse(&bytes).map_err(mesh_error)?).map_err(mesh_error),
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
            obj::parse(text).map_err(mesh_error)
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
    let mesh = read(file)?;
    let (mesh, adjacency) = prepare(&mesh, weld_mm, closure).map_err(mesh_error)?;
    Tracer::new(mesh, &adjacency, crease_deg).map_err(mesh_error)
}
