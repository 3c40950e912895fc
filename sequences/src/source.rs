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
/// Largest mesh file (STL or OBJ), bytes: a binary STL of 500 000 triangles (windcell's limit)
/// is 25 MB; ASCII STL takes about 250 bytes per triangle.
pub const MAX_MESH_BYTES: u64 = 32 << 20;

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

/// Reads the whole of the regular file `path`, at most `max_bytes` bytes.
///
/// A missing or unreadable file is [`Error::Io`]; a device, FIFO, socket or folder is
/// [`Error::NotRegularFile`] (refused without opening it, so a FIFO never blocks); a file larger
/// than `max_bytes` (by its size, or by what it turns out to hold while it is read) is
/// [`Error::FileTooLarge`].
pub fn read_bytes(path: &Path, max_bytes: u64) -> Result<Vec<u8>, Error> {
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
    let too_large = |bytes| Error::FileTooLarge {
        file: path.to_path_buf(),
        bytes,
        limit_bytes: max_bytes,
    };
    if metadata.len() > max_bytes {
        return Err(too_large(metadata.len()));
    }
    let file = std::fs::File::open(path).map_err(io)?;
    let mut bytes = Vec::with_capacity(usize::try_from(metadata.len()).unwrap_or(0));
    file.take(max_bytes + 1)
        .read_to_end(&mut bytes)
        .map_err(io)?;
    if bytes.len() as u64 > max_bytes {
        return Err(too_large(bytes.len() as u64));
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
}
