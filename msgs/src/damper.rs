//! The `mrtwin_msgs` interface package: Rust twins of `msg/*.msg` (field for field,
//! in the same order, so serde's CDR encoding matches what rosidl generates).

use serde::{Deserialize, Serialize};

use crate::ros::{Header, Time};
use crate::{join_definitions, RosMessage};

/// `msg/DamperSample.msg`.
pub const DAMPER_SAMPLE_MSG: &str = include_str!("../msg/DamperSample.msg");
/// `msg/TwinOutput.msg`.
pub const TWIN_OUTPUT_MSG: &str = include_str!("../msg/TwinOutput.msg");
/// `msg/YieldEstimate.msg`.
pub const YIELD_ESTIMATE_MSG: &str = include_str!("../msg/YieldEstimate.msg");

fn with_header(own: &str) -> String {
    join_definitions(
        own,
        &[
            ("std_msgs/Header", Header::MSG),
            ("builtin_interfaces/Time", Time::MSG),
        ],
    )
}

/// `mrtwin_msgs/msg/DamperSample`: one sensor sample (SI; PHYSICS.md sign conventions).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct DamperSample {
    /// Stamp = time of the measurement; frame_id = damper name.
    pub header: Header,
    /// Piston displacement \[m\], positive in extension.
    pub displacement: f64,
    /// Piston velocity \[m/s\].
    pub velocity: f64,
    /// Rod force \[N\], positive when resisting extension.
    pub force: f64,
    /// Coil current \[A\].
    pub current: f64,
    /// Temperature \[°C\]; NaN when not measured.
    pub temperature: f64,
}

impl RosMessage for DamperSample {
    const TYPE_NAME: &'static str = "mrtwin_msgs/msg/DamperSample";
    fn definition() -> String {
        with_header(DAMPER_SAMPLE_MSG)
    }
}

/// `mrtwin_msgs/msg/TwinOutput`: the twin's prediction for one sample.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct TwinOutput {
    /// Stamp = the sample's stamp.
    pub header: Header,
    /// Model force \[N\].
    pub predicted_force: f64,
    /// Force of the sample \[N\].
    pub measured_force: f64,
    /// measured − predicted \[N\].
    pub residual: f64,
    /// Model dissipated power \[W\].
    pub dissipated_power: f64,
    /// Model fluid temperature \[°C\].
    pub fluid_temperature: f64,
    /// Model id.
    pub model_id: String,
    /// Health level: 0 OK, 1 WARN, 2 ERROR, 3 STALE.
    pub health_level: u8,
}

impl RosMessage for TwinOutput {
    const TYPE_NAME: &'static str = "mrtwin_msgs/msg/TwinOutput";
    fn definition() -> String {
        with_header(TWIN_OUTPUT_MSG)
    }
}

/// `mrtwin_msgs/msg/YieldEstimate`: the online yield-stress estimate.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct YieldEstimate {
    /// Stamp of the last sample used.
    pub header: Header,
    /// Coil current of the estimate \[A\].
    pub current: f64,
    /// τ0 at that current \[Pa\] (NaN before the first estimate).
    pub tau0: f64,
    /// Its standard deviation \[Pa\].
    pub tau0_std: f64,
    /// Currents seen so far, ascending \[A\].
    pub curve_current: Vec<f64>,
    /// τ0 at each \[Pa\].
    pub curve_tau0: Vec<f64>,
    /// Standard deviation at each \[Pa\].
    pub curve_tau0_std: Vec<f64>,
}

impl RosMessage for YieldEstimate {
    const TYPE_NAME: &'static str = "mrtwin_msgs/msg/YieldEstimate";
    fn definition() -> String {
        with_header(YIELD_ESTIMATE_MSG)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Field names of a .msg text, in order (comments and constants skipped).
    fn msg_field_names(msg: &str) -> Vec<String> {
        msg.lines()
            .map(|l| l.split('#').next().unwrap_or("").trim())
            .filter(|l| !l.is_empty() && !l.contains('='))
            .filter_map(|l| l.split_whitespace().nth(1).map(str::to_string))
            .collect()
    }

    /// Top-level field names of `T` in serialization order, from its JSON form.
    fn serde_field_names<T: Serialize + Default>() -> Vec<String> {
        let v: serde_json::Value = serde_json::to_value(T::default()).unwrap();
        let json = serde_json::to_string(&T::default()).unwrap();
        let mut names: Vec<String> = v.as_object().unwrap().keys().cloned().collect();
        names.sort_by_key(|k| json.find(&format!("\"{k}\":")).unwrap());
        names
    }

    #[test]
    fn rust_fields_follow_the_msg_files() {
        assert_eq!(
            serde_field_names::<DamperSample>(),
            msg_field_names(DAMPER_SAMPLE_MSG)
        );
        assert_eq!(
            serde_field_names::<TwinOutput>(),
            msg_field_names(TWIN_OUTPUT_MSG)
        );
        assert_eq!(
            serde_field_names::<YieldEstimate>(),
            msg_field_names(YIELD_ESTIMATE_MSG)
        );
    }

    #[test]
    fn definitions_carry_dependencies() {
        let d = DamperSample::definition();
        assert!(d.starts_with("# One sensor sample"));
        assert!(d.contains("\nMSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\n"));
        assert!(d.contains("\nMSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n"));
    }
}
