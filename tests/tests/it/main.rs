//! Integration tests of `tests`, one binary for the crate (each test file is a module: one link of
//! the dependency graph instead of one per file): the whole cell: timing, the TOOL step, the
//! transfer to the simulators, the App. B validation.

mod timing;
mod tool;
mod transfer;
mod validation;
