//! Integration tests of `mandrel-drive`, one binary for the crate (each test file is a module: one
//! link of the dependency graph instead of one per file): the indexer end to end, GRBL streaming,
//! the wired sync lines (feature `hardware`).

mod end_to_end;
mod grbl_stream_rate;
mod hardware;
mod link_contract;
