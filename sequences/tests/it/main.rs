//! Integration tests of `sequences`, one binary for the crate (each test file is a module: one link
//! of the dependency graph instead of one per file): DXF, the round trip of every operator file and
//! the robot programs.

mod dxf;
mod reader_mutations;
mod robot_programs;
mod round_trip;
