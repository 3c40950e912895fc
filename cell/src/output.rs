//! Writing a set of output files all or nothing: everything is written into a fresh temporary
//! directory beside the destination first, and moved into place only when every file is complete.

use std::fs;
use std::path::{Path, PathBuf};

use crate::Error;

fn output_error(path: &Path) -> impl FnOnce(std::io::Error) -> Error + '_ {
    move |source| Error::Output {
        path: path.to_path_buf(),
        source,
    }
}

/// Writes `files` (names relative to `dir`) so that either all of them land in `dir` or none does.
/// `dir` is created when missing; other files in it are left alone.
pub fn write_all(dir: &Path, files: &[(PathBuf, String)]) -> Result<(), Error> {
    let parent = match dir.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    fs::create_dir_all(&parent).map_err(output_error(&parent))?;
    let staging = tempfile::Builder::new()
        .prefix(".windcell-")
        .tempdir_in(&parent)
        .map_err(output_error(&parent))?;
    for (name, contents) in files {
        let path = staging.path().join(name);
        fs::write(&path, contents).map_err(output_error(&path))?;
    }
    if !dir.exists() {
        let staged = staging.keep();
        return fs::rename(&staged, dir).map_err(|source| {
            let _ = fs::remove_dir_all(&staged);
            Error::Output {
                path: dir.to_path_buf(),
                source,
            }
        });
    }
    for (name, _) in files {
        let target = dir.join(name);
        fs::rename(staging.path().join(name), &target).map_err(output_error(&target))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn creates_the_directory_or_adds_to_it() {
        let root = tempfile::tempdir().unwrap();
        let dir = root.path().join("out");
        let files = vec![(PathBuf::from("A_1.ROB"), "x\n".to_string())];
        write_all(&dir, &files).unwrap();
        assert_eq!(fs::read_to_string(dir.join("A_1.ROB")).unwrap(), "x\n");
        fs::write(dir.join("keep.txt"), "k").unwrap();
        let more = vec![(PathBuf::from("A_1.ROB"), "y\n".to_string())];
        write_all(&dir, &more).unwrap();
        assert_eq!(fs::read_to_string(dir.join("A_1.ROB")).unwrap(), "y\n");
        assert!(dir.join("keep.txt").exists());
        let leftovers: Vec<_> = fs::read_dir(root.path())
            .unwrap()
            .filter(|e| {
                e.as_ref()
                    .unwrap()
                    .file_name()
                    .to_string_lossy()
                    .starts_with(".windcell-")
            })
            .collect();
        assert!(leftovers.is_empty());
    }
}
