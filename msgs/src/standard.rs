//! Standard ROS 2 types the twin publishes so that stock tools (`ros2 topic echo`,
//! rqt_robot_monitor, diagnostic_aggregator, Foxglove, plotters) need nothing of ours.

use serde::{Deserialize, Serialize};

use crate::ros::{Header, Time};
use crate::{join_definitions, RosMessage};

/// `std_msgs/msg/Float64`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Float64 {
    /// The value.
    pub data: f64,
}

impl RosMessage for Float64 {
    const TYPE_NAME: &'static str = "std_msgs/msg/Float64";
    fn definition() -> String {
        join_definitions("float64 data\n", &[])
    }
}

/// `rosgraph_msgs/msg/Clock`: simulated time, published on `/clock` during replay.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Clock {
    /// The time.
    pub clock: Time,
}

impl RosMessage for Clock {
    const TYPE_NAME: &'static str = "rosgraph_msgs/msg/Clock";
    fn definition() -> String {
        join_definitions(
            "builtin_interfaces/Time clock\n",
            &[("builtin_interfaces/Time", Time::MSG)],
        )
    }
}

/// `diagnostic_msgs/msg/KeyValue`.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct KeyValue {
    /// What the value is.
    pub key: String,
    /// The value, as text.
    pub value: String,
}

impl KeyValue {
    /// .msg text.
    pub const MSG: &'static str = "string key\nstring value\n";

    /// A key/value pair.
    pub fn new(key: impl Into<String>, value: impl Into<String>) -> Self {
        Self {
            key: key.into(),
            value: value.into(),
        }
    }
}

/// `diagnostic_msgs/msg/DiagnosticStatus`: one check. `level` is one of the constants.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct DiagnosticStatus {
    /// [`DiagnosticStatus::OK`] … [`DiagnosticStatus::STALE`].
    pub level: u8,
    /// `"<node>: <check>"`.
    pub name: String,
    /// Human-readable summary.
    pub message: String,
    /// Hardware the check is about (the damper name).
    pub hardware_id: String,
    /// Measured values of the check.
    pub values: Vec<KeyValue>,
}

impl DiagnosticStatus {
    /// Level OK.
    pub const OK: u8 = 0;
    /// Level WARN.
    pub const WARN: u8 = 1;
    /// Level ERROR.
    pub const ERROR: u8 = 2;
    /// Level STALE.
    pub const STALE: u8 = 3;
    /// .msg text (as in diagnostic_msgs).
    pub const MSG: &'static str = "byte OK=0\nbyte WARN=1\nbyte ERROR=2\nbyte STALE=3\n\
byte level\nstring name\nstring message\nstring hardware_id\nKeyValue[] values\n";
}

/// `diagnostic_msgs/msg/DiagnosticArray`, published on `/diagnostics`.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct DiagnosticArray {
    /// Stamp of the report.
    pub header: Header,
    /// One entry per check.
    pub status: Vec<DiagnosticStatus>,
}

impl RosMessage for DiagnosticArray {
    const TYPE_NAME: &'static str = "diagnostic_msgs/msg/DiagnosticArray";
    fn definition() -> String {
        join_definitions(
            "std_msgs/Header header\nDiagnosticStatus[] status\n",
            &[
                ("std_msgs/Header", Header::MSG),
                ("builtin_interfaces/Time", Time::MSG),
                ("diagnostic_msgs/DiagnosticStatus", DiagnosticStatus::MSG),
                ("diagnostic_msgs/KeyValue", KeyValue::MSG),
            ],
        )
    }
}
