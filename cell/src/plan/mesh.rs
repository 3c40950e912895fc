//! Mesh mandrels from files: STL (binary or ASCII) or OBJ, chosen by the file extension, welded,
//! validated and prepared for tracing. Every error names the file, and the line or triangle.
//!
//! The file is streamed, never read whole: an STL file's corners are welded as they are parsed
//! (`paths::mesh::stl::read`), an OBJ file is read line by line, so a mesh of
//! `paths::limits::MAX_TRIANGLES` triangles (a 250 MB binary STL, a 2 GB ASCII STL) costs memory
//! per triangle, not per byte of the file (docs/ARCHITECTURE.md, "Limits").

use std::io::{BufRead, BufReader, Read};
use std::path::Path;

use paths::mesh::cache::{Checksum, Key, decode, encode};
use paths::mesh::trace::Tracer;
use paths::mesh::{
    Adjacency, Closure, Mesh, obj, prepare, prepare_welded, stl, with_byte, with_column_in_row,
    with_line,
};

use crate::Error;

/// Read buffer of a mesh file, bytes.
const READ_BUFFER_BYTES: usize = 1 << 18;

/// Where a mesh file's triangles are: the line of each for the text formats, nothing for binary
/// STL (its records are at fixed byte offsets).
#[derive(Debug, Default)]
struct Places {
    lines: Option<Vec<usize>>,
}

impl Places {
    /// `error` at its line and column (text, the column read back from the file's line) or byte
    /// offset (binary), where it names a triangle or a line.
    fn locate(&self, file: &Path, error: paths::Error) -> paths::Error {
        match &self.lines {
            Some(lines) => {
                let error = with_line(error, lines);
                match &error {
                    paths::Error::MeshSyntax {
                        line: Some(line),
                        column: None,
                        ..
                    } => {
                        let line = *line;
                        let row = line_of(file, line).unwrap_or_default();
                        with_column_in_row(error, line, &row)
                    }
                    _ => error,
                }
            }
            None => with_byte(error),
        }
    }
}

/// Line `line` (1-based) of a text file, read again up to it (only when an error names it).
fn line_of(file: &Path, line: usize) -> Option<String> {
    let (handle, _) = sequences::source::open(file, sequences::source::MAX_MESH_BYTES).ok()?;
    let mut reader = BufReader::with_capacity(READ_BUFFER_BYTES, handle);
    let mut buf = Vec::new();
    for _ in 0..line {
        buf.clear();
        let read = (&mut reader)
            .take(paths::mesh::MAX_LINE_BYTES as u64 + 2)
            .read_until(b'\n', &mut buf)
            .ok()?;
        if read == 0 {
            return None;
        }
    }
    let text = String::from_utf8_lossy(&buf);
    Some(text.trim_end_matches(['\n', '\r']).to_string())
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

/// Prepared meshes of at least this many triangles are cached beside their file (below it,
/// preparing takes a few tens of milliseconds, less than checking a cache is worth).
pub const CACHE_MIN_TRIANGLES: usize = 100_000;

/// The cache file of a mesh file: `NAME.windcell-prepared` beside it.
pub fn cache_path(file: &Path) -> std::path::PathBuf {
    let mut name = file.file_name().unwrap_or_default().to_os_string();
    name.push(".windcell-prepared");
    file.with_file_name(name)
}

/// A reader that feeds every byte it passes on to a checksum, so the mesh file's checksum comes
/// from the same pass that parses it.
struct Summing<R> {
    inner: R,
    sum: Checksum,
}

impl<R: Read> Read for Summing<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        self.sum.update(&buf[..n]);
        Ok(n)
    }
}

/// The checksum of the whole of `handle`, read in pieces.
fn checksum_of(mut handle: std::fs::File) -> std::io::Result<u64> {
    let mut sum = Checksum::default();
    let mut buf = vec![0u8; 1 << 20];
    loop {
        match handle.read(&mut buf) {
            Ok(0) => return Ok(sum.value()),
            Ok(n) => sum.update(&buf[..n]),
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
}

/// The prepared mesh from `file`'s cache, when there is one made from this very file (size and
/// checksum), tolerance and closure; `None` otherwise (then the mesh is prepared from the file).
fn from_cache(
    file: &Path,
    weld_mm: f64,
    closure: Closure,
    handle: &std::fs::File,
    len: u64,
) -> Option<(Mesh, Adjacency)> {
    let cache = cache_path(file);
    let metadata = std::fs::metadata(&cache).ok()?;
    // A cache is about 52 bytes per triangle; anything far larger is not one.
    if !metadata.is_file() || metadata.len() > 128 * paths::limits::MAX_TRIANGLES as u64 {
        return None;
    }
    let bytes = std::fs::read(&cache).ok()?;
    let key = Key {
        source_bytes: len,
        source_checksum: checksum_of(handle.try_clone().ok()?).ok()?,
        weld_mm,
        closure,
    };
    decode(&bytes, &key)
}

/// Writes the cache of a prepared mesh beside `file` (staged under a temporary name, then
/// renamed, so a reader never sees half of it). A folder that cannot be written is no error: the
/// mesh is prepared from the file next time.
fn write_cache(file: &Path, key: &Key, mesh: &Mesh, adjacency: &Adjacency) {
    let cache = cache_path(file);
    let mut staged = cache.clone().into_os_string();
    staged.push(format!(".{}.tmp", std::process::id()));
    let staged = std::path::PathBuf::from(staged);
    let bytes = encode(key, mesh, adjacency);
    if std::fs::write(&staged, bytes).is_err() || std::fs::rename(&staged, &cache).is_err() {
        let _ = std::fs::remove_file(&staged);
    }
}

/// Reads, welds at `weld_mm` and validates (closed when `closure` says so) a mesh: the mesh and
/// its adjacency, ready for [`Tracer::new`] and the collision check's solid.
pub fn load_prepared(
    file: &Path,
    weld_mm: f64,
    closure: Closure,
) -> Result<(Mesh, Adjacency), Error> {
    let mesh_error = |source| Error::Mesh {
        file: file.to_path_buf(),
        source,
    };
    let ext = file
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let (mut handle, len) = sequences::source::open(file, sequences::source::MAX_MESH_BYTES)?;
    if ext != "stl" && ext != "obj" {
        return Err(mesh_error(paths::Error::MeshSyntax {
            line: None,
            column: None,
            byte: None,
            message: format!("unknown mesh format `.{ext}` (expected .stl or .obj)"),
        }));
    }
    if let Some(prepared) = from_cache(file, weld_mm, closure, &handle, len) {
        return Ok(prepared);
    }
    // Checking a cache read the file through a clone of the handle, which shares its offset.
    std::io::Seek::rewind(&mut handle).map_err(|source| sequences::Error::Io {
        file: file.to_path_buf(),
        source,
    })?;
    let mut summing = Summing {
        inner: handle,
        sum: Checksum::default(),
    };
    let max = paths::limits::MAX_TRIANGLES;
    let prepared = {
        let reader = BufReader::with_capacity(READ_BUFFER_BYTES, &mut summing);
        match ext.as_str() {
            "stl" => {
                let welded = stl::read(reader, len, weld_mm, max).map_err(mesh_error)?;
                let places = Places {
                    lines: welded.lines,
                };
                prepare_welded(welded.mesh, closure)
                    .map_err(|e| mesh_error(places.locate(file, e)))?
            }
            _ => {
                let (mesh, lines) = obj::read(reader, max).map_err(mesh_error)?;
                let places = Places { lines: Some(lines) };
                prepare(&mesh, weld_mm, closure).map_err(|e| mesh_error(places.locate(file, e)))?
            }
        }
    };
    if prepared.0.triangles().len() >= CACHE_MIN_TRIANGLES {
        // The checksum covers the whole file: read what the parser left (nothing, normally).
        if std::io::copy(&mut summing, &mut std::io::sink()).is_ok() {
            let key = Key {
                source_bytes: len,
                source_checksum: summing.sum.value(),
                weld_mm,
                closure,
            };
            write_cache(file, &key, &prepared.0, &prepared.1);
        }
    }
    Ok(prepared)
}

/// A mesh mandrel ready for planning and checking: the tracer the paths are traced on and the
/// collision check's solid, both from the same prepared triangles.
#[derive(Debug, Clone)]
pub struct Ready {
    /// The tracer ([`Tracer::new`] at [`paths::mesh::trace::DEFAULT_CREASE_DEG`]).
    pub tracer: std::sync::Arc<Tracer>,
    /// The solid ([`paths::clearance::MeshSolid::with_adjacency`]).
    pub solid: std::sync::Arc<paths::clearance::MeshSolid>,
}

/// The mesh mandrel last made ready in this process, with what it was made from: the file, its
/// size and checksum, the welding tolerance (a closed surface is always required). Planning a job
/// again, or another job on the same mesh file, takes it instead of reading and preparing the file
/// again (one mesh is kept: jobs on one mandrel are planned in turn).
static LAST_READY: std::sync::Mutex<Option<(std::path::PathBuf, Key, Ready)>> =
    std::sync::Mutex::new(None);

/// What a mesh file's ready mandrel is made from (`None` when the file cannot be read; reading
/// it to prepare it then says why).
pub fn ready_key(file: &Path, weld_mm: f64) -> Option<Key> {
    let (handle, len) = sequences::source::open(file, sequences::source::MAX_MESH_BYTES).ok()?;
    Some(Key {
        source_bytes: len,
        source_checksum: checksum_of(handle).ok()?,
        weld_mm,
        closure: Closure::Closed,
    })
}

/// The mesh mandrel made ready from `file` with `key`, if it is the one kept.
pub fn ready_kept(file: &Path, key: &Key) -> Option<Ready> {
    let kept = LAST_READY.lock().unwrap_or_else(|p| p.into_inner());
    match &*kept {
        Some((f, k, ready)) if f == file && k == key => Some(ready.clone()),
        _ => None,
    }
}

/// Keeps the mesh mandrel made ready from `file` with `key` (in place of the one kept).
pub fn keep_ready(file: &Path, key: Key, ready: Ready) {
    let mut kept = LAST_READY.lock().unwrap_or_else(|p| p.into_inner());
    *kept = Some((file.to_path_buf(), key, ready));
}

/// Forgets the mesh mandrel kept by [`keep_ready`]: the next plan prepares its mesh as a fresh
/// process does (the `plan` benchmarks measure a `windcell plan` run so).
pub fn forget_ready() {
    *LAST_READY.lock().unwrap_or_else(|p| p.into_inner()) = None;
}

#[cfg(test)]
mod tests {
    use super::*;
    use paths::mesh::{DEFAULT_WELD_MM, triasym};

    /// A closed cylinder of 2 · 256 · `rings` + 512 triangles, radius `r_mm`, as binary STL.
    fn cylinder_stl(rings: usize, r_mm: f64) -> Vec<u8> {
        let profile: Vec<(f64, f64)> = (0..=rings).map(|i| (i as f64, r_mm)).collect();
        stl::write_binary(&triasym::revolution(&profile, 256, true).unwrap(), "test")
    }

    #[test]
    fn a_large_mesh_is_cached_beside_its_file_and_prepared_again_when_the_file_changes() {
        let tmp = tempfile::tempdir().unwrap();
        let file = tmp.path().join("m.stl");
        std::fs::write(&file, cylinder_stl(200, 30.0)).unwrap();
        let fresh = load_prepared(&file, DEFAULT_WELD_MM, Closure::Closed).unwrap();
        assert!(fresh.0.triangles().len() >= CACHE_MIN_TRIANGLES);
        let cache = cache_path(&file);
        assert!(cache.is_file(), "no cache written");
        // Read back from the cache: the same prepared mesh.
        let cached = load_prepared(&file, DEFAULT_WELD_MM, Closure::Closed).unwrap();
        assert_eq!(cached, fresh);
        // Another tolerance does not use it.
        let other = load_prepared(&file, 2e-4, Closure::Closed).unwrap();
        assert_eq!(other.0.triangles().len(), fresh.0.triangles().len());
        // The file changes (same size, another radius): prepared from the file, cache replaced.
        std::fs::write(&file, cylinder_stl(200, 31.0)).unwrap();
        let changed = load_prepared(&file, DEFAULT_WELD_MM, Closure::Closed).unwrap();
        let radius = |m: &Mesh| {
            m.vertices()
                .iter()
                .map(|v| v.x.hypot(v.y))
                .fold(0.0, f64::max)
        };
        assert!(
            (radius(&changed.0) - 31.0).abs() < 1e-5,
            "{}",
            radius(&changed.0)
        );
        assert_eq!(
            load_prepared(&file, DEFAULT_WELD_MM, Closure::Closed).unwrap(),
            changed
        );
        // A corrupted cache is not read: the mesh is prepared from the file.
        let mut bytes = std::fs::read(&cache).unwrap();
        let middle = bytes.len() / 2;
        bytes[middle] ^= 0xff;
        std::fs::write(&cache, bytes).unwrap();
        assert_eq!(
            load_prepared(&file, DEFAULT_WELD_MM, Closure::Closed).unwrap(),
            changed
        );
    }

    /// A kept mesh is taken only for the file it was made from, unchanged (same size, another
    /// radius is a miss), at the same tolerance.
    #[test]
    fn a_kept_mesh_is_taken_only_for_its_unchanged_file_and_tolerance() {
        let tmp = tempfile::tempdir().unwrap();
        let file = tmp.path().join("k.stl");
        std::fs::write(&file, cylinder_stl(4, 30.0)).unwrap();
        let (mesh, adjacency) = load_prepared(&file, DEFAULT_WELD_MM, Closure::Closed).unwrap();
        let ready = Ready {
            tracer: std::sync::Arc::new(
                Tracer::new(
                    mesh.clone(),
                    &adjacency,
                    paths::mesh::trace::DEFAULT_CREASE_DEG,
                )
                .unwrap(),
            ),
            solid: std::sync::Arc::new(
                paths::clearance::MeshSolid::with_adjacency(&mesh, &adjacency).unwrap(),
            ),
        };
        let key = ready_key(&file, DEFAULT_WELD_MM).unwrap();
        // The kept mesh is the process's: a test planning a mesh job on another thread may replace
        // it between keeping and taking, so keeping is tried again a few times.
        let taken = (0..20).any(|_| {
            keep_ready(&file, key, ready.clone());
            ready_kept(&file, &ready_key(&file, DEFAULT_WELD_MM).unwrap()).is_some()
        });
        assert!(taken);
        assert!(ready_kept(&file, &ready_key(&file, 2e-4).unwrap()).is_none());
        let other = tmp.path().join("other.stl");
        std::fs::write(&other, cylinder_stl(4, 30.0)).unwrap();
        assert!(ready_kept(&other, &ready_key(&other, DEFAULT_WELD_MM).unwrap()).is_none());
        let before = std::fs::metadata(&file).unwrap().len();
        std::fs::write(&file, cylinder_stl(4, 31.0)).unwrap();
        assert_eq!(std::fs::metadata(&file).unwrap().len(), before);
        assert!(ready_kept(&file, &ready_key(&file, DEFAULT_WELD_MM).unwrap()).is_none());
        assert!(ready_key(&tmp.path().join("missing.stl"), DEFAULT_WELD_MM).is_none());
    }

    #[test]
    fn a_small_mesh_leaves_no_cache() {
        let tmp = tempfile::tempdir().unwrap();
        let file = tmp.path().join("s.stl");
        std::fs::write(&file, cylinder_stl(10, 30.0)).unwrap();
        load_prepared(&file, DEFAULT_WELD_MM, Closure::Closed).unwrap();
        assert!(!cache_path(&file).exists());
    }
}
