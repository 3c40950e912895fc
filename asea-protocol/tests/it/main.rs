//! Integration tests of `asea-protocol`, one binary for the crate (each test file is a module: one
//! link of the dependency graph instead of one per file): the telegram link end to end, its fault
//! classes, retry rules and stop phases.

mod end_to_end;
mod fault_classes;
mod link_contract;
mod retry_rules;
mod stop_phases;
