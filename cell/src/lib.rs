//! The windcell coordinator library.
