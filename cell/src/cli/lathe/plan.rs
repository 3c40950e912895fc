//! `windcell lathe plan VESSEL.toml|JOB.wind -o DIR --dialect D [--json]`: a lathe winding job to
//! G-code (seed 002's patterns and eye paths), with a summary.

use std::path::{Path, PathBuf};

use clap::Args;
use sequences::gcode::{Dialect, Frame, Header};
use sequences::machine::{Extent, Refusal};
use sequences::vessel::VesselFile;

use super::Failure;
use super::{machine, out_file};

/// How the summary's tow and time differ from FiberPath's for the same `.wind` file, and why
/// (docs/fiberpath.md: the passes and their tow are FiberPath's; the end turns and the time
/// model are not).
pub const FIBERPATH_DIFFERENCE: &str = "against FiberPath: the same passes; the tow differs at \
    the ends (the mandrel turns forward only, by the least turn that keeps the pattern, each end \
    turn counted at its own radius; FiberPath spins back and counts every arc at the base \
    diameter) and the time is at the axes' velocity and acceleration limits (FiberPath's: \
    surface distance over the feed)";

/// A machine's refusal as one line: at the profile's field when it came from a file, else at the
/// job, with what to change when the machine was the dialect's default (a `.wind` job has no axes
/// field: its machine turns the delivery eye; a vessel file has `axes`).
fn refusal(args: &LathePlanArgs, r: &Refusal) -> String {
    if let Some(place) = &r.place {
        return format!("{place}: {}", r.message);
    }
    let hint = match (
        &args.machine,
        args.job.extension().is_some_and(|e| e == "wind"),
    ) {
        (Some(_), _) => String::new(),
        (None, true) => format!(
            " (a .wind job turns the delivery eye, which the {} dialect's default machine lacks: \
             choose grbl, linuxcnc, marlin, mach3 or fanuc; `windcell lathe plan --help`)",
            args.dialect
        ),
        (None, false) => " (or set `axes` in the vessel file's [machine] table; \
                          docs/file-formats.md)"
            .to_string(),
    };
    format!("{}: {}{hint}", args.job.display(), r.message)
}

/// Plan a lathe winding job (vessel TOML or FiberPath/Cyclone `.wind`) and write its G-code.
#[derive(Debug, Args)]
pub struct LathePlanArgs {
    /// The job: a vessel file (TOML) or a `.wind` file.
    pub job: PathBuf,
    /// Folder to write `NAME.EXT` into (created if missing; nothing is written on bad input).
    /// Always a folder: `-o part.gcode` is refused.
    #[arg(short = 'o', long = "out", value_name = "FOLDER")]
    pub out: PathBuf,
    /// The controller's G-code: fw-cnc, mach3, grbl, linuxcnc, marlin or fanuc
    /// (docs/lathe.md, "Dialects").
    #[arg(long, value_parser = parse_dialect)]
    pub dialect: Dialect,
    /// The machine the program is written for: a built-in (fiberpath-xab, fw-cnc, grbl-4axis,
    /// linuxcnc-4axis, marlin-4axis, mach3-4axis, fanuc-4axis) or a profile file (FILE.toml;
    /// docs/lathe.md, "Machine coordinates"). Default: fiberpath-xab for a .wind job in Marlin,
    /// fw-cnc for fw-cnc, else the dialect's 4-axis winder.
    #[arg(long, value_name = "NAME|FILE.toml")]
    pub machine: Option<String>,
    /// Also draw the layup as SVG: the unwrapped mandrel with every pass of every layer, the
    /// turnarounds, a legend of the layers and the thickness along the mandrel.
    #[arg(long, value_name = "FILE.svg")]
    pub svg: Option<PathBuf>,
    /// Also write the layup in 3-D for Foxglove (MCAP, `/lathe/layup`): the mandrel, then each
    /// layer's tow path at the time the layer starts.
    #[arg(long, value_name = "FILE.mcap")]
    pub record: Option<PathBuf>,
    /// Replace an earlier output of the same name (refused otherwise).
    #[arg(long)]
    pub force: bool,
    /// Print the summary as one JSON document.
    #[arg(long)]
    pub json: bool,
}

/// `--dialect`: one of the six, the message naming them and the help that describes them.
pub fn parse_dialect(name: &str) -> Result<Dialect, String> {
    Dialect::from_name(name).ok_or_else(|| {
        let names: Vec<&str> = Dialect::ALL.iter().map(|d| d.name()).collect();
        format!("unknown dialect `{name}`: one of {}", names.join(", "))
    })
}

/// Loads a job file of either kind, checked; errors are located in the file.
pub fn load(path: &Path) -> Result<(String, paths::vessel::Job, paths::vessel::Plan), Failure> {
    if path.extension().is_some_and(|e| e == "wind") {
        let (job, name) = sequences::wind::WindFile::load(path).map_err(Failure::input)?;
        let plan = job
            .check()
            .map_err(|e| Failure::input(format!("{}: {e}", path.display())))?;
        return Ok((name, job, plan));
    }
    let (loaded, text) = VesselFile::load(path).map_err(Failure::input)?;
    let plan = loaded
        .check(&text)
        .map_err(|e| Failure::input(e.in_file(path)))?;
    Ok((loaded.name, loaded.job, plan))
}

/// Runs `windcell lathe plan`.
pub fn run(args: LathePlanArgs) -> Result<(), Failure> {
    out_file::check_out_dir(&args.out)?;
    let (name, job, plan) = load(&args.job)?;
    let is_wind = args.job.extension().is_some_and(|e| e == "wind");
    let profile = machine::resolve(args.machine.as_deref(), args.dialect, &args.job)?;
    let offset = profile.carriage_offset_mm(machine::mandrel_start_mm(&job));
    let frame = Frame::of_machine(&profile, offset);
    // The machine must have every axis the plan moves, within its travel: refuse before
    // creating anything.
    let axes = job.machine.axes;
    let used = [true, true, axes.cross_feed(), axes.eye_rotation()];
    let mut extent = Extent::new(frame);
    let Ok(()) = plan.emit(&mut extent);
    profile
        .admits(&extent, used)
        .map_err(|r| Failure::input(refusal(&args, &r)))?;
    let target = args
        .out
        .join(format!("{name}.{}", args.dialect.extension()));
    out_file::check_target(&target, args.force)?;
    let mut inputs = vec![args.job.clone()];
    if let Some(m) = args
        .machine
        .as_deref()
        .filter(|m| m.ends_with(".toml") || m.contains('/'))
    {
        inputs.push(PathBuf::from(m));
    }
    let outputs: Vec<&Path> = std::iter::once(target.as_path())
        .chain(
            [&args.svg, &args.record]
                .into_iter()
                .flatten()
                .map(PathBuf::as_path),
        )
        .collect();
    cell::plan::output::check_outputs(&outputs, &inputs).map_err(Failure::from_cell)?;
    for extra in [&args.svg, &args.record].into_iter().flatten() {
        cell::plan::output::check_file(extra).map_err(Failure::from_cell)?;
        if extra.exists() && !args.force {
            return Err(Failure::input(format!(
                "{}: exists; --force replaces it",
                extra.display()
            )));
        }
    }
    let mut staged = out_file::Staged::new(&args.out, target.clone())?;
    let out = std::io::BufWriter::with_capacity(1 << 16, staged.file());
    let header = Header {
        title: name.clone(),
        parameters: Some(machine::parameters(&job)),
    };
    let (summary, out) =
        cell::lathe::gcode::write_in_frame(&plan, axes, args.dialect, frame, &header, out)
            .map_err(Failure::runtime)?;
    out.into_inner()
        .map_err(|e| Failure::runtime(format!("{}: {}", target.display(), e.error())))?;
    staged.persist()?;
    let layup = match &args.svg {
        Some(svg) => {
            let (text, layup) =
                cell::lathe::layup_svg::draw(&job, &plan, machine::mandrel_start_mm(&job), &name);
            cell::plan::output::write_file(svg, text.as_bytes()).map_err(Failure::from_cell)?;
            Some((svg, layup))
        }
        None => None,
    };
    if let Some(record) = &args.record {
        let bytes = cell::lathe::layup_scene::mcap(&job, &plan, machine::mandrel_start_mm(&job))
            .map_err(Failure::from_cell)?;
        cell::plan::output::write_file(record, &bytes).map_err(Failure::from_cell)?;
    }
    let text = if args.json {
        let mut value = serde_json::to_value(&summary).map_err(Failure::runtime)?;
        value["file"] = target.display().to_string().into();
        if is_wind {
            value["fiberpath_difference"] = FIBERPATH_DIFFERENCE.into();
        }
        if let Some((svg, l)) = &layup {
            let mid = l.thickness[l.thickness.len() / 2];
            value["svg"] = serde_json::json!({
                "file": svg.display().to_string(),
                "passes": l.passes_drawn,
                "turnarounds": l.turns_drawn,
                "thickness_mm": l.thickness,
                "thickness_middle_mm": mid.1,
            });
        }
        value["machine"] = serde_json::json!({
            "name": profile.name,
            "carriage_offset_mm": offset,
        });
        let mut t = serde_json::to_string_pretty(&value).map_err(Failure::runtime)?;
        t.push('\n');
        t
    } else {
        let mut t = String::new();
        for l in &summary.layer {
            t += &format!(
                "layer {} {:?}: {} circuits at {:.3}° on radius {:.3} mm, tow {:.1} m{}\n",
                l.mark.number,
                l.mark.kind,
                l.mark.circuits,
                l.mark.wind_angle_deg,
                l.mark.winding_radius_mm,
                l.mark.tow_length_mm / 1000.0,
                l.pattern
                    .map(|p| format!(
                        ", pitch {}° ({} cycles × {} patterns), dwell {:.4}°, advance {:.4}°",
                        p.pitch.deg(),
                        p.cycles_per_pattern(),
                        p.patterns_per_layer,
                        p.dwell_deg,
                        p.advance_deg
                    ))
                    .unwrap_or_default()
            );
        }
        t += &format!(
            "{} layers, {} circuits, {} lines, tow {:.1} m, time {} ({:.1} s; {:.1} s at the \
             velocity limits alone)\nwrote {} for machine {}\n",
            summary.layers,
            summary.circuits,
            summary.lines,
            summary.tow_length_mm / 1000.0,
            cell::lathe::gcode::clock(summary.time_s),
            summary.time_s,
            summary.nominal_time_s,
            target.display(),
            profile.name
        );
        if let Some((svg, _)) = &layup {
            t += &format!("drew {}\n", svg.display());
        }
        if is_wind {
            t += FIBERPATH_DIFFERENCE;
            t.push('\n');
        }
        t
    };
    crate::cli::print(&text)
}
