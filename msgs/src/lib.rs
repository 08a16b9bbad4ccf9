//! mrtwin message types.
//!
//! * [`ros`]: `builtin_interfaces/Time` and `std_msgs/Header`, the building blocks.
//! * [`damper`]: the `mrtwin_msgs` interface package (`msg/*.msg` beside this crate):
//!   [`DamperSample`], [`TwinOutput`], [`YieldEstimate`].
//! * [`standard`]: the standard ROS 2 types the twin also publishes so stock tools need
//!   nothing of ours: `std_msgs/Float64`, `diagnostic_msgs/DiagnosticArray`,
//!   `rosgraph_msgs/Clock`.
//! * [`cdr`]: CDR encoding with the 4-byte encapsulation header, as DDS and rosbag2 carry it.
//! * [`shm`]: `#[repr(C)]` plain-data payloads for iceoryx2 shared memory.
//!
//! Every ROS type implements [`RosMessage`]: its ROS type name and its full `ros2msg`
//! definition (dependencies included, as MCAP schemas carry it). The Rust structs list the
//! fields in the order of the .msg files, which is what makes serde's output CDR-compatible
//! field for field.

pub mod cdr;
pub mod damper;
pub mod ros;
pub mod shm;
pub mod standard;

pub use damper::{DamperSample, TwinOutput, YieldEstimate};
pub use ros::{Header, Time};
pub use standard::{
    Clock, DiagnosticArray, DiagnosticStatus, Float64, Float64MultiArray, KeyValue,
    MultiArrayDimension, MultiArrayLayout, SAMPLE_ARRAY_LABEL,
};

/// A ROS 2 message type.
pub trait RosMessage: serde::Serialize + serde::de::DeserializeOwned {
    /// ROS type name, `package/msg/Type`.
    const TYPE_NAME: &'static str;
    /// Full `ros2msg` definition: this type's .msg text, then every type it uses,
    /// each after a `====…` line and `MSG: package/Type` (the MCAP `ros2msg` encoding).
    fn definition() -> String;
}

/// Separator between message definitions in a `ros2msg` schema.
pub(crate) const DEFINITION_SEPARATOR: &str =
    "================================================================================";

/// Join a type's own .msg text with its dependencies' (`(name "pkg/Type", text)`).
pub(crate) fn join_definitions(own: &str, deps: &[(&str, &str)]) -> String {
    let mut out = own.trim_end().to_string();
    for (name, text) in deps {
        out.push('\n');
        out.push_str(DEFINITION_SEPARATOR);
        out.push_str("\nMSG: ");
        out.push_str(name);
        out.push('\n');
        out.push_str(text.trim_end());
    }
    out.push('\n');
    out
}
