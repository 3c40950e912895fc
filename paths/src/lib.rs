//! Mandrel geometry and motion maths for windcell. No I/O.
