//! Writing a set of output files all or nothing.
//!
//! Every check that could stop the set half-way is made before anything is written: the
//! destination must be a folder (or absent, under a folder), no output name may be held by a
//! folder or other non-file, and control files of an earlier plan of the same job that this plan
//! does not write (`CYL_3.ROB` beside a new two-path `CYL.SEQ`) are refused or removed as
//! [`Stale`] says. The files are then written into a hidden staging folder:
//!
//! - a destination that does not exist yet is created by renaming the staging folder onto it,
//!   one step;
//! - into an existing folder, the files it already holds are moved aside into the staging
//!   folder, the new files are renamed into place (the sequence and run files, which name the
//!   others, last), and on any failure the moved-aside files are put back, so the folder is
//!   either as it was or holds the whole new set.
//!
//! Messages name the destination and the output file, never the staging folder.

use std::ffi::OsStr;
use std::fs;
use std::io::ErrorKind;
use std::path::{Path, PathBuf};

use crate::Error;

/// What to do with control files of an earlier plan of the same job that the new plan does not
/// write.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum Stale {
    /// Refuse to write anything (the default: nothing is deleted unasked).
    #[default]
    Refuse,
    /// Remove them as part of the same all-or-nothing step.
    Remove,
}

fn refuse(path: &Path, reason: impl Into<String>) -> Error {
    Error::OutputPath {
        path: path.to_path_buf(),
        reason: reason.into(),
    }
}

fn failed(path: &Path) -> impl Fn(std::io::Error) -> Error + '_ {
    move |source| Error::Output {
        path: path.to_path_buf(),
        source,
    }
}

/// Checks that `dir` can hold output: it is a folder, or it does not exist and its nearest
/// existing ancestor is a folder. Made before any work so that a wrong `-o` fails at once.
pub fn check_dir(dir: &Path) -> Result<(), Error> {
    if dir.as_os_str().is_empty() {
        return Err(refuse(dir, "is empty; name an output folder"));
    }
    match fs::metadata(dir) {
        Ok(m) if m.is_dir() => return Ok(()),
        Ok(_) => return Err(refuse(dir, "exists and is not a folder")),
        Err(e) if e.kind() == ErrorKind::NotFound => {}
        Err(e) if e.kind() == ErrorKind::NotADirectory => {}
        Err(source) => return Err(failed(dir)(source)),
    }
    for ancestor in dir.ancestors().skip(1) {
        if ancestor.as_os_str().is_empty() {
            break;
        }
        match fs::metadata(ancestor) {
            Ok(m) if m.is_dir() => return Ok(()),
            Ok(_) => {
                return Err(refuse(
                    dir,
                    format!("lies under {}, which is not a folder", ancestor.display()),
                ));
            }
            Err(_) => continue,
        }
    }
    Ok(())
}

/// Checks that the single output file `path` can be written: it is a regular file or absent,
/// and its folder exists.
pub fn check_file(path: &Path) -> Result<(), Error> {
    if path.file_name().is_none() {
        return Err(refuse(path, "does not name a file"));
    }
    match fs::symlink_metadata(path) {
        Ok(m) if m.is_file() => {}
        Ok(m) if m.is_dir() => return Err(refuse(path, "is a folder")),
        Ok(_) => return Err(refuse(path, "exists and is not a regular file")),
        Err(e) if e.kind() == ErrorKind::NotFound => {}
        Err(e) if e.kind() == ErrorKind::NotADirectory => {
            return Err(refuse(path, "lies under a file, not a folder"));
        }
        Err(source) => return Err(failed(path)(source)),
    }
    let parent = folder_of(path);
    match fs::metadata(&parent) {
        Ok(m) if m.is_dir() => Ok(()),
        Ok(_) => Err(refuse(path, "lies under a file, not a folder")),
        Err(_) => Err(refuse(
            path,
            format!("its folder {} does not exist", parent.display()),
        )),
    }
}

/// Refuses an output file that is one of the command's `inputs` (the same file, by device and
/// inode, whatever the path says): writing it would destroy what the command reads.
pub fn not_an_input(output: &Path, inputs: &[PathBuf]) -> Result<(), Error> {
    use std::os::unix::fs::MetadataExt;
    let Ok(out) = fs::metadata(output) else {
        return Ok(());
    };
    for input in inputs {
        if let Ok(m) = fs::metadata(input)
            && m.dev() == out.dev()
            && m.ino() == out.ino()
        {
            return Err(refuse(
                output,
                format!(
                    "is {}, an input of this command; name another output",
                    input.display()
                ),
            ));
        }
    }
    Ok(())
}

/// Where `path` is: its folder's canonical path joined with its file name (`None` when the folder
/// cannot be looked at), so that two spellings of one output (`a/../b/x`, `b/x`) compare equal
/// before either exists.
fn identity(path: &Path) -> Option<PathBuf> {
    let name = path.file_name()?;
    fs::canonicalize(folder_of(path)).ok().map(|d| d.join(name))
}

/// The one rule for outputs: every path a command writes is checked against every path it reads
/// and against each other before anything is written. An output that is an input (by device and
/// inode, or by where it lies) would destroy what the command reads; two outputs at one place
/// would leave one of them half-written over the other.
pub fn check_outputs(outputs: &[&Path], inputs: &[PathBuf]) -> Result<(), Error> {
    for (k, output) in outputs.iter().enumerate() {
        not_an_input(output, inputs)?;
        let here = identity(output);
        if here.is_some() {
            for input in inputs {
                if identity(input) == here {
                    return Err(refuse(
                        output,
                        format!(
                            "is {}, an input of this command; name another output",
                            input.display()
                        ),
                    ));
                }
            }
        }
        for earlier in &outputs[..k] {
            if here.is_some() && identity(earlier) == here {
                return Err(refuse(
                    output,
                    format!(
                        "is also the output {}: two outputs cannot share one file",
                        earlier.display()
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// The files a job reads: the job file, its mesh and its DXF drawings (relative to the job's
/// folder).
pub fn inputs_of_job(job: &sequences::Job, file: &Path) -> Vec<PathBuf> {
    let dir = file.parent().unwrap_or(Path::new(""));
    let mut inputs = vec![file.to_path_buf()];
    inputs.extend(job.mandrel.mesh.iter().map(|m| dir.join(m.get_ref())));
    inputs.extend(job.mandrel.spine_dxf.iter().map(|m| dir.join(m.get_ref())));
    inputs.extend(
        job.paths
            .iter()
            .filter_map(|p| p.dxf.as_ref())
            .map(|d| dir.join(d.get_ref())),
    );
    inputs
}

/// [`check_file`] on each of a command's single output files, then [`check_outputs`].
pub fn check_output_files(outputs: &[&Path], inputs: &[PathBuf]) -> Result<(), Error> {
    for output in outputs {
        check_file(output)?;
    }
    check_outputs(outputs, inputs)
}

fn folder_of(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// A new hidden file or folder in `parent` (`.windcell-<process>-<n>`), created with the
/// ordinary permissions (the umask applies, as for the outputs themselves); `make` creates it
/// and fails if it exists.
fn staging_in(
    parent: &Path,
    make: impl Fn(&Path) -> std::io::Result<()>,
) -> std::io::Result<PathBuf> {
    let mut last = None;
    for n in 0..100 {
        let path = parent.join(format!(".windcell-{}-{n}", std::process::id()));
        match make(&path) {
            Ok(()) => return Ok(path),
            Err(e) if e.kind() == ErrorKind::AlreadyExists => last = Some(e),
            Err(e) => return Err(e),
        }
    }
    Err(last.unwrap_or_else(|| ErrorKind::AlreadyExists.into()))
}

/// A staging folder, removed when dropped (after its contents were moved out, or on failure).
struct Staging(PathBuf);

impl Drop for Staging {
    fn drop(&mut self) {
        let _ = fs::remove_dir_all(&self.0);
    }
}

/// Writes the single file `path` all or nothing: into a hidden file beside it, renamed into place.
pub fn write_file(path: &Path, contents: &[u8]) -> Result<(), Error> {
    check_file(path)?;
    let staged = staging_in(&folder_of(path), |p| {
        fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(p)
            .and_then(|mut f| std::io::Write::write_all(&mut f, contents))
    })
    .map_err(failed(path))?;
    fs::rename(&staged, path).map_err(|source| {
        let _ = fs::remove_file(&staged);
        failed(path)(source)
    })
}

/// `NAME_<digits>.ROB` or `NAME_<digits>.IND`: a control file of a plan of the job `stem`.
fn is_control_file_of(name: &OsStr, stem: &str) -> bool {
    let Some(name) = name.to_str() else {
        return false;
    };
    let Some(rest) = name
        .strip_prefix(stem)
        .and_then(|r| r.strip_prefix('_'))
        .and_then(|r| r.strip_suffix(".ROB").or_else(|| r.strip_suffix(".IND")))
    else {
        return false;
    };
    !rest.is_empty() && rest.bytes().all(|b| b.is_ascii_digit())
}

/// Writes `files` (names relative to `dir`, the sequence and run files last) so that either all
/// of them land in `dir` or none does; see the module documentation. `stem` is the job name whose
/// earlier control files in `dir` are [`Stale`] when this set does not include them.
pub fn write_all(
    dir: &Path,
    files: &[(PathBuf, String)],
    stem: &str,
    stale: Stale,
) -> Result<(), Error> {
    check_dir(dir)?;
    let exists = dir.is_dir();
    let mut earlier = Vec::new();
    if exists {
        for (name, _) in files {
            let target = dir.join(name);
            match fs::symlink_metadata(&target) {
                Ok(m) if m.is_file() => {}
                Ok(m) if m.is_dir() => {
                    return Err(refuse(
                        &target,
                        "is a folder; the output file cannot replace it (nothing written)",
                    ));
                }
                Ok(_) => {
                    return Err(refuse(
                        &target,
                        "exists and is not a regular file (nothing written)",
                    ));
                }
                Err(_) => {}
            }
        }
        for entry in fs::read_dir(dir).map_err(failed(dir))? {
            let entry = entry.map_err(failed(dir))?;
            let name = entry.file_name();
            if is_control_file_of(&name, stem)
                && !files.iter().any(|(f, _)| f.as_os_str() == name)
                && entry.file_type().is_ok_and(|t| t.is_file())
            {
                earlier.push(PathBuf::from(name));
            }
        }
        earlier.sort();
        if let (Some(first), Stale::Refuse) = (earlier.first(), stale) {
            return Err(refuse(
                &dir.join(first),
                format!(
                    "is one of {} control file(s) of an earlier plan of {stem} that this plan \
                     does not write; remove them or pass --stale remove (nothing written)",
                    earlier.len()
                ),
            ));
        }
    }
    let staging_parent = if exists {
        dir.to_path_buf()
    } else {
        let parent = folder_of(dir);
        fs::create_dir_all(&parent).map_err(failed(dir))?;
        parent
    };
    let staging = Staging(staging_in(&staging_parent, |p| fs::create_dir(p)).map_err(failed(dir))?);
    for (name, contents) in files {
        fs::write(staging.0.join(name), contents).map_err(failed(&dir.join(name)))?;
    }
    if !exists {
        return fs::rename(&staging.0, dir).map_err(failed(dir));
    }
    let aside = staging.0.join(".earlier");
    fs::create_dir(&aside).map_err(failed(dir))?;
    // Each step, undone in reverse order if a later one fails.
    let mut done: Vec<(PathBuf, PathBuf)> = Vec::new();
    let mut step = |from: PathBuf, to: PathBuf, report: PathBuf| -> Result<(), Error> {
        match fs::rename(&from, &to) {
            Ok(()) => {
                done.push((from, to));
                Ok(())
            }
            Err(source) => {
                for (from, to) in done.drain(..).rev() {
                    let _ = fs::rename(&to, &from);
                }
                Err(failed(&report)(source))
            }
        }
    };
    let replaced = files
        .iter()
        .map(|(name, _)| name.clone())
        .filter(|name| dir.join(name).exists())
        .chain(earlier.iter().cloned())
        .collect::<Vec<_>>();
    for name in &replaced {
        step(dir.join(name), aside.join(name), dir.join(name))?;
    }
    for (name, _) in files {
        step(staging.0.join(name), dir.join(name), dir.join(name))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn set(names: &[&str], contents: &str) -> Vec<(PathBuf, String)> {
        names
            .iter()
            .map(|n| (PathBuf::from(n), contents.to_string()))
            .collect()
    }

    fn listing(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    /// Only a folder that is missing (or lies under a missing one) is left to be created; any
    /// other reason the system gives for not reading it (a symbolic-link loop, a name too long)
    /// is refused at once, before the ancestors are looked at.
    #[test]
    fn staging_skips_names_taken_and_gives_up_at_once_on_other_errors() {
        let tmp = tempfile::tempdir().unwrap();
        let taken = tmp
            .path()
            .join(format!(".windcell-{}-0", std::process::id()));
        fs::create_dir(&taken).unwrap();
        let made = staging_in(tmp.path(), |p| fs::create_dir(p)).unwrap();
        assert_eq!(
            made,
            tmp.path()
                .join(format!(".windcell-{}-1", std::process::id()))
        );
        let calls = std::cell::Cell::new(0);
        let e = staging_in(tmp.path(), |_| {
            calls.set(calls.get() + 1);
            Err(ErrorKind::PermissionDenied.into())
        })
        .unwrap_err();
        assert_eq!(e.kind(), ErrorKind::PermissionDenied);
        assert_eq!(calls.get(), 1);
    }

    #[test]
    fn an_output_folder_the_system_cannot_look_at_is_refused() {
        let tmp = tempfile::tempdir().unwrap();
        let looped = tmp.path().join("loop");
        std::os::unix::fs::symlink(&looped, &looped).unwrap();
        let e = check_dir(&looped).unwrap_err();
        assert!(matches!(e, Error::Output { .. }), "{e}");
        let long = tmp.path().join("n".repeat(300));
        let e = check_dir(&long).unwrap_err();
        assert!(matches!(e, Error::Output { .. }), "{e}");
        // Missing, and missing under a missing folder: fine, the parent is a folder.
        check_dir(&tmp.path().join("new")).unwrap();
        check_dir(&tmp.path().join("new/deeper")).unwrap();
    }

    #[test]
    fn creates_the_directory_or_adds_to_it() {
        let root = tempfile::tempdir().unwrap();
        let dir = root.path().join("out");
        write_all(&dir, &set(&["A_1.ROB"], "x\n"), "A", Stale::Refuse).unwrap();
        assert_eq!(fs::read_to_string(dir.join("A_1.ROB")).unwrap(), "x\n");
        fs::write(dir.join("keep.txt"), "k").unwrap();
        write_all(&dir, &set(&["A_1.ROB"], "y\n"), "A", Stale::Refuse).unwrap();
        assert_eq!(fs::read_to_string(dir.join("A_1.ROB")).unwrap(), "y\n");
        assert_eq!(listing(&dir), ["A_1.ROB", "keep.txt"]);
        assert_eq!(listing(root.path()), ["out"]);
    }

    #[test]
    fn a_folder_named_like_an_output_stops_the_set_before_anything_is_written() {
        let root = tempfile::tempdir().unwrap();
        let dir = root.path().join("out");
        write_all(
            &dir,
            &set(&["A_1.ROB", "A_2.ROB", "A.SEQ"], "old\n"),
            "A",
            Stale::Refuse,
        )
        .unwrap();
        fs::remove_file(dir.join("A_2.ROB")).unwrap();
        fs::create_dir(dir.join("A_2.ROB")).unwrap();
        let e = write_all(
            &dir,
            &set(&["A_1.ROB", "A_2.ROB", "A.SEQ"], "new\n"),
            "A",
            Stale::Refuse,
        )
        .unwrap_err();
        assert!(e.is_input(), "{e}");
        assert!(e.to_string().contains("A_2.ROB: is a folder"), "{e}");
        assert!(!e.to_string().contains(".windcell-"), "{e}");
        assert_eq!(fs::read_to_string(dir.join("A_1.ROB")).unwrap(), "old\n");
        assert_eq!(fs::read_to_string(dir.join("A.SEQ")).unwrap(), "old\n");
        assert_eq!(listing(&dir), ["A.SEQ", "A_1.ROB", "A_2.ROB"]);
        // A symbolic link in an output's place is not written through either.
        fs::remove_dir(dir.join("A_2.ROB")).unwrap();
        std::os::unix::fs::symlink(dir.join("A.SEQ"), dir.join("A_2.ROB")).unwrap();
        let e = write_all(
            &dir,
            &set(&["A_1.ROB", "A_2.ROB", "A.SEQ"], "new\n"),
            "A",
            Stale::Refuse,
        )
        .unwrap_err();
        assert!(
            e.to_string()
                .contains("A_2.ROB: exists and is not a regular file"),
            "{e}"
        );
        assert_eq!(fs::read_to_string(dir.join("A.SEQ")).unwrap(), "old\n");
    }

    #[test]
    fn stale_control_files_are_refused_or_removed_as_asked() {
        let root = tempfile::tempdir().unwrap();
        let dir = root.path().join("out");
        let old = set(
            &["A_1.ROB", "A_1.IND", "A_3.ROB", "A_3.IND", "A.SEQ"],
            "old\n",
        );
        write_all(&dir, &old, "A", Stale::Refuse).unwrap();
        fs::write(dir.join("AB_3.ROB"), "other job").unwrap();
        let new = set(&["A_1.ROB", "A_1.IND", "A.SEQ"], "new\n");
        let e = write_all(&dir, &new, "A", Stale::Refuse).unwrap_err();
        assert!(e.is_input());
        assert!(
            e.to_string()
                .contains("A_3.IND: is one of 2 control file(s)"),
            "{e}"
        );
        assert_eq!(fs::read_to_string(dir.join("A_1.ROB")).unwrap(), "old\n");
        write_all(&dir, &new, "A", Stale::Remove).unwrap();
        assert_eq!(listing(&dir), ["A.SEQ", "AB_3.ROB", "A_1.IND", "A_1.ROB"]);
        assert_eq!(fs::read_to_string(dir.join("A.SEQ")).unwrap(), "new\n");
    }

    #[test]
    fn output_paths_that_cannot_be_folders_are_input_errors() {
        let root = tempfile::tempdir().unwrap();
        let file = root.path().join("f");
        fs::write(&file, "x").unwrap();
        for dir in [file.clone(), file.join("sub"), file.join("sub/deeper")] {
            let e = write_all(&dir, &set(&["A_1.ROB"], "x"), "A", Stale::Refuse).unwrap_err();
            assert!(e.is_input(), "{e}");
            assert!(e.to_string().starts_with(&dir.display().to_string()), "{e}");
        }
        let e = check_file(&root.path().join("f/x.stl")).unwrap_err();
        assert!(
            e.to_string().ends_with("lies under a file, not a folder"),
            "{e}"
        );
        let e = check_file(root.path()).unwrap_err();
        assert!(e.to_string().ends_with("is a folder"), "{e}");
        // A symbolic link is neither a file nor a folder: not written through.
        let link = root.path().join("l.stl");
        std::os::unix::fs::symlink(&file, &link).unwrap();
        let e = check_file(&link).unwrap_err();
        assert!(
            e.to_string().ends_with("exists and is not a regular file"),
            "{e}"
        );
        fs::remove_file(&link).unwrap();
        // A file in a folder that does not exist; a bare name, in the working folder.
        let e = check_file(&root.path().join("missing/x.stl")).unwrap_err();
        assert!(e.to_string().contains("does not exist"), "{e}");
        check_file(Path::new("windcell-output-check-x.stl")).unwrap();
        // A name the system refuses to look up is refused, not treated as absent.
        let e = check_file(&root.path().join("n".repeat(300))).unwrap_err();
        assert!(matches!(e, Error::Output { .. }), "{e}");
        assert_eq!(listing(root.path()), ["f"]);
    }

    #[test]
    fn control_file_names_of_a_job() {
        assert!(is_control_file_of(OsStr::new("CYL_3.ROB"), "CYL"));
        assert!(is_control_file_of(OsStr::new("CYL_12.IND"), "CYL"));
        assert!(!is_control_file_of(OsStr::new("CYL_3.SEQ"), "CYL"));
        assert!(!is_control_file_of(OsStr::new("CYL_.ROB"), "CYL"));
        assert!(!is_control_file_of(OsStr::new("CYL_x.ROB"), "CYL"));
        assert!(!is_control_file_of(OsStr::new("CYLX_3.ROB"), "CYL"));
        assert!(!is_control_file_of(OsStr::new("CY_3.ROB"), "CYL"));
    }

    #[test]
    fn single_files_are_replaced_whole() {
        let root = tempfile::tempdir().unwrap();
        let path = root.path().join("m.stl");
        write_file(&path, b"one").unwrap();
        write_file(&path, b"two").unwrap();
        assert_eq!(fs::read(&path).unwrap(), b"two");
        assert_eq!(listing(root.path()), ["m.stl"]);
    }
}
