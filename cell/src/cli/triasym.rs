//! `windcell triasym JOB.toml -o MANDREL.stl`: mesh a job's tube mandrel the TRIASYM way (seed 001
//! §3.1: sections normal to the spine, facets per circumference, flat end caps) and write an STL.

use std::path::PathBuf;

use cell::plan::{output, tool};
use clap::Args;
use paths::mesh::{Closure, stl, triasym};
use sequences::Job;

use super::Failure;

/// Generate the triangulated mandrel of a job's spine and diameter (STL).
#[derive(Debug, Args)]
#[command(allow_negative_numbers = true)]
pub struct TriasymArgs {
    /// The job file (a `tube` or `mesh` mandrel: its spine and diameter are used).
    pub job: PathBuf,
    /// The file to write: `.stl` (binary, or ASCII with --ascii) or `.obj`.
    #[arg(short = 'o', long = "out", value_name = "FILE")]
    pub out: PathBuf,
    /// Facets per circumference.
    #[arg(long, default_value_t = 128, allow_negative_numbers = true)]
    pub facets: usize,
    /// Section spacing along the spine, mm (at most; the sections are equally spaced).
    #[arg(long, default_value_t = 2.5, allow_negative_numbers = true)]
    pub spacing_mm: f64,
    /// Write ASCII STL instead of binary (an output ending in `.obj` is written as OBJ).
    #[arg(long)]
    pub ascii: bool,
}

/// Runs `windcell triasym`.
pub fn run(args: TriasymArgs) -> Result<(), Failure> {
    let ext = args
        .out
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    if ext != "stl" && ext != "obj" {
        let given = if ext.is_empty() {
            "a name without an extension".to_string()
        } else {
            format!("`.{ext}`")
        };
        return Err(Failure::input(format!(
            "{}: triasym writes .stl or .obj files, not {given}",
            args.out.display()
        )));
    }
    if ext == "obj" && args.ascii {
        return Err(Failure::input(format!(
            "{}: --ascii applies to STL; OBJ is always text",
            args.out.display()
        )));
    }
    output::check_file(&args.out).map_err(Failure::from_cell)?;
    let (job, text) = Job::load(&args.job).map_err(Failure::input)?;
    output::not_an_input(&args.out, &output::inputs_of_job(&job, &args.job))
        .map_err(Failure::from_cell)?;
    let tube = tool::mandrel_in(&job, &text, &args.job).map_err(Failure::from_cell)?;
    let mesh = triasym::tube(&tube, args.facets, args.spacing_mm, true).map_err(|e| {
        Failure::input(format!(
            "triasym --facets {} --spacing-mm {}: {e}",
            args.facets,
            paths::limits::shown(args.spacing_mm)
        ))
    })?;
    mesh.validate(Closure::Closed).map_err(Failure::runtime)?;
    let name = job.name.get_ref();
    let bytes = if ext == "obj" {
        paths::mesh::obj::write(&mesh).into_bytes()
    } else if args.ascii {
        stl::write_ascii(&mesh, name).into_bytes()
    } else {
        stl::write_binary(
            &mesh,
            &format!(
                "windcell TRIASYM {name}: {} facets, sections every {} mm",
                args.facets, args.spacing_mm
            ),
        )
    };
    output::write_file(&args.out, &bytes).map_err(Failure::from_cell)?;
    super::print(&format!(
        "wrote {} ({} triangles)\n",
        args.out.display(),
        mesh.triangles().len()
    ))
}
