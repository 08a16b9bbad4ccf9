//! mrtwin I/O.
//!
//! - [`csv`]: recordings in the project's CSV format (PHYSICS.md,
//!   "Recording format (CSV)"), read and written loss-free.
//! - [`utfsm`]: readers for the real MR damper recordings from the UTFSM test
//!   press (`shared/data/real/maurel-utfsm`).
//! - [`bag`]: rosbag2 directories with MCAP storage (and bare `.mcap` files).
//! - [`qos`]: the QoS reliability shared by the ROS 2 adapter and the bags.
//! - [`transport`]: the adapter interface of the middleware; the adapters are behind
//!   features: [`ros2`] (DDS via ros2-client), [`zenoh`], [`iceoryx2`] (shared memory).
//!   Their settings (`Ros2Config`, `ZenohConfig`, `Iceoryx2Config`) are compiled in every
//!   build, so one parameter file reads the same whatever the build holds.
//! - [`params`]: the parameters a node serves through a middleware's own tools
//!   ([`params::ParamService`]; the ROS 2 adapter serves them as ROS 2 parameters).
//! - `foxglove` (feature `foxglove`): a Foxglove WebSocket server, the live view of a
//!   twin, behind the same [`transport::Transport`] interface (publish only).
//! - [`wake`]: the [`wake::Doorbell`] an adapter rings when a message arrives, so the loop
//!   that reads it sleeps until then.

pub mod bag;
pub mod csv;
#[cfg(feature = "foxglove")]
pub mod foxglove;
pub mod iceoryx2;
pub mod params;
pub mod qos;
pub mod ros2;
pub mod transport;
pub mod utfsm;
pub mod wake;
pub mod zenoh;

pub use csv::{
    derive_velocity, parse_csv, read_csv, to_csv_string, write_csv, Recording, RecordingError,
    Sample,
};

/// Why [`open_recording`] failed: the bag's or the CSV's own error.
#[derive(Debug, thiserror::Error)]
pub enum OpenRecordingError {
    /// Reading the bag failed.
    #[error(transparent)]
    Bag(#[from] bag::BagError),
    /// Reading the CSV failed.
    #[error(transparent)]
    Csv(#[from] RecordingError),
}

/// `true` when `path` is read as a bag: a directory, a `.mcap` file, or a file that
/// starts with the MCAP magic.
pub fn is_bag_path(path: &std::path::Path) -> bool {
    use std::io::Read;
    if path.is_dir()
        || path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("mcap"))
    {
        return true;
    }
    let mut head = [0u8; 8];
    std::fs::File::open(path)
        .and_then(|mut f| f.read_exact(&mut head))
        .is_ok_and(|_| head == *mcap::MAGIC)
}

/// Open a recording from a bag (directory or `.mcap`: its `sensor/sample` topic, see
/// [`bag::read_recording`]) or a CSV file ([`read_csv`]).
pub fn open_recording(path: &std::path::Path) -> Result<Recording, OpenRecordingError> {
    if is_bag_path(path) {
        Ok(bag::read_recording(path)?)
    } else {
        Ok(read_csv(path)?)
    }
}
