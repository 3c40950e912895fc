//! `windcell check JOB.toml [--json] [--svg FILE] [--record FILE.mcap]`: the clearance check
//! (seed 001 §5.7). Exit 0 when clear, 3 on a collision or snag, 2 for bad input.

use std::path::PathBuf;

use cell::plan::check;
use clap::Args;
use sequences::Job;

use super::Failure;

/// Exit code when the check finds a collision or a snag.
pub const EXIT_FINDING: u8 = 3;

/// Check a job for collisions of the eye and the arm and for snags of the free fibre.
#[derive(Debug, Args)]
pub struct CheckArgs {
    /// The job file (TOML).
    pub job: PathBuf,
    /// Print every segment's clearances and the findings as one JSON document.
    #[arg(long)]
    pub json: bool,
    /// Draw Figure 5.9 (side and top views) as SVG to this file.
    #[arg(long, value_name = "FILE")]
    pub svg: Option<PathBuf>,
    /// Write the scene for Foxglove's 3-D panel as MCAP to this file.
    #[arg(long, value_name = "FILE.mcap")]
    pub record: Option<PathBuf>,
}

/// Runs `windcell check`.
pub fn run(args: CheckArgs) -> Result<(), Failure> {
    let (job, text) = Job::load(&args.job).map_err(Failure::input)?;
    let inputs = cell::plan::output::inputs_of_job(&job, &args.job);
    let outputs: Vec<&std::path::Path> = args
        .svg
        .iter()
        .chain(&args.record)
        .map(|p| p.as_path())
        .collect();
    cell::plan::output::check_output_files(&outputs, &inputs).map_err(Failure::from_cell)?;
    let checked = check::run(&job, &text, &args.job).map_err(Failure::from_cell)?;
    super::admit_plan(&job, &text, &args.job, &checked.plan)?;
    let mut files: Vec<(PathBuf, Vec<u8>)> = Vec::new();
    if let Some(svg) = &args.svg {
        files.push((svg.clone(), cell::plan::figure::svg(&checked).into_bytes()));
    }
    if let Some(record) = &args.record {
        files.push((
            record.clone(),
            cell::record::scene::mcap(&checked).map_err(Failure::from_cell)?,
        ));
    }
    for (path, bytes) in files {
        cell::plan::output::write_file(&path, &bytes).map_err(Failure::from_cell)?;
    }
    let mut out = String::new();
    if args.json {
        out = serde_json::to_string_pretty(&check::json(&checked)).map_err(Failure::runtime)?;
        out.push('\n');
    } else {
        for f in &checked.report.findings {
            out += &check::finding_line(&checked, f);
            out.push('\n');
        }
        out += &check::summary(&checked);
        out.push('\n');
    }
    super::print(&out)?;
    if checked.report.is_clear() {
        Ok(())
    } else {
        Err(Failure {
            message: check::summary(&checked),
            exit_code: EXIT_FINDING,
        })
    }
}
