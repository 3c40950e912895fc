//! The windcell coordinator library: the TOOL step that turns a job into control files, and the
//! pieces the `windcell` command line is built from.

pub mod batch;
pub mod cellfile;
pub mod check;
pub mod coordinator;
pub mod device;
pub mod error;
pub mod figure;
pub mod journal;
pub mod mesh;
pub mod output;
pub mod report;
pub mod scene;
pub mod simcell;
pub mod tool;
pub mod transfer;

pub use error::Error;
