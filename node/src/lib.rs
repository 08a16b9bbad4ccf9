//! The twin node and the test-stand node, independent of any middleware.
//!
//! * [`conditioning`]: what the real world does to a sensor stream (NaN, duplicates,
//!   out-of-order stamps, gaps) and what the node does about it.
//! * [`pipeline`]: one sample in → model step, residual, yield-stress estimate, health.
//!   Timestamps drive the model, never the wall clock; the same code serves live streams
//!   and replays, so a replay gives the same numbers as the live run.
//! * [`diagnostics`]: health checks as `diagnostic_msgs/DiagnosticArray`.
//! * [`config`]: the nodes' `ros__parameters`.
//! * [`runner`]: the twin node's loop over the transports (publishing, 1 Hz diagnostics,
//!   staleness, the iceoryx2 control service).
//! * [`stand`]: the simulated test stand as a live, real-time paced sensor stream, with
//!   optional faults.

pub mod conditioning;
pub mod config;
pub mod diagnostics;
pub mod pipeline;
pub mod runner;
pub mod stand;
pub mod transports;
