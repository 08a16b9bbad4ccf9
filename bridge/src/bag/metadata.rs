//! `metadata.yaml` of a rosbag2 directory (`rosbag2_bagfile_information`), as rosbag2
//! writes it in format version 8 (ROS 2 Iron; read by every rosbag2 since, and by
//! python `rosbags`), and the offered-QoS strings rosbag2 records per topic.
//!
//! Reading is lenient about what other writers leave out (missing counts, files list,
//! QoS as a string (≤ v8) or a list (v9)); writing always emits every field.

use std::collections::BTreeMap;
use std::path::Path;

use serde::{Deserialize, Serialize};

use super::BagError;
use crate::qos::Reliability;

/// The format version we write (rosbag2 Iron; Jazzy readers accept it).
pub const METADATA_VERSION: u32 = 8;

/// Name of the metadata file in a bag directory.
pub const METADATA_FILE: &str = "metadata.yaml";

/// The whole file: one top-level key.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct MetadataFile {
    /// What rosbag2 calls it.
    pub rosbag2_bagfile_information: BagInfo,
}

/// `rosbag2_bagfile_information`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct BagInfo {
    /// Format version (we write [`METADATA_VERSION`]).
    pub version: u32,
    /// Storage plugin: `mcap` (the only one read here) or `sqlite3`.
    pub storage_identifier: String,
    /// Storage files relative to the directory, in order.
    #[serde(default)]
    pub relative_file_paths: Vec<String>,
    /// Last minus first message time.
    #[serde(default)]
    pub duration: Duration,
    /// First message time.
    #[serde(default)]
    pub starting_time: StartingTime,
    /// Messages in all files.
    #[serde(default)]
    pub message_count: u64,
    /// Per-topic metadata and counts.
    #[serde(default)]
    pub topics_with_message_count: Vec<TopicWithCount>,
    /// `""` (no file compression).
    #[serde(default)]
    pub compression_format: String,
    /// `""` (no file compression).
    #[serde(default)]
    pub compression_mode: String,
    /// Per-file times and counts.
    #[serde(default)]
    pub files: Vec<FileInfo>,
    /// Free key/value pairs.
    #[serde(default)]
    pub custom_data: Option<BTreeMap<String, String>>,
    /// Distribution that wrote the bag.
    #[serde(default)]
    pub ros_distro: String,
}

/// `{nanoseconds: …}`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Duration {
    /// Nanoseconds.
    pub nanoseconds: u64,
}

/// `{nanoseconds_since_epoch: …}`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct StartingTime {
    /// Nanoseconds since the epoch (or since the start of simulated time).
    pub nanoseconds_since_epoch: u64,
}

/// One entry of `topics_with_message_count`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TopicWithCount {
    /// The topic.
    pub topic_metadata: TopicMetadata,
    /// Its messages in the bag.
    #[serde(default)]
    pub message_count: u64,
}

/// `topic_metadata`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TopicMetadata {
    /// Absolute topic name.
    pub name: String,
    /// ROS type, `pkg/msg/Type`.
    #[serde(rename = "type")]
    pub type_name: String,
    /// `cdr`.
    #[serde(default)]
    pub serialization_format: String,
    /// The publishers' QoS: a YAML string (≤ v8, what we write) or a list (v9).
    #[serde(default)]
    pub offered_qos_profiles: serde_norway::Value,
    /// RIHS01 type hash; empty when unknown (we leave it empty).
    #[serde(default)]
    pub type_description_hash: String,
}

/// One entry of `files`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FileInfo {
    /// File name relative to the directory.
    pub path: String,
    /// First message time in this file.
    #[serde(default)]
    pub starting_time: StartingTime,
    /// Last minus first message time in this file.
    #[serde(default)]
    pub duration: Duration,
    /// Messages in this file.
    #[serde(default)]
    pub message_count: u64,
}

/// The `offered_qos_profiles` string rosbag2 (≤ Iron) records for one publisher: history
/// unknown (3) with depth 0, as rosbag2 cannot see a publisher's history; volatile
/// durability (2); automatic liveliness (1); infinite deadline, lifespan and lease
/// (9223372036 s 854775807 ns, rmw's "infinite").
pub fn qos_profiles_yaml(reliability: Reliability) -> String {
    let r = match reliability {
        Reliability::Reliable => 1,
        Reliability::BestEffort => 2,
    };
    let inf = "\n    sec: 9223372036\n    nsec: 854775807";
    format!(
        "- history: 3\n  depth: 0\n  reliability: {r}\n  durability: 2\n  deadline:{inf}\n  \
         lifespan:{inf}\n  liveliness: 1\n  liveliness_lease_duration:{inf}\n  \
         avoid_ros_namespace_conventions: false"
    )
}

/// Parse a `metadata.yaml` (named in errors).
pub fn read_metadata(path: &Path) -> Result<BagInfo, BagError> {
    let text = std::fs::read_to_string(path).map_err(|e| BagError::io(path, "read", e))?;
    parse_metadata(&text, path)
}

/// Parse the text of a `metadata.yaml`; `path` names it in errors (what
/// [`read_metadata`] does once the file is read).
pub fn parse_metadata(text: &str, path: &Path) -> Result<BagInfo, BagError> {
    if text.trim().is_empty() {
        return Err(BagError::Metadata {
            file: path.to_owned(),
            reason: "file is empty".into(),
        });
    }
    let file: MetadataFile = serde_norway::from_str(text).map_err(|e| BagError::Metadata {
        file: path.to_owned(),
        reason: e.to_string(),
    })?;
    Ok(file.rosbag2_bagfile_information)
}

/// Render `info` as the text of a `metadata.yaml`.
pub fn to_yaml(info: &BagInfo) -> String {
    let mut text = serde_norway::to_string(&MetadataFile {
        rosbag2_bagfile_information: info.clone(),
    })
    .expect("plain data always serialises");
    if !text.ends_with('\n') {
        text.push('\n');
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn qos_string_parses_as_yaml_list() {
        let v: serde_norway::Value =
            serde_norway::from_str(&qos_profiles_yaml(Reliability::BestEffort)).unwrap();
        let first = &v.as_sequence().unwrap()[0];
        assert_eq!(first["reliability"].as_u64(), Some(2));
        assert_eq!(first["deadline"]["nsec"].as_u64(), Some(854775807));
    }

    #[test]
    fn round_trips_and_accepts_v9_lists() {
        let info = BagInfo {
            version: METADATA_VERSION,
            storage_identifier: "mcap".into(),
            relative_file_paths: vec!["b_0.mcap".into()],
            message_count: 3,
            topics_with_message_count: vec![TopicWithCount {
                topic_metadata: TopicMetadata {
                    name: "/d/sensor/sample".into(),
                    type_name: "mrtwin_msgs/msg/DamperSample".into(),
                    serialization_format: "cdr".into(),
                    offered_qos_profiles: serde_norway::Value::String(qos_profiles_yaml(
                        Reliability::Reliable,
                    )),
                    type_description_hash: String::new(),
                },
                message_count: 3,
            }],
            ..Default::default()
        };
        let back: MetadataFile = serde_norway::from_str(&to_yaml(&info)).unwrap();
        assert_eq!(back.rosbag2_bagfile_information, info);
        let v9 = "rosbag2_bagfile_information:\n  version: 9\n  storage_identifier: mcap\n  \
                  topics_with_message_count:\n    - topic_metadata:\n        name: /a\n        \
                  type: std_msgs/msg/Float64\n        serialization_format: cdr\n        \
                  offered_qos_profiles:\n          - history: keep_last\n      message_count: 1\n";
        let parsed: MetadataFile = serde_norway::from_str(v9).unwrap();
        assert_eq!(parsed.rosbag2_bagfile_information.version, 9);
    }
}
