//! The twin node and the test-stand node, independent of any middleware.
//!
//! * [`conditioning`]: what the real world does to a sensor stream (NaN, duplicates,
//!   out-of-order stamps, gaps) and what the node does about it.
//! * [`pipeline`]: one sample in → model step, residual, yield-stress estimate, health.
//!   Timestamps drive the model, never the wall clock; the same code serves live streams
//!   and replays, so a replay gives the same numbers as the live run.
//! * [`diagnostics`]: health checks as `diagnostic_msgs/DiagnosticArray`.
//! * [`config`]: the nodes' `ros__parameters`.
//! * [`fit`]: the twin's own model calibrated to recordings through the pipeline
//!   (`mrtwin fit`), so a replay shows the residual the fit minimised.
//! * [`core`]: the twin core: one sample in, the messages to publish out (outputs, yield
//!   estimates, diagnostics on the sample stamps); no clock, no transport. Live, replay
//!   and record are thin loops around it.
//! * [`runner`]: the live twin node: the core over the transports, with the wall clock
//!   for STALE and the iceoryx2 control service.
//! * [`fleet`]: many dampers in one process: N stands in one paced loop, N twin cores in
//!   another, each damper on its own transport.
//! * [`monitor`]: the central view of many dampers behind routers: STALE when a damper's
//!   outputs stop arriving, its twin's own level otherwise.
//! * [`parameters`]: the twin's and the stand's settings as ROS 2 parameters.
//! * [`stand`]: the simulated test stand as a live, real-time paced sensor stream, with
//!   optional faults.

pub mod conditioning;
pub mod config;
pub mod core;
pub mod diagnostics;
pub mod fit;
pub mod fleet;
pub mod monitor;
pub mod parameters;
pub mod pipeline;
pub mod runner;
pub mod stand;
pub mod transports;
