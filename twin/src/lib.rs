//! # twin — the physics of the mrtwin MR damper twin
//!
//! Pure computation: no I/O, no middleware. Every model is driven sample by sample through
//! [`DamperModel::step`], so the same code serves live streams, replays and offline fits.
//!
//! * [`fluid`]: Bingham, Herschel–Bulkley and the simplified Bodner–Partom law of
//!   Skalski & Zalewski (2014), eqs. (5.2)–(5.5).
//! * [`gap`]: flow through the annular gap (slit) for each law, with flow blocking.
//! * [`models`]: the Bingham baseline, Spencer's modified Bouc–Wen, the direct-shear gap
//!   of the first paper and the two-chamber model of Graczykowski & Pawłowski.
//! * [`effects`]: the effect ids of PHYSICS.md.
//! * [`integrate`]: TR-BDF2, the stiff integrator.
//! * [`stand`]: the test-stand programme (sinusoids at fixed currents) and noise.
//! * [`metrics`]: loop work and the z-loop opening.
//!
//! Units are SI inside (m, s, N, Pa, A), temperatures in °C; x is positive in extension
//! and F positive when the damper resists extension.

pub mod effects;
pub mod fluid;
pub mod gap;
pub mod integrate;
pub mod metrics;
pub mod model;
pub mod models;
pub mod stand;

pub use effects::{Effect, EffectSet, EffectsChoice};
pub use model::{DamperInput, DamperModel, DamperOutput};
pub use models::{ModelKind, ModelParams};
