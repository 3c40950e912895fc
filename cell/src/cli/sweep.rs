//! `windcell sweep JOB.toml -o DIR --paths N`: a coverage set. The job's first traced path is
//! repeated `N` times at start angles `360°/N` apart (programs 1…N) and the whole set is planned
//! and written as `plan` writes one job, so a mesh mandrel is covered from its STL.

use std::path::PathBuf;

use cell::plan::report::PlanReport;
use cell::plan::{output, tool};
use clap::Args;
use sequences::Job;

use super::Failure;

/// Plan a coverage set: the job's first path repeated around the mandrel.
#[derive(Debug, Args)]
#[command(allow_negative_numbers = true)]
pub struct SweepArgs {
    /// The job file (TOML); its first path without `dxf` is the pattern.
    pub job: PathBuf,
    /// Where to write the control files (created if missing; written all or nothing).
    #[arg(short = 'o', long = "out", value_name = "DIR")]
    pub out: PathBuf,
    /// Number of paths, 1–255, at equal steps of start angle.
    #[arg(long, default_value_t = 40, value_parser = clap::value_parser!(u8).range(1..), allow_negative_numbers = true)]
    pub paths: u8,
    /// Print the plan as one JSON document on standard output.
    #[arg(long)]
    pub json: bool,
    /// Control files of an earlier plan of the same job in the output folder that this plan does
    /// not write (`NAME_3.ROB` beside a new two-path plan): `refuse` to write, or `remove` them.
    #[arg(long, value_enum, default_value = "refuse")]
    pub stale: output::Stale,
}

/// Runs `windcell sweep`.
pub fn run(args: SweepArgs) -> Result<(), Failure> {
    let (job, text) = Job::load(&args.job).map_err(Failure::input)?;
    output::check_dir(&args.out).map_err(Failure::from_cell)?;
    let paths = std::num::NonZeroU8::new(args.paths)
        .ok_or_else(|| Failure::input("sweep: --paths must lie in 1..=255"))?;
    let job = cell::plan::sweep::expand(&job, &args.job, paths).map_err(Failure::from_cell)?;
    let plan = tool::plan(&job, &text, &args.job).map_err(Failure::from_cell)?;
    let files = cell::plan::files::control_files(&job, &plan).map_err(Failure::from_cell)?;
    super::admit(&job, &text, &args.job, &files)?;
    // The collision and snag check, as `plan` prints it (`windcell run --job` refuses the set
    // while it finds anything).
    let checked = cell::plan::check::check(&job, &text, &args.job, plan.clone())
        .map_err(Failure::from_cell)?;
    let check_line = cell::plan::check::summary(&checked);
    output::write_all(&args.out, &files, job.name.get_ref(), args.stale)
        .map_err(Failure::from_cell)?;
    let out = if args.json {
        let mut value =
            serde_json::to_value(PlanReport::new(&job, &plan)).map_err(Failure::runtime)?;
        if let Some(obj) = value.as_object_mut() {
            obj.insert("check".into(), check_line.clone().into());
            obj.insert("check_clear".into(), checked.report.is_clear().into());
        }
        let mut s = serde_json::to_string_pretty(&value).map_err(Failure::runtime)?;
        s.push('\n');
        s
    } else {
        let worst = plan
            .paths
            .iter()
            .filter_map(|p| p.smoothing_deviation_mm)
            .fold(0.0f64, f64::max);
        format!(
            "{} paths of {} segments planned, smoothed paths ≤ {worst:.4} mm from the traced ones\n\
             {check_line}\n\
             wrote {} file{} ({}) to {}\n",
            plan.paths.len(),
            plan.paths.first().map_or(0, |p| p.plan.segments.len()),
            files.len(),
            if files.len() == 1 { "" } else { "s" },
            super::plan::file_kinds(&files),
            args.out.display()
        )
    };
    super::print(&out)
}
