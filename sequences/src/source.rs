//! Reading an operator's file with a size cap: a job, a DXF drawing, a mesh. Only regular files
//! are read; a device (`/dev/zero`), a FIFO or a folder is refused before it is opened, and a file
//! larger than the cap is refused before it is read, so no input can make a command read for long
//! or allocate more than the cap (docs/ARCHITECTURE.md, "Limits").

use std::io::Read;
use std::path::Path;

use crate::Error;

/// Largest job file, bytes (the shipped jobs are about 2 KiB).
pub const MAX_JOB_BYTES: u64 = 1 << 20;
/// Largest DXF drawing, bytes.
pub const MAX_DXF_BYTES: u64 = 16 << 20;
/// Largest mesh file (STL or OBJ), bytes: 2 GiB. A mesh is streamed ([`open`]), never read whole,
/// so this caps the reading time, not the memory (the triangle limit does that). A binary STL of
/// 5 000 000 triangles (windcell's limit, `paths::limits::MAX_TRIANGLES`) is 250 MB; windcell's
/// own ASCII STL takes 230–400 bytes per triangle (`triasym --ascii`, 1.15–2.0 GB at the limit),
/// OBJ about 55.
pub const MAX_MESH_BYTES: u64 = 2 << 30;

/// Largest robot or indexer control file, sequence or run file, bytes: a discrete `.ROB` of
/// 10 000 segments (the plan's limit) is about 1.2 MB.
pub const MAX_CONTROL_FILE_BYTES: u64 = 8 << 20;
/// Largest part program or G-code file, bytes (a 40-layer tube planned as a part program is a
/// few MB).
pub const MAX_PROGRAM_BYTES: u64 = 64 << 20;
/// Largest run journal, bytes: about 200 000 records of ~300 bytes.
pub const MAX_JOURNAL_BYTES: u64 = 64 << 20;

/// What kind of file system object `path` names, in words, when it is not a regular file.
fn not_regular(file_type: std::fs::FileType) -> Option<&'static str> {
    use std::os::unix::fs::FileTypeExt;
    if file_type.is_file() {
        None
    } else if file_type.is_dir() {
        Some("a folder")
    } else if file_type.is_char_device() {
        Some("a character device")
    } else if file_type.is_block_device() {
        Some("a block device")
    } else if file_type.is_fifo() {
        Some("a FIFO (named pipe)")
    } else if file_type.is_socket() {
        Some("a socket")
    } else {
        Some("not a regular file")
    }
}

/// Opens the regular file `path` for streaming when it holds at most `max_bytes` bytes: the file
/// and its size. Refuses what [`read_bytes`] refuses, without reading it.
pub fn open(path: &Path, max_bytes: u64) -> Result<(std::fs::File, u64), Error> {
    let io = |source| Error::Io {
        file: path.to_path_buf(),
        source,
    };
    let metadata = std::fs::metadata(path).map_err(io)?;
    if let Some(kind) = not_regular(metadata.file_type()) {
        return Err(Error::NotRegularFile {
            file: path.to_path_buf(),
            kind,
        });
    }
    if metadata.len() > max_bytes {
        return Err(Error::FileTooLarge {
            file: path.to_path_buf(),
            bytes: metadata.len(),
            limit_bytes: max_bytes,
        });
    }
    let file = std::fs::File::open(path).map_err(io)?;
    Ok((file, metadata.len()))
}

/// Reads the whole of the regular file `path`, at most `max_bytes` bytes.
///
/// A missing or unreadable file is [`Error::Io`]; a device, FIFO, socket or folder is
/// [`Error::NotRegularFile`] (refused without opening it, so a FIFO never blocks); a file larger
/// than `max_bytes` (by its size, or by what it turns out to hold while it is read) is
/// [`Error::FileTooLarge`].
pub fn read_bytes(path: &Path, max_bytes: u64) -> Result<Vec<u8>, Error> {
    let (file, len) = open(path, max_bytes)?;
    let mut bytes = Vec::with_capacity(usize::try_from(len).unwrap_or(0));
    file.take(max_bytes + 1)
        .read_to_end(&mut bytes)
        .map_err(|source| Error::Io {
            file: path.to_path_buf(),
            source,
        })?;
    if bytes.len() as u64 > max_bytes {
        return Err(Error::FileTooLarge {
            file: path.to_path_buf(),
            bytes: bytes.len() as u64,
            limit_bytes: max_bytes,
        });
    }
    Ok(bytes)
}

/// Reads the regular file `path` as UTF-8 text, at most `max_bytes` bytes (see [`read_bytes`]).
/// Bytes that are not UTF-8 (a UTF-16 file, a binary file) are an error at their line and column,
/// with their byte offset.
pub fn read_text(path: &Path, max_bytes: u64) -> Result<String, Error> {
    let bytes = read_bytes(path, max_bytes)?;
    text(bytes).map_err(|e| e.in_file(path))
}

/// `bytes` as UTF-8 text, or a located error at the first byte that is not.
pub fn text(bytes: Vec<u8>) -> Result<String, Error> {
    match String::from_utf8(bytes) {
        Ok(text) => Ok(text),
        Err(e) => {
            let offset = e.utf8_error().valid_up_to();
            let bytes = e.as_bytes();
            let valid = std::str::from_utf8(&bytes[..offset]).unwrap_or_default();
            let (line, column) = crate::error::line_column(valid, offset);
            let hint = if bytes.starts_with(&[0xFF, 0xFE]) || bytes.starts_with(&[0xFE, 0xFF]) {
                " (the file is UTF-16; save it as UTF-8)"
            } else {
                " (a binary file, or text in another encoding; save it as UTF-8)"
            };
            Err(Error::at(
                line,
                column,
                format!(
                    "byte 0x{:02X} at offset {offset} is not UTF-8 text{hint}",
                    bytes[offset]
                ),
            ))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn devices_and_folders_are_refused_before_reading() {
        let e = read_bytes(Path::new("/dev/zero"), MAX_JOB_BYTES).unwrap_err();
        assert!(
            matches!(e, Error::NotRegularFile { kind, .. } if kind == "a character device"),
            "{e}"
        );
        assert_eq!(
            e.to_string(),
            "/dev/zero: is a character device, not a regular file"
        );
        let dir = tempfile::tempdir().unwrap();
        let e = read_bytes(dir.path(), MAX_JOB_BYTES).unwrap_err();
        assert!(matches!(
            e,
            Error::NotRegularFile {
                kind: "a folder",
                ..
            }
        ));
    }

    #[test]
    fn a_file_over_the_cap_is_refused_and_one_at_the_cap_is_read() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.toml");
        std::fs::write(&path, vec![b'x'; 11]).unwrap();
        let e = read_bytes(&path, 10).unwrap_err();
        assert!(matches!(
            e,
            Error::FileTooLarge {
                bytes: 11,
                limit_bytes: 10,
                ..
            }
        ));
        assert!(
            e.to_string()
                .ends_with("11 bytes, more than the limit of 10 bytes"),
            "{e}"
        );
        assert_eq!(read_bytes(&path, 11).unwrap().len(), 11);
    }

    #[test]
    fn text_that_is_not_utf8_is_located() {
        let e = text(b"name = 1\nab\xFFc".to_vec()).unwrap_err().to_string();
        assert!(
            e.starts_with("2:3: byte 0xFF at offset 11 is not UTF-8"),
            "{e}"
        );
        let e = text(vec![0xFF, 0xFE, b'n', 0]).unwrap_err().to_string();
        assert!(e.starts_with("1:1: byte 0xFF at offset 0"), "{e}");
        assert!(e.contains("UTF-16"), "{e}");
    }

    #[test]
    fn text_comes_back_whole_and_its_errors_name_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("job.toml");
        std::fs::write(&path, "name = \"A\"\nsegments = 51\n").unwrap();
        assert_eq!(
            read_text(&path, MAX_JOB_BYTES).unwrap(),
            "name = \"A\"\nsegments = 51\n"
        );
        std::fs::write(&path, b"name = 1\nab\xFFc").unwrap();
        let e = read_text(&path, MAX_JOB_BYTES).unwrap_err().to_string();
        assert!(
            e.starts_with(&format!("{}:2:3: byte 0xFF", path.display())),
            "{e}"
        );
    }

    /// Files under `/proc` are regular files whose size reads as 0 while they hold text: only the
    /// cap applied while reading can refuse them, so this is the test of that second cap.
    #[test]
    fn a_file_whose_size_reads_zero_is_capped_while_it_is_read() {
        let status = Path::new("/proc/self/status");
        if std::fs::metadata(status).map(|m| m.len()).ok() != Some(0) {
            eprintln!("skipped: no /proc/self/status reading zero bytes on this system");
            return;
        }
        let e = read_bytes(status, 16).unwrap_err();
        assert!(
            matches!(
                e,
                Error::FileTooLarge {
                    bytes: 17,
                    limit_bytes: 16,
                    ..
                }
            ),
            "{e}"
        );
        assert!(
            read_text(status, MAX_JOB_BYTES)
                .unwrap()
                .starts_with("Name:")
        );
    }

    /// Each cap holds the largest file of its kind that windcell itself writes or ships, and
    /// stays within the memory budget of docs/ARCHITECTURE.md ("Limits": a few hundred MB with
    /// the parsed form beside the text).
    #[test]
    fn each_cap_holds_the_largest_file_of_its_kind_and_stays_within_the_budget() {
        use crate::MandrelMove;
        use crate::rob::{Header, Instruction, Interpolation, Movement, Reference, RobotFile};
        let v: [f64; 4] = [-0.123456789012, -0.987654321098, -0.5, -0.617283950617];
        let norm = v.iter().map(|c| c * c).sum::<f64>().sqrt();
        let widest = Instruction {
            number: 1,
            speed_pct: 99.875,
            position_mm: [-2047.9375, -2047.9375, -2047.9375],
            q: v.map(|c| c / norm),
            interpolation: Interpolation::Rectangular,
            reference: Reference::Absolute,
            mandrel: MandrelMove {
                accel_rps2: 19.875,
                start_stop_rps: 0.125,
                max_rps: 9.875,
                steps: -999_999,
            },
        };
        let rob = RobotFile {
            header: Header {
                program: 255,
                base_speed_mm_s: 1000.0,
                max_speed_mm_s: 2300.0,
                movement: Movement::Discrete,
                sync_mandrel_deg: -359.875,
            },
            instructions: (1..=paths::limits::MAX_SEGMENTS as u16)
                .map(|number| Instruction { number, ..widest })
                .collect(),
        };
        let rob_bytes = rob.write().unwrap().len() as u64;
        assert!(
            rob_bytes <= MAX_CONTROL_FILE_BYTES,
            "{rob_bytes} bytes of .ROB"
        );
        // A binary STL at the triangle limit: 84-byte header and count, 50 bytes a triangle; an
        // ASCII STL at the limit with every number in its longest `{:e}` form (24 characters).
        let stl_bytes = 84 + 50 * paths::limits::MAX_TRIANGLES as u64;
        assert!(stl_bytes <= MAX_MESH_BYTES, "{stl_bytes} bytes of STL");
        let number = "-1.2345678901234567e-300";
        let facet = format!(
            "  facet normal {number} {number} {number}\n    outer loop\n{}    endloop\n  endfacet\n",
            format!("      vertex {number} {number} {number}\n").repeat(3)
        );
        let ascii_bytes = facet.len() as u64 * paths::limits::MAX_TRIANGLES as u64;
        assert!(
            ascii_bytes <= MAX_MESH_BYTES,
            "{ascii_bytes} bytes of ASCII STL"
        );
        // A journal of the most segments a job may hold, at 300 bytes a record.
        assert!(300 * paths::limits::MAX_JOB_SEGMENTS as u64 <= MAX_JOURNAL_BYTES);
        let examples = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples");
        for (name, cap) in [
            ("sbend.toml", MAX_JOB_BYTES),
            ("cylinder.toml", MAX_JOB_BYTES),
            ("seed002-vessel.toml", MAX_JOB_BYTES),
            ("FW-CNC.PAR", MAX_JOB_BYTES),
            ("sbend-path.dxf", MAX_DXF_BYTES),
            ("sbend.stl", MAX_MESH_BYTES),
            ("cone-dome-cylinder.prg", MAX_PROGRAM_BYTES),
        ] {
            read_bytes(&examples.join(name), cap).unwrap_or_else(|e| panic!("{name}: {e}"));
        }
        // Files read whole stay small; a mesh is streamed instead (`open`).
        for cap in [
            MAX_JOB_BYTES,
            MAX_DXF_BYTES,
            MAX_CONTROL_FILE_BYTES,
            MAX_PROGRAM_BYTES,
            MAX_JOURNAL_BYTES,
        ] {
            assert!(cap <= 64 << 20, "{cap}");
        }
    }
}
