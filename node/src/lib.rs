//! The twin node (issue 3).
