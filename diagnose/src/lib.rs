//! Diagnose: find the physics a damper model left out (issue 6).
