//! The operator's files for windcell.
