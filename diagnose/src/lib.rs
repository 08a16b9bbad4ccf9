//! Diagnose: find the physics a damper model left out (issue 6).
//!
//! Given a recording, fit the incompressible Bingham flow-mode damper with free yield force
//! and viscous coefficient per current knot ([`model`]), locate where its residual
//! concentrates (stroke phase, direction, speed, current, segment, time, after current
//! steps), refit with each candidate effect of PHYSICS.md and accept one only when the
//! held-out error falls clearly, an information criterion with the effective sample size
//! supports it, its parameter's 95 % interval excludes the no-effect value, and the
//! residual structure in a flagged region falls ([`select`]); repeat (forward selection).
//! Pure computation: no I/O. docs/diagnose.md describes every rule and threshold.

pub mod antialias;
pub mod bingham;
pub mod calibrate;
pub mod current;
pub mod data;
pub mod limits;
pub mod measure;
pub mod model;
pub mod report;
pub mod select;
pub mod sindy;
pub mod stats;
pub mod study;
pub mod subsample;
pub mod unexplained;

pub use calibrate::Calibration;
pub use data::{DataError, Signals, YieldCurve};
pub use report::Report;
pub use select::{
    diagnose, diagnose_with_progress, AcceptanceThresholds, Diagnosis, Options, Progress, Selector,
};
