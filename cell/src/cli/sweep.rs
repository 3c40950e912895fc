//! `windcell sweep JOB.toml -o DIR --paths N`: a coverage set. The job's first traced path is
//! repeated `N` times at start angles `360°/N` apart (programs 1…N) and the whole set is planned
//! and written as `plan` writes one job, so a mesh mandrel is covered from its STL.

use std::path::PathBuf;

use cell::plan::report::PlanReport;
use cell::plan::{output, tool};
use clap::Args;
use sequences::Job;
use toml::Spanned;

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
    let (mut job, text) = Job::load(&args.job).map_err(Failure::input)?;
    output::check_dir(&args.out).map_err(Failure::from_cell)?;
    let Some(pattern) = job.paths.iter().find(|p| p.dxf.is_none()).cloned() else {
        return Err(Failure::input(format!(
            "{}: the job has no traced [[path]] (direction, wind_angle_deg, start_angle_deg) to sweep",
            args.job.display()
        )));
    };
    let start = pattern
        .start_angle_deg
        .as_ref()
        .map_or(0.0, |s| *s.get_ref());
    let span = pattern
        .start_angle_deg
        .as_ref()
        .map_or(pattern.program.span(), |s| s.span());
    job.paths = (0..args.paths)
        .map(|k| {
            let mut p = pattern.clone();
            p.program = Spanned::new(pattern.program.span(), k + 1);
            p.start_angle_deg = Some(Spanned::new(
                span.clone(),
                start + 360.0 * f64::from(k) / f64::from(args.paths),
            ));
            p
        })
        .collect();
    let plan = tool::plan(&job, &text, &args.job).map_err(Failure::from_cell)?;
    let files = cell::plan::files::control_files(&job, &plan).map_err(Failure::from_cell)?;
    output::write_all(&args.out, &files, job.name.get_ref(), args.stale)
        .map_err(Failure::from_cell)?;
    let out = if args.json {
        let mut s = serde_json::to_string_pretty(&PlanReport::new(&job, &plan))
            .map_err(Failure::runtime)?;
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
             wrote {} file{} ({}) to {}\n",
            plan.paths.len(),
            pattern.segments.get_ref(),
            files.len(),
            if files.len() == 1 { "" } else { "s" },
            super::plan::file_kinds(&files),
            args.out.display()
        )
    };
    super::print(&out)
}
