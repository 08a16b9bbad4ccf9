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

/// `std_msgs/msg/MultiArrayDimension`.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct MultiArrayDimension {
    /// Label of the dimension.
    pub label: String,
    /// Size of the dimension.
    pub size: u32,
    /// Stride of the dimension.
    pub stride: u32,
}

/// `std_msgs/msg/MultiArrayLayout`.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct MultiArrayLayout {
    /// Dimensions.
    pub dim: Vec<MultiArrayDimension>,
    /// Padding elements at the front of data.
    pub data_offset: u32,
}

/// `std_msgs/msg/Float64MultiArray`: the standard-type form of a damper sample, for
/// publishers without our message package (plain rclpy, `ros2 topic pub`). One dimension
/// whose label lists the channels: [`SAMPLE_ARRAY_LABEL`].
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Float64MultiArray {
    /// Layout.
    pub layout: MultiArrayLayout,
    /// Values.
    pub data: Vec<f64>,
}

/// The label of the single dimension of a damper sample as `Float64MultiArray`: the
/// channels in order, SI units.
pub const SAMPLE_ARRAY_LABEL: &str =
    "time_s,displacement_m,velocity_m_s,force_N,current_A,temperature_C";

impl RosMessage for Float64MultiArray {
    const TYPE_NAME: &'static str = "std_msgs/msg/Float64MultiArray";
    fn definition() -> String {
        join_definitions(
            "MultiArrayLayout layout\nfloat64[] data\n",
            &[
                (
                    "std_msgs/MultiArrayLayout",
                    "MultiArrayDimension[] dim\nuint32 data_offset\n",
                ),
                (
                    "std_msgs/MultiArrayDimension",
                    "string label\nuint32 size\nuint32 stride\n",
                ),
            ],
        )
    }
}

impl Float64MultiArray {
    /// A damper sample from its standard-type form; the error says what does not fit.
    pub fn to_damper_sample(&self, frame_id: &str) -> Result<crate::DamperSample, String> {
        let label = self
            .layout
            .dim
            .first()
            .map(|d| d.label.as_str())
            .unwrap_or("");
        if self.layout.dim.len() != 1 || label != SAMPLE_ARRAY_LABEL {
            return Err(format!(
                "a damper sample as Float64MultiArray needs one dimension labelled '{SAMPLE_ARRAY_LABEL}', got {:?}",
                self.layout.dim.iter().map(|d| d.label.as_str()).collect::<Vec<_>>()
            ));
        }
        let off = self.layout.data_offset as usize;
        let d = self.data.get(off..off + 6).ok_or_else(|| {
            format!(
                "needs 6 values after data_offset {off}, got {}",
                self.data.len()
            )
        })?;
        Ok(crate::DamperSample {
            header: Header::at(d[0], frame_id),
            displacement: d[1],
            velocity: d[2],
            force: d[3],
            current: d[4],
            temperature: d[5],
        })
    }
}
