//! The operator's files for windcell: the job file (TOML) and the control files of seed 001 §5.6:
//! robot control files (.ROB), mandrel control files (.IND), sequence and run files; the lathe
//! winder's part programs and FW-CNC.PAR (seed 000 Fig 9-1, App. A); and the
//! AutoCAD DXF drawings that paths and spine profiles arrive in (§5.5).
//!
//! Parsing takes `&str` and reports line and column; loading adds the path; writing then parsing
//! gives the same value. The formats are documented in `docs/file-formats.md`.

pub mod dxf;
pub mod error;
pub mod gcode;
pub mod ind;
pub mod job;
pub mod machine;
pub mod part_program;
pub mod program;
pub mod rob;
pub mod run;
pub mod sequence;
pub mod source;
pub mod syntax;
pub mod vessel;
pub mod wind;

pub use dxf::Drawing;
pub use error::Error;
pub use ind::{MandrelFile, MandrelMove};
pub use job::Job;
pub use part_program::{MachineParameters, PartProgram};
pub use program::{ProgramPath, ProgramTarget, ReadProgram};
pub use rob::{Movement, RobotFile};
pub use run::RunFile;
pub use sequence::SequenceFile;
