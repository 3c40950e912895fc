//! `windcell plan JOB.toml -o DIR [--json]`: the TOOL step (seed 001 §5.6).

use std::path::PathBuf;

use cell::plan::report::PlanReport;
use cell::plan::{output, tool};
use clap::Args;
use sequences::Job;

use super::Failure;

/// Turn a job file into robot (.ROB) and mandrel (.IND) control files, a sequence file and a run file.
#[derive(Debug, Args)]
#[command(allow_negative_numbers = true)]
pub struct PlanArgs {
    /// The job file (TOML).
    pub job: PathBuf,
    /// Where to write the control files (created if missing; written all or nothing).
    #[arg(short = 'o', long = "out", value_name = "DIR")]
    pub out: PathBuf,
    /// Print the plan as one JSON document on standard output.
    #[arg(long)]
    pub json: bool,
    /// Control files of an earlier plan of the same job in the output folder that this plan does
    /// not write (`NAME_3.ROB` beside a new two-path plan): `refuse` to write, or `remove` them.
    #[arg(long, value_enum, default_value = "refuse")]
    pub stale: output::Stale,
}

/// Runs `windcell plan`.
pub fn run(args: PlanArgs) -> Result<(), Failure> {
    let (job, text) = Job::load(&args.job).map_err(Failure::input)?;
    output::check_dir(&args.out).map_err(Failure::from_cell)?;
    let plan = tool::plan(&job, &text, &args.job).map_err(Failure::from_cell)?;
    let files = cell::plan::files::control_files(&job, &plan).map_err(Failure::from_cell)?;
    super::admit(&job, &text, &args.job, &files)?;
    // The collision and snag check's one line (`windcell check` shows every segment; the plan
    // is written either way, and `windcell run` refuses it while the check finds anything).
    let checked = cell::plan::check::check(&job, &text, &args.job, plan.clone())
        .map_err(Failure::from_cell)?;
    let check_line = cell::plan::check::summary(&checked);
    output::write_all(&args.out, &files, job.name.get_ref(), args.stale)
        .map_err(Failure::from_cell)?;
    let mut out = String::new();
    if args.json {
        let report = PlanReport::new(&job, &plan);
        let mut value = serde_json::to_value(&report).map_err(Failure::runtime)?;
        // Mesh mandrels and imported paths: how far smoothing moved the path; imported paths:
        // how far each drawing point lies from the mandrel surface.
        if let Some(paths) = value.get_mut("paths").and_then(|p| p.as_array_mut()) {
            for (json, planned) in paths.iter_mut().zip(&plan.paths) {
                if let (Some(obj), Some(d)) = (json.as_object_mut(), planned.smoothing_deviation_mm)
                {
                    obj.insert("smoothing_deviation_mm".into(), d.into());
                }
                if let (Some(obj), Some(d)) = (json.as_object_mut(), &planned.surface_distances_mm)
                {
                    let worst = d.iter().fold(0.0f64, |w, x| w.max(x.abs()));
                    obj.insert("dxf_surface_distance_mm".into(), d.clone().into());
                    obj.insert("dxf_max_surface_distance_mm".into(), worst.into());
                }
            }
        }
        if let Some(obj) = value.as_object_mut() {
            obj.insert("check".into(), check_line.clone().into());
            obj.insert("check_clear".into(), checked.report.is_clear().into());
        }
        out = serde_json::to_string_pretty(&value).map_err(Failure::runtime)?;
        out.push('\n');
    } else {
        for p in &plan.paths {
            let paced = p.plan.segments.iter().filter(|s| s.robot_paced).count();
            out += &format!(
                "{}: {} segments, {} mandrel motor steps, drift ≤ {:.4}° from the ideal mandrel \
                 angle, payout eye ≥ {:.1} mm from the mandrel surface, fibre enters the eye at \
                 ≤ {:.2}° to its axis{}{}\n",
                p.name,
                p.plan.segments.len(),
                p.plan.segments.iter().map(|s| s.steps).sum::<i64>(),
                p.plan.max_drift_rad.to_degrees(),
                p.plan.min_eye_clearance_mm,
                p.plan.max_entry_angle_rad.to_degrees(),
                p.smoothing_deviation_mm
                    .map(|d| format!(", smoothed path ≤ {d:.4} mm from the traced one"))
                    .unwrap_or_default(),
                if paced > 0 {
                    format!(", {paced} segments at the robot's time (mandrel slowed)")
                } else {
                    String::new()
                }
            );
        }
        out += &check_line;
        out.push('\n');
        out += &format!(
            "wrote {} file{} ({}) to {}\n",
            files.len(),
            if files.len() == 1 { "" } else { "s" },
            file_kinds(&files),
            args.out.display()
        );
    }
    super::print(&out)
}

/// What the written files are, by extension, in the order first written: the IRB 6/2's control
/// files (`.ROB` robot, `.IND` mandrel, `.SEQ` sequence, `.RUN` run) or a six-axis arm's plan
/// (`.plan.json`, for `windcell post`) and mandrel indexer program.
pub(crate) fn file_kinds(files: &[(std::path::PathBuf, String)]) -> String {
    let mut kinds: Vec<&str> = Vec::new();
    for (path, _) in files {
        let name = path.to_string_lossy().to_ascii_lowercase();
        let kind = if name.ends_with(".plan.json") {
            ".plan.json six-axis plan"
        } else if name.ends_with(".rob") {
            ".ROB robot"
        } else if name.ends_with(".ind") {
            ".IND mandrel"
        } else if name.ends_with(".seq") {
            ".SEQ sequence"
        } else if name.ends_with(".run") {
            ".RUN run"
        } else {
            "other"
        };
        if !kinds.contains(&kind) {
            kinds.push(kind);
        }
    }
    kinds.join(", ")
}

#[cfg(test)]
mod tests {
    use super::file_kinds;
    use std::path::PathBuf;

    #[test]
    fn the_summary_names_the_kinds_of_file_written() {
        let f = |names: &[&str]| -> Vec<(PathBuf, String)> {
            names
                .iter()
                .map(|n| (PathBuf::from(n), String::new()))
                .collect()
        };
        assert_eq!(
            file_kinds(&f(&[
                "SB_1.ROB", "SB_1.IND", "SB_2.ROB", "SB_2.IND", "SB.SEQ", "SB.RUN"
            ])),
            ".ROB robot, .IND mandrel, .SEQ sequence, .RUN run"
        );
        assert_eq!(
            file_kinds(&f(&["IRB2600.plan.json"])),
            ".plan.json six-axis plan"
        );
        assert_eq!(
            file_kinds(&f(&["UR.plan.json", "UR_1.IND", "UR_2.IND"])),
            ".plan.json six-axis plan, .IND mandrel"
        );
    }
}
