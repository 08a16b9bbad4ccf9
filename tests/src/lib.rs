//! End-to-end test support for mrtwin (see `tests/`).
