//! `windcell lathe plan --machine NAME|FILE.toml`: the machine profile a program is written for
//! (`sequences::machine`), its default for each dialect, and where the mandrel starts in the
//! planner's frame (the written carriage zero of a `mandrel-start` machine).

use std::path::Path;

use paths::vessel::{Job, Mandrel};
use sequences::gcode::{Dialect, Parameters};
use sequences::machine::{BUILTINS, MachineProfile};

use super::super::Failure;

/// The default machine: FiberPath's XAB machine for a `.wind` job in Marlin, seed 000's FW-CNC
/// for its own dialect, else the dialect's usual 4-axis winder.
pub fn default_name(dialect: Dialect, job: &Path) -> String {
    match dialect {
        Dialect::Marlin if job.extension().is_some_and(|e| e == "wind") => {
            "fiberpath-xab".to_string()
        }
        Dialect::FwCnc => "fw-cnc".to_string(),
        d => format!("{}-4axis", d.name()),
    }
}

/// `--machine`: a built-in's name or a profile file (a path ending in `.toml`).
pub fn resolve(arg: Option<&str>, dialect: Dialect, job: &Path) -> Result<MachineProfile, Failure> {
    let name = arg.map_or_else(|| default_name(dialect, job), str::to_string);
    if name.ends_with(".toml") || name.contains('/') {
        return MachineProfile::load(Path::new(&name)).map_err(Failure::input);
    }
    MachineProfile::builtin(&name).ok_or_else(|| {
        Failure::input(format!(
            "--machine `{name}`: neither a built-in ({}) nor a profile file (FILE.toml); see \
             `windcell lathe plan --help`",
            BUILTINS.join(", ")
        ))
    })
}

/// Where the mandrel's start (the end where winding starts) is in the planner's frame, mm from
/// the middle: half the wound length of a tube, cone or nose; on a seed 002 vessel the first
/// polar opening's plane, `Lc/2 + √(Rc² − rp²)` from the middle (hemispherical domes).
pub fn mandrel_start_mm(job: &Job) -> f64 {
    match job.mandrel {
        Mandrel::Vessel {
            cylinder_radius_mm,
            cylinder_length_mm,
            polar_radius_mm,
        } => {
            -(cylinder_length_mm / 2.0
                + (cylinder_radius_mm.powi(2) - polar_radius_mm.powi(2))
                    .max(0.0)
                    .sqrt())
        }
        Mandrel::Tube { length_mm, .. }
        | Mandrel::Cone { length_mm, .. }
        | Mandrel::VonKarman { length_mm, .. } => -length_mm / 2.0,
    }
}

/// FiberPath's header values for a job: the diameter at the carriage's start, the wound
/// length, the tow.
pub fn parameters(job: &Job) -> Parameters {
    Parameters {
        diameter_mm: 2.0 * job.mandrel.radius_mm(),
        wind_length_mm: -2.0 * mandrel_start_mm(job),
        tow_width_mm: job.tow.band_mm,
        tow_thickness_mm: job.tow.thickness_mm,
    }
}
