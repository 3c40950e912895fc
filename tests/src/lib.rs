//! End-to-end tests of the whole cell live in `tests/tests/`.
