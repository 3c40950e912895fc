//! Integration tests of `sequences`, one binary for the crate (each test file is a module: one link
//! of the dependency graph instead of one per file): DXF and the round trip of every operator file.

mod dxf;
mod round_trip;
