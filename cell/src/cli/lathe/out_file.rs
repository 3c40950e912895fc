//! Where `windcell lathe plan` writes: `-o` names a folder (created if missing), the program is
//! `FOLDER/NAME.EXT`, an earlier output of the same name is kept unless `--force`, and the file
//! is written whole (a hidden staging file renamed into place) with the ordinary permissions
//! (0666 less the umask: 0644 under the usual umask 022, as the robot cell's control files).

use std::io::Write;
use std::path::{Path, PathBuf};

use super::super::Failure;

/// Extensions that name a program or drawing file rather than a folder: `-o part.gcode` is
/// refused with a message saying that `-o` is a folder.
const FILE_EXTENSIONS: [&str; 12] = [
    "gcode", "nc", "ngc", "tap", "prg", "g", "cnc", "txt", "svg", "mcap", "json", "csv",
];

/// Checks `-o` before anything is planned: a folder or nothing at that path, never a file name.
pub fn check_out_dir(dir: &Path) -> Result<(), Failure> {
    let shown = dir.display();
    match std::fs::metadata(dir) {
        Ok(m) if m.is_dir() => return Ok(()),
        Ok(_) => {
            return Err(Failure::input(format!(
                "-o {shown}: is a file; -o names the folder the program is written into \
                 (as FOLDER/NAME.EXT, NAME the job's name)"
            )));
        }
        Err(_) => {}
    }
    if let Some(ext) = dir.extension().and_then(|e| e.to_str())
        && FILE_EXTENSIONS.contains(&ext.to_ascii_lowercase().as_str())
    {
        return Err(Failure::input(format!(
            "-o {shown}: looks like a file name; -o names the folder the program is written \
             into (as FOLDER/NAME.EXT, NAME the job's name), e.g. -o {}",
            dir.parent()
                .filter(|p| !p.as_os_str().is_empty())
                .map_or_else(|| "out".to_string(), |p| p.display().to_string())
        )));
    }
    cell::plan::output::check_dir(dir).map_err(Failure::from_cell)
}

/// Refuses to replace an earlier output unless `force`.
pub fn check_target(target: &Path, force: bool) -> Result<(), Failure> {
    match std::fs::symlink_metadata(target) {
        Ok(m) if m.is_dir() => Err(Failure::input(format!(
            "{}: is a folder, where the program would be written",
            target.display()
        ))),
        Ok(_) if !force => Err(Failure::input(format!(
            "{}: exists (an earlier output of the same name); --force replaces it",
            target.display()
        ))),
        _ => Ok(()),
    }
}

/// A file being written: a hidden staging file in the output folder, persisted by
/// [`Staged::persist`] (dropped, it is removed).
pub struct Staged {
    file: tempfile::NamedTempFile,
    target: PathBuf,
}

impl Staged {
    /// Creates the folder if needed and a staging file for `target` in it.
    pub fn new(dir: &Path, target: PathBuf) -> Result<Staged, Failure> {
        std::fs::create_dir_all(dir)
            .map_err(|e| Failure::runtime(format!("{}: {e}", dir.display())))?;
        let file = staging_file(dir)
            .map_err(|e| Failure::runtime(format!("{}: {e}", target.display())))?;
        Ok(Staged { file, target })
    }

    /// The file to write into.
    pub fn file(&mut self) -> &mut std::fs::File {
        self.file.as_file_mut()
    }

    /// Flushes and renames the staging file onto the target.
    pub fn persist(self) -> Result<PathBuf, Failure> {
        let target = self.target;
        let mut file = self.file;
        file.flush()
            .map_err(|e| Failure::runtime(format!("{}: {e}", target.display())))?;
        file.persist(&target)
            .map_err(|e| Failure::runtime(format!("{}: {}", target.display(), e.error)))?;
        Ok(target)
    }
}

/// A hidden temporary file in `dir`, created with mode 0666 before the umask (tempfile's own
/// default is 0600, private to the user, which is not what an output file should be).
fn staging_file(dir: &Path) -> std::io::Result<tempfile::NamedTempFile> {
    let mut builder = tempfile::Builder::new();
    builder.prefix(".windcell-");
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        builder.permissions(std::fs::Permissions::from_mode(0o666));
    }
    builder.tempfile_in(dir)
}
