//! Integration tests of `cell`, one binary for the crate (each test file is a module: one link of
//! the dependency graph instead of one per file): the `windcell` command line, the coordinator on
//! the simulated cell, the simulators on pseudo-terminals.

mod bad_input;
mod check_cli;
mod check_fixtures;
mod cli;
mod common;
mod coordinator;
mod example_mutations;
mod fiberpath_tools;
mod lathe_cli;
mod lathe_machine;
mod lathe_output;
mod lathe_run_cli;
mod lathe_stream_marlin;
mod lathe_stream_pty;
mod lathe_svg;
mod layering;
mod link_contract;
mod live_view;
mod mesh_cli;
mod plan_guards;
mod predict_setup;
mod record_cli;
mod robot_programs;
mod run_cli;
mod run_grbl_pty;
mod run_pty;
mod run_resume_safety;
mod sim_indexer;
mod sim_robot;
mod simcell_events;
mod six_axis;
