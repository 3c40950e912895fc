//! Integration tests of `paths`, one binary for the crate (each test file is a module: one link of
//! the dependency graph instead of one per file): mesh accuracy and robustness, placement.

mod arm_kinematics;
mod mesh_accuracy;
mod mesh_robustness;
mod placement;
