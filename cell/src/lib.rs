//! The windcell coordinator library: the TOOL step that turns a job into control files, and the
//! pieces the `windcell` command line is built from.

pub mod error;
pub mod lathe;
pub mod mesh;
pub mod output;
pub mod report;
pub mod tool;
pub mod transfer;

pub use error::Error;
