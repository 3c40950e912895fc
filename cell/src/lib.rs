//! The windcell coordinator library: the TOOL step that turns a job into control files, and the
//! pieces the `windcell` command line is built from.

pub mod batch;
pub mod cellfile;
pub mod check;
pub mod coordinator;
pub mod device;
pub mod error;
pub mod figure;
pub mod gcode;
pub mod imported;
pub mod journal;
pub mod lathe;
pub mod layup_scene;
pub mod layup_svg;
pub mod linktap;
pub mod mesh;
pub mod output;
pub mod predict;
pub mod record;
pub mod report;
pub mod scene;
pub mod simcell;
pub mod stream_watch;
pub mod tool;
pub mod trace_plot;
pub mod transfer;
pub mod wiretap;

pub use error::Error;
