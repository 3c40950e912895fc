//! The files a plan writes: the IRB 6/2's control files (`.ROB`, `.IND`, `.SEQ`, `.RUN`, seed 001
//! §5.6) or a six-axis arm's plan (`NAME.plan.json`) and indexer files.

use std::path::PathBuf;

use sequences::Job;
use sequences::{RunFile, SequenceFile};

use crate::Error;
use crate::plan::report::PlanReport;
use crate::plan::tool::{self, JobPlan};

/// Every output file of a planned job: `(file name, contents)`. Fails if a file cannot be
/// written as its reader would read it back ([`sequences::Error::Unwritable`]).
///
/// A six-axis arm has no `.ROB` files (its controller's programs come from `windcell post`): the
/// set is the plan itself, `NAME.plan.json` (the `plan --json` report), and each path's `.IND`
/// file when windcell's indexer turns the mandrel.
pub fn control_files(job: &Job, plan: &JobPlan) -> Result<Vec<(PathBuf, String)>, Error> {
    let mut files = Vec::new();
    if job.six_axis_arm().is_some() {
        if job.mandrel_axis().drive == paths::arm::MandrelDrive::Indexer {
            for path in &plan.paths {
                files.push((
                    PathBuf::from(format!("{}.IND", path.name)),
                    tool::mandrel_file(job, path).write()?,
                ));
            }
        }
        let name = PathBuf::from(format!("{}.plan.json", job.name.get_ref()));
        let report = PlanReport::new(job, plan);
        let mut json = serde_json::to_string_pretty(&report).map_err(|e| Error::Output {
            path: name.clone(),
            source: std::io::Error::other(e),
        })?;
        json.push('\n');
        files.push((name, json));
        return Ok(files);
    }
    for path in &plan.paths {
        files.push((
            PathBuf::from(format!("{}.ROB", path.name)),
            tool::robot_file(job, path)?.write()?,
        ));
        files.push((
            PathBuf::from(format!("{}.IND", path.name)),
            tool::mandrel_file(job, path).write()?,
        ));
    }
    let sequence = SequenceFile {
        names: plan.paths.iter().map(|p| p.name.clone()).collect(),
    };
    let run = RunFile {
        programs: plan.paths.iter().map(|p| p.program).collect(),
    };
    files.push((
        PathBuf::from(format!("{}.SEQ", job.name.get_ref())),
        sequence.write()?,
    ));
    files.push((
        PathBuf::from(format!("{}.RUN", job.name.get_ref())),
        run.write()?,
    ));
    Ok(files)
}
