//! mrtwin I/O.
//!
//! - [`recording`]: recordings in the project's CSV format (PHYSICS.md,
//!   "Recording format (CSV)"), read and written loss-free.
//! - [`utfsm`]: readers for the real MR damper recordings from the UTFSM test
//!   press (`shared/data/real/maurel-utfsm`).
//! - [`bag`]: rosbag2 directories with MCAP storage (and bare `.mcap` files).
//! - [`transport`]: the adapter interface of the middleware; the adapters are behind
//!   features: [`ros2`] (DDS via ros2-client), [`zenoh`], [`iceoryx2`] (shared memory).

pub mod bag;
pub mod recording;
pub mod transport;
pub mod utfsm;

#[cfg(feature = "iceoryx2")]
pub mod iceoryx2;
#[cfg(feature = "ros2")]
pub mod ros2;
#[cfg(feature = "zenoh")]
pub mod zenoh;

pub use recording::{
    derive_velocity, parse_csv, read_csv, to_csv_string, write_csv, Recording, RecordingError,
    Sample,
};
