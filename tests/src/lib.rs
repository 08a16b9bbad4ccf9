//! End-to-end test support for mrtwin (see `tests/`).
//!
//! The tests of the `mrtwin` binary itself live in `cli/tests/`: only a binary's own
//! package gets it built before its integration tests and its path as
//! `CARGO_BIN_EXE_mrtwin`, so tests here could not find it reliably.
