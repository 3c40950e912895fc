//! Planning, offline: from a job file to checked control files (seed 001 §5.6, §5.7).
//!
//! - [`tool`]: the TOOL step (paths, eye poses, mandrel steps) and each control file;
//! - [`files`]: the set of files a plan writes (IRB 6/2 control files, a six-axis plan);
//! - [`mesh`], [`imported`]: mandrels from mesh files and paths from DXF drawings, with file names
//!   in their errors;
//! - [`check`] and [`figure`]: the collision and snag check and its picture (Figure 5.9);
//! - [`program`]: a stored robot program's layout in the robot's memory;
//! - [`post`]: a six-axis plan as programs for the arm's controller (`windcell post`);
//! - [`report`]: `plan --json`; [`output`]: writing a set of files all or nothing;
//! - [`sweep`]: a coverage set, one job's path repeated around the mandrel.
//!
//! Nothing here talks to a device: `run` takes the plan from here.

pub mod check;
pub mod figure;
pub mod files;
pub mod imported;
pub mod mesh;
pub mod output;
pub mod post;
pub mod program;
pub mod report;
pub mod sweep;
pub mod tool;
