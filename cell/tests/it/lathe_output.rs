//! `windcell lathe plan`'s output as a user expects it: the ordinary permissions, `-o` always a
//! folder, an earlier output kept unless `--force`, and `--dialect` refusals pointing at the help.

use crate::common;

use common::lathe::{lathe_plan, refused_in_one_line};
use common::{example, stderr, variant};

/// The test tube ([`common::lathe::tube`]) with its helical layer only, written into `dir` as `tube.wind`.
fn tube(dir: &std::path::Path) -> std::path::PathBuf {
    variant(
        &common::lathe::tube(),
        dir,
        "tube.wind",
        &[("    { \"windType\": \"hoop\" },\n", "")],
    )
}

/// `windcell lathe plan JOB -o OUT --dialect marlin EXTRA…`.
fn plan(job: &std::path::Path, out: &std::path::Path, extra: &[&str]) -> std::process::Output {
    lathe_plan(job, out, "marlin", extra)
}

#[cfg(unix)]
#[test]
fn the_program_has_the_ordinary_permissions() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    let job = tube(dir.path());
    let out = dir.path().join("out");
    let o = plan(&job, &out, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let mode = std::fs::metadata(out.join("tube.gcode"))
        .unwrap()
        .permissions()
        .mode();
    // What a file created by this process with mode 0666 gets: the umask applied. The umask is
    // read the way a shell reports it, by creating a file the ordinary way and looking.
    let probe = dir.path().join("probe");
    std::fs::write(&probe, b"").unwrap();
    let ordinary = std::fs::metadata(&probe).unwrap().permissions().mode();
    assert_eq!(mode & 0o777, ordinary & 0o777, "{mode:o} vs {ordinary:o}");
    assert_ne!(
        mode & 0o044,
        0,
        "readable by others under umask 022: {mode:o}"
    );
    // No staging file is left behind.
    let names: Vec<_> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names.len(), 1, "{names:?}");
}

#[test]
fn out_names_a_folder_never_a_file() {
    let dir = tempfile::tempdir().unwrap();
    let job = tube(dir.path());
    // A file name that does not exist yet: refused, nothing created.
    let file = dir.path().join("part.gcode");
    let err = refused_in_one_line(&plan(&job, &file, &[]), "looks like a file name", &file);
    assert!(err.contains("folder"), "{err}");
    // An existing file: refused, left as it was.
    std::fs::write(&file, b"keep").unwrap();
    let o = plan(&job, &file, &[]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("is a file"), "{}", stderr(&o));
    assert_eq!(std::fs::read(&file).unwrap(), b"keep");
}

#[test]
fn an_earlier_output_is_kept_unless_forced() {
    let dir = tempfile::tempdir().unwrap();
    let job = tube(dir.path());
    let out = dir.path().join("out");
    assert!(plan(&job, &out, &[]).status.success());
    let target = out.join("tube.gcode");
    std::fs::write(&target, b"earlier").unwrap();
    let o = plan(&job, &out, &[]);
    assert_eq!(o.status.code(), Some(2));
    let err = stderr(&o);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(
        err.contains("tube.gcode") && err.contains("--force"),
        "{err}"
    );
    assert_eq!(std::fs::read(&target).unwrap(), b"earlier");
    let o = plan(&job, &out, &["--force"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        std::fs::read_to_string(&target)
            .unwrap()
            .starts_with("; windcell")
    );
}

#[test]
fn dialect_refusals_point_at_the_help() {
    let dir = tempfile::tempdir().unwrap();
    let job = tube(dir.path());
    let out = dir.path().join("out");
    let o = lathe_plan(&job, &out, "haas", &[]);
    assert_eq!(o.status.code(), Some(2));
    let err = stderr(&o);
    assert!(err.contains("unknown dialect `haas`"), "{err}");
    assert!(err.contains("lathe plan --help"), "{err}");
    assert!(!out.exists());
    // A .wind job on fw-cnc: the message says what a .wind job needs, not the vessel file's
    // `axes` field it does not have.
    let err = refused_in_one_line(&lathe_plan(&job, &out, "fw-cnc", &[]), "tube.wind", &out);
    assert!(!err.contains("axes = 3"), "{err}");
    assert!(err.contains("marlin"), "{err}");
    // A vessel file: pointed at its [machine] table.
    let o = lathe_plan(&example("seed002-vessel.toml"), &out, "fw-cnc", &[]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("[machine]"), "{}", stderr(&o));
    assert!(!out.exists());
}
