//! The batch as the operator has it (seed 001 §5.6.3): a sequence file naming robot control files
//! (and their mandrel files), a run file naming program numbers; or a job file planned in memory.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use sequences::{MandrelFile, RobotFile, RunFile, SequenceFile};

use crate::Error;
use crate::run::cellfile::Cell;
use crate::run::coordinator::{Batch, Item, ItemPlaces, Reach, RunMode};
use crate::run::journal::{FNV_BASIS, fnv1a};

/// Control files in memory: name (without extension) and extension → text.
pub type FileSet = BTreeMap<String, String>;

/// What a batch is made of before the pre-run check.
#[derive(Debug, Clone)]
pub struct Loaded {
    /// Items in winding order for `mode`.
    pub items: Vec<Item>,
    /// The mode: `--mode`, else the first control file's movement.
    pub mode: RunMode,
    /// Hash of every file's text.
    pub job_id: String,
    /// The sequence file's path (journal default beside it).
    pub sequence_path: PathBuf,
}

/// Reads a control, sequence or run file with the size cap of `sequences::source`.
fn read(path: &Path) -> Result<String, Error> {
    Ok(sequences::source::read_text(
        path,
        sequences::source::MAX_CONTROL_FILE_BYTES,
    )?)
}

/// Loads `DIR/NAME.SEQ`, its run file (`run`, default `DIR/NAME.RUN`) and the control files it
/// names.
pub fn load(seq: &Path, run: Option<&Path>, mode: Option<RunMode>) -> Result<Loaded, Error> {
    let dir = seq.parent().unwrap_or(Path::new("."));
    let seq_text = read(seq)?;
    let sequence = SequenceFile::parse(&seq_text).map_err(|e| Error::File(e.in_file(seq)))?;
    let mut files = FileSet::new();
    files.insert("SEQ".into(), seq_text);
    let run_path = run.map_or_else(|| seq.with_extension("RUN"), Path::to_path_buf);
    for name in sequence.distinct() {
        let rob = dir.join(format!("{name}.ROB"));
        files.insert(format!("{name}.ROB"), read(&rob)?);
        let ind = dir.join(format!("{name}.IND"));
        if ind.exists() {
            files.insert(format!("{name}.IND"), read(&ind)?);
        }
    }
    let needs_run = |m: RunMode| m != RunMode::Discrete;
    if run.is_some() || run_path.exists() {
        files.insert("RUN".into(), read(&run_path)?);
    }
    let loaded = from_files(&files, mode, dir, &run_path)?;
    if needs_run(loaded.mode) && !files.contains_key("RUN") {
        return Err(Error::MissingFile {
            file: run_path,
            why: "program mode runs the run file's programs",
        });
    }
    Ok(Loaded {
        sequence_path: seq.to_path_buf(),
        ..loaded
    })
}

/// Makes the batch from control-file texts (`SEQ`, `RUN`, `NAME.ROB`, `NAME.IND`); `dir` and
/// `run_path` only name files in errors.
pub fn from_files(
    files: &FileSet,
    mode: Option<RunMode>,
    dir: &Path,
    run_path: &Path,
) -> Result<Loaded, Error> {
    let seq_text = files.get("SEQ").map(String::as_str).unwrap_or("");
    let sequence = SequenceFile::parse(seq_text).map_err(Error::File)?;
    let mut robs: BTreeMap<&str, (RobotFile, Option<MandrelFile>, ItemPlaces)> = BTreeMap::new();
    let mut hash = fnv1a(FNV_BASIS, seq_text.as_bytes());
    for name in sequence.distinct() {
        let rob_path = dir.join(format!("{name}.ROB"));
        let text = files
            .get(&format!("{name}.ROB"))
            .ok_or_else(|| Error::MissingFile {
                file: rob_path.clone(),
                why: "named in the sequence",
            })?;
        hash = fnv1a(hash, text.as_bytes());
        let (rob, rob_places) =
            RobotFile::parse_placed(text).map_err(|e| Error::File(e.in_file(&rob_path)))?;
        let (ind, ind_places) = match files.get(&format!("{name}.IND")) {
            Some(t) => {
                hash = fnv1a(hash, t.as_bytes());
                let p = dir.join(format!("{name}.IND"));
                let (ind, places) =
                    MandrelFile::parse_placed(t).map_err(|e| Error::File(e.in_file(&p)))?;
                (Some(ind), Some((p, places)))
            }
            None => (None, None),
        };
        if let Some((other, _)) = robs
            .iter()
            .find(|(_, (r, _, _))| r.header.program == rob.header.program)
        {
            let (line, column) = rob_places.field("program").unwrap_or((1, 1));
            return Err(Error::DuplicateProgram {
                file: rob_path,
                line,
                column,
                program: rob.header.program,
                other: dir.join(format!("{other}.ROB")),
            });
        }
        let places = ItemPlaces {
            rob: (rob_path, rob_places),
            ind: ind_places,
        };
        robs.insert(name, (rob, ind, places));
    }
    let first = robs
        .get(sequence.names[0].as_str())
        .map(|(r, _, _)| r.header.movement);
    let mode = mode
        .or(first.map(RunMode::from_movement))
        .unwrap_or(RunMode::Discrete);
    let item = |name: &str| -> Item {
        let (rob, ind, places) = robs[name].clone();
        Item {
            name: name.to_string(),
            rob,
            ind,
            places: Some(places),
        }
    };
    let items = if mode == RunMode::Discrete {
        sequence.names.iter().map(|n| item(n)).collect()
    } else {
        let run_text = files.get("RUN").map(String::as_str).unwrap_or("");
        hash = fnv1a(hash, run_text.as_bytes());
        let run = RunFile::parse(run_text).map_err(|e| Error::File(e.in_file(run_path)))?;
        let mut items = Vec::new();
        for (line, p) in run.programs.iter().enumerate() {
            let name = robs
                .iter()
                .find(|(_, (r, _, _))| r.header.program == *p)
                .map(|(n, _)| *n)
                .ok_or_else(|| Error::ProgramNotLoaded {
                    file: run_path.to_path_buf(),
                    line: line + 1,
                    program: *p,
                })?;
            items.push(item(name));
        }
        items
    };
    Ok(Loaded {
        items,
        mode,
        job_id: format!("{hash:016x}"),
        sequence_path: dir.join("SEQ"),
    })
}

/// Control files of a planned job, in memory, as [`from_files`] reads them.
pub fn files_of_job(files: &[(PathBuf, String)]) -> FileSet {
    let mut set = FileSet::new();
    for (path, text) in files {
        let name = path
            .file_name()
            .and_then(|n| n.to_str())
            .unwrap_or_default()
            .to_string();
        let key = match path.extension().and_then(|e| e.to_str()) {
            Some("SEQ") => "SEQ".to_string(),
            Some("RUN") => "RUN".to_string(),
            _ => name,
        };
        set.insert(key, text.clone());
    }
    set
}

/// The arm's envelope for the pre-run check: the eye at most the two links and the eye mechanism
/// from the shoulder, and every pose on the job's five-axis arm ([`Reach::arm`]).
pub fn envelope(job: &sequences::Job) -> Reach {
    let arm = crate::plan::tool::arm(job);
    let stretch = arm.upper_arm_mm + arm.forearm_mm + arm.eye_mechanism_mm;
    Reach {
        max_radius_mm: stretch,
        min_radius_mm: 0.0,
        z_range_mm: (
            arm.shoulder_height_mm - stretch,
            arm.shoulder_height_mm + stretch,
        ),
        arm: Some(arm),
    }
}

/// A job's control files planned in memory (`files`, as [`crate::plan::files::control_files`]
/// makes them) read back as [`load`] reads them from disk, for `mode` (else their movement).
pub fn of_job(
    job_path: &Path,
    files: &[(PathBuf, String)],
    mode: Option<RunMode>,
) -> Result<Loaded, Error> {
    let dir = job_path.parent().unwrap_or(Path::new("."));
    let mut loaded = from_files(&files_of_job(files), mode, dir, &dir.join("RUN"))?;
    loaded.sequence_path = job_path.to_path_buf();
    // The files are in memory, not yet written where `dir` would name them: a refusal names
    // the control file and the instruction, and the job value behind it ([`admit`]).
    for item in &mut loaded.items {
        item.places = None;
    }
    Ok(loaded)
}

/// What `windcell run` makes of a planned job on the job's own cell: its control files (`files`,
/// as [`crate::plan::files::control_files`] makes them) read back and put through the pre-run
/// check ([`Batch::new`]: each instruction in the devices' units and ranges, within the arm's
/// envelope, each mandrel move within the drive's pulse rates and counts, the programs within
/// the robot's memory): [`of_job`], then the [`Batch::new`] `run` makes before it moves. `plan`,
/// `sweep` and `check` refuse with it what `run` would refuse, so a plan that exits 0 is one
/// `run` accepts. Errors name the job file.
pub fn admit(
    job: &sequences::Job,
    text: &str,
    job_path: &Path,
    files: &[(PathBuf, String)],
    mode: Option<RunMode>,
) -> Result<(Loaded, Batch), Error> {
    let refused = |source| not_runnable(job, text, job_path, source);
    let loaded = of_job(job_path, files, mode).map_err(refused)?;
    let cell = Cell::of_job(job, job_path)?;
    let batch = Batch::new(
        loaded.items.clone(),
        loaded.mode,
        loaded.job_id.clone(),
        cell.drive,
        envelope(job),
    )
    .map_err(refused)?;
    Ok((loaded, batch))
}

/// A pre-run refusal of a job's planned files ([`Error::NotRunnable`]), placed at the job value
/// behind it where one is (`text` is the job's).
pub fn not_runnable(job: &sequences::Job, text: &str, job_path: &Path, source: Error) -> Error {
    Error::NotRunnable {
        job: job_path.to_path_buf(),
        place: job_field(job, &source).map(|span| sequences::error::line_column(text, span.start)),
        source: Box::new(source),
    }
}

/// The job-file value behind a pre-run refusal, as its span in the job's text: every figure of a
/// planned control file that the devices can refuse comes from one `[cell]` value, so the
/// control-file value the refusal is about ([`Error::control_value`]) names it. A mandrel move's
/// acceleration is `[cell.drive] accel_rps2`; its top speed and pulse rate are
/// `mandrel_speed_rps`; its start/stop speed is `[cell.drive] start_stop_rps`; the header's speeds
/// are `base_speed_mm_s` and `max_speed_mm_s`; an instruction's speed is a fraction of
/// `base_speed_mm_s`. `None` for a refusal no single job value causes (the robot's memory, a
/// position, the steps).
fn job_field(job: &sequences::Job, refusal: &Error) -> Option<std::ops::Range<usize>> {
    let c = &job.cell;
    match refusal.control_value()?.field {
        "accel_rps2" => Some(c.drive.accel_rps2.span()),
        "start_rps" => Some(c.drive.start_stop_rps.span()),
        "max_rps" => Some(c.mandrel_speed_rps.span()),
        "max_speed_mm_s" => Some(c.max_speed_mm_s.span()),
        "base_speed_mm_s" | "speed_pct" => Some(c.base_speed_mm_s.span()),
        _ => None,
    }
}
