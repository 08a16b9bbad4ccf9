//! Yield-stress identification, online estimation and health checks (issue 5).
//!
//! Pure computation, no I/O:
//! * [`identify`]: the offline pipeline of Skalski & Zalewski (2014): shear rate and yield
//!   point from the first loading, n and R0 of the Bodner–Partom law by Levenberg–Marquardt
//!   on (5.3), and their dependence on current and temperature in the form of (5.5).
//! * [`online`]: recursive least-squares estimate of τ0(I) with its uncertainty while
//!   samples stream in.
//! * [`health`]: the health checks of the twin (prediction residual, innovation
//!   consistency, yield stress against the commissioned reference, gas preload, dissipated
//!   power and temperature rise, sample rate, rejected data).

pub mod health;
pub mod identify;
pub mod online;

pub use health::{Check, CheckId, HealthConfig, HealthMonitor, Level, Observation};
pub use online::{
    force_per_pa, regressor, EstimatorConfig, EstimatorSample, LawAt, PreYieldGate, RejectReason,
    Tau0Estimate, UpdateOutcome, YieldEstimator,
};
